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
    let values: Vec<f64> = img.iter().map(|&v| f64::from(v)).collect();
    let (data, _) = hann_fft(&values, w, h);
    let (mut sum, mut cnt) = (vec![0.0; bands], vec![0usize; bands]);
    let fxs: Vec<f64> = (0..w).map(|x| dft_frequency(x, w)).collect();
    for y in 0..h {
        let fy = dft_frequency(y, h);
        for (x, &fx) in fxs.iter().enumerate() {
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

/// The 2-D DFT of `values` (row-major `w x h`, `w, h >= 2`) after removing their mean and
/// applying a separable Hann window, and the window's energy `Σ window²` (the periodogram
/// `|F|² / Σ window²` then estimates the power per sample).
pub(crate) fn hann_fft(values: &[f64], w: usize, h: usize) -> (Vec<Complex<f64>>, f64) {
    let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
    let hann = |n: usize| -> Vec<f64> {
        (0..n)
            .map(|i| {
                0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (n.max(2) - 1) as f64).cos()
            })
            .collect()
    };
    let (hx, hy) = (hann(w), hann(h));
    let mut energy = 0.0;
    let mut data: Vec<Complex<f64>> = values
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let win = hx[i % w] * hy[i / w];
            energy += win * win;
            Complex::new((v - mean) * win, 0.0)
        })
        .collect();
    fft2(&mut data, w, h, false);
    (data, energy)
}

/// In-place 2-D discrete Fourier transform of a row-major `w x h` array (rows, then columns);
/// `inverse` runs the unnormalised inverse (divide by `w * h` to undo a forward transform).
pub(crate) fn fft2(data: &mut [Complex<f64>], w: usize, h: usize, inverse: bool) {
    if w == 0 || h == 0 || data.len() != w * h {
        return;
    }
    let mut planner = FftPlanner::<f64>::new();
    let plan = |p: &mut FftPlanner<f64>, n: usize| {
        if inverse {
            p.plan_fft_inverse(n)
        } else {
            p.plan_fft_forward(n)
        }
    };
    // Rows in place, then the columns as the rows of the transpose: contiguous transforms
    // instead of a strided gather per column (the same transforms, so the same values).
    plan(&mut planner, w).process(data);
    let mut columns = vec![Complex::new(0.0, 0.0); w * h];
    transpose(data, &mut columns, w, h);
    plan(&mut planner, h).process(&mut columns);
    transpose(&columns, data, h, w);
}

/// `dst` (`h x w`, row-major) = the transpose of `src` (`w x h`), in cache-sized tiles.
fn transpose(src: &[Complex<f64>], dst: &mut [Complex<f64>], w: usize, h: usize) {
    const TILE: usize = 32;
    for y0 in (0..h).step_by(TILE) {
        for x0 in (0..w).step_by(TILE) {
            for y in y0..(y0 + TILE).min(h) {
                for x in x0..(x0 + TILE).min(w) {
                    dst[x * h + y] = src[y * w + x];
                }
            }
        }
    }
}

/// Signed frequency, cycles per sample, of DFT index `i` of `n`.
pub(crate) fn dft_frequency(i: usize, n: usize) -> f64 {
    if i <= n / 2 {
        i as f64 / n as f64
    } else {
        (i as f64 - n as f64) / n as f64
    }
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
