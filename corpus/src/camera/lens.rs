//! The optics: Brown–Conrady remapping with pixel integration, the hidden vignetting and the
//! point-spread function (defocus disc ⊗ Airy diffraction ⊗ optional hidden Gaussian).
//!
//! The remap does not average the `n × n` sub-positions of a pixel straight away: it keeps them
//! as `n²` *phase planes* (a real-geometry image `n` times finer than the sensor). The PSF then
//! maps those point samples of the focal-plane irradiance onto the sensor pixels with a kernel
//! that is the PSF integrated over a pixel's footprint, evaluated at each sub-position's offset
//! ([`PsfKernel`]). A pixel therefore integrates the blurred irradiance over its area exactly
//! once; integrating first and convolving with a pixel-integrated kernel afterwards would count
//! the pixel aperture twice (an extra `sinc` in the MTF, 0.64 at Nyquist).

use rayon::prelude::*;
use regolith_format::camera_model::CameraModel;

use super::{CameraPhysics, PinholeImage};

/// Residual (normalised units) at which the inverse distortion is accepted.
pub const UNDISTORT_TOLERANCE: f64 = 1e-10;
const UNDISTORT_MAX_ITER: usize = 60;

/// Kernel entries below this fraction of the peak are cut (the kernel is then renormalised).
pub const PSF_CUTOFF: f64 = 1e-4;
/// Largest kernel radius considered, real pixels.
const PSF_MAX_RADIUS: usize = 24;
/// Frequency step of the kernel's inverse transform, cycles/pixel: the kernel is exact up to
/// periodisation with a period of 64 pixels, far beyond [`PSF_MAX_RADIUS`].
const PSF_DNU: f64 = 1.0 / 64.0;
/// Highest frequency integrated when the optics have no diffraction cut-off (f-number or
/// wavelength 0), cycles/pixel.
const PSF_NU_MAX_NO_DIFFRACTION: f64 = 8.0;
/// Without a diffraction cut-off the transfer function is apodised by a Gaussian of this sigma
/// (pixels; 0.4 % of a pixel's variance) so that truncating it at
/// [`PSF_NU_MAX_NO_DIFFRACTION`] leaves no Gibbs ringing.
const PSF_APODISE_SIGMA: f64 = 0.08;

/// Jacobian `∂(xd, yd)/∂(x, y)` of [`CameraModel::distort`] (row-major `[j00, j01, j10, j11]`).
pub fn distortion_jacobian(camera: &CameraModel, x: f64, y: f64) -> [f64; 4] {
    let d = &camera.distortion;
    let r2 = x * x + y * y;
    let radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
    let dradial = d.k1 + r2 * (2.0 * d.k2 + 3.0 * r2 * d.k3);
    [
        radial + 2.0 * x * x * dradial + 2.0 * d.p1 * y + 6.0 * d.p2 * x,
        2.0 * x * y * dradial + 2.0 * d.p1 * x + 2.0 * d.p2 * y,
        2.0 * x * y * dradial + 2.0 * d.p1 * x + 2.0 * d.p2 * y,
        radial + 2.0 * y * y * dradial + 6.0 * d.p1 * y + 2.0 * d.p2 * x,
    ]
}

/// Inverts Brown–Conrady: the undistorted normalised `(x, y)` whose distortion is `(xd, yd)`,
/// by Newton iteration from `guess` with the analytic Jacobian, to a residual below
/// [`UNDISTORT_TOLERANCE`]. `None` when it does not converge or lands where the distortion
/// folds over (Jacobian determinant ≤ 0: no real ray reaches that sensor point).
pub fn undistort_from(
    camera: &CameraModel,
    xd: f64,
    yd: f64,
    guess: (f64, f64),
) -> Option<(f64, f64)> {
    let (mut x, mut y) = guess;
    for _ in 0..UNDISTORT_MAX_ITER {
        let (fx, fy) = camera.distort(x, y);
        let (ex, ey) = (fx - xd, fy - yd);
        let [j00, j01, j10, j11] = distortion_jacobian(camera, x, y);
        let det = j00 * j11 - j01 * j10;
        if det.is_nan() || det <= 1e-9 || !det.is_finite() {
            return None;
        }
        if ex.abs() <= UNDISTORT_TOLERANCE && ey.abs() <= UNDISTORT_TOLERANCE {
            return Some((x, y));
        }
        x -= (j11 * ex - j01 * ey) / det;
        y -= (-j10 * ex + j00 * ey) / det;
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
    }
    None
}

/// [`undistort_from`] starting at the distorted point itself.
pub fn undistort(camera: &CameraModel, xd: f64, yd: f64) -> Option<(f64, f64)> {
    undistort_from(camera, xd, yd, (xd, yd))
}

/// The hidden `vignetting` of strength `s` at pixel `(u, v)`: the cos⁴ law
/// `f = 1 / (1 + a ρ²)²` (an off-axis angle with `tan²θ = a ρ²`), `ρ` the distance from the
/// principal point over the distance from it to the farthest corner pixel centre, and `a` such
/// that `f(1) = 1 − s` exactly (`a = (1 − s)^(−1/2) − 1`). `s` is clamped to `[0, 1)`.
pub fn vignetting_factor(camera: &CameraModel, strength: f64, u: f64, v: f64) -> f64 {
    let a = vignetting_a(strength);
    let rho2 = ((u - camera.cx).powi(2) + (v - camera.cy).powi(2)) / corner_distance2(camera);
    1.0 / (1.0 + a * rho2).powi(2)
}

fn vignetting_a(strength: f64) -> f64 {
    let s = if strength.is_finite() {
        strength.clamp(0.0, 0.999_999)
    } else {
        0.0
    };
    1.0 / (1.0 - s).sqrt() - 1.0
}

/// Squared distance from the principal point to the farthest corner pixel centre.
fn corner_distance2(camera: &CameraModel) -> f64 {
    let (w, h) = (
        f64::from(camera.width) - 1.0,
        f64::from(camera.height) - 1.0,
    );
    let mut best: f64 = 0.0;
    for (u, v) in [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)] {
        best = best.max((u - camera.cx).powi(2) + (v - camera.cy).powi(2));
    }
    best.max(1e-12)
}

/// Bessel function of the first kind `J_n(x)` by the trapezoid rule on Bessel's integral
/// `(1/2π) ∫ cos(nτ − x sin τ) dτ` over a full period (exponentially convergent; the number of
/// nodes grows with `|x|`).
pub fn bessel_j(n: i32, x: f64) -> f64 {
    let m = 2 * (32 + x.abs().ceil() as usize);
    let h = std::f64::consts::TAU / m as f64;
    let sum: f64 = (0..m)
        .map(|k| {
            let t = -std::f64::consts::PI + k as f64 * h;
            (f64::from(n) * t - x * t.sin()).cos()
        })
        .sum();
    sum / m as f64
}

/// The optical transfer function of the always-present optics and the hidden blur, radial:
/// Airy (incoherent circular aperture, cut-off `pitch/(λN)` cycles/pixel) × defocus disc
/// (`2 J1(2πRν)/(2πRν)`) × Gaussian (`exp(−2π²σ²ν²)`).
pub fn optics_otf(physics: &CameraPhysics, blur_sigma_px: f64, nu: f64) -> f64 {
    let mut h = 1.0;
    if let Some(cut) = diffraction_cutoff(physics) {
        let s = nu / cut;
        if s >= 1.0 {
            return 0.0;
        }
        h *= (2.0 / std::f64::consts::PI) * (s.acos() - s * (1.0 - s * s).sqrt());
    }
    let r = physics.defocus_radius_px.max(0.0);
    let z = std::f64::consts::TAU * r * nu;
    if z > 1e-9 {
        h *= 2.0 * bessel_j(1, z) / z;
    }
    let s = blur_sigma_px.max(0.0);
    h * (-2.0 * std::f64::consts::PI.powi(2) * s * s * nu * nu).exp()
}

/// The diffraction cut-off frequency `pitch / (λ N)` in cycles per pixel; `None` without
/// diffraction (a non-positive f-number, wavelength or pitch).
pub fn diffraction_cutoff(physics: &CameraPhysics) -> Option<f64> {
    let ln = physics.wavelength_um * physics.f_number;
    (ln > 0.0 && physics.pixel_pitch_um > 0.0 && ln.is_finite())
        .then(|| physics.pixel_pitch_um / ln)
}

fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-12 {
        1.0
    } else {
        let px = std::f64::consts::PI * x;
        px.sin() / px
    }
}

/// The PSF as weights from the `n × n` sub-position samples of the focal plane onto pixels.
///
/// For output pixel `p` and sub-position `q` (real position `s(q)`), the weight is the share of
/// a point source at `s(q)` that the PSF puts inside pixel `p`'s footprint — the PSF integrated
/// over a pixel, `(box ⊗ PSF)(s(q) − p)`, exact in the frequency domain (the box's transform is
/// `sinc νx · sinc νy`). The kernel is cut where it falls below [`PSF_CUTOFF`] of its peak
/// (circularly) and renormalised so every sub-position deposits exactly `1/n²` (a flat field
/// stays flat, energy is conserved).
#[derive(Debug, Clone)]
pub struct PsfKernel {
    /// Sub-positions per pixel and axis.
    pub oversample: usize,
    /// Radius in real pixels: an output pixel reads `2·radius + 1` pixels of each phase plane.
    pub radius: usize,
    /// Per phase `a = ay·n + ax`: `(2r+1)²` weights, row-major over `(ky, kx)`; weight of the
    /// sample of phase `a` in padded pixel `(py + ky, px + kx)` for output pixel `(py, px)`.
    pub phases: Vec<Vec<f32>>,
}

impl PsfKernel {
    /// Side of one phase's weight grid.
    pub fn side(&self) -> usize {
        2 * self.radius + 1
    }

    /// Offset (real pixels) of a tap `k` of phase `a` from the output pixel centre, one axis.
    pub fn offset(&self, k: usize, a: usize) -> f64 {
        let n = self.oversample as f64;
        k as f64 - self.radius as f64 + (a as f64 + 0.5) / n - 0.5
    }

    /// The line-spread function along x: `(offset, weight)` pairs, weights summing to 1
    /// (the kernel's mass at each sub-pixel x offset, summed over y).
    pub fn line_spread_x(&self) -> Vec<(f64, f64)> {
        let (n, side) = (self.oversample, self.side());
        let mut out = Vec::with_capacity(side * n);
        for kx in 0..side {
            for ax in 0..n {
                let mut w = 0.0;
                for ay in 0..n {
                    let phase = self.phases.get(ay * n + ax);
                    for ky in 0..side {
                        w += phase
                            .and_then(|p| p.get(ky * side + kx))
                            .map_or(0.0, |&v| f64::from(v));
                    }
                }
                out.push((self.offset(kx, ax), w));
            }
        }
        out
    }
}

/// Builds the PSF kernel for `oversample` sub-positions per pixel and axis: the defocus disc of
/// `physics.defocus_radius_px` ⊗ the Airy pattern of `physics.f_number`,
/// `physics.wavelength_um`, `physics.pixel_pitch_um` ⊗ a Gaussian of `blur_sigma_px` (hidden
/// `blur`; `None` = no Gaussian), integrated over the pixel footprint.
pub fn psf_kernel(
    physics: &CameraPhysics,
    blur_sigma_px: Option<f64>,
    oversample: usize,
) -> PsfKernel {
    let n = oversample.max(1);
    let sigma = blur_sigma_px
        .filter(|s| s.is_finite())
        .unwrap_or(0.0)
        .max(0.0);
    let cutoff = diffraction_cutoff(physics);
    if cutoff.is_none() && sigma <= 0.0 && physics.defocus_radius_px.max(0.0) <= 0.0 {
        // Ideal optics: every sub-position's light stays in its own pixel.
        return PsfKernel {
            oversample: n,
            radius: 0,
            phases: vec![vec![1.0 / (n * n) as f32]; n * n],
        };
    }
    let apodise = if cutoff.is_some() {
        0.0
    } else {
        PSF_APODISE_SIGMA
    };
    let nu_max = cutoff.map_or(PSF_NU_MAX_NO_DIFFRACTION, |c| {
        c.min(PSF_NU_MAX_NO_DIFFRACTION)
    });
    let m = (nu_max / PSF_DNU).ceil() as usize + 1;
    // Spectrum on the quadrant νx, νy ≥ 0 with trapezoid weights (½ on the axes).
    let nus: Vec<f64> = (0..m).map(|i| i as f64 * PSF_DNU).collect();
    let w_axis = |i: usize| if i == 0 { 0.5 } else { 1.0 };
    let radial: Vec<f64> = (0..m * m)
        .into_par_iter()
        .map(|idx| {
            let (i, j) = (idx / m, idx % m);
            let (a, b) = (nus[i], nus[j]);
            let nu = (a * a + b * b).sqrt();
            if nu > nu_max {
                0.0
            } else {
                optics_otf(physics, sigma, nu)
                    * (-2.0 * std::f64::consts::PI.powi(2) * apodise * apodise * nu * nu).exp()
                    * sinc(a)
                    * sinc(b)
                    * w_axis(i)
                    * w_axis(j)
            }
        })
        .collect();
    // Offsets for the largest radius, every sub-pixel phase: d = k − R + (a + ½)/n − ½.
    let rmax = PSF_MAX_RADIUS;
    let side_max = 2 * rmax + 1;
    let offsets: Vec<f64> = (0..side_max * n)
        .map(|t| (t / n) as f64 - rmax as f64 + ((t % n) as f64 + 0.5) / n as f64 - 0.5)
        .collect();
    let cos_tab: Vec<f64> = offsets
        .iter()
        .flat_map(|&d| {
            nus.iter()
                .map(move |&nu| (std::f64::consts::TAU * nu * d).cos())
        })
        .collect();
    // tmp[i][ty] = Σ_j H[i][j] cos(2π ν_j d_ty)
    let nd = offsets.len();
    let tmp: Vec<f64> = (0..m * nd)
        .into_par_iter()
        .map(|idx| {
            let (i, ty) = (idx / nd, idx % nd);
            let row = &radial[i * m..(i + 1) * m];
            let c = &cos_tab[ty * m..(ty + 1) * m];
            row.iter().zip(c).map(|(h, c)| h * c).sum()
        })
        .collect();
    let scale = 4.0 * PSF_DNU * PSF_DNU;
    // full[ty][tx] = scale Σ_i cos(2π ν_i d_tx) tmp[i][ty]
    let full: Vec<f64> = (0..nd * nd)
        .into_par_iter()
        .map(|idx| {
            let (ty, tx) = (idx / nd, idx % nd);
            let c = &cos_tab[tx * m..(tx + 1) * m];
            let s: f64 = (0..m).map(|i| c[i] * tmp[i * nd + ty]).sum();
            (s * scale).max(0.0)
        })
        .collect();
    let peak = full.iter().copied().fold(0.0, f64::max);
    let threshold = PSF_CUTOFF * peak;
    let mut r_cut: f64 = 0.0;
    for (idx, &v) in full.iter().enumerate() {
        if v >= threshold && peak > 0.0 {
            let (dy, dx) = (offsets[idx / nd], offsets[idx % nd]);
            r_cut = r_cut.max((dx * dx + dy * dy).sqrt());
        }
    }
    let radius = ((r_cut - 0.5).ceil().max(0.0) as usize).min(rmax);
    let side = 2 * radius + 1;
    let mut phases = vec![vec![0f32; side * side]; n * n];
    for ay in 0..n {
        for ax in 0..n {
            let mut weights = vec![0.0f64; side * side];
            for ky in 0..side {
                for kx in 0..side {
                    let ty = (ky + rmax - radius) * n + ay;
                    let tx = (kx + rmax - radius) * n + ax;
                    let (dy, dx) = (offsets[ty], offsets[tx]);
                    let v = full[ty * nd + tx];
                    if (dx * dx + dy * dy).sqrt() <= r_cut && v >= threshold {
                        weights[ky * side + kx] = v;
                    }
                }
            }
            let total: f64 = weights.iter().sum();
            let norm = if total > 0.0 {
                1.0 / (total * (n * n) as f64)
            } else {
                0.0
            };
            let phase = &mut phases[ay * n + ax];
            if total > 0.0 {
                for (p, w) in phase.iter_mut().zip(&weights) {
                    *p = (w * norm) as f32;
                }
            } else {
                // Degenerate optics: the sample stays in its own pixel.
                phase[radius * side + radius] = 1.0 / (n * n) as f32;
            }
        }
    }
    PsfKernel {
        oversample: n,
        radius,
        phases,
    }
}

/// The focal-plane samples of the real camera: `n²` phase planes over the image padded by
/// `pad` pixels on every side (`(width + 2 pad) × (height + 2 pad)` each).
#[derive(Debug, Clone)]
pub struct FocalPlane {
    /// Sub-positions per pixel and axis.
    pub oversample: usize,
    /// Padding in real pixels.
    pub pad: usize,
    /// Padded width.
    pub width: usize,
    /// Padded height.
    pub height: usize,
    /// Phase `a = ay·n + ax` holds the sample at real position
    /// `(X − pad + (ax + ½)/n − ½, Y − pad + (ay + ½)/n − ½)` at index `Y·width + X`.
    pub planes: Vec<Vec<f32>>,
    /// Sub-positions where the distortion could not be inverted (sampled as black).
    pub unconverged: usize,
}

/// Bilinear sample of the pinhole radiance at canvas position `(u, v)`, clamp-to-edge.
pub fn bilinear(img: &PinholeImage, u: f64, v: f64) -> f64 {
    if img.width == 0 || img.height == 0 {
        return 0.0;
    }
    let (wm, hm) = ((img.width - 1) as f64, (img.height - 1) as f64);
    let (u, v) = (u.clamp(0.0, wm), v.clamp(0.0, hm));
    let (u0, v0) = (u.floor(), v.floor());
    let (fu, fv) = (u - u0, v - v0);
    let (i0, j0) = (u0 as usize, v0 as usize);
    let (i1, j1) = ((i0 + 1).min(img.width - 1), (j0 + 1).min(img.height - 1));
    let at = |i: usize, j: usize| {
        img.radiance
            .get(j * img.width + i)
            .map_or(0.0, |&r| f64::from(r))
    };
    let top = at(i0, j0) * (1.0 - fu) + at(i1, j0) * fu;
    let bottom = at(i0, j1) * (1.0 - fu) + at(i1, j1) * fu;
    top * (1.0 - fv) + bottom * fv
}

/// Step 1 and 2: samples the pinhole render at the undistorted position of every sub-position
/// of every (padded) pixel of `camera`, times the hidden vignetting (`None` = none).
pub fn remap(
    pinhole: &PinholeImage,
    camera: &CameraModel,
    oversample: usize,
    pad: usize,
    vignetting_strength: Option<f64>,
) -> FocalPlane {
    let n = oversample.max(1);
    let (w, h) = (
        camera.width as usize + 2 * pad,
        camera.height as usize + 2 * pad,
    );
    let vig = vignetting_strength.map(|s| (vignetting_a(s), corner_distance2(camera)));
    let rows: Vec<(Vec<f32>, usize)> = (0..h * n)
        .into_par_iter()
        .map(|fy| {
            let (y, ay) = (fy / n, fy % n);
            let v = y as f64 - pad as f64 + (ay as f64 + 0.5) / n as f64 - 0.5;
            let yd = (v - camera.cy) / camera.fy;
            let mut row = vec![0f32; w * n];
            let mut bad = 0;
            let mut guess: Option<(f64, f64)> = None;
            for (fx, out) in row.iter_mut().enumerate() {
                let u = (fx / n) as f64 - pad as f64 + ((fx % n) as f64 + 0.5) / n as f64 - 0.5;
                let xd = (u - camera.cx) / camera.fx;
                let sol = guess
                    .and_then(|g| undistort_from(camera, xd, yd, g))
                    .or_else(|| undistort(camera, xd, yd));
                guess = sol;
                let Some((x, y)) = sol else {
                    bad += 1;
                    continue;
                };
                let mut r = bilinear(
                    pinhole,
                    pinhole.fx * x + pinhole.cx,
                    pinhole.fy * y + pinhole.cy,
                );
                if let Some((a, c2)) = vig {
                    let rho2 = ((u - camera.cx).powi(2) + (v - camera.cy).powi(2)) / c2;
                    r /= (1.0 + a * rho2).powi(2);
                }
                *out = r as f32;
            }
            (row, bad)
        })
        .collect();
    let mut planes = vec![vec![0f32; w * h]; n * n];
    let mut unconverged = 0;
    for (fy, (row, bad)) in rows.into_iter().enumerate() {
        unconverged += bad;
        let (y, ay) = (fy / n, fy % n);
        for (fx, r) in row.into_iter().enumerate() {
            let (x, ax) = (fx / n, fx % n);
            planes[ay * n + ax][y * w + x] = r;
        }
    }
    FocalPlane {
        oversample: n,
        pad,
        width: w,
        height: h,
        planes,
        unconverged,
    }
}

/// Step 3: the sensor irradiance per pixel (radiance units, `width × height` of the camera,
/// row-major): the PSF kernel applied from the focal-plane samples onto the pixels. Samples
/// beyond the focal plane's padding are clamped to its edge.
pub fn apply_psf(plane: &FocalPlane, kernel: &PsfKernel, width: usize, height: usize) -> Vec<f32> {
    let n = plane.oversample;
    let r = kernel.radius as isize;
    let side = kernel.side();
    let pad = plane.pad as isize;
    let (pw, ph) = (plane.width as isize, plane.height as isize);
    let rows: Vec<Vec<f32>> = (0..height)
        .into_par_iter()
        .map(|py| {
            let mut acc = vec![0f32; width];
            let mut line = vec![0f32; width + side];
            for (a, weights) in kernel.phases.iter().enumerate().take(n * n) {
                let Some(src) = plane.planes.get(a) else {
                    continue;
                };
                for ky in 0..side {
                    let y = (py as isize + pad - r + ky as isize).clamp(0, ph - 1) as usize;
                    // The padded row, read from x = px + pad − r, clamped to the plane's edge.
                    for (i, l) in line.iter_mut().enumerate() {
                        let x = (i as isize + pad - r).clamp(0, pw - 1) as usize;
                        *l = src.get(y * plane.width + x).copied().unwrap_or(0.0);
                    }
                    for kx in 0..side {
                        let wgt = weights.get(ky * side + kx).copied().unwrap_or(0.0);
                        if wgt <= 0.0 {
                            continue;
                        }
                        for (o, s) in acc.iter_mut().zip(&line[kx..kx + width]) {
                            *o += wgt * s;
                        }
                    }
                }
            }
            acc
        })
        .collect();
    rows.concat()
}
