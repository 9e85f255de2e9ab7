//! SIFT (Lowe 2004) detector and 128-d descriptor, following OpenCV's `SIFT` step by step.
//!
//! Scale space: the image (in 0..255 so thresholds are OpenCV's) is doubled with bilinear
//! interpolation, blurred to `σ = 1.6` assuming a camera blur of 0.5 px, and split into
//! octaves of `n + 3` Gaussian layers (`n = 3` scales per octave); octaves are decimated by
//! taking every second pixel. Extrema of the difference of Gaussians over 3×3×3 neighbours
//! (`≥`/`≤`, above a pre-threshold `⌊0.5·0.04/n·255⌋`) are refined by up to five Newton
//! steps, kept if `|D| · n ≥ contrast_threshold` and `tr²/det < (r + 1)²/r` with
//! `r = edge_threshold`, then given one keypoint per orientation-histogram peak above 80 % of
//! the maximum (36 bins, Gaussian window 1.5σ, parabolic peak fit).
//!
//! One deliberate difference from OpenCV: OpenCV maps positions in the doubled image back by
//! halving them, which shifts every keypoint by a quarter pixel; we use the exact inverse of
//! the bilinear doubling, `x = x₂ / 2 − 0.25`, so positions follow the pixel-centre convention.
//!
//! Each octave's layers are built in order (each blurs the previous one) with row-parallel
//! filters; extrema are searched row-parallel and sorted at the end, so output does not
//! depend on thread count.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::image::{decimate2, gaussian_blur, upsample2, GreyF32};
use super::keypoint::{sort_keypoints, Keypoint};

/// SIFT parameters; defaults are OpenCV's `SIFT::create()`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SiftParams {
    /// Scales per octave (OpenCV `nOctaveLayers`, 3).
    pub octave_layers: usize,
    /// Contrast threshold on `|D| · octave_layers` with `D` in `[0, 1]` units (0.04).
    pub contrast_threshold: f32,
    /// Edge threshold `r` of the principal-curvature test (10).
    pub edge_threshold: f32,
    /// Blur of the base layer, px (1.6).
    pub sigma: f64,
    /// Double the image first (OpenCV's `firstOctave = -1`; default true).
    pub upscale: bool,
    /// Keep only the strongest N keypoints; 0 = all (OpenCV `nfeatures`, 0).
    pub max_features: usize,
}

impl Default for SiftParams {
    fn default() -> Self {
        SiftParams {
            octave_layers: 3,
            contrast_threshold: 0.04,
            edge_threshold: 10.0,
            sigma: 1.6,
            upscale: true,
            max_features: 0,
        }
    }
}

/// Pixels ignored at each octave's border.
const BORDER: usize = 5;
/// Newton steps allowed when refining an extremum.
const MAX_INTERP_STEPS: usize = 5;
/// Orientation histogram bins.
const ORI_BINS: usize = 36;
/// Orientation window σ as a multiple of the keypoint scale.
const ORI_SIG_FCTR: f32 = 1.5;
/// Peaks above this fraction of the maximum get their own keypoint.
const ORI_PEAK_RATIO: f32 = 0.8;
/// Descriptor: 4×4 cells of 8 bins.
const DESCR_WIDTH: usize = 4;
const DESCR_BINS: usize = 8;
/// Descriptor cell width as a multiple of the keypoint scale.
const DESCR_SCL_FCTR: f32 = 3.0;
/// Clipping of normalised descriptor entries.
const DESCR_MAG_THR: f32 = 0.2;
/// Final descriptor scaling (values then round to 0..=255 like OpenCV's).
const INT_DESCR_FCTR: f32 = 512.0;

/// The Gaussian and DoG pyramids.
pub struct ScaleSpace {
    /// `gauss[o][i]`, `i` in `0..n + 3`.
    pub gauss: Vec<Vec<GreyF32>>,
    /// `dog[o][i] = gauss[o][i + 1] − gauss[o][i]`.
    pub dog: Vec<Vec<GreyF32>>,
    /// `-1` when the base is the doubled image, else 0.
    pub first_octave: i32,
}

/// Builds the scale space (see the module docs); empty for images too small to hold one.
pub fn scale_space(img: &GreyF32, p: &SiftParams) -> ScaleSpace {
    let n = p.octave_layers.max(1);
    let first_octave = if p.upscale { -1 } else { 0 };
    let empty = ScaleSpace {
        gauss: Vec::new(),
        dog: Vec::new(),
        first_octave,
    };
    if img.is_degenerate() {
        return empty;
    }
    let mut base = img.scaled(255.0);
    let assumed = if p.upscale {
        base = upsample2(&base);
        1.0
    } else {
        0.5
    };
    let base_blur = (p.sigma * p.sigma - assumed * assumed).max(0.01).sqrt();
    base = gaussian_blur(&base, base_blur);
    let min_side = base.width.min(base.height) as f64;
    let octaves = ((min_side.log2() - 2.0).round() as i64).max(0) as usize;
    let k = 2f64.powf(1.0 / n as f64);
    let sig: Vec<f64> = (0..n + 3)
        .map(|i| {
            if i == 0 {
                p.sigma
            } else {
                let prev = k.powi(i as i32 - 1) * p.sigma;
                ((prev * k).powi(2) - prev * prev).sqrt()
            }
        })
        .collect();
    let mut gauss: Vec<Vec<GreyF32>> = Vec::new();
    for o in 0..octaves {
        let first = match gauss.last().and_then(|prev| prev.get(n)) {
            Some(prev) if o > 0 => decimate2(prev),
            _ => base.clone(),
        };
        if first.width == 0 || first.height == 0 {
            break;
        }
        let mut layers = vec![first];
        for s in sig.iter().skip(1) {
            let next = layers.last().map(|l| gaussian_blur(l, *s));
            layers.extend(next);
        }
        gauss.push(layers);
    }
    let dog = gauss
        .iter()
        .map(|layers| {
            layers
                .windows(2)
                .map(|w| match w {
                    [a, b] => GreyF32 {
                        width: a.width,
                        height: a.height,
                        data: b.data.par_iter().zip(&a.data).map(|(y, x)| y - x).collect(),
                    },
                    _ => GreyF32::zeros(0, 0),
                })
                .collect()
        })
        .collect();
    ScaleSpace {
        gauss,
        dog,
        first_octave,
    }
}

/// SIFT keypoints (see the module docs).
pub fn detect_sift(img: &GreyF32, p: &SiftParams) -> Vec<Keypoint> {
    let ss = scale_space(img, p);
    find_keypoints(&ss, p)
}

/// SIFT keypoints and their descriptors from one scale space.
pub fn detect_and_describe_sift(img: &GreyF32, p: &SiftParams) -> (Vec<Keypoint>, Vec<Vec<f32>>) {
    let ss = scale_space(img, p);
    let kps = find_keypoints(&ss, p);
    let desc = describe_in(&ss, &kps, p);
    (kps, desc)
}

/// 128-d SIFT descriptors of given keypoints (keypoints from [`detect_sift`]).
pub fn describe_sift(img: &GreyF32, kps: &[Keypoint], p: &SiftParams) -> Vec<Vec<f32>> {
    let ss = scale_space(img, p);
    describe_in(&ss, kps, p)
}

fn find_keypoints(ss: &ScaleSpace, p: &SiftParams) -> Vec<Keypoint> {
    let n = p.octave_layers.max(1);
    let threshold = (0.5 * p.contrast_threshold / n as f32 * 255.0).floor();
    let tasks: Vec<(usize, usize)> = (0..ss.dog.len())
        .flat_map(|o| (1..=n).map(move |l| (o, l)))
        .collect();
    let mut kps: Vec<Keypoint> = tasks
        .into_par_iter()
        .flat_map_iter(|(o, l)| {
            let dogs = ss.dog.get(o).map(Vec::as_slice).unwrap_or(&[]);
            let h = dogs.first().map_or(0, |d| d.height);
            let rows = BORDER..h.saturating_sub(BORDER);
            rows.flat_map(move |r| {
                extrema_in_row(dogs, l, r, threshold)
                    .into_iter()
                    .map(move |c| (r, c))
            })
            .flat_map(move |(r, c)| refine(ss, o, l, r, c, p))
            .collect::<Vec<_>>()
        })
        .collect();
    sort_keypoints(&mut kps);
    kps.dedup_by(|a, b| a.x == b.x && a.y == b.y && a.size == b.size && a.angle == b.angle);
    if p.max_features > 0 {
        kps.truncate(p.max_features);
    }
    kps
}

#[inline]
fn px(d: &[GreyF32], l: usize, r: usize, c: usize) -> f32 {
    d.get(l).map(|im| im.at(c, r)).unwrap_or(0.0)
}

/// Columns `c` of row `r` in layer `l` where the DoG value `v` has `|v| > threshold` and is
/// `≥` (or `≤`) all 26 neighbours in the 3×3×3 block, `BORDER` pixels from the sides.
fn extrema_in_row(d: &[GreyF32], l: usize, r: usize, threshold: f32) -> Vec<usize> {
    let row = |ll: usize, rr: usize| d.get(ll).map(|im| im.row(rr)).unwrap_or(&[]);
    let centre = row(l, r);
    let w = centre.len();
    // The nine rows of the block, the centre's first (its neighbours reject most candidates):
    // layers l-1..=l+1 × rows r-1..=r+1; a missing row reads as zeros.
    let rows: [&[f32]; 9] =
        std::array::from_fn(|i| row(l + (i + 4) % 9 / 3 - 1, r + (i + 4) % 9 % 3 - 1));
    let zeros = if rows.iter().any(|s| s.len() != w) {
        vec![0.0; w]
    } else {
        Vec::new()
    };
    let block = rows.map(|s| if s.len() == w { s } else { zeros.as_slice() });
    let mut found = Vec::new();
    for c in BORDER..w.saturating_sub(BORDER) {
        let Some(&v) = centre.get(c) else {
            continue;
        };
        if v.is_nan() || v.abs() <= threshold {
            continue;
        }
        let extremum = if v > 0.0 {
            block_all(&block, c, |u| v >= u)
        } else {
            block_all(&block, c, |u| v <= u)
        };
        if extremum {
            found.push(c);
        }
    }
    found
}

/// Whether `keeps` holds for columns `c - 1..=c + 1` of every row of `block`.
#[inline(always)]
fn block_all(block: &[&[f32]; 9], c: usize, keeps: impl Fn(f32) -> bool) -> bool {
    block.iter().all(|s| {
        s.get(c - 1..c + 2)
            .is_some_and(|t| t.iter().all(|&u| keeps(u)))
    })
}

/// Solves the 3×3 system `a x = b` (Cramer's rule in `f64`); zeros if singular.
pub(super) fn solve3(a: [[f32; 3]; 3], b: [f32; 3]) -> [f32; 3] {
    let m = a.map(|r| r.map(f64::from));
    let v = b.map(f64::from);
    let det3 = |[[a, b, c], [d, e, f], [g, h, i]]: [[f64; 3]; 3]| {
        a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    };
    let det = det3(m);
    if det.abs() < 1e-30 || !det.is_finite() {
        return [0.0; 3];
    }
    let column = |k: usize| {
        let mut c = m;
        for (row, &vi) in c.iter_mut().zip(&v) {
            if let Some(x) = row.get_mut(k) {
                *x = vi;
            }
        }
        (det3(c) / det) as f32
    };
    [column(0), column(1), column(2)]
}

/// Gradient and Hessian of the DoG at `(l, r, c)` in `[0, 1]` units.
fn derivatives(d: &[GreyF32], l: usize, r: usize, c: usize) -> ([f32; 3], [[f32; 3]; 3]) {
    let s = 1.0 / 255.0;
    let g = |ll: usize, rr: usize, cc: usize| px(d, ll, rr, cc);
    let v2 = 2.0 * g(l, r, c);
    let grad = [
        (g(l, r, c + 1) - g(l, r, c - 1)) * 0.5 * s,
        (g(l, r + 1, c) - g(l, r - 1, c)) * 0.5 * s,
        (g(l + 1, r, c) - g(l - 1, r, c)) * 0.5 * s,
    ];
    let dxx = (g(l, r, c + 1) + g(l, r, c - 1) - v2) * s;
    let dyy = (g(l, r + 1, c) + g(l, r - 1, c) - v2) * s;
    let dss = (g(l + 1, r, c) + g(l - 1, r, c) - v2) * s;
    let q = 0.25 * s;
    let dxy =
        (g(l, r + 1, c + 1) - g(l, r + 1, c - 1) - g(l, r - 1, c + 1) + g(l, r - 1, c - 1)) * q;
    let dxs =
        (g(l + 1, r, c + 1) - g(l + 1, r, c - 1) - g(l - 1, r, c + 1) + g(l - 1, r, c - 1)) * q;
    let dys =
        (g(l + 1, r + 1, c) - g(l + 1, r - 1, c) - g(l - 1, r + 1, c) + g(l - 1, r - 1, c)) * q;
    (grad, [[dxx, dxy, dxs], [dxy, dyy, dys], [dxs, dys, dss]])
}

/// Newton refinement, contrast and edge tests, then orientation assignment; 0..n keypoints.
fn refine(
    ss: &ScaleSpace,
    o: usize,
    l0: usize,
    r0: usize,
    c0: usize,
    p: &SiftParams,
) -> Vec<Keypoint> {
    let n = p.octave_layers.max(1);
    let d = ss.dog.get(o).map(Vec::as_slice).unwrap_or(&[]);
    let (w, h) = d
        .first()
        .map(|im| (im.width as i64, im.height as i64))
        .unwrap_or((0, 0));
    let (mut l, mut r, mut c) = (l0 as i64, r0 as i64, c0 as i64);
    let mut x = [0.0f32; 3];
    let mut converged = false;
    for _ in 0..MAX_INTERP_STEPS {
        let (grad, hess) = derivatives(d, l as usize, r as usize, c as usize);
        let sol = solve3(hess, grad);
        x = [-sol[0], -sol[1], -sol[2]];
        if x.iter().all(|v| v.abs() < 0.5) {
            converged = true;
            break;
        }
        if x.iter()
            .any(|v| !v.is_finite() || v.abs() > (i32::MAX / 3) as f32)
        {
            return Vec::new();
        }
        c += x[0].round() as i64;
        r += x[1].round() as i64;
        l += x[2].round() as i64;
        let b = BORDER as i64;
        if l < 1 || l > n as i64 || c < b || c >= w - b || r < b || r >= h - b {
            return Vec::new();
        }
    }
    if !converged {
        return Vec::new();
    }
    let (l, r, c) = (l as usize, r as usize, c as usize);
    let (grad, hess) = derivatives(d, l, r, c);
    let t: f32 = grad.iter().zip(&x).map(|(g, v)| g * v).sum();
    let contr = px(d, l, r, c) / 255.0 + t * 0.5;
    if contr.abs() * (n as f32) < p.contrast_threshold {
        return Vec::new();
    }
    let (dxx, dyy, dxy) = (hess[0][0], hess[1][1], hess[0][1]);
    let (tr, det) = (dxx + dyy, dxx * dyy - dxy * dxy);
    let e = p.edge_threshold;
    if det <= 0.0 || tr * tr * e >= (e + 1.0) * (e + 1.0) * det {
        return Vec::new();
    }
    let scale = (1u64 << o) as f32;
    let size_oct = p.sigma as f32 * 2f32.powf((l as f32 + x[2]) / n as f32) * 2.0;
    let (xb, yb) = ((c as f32 + x[0]) * scale, (r as f32 + x[1]) * scale);
    let (xo, yo, size, octave) = if ss.first_octave < 0 {
        (
            xb * 0.5 - 0.25,
            yb * 0.5 - 0.25,
            size_oct * scale * 0.5,
            o as i32 - 1,
        )
    } else {
        (xb, yb, size_oct * scale, o as i32)
    };
    let Some(img) = ss.gauss.get(o).and_then(|g| g.get(l)) else {
        return Vec::new();
    };
    let scl = size_oct * 0.5;
    let hist = orientation_hist(img, c, r, (4.5 * scl).round() as i64, ORI_SIG_FCTR * scl);
    let omax = hist.iter().copied().fold(0.0f32, f32::max);
    let mag_thr = omax * ORI_PEAK_RATIO;
    let nb = ORI_BINS;
    (0..nb)
        .filter_map(|j| {
            let hl = hist.get((j + nb - 1) % nb).copied().unwrap_or(0.0);
            let hr = hist.get((j + 1) % nb).copied().unwrap_or(0.0);
            let hj = hist.get(j).copied().unwrap_or(0.0);
            if !(hj > hl && hj > hr && hj >= mag_thr) {
                return None;
            }
            let mut bin = j as f32 + 0.5 * (hl - hr) / (hl - 2.0 * hj + hr);
            if bin < 0.0 {
                bin += nb as f32;
            } else if bin >= nb as f32 {
                bin -= nb as f32;
            }
            let mut angle = 360.0 - (360.0 / nb as f32) * bin;
            if (angle - 360.0).abs() < f32::EPSILON {
                angle = 0.0;
            }
            Some(Keypoint {
                x: xo,
                y: yo,
                size,
                angle,
                response: contr.abs(),
                octave,
            })
        })
        .collect()
}

/// Gradient at an interior pixel: `(dx, dy)` with `dy` pointing up, as OpenCV's SIFT.
#[inline]
fn grad(img: &GreyF32, x: usize, y: usize) -> (f32, f32) {
    (
        img.at(x + 1, y) - img.at(x - 1, y),
        img.at(x, y - 1) - img.at(x, y + 1),
    )
}

/// Degrees in `[0, 360)` of the vector `(x, y)`, within 0.015° (a degree-7 odd minimax
/// polynomial for `atan` on `[0, 1]` and the octant symmetries, the approximation OpenCV's
/// SIFT uses too); an order of magnitude faster than `atan2`, which dominated the
/// orientation histograms.
#[inline]
fn degrees(y: f32, x: f32) -> f32 {
    const P1: f32 = 0.999_787_8 * 180.0 / std::f32::consts::PI;
    const P3: f32 = -0.325_808_4 * 180.0 / std::f32::consts::PI;
    const P5: f32 = 0.155_578_65 * 180.0 / std::f32::consts::PI;
    const P7: f32 = -0.044_326_556 * 180.0 / std::f32::consts::PI;
    let (ax, ay) = (x.abs(), y.abs());
    let poly = |c: f32| {
        let c2 = c * c;
        (((P7 * c2 + P5) * c2 + P3) * c2 + P1) * c
    };
    let mut a = if ax >= ay {
        poly(ay / (ax + f32::EPSILON))
    } else {
        90.0 - poly(ax / (ay + f32::EPSILON))
    };
    if x < 0.0 {
        a = 180.0 - a;
    }
    if y < 0.0 {
        a = 360.0 - a;
    }
    if a >= 360.0 {
        a - 360.0
    } else {
        a
    }
}

/// `x.round() as i64` (half away from zero) for `|x| < 2^31`, inlined: `f32::round` is a
/// library call on baseline x86-64. The fraction `x − trunc(x)` is exact in `f32`.
#[inline]
fn round_i64(x: f32) -> i64 {
    let t = x as i64;
    let f = x - t as f32;
    t + i64::from(f >= 0.5) - i64::from(f <= -0.5)
}

/// `x.floor() as i64` for `|x| < 2^31`, inlined (see [`round_i64`]).
#[inline]
fn floor_i64(x: f32) -> i64 {
    let t = x as i64;
    t - i64::from((t as f32) > x)
}

/// Smoothed 36-bin orientation histogram around `(x, y)`.
fn orientation_hist(img: &GreyF32, x: usize, y: usize, radius: i64, sigma: f32) -> [f32; ORI_BINS] {
    let nb = ORI_BINS;
    let mut raw = [0.0f32; ORI_BINS];
    let expf_scale = -1.0 / (2.0 * sigma * sigma);
    let (w, h) = (img.width as i64, img.height as i64);
    // exp(−(i² + j²)/2σ²) = exp(−i²/2σ²)·exp(−j²/2σ²): one exp per offset, not per pixel.
    let weights: Vec<f32> = (-radius..=radius)
        .map(|i| ((i * i) as f32 * expf_scale).exp())
        .collect();
    let weight = |i: i64| weights.get((i + radius) as usize).copied().unwrap_or(0.0);
    for i in -radius..=radius {
        let yy = y as i64 + i;
        if yy <= 0 || yy >= h - 1 {
            continue;
        }
        for j in -radius..=radius {
            let xx = x as i64 + j;
            if xx <= 0 || xx >= w - 1 {
                continue;
            }
            let (dx, dy) = grad(img, xx as usize, yy as usize);
            let weight = weight(i) * weight(j);
            let mag = (dx * dx + dy * dy).sqrt();
            let mut bin = round_i64((nb as f32 / 360.0) * degrees(dy, dx));
            bin = bin.rem_euclid(nb as i64);
            if let Some(b) = raw.get_mut(bin as usize) {
                *b += weight * mag;
            }
        }
    }
    let g = |k: i64| {
        raw.get(k.rem_euclid(nb as i64) as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let mut hist = [0.0f32; ORI_BINS];
    for (k, out) in hist.iter_mut().enumerate() {
        let k = k as i64;
        *out = (g(k - 2) + g(k + 2)) * (1.0 / 16.0)
            + (g(k - 1) + g(k + 1)) * (4.0 / 16.0)
            + g(k) * (6.0 / 16.0);
    }
    hist
}

fn describe_in(ss: &ScaleSpace, kps: &[Keypoint], p: &SiftParams) -> Vec<Vec<f32>> {
    let n = p.octave_layers.max(1) as f32;
    kps.par_iter()
        .map(|kp| {
            let o = (kp.octave - ss.first_octave).max(0) as usize;
            let to_oct = 2f32.powi(-(kp.octave - ss.first_octave));
            let (xb, yb) = if ss.first_octave < 0 {
                (kp.x * 2.0 + 0.5, kp.y * 2.0 + 0.5)
            } else {
                (kp.x, kp.y)
            };
            // Size in the octave's own pixels (for a doubled base, octave −1 is the base).
            let size_oct = kp.size * 2f32.powi(-kp.octave);
            let layer = (n * (size_oct / (2.0 * p.sigma as f32)).log2())
                .round()
                .clamp(1.0, n) as usize;
            match ss.gauss.get(o).and_then(|g| g.get(layer)) {
                Some(img) => {
                    let mut angle = 360.0 - kp.angle;
                    if (angle - 360.0).abs() < f32::EPSILON {
                        angle = 0.0;
                    }
                    descriptor(img, xb * to_oct, yb * to_oct, angle, size_oct * 0.5)
                }
                None => vec![0.0; DESCR_WIDTH * DESCR_WIDTH * DESCR_BINS],
            }
        })
        .collect()
}

/// OpenCV's `calcSIFTDescriptor`: 4×4×8 trilinear histogram, clip at 0.2, scale to 0..255.
fn descriptor(img: &GreyF32, ptx: f32, pty: f32, ori: f32, scl: f32) -> Vec<f32> {
    let (d, nb) = (DESCR_WIDTH, DESCR_BINS);
    let (px0, py0) = (ptx.round() as i64, pty.round() as i64);
    let (cos_t, sin_t) = (ori.to_radians().cos(), ori.to_radians().sin());
    let bins_per_deg = nb as f32 / 360.0;
    let exp_scale = -1.0 / (d as f32 * d as f32 * 0.5);
    let hist_width = DESCR_SCL_FCTR * scl;
    let (w, h) = (img.width as i64, img.height as i64);
    let diag = ((w * w + h * h) as f64).sqrt() as i64;
    let radius =
        ((hist_width * std::f32::consts::SQRT_2 * (d as f32 + 1.0) * 0.5).round() as i64).min(diag);
    let (cos_t, sin_t) = (cos_t / hist_width, sin_t / hist_width);
    // The rotation keeps lengths, so the window exp(−(c_rot² + r_rot²)/(d²/2)) is
    // exp(−(i² + j²)/(d² hist_width²/2)): one exp per offset, not per pixel.
    let weights: Vec<f32> = (-radius..=radius)
        .map(|i| ((i * i) as f32 / (hist_width * hist_width) * exp_scale).exp())
        .collect();
    let weight = |i: i64| weights.get((i + radius) as usize).copied().unwrap_or(0.0);
    let stride_c = nb + 2;
    let stride_r = (d + 2) * stride_c;
    let mut hist = vec![0.0f32; (d + 2) * stride_r];
    for i in -radius..=radius {
        for j in -radius..=radius {
            let c_rot = j as f32 * cos_t - i as f32 * sin_t;
            let r_rot = j as f32 * sin_t + i as f32 * cos_t;
            let rbin = r_rot + d as f32 / 2.0 - 0.5;
            let cbin = c_rot + d as f32 / 2.0 - 0.5;
            let (r, c) = (py0 + i, px0 + j);
            if !(rbin > -1.0
                && rbin < d as f32
                && cbin > -1.0
                && cbin < d as f32
                && r > 0
                && r < h - 1
                && c > 0
                && c < w - 1)
            {
                continue;
            }
            let (dx, dy) = grad(img, c as usize, r as usize);
            let mag = (dx * dx + dy * dy).sqrt() * weight(i) * weight(j);
            let obin = (degrees(dy, dx) - ori) * bins_per_deg;
            let (r0, c0, o0) = (floor_i64(rbin), floor_i64(cbin), floor_i64(obin));
            let (fr, fc, fo) = (rbin - r0 as f32, cbin - c0 as f32, obin - o0 as f32);
            let o0 = o0.rem_euclid(nb as i64) as usize;
            let (r0, c0) = ((r0 + 1) as usize, (c0 + 1) as usize);
            let v_r1 = mag * fr;
            let v_r0 = mag - v_r1;
            for (dr, vr) in [(0, v_r0), (1, v_r1)] {
                let v_c1 = vr * fc;
                for (dc, vc) in [(0, vr - v_c1), (1, v_c1)] {
                    let v_o1 = vc * fo;
                    let base = (r0 + dr) * stride_r + (c0 + dc) * stride_c + o0;
                    for (k, v) in [(0, vc - v_o1), (1, v_o1)] {
                        if let Some(b) = hist.get_mut(base + k) {
                            *b += v;
                        }
                    }
                }
            }
        }
    }
    let mut out = vec![0.0f32; d * d * nb];
    for i in 0..d {
        for j in 0..d {
            let base = (i + 1) * stride_r + (j + 1) * stride_c;
            let cell: Vec<f32> = hist
                .get(base..base + nb + 2)
                .map(<[f32]>::to_vec)
                .unwrap_or_default();
            for k in 0..nb {
                let wrapped = if k < 2 {
                    cell.get(nb + k).copied().unwrap_or(0.0)
                } else {
                    0.0
                };
                if let Some(o) = out.get_mut((i * d + j) * nb + k) {
                    *o = cell.get(k).copied().unwrap_or(0.0) + wrapped;
                }
            }
        }
    }
    let norm = out.iter().map(|v| v * v).sum::<f32>().sqrt();
    let thr = norm * DESCR_MAG_THR;
    out.iter_mut().for_each(|v| *v = v.min(thr));
    let norm = out.iter().map(|v| v * v).sum::<f32>().sqrt();
    let k = INT_DESCR_FCTR / norm.max(f32::EPSILON);
    out.iter_mut()
        .for_each(|v| *v = (*v * k).round().clamp(0.0, 255.0));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_degrees_is_within_0_015_degree_of_atan2() {
        let mut worst = 0.0f32;
        for k in 0..20_000 {
            let t = k as f32 * 0.000_314_159_27;
            for r in [1e-3f32, 1.0, 250.0] {
                let (x, y) = (r * t.cos(), r * t.sin());
                let want = y.atan2(x).to_degrees().rem_euclid(360.0);
                let got = degrees(y, x);
                assert!((0.0..360.0).contains(&got), "{got} at ({x}, {y})");
                let err = (got - want).abs();
                worst = worst.max(err.min(360.0 - err));
            }
        }
        assert!(worst < 0.015, "worst error {worst}°");
        assert_eq!(degrees(0.0, 0.0), 0.0);
    }

    #[test]
    fn inline_round_and_floor_match_std() {
        let mut v: Vec<f32> = (-2000..=2000).map(|k| k as f32 * 0.25).collect();
        v.extend([0.5f32, -0.5, 0.49999997, -0.49999997, 1e9, -1e9, 2.5, -2.5]);
        for x in v {
            assert_eq!(round_i64(x), x.round() as i64, "round {x}");
            assert_eq!(floor_i64(x), x.floor() as i64, "floor {x}");
        }
    }
}
