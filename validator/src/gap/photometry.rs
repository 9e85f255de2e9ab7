//! Stage 2 of attribution: the photometric effects `exposure`, `vignetting`, `gamma` and `blur`
//! fitted jointly, with and without `shadows`.
//!
//! The model of a real pixel is the camera's, in its physical order (see
//! [`crate::sensor::image`]): `DN = 255 · max(0, g · V_s(u, v) · (B_σ ∗ R) + o)^(1/γ)`, with `R` the
//! rendered radiance (with or without cast shadows), `V_s` the vignetting falloff of strength
//! `s`, `B_σ` the Gaussian PSF. Vignetting is smooth, so `B_σ ∗ (V R) ≈ V (B_σ ∗ R)`; the
//! blurred radiance is precomputed at σ = 0, 0.25, … 3 px and interpolated linearly in σ, which
//! makes σ an ordinary parameter of the joint least-squares fit (blur and the response curve
//! masquerade as each other when fitted one at a time; here they are fitted together).
//!
//! Samples are taken on a regular grid inside the render's terrain mask eroded by 4 px (so a
//! silhouette misaligned by a few pixels does not count), where the real mean is neither black
//! nor saturated. The real side is the mean of the frames, so noise enters only as variance.

use crate::sensor::gaussian_blur;

use super::lsq::{solve, Problem};
use super::views::{GapView, Prediction};

/// σ grid of the precomputed blurs, px.
const SIGMA_STEP: f64 = 0.25;
const SIGMAS: usize = 13;
/// Sample grid stride, pixels.
const STRIDE: usize = 6;
const ERODE: usize = 4;

/// The photometric samples of one view.
#[derive(Debug, Clone, Default)]
pub struct Samples {
    /// Fold (capture index) of each sample.
    pub fold: Vec<usize>,
    /// Real mean DN.
    pub real: Vec<f64>,
    /// Blurred radiance at each σ of the grid, `SIGMAS` values per sample.
    pub radiance: Vec<[f64; SIGMAS]>,
    /// Vignetting factor at strength 0.5 (the falloff shape; other strengths are derived).
    pub rho2: Vec<f64>,
}

impl Samples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.real.len()
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.real.is_empty()
    }

    /// Appends the samples of one view.
    pub fn add(&mut self, fold: usize, v: &GapView, p: &Prediction) {
        let (w, h) = (v.width, v.height);
        let real = v.mean();
        let blurred: Vec<Vec<f32>> = (0..SIGMAS)
            .map(|i| gaussian_blur(&p.radiance, w, h, i as f64 * SIGMA_STEP))
            .collect();
        let eroded = erode(&p.mask, w, h, ERODE);
        let cam = &v.camera_model;
        let corner2 = [
            (0.0, 0.0),
            ((w - 1) as f64, 0.0),
            (0.0, (h - 1) as f64),
            ((w - 1) as f64, (h - 1) as f64),
        ]
        .iter()
        .map(|(x, y)| (x - cam.cx).powi(2) + (y - cam.cy).powi(2))
        .fold(1e-9f64, f64::max);
        for y in (0..h).step_by(STRIDE) {
            for x in (0..w).step_by(STRIDE) {
                let i = y * w + x;
                let r = f64::from(real[i]);
                if !eroded[i] || !(2.0..=253.0).contains(&r) {
                    continue;
                }
                let mut rad = [0.0; SIGMAS];
                for (k, b) in blurred.iter().enumerate() {
                    rad[k] = f64::from(b[i]);
                }
                self.fold.push(fold);
                self.real.push(r);
                self.radiance.push(rad);
                self.rho2
                    .push(((x as f64 - cam.cx).powi(2) + (y as f64 - cam.cy).powi(2)) / corner2);
            }
        }
    }
}

/// `mask` eroded by a square of half-side `r`.
pub fn erode(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let mut rows = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            rows[y * w + x] = (a..=b).all(|xx| mask[y * w + xx]);
        }
    }
    let mut out = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
            out[y * w + x] = (a..=b).all(|yy| rows[yy * w + x]);
        }
    }
    out
}

/// Parameters of the joint model, in this order.
pub const PARAMS: [&str; 5] = ["gain", "offset", "strength", "gamma", "sigma_px"];
/// Neutral values.
pub const NEUTRAL: [f64; 5] = [1.0, 0.0, 0.0, 1.0, 0.0];
const LOWER: [f64; 5] = [0.3, -0.2, 0.0, 0.5, 0.0];
const UPPER: [f64; 5] = [2.0, 0.2, 0.9, 3.5, 3.0];
const STEP: [f64; 5] = [1e-5, 1e-5, 1e-5, 1e-5, 1e-4];

/// The free parameters of a subset of {`exposure`, `vignetting`, `gamma`, `blur`}.
pub fn free(effects: &[&str]) -> Vec<usize> {
    let mut out = Vec::new();
    for (name, idx) in [
        ("exposure", &[0usize, 1][..]),
        ("vignetting", &[2]),
        ("gamma", &[3]),
        ("blur", &[4]),
    ] {
        if effects.contains(&name) {
            out.extend_from_slice(idx);
        }
    }
    out
}

/// Predicted DN of sample `i` at full parameters `p`.
pub fn predict(s: &Samples, i: usize, p: &[f64; 5]) -> f64 {
    let t = (p[4] / SIGMA_STEP).clamp(0.0, (SIGMAS - 1) as f64);
    let k = (t.floor() as usize).min(SIGMAS - 2);
    let f = t - k as f64;
    let rad = s.radiance[i][k] * (1.0 - f) + s.radiance[i][k + 1] * f;
    let strength = p[2].clamp(0.0, 0.999_999);
    let c = (1.0 - strength).powf(-0.5) - 1.0;
    let v = 1.0 / (1.0 + c * s.rho2[i]).powi(2);
    let e = (p[0] * v * rad + p[1]).max(0.0);
    255.0
        * if (p[3] - 1.0).abs() < 1e-12 {
            e
        } else {
            e.powf(1.0 / p[3])
        }
}

/// A fitted subset.
#[derive(Debug, Clone, PartialEq)]
pub struct PhotometricFit {
    /// Full parameter vector (inactive ones neutral).
    pub params: [f64; 5],
    /// Standard errors (inactive ones 0).
    pub std_err: [f64; 5],
    /// Mean squared error on the fitted samples, DN².
    pub mse: f64,
}

/// Fits the subset `effects` on the samples whose fold passes `use_fold`.
pub fn fit(
    s: &Samples,
    effects: &[&str],
    use_fold: &(dyn Fn(usize) -> bool + Sync),
) -> PhotometricFit {
    let idx = free(effects);
    let rows: Vec<usize> = (0..s.len()).filter(|&i| use_fold(s.fold[i])).collect();
    let expand = |q: &[f64]| {
        let mut p = NEUTRAL;
        for (&i, v) in idx.iter().zip(q) {
            p[i] = *v;
        }
        p
    };
    let f = |q: &[f64], out: &mut Vec<f64>| {
        let p = expand(q);
        out.clear();
        out.extend(rows.iter().map(|&i| predict(s, i, &p) - s.real[i]));
    };
    let sol = solve(
        &Problem {
            residuals: &f,
            start: idx.iter().map(|&i| NEUTRAL[i]).collect(),
            lower: idx.iter().map(|&i| LOWER[i]).collect(),
            upper: idx.iter().map(|&i| UPPER[i]).collect(),
            step: idx.iter().map(|&i| STEP[i]).collect(),
        },
        60,
    );
    let mut std_err = [0.0; 5];
    for (&i, e) in idx.iter().zip(&sol.std_err) {
        std_err[i] = *e;
    }
    PhotometricFit {
        params: expand(&sol.params),
        std_err,
        mse: sol.sse / sol.n.max(1) as f64,
    }
}

/// Mean squared error (DN²) at `p` on the samples whose fold passes `use_fold`.
pub fn mse(s: &Samples, p: &[f64; 5], use_fold: &dyn Fn(usize) -> bool) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for i in (0..s.len()).filter(|&i| use_fold(s.fold[i])) {
        sum += (predict(s, i, p) - s.real[i]).powi(2);
        n += 1;
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}
