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
//! pooled function can.
//!
//! The PSF is then found by forward modelling, not by subtracting widths: the render is passed
//! through the sensor model with a Gaussian PSF of σ added (the same discrete filter the model
//! applies, on the camera's 8-bit range), its edges are measured by the same profiles and the
//! same fit, and σ is the value at which they are as wide as the real ones (a false-position
//! search in σ², started at the quadrature difference below). Whatever the estimator reads
//! besides the PSF — a terrain edge that is not a clean step, the sampled kernel of a blur
//! under a pixel on point-sampled images, the profile window — it reads on both sides and it
//! cancels. The quadrature difference `σ_real² − σ_render²` still decides whether there is a
//! blur ([`EdgeBlur::excess_px`]: below σ ≈ 0.4 px the sampled kernel hardly widens a
//! point-sampled edge, so a width excess of noise would match a σ of 0.3–0.4), but no longer
//! values it: it read small blurs low and large ones high, the matched σ within a few
//! hundredths of a pixel (figures: docs/gap-findings.md, "The skyline blur's estimator"). A
//! camera that integrates over its pixel area shows that area's 1/12 px² as blur the
//! point-sampled simulation lacks, which is what it is.
//!
//! The skyline is a witness only where the real image shows, beyond the terrain's edge, what
//! the render shows there: an unlit background (a sky, or a lab draped in black). A lit one —
//! the testbed's rim, the hall's floor and walls, which no entry holds — makes the real edge a
//! step between two lit surfaces (often a staircase: terrain, the rim's inner face, its top),
//! wider than any PSF: on independently rendered lab campaigns (docs/gap-findings.md, far
//! sides 27–44 DN above the render's sky) such edges read 0.6–1.6 px with nothing hidden. So a
//! profile counts only when the real far side is no brighter than the render's sky plus the
//! largest offset an exposure of the catalogue lifts a black background by
//! ([`dark_background_dn`]); and a view counts only when most of its profiles do (a lit
//! background has dark patches too: a shadowed floor, a dark wall panel). Without such a view
//! the blur is not measured, and the run says so.
//!
//! Known limit: the blur is measured before the photometry, so the render is not clipped
//! where a negative exposure offset clips a black sky in the real frames. The profiles whose
//! transition falls below the clip show no sample between sky and terrain; their sky level is
//! then free and they read sharper. Censoring the clipped samples keeps a large blur's width;
//! a small one next to such an offset is missed. A second measure through the fitted exposure
//! (the render's edges then clip alike) was tried and not made, nor were a sky level fixed at
//! the render's or shared by every clipped profile (figures: docs/gap-findings.md, "The
//! skyline blur's estimator").

use rayon::prelude::*;

use super::lsq::{solve, Problem};
use crate::sensor::Effect;

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

/// Root mean square error of the measured σ over the calibration campaigns (mini seeds
/// 108–114, alone and next to an exposure: 14 fits on the laser entry, σ 0.93–1.54 px,
/// errors −0.066 … +0.111 px, RMS 0.046 px), px: the estimator's calibration, part of a
/// measured σ's standard error.
pub const CALIBRATION_PX: f64 = 0.05;

/// The skyline edge measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeBlur {
    /// Gaussian PSF σ whose blurred renders' edges are as wide as the real ones, px (0 when
    /// the real edges are sharper).
    pub sigma_px: f64,
    /// The real edges' width in excess of the render's, `sqrt(σ_real² − σ_render²)`, px (0
    /// when sharper): what the evidence for a blur is judged on. The sensor's sampled kernel
    /// hardly widens a point-sampled edge below σ ≈ 0.4 px, so there a tiny excess (the real
    /// frames' noise, a few hundredths of a pixel) matches a σ of 0.3–0.4.
    pub excess_px: f64,
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

/// The most an unlit background's level can exceed the render's sky, DN: the largest offset of
/// the catalogue's exposure range (what a black level lifts a black background by).
pub fn dark_background_dn() -> f64 {
    Effect::default_range("exposure")
        .and_then(|r| r.iter().find(|p| p.name == "offset"))
        .map_or(0.0, |p| 255.0 * p.max)
}

/// One edge profile: its normalised samples and the level of its far (sky) side.
struct EdgeFit {
    /// `(y − c, (v − a) / b)` pairs of the uncensored samples.
    samples: Vec<(f64, f64)>,
    /// The fitted level `a` beyond the edge, DN.
    far_dn: f64,
    /// The mean of the samples beyond the edge, DN.
    far_mean_dn: f64,
}

/// The profile of the edge at `(x, y0)` in `img`, normalised by its own fit, `None` when the
/// step is too weak. The fit is a blurred step `a + b · step(y − c, s)` over ±[`HALF`] px; a
/// censored sample (within [`CLIP_GUARD_DN`] of 0 or 255) counts only where the model crosses
/// its bound.
fn edge_fit(img: &[f32], w: usize, x: usize, y0: usize) -> Option<EdgeFit> {
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
    Some(EdgeFit {
        samples: ys
            .iter()
            .zip(&vs)
            .filter(|(_, &v)| v > floor && v < ceil)
            .map(|(y, v)| (y - p[2], (v - p[0]) / p[1]))
            .filter(|(t, _)| t.abs() <= 4.0)
            .collect(),
        far_dn: p[0],
        far_mean_dn: lo,
    })
}

/// [`edge_fit`]'s normalised samples.
fn edge_samples(img: &[f32], w: usize, x: usize, y0: usize) -> Option<Vec<(f64, f64)>> {
    edge_fit(img, w, x, y0).map(|f| f.samples)
}

/// The σ of one pooled edge-spread function: the normalised samples of every profile (each at
/// its own sub-pixel phase, as in the slanted-edge method) fitted with `step(t, s)`.
fn pooled_sigma(samples: &[(f64, f64)]) -> f64 {
    let f = |p: &[f64], out: &mut Vec<f64>| {
        out.clear();
        out.par_extend(samples.par_iter().map(|(t, v)| step(*t, p[0]) - v));
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

/// One view's skyline: the real frames' mean, the render's terrain mask, and the render
/// through the sensor model with a Gaussian PSF of σ px added (`render(0.0)`: without one).
#[derive(Clone, Copy)]
pub struct EdgeView<'a> {
    /// Real DN (the frame mean).
    pub real: &'a [f32],
    /// The render sees terrain.
    pub mask: &'a [bool],
    /// Width.
    pub w: usize,
    /// Height.
    pub h: usize,
    /// The render's DN with a PSF of the given σ, px, on the camera's 8-bit range.
    pub render: &'a (dyn Fn(f64) -> Vec<f32> + Sync),
}

/// One usable skyline profile: its view, column and edge row, and the normalised samples of
/// the real frames and of the render without an added PSF.
struct Site {
    view: usize,
    x: usize,
    y0: usize,
    real: Vec<(f64, f64)>,
    render: Vec<(f64, f64)>,
}

/// The skyline profiles of several views, found and sampled once: [`Skyline::measure`] then
/// measures on any subset of the views (the jackknife over captures leaves each out in turn)
/// exactly as on views given alone.
pub struct Skyline<'a> {
    views: &'a [EdgeView<'a>],
    sites: Vec<Site>,
    /// Views with skyline profiles whose background most of them show lit.
    pub lit_views: usize,
    /// Profiles dropped for a lit background.
    pub lit_profiles: usize,
}

impl<'a> Skyline<'a> {
    /// Finds every view's skyline profiles where both the real frames and the render show an
    /// edge and the real background beyond it is unlit (see the module docs).
    pub fn sample(views: &'a [EdgeView<'a>]) -> Skyline<'a> {
        let dark = dark_background_dn();
        let per_view: Vec<(Vec<Site>, usize)> = views
            .par_iter()
            .enumerate()
            .map(|(i, v)| {
                let plain = (v.render)(0.0);
                let fits: Vec<(Site, bool)> = skyline(v.mask, v.w, v.h)
                    .into_par_iter()
                    .filter_map(|(x, y0)| {
                        let real = edge_fit(v.real, v.w, x, y0)?;
                        let render = edge_fit(&plain, v.w, x, y0)?;
                        let unlit = real.far_dn - render.far_mean_dn <= dark;
                        let site = Site {
                            view: i,
                            x,
                            y0,
                            real: real.samples,
                            render: render.samples,
                        };
                        Some((site, unlit))
                    })
                    .collect();
                let unlit = fits.iter().filter(|(_, u)| *u).count();
                let total = fits.len();
                if 2 * unlit > total {
                    (
                        fits.into_iter()
                            .filter(|(_, u)| *u)
                            .map(|(s, _)| s)
                            .collect(),
                        total - unlit,
                    )
                } else {
                    (Vec::new(), total)
                }
            })
            .collect();
        let lit_views = per_view
            .iter()
            .filter(|(s, d)| s.is_empty() && *d > 0)
            .count();
        let lit_profiles = per_view.iter().map(|(_, d)| d).sum();
        Skyline {
            views,
            sites: per_view.into_iter().flat_map(|(s, _)| s).collect(),
            lit_views,
            lit_profiles,
        }
    }

    /// Measures the PSF the renders of the views `keep` selects lack along their skylines: the
    /// σ whose blurred renders' pooled edges are as wide as the real ones (both measured by the
    /// same profiles and the same fit). `None` with fewer than 30 usable profiles.
    pub fn measure(&self, keep: &(dyn Fn(usize) -> bool + Sync)) -> Option<EdgeBlur> {
        let sites: Vec<&Site> = self.sites.iter().filter(|s| keep(s.view)).collect();
        if sites.len() < MIN_PROFILES {
            return None;
        }
        let pooled = |of: &dyn Fn(&Site) -> &[(f64, f64)]| -> Vec<(f64, f64)> {
            sites.iter().flat_map(|s| of(s).iter().copied()).collect()
        };
        let (sq, sr) = (
            pooled_sigma(&pooled(&|s| &s.real)),
            pooled_sigma(&pooled(&|s| &s.render)),
        );
        let width = |sigma: f64| {
            let imgs: Vec<Option<Vec<f32>>> = self
                .views
                .par_iter()
                .enumerate()
                .map(|(i, v)| keep(i).then(|| (v.render)(sigma)))
                .collect();
            let samples: Vec<(f64, f64)> = sites
                .par_iter()
                .filter_map(|s| {
                    let img = imgs[s.view].as_ref()?;
                    edge_samples(img, self.views[s.view].w, s.x, s.y0)
                })
                .flatten()
                .collect();
            pooled_sigma(&samples)
        };
        Some(EdgeBlur {
            sigma_px: match_width(sq, sr, &width),
            excess_px: (sq * sq - sr * sr).max(0.0).sqrt(),
            render_var: sr * sr,
            real_var: sq * sq,
            profiles: sites.len(),
        })
    }
}

/// Measures the PSF the renders lack along the skylines of their masks, over several views
/// ([`Skyline::measure`] on all of them).
pub fn measure(views: &[EdgeView<'_>]) -> Option<EdgeBlur> {
    Skyline::sample(views).measure(&|_| true)
}

/// Largest PSF σ searched, px.
const MAX_SIGMA_PX: f64 = 4.0;

/// The σ at which `width(σ)` (the blurred render's edge σ, `w0` at 0, increasing) reaches
/// `target`, to 0.002 px (or 10⁻⁶ px² in the variance); 0 when the render is already as
/// wide. Edge variances add nearly as the PSF's, so the root is sought in σ² by false position
/// (Illinois), started at the quadrature difference.
fn match_width(target: f64, w0: f64, width: &dyn Fn(f64) -> f64) -> f64 {
    let f = |u: f64| width(u.sqrt()).powi(2) - target * target;
    let mut lo = (0.0, w0 * w0 - target * target);
    if lo.1 >= 0.0 {
        return 0.0;
    }
    let max_u = MAX_SIGMA_PX * MAX_SIGMA_PX;
    let mut u = (-lo.1).min(max_u);
    let mut hi = loop {
        let fu = f(u);
        if fu.abs() < 1e-6 {
            return u.sqrt();
        }
        if fu >= 0.0 {
            break (u, fu);
        }
        if u >= max_u {
            return MAX_SIGMA_PX;
        }
        lo = (u, fu);
        u = (2.0 * u).min(max_u);
    };
    // Which end moved last: the other end's value is halved when it stays twice (Illinois).
    let mut last = 0i8;
    for _ in 0..12 {
        if hi.0.sqrt() - lo.0.sqrt() < 0.002 {
            break;
        }
        let u = (lo.0 * hi.1 - hi.0 * lo.1) / (hi.1 - lo.1);
        let fu = f(u);
        if fu.abs() < 1e-6 {
            return u.sqrt();
        }
        if fu >= 0.0 {
            hi = (u, fu);
            if last == 1 {
                lo.1 /= 2.0;
            }
            last = 1;
        } else {
            lo = (u, fu);
            if last == -1 {
                hi.1 /= 2.0;
            }
            last = -1;
        }
    }
    0.5 * (lo.0.sqrt() + hi.0.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::gaussian_blur;

    /// A bright textured terrain below a wavy skyline, black sky above: box anti-aliased
    /// (`area`) or point-sampled at the pixel centres.
    fn scene(w: usize, h: usize, area: bool) -> (Vec<f32>, Vec<bool>) {
        let sky = |x: f64| 40.0 + 3.0 * (x / 37.0).sin();
        let mut img = vec![0.0f32; w * h];
        let mut mask = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let below = (y as f64 + 0.5) - sky(x as f64);
                let cover = if area {
                    below.clamp(0.0, 1.0)
                } else {
                    f64::from(u8::from(below >= 0.0))
                };
                img[y * w + x] =
                    (120.0 + 10.0 * ((x * 7 + y * 3) % 5) as f64 / 5.0) as f32 * cover as f32;
                mask[y * w + x] = y as f64 >= sky(x as f64);
            }
        }
        (img, mask)
    }

    /// The σ measured for `real` against `render` blurred by the sensor's own filter.
    fn measured(real: &[f32], render: &[f32], mask: &[bool], w: usize, h: usize) -> EdgeBlur {
        let blurred = |s: f64| gaussian_blur(render, w, h, s);
        measure(&[EdgeView {
            real,
            mask,
            w,
            h,
            render: &blurred,
        }])
        .unwrap()
    }

    #[test]
    fn recovers_the_psf_of_a_blurred_copy() {
        let (w, h) = (256, 96);
        for area in [true, false] {
            let (render, mask) = scene(w, h, area);
            for sigma in [0.4, 0.6, 1.0, 1.5] {
                let real = gaussian_blur(&render, w, h, sigma);
                let m = measured(&real, &render, &mask, w, h);
                assert!((m.sigma_px - sigma).abs() < 0.03, "{area} {sigma}: {m:?}");
            }
            let m = measured(&render, &render, &mask, w, h);
            assert!(m.sigma_px < 0.01, "{m:?}");
        }
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
        let (render, mask) = scene(w, h, true);
        for (gain, offset) in [(0.76, -0.045), (1.0, -0.02), (2.2, 0.0)] {
            let real = exposed(&gaussian_blur(&render, w, h, 1.5), gain, offset);
            let m = measured(&real, &render, &mask, w, h);
            assert!((m.sigma_px - 1.5).abs() < 0.1, "{gain} {offset}: {m:?}");
        }
    }

    #[test]
    fn a_lit_background_is_no_witness_and_a_lifted_black_one_is() {
        let (w, h) = (256, 96);
        let (render, mask) = scene(w, h, true);
        let blurred = |s: f64| gaussian_blur(&render, w, h, s);
        let skyline_of = |real: &[f32]| {
            let views = [EdgeView {
                real,
                mask: &mask,
                w,
                h,
                render: &blurred,
            }];
            let s = Skyline::sample(&views);
            (s.measure(&|_| true).map(|m| m.sigma_px), s.lit_views)
        };
        // A lit rim beyond the terrain (40 DN with a texture of its own): no witness.
        let lit: Vec<f32> = render
            .iter()
            .zip(&mask)
            .enumerate()
            .map(|(i, (v, m))| if *m { *v } else { 40.0 + (i % 7) as f32 })
            .collect();
        assert_eq!(skyline_of(&gaussian_blur(&lit, w, h, 1.0)), (None, 1));
        // A black background lifted by an exposure offset within the catalogue: measured.
        let lifted = exposed(&gaussian_blur(&render, w, h, 1.0), 1.0, 0.04);
        let (sigma, lit_views) = skyline_of(&lifted);
        assert_eq!(lit_views, 0);
        assert!((sigma.unwrap() - 1.0).abs() < 0.1, "{sigma:?}");
    }

    #[test]
    fn the_width_is_matched_in_variance_to_the_root() {
        // Edge variances that add: w(σ)² = 0.2 + 1.3 σ².
        let width = |s: f64| (0.2 + 1.3 * s * s).sqrt();
        for sigma in [0.05, 0.5, 1.7, 3.9] {
            let got = match_width(width(sigma), width(0.0), &width);
            assert!((got - sigma).abs() < 0.002, "{sigma}: {got}");
        }
        assert_eq!(match_width(0.3, width(0.0), &width), 0.0);
        assert_eq!(match_width(width(9.0), width(0.0), &width), MAX_SIGMA_PX);
    }
}
