//! The sensor: exposure, fixed patterns (PRNU, DSNU, column FPN), photon shot noise, black
//! level, read noise, the response curve and 8-bit quantisation (steps 4–7).
//!
//! Randomness is drawn per row from `ChaCha8Rng`s seeded by
//! [`item_rng`]`(seed, stage, row)`, so the bytes never depend on the
//! thread count: the fixed patterns use `fixed_seed` (stages `camera.prnu`, `camera.dsnu`,
//! `camera.column-fpn`), the temporal noise `frame_seed` (stage `camera.temporal`).

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use rayon::prelude::*;

use super::{CameraPhysics, HiddenOptics};
use crate::seeding::item_rng;

/// Full scale: normalised signal 1.0 is this many DN.
pub const FULL_SCALE_DN: f64 = 255.0;

/// Above this mean (electrons) a Poisson draw uses the normal approximation rounded to the
/// nearest integer (continuity); below it is exact.
pub const POISSON_NORMAL_ABOVE: f64 = 1000.0;

/// The camera's fixed patterns: identical in every frame of one `fixed_seed`.
#[derive(Debug, Clone)]
pub struct FixedPattern {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Per-pixel relative response `1 + prnu_sigma·N(0,1)` (row-major).
    pub prnu: Vec<f32>,
    /// Per-pixel dark offset, DN (`dsnu_sigma_dn·N(0,1)`).
    pub dsnu: Vec<f32>,
    /// Per-column offset, DN (`column_fpn_sigma_dn·N(0,1)`).
    pub column: Vec<f32>,
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

impl FixedPattern {
    /// Draws the patterns of a `width × height` sensor from `fixed_seed`.
    pub fn new(physics: &CameraPhysics, width: usize, height: usize, fixed_seed: u64) -> Self {
        let draw = |stage: &'static str, sigma: f64, base: f64| -> Vec<f32> {
            let rows: Vec<Vec<f32>> = (0..height)
                .into_par_iter()
                .map(|row| {
                    let mut rng = item_rng(fixed_seed, stage, row as u64);
                    (0..width)
                        .map(|_| (base + sigma * normal(&mut rng)) as f32)
                        .collect()
                })
                .collect();
            rows.concat()
        };
        let prnu = draw("camera.prnu", physics.prnu_sigma, 1.0);
        let dsnu = draw("camera.dsnu", physics.dsnu_sigma_dn, 0.0);
        let mut rng = item_rng(fixed_seed, "camera.column-fpn", 0);
        let column = (0..width)
            .map(|_| (physics.column_fpn_sigma_dn * normal(&mut rng)) as f32)
            .collect();
        FixedPattern {
            width,
            height,
            prnu,
            dsnu,
            column,
        }
    }
}

/// A Poisson draw of mean `lambda` (0 for a non-positive or non-finite mean).
pub fn poisson(rng: &mut ChaCha8Rng, lambda: f64) -> f64 {
    if !(lambda.is_finite() && lambda > 0.0) {
        return 0.0;
    }
    if lambda > POISSON_NORMAL_ABOVE {
        return (lambda + lambda.sqrt() * normal(rng)).round().max(0.0);
    }
    match Poisson::new(lambda) {
        Ok(p) => p.sample(rng),
        Err(_) => 0.0,
    }
}

/// The response curve (hidden `gamma`) and quantisation of one DN value: the DN normalised by
/// [`FULL_SCALE_DN`], clipped to [0, 1], raised to `1/γ`, rounded to 8 bits.
pub fn respond(dn: f64, gamma: Option<f64>) -> u8 {
    let x = if dn.is_finite() {
        (dn / FULL_SCALE_DN).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let y = match gamma {
        Some(g) if g.is_finite() && g > 0.0 => x.powf(1.0 / g),
        _ => x,
    };
    (y * FULL_SCALE_DN).round().clamp(0.0, 255.0) as u8
}

/// Steps 4–7 on one row of sensor irradiance (radiance units) → 8-bit pixels.
pub fn sensor_row(
    irradiance: &[f32],
    row: usize,
    pattern: &FixedPattern,
    physics: &CameraPhysics,
    hidden: &HiddenOptics,
    frame_seed: u64,
) -> Vec<u8> {
    let (g, o) = hidden.exposure.unwrap_or((1.0, 0.0));
    let (gain, read_sigma) = hidden.noise;
    let mut rng = item_rng(frame_seed, "camera.temporal", row as u64);
    let base = row * pattern.width;
    irradiance
        .iter()
        .enumerate()
        .map(|(col, &r)| {
            let at = |v: &[f32], i: usize, d: f32| f64::from(v.get(i).copied().unwrap_or(d));
            // 4. Exposure.
            let signal = FULL_SCALE_DN * (g * f64::from(r) + o);
            // 5. PRNU, shot noise, dark offsets, black level, read noise.
            let mean = (signal * at(&pattern.prnu, base + col, 1.0)).max(0.0);
            let shot = if gain > 0.0 && gain.is_finite() {
                poisson(&mut rng, mean / gain) * gain
            } else {
                mean
            };
            let read = if read_sigma > 0.0 {
                read_sigma * normal(&mut rng)
            } else {
                0.0
            };
            let dn = shot
                + at(&pattern.dsnu, base + col, 0.0)
                + at(&pattern.column, col, 0.0)
                + physics.black_level_dn
                + read;
            // 6–7. Response and quantisation.
            respond(dn, hidden.gamma)
        })
        .collect()
}
