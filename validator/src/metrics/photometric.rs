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

/// Output rows of one band of [`ssim_sum`]: a band filters the rows it reaches (its own and
/// the kernel's radius either side) horizontally into its own scratch, so the five moment
/// planes SSIM needs are never held whole.
const BAND: usize = 32;

/// The five moments SSIM filters: `a`, `b`, `a²`, `b²` and `ab` of one pixel.
const MOMENTS: usize = 5;

/// One row's five moments filtered horizontally (edge-clamped): `out[m][x] = Σ_i k_i ·
/// v_m(x + i − r)`, summed tap by tap from 0 over the row padded with its edge values.
fn filter_row(a: &[f32], b: &[f32], k: &[f64; 11], pad: &mut Vec<f64>, out: &mut [Vec<f64>]) {
    let r = k.len() / 2;
    for (m, o) in out.iter_mut().enumerate() {
        let value = |i: usize| {
            let (x, y) = (
                f64::from(a.get(i).copied().unwrap_or(0.0)),
                f64::from(b.get(i).copied().unwrap_or(0.0)),
            );
            match m {
                0 => x,
                1 => y,
                2 => x * x,
                3 => y * y,
                _ => x * y,
            }
        };
        let w = a.len();
        pad.clear();
        pad.extend(std::iter::repeat_n(value(0), r));
        pad.extend((0..w).map(value));
        pad.extend(std::iter::repeat_n(value(w.saturating_sub(1)), r));
        // Tap by tap over the whole row (vectorises): each output still sums its taps in
        // order from 0.
        o.clear();
        o.resize(w, 0.0);
        for (i, kv) in k.iter().enumerate() {
            for (s, v) in o.iter_mut().zip(pad.get(i..).unwrap_or(&[])) {
                *s += kv * v;
            }
        }
    }
}

/// The sum of SSIM over the `mask` pixels of two `w × h` images, the five local moments
/// filtered separably with the Gaussian window, edge-clamped (the source row of tap `i` of
/// output row `y` is `min(max(y + i − r, 0), h − 1)`). Bands of rows are computed in parallel,
/// each pixel's moments and SSIM from the same sums in the same order as a per-pixel loop, and
/// the pixels' SSIM added in image order, so the sum does not depend on the bands or threads.
fn ssim_sum(a: &[f32], b: &[f32], mask: &[bool], w: usize, h: usize) -> f64 {
    let k = gauss_kernel();
    let r = k.len() / 2;
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let source = |y: usize, i: usize| (y + i).saturating_sub(r).min(h - 1);
    let bands: Vec<Vec<f64>> = (0..h.div_ceil(BAND))
        .into_par_iter()
        .map(|band| {
            let (y0, y1) = (band * BAND, ((band + 1) * BAND).min(h));
            let (lo, hi) = (source(y0, 0), source(y1 - 1, k.len() - 1));
            let mut pad = Vec::new();
            // Horizontally filtered moments of source rows lo..=hi.
            let rows: Vec<Vec<Vec<f64>>> = (lo..=hi)
                .map(|y| {
                    let mut out = vec![Vec::new(); MOMENTS];
                    let (ra, rb) = (
                        a.get(y * w..(y + 1) * w).unwrap_or(&[]),
                        b.get(y * w..(y + 1) * w).unwrap_or(&[]),
                    );
                    filter_row(ra, rb, &k, &mut pad, &mut out);
                    out
                })
                .collect();
            let mut terms = Vec::new();
            let mut mu = vec![vec![0.0; w]; MOMENTS];
            for y in y0..y1 {
                for (m, o) in mu.iter_mut().enumerate() {
                    o.fill(0.0);
                    for (i, kv) in k.iter().enumerate() {
                        let src = rows
                            .get(source(y, i) - lo)
                            .and_then(|r| r.get(m))
                            .map_or(&[][..], |r| r.as_slice());
                        for (s, v) in o.iter_mut().zip(src) {
                            *s += kv * v;
                        }
                    }
                }
                let keep = mask.get(y * w..(y + 1) * w).unwrap_or(&[]);
                for (x, _) in keep.iter().enumerate().filter(|(_, &m)| m) {
                    let at = |m: usize| mu.get(m).and_then(|r| r.get(x)).copied().unwrap_or(0.0);
                    let (ma, mb) = (at(0), at(1));
                    let va = at(2) - ma * ma;
                    let vb = at(3) - mb * mb;
                    let cov = at(4) - ma * mb;
                    terms.push(
                        ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                            / ((ma * ma + mb * mb + c1) * (va + vb + c2)),
                    );
                }
            }
            terms
        })
        .collect();
    bands.iter().flatten().fold(0.0, |s, t| s + t)
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
    let ssim = ssim_sum(a, b, mask, w, h);
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

    /// The banded SSIM is the per-pixel computation bit for bit: each moment filtered with
    /// the clamped separable window tap by tap, SSIM added over the mask in image order.
    /// Sizes that split into bands unevenly, shorter than one band and than the window.
    #[test]
    fn ssim_is_the_per_pixel_clamped_computation_bit_for_bit() {
        for (w, h) in [(37, 23), (41, 77), (6, 4)] {
            let a: Vec<f32> = (0..w * h)
                .map(|i| ((i * 7919) % 251) as f32 * 0.37 + (i % 7) as f32 * 1e-3)
                .collect();
            let b: Vec<f32> = (0..w * h).map(|i| ((i * 104_729) % 241) as f32).collect();
            let mask: Vec<bool> = (0..w * h).map(|i| i % 5 != 2).collect();
            let k = gauss_kernel();
            let r = k.len() / 2;
            let filtered = |v: &dyn Fn(usize) -> f64| {
                let at = |x: isize, y: usize| v(y * w + x.clamp(0, w as isize - 1) as usize);
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
                let mut out = vec![0.0; w * h];
                for y in 0..h {
                    for x in 0..w {
                        let mut s = 0.0;
                        for (i, kv) in k.iter().enumerate() {
                            let yy = (y + i).saturating_sub(r).min(h - 1);
                            s += kv * rows[yy * w + x];
                        }
                        out[y * w + x] = s;
                    }
                }
                out
            };
            let (fa, fb) = (|i: usize| f64::from(a[i]), |i: usize| f64::from(b[i]));
            let mu_a = filtered(&fa);
            let mu_b = filtered(&fb);
            let aa = filtered(&|i| fa(i) * fa(i));
            let bb = filtered(&|i| fb(i) * fb(i));
            let ab = filtered(&|i| fa(i) * fb(i));
            let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
            let mut expected = 0.0;
            for i in 0..w * h {
                if mask[i] {
                    let (ma, mb) = (mu_a[i], mu_b[i]);
                    let (va, vb, cov) = (aa[i] - ma * ma, bb[i] - mb * mb, ab[i] - ma * mb);
                    expected += ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                        / ((ma * ma + mb * mb + c1) * (va + vb + c2));
                }
            }
            let got = ssim_sum(&a, &b, &mask, w, h);
            assert_eq!(got.to_bits(), expected.to_bits(), "{w} x {h}");
        }
    }
}
