//! The per-pixel loop: camera rays, supersampling, shading and shadow rays.
//!
//! Each output pixel is independent: its samples are generated from its own coordinates, traced
//! and averaged in a fixed order, and rows are computed in parallel with an indexed rayon
//! `map().collect()`, so the output bytes do not depend on the thread count.
//!
//! Sample positions: with `n = supersample`, sample `(a, b)` of pixel `(c, r)` is at
//! `(c + (a + 0.5) / n - 0.5, r + (b + 0.5) / n - 0.5)` and the radiance is their plain mean
//! (box filter, misses count as 0). Depth and mask always come from the pixel centre, which is
//! one of the samples when `n` is odd and an extra ray when it is even. A camera ray direction
//! is `R * (x, y, 1)` with `(x, y)` the normalised undistorted coordinates, so the ray
//! parameter `t` of a hit *is* its camera-frame depth.

use rayon::prelude::*;
use regolith_format::camera_model::CameraModel;

use super::shading::{footprint_m, light_direction, sample_albedo_filtered, shade};
use super::{Hit, Light, RenderOptions, Rendered, Scene, SceneKind, View};

/// Shadow-ray start offset along the normal: heightfields, in cells.
const HF_SHADOW_EPS_CELLS: f64 = 1e-3;
/// Shadow-ray start offset along the normal: meshes, as a share of the bounding-box diagonal.
const MESH_SHADOW_EPS: f64 = 1e-6;

struct Sample {
    radiance: f64,
    depth: Option<f64>,
}

pub(crate) fn render_scene(
    scene: &Scene<'_>,
    light: &Light,
    view: &View,
    opts: &RenderOptions,
) -> Rendered {
    let cam = &view.camera;
    let (w, h) = (cam.width as usize, cam.height as usize);
    let n = opts.supersample.max(1);
    let rot = view.ground_from_camera.rotation_matrix();
    let centre = view.ground_from_camera.translation_m;
    let to_light = light_direction(light);
    let ambient = light.ambient;

    let per_pixel = samples_per_pixel(n);
    let odd_centre = (n % 2 == 1).then_some(((n / 2) * n + n / 2) as usize);
    let table = opts.distort.then(|| scene.ray_table(cam, n));
    let pinhole = |u: f64, v: f64| -> (f64, f64) {
        let y = (v - cam.cy) / cam.fy;
        ((u - cam.cx - cam.skew * y) / cam.fx, y)
    };
    // Normalised undistorted coordinates of sample `k` (see `sample_offset`) of pixel (c, r).
    let ray_xy = |c: usize, r: usize, k: usize| -> (f64, f64) {
        match &table {
            Some(t) => {
                t.xy.get((r * w + c) * per_pixel + k)
                    .map_or((f64::NAN, f64::NAN), |p| (p[0], p[1]))
            }
            None => {
                let (du, dv) = sample_offset(n, k);
                pinhole(c as f64 + du, r as f64 + dv)
            }
        }
    };

    // Neighbouring samples' spacing in normalised image coordinates (for texture filtering).
    let spread = if opts.filter_textures {
        2.0 / ((cam.fx.abs() + cam.fy.abs()) * f64::from(n))
    } else {
        0.0
    };
    let sample = |x: f64, y: f64| -> Sample {
        let d = std::array::from_fn(|k| rot[k][0] * x + rot[k][1] * y + rot[k][2]);
        let Some((hit, albedo, eps)) = trace(scene, centre, d, spread) else {
            return Sample {
                radiance: 0.0,
                depth: None,
            };
        };
        let n_dot_l: f64 = (0..3).map(|k| hit.normal[k] * to_light[k]).sum();
        let visible = if opts.shadows && n_dot_l > 0.0 {
            let o = std::array::from_fn(|k| hit.point[k] + hit.normal[k] * eps);
            if occluded(scene, o, to_light) {
                0.0
            } else {
                1.0
            }
        } else {
            1.0
        };
        Sample {
            radiance: shade(f64::from(albedo), ambient, hit.normal, to_light, visible),
            depth: Some(hit.t),
        }
    };

    let rows: Vec<(Vec<f32>, Vec<f32>, Vec<u8>)> = (0..h)
        .into_par_iter()
        .map(|r| {
            let mut rad = vec![0f32; w];
            let mut depth = vec![f32::NAN; w];
            let mut mask = vec![0u8; w];
            for c in 0..w {
                let mut sum = 0.0;
                let mut centre_depth = None;
                for k in 0..(n * n) as usize {
                    let (x, y) = ray_xy(c, r, k);
                    let s = sample(x, y);
                    sum += s.radiance;
                    if Some(k) == odd_centre {
                        centre_depth = s.depth;
                    }
                }
                if n.is_multiple_of(2) {
                    let (x, y) = ray_xy(c, r, (n * n) as usize);
                    centre_depth = sample(x, y).depth;
                }
                if let (Some(px), Some(d), Some(m)) =
                    (rad.get_mut(c), depth.get_mut(c), mask.get_mut(c))
                {
                    *px = (sum / f64::from(n * n)) as f32;
                    if let Some(z) = centre_depth {
                        *d = z as f32;
                        *m = 255;
                    }
                }
            }
            (rad, depth, mask)
        })
        .collect();

    let mut out = Rendered {
        width: w,
        height: h,
        radiance: Vec::with_capacity(w * h),
        depth: Vec::with_capacity(w * h),
        mask: Vec::with_capacity(w * h),
    };
    for (rad, depth, mask) in rows {
        out.radiance.extend(rad);
        out.depth.extend(depth);
        out.mask.extend(mask);
    }
    out
}

/// Rays per pixel: the `n x n` samples, plus the centre ray when `n` is even.
fn samples_per_pixel(n: u32) -> usize {
    (n * n) as usize + usize::from(n.is_multiple_of(2))
}

/// Offset from the pixel centre of sample `k`: `k = b * n + a` for the `n x n` samples, `n * n`
/// for the extra centre ray of an even `n`.
fn sample_offset(n: u32, k: usize) -> (f64, f64) {
    let nn = (n * n) as usize;
    if k >= nn {
        return (0.0, 0.0);
    }
    let (a, b) = ((k % n as usize) as f64, (k / n as usize) as f64);
    let n = f64::from(n);
    ((a + 0.5) / n - 0.5, (b + 0.5) / n - 0.5)
}

/// The normalised undistorted coordinates of every camera ray of one camera model and sampling
/// rate, pixel by pixel (row-major, [`samples_per_pixel`] rays each, in [`sample_offset`] order).
///
/// Why: inverting the lens distortion is a Newton iteration per ray, about a fifth of a
/// 1280 x 1024 render; `validate` and `gap` render every camera at every capture, so the rays
/// are computed once per camera and looked up afterwards. The values are exactly those of
/// [`unproject`], so a cached and an uncached render are byte-identical.
pub(crate) struct RayTable {
    pub(crate) camera: CameraModel,
    pub(crate) supersample: u32,
    pub(crate) xy: Vec<[f64; 2]>,
}

impl RayTable {
    pub(crate) fn new(cam: &CameraModel, n: u32) -> RayTable {
        let n = n.max(1);
        let w = cam.width as usize;
        let per_pixel = samples_per_pixel(n);
        let rows: Vec<Vec<[f64; 2]>> = (0..cam.height as usize)
            .into_par_iter()
            .map(|r| {
                let mut row = Vec::with_capacity(w * per_pixel);
                for c in 0..w {
                    for k in 0..per_pixel {
                        let (du, dv) = sample_offset(n, k);
                        let (x, y) = unproject(cam, c as f64 + du, r as f64 + dv);
                        row.push([x, y]);
                    }
                }
                row
            })
            .collect();
        RayTable {
            camera: cam.clone(),
            supersample: n,
            xy: rows.concat(),
        }
    }
}

/// The nearest hit, its albedo (filtered over the footprint of a sample `spread` wide in
/// normalised image coordinates) and the shadow-ray offset to use there.
fn trace(scene: &Scene<'_>, o: [f64; 3], d: [f64; 3], spread: f64) -> Option<(Hit, f32, f64)> {
    match &scene.kind {
        SceneKind::Heightfield {
            tracer,
            albedo,
            mips,
        } => {
            let hit = tracer.trace(o, d, f64::INFINITY)?;
            let foot = footprint_m(hit.t, d, hit.normal, spread);
            let a = sample_albedo_filtered(albedo, mips, hit.point[0], hit.point[1], foot);
            Some((hit, a, tracer.cell_m() * HF_SHADOW_EPS_CELLS))
        }
        SceneKind::Mesh { tracer } => {
            let (hit, a) = tracer.trace_albedo(o, d, f64::INFINITY, spread)?;
            Some((hit, a, tracer.extent() * MESH_SHADOW_EPS))
        }
    }
}

fn occluded(scene: &Scene<'_>, o: [f64; 3], d: [f64; 3]) -> bool {
    match &scene.kind {
        SceneKind::Heightfield { tracer, .. } => tracer.occluded(o, d, f64::INFINITY),
        SceneKind::Mesh { tracer } => tracer.occluded(o, d, f64::INFINITY),
    }
}

/// `CameraModel::unproject` with an analytic Jacobian: the same Newton iteration on the same
/// equations (so the same root, to ~1e-12), but ~4x cheaper than the numerical Jacobian, which
/// matters at one call per sample.
pub(crate) fn unproject(cam: &CameraModel, u: f64, v: f64) -> (f64, f64) {
    let d = cam.distortion;
    let yd = (v - cam.cy) / cam.fy;
    let xd = (u - cam.cx - cam.skew * yd) / cam.fx;
    let (mut x, mut y) = (xd, yd);
    for _ in 0..20 {
        let r2 = x * x + y * y;
        let rad = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
        let drad = d.k1 + r2 * (2.0 * d.k2 + 3.0 * d.k3 * r2);
        let ex = x * rad + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x) - xd;
        let ey = y * rad + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y - yd;
        if ex.abs() < 1e-14 && ey.abs() < 1e-14 {
            break;
        }
        let j00 = rad + 2.0 * x * x * drad + 2.0 * d.p1 * y + 6.0 * d.p2 * x;
        let j01 = 2.0 * x * y * drad + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
        let j10 = 2.0 * x * y * drad + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
        let j11 = rad + 2.0 * y * y * drad + 6.0 * d.p1 * y + 2.0 * d.p2 * x;
        let det = j00 * j11 - j01 * j10;
        if det.abs() < 1e-12 {
            break;
        }
        x -= (j11 * ex - j01 * ey) / det;
        y -= (-j10 * ex + j00 * ey) / det;
    }
    (x, y)
}
