//! Photometric agreement inside a common mask: RMS difference and SSIM (Wang et al. 2004 with an
//! 11×11 Gaussian window, σ = 1.5, K1 = 0.01, K2 = 0.03, dynamic range 255).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Photometric figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Photometric {
    /// Pixels compared.
    pub pixels: usize,
    /// RMS of `a − b` in grey levels (0–255).
    pub rms: f64,
    /// Mean of `a − b`.
    pub mean_diff: f64,
    /// Mean SSIM over mask pixels.
    pub ssim: f64,
}

fn gauss_kernel() -> [f64; 11] {
    let mut k = [0.0; 11];
    for (i, v) in k.iter_mut().enumerate() {
        let x = i as f64 - 5.0;
        *v = (-x * x / (2.0 * 1.5 * 1.5)).exp();
    }
    let s: f64 = k.iter().sum();
    k.map(|v| v / s)
}

/// Separable Gaussian filter with edge clamping. Row by row: a row is padded with its edge
/// values so the horizontal taps need no clamping, and both passes add whole rows, tap by tap
/// (the horizontal one the padded row shifted by the tap); each output is the same sum in the
/// same order as a per-pixel loop, so the result does not depend on the rows' split between
/// threads.
fn filter(img: &[f64], w: usize, h: usize) -> Vec<f64> {
    let k = gauss_kernel();
    let r = k.len() / 2;
    if w == 0 || h == 0 || img.len() != w * h {
        return vec![0.0; img.len()];
    }
    let mut tmp = vec![0.0; w * h];
    tmp.par_chunks_mut(w)
        .zip(img.par_chunks(w))
        .for_each_init(Vec::new, |pad, (out, row)| {
            pad.clear();
            let first = row.first().copied().unwrap_or(0.0);
            let last = row.last().copied().unwrap_or(0.0);
            pad.extend(std::iter::repeat_n(first, r));
            pad.extend_from_slice(row);
            pad.extend(std::iter::repeat_n(last, r));
            // Tap by tap over the whole row (vectorises): each output still sums its taps
            // in order from 0.
            out.fill(0.0);
            for (i, kv) in k.iter().enumerate() {
                for (o, v) in out.iter_mut().zip(pad.get(i..).unwrap_or(&[])) {
                    *o += kv * v;
                }
            }
        });
    let mut out = vec![0.0; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
        o.fill(0.0);
        for (i, kv) in k.iter().enumerate() {
            let yy = (y + i).saturating_sub(r).min(h - 1);
            for (s, v) in o
                .iter_mut()
                .zip(tmp.get(yy * w..(yy + 1) * w).unwrap_or(&[]))
            {
                *s += kv * v;
            }
        }
    });
    out
}

/// Compares two grey images (0–255) of size `w × h` over `mask` (true = compare).
pub fn compare(a: &[f32], b: &[f32], mask: &[bool], w: usize, h: usize) -> Photometric {
    let n = w * h;
    if a.len() != n || b.len() != n || mask.len() != n || n == 0 {
        return Photometric {
            pixels: 0,
            rms: 0.0,
            mean_diff: 0.0,
            ssim: 0.0,
        };
    }
    let (mut s2, mut s1, mut cnt) = (0.0, 0.0, 0usize);
    for i in 0..n {
        if mask[i] {
            let d = f64::from(a[i]) - f64::from(b[i]);
            s2 += d * d;
            s1 += d;
            cnt += 1;
        }
    }
    let af: Vec<f64> = a.iter().map(|&v| f64::from(v)).collect();
    let bf: Vec<f64> = b.iter().map(|&v| f64::from(v)).collect();
    let mu_a = filter(&af, w, h);
    let mu_b = filter(&bf, w, h);
    let aa = filter(&af.iter().map(|v| v * v).collect::<Vec<_>>(), w, h);
    let bb = filter(&bf.iter().map(|v| v * v).collect::<Vec<_>>(), w, h);
    let ab = filter(
        &af.iter().zip(&bf).map(|(x, y)| x * y).collect::<Vec<_>>(),
        w,
        h,
    );
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let mut ssim = 0.0;
    for i in 0..n {
        if mask[i] {
            let (ma, mb) = (mu_a[i], mu_b[i]);
            let va = aa[i] - ma * ma;
            let vb = bb[i] - mb * mb;
            let cov = ab[i] - ma * mb;
            ssim += ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                / ((ma * ma + mb * mb + c1) * (va + vb + c2));
        }
    }
    let c = cnt.max(1) as f64;
    Photometric {
        pixels: cnt,
        rms: (s2 / c).sqrt(),
        mean_diff: s1 / c,
        ssim: ssim / c,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_have_ssim_one_and_zero_rms() {
        let img: Vec<f32> = (0..64 * 48).map(|i| ((i * 7919) % 251) as f32).collect();
        let mask = vec![true; img.len()];
        let p = compare(&img, &img, &mask, 64, 48);
        assert_eq!(p.rms, 0.0);
        assert!((p.ssim - 1.0).abs() < 1e-12);
        let shifted: Vec<f32> = img.iter().map(|v| v + 10.0).collect();
        let q = compare(&img, &shifted, &mask, 64, 48);
        assert!((q.rms - 10.0).abs() < 1e-9 && (q.mean_diff + 10.0).abs() < 1e-9);
        assert!(q.ssim < 1.0);
        let noise: Vec<f32> = (0..img.len())
            .map(|i| ((i * 104729) % 256) as f32)
            .collect();
        assert!(compare(&img, &noise, &mask, 64, 48).ssim < 0.2);
    }

    #[test]
    fn the_filter_is_the_per_pixel_clamped_convolution_bit_for_bit() {
        let (w, h) = (37, 23);
        let img: Vec<f64> = (0..w * h)
            .map(|i| ((i * 7919) % 251) as f64 * 0.37 + (i % 7) as f64 * 1e-3)
            .collect();
        let k = gauss_kernel();
        let r = k.len() / 2;
        let at = |x: isize, y: usize| img[y * w + x.clamp(0, w as isize - 1) as usize];
        let mut rows = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0;
                for (i, kv) in k.iter().enumerate() {
                    s += kv * at(x as isize + i as isize - r as isize, y);
                }
                rows[y * w + x] = s;
            }
        }
        let mut expected = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0;
                for (i, kv) in k.iter().enumerate() {
                    let yy = (y + i).saturating_sub(r).min(h - 1);
                    s += kv * rows[yy * w + x];
                }
                expected[y * w + x] = s;
            }
        }
        let got = filter(&img, w, h);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        assert_eq!(bits(&got), bits(&expected));
    }
}
