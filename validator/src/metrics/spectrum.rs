//! Radial power spectra (the thesis compared NavCam and simulator images by FFT and found the
//! renders missing high frequencies). A Hann window suppresses the border discontinuity; the
//! power |F|² is averaged over annuli of normalised radial frequency (0 to 0.5 cycles/pixel) in
//! equal bands; the comparison is the log10 ratio per band.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use serde::Serialize;

/// A radial spectrum: mean power per band.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RadialSpectrum {
    /// Upper edge of each band in cycles per pixel.
    pub band_upper: Vec<f64>,
    /// Mean power per band.
    pub power: Vec<f64>,
}

/// Computes the radial spectrum of a grey image (any range) in `bands` bands.
pub fn radial_spectrum(img: &[f32], w: usize, h: usize, bands: usize) -> RadialSpectrum {
    let bands = bands.max(1);
    let band_upper: Vec<f64> = (1..=bands).map(|k| 0.5 * k as f64 / bands as f64).collect();
    if img.len() != w * h || w < 2 || h < 2 {
        return RadialSpectrum {
            band_upper,
            power: vec![0.0; bands],
        };
    }
    let mean = img.iter().map(|&v| f64::from(v)).sum::<f64>() / img.len() as f64;
    let hann = |i: usize, n: usize| {
        0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64).cos()
    };
    let mut data: Vec<Complex<f64>> = (0..w * h)
        .map(|i| {
            Complex::new(
                (f64::from(img[i]) - mean) * hann(i % w, w) * hann(i / w, h),
                0.0,
            )
        })
        .collect();
    let mut planner = FftPlanner::<f64>::new();
    let row = planner.plan_fft_forward(w);
    for r in data.chunks_exact_mut(w) {
        row.process(r);
    }
    let col = planner.plan_fft_forward(h);
    let mut column = vec![Complex::new(0.0, 0.0); h];
    for x in 0..w {
        for y in 0..h {
            column[y] = data[y * w + x];
        }
        col.process(&mut column);
        for y in 0..h {
            data[y * w + x] = column[y];
        }
    }
    let (mut sum, mut cnt) = (vec![0.0; bands], vec![0usize; bands]);
    for y in 0..h {
        let fy = if y <= h / 2 {
            y as f64
        } else {
            y as f64 - h as f64
        } / h as f64;
        for x in 0..w {
            let fx = if x <= w / 2 {
                x as f64
            } else {
                x as f64 - w as f64
            } / w as f64;
            let f = fx.hypot(fy);
            if f == 0.0 || f > 0.5 {
                continue;
            }
            let b = ((f / 0.5 * bands as f64).ceil() as usize).clamp(1, bands) - 1;
            sum[b] += data[y * w + x].norm_sqr();
            cnt[b] += 1;
        }
    }
    let power = sum
        .iter()
        .zip(&cnt)
        .map(|(s, &c)| if c > 0 { s / c as f64 } else { 0.0 })
        .collect();
    RadialSpectrum { band_upper, power }
}

/// log10(power_a / power_b) per band (0 where either is zero).
pub fn log_ratio(a: &RadialSpectrum, b: &RadialSpectrum) -> Vec<f64> {
    a.power
        .iter()
        .zip(&b.power)
        .map(|(&pa, &pb)| {
            if pa > 0.0 && pb > 0.0 {
                (pa / pb).log10()
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sinusoid_lands_in_its_band_and_blur_lowers_high_bands() {
        let (w, h) = (64, 64);
        // 0.25 cycles/pixel along x: band 5 of 10 (0.2, 0.25].
        let img: Vec<f32> = (0..w * h)
            .map(|i| (2.0 * std::f32::consts::PI * 0.25 * (i % w) as f32).sin() * 50.0 + 100.0)
            .collect();
        let s = radial_spectrum(&img, w, h, 10);
        let peak = s
            .power
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap()
            .0;
        assert_eq!(peak, 4);
        let noise: Vec<f32> = (0..w * h).map(|i| ((i * 7919 + 13) % 256) as f32).collect();
        let nz = &noise;
        let blurred: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let xs = [x.saturating_sub(1), x, (x + 1).min(w - 1)];
                let ys = [y.saturating_sub(1), y, (y + 1).min(h - 1)];
                xs.iter()
                    .flat_map(|&xx| ys.iter().map(move |&yy| nz[yy * w + xx]))
                    .sum::<f32>()
                    / 9.0
            })
            .collect();
        let r = log_ratio(
            &radial_spectrum(&blurred, w, h, 8),
            &radial_spectrum(&noise, w, h, 8),
        );
        assert!(
            r[7] < r[0] - 0.5,
            "blur must remove high frequencies: {r:?}"
        );
    }
}
