//! The corpus's own camera: turns a linear radiance render of an ideal pinhole camera into the
//! 8-bit frames a real camera would write.
//!
//! **Why a separate camera.** The corpus makes synthetic "real" frames to test the validator.
//! Making them with the validator's own sensor model would be the *inverse crime*: a model
//! fitted to data it generated itself finds its own assumptions, not the camera's. So this
//! module is written from the physics alone and shares no code with `regolith-validator`; only
//! the *semantics* of the hidden effects (`regolith_format::effects` and
//! `format-spec/registry.md`) are shared, as they must be for the gap workflow to name them.
//!
//! **Input.** A physically based renderer (Mitsuba) draws a linear radiance image from an
//! ideal pinhole camera ([`PinholeImage`]) covering the real camera's field with a margin and
//! finer than the real image by an oversampling factor; [`pinhole_canvas`] says which canvas.
//! Radiance 1.0 is 255 DN at unit exposure.
//!
//! **Order of effects** (the camera's physical order, also the project's documented order):
//! 1. *Lens distortion and pixel integration* ([`lens::remap`]): each pixel is sampled at
//!    `n × n` sub-positions (`n` = the canvas's oversampling); each sub-position's distorted
//!    normalised coordinates are undistorted by inverting Brown–Conrady (Newton, residual
//!    < 1e-10, [`lens::undistort`]) and the canvas is sampled bilinearly there.
//! 2. *Vignetting* (hidden `vignetting`, [`lens::vignetting_factor`]): a cos⁴-law falloff
//!    `1/(1 + aρ²)²` whose corner/centre ratio is exactly `1 − strength`, on the radiance.
//! 3. *PSF* ([`lens::psf_kernel`], [`lens::apply_psf`]): a defocus disc ⊗ an Airy diffraction
//!    pattern, ⊗ a Gaussian for a hidden `blur`, integrated over each pixel's footprint — the
//!    sub-position samples of step 1 are spread by the PSF and integrated by the pixels (the
//!    pixel aperture counts once). Not a Gaussian: a sharp core with diffraction wings.
//! 4. *Exposure* (hidden `exposure` (g, o)): `signal = g·radiance + o`, DN = 255·signal.
//! 5. *Sensor* ([`sensor`]): PRNU (fixed, multiplicative) → photon shot noise (Poisson in
//!    electron-equivalents, variance `gain·signal` DN²) → DSNU (fixed, per pixel) + column FPN
//!    (fixed, per column) + black level → read noise `N(0, read_sigma²)`.
//! 6. *Response* (hidden `gamma`): `out = in^(1/γ)` on the normalised DN clipped to [0, 1].
//! 7. *Quantisation*: rounded to 8 bits.
//!
//! Determinism: fixed patterns come from `fixed_seed` (the same for every frame of a camera),
//! temporal noise from `frame_seed`; each row has its own generator, so the bytes do not depend
//! on rayon's thread count.

pub mod lens;
pub mod sensor;

#[cfg(test)]
mod tests;

use rayon::prelude::*;
use regolith_format::camera_model::CameraModel;

pub use lens::{apply_psf, psf_kernel, remap, undistort, vignetting_factor, FocalPlane, PsfKernel};
pub use sensor::FixedPattern;

/// A linear radiance image from an ideal pinhole camera (no distortion), row-major, row 0 at
/// the top; radiance 1.0 = 255 DN at unit exposure. Pixel centres at integer `(u, v)`.
#[derive(Debug, Clone, PartialEq)]
pub struct PinholeImage {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// `width × height` radiances.
    pub radiance: Vec<f32>,
}

impl PinholeImage {
    /// An image on the canvas `spec` with these radiances.
    pub fn from_spec(spec: &PinholeSpec, radiance: Vec<f32>) -> PinholeImage {
        PinholeImage {
            width: spec.width,
            height: spec.height,
            fx: spec.fx,
            fy: spec.fy,
            cx: spec.cx,
            cy: spec.cy,
            radiance,
        }
    }
}

/// The pinhole canvas a renderer must draw ([`pinhole_canvas`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeSpec {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Focal length along x, pixels (the real camera's × oversample).
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels (pixel-centre convention).
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

impl PinholeSpec {
    /// The canvas pixel `(u, v)` of the normalised undistorted direction `(x, y)`.
    pub fn to_pixel(&self, x: f64, y: f64) -> [f64; 2] {
        [self.fx * x + self.cx, self.fy * y + self.cy]
    }
}

/// The pinhole canvas a renderer must draw so `camera` (with Brown–Conrady distortion) can be
/// resampled from it: same orientation, focal lengths scaled by `oversample` (≥ 1; 2 is a good
/// choice), extent covering the undistorted positions of every pixel of `camera` extended by
/// `margin_px` real pixels on each side (pass at least [`psf_margin_px`] for the PSF), plus one
/// canvas pixel for the bilinear interpolation. Positions where the distortion cannot be
/// inverted (beyond a fold-over) are left out.
pub fn pinhole_canvas(camera: &CameraModel, oversample: u32, margin_px: f64) -> PinholeSpec {
    let n = f64::from(oversample.max(1));
    let m = if margin_px.is_finite() {
        margin_px.max(0.0)
    } else {
        0.0
    };
    let (w, h) = (f64::from(camera.width), f64::from(camera.height));
    let (u0, u1, v0, v1) = (-0.5 - m, w - 0.5 + m, -0.5 - m, h - 0.5 + m);
    // The border densely (quarter pixels) and the interior on every pixel.
    let mut pts: Vec<(f64, f64)> = Vec::new();
    let nu = ((u1 - u0) * 4.0).ceil() as usize;
    let nv = ((v1 - v0) * 4.0).ceil() as usize;
    for i in 0..=nu {
        let u = u0 + (u1 - u0) * i as f64 / nu.max(1) as f64;
        pts.push((u, v0));
        pts.push((u, v1));
    }
    for j in 0..=nv {
        let v = v0 + (v1 - v0) * j as f64 / nv.max(1) as f64;
        pts.push((u0, v));
        pts.push((u1, v));
    }
    let rows: Vec<[f64; 4]> = (0..=(v1 - v0).floor() as usize)
        .into_par_iter()
        .map(|j| {
            let v = v0 + j as f64;
            let mut b = [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ];
            let mut guess = None;
            for i in 0..=(u1 - u0).floor() as usize {
                let u = u0 + i as f64;
                let (xd, yd) = ((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy);
                let sol = guess
                    .and_then(|g| lens::undistort_from(camera, xd, yd, g))
                    .or_else(|| undistort(camera, xd, yd));
                guess = sol;
                if let Some((x, y)) = sol {
                    b = [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)];
                }
            }
            b
        })
        .collect();
    let mut b = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for r in rows {
        b = [
            b[0].min(r[0]),
            b[1].max(r[1]),
            b[2].min(r[2]),
            b[3].max(r[3]),
        ];
    }
    for (u, v) in pts {
        if let Some((x, y)) = undistort(
            camera,
            (u - camera.cx) / camera.fx,
            (v - camera.cy) / camera.fy,
        ) {
            b = [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)];
        }
    }
    if !b.iter().all(|v| v.is_finite()) {
        b = [0.0; 4];
    }
    let (fx, fy) = (camera.fx * n, camera.fy * n);
    let cx = (-fx * b[0]).ceil() + 1.0;
    let cy = (-fy * b[2]).ceil() + 1.0;
    PinholeSpec {
        width: (fx * b[1] + cx).floor() as usize + 3,
        height: (fy * b[3] + cy).floor() as usize + 3,
        fx,
        fy,
        cx,
        cy,
    }
}

/// The margin (real pixels) [`pinhole_canvas`] needs for this camera's PSF: the kernel radius
/// plus one pixel.
pub fn psf_margin_px(physics: &CameraPhysics, hidden: &HiddenOptics) -> f64 {
    psf_kernel(physics, hidden.blur_sigma_px, 1).radius as f64 + 1.0
}

/// The real camera's fixed properties (always present; not catalogue effects): optics and
/// sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPhysics {
    /// Defocus (pillbox) disc radius, real pixels.
    pub defocus_radius_px: f64,
    /// Working f-number (diffraction); ≤ 0 disables diffraction.
    pub f_number: f64,
    /// Effective wavelength, µm (diffraction).
    pub wavelength_um: f64,
    /// Pixel pitch, µm (diffraction in pixels).
    pub pixel_pitch_um: f64,
    /// Photo-response non-uniformity, relative standard deviation.
    pub prnu_sigma: f64,
    /// Dark-signal non-uniformity, DN standard deviation.
    pub dsnu_sigma_dn: f64,
    /// Column fixed-pattern offset, DN standard deviation.
    pub column_fpn_sigma_dn: f64,
    /// Black level (pedestal), DN.
    pub black_level_dn: f64,
}

impl CameraPhysics {
    /// A lab navigation camera: a 1.3-megapixel-class global-shutter CMOS behind a fixed-focus
    /// lens stopped down to f/8.
    ///
    /// * `defocus_radius_px` 0.6: a fixed-focus lens set for the middle of the working range
    ///   leaves a blur circle of about one pixel diameter at its ends; 0.6 px is a typical
    ///   mid-range value, large enough to matter, small enough to be "in focus".
    /// * `f_number` 8, `wavelength_um` 0.55, `pixel_pitch_um` 5.3: f/8 for depth of field,
    ///   0.55 µm the centre of a monochrome sensor's visible response, 5.3 µm a common pitch of
    ///   such sensors. The Airy first zero `1.22 λN/pitch` is 1.01 px: diffraction as wide as a
    ///   pixel, as in a lens stopped down for depth of field.
    /// * `prnu_sigma` 0.01: EMVA 1288 datasheets of industrial CMOS sensors report 0.5–1.5 %.
    /// * `dsnu_sigma_dn` 0.4, `column_fpn_sigma_dn` 0.3: dark non-uniformity of a few electrons
    ///   at 8 bits, below the read noise (as sensors with correlated double sampling have);
    ///   column amplifiers leave a faint column pattern, somewhat weaker than the per-pixel one.
    /// * `black_level_dn` 2.0: a pedestal keeps the read noise of dark pixels from being clipped
    ///   at 0, as camera firmware does.
    pub const NAVCAM: CameraPhysics = CameraPhysics {
        defocus_radius_px: 0.6,
        f_number: 8.0,
        wavelength_um: 0.55,
        pixel_pitch_um: 5.3,
        prnu_sigma: 0.01,
        dsnu_sigma_dn: 0.4,
        column_fpn_sigma_dn: 0.3,
        black_level_dn: 2.0,
    };

    /// Ideal optics and sensor: no defocus, no diffraction, no fixed pattern, no black level
    /// (for tests and for isolating one effect).
    pub const IDEAL: CameraPhysics = CameraPhysics {
        defocus_radius_px: 0.0,
        f_number: 0.0,
        wavelength_um: 0.0,
        pixel_pitch_um: 0.0,
        prnu_sigma: 0.0,
        dsnu_sigma_dn: 0.0,
        column_fpn_sigma_dn: 0.0,
        black_level_dn: 0.0,
    };
}

/// Catalogue effects hidden in this camera (`None` = absent), with the effect registry's
/// semantics (`format-spec/registry.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HiddenOptics {
    /// `vignetting.strength`: cos⁴-law falloff, corners at `1 − strength` of the centre.
    pub vignetting_strength: Option<f64>,
    /// `blur.sigma_px`: an added Gaussian PSF of this sigma, real pixels.
    pub blur_sigma_px: Option<f64>,
    /// `exposure.(gain, offset)`: `signal = gain·radiance + offset` (normalised).
    pub exposure: Option<(f64, f64)>,
    /// `(gain, read_sigma)`: shot noise of variance `gain × signal` (DN²) plus read noise of
    /// `read_sigma` DN. Always present: the baseline [`HiddenOptics::BASELINE_NOISE`] or a
    /// hidden `noise`.
    pub noise: (f64, f64),
    /// `gamma.gamma`: response `out = in^(1/gamma)`.
    pub gamma: Option<f64>,
}

impl HiddenOptics {
    /// The baseline noise every real image has (`effects`: gain 0.05 DN/DN, read σ 0.8 DN).
    pub const BASELINE_NOISE: (f64, f64) = (0.05, 0.8);

    /// No hidden effect, baseline noise.
    pub const BASELINE: HiddenOptics = HiddenOptics {
        vignetting_strength: None,
        blur_sigma_px: None,
        exposure: None,
        noise: HiddenOptics::BASELINE_NOISE,
        gamma: None,
    };
}

/// Steps 1–3: the sensor irradiance of `camera` (radiance units, `width × height`, row-major)
/// before exposure and the sensor. The oversampling is the canvas's (`pinhole.fx / camera.fx`,
/// rounded, at least 1).
pub fn irradiance(
    pinhole: &PinholeImage,
    camera: &CameraModel,
    physics: &CameraPhysics,
    hidden: &HiddenOptics,
) -> Vec<f32> {
    let ratio = (pinhole.fx / camera.fx).max(pinhole.fy / camera.fy);
    let n = if ratio.is_finite() {
        ratio.round().clamp(1.0, 16.0) as usize
    } else {
        1
    };
    let kernel = psf_kernel(physics, hidden.blur_sigma_px, n);
    let plane = remap(
        pinhole,
        camera,
        n,
        kernel.radius,
        hidden.vignetting_strength,
    );
    apply_psf(
        &plane,
        &kernel,
        camera.width as usize,
        camera.height as usize,
    )
}

/// Makes one 8-bit frame (row-major, `camera.width × camera.height`) of the real camera
/// `camera` (intrinsics and its true distortion) from a pinhole render of the same viewpoint.
/// `fixed_seed` seeds the camera's fixed patterns (PRNU, DSNU, column FPN: identical across the
/// frames of one camera), `frame_seed` the temporal noise. Deterministic for any thread count.
/// Sub-positions whose distortion cannot be inverted are black; canvas positions beyond the
/// pinhole image repeat its edge.
pub fn expose(
    pinhole: &PinholeImage,
    camera: &CameraModel,
    physics: &CameraPhysics,
    hidden: &HiddenOptics,
    fixed_seed: u64,
    frame_seed: u64,
) -> Vec<u8> {
    expose_frames(pinhole, camera, physics, hidden, fixed_seed, &[frame_seed])
        .pop()
        .unwrap_or_default()
}

/// The frames [`expose`] makes for each of `frame_seeds`, with the optics (remap, vignetting,
/// PSF) and the fixed pattern computed once: frames of one pose differ only in their temporal
/// noise.
pub fn expose_frames(
    pinhole: &PinholeImage,
    camera: &CameraModel,
    physics: &CameraPhysics,
    hidden: &HiddenOptics,
    fixed_seed: u64,
    frame_seeds: &[u64],
) -> Vec<Vec<u8>> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let irr = irradiance(pinhole, camera, physics, hidden);
    let pattern = FixedPattern::new(physics, w, h, fixed_seed);
    frame_seeds
        .iter()
        .map(|&frame_seed| {
            let rows: Vec<Vec<u8>> = (0..h)
                .into_par_iter()
                .map(|row| {
                    let line = irr.get(row * w..(row + 1) * w).unwrap_or(&[]);
                    sensor::sensor_row(line, row, &pattern, physics, hidden, frame_seed)
                })
                .collect();
            rows.concat()
        })
        .collect()
}
