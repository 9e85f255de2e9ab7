//! The image-side effects and their fixed physical order.
//!
//! 1. **Vignetting** (optics): radiance times [`vignetting_factor`].
//! 2. **Blur** (optics, PSF): Gaussian, `sigma_px`, edges replicated.
//! 3. **Exposure** (integration + black level): `e = gain * radiance + offset`; then
//!    `DN = 255 * e`. Without an exposure effect `DN = 255 * radiance`.
//! 4. **Noise** (sensor): `DN + N(0, gain * max(DN, 0) + read_sigma²)`, a `ChaCha8Rng` seeded
//!    with `seed`, pixels in row-major order (deterministic, single stream).
//! 5. **Gamma** (response): `DN = 255 * (max(DN, 0) / 255)^(1 / gamma)`.
//!
//! The output stays float and unclamped so fits see the exact model; [`quantise_u8`] makes
//! the 8-bit image.
//!
//! The vignetting model is the cos⁴ law of a pinhole, `f = 1 / (1 + c ρ²)²` with `ρ` the
//! distance from the principal point divided by the distance to the farthest image corner, and
//! `c = (1 - strength)^(-1/2) - 1` so that the farthest corner receives exactly
//! `1 - strength` of the centre's radiance. It is the falloff of an ideal lens whose corner
//! field angle has `tan² θ = c`, one parameter, monotone, and 1 at the principal point.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use regolith_format::camera_model::CameraModel;

use super::{gaussian_blur, Effect};

/// Full scale of the digital numbers.
const FULL_SCALE: f64 = 255.0;

/// Undoes the response curve and the black level of `effects` on digital numbers: the result
/// is proportional to the radiance reaching the sensor (exposure gain and vignetting are
/// factors and stay; blur and noise cannot be undone). Ratios of two images of one view are
/// then ratios of radiance.
pub fn undo_response(effects: &[Effect], dn: &[f32]) -> Vec<f32> {
    let mut img: Vec<f64> = dn.iter().map(|&v| f64::from(v)).collect();
    for e in effects.iter().rev() {
        if let Effect::Gamma { gamma } = *e {
            if gamma > 0.0 {
                img.iter_mut()
                    .for_each(|px| *px = FULL_SCALE * (px.max(0.0) / FULL_SCALE).powf(gamma));
            }
        }
    }
    for e in effects.iter().rev() {
        if let Effect::Exposure { offset, .. } = *e {
            img.iter_mut().for_each(|px| *px -= FULL_SCALE * offset);
        }
    }
    img.into_iter().map(|v| v as f32).collect()
}

/// Vignetting gain at pixel `(u, v)` for `strength` (see the module docs).
pub fn vignetting_factor(
    strength: f64,
    u: f64,
    v: f64,
    width: usize,
    height: usize,
    camera: &CameraModel,
) -> f64 {
    let s = strength.clamp(0.0, 0.999_999);
    let c = (1.0 - s).powf(-0.5) - 1.0;
    let (w, h) = ((width.max(1) - 1) as f64, (height.max(1) - 1) as f64);
    let corner2 = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .map(|(x, y)| (x - camera.cx).powi(2) + (y - camera.cy).powi(2))
        .fold(0.0f64, f64::max);
    if corner2 <= 0.0 {
        return 1.0;
    }
    let rho2 = ((u - camera.cx).powi(2) + (v - camera.cy).powi(2)) / corner2;
    1.0 / (1.0 + c * rho2).powi(2)
}

/// 8-bit image: rounds and clamps to 0..255 (`NaN` → 0).
pub fn quantise_u8(dn: &[f32]) -> Vec<u8> {
    dn.iter()
        .map(|v| {
            if v.is_nan() {
                0
            } else {
                v.round().clamp(0.0, 255.0) as u8
            }
        })
        .collect()
}

/// Applies the image effects of `effects` in the documented order.
pub(crate) fn apply(
    effects: &[Effect],
    radiance: &[f32],
    width: usize,
    height: usize,
    camera: &CameraModel,
    seed: u64,
) -> Vec<f32> {
    let mut img: Vec<f64> = radiance.iter().map(|&v| f64::from(v)).collect();
    for e in effects {
        if let Effect::Vignetting { strength } = *e {
            for (i, px) in img.iter_mut().enumerate() {
                let (u, v) = ((i % width.max(1)) as f64, (i / width.max(1)) as f64);
                *px *= vignetting_factor(strength, u, v, width, height, camera);
            }
        }
    }
    for e in effects {
        if let Effect::Blur { sigma_px } = *e {
            let f: Vec<f32> = img.iter().map(|&v| v as f32).collect();
            img = gaussian_blur(&f, width, height, sigma_px)
                .into_iter()
                .map(f64::from)
                .collect();
        }
    }
    for e in effects {
        if let Effect::Exposure { gain, offset } = *e {
            img.iter_mut().for_each(|px| *px = gain * *px + offset);
        }
    }
    img.iter_mut().for_each(|px| *px *= FULL_SCALE);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for e in effects {
        if let Effect::Noise { gain, read_sigma } = *e {
            for px in img.iter_mut() {
                let var = noise_variance(gain, read_sigma, *px);
                let z: f64 = StandardNormal.sample(&mut rng);
                *px += var.sqrt() * z;
            }
        }
    }
    for e in effects {
        if let Effect::Gamma { gamma } = *e {
            if gamma > 0.0 {
                img.iter_mut()
                    .for_each(|px| *px = FULL_SCALE * (px.max(0.0) / FULL_SCALE).powf(1.0 / gamma));
            }
        }
    }
    img.into_iter().map(|v| v as f32).collect()
}

/// Variance (DN²) of the `noise` effect at signal `dn` (DN, before the response curve): shot
/// noise `gain · dn` plus read noise.
pub fn noise_variance(gain: f64, read_sigma: f64, dn: f64) -> f64 {
    gain.max(0.0) * dn.max(0.0) + read_sigma * read_sigma
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undo_response_inverts_gamma_and_black_level_up_to_the_gain() {
        let effects = [
            Effect::Exposure {
                gain: 0.8,
                offset: 0.03,
            },
            Effect::Gamma { gamma: 1.7 },
        ];
        let radiance = [0.1f32, 0.2, 0.4, 0.8];
        let cam = CameraModel::pinhole(4, 1, 2.0, 2.0, 2.0, 0.5);
        let dn = apply(&effects, &radiance, 4, 1, &cam, 0);
        let lin = undo_response(&effects, &dn);
        for (l, r) in lin.iter().zip(&radiance) {
            assert!(
                (f64::from(*l) - 255.0 * 0.8 * f64::from(*r)).abs() < 1e-3,
                "{l} vs {r}"
            );
        }
        // Without a response curve or black level the images pass unchanged.
        assert_eq!(
            undo_response(&[Effect::Blur { sigma_px: 1.0 }], &[3.0, 4.0]),
            [3.0, 4.0]
        );
    }
}
