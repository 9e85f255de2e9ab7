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

/// A camera ray's first hit: what shading it under any light needs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SurfaceSample {
    hit: Hit,
    albedo: f32,
    /// What was hit: 0 the geometry, `i + 1` the scene's sphere `i`.
    object: u32,
}

/// The first hits of every camera ray of one view (row-major, every sample of a pixel in turn,
/// and its centre ray after them when the samples per axis are even; `None` where a ray sees
/// nothing): the view's geometry, traced once by [`super::Scene::primary_hits`], to be shaded
/// under several lights by [`super::Scene::relight`].
///
/// Why: a search over the light's direction renders the same view under many lights, and the
/// camera rays — which do not depend on the light — are most of a render's work. Shading kept
/// hits gives the bytes a full render gives.
#[derive(Debug, Clone)]
pub struct PrimaryHits {
    width: usize,
    height: usize,
    supersample: u32,
    hits: Vec<Option<SurfaceSample>>,
}

impl PrimaryHits {
    /// The same hits with the geometry's albedo `albedo` everywhere (the spheres keep theirs):
    /// the view of the same geometry under a uniform texture, without tracing it again.
    pub fn with_geometry_albedo(&self, albedo: f32) -> PrimaryHits {
        let mut out = self.clone();
        for s in out.hits.iter_mut().flatten() {
            if s.object == 0 {
                s.albedo = albedo;
            }
        }
        out
    }
}

/// The first hit of every camera ray of `view` (see [`PrimaryHits`]).
pub(crate) fn primary_hits(scene: &Scene<'_>, view: &View, opts: &RenderOptions) -> PrimaryHits {
    let rays = CameraRays::new(scene, view, opts);
    let per_pixel = samples_per_pixel(rays.n);
    let row_len = rays.w * per_pixel;
    let mut hits = vec![None; row_len * rays.h];
    if row_len > 0 {
        hits.par_chunks_mut(row_len)
            .enumerate()
            .for_each(|(r, row)| {
                for (i, hit) in row.iter_mut().enumerate() {
                    *hit = rays.first_hit(scene, i / per_pixel, r, i % per_pixel);
                }
            });
    }
    PrimaryHits {
        width: rays.w,
        height: rays.h,
        supersample: rays.n,
        hits,
    }
}

pub(crate) fn render_scene(
    scene: &Scene<'_>,
    light: &Light,
    view: &View,
    opts: &RenderOptions,
) -> Rendered {
    let rays = CameraRays::new(scene, view, opts);
    let shader = Shader::new(scene, light, opts.shadows);
    if opts.adaptive && rays.n > 1 {
        let n = rays.n;
        let centre_k = if n.is_multiple_of(2) {
            (n * n) as usize
        } else {
            ((n / 2) * n + n / 2) as usize
        };
        let pixel_spread = rays.spread * f64::from(n);
        return assemble_at_edges(scene, &rays, &shader, |c, r| {
            rays.hit_with_spread(scene, c, r, centre_k, pixel_spread)
        });
    }
    assemble(
        rays.w,
        rays.h,
        rays.n,
        |c, r, k| rays.first_hit(scene, c, r, k),
        |s, _| shader.shade(s),
    )
}

/// [`render_scene`] of `view` with `hits`, its camera rays' first hits at one sample a pixel
/// ([`primary_hits`] of the same view): the same bytes. An adaptive render takes its pixel
/// centres from them (a centre ray is the one-sample ray, its texture filtered over the same
/// pixel) and traces only its edge pixels' samples; a render at one sample a pixel is their
/// relight; any other sampling is traced as [`render_scene`] traces it.
pub(crate) fn render_from_hits(
    scene: &Scene<'_>,
    hits: &PrimaryHits,
    light: &Light,
    view: &View,
    opts: &RenderOptions,
) -> Rendered {
    let rays = CameraRays::new(scene, view, opts);
    let fits = hits.supersample == 1 && hits.width == rays.w && hits.height == rays.h;
    if !fits {
        return render_scene(scene, light, view, opts);
    }
    if rays.n == 1 {
        return relight(scene, hits, light, opts.shadows);
    }
    if !opts.adaptive {
        return render_scene(scene, light, view, opts);
    }
    let shader = Shader::new(scene, light, opts.shadows);
    assemble_at_edges(scene, &rays, &shader, |c, r| {
        hits.hits.get(r * rays.w + c).copied().flatten()
    })
}

/// Range ratio to the pixel's angular size past which two neighbouring pixel centres are not
/// on one surface: `tan 80°`. Two centres on one surface seen at incidence θ differ in range by
/// about `t · Δ · tan θ` (`Δ` the pixel's angle); more than a surface seen at 80° shows is an
/// occlusion edge, or ground so oblique that one sample misrepresents the pixel.
const EDGE_RANGE_SLOPE: f64 = 5.671_281_819_617_709;

/// Largest radiance difference between neighbouring pixel centres from their shading alone
/// (normal and light, at their mean albedo) that leaves a pixel at one sample: one digital
/// number at unit exposure (radiance 1 = 255 DN). Where two facets meet inside a pixel the
/// full samples' mean lies between the two sides' values, so one sample is off by at most this.
const SHADING_STEP: f64 = 1.0 / 255.0;

/// What the edge test of [`assemble_at_edges`] keeps of a pixel centre's ray.
#[derive(Clone, Copy)]
struct Centre {
    /// Ray parameter of the hit, `NaN` for a miss.
    t: f64,
    /// Radiance shaded from this one sample (its texture filtered over the whole pixel).
    radiance: f64,
    /// In the cast shadow of the light.
    shadowed: bool,
    /// What was hit ([`SurfaceSample::object`]).
    object: u32,
    /// Albedo of the hit.
    albedo: f64,
    /// Its radiance per unit albedo: what the light and the surface's normal make of it.
    shading: f64,
}

impl Centre {
    /// The centre ray's hit `s` (`None`: a miss) shaded by `shader`.
    fn of(s: Option<&SurfaceSample>, shader: &Shader<'_, '_>) -> Centre {
        match s {
            Some(s) => {
                let (radiance, shadowed) = shader.shade_lit(s);
                let albedo = f64::from(s.albedo);
                Centre {
                    t: s.hit.t,
                    radiance,
                    shadowed,
                    object: s.object,
                    albedo,
                    shading: if albedo > 0.0 { radiance / albedo } else { 0.0 },
                }
            }
            None => Centre {
                t: f64::NAN,
                radiance: 0.0,
                shadowed: false,
                object: 0,
                albedo: 0.0,
                shading: 0.0,
            },
        }
    }
}

/// The image with `n x n` samples only where they change it (`RenderOptions::adaptive`:
/// adaptive supersampling on what the samples see, not on the texture, which the mip filter
/// already integrates): every pixel's centre ray is traced once, its texture filtered over
/// the whole pixel's footprint, and shaded once; a pixel whose centre differs from a
/// 4-neighbour's in what it sees (surface or nothing, another object, a range jump past
/// [`EDGE_RANGE_SLOPE`], lit or in cast shadow, a shading step past [`SHADING_STEP`]) is an
/// edge pixel and gets the plain mean of its `n x n` samples, as [`assemble`] gives every
/// pixel. A straight edge that separates any sample of a pixel from its centre also
/// separates the centre from a 4-neighbour's, so such an edge is never missed. Depth and mask
/// come from the centre ray as there. Each pixel is a pure function of its own and its
/// neighbours' rays.
///
/// `centre(c, r)` is pixel `(c, r)`'s centre ray's hit, its texture filtered over the pixel:
/// traced here, or kept from [`primary_hits`] at one sample a pixel (the same ray and filter).
fn assemble_at_edges(
    scene: &Scene<'_>,
    rays: &CameraRays<'_>,
    shader: &Shader<'_, '_>,
    centre: impl Fn(usize, usize) -> Option<SurfaceSample> + Sync,
) -> Rendered {
    let (w, h, n) = (rays.w, rays.h, rays.n);
    let mut centres = vec![Centre::of(None, shader); w * h];
    if w > 0 {
        centres.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
            for (c, out) in row.iter_mut().enumerate() {
                *out = Centre::of(centre(c, r).as_ref(), shader);
            }
        });
    }
    let pixel_angle = 2.0 / (rays.cam.fx.abs() + rays.cam.fy.abs());
    let apart = |a: &Centre, b: &Centre| -> bool {
        match (a.t.is_nan(), b.t.is_nan()) {
            (true, true) => false,
            (false, false) => {
                a.shadowed != b.shadowed
                    || a.object != b.object
                    || 0.5 * (a.albedo + b.albedo) * (a.shading - b.shading).abs() > SHADING_STEP
                    || (a.t - b.t).abs() > EDGE_RANGE_SLOPE * pixel_angle * a.t.min(b.t)
            }
            _ => true,
        }
    };
    image_of(w, h, |c, r| {
        let Some(me) = centres.get(r * w + c) else {
            return (0.0, None);
        };
        let neighbours = [
            (c > 0).then(|| r * w + c - 1),
            (c + 1 < w).then(|| r * w + c + 1),
            (r > 0).then(|| (r - 1) * w + c),
            (r + 1 < h).then(|| (r + 1) * w + c),
        ];
        let edge = neighbours
            .into_iter()
            .flatten()
            .filter_map(|i| centres.get(i))
            .any(|o| apart(me, o));
        let value = if edge {
            let sum: f64 = (0..(n * n) as usize)
                .map(|k| {
                    rays.first_hit(scene, c, r, k)
                        .map_or(0.0, |s| shader.shade(&s))
                })
                .sum();
            sum / f64::from(n * n)
        } else {
            me.radiance
        };
        (value, (!me.t.is_nan()).then_some(me.t))
    })
}

/// `hits` shaded under `light` (cast shadows with `shadows`): byte for byte the render of the
/// view they were traced from.
pub(crate) fn relight(
    scene: &Scene<'_>,
    hits: &PrimaryHits,
    light: &Light,
    shadows: bool,
) -> Rendered {
    let shader = Shader::new(scene, light, shadows);
    shade_hits(hits, |s, _| shader.shade(s))
}

/// The image of `hits`, each hit's radiance `shade(hit, ray index)` (see [`assemble`]).
fn shade_hits(hits: &PrimaryHits, shade: impl Fn(&SurfaceSample, usize) -> f64 + Sync) -> Rendered {
    let (w, per_pixel) = (hits.width, samples_per_pixel(hits.supersample));
    assemble(
        w,
        hits.height,
        hits.supersample,
        |c, r, k| {
            hits.hits
                .get((r * w + c) * per_pixel + k)
                .copied()
                .flatten()
        },
        shade,
    )
}

/// Which camera rays of one view ([`PrimaryHits`], in their order) meet a surface in a light's
/// cast shadow, one bit a ray: all that a shadowed relight adds to a lit one, made by
/// [`super::Scene::cast_shadow`] and used by [`super::Scene::relight_cast`].
///
/// Why: a search over the light's direction comes back to the directions it has tried (each
/// capture's leave-one-out search walks the same lattice), and the shadow rays are what a
/// relight costs. Kept for a later relight they take a bit a ray, where the shadowed image
/// takes four bytes a pixel (a 1280 x 1024 view: 160 KB against 5.2 MB).
#[derive(Debug, Clone)]
pub struct CastShadow {
    /// The unit direction to the light the shadow rays were traced towards.
    to_light: [f64; 3],
    /// Bit `i % 64` of word `i / 64`: ray `i`'s hit is in the cast shadow.
    bits: Vec<u64>,
}

impl CastShadow {
    /// The bytes it keeps.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.bits.as_slice())
    }

    /// Whether ray `i`'s hit lies in the cast shadow.
    fn shadowed(&self, i: usize) -> bool {
        self.bits
            .get(i / 64)
            .is_some_and(|w| w & (1u64 << (i % 64)) != 0)
    }
}

/// The cast shadow of `light` on `hits` (see [`CastShadow`]).
pub(crate) fn cast_shadow(scene: &Scene<'_>, hits: &PrimaryHits, light: &Light) -> CastShadow {
    let shader = Shader::new(scene, light, true);
    let bits = hits
        .hits
        .par_chunks(64)
        .map(|rays| {
            rays.iter().enumerate().fold(0u64, |word, (k, s)| {
                if s.as_ref().is_some_and(|s| shader.in_shadow(s)) {
                    word | (1u64 << k)
                } else {
                    word
                }
            })
        })
        .collect();
    CastShadow {
        to_light: shader.to_light,
        bits,
    }
}

/// `hits` shaded under `light` with the cast shadow `cast`: byte for byte [`relight`] with
/// shadows when `cast` was made for this light's direction and these hits; otherwise (another
/// direction) the shadow rays are traced again, so the image is always the shadowed render's.
pub(crate) fn relight_cast(
    scene: &Scene<'_>,
    hits: &PrimaryHits,
    light: &Light,
    cast: &CastShadow,
) -> Rendered {
    let shader = Shader::new(scene, light, true);
    if shader.to_light != cast.to_light || cast.bits.len() != hits.hits.len().div_ceil(64) {
        return relight(scene, hits, light, true);
    }
    shade_hits(hits, |s, i| shader.radiance(s, cast.shadowed(i)))
}

/// The camera rays of one view: their directions in the ground frame and where they first
/// hit the scene.
struct CameraRays<'c> {
    w: usize,
    h: usize,
    n: u32,
    cam: &'c CameraModel,
    rot: [[f64; 3]; 3],
    centre: [f64; 3],
    table: Option<std::sync::Arc<RayTable>>,
    /// Neighbouring samples' spacing in normalised image coordinates (texture filtering).
    spread: f64,
}

impl<'c> CameraRays<'c> {
    fn new(scene: &Scene<'_>, view: &'c View, opts: &RenderOptions) -> CameraRays<'c> {
        let cam = &view.camera;
        let n = opts.supersample.max(1);
        CameraRays {
            w: cam.width as usize,
            h: cam.height as usize,
            n,
            cam,
            rot: view.ground_from_camera.rotation_matrix(),
            centre: view.ground_from_camera.translation_m,
            table: opts.distort.then(|| scene.ray_table(cam, n)),
            spread: if opts.filter_textures {
                2.0 / ((cam.fx.abs() + cam.fy.abs()) * f64::from(n))
            } else {
                0.0
            },
        }
    }

    /// Normalised undistorted coordinates of sample `k` (see [`sample_offset`]) of pixel
    /// `(c, r)`.
    fn xy(&self, c: usize, r: usize, k: usize) -> (f64, f64) {
        match &self.table {
            Some(t) => {
                t.xy.get((r * self.w + c) * samples_per_pixel(self.n) + k)
                    .map_or((f64::NAN, f64::NAN), |p| (p[0], p[1]))
            }
            None => {
                let (du, dv) = sample_offset(self.n, k);
                let (u, v) = (c as f64 + du, r as f64 + dv);
                let cam = self.cam;
                let y = (v - cam.cy) / cam.fy;
                ((u - cam.cx - cam.skew * y) / cam.fx, y)
            }
        }
    }

    /// The first hit of ray `k` of pixel `(c, r)`.
    fn first_hit(&self, scene: &Scene<'_>, c: usize, r: usize, k: usize) -> Option<SurfaceSample> {
        self.hit_with_spread(scene, c, r, k, self.spread)
    }

    /// [`CameraRays::first_hit`] with its texture filtered as if the samples were `spread`
    /// apart.
    fn hit_with_spread(
        &self,
        scene: &Scene<'_>,
        c: usize,
        r: usize,
        k: usize,
        spread: f64,
    ) -> Option<SurfaceSample> {
        let (x, y) = self.xy(c, r, k);
        let rot = &self.rot;
        let d = std::array::from_fn(|i| rot[i][0] * x + rot[i][1] * y + rot[i][2]);
        let (hit, albedo, object) = trace(scene, self.centre, d, spread)?;
        Some(SurfaceSample {
            hit,
            albedo,
            object,
        })
    }
}

/// Lambertian shading of hits under one light, with or without cast shadows.
struct Shader<'s, 'a> {
    scene: &'s Scene<'a>,
    to_light: [f64; 3],
    ambient: f64,
    shadows: bool,
    /// Shadow-ray start offset along the normal, metres.
    eps: f64,
}

impl<'s, 'a> Shader<'s, 'a> {
    fn new(scene: &'s Scene<'a>, light: &Light, shadows: bool) -> Shader<'s, 'a> {
        let eps = match &scene.kind {
            SceneKind::Heightfield { tracer, .. } => tracer.cell_m() * HF_SHADOW_EPS_CELLS,
            SceneKind::Mesh { tracer } => tracer.extent() * MESH_SHADOW_EPS,
        };
        Shader {
            scene,
            to_light: light_direction(light),
            ambient: light.ambient,
            shadows,
            eps,
        }
    }

    /// The radiance of `s`.
    fn shade(&self, s: &SurfaceSample) -> f64 {
        self.shade_lit(s).0
    }

    /// The radiance of `s`, and whether it lies in the light's cast shadow.
    fn shade_lit(&self, s: &SurfaceSample) -> (f64, bool) {
        let shadowed = self.in_shadow(s);
        (self.radiance(s, shadowed), shadowed)
    }

    /// Whether `s` lies in the light's cast shadow (never without shadows): it faces the light
    /// and a ray towards it meets the scene.
    fn in_shadow(&self, s: &SurfaceSample) -> bool {
        let (hit, to_light) = (&s.hit, self.to_light);
        let n_dot_l: f64 = (0..3).map(|k| hit.normal[k] * to_light[k]).sum();
        self.shadows && n_dot_l > 0.0 && {
            let o = std::array::from_fn(|k| hit.point[k] + hit.normal[k] * self.eps);
            occluded(self.scene, o, to_light)
        }
    }

    /// The radiance of `s`, `shadowed` or lit directly.
    fn radiance(&self, s: &SurfaceSample, shadowed: bool) -> f64 {
        shade(
            f64::from(s.albedo),
            self.ambient,
            s.hit.normal,
            self.to_light,
            if shadowed { 0.0 } else { 1.0 },
        )
    }
}

/// The image of `w x h` pixels at `n x n` samples each: the plain mean of the samples'
/// radiance (`shade` of each sample's first hit, `hit`, and its ray's index in
/// [`PrimaryHits`] order; a miss counts as 0), the depth and mask from the pixel centre's ray.
/// Rows in parallel, each pixel a pure function of its own samples.
fn assemble(
    w: usize,
    h: usize,
    n: u32,
    hit: impl Fn(usize, usize, usize) -> Option<SurfaceSample> + Sync,
    shade: impl Fn(&SurfaceSample, usize) -> f64 + Sync,
) -> Rendered {
    let odd_centre = (n % 2 == 1).then_some(((n / 2) * n + n / 2) as usize);
    let per_pixel = samples_per_pixel(n);
    image_of(w, h, |c, r| {
        let mut sum = 0.0;
        let mut centre_depth = None;
        for k in 0..(n * n) as usize {
            let s = hit(c, r, k);
            sum += s
                .as_ref()
                .map_or(0.0, |s| shade(s, (r * w + c) * per_pixel + k));
            if Some(k) == odd_centre {
                centre_depth = s.map(|s| s.hit.t);
            }
        }
        if n.is_multiple_of(2) {
            centre_depth = hit(c, r, (n * n) as usize).map(|s| s.hit.t);
        }
        (sum / f64::from(n * n), centre_depth)
    })
}

/// The `w x h` image whose pixel `(c, r)` is `pixel(c, r)`: its radiance and the depth of the
/// surface its centre sees (`None`: nothing, depth `NaN` and mask 0). Rows in parallel, each
/// written in place, each pixel computed once, so the bytes do not depend on the thread count.
fn image_of(
    w: usize,
    h: usize,
    pixel: impl Fn(usize, usize) -> (f64, Option<f64>) + Sync,
) -> Rendered {
    let mut out = Rendered {
        width: w,
        height: h,
        radiance: vec![0.0; w * h],
        depth: vec![f32::NAN; w * h],
        mask: vec![0; w * h],
    };
    if w == 0 {
        return out;
    }
    out.radiance
        .par_chunks_mut(w)
        .zip(out.depth.par_chunks_mut(w))
        .zip(out.mask.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, ((radiance, depth), mask))| {
            for (c, ((v, d), m)) in radiance
                .iter_mut()
                .zip(depth.iter_mut())
                .zip(mask.iter_mut())
                .enumerate()
            {
                let (value, centre) = pixel(c, r);
                *v = value as f32;
                if let Some(t) = centre {
                    *d = t as f32;
                    *m = 255;
                }
            }
        });
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

/// The nearest hit and its albedo (filtered over the footprint of a sample `spread` wide in
/// normalised image coordinates): the geometry's or a sphere's, whichever is nearer.
/// The nearest hit, its albedo and what it belongs to (see [`SurfaceSample::object`]).
fn trace(scene: &Scene<'_>, o: [f64; 3], d: [f64; 3], spread: f64) -> Option<(Hit, f32, u32)> {
    let ground = trace_geometry(scene, o, d, spread);
    let t_max = ground.map_or(f64::INFINITY, |(h, _)| h.t);
    let ball = (1u32..)
        .zip(&scene.spheres)
        .filter_map(|(i, s)| s.hit(o, d, 0.0, t_max).map(|h| (h, s.albedo, i)))
        .min_by(|a, b| a.0.t.total_cmp(&b.0.t));
    ball.or(ground.map(|(h, a)| (h, a, 0)))
}

/// The nearest hit of the scene's geometry (spheres aside) and its albedo.
fn trace_geometry(scene: &Scene<'_>, o: [f64; 3], d: [f64; 3], spread: f64) -> Option<(Hit, f32)> {
    match &scene.kind {
        SceneKind::Heightfield {
            tracer,
            albedo,
            mips,
        } => {
            let hit = tracer.trace(o, d, f64::INFINITY)?;
            let foot = footprint_m(hit.t, d, hit.normal, spread);
            let a = sample_albedo_filtered(albedo, mips, hit.point[0], hit.point[1], foot);
            Some((hit, a))
        }
        SceneKind::Mesh { tracer } => tracer.trace_albedo(o, d, f64::INFINITY, spread),
    }
}

fn occluded(scene: &Scene<'_>, o: [f64; 3], d: [f64; 3]) -> bool {
    let ball = || {
        scene
            .spheres
            .iter()
            .any(|s| s.hit(o, d, 0.0, f64::INFINITY).is_some())
    };
    ball()
        || match &scene.kind {
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
