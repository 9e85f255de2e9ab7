//! The `blur` effect, measured on the skyline: the width of the terrain/sky edge in the real
//! frames against the same edge in the render.
//!
//! Blur cannot be fitted reliably by matching pixels: a terrain entry's render carries noise
//! of its own (laser range noise in the DEM's normals, reflectance speckle in its texture) that
//! the real image does not have, and blurring the render removes that noise too, so a pixel fit
//! finds "blur" on every entry. An occluding edge against the sky is different: in the render it
//! is a sharp step, in the real image it is softened by the lens PSF, and its
//! width does not depend on where exactly the edge lies (each profile is measured on its own,
//! so a small misalignment does not matter).
//!
//! For every column where the render's terrain mask starts below sky and the skyline is nearly
//! horizontal (it moves at most 1 px over 4 columns), the vertical profile ±[`HALF`] px around
//! it is fitted with a Gaussian-blurred step, which locates the edge to a fraction of a pixel
//! and normalises its levels. The normalised samples of all profiles, each at its own sub-pixel
//! phase, are pooled into one edge-spread function per image (the slanted-edge method of
//! ISO 12233), whose σ is fitted once: a single profile cannot resolve σ below about 0.5 px, the
//! pooled function can. `σ_blur² = σ_real² − σ_render²`, with the render point-sampled (no
//! supersampling): a camera that integrates over its pixel area then shows that area's
//! 1/12 px² as blur the point-sampled simulation lacks, which is what it is.
//!
//! Known limit: a negative exposure offset clips a black sky, and the profiles whose
//! transition falls below the clip show no sample between sky and terrain; their sky level is
//! then free, any lower level with a sharper edge fits as well, and they read as steps (mini
//! seed 107, exposure alone: a real edge variance of 0.001 px² against the render's 0.039). A
//! small blur next to such an offset is missed (the same seed: 0.52 px). Fixing the sky level
//! at the render's did not recover it (0.19 px). Nor does one sky level shared by every
//! clipped profile, fitted jointly with one σ (each profile its own step and position): on
//! seed 107 it read 0.59 px, but on a synthetic dark edge with pixel-scale texture the shared
//! level ran to the search's bound (−60 DN for −8) whatever the σ, so the σ it gave was the
//! texture's, not the edge's.

use super::lsq::{solve, Problem};
use super::views::ImagePair;

/// Half-height of an edge profile, px.
pub const HALF: usize = 6;
/// Minimum step across an edge, DN (sky to terrain), for the profile to count.
const MIN_STEP: f64 = 20.0;
/// Minimum number of profiles for a measurement.
const MIN_PROFILES: usize = 30;
/// Samples this close (DN) to the 8-bit floor or ceiling are censored: clipping cuts an edge's
/// foot off, and a cut edge looks sharper (a hidden exposure offset of −0.045 against a black
/// sky made a 1.51 px blur read 1.21; censored, 1.59). A censored sample only says the edge is
/// at most (at least) that level there. The guard covers part of the read noise the clip
/// rectifies; a wider one selects noise: at 8 DN a 0.54 px blur read 0.33 (0.42 at 3 DN),
/// because the samples kept just above it are those the noise lifted.
const CLIP_GUARD_DN: f64 = 3.0;

/// Standard deviation of the measured σ about the truth over mini's blur campaigns (seeds
/// 101–107, alone and next to an exposure: 13 fits on the laser entry, errors −0.11 to
/// +0.17 px, RMS 0.107 px), px: the estimator's calibration, part of a measured σ's standard
/// error. Large blurs read high (σ ≈ 1.5 px: +0.00 to +0.17) and small ones low (σ ≈ 0.53 px:
/// −0.11): the terrain's edge is not a clean step, and on point-sampled images a blur well
/// under a pixel shows no sub-pixel phases. Measured on the campaign's true terrain as well
/// (seeds 101, 102, 105: +0.07, −0.10, +0.12 px), so it is the estimator's, not the entry's.
pub const CALIBRATION_PX: f64 = 0.11;

/// The skyline edge measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeBlur {
    /// Gaussian PSF σ the real edges have in excess of the render's, px (0 when sharper).
    pub sigma_px: f64,
    /// Edge variance of the render, px².
    pub render_var: f64,
    /// Edge variance of the real frames, px².
    pub real_var: f64,
    /// Profiles used.
    pub profiles: usize,
}

/// Skyline rows `(x, y0)`: `y0` is the first terrain row of column `x` with sky above.
fn skyline(mask: &[bool], w: usize, h: usize) -> Vec<(usize, usize)> {
    let top: Vec<Option<usize>> = (0..w)
        .map(|x| {
            let y0 = (0..h).find(|&y| mask[y * w + x])?;
            let clean =
                y0 > HALF && y0 + HALF + 1 < h && (y0..=y0 + HALF + 1).all(|y| mask[y * w + x]);
            clean.then_some(y0)
        })
        .collect();
    (2..w.saturating_sub(2))
        .filter_map(|x| {
            let y0 = top[x]?;
            let (a, b) = (top[x - 2]?, top[x + 2]?);
            (a.abs_diff(b) <= 1 && a.abs_diff(y0) <= 1).then_some((x, y0))
        })
        .collect()
}

/// `erf` (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7).
pub(super) fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let y = 1.0 - poly * (-x * x).exp();
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// The unit step blurred by a Gaussian of σ `s`, sampled at `t` (relative to the edge).
fn step(t: f64, s: f64) -> f64 {
    0.5 * (1.0 + erf(t / (s * std::f64::consts::SQRT_2)))
}

/// The profile of the edge at `(x, y0)` in `img`, normalised by its own fit: `(y − c, (v − a)
/// / b)` pairs of the uncensored samples, `None` when the step is too weak. The fit is a
/// blurred step `a + b · step(y − c, s)` over ±[`HALF`] px; a censored sample (within
/// [`CLIP_GUARD_DN`] of 0 or 255) counts only where the model crosses its bound.
fn edge_samples(img: &[f32], w: usize, x: usize, y0: usize) -> Option<Vec<(f64, f64)>> {
    let ys: Vec<f64> = (y0 - HALF..=y0 + HALF).map(|y| y as f64).collect();
    let vs: Vec<f64> = (y0 - HALF..=y0 + HALF)
        .map(|y| f64::from(img[y * w + x]))
        .collect();
    let lo = vs[..HALF].iter().sum::<f64>() / HALF as f64;
    let hi = vs[HALF + 1..].iter().sum::<f64>() / HALF as f64;
    if hi - lo < MIN_STEP {
        return None;
    }
    let (floor, ceil) = (CLIP_GUARD_DN, 255.0 - CLIP_GUARD_DN);
    let f = |p: &[f64], out: &mut Vec<f64>| {
        out.clear();
        out.extend(ys.iter().zip(&vs).map(|(y, &v)| {
            let m = p[0] + p[1] * step(y - p[2], p[3]);
            if v <= floor {
                (m - floor).max(0.0)
            } else if v >= ceil {
                (m - ceil).min(0.0)
            } else {
                m - v
            }
        }));
    };
    let y = y0 as f64;
    let sol = solve(
        &Problem {
            residuals: &f,
            start: vec![lo, hi - lo, y - 0.5, 0.8],
            lower: vec![lo - 100.0, 1.0, y - 3.0, 0.02],
            upper: vec![hi + 100.0, 512.0, y + 2.0, 4.0],
            step: vec![1e-4, 1e-4, 1e-5, 1e-5],
        },
        30,
    );
    let p = &sol.params;
    Some(
        ys.iter()
            .zip(&vs)
            .filter(|(_, &v)| v > floor && v < ceil)
            .map(|(y, v)| (y - p[2], (v - p[0]) / p[1]))
            .filter(|(t, _)| t.abs() <= 4.0)
            .collect(),
    )
}

/// The σ of one pooled edge-spread function: the normalised samples of every profile (each at
/// its own sub-pixel phase, as in the slanted-edge method) fitted with `step(t, s)`.
fn pooled_sigma(samples: &[(f64, f64)]) -> f64 {
    let f = |p: &[f64], out: &mut Vec<f64>| {
        out.clear();
        out.extend(samples.iter().map(|(t, v)| step(*t, p[0]) - v));
    };
    solve(
        &Problem {
            residuals: &f,
            start: vec![0.6],
            lower: vec![0.02],
            upper: vec![4.0],
            step: vec![1e-5],
        },
        50,
    )
    .params[0]
}

/// Measures the excess edge blur of the real images over the renders along the skyline of the
/// render masks, over several views; `None` with fewer than 30 usable profiles.
pub fn measure(views: &[ImagePair<'_>]) -> Option<EdgeBlur> {
    let mut real = Vec::new();
    let mut render = Vec::new();
    let mut profiles = 0;
    for v in views {
        for (x, y0) in skyline(v.mask, v.w, v.h) {
            if let (Some(q), Some(r)) = (
                edge_samples(v.real, v.w, x, y0),
                edge_samples(v.render, v.w, x, y0),
            ) {
                real.extend(q);
                render.extend(r);
                profiles += 1;
            }
        }
    }
    if profiles < MIN_PROFILES {
        return None;
    }
    let (sq, sr) = (pooled_sigma(&real), pooled_sigma(&render));
    Some(EdgeBlur {
        sigma_px: (sq * sq - sr * sr).max(0.0).sqrt(),
        render_var: sr * sr,
        real_var: sq * sq,
        profiles,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::gaussian_blur;

    /// A bright terrain below a wavy skyline, black sky above, box anti-aliased.
    fn scene(w: usize, h: usize) -> (Vec<f32>, Vec<bool>) {
        let sky = |x: f64| 40.0 + 3.0 * (x / 37.0).sin();
        let mut img = vec![0.0f32; w * h];
        let mut mask = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let cover = ((y as f64 + 0.5) - sky(x as f64)).clamp(0.0, 1.0);
                img[y * w + x] =
                    (120.0 + 10.0 * ((x * 7 + y * 3) % 5) as f64 / 5.0) as f32 * cover as f32;
                mask[y * w + x] = y as f64 >= sky(x as f64);
            }
        }
        (img, mask)
    }

    #[test]
    fn recovers_the_psf_of_a_blurred_copy() {
        let (w, h) = (256, 96);
        let (render, mask) = scene(w, h);
        for sigma in [0.6, 1.0, 1.5] {
            let real = gaussian_blur(&render, w, h, sigma);
            let m = measure(&[ImagePair {
                real: &real,
                render: &render,
                mask: &mask,
                w,
                h,
            }])
            .unwrap();
            assert!((m.sigma_px - sigma).abs() < 0.1, "{sigma}: {m:?}");
        }
        let m = measure(&[ImagePair {
            real: &render,
            render: &render,
            mask: &mask,
            w,
            h,
        }])
        .unwrap();
        assert!(m.sigma_px < 0.05, "{m:?}");
    }

    /// The corpus's exposure: `gain · v + offset · 255`, then the 8-bit clip.
    fn exposed(img: &[f32], gain: f32, offset: f32) -> Vec<f32> {
        img.iter()
            .map(|v| (gain * v + offset * 255.0).clamp(0.0, 255.0).round())
            .collect()
    }

    #[test]
    fn an_edge_clipped_by_a_negative_offset_keeps_its_width() {
        let (w, h) = (256, 96);
        let (render, mask) = scene(w, h);
        for (gain, offset) in [(0.76, -0.045), (1.0, -0.02), (2.2, 0.0)] {
            let real = exposed(&gaussian_blur(&render, w, h, 1.5), gain, offset);
            let m = measure(&[ImagePair {
                real: &real,
                render: &render,
                mask: &mask,
                w,
                h,
            }])
            .unwrap();
            assert!((m.sigma_px - 1.5).abs() < 0.1, "{gain} {offset}: {m:?}");
        }
    }
}
