//! Deterministic CPU renderer: re-renders a heightfield or a triangle mesh at a camera pose.
//!
//! Design decisions:
//! * **Ray casting, not rasterisation.** Every output pixel is unprojected through the
//!   [`CameraModel`] (pixel `(0, 0)` = centre of the top-left pixel) and traced, so a raw
//!   *distorted* image is rendered directly, without a remap, and the same tracer serves the
//!   corpus' laser-scan simulation ([`HeightfieldTracer`]). Inverting the distortion is a Newton
//!   iteration per ray, so a [`Scene`] keeps each camera's rays in a table (`raster::RayTable`)
//!   and the next views of that camera (validate renders every camera at every capture) skip it.
//! * **Heightfields** are traced through a min/max quadtree ("max-mip") over the cell quads,
//!   see [`heightfield`]; every quad between four cell centres is split along its NW–SE diagonal
//!   into two planar triangles, the same split as the compiler's glTF meshes. **Meshes** are
//!   traced through a bounding-volume hierarchy ([`mesh`]) and shaded with per-face normals.
//!   A scene may also hold exact [`Sphere`]s beside its geometry (a synthetic campaign's
//!   survey marker balls), intersected analytically.
//! * **Texture filtering**: a ray sample whose footprint on the surface spans more than one
//!   texel reads the texture's box-filtered mip levels, trilinearly at `log2(footprint)`
//!   (`shading::MipChain`; the footprint is the side of the square with the area of the
//!   sample's footprint ellipse, from the hit distance, the sample spacing and the incidence).
//!   A point-sampled fine texture seen from afar aliases into noise; a magnified one (the usual
//!   case for rover cameras over a terrain texture) is sampled bilinearly exactly as without.
//!   Heightfield albedo and mesh textures filter alike (a mesh triangle's texel size comes from
//!   its uv and world areas), so a heightfield and its mesh still render alike.
//! * **Samples per pixel**: `supersample = n` takes `n x n` stratified samples per pixel and
//!   box-filters them; with [`RenderOptions::adaptive`] only edge pixels do — where a pixel's
//!   centre ray sees other geometry, light or shading than a neighbour's (an occlusion edge, an
//!   outline, a cast shadow's edge, a crease between facets) — and every other pixel is shaded
//!   once from its centre ray with its texture filtered over the whole pixel: within one smooth
//!   surface the texture filter does what the samples would. `validate` renders so, with 1.3
//!   to 2.3 rays a pixel instead of 5 on the corpus's laser entries.
//! * **Shading** is Lambertian with an ambient share (see [`shading`]):
//!   `radiance = albedo * (ambient + (1 - ambient) * max(0, n·l) * visible)`, where `visible`
//!   is 0 when a shadow ray toward the light hits the terrain (only with `shadows: true`).
//! * **Relighting:** a view's camera rays can be traced once ([`Scene::primary_hits`]) and
//!   their first hits shaded under other lights ([`Scene::relight`]), byte for byte a render
//!   under each: the search for a light's direction renders the same views under dozens of
//!   lights, and the camera rays are most of a render's work. A light's cast shadow on them
//!   can be kept, one bit a ray ([`Scene::cast_shadow`]), and shaded again without a shadow
//!   ray ([`Scene::relight_cast`]), for the directions a search comes back to.
//! * **Determinism:** rows are rendered in parallel with rayon, but every pixel is a pure
//!   function of its coordinates (no reductions across pixels), so the bytes do not depend on
//!   the number of threads.
//! * Bad geometry never panics: a height grid whose `z` is shorter than `width * height` treats
//!   the missing cells as holes, non-finite heights are holes, and a triangle with an
//!   out-of-range vertex index is skipped.

pub mod grid_mesh;
pub mod heightfield;
pub mod mesh;
mod raster;
pub mod shading;

/// The renderer's own inverse of the lens distortion, for code that back-projects its pixels.
pub(crate) use raster::unproject;
pub use raster::{CastShadow, PrimaryHits};

use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;

pub use heightfield::{HeightfieldTracer, Hit};
pub use mesh::MeshTracer;
pub use regolith_format::grid::{AlbedoGrid, HeightGrid};
pub use regolith_format::lighting::Light;

/// A triangle mesh in the ground frame (z up) with per-vertex albedo and an optional texture.
#[derive(Debug, Clone, PartialEq)]
pub struct TriMeshF32 {
    /// Ground position that `positions` are relative to.
    pub origin_m: [f64; 3],
    /// Vertex positions relative to `origin_m`.
    pub positions: Vec<[f32; 3]>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
    /// Albedo per vertex, 0..1 (missing values count as 0); used by the triangles the texture
    /// does not cover (SfM vertex colours).
    pub albedo: Vec<f32>,
    /// Texture: a triangle whose three vertices have finite texture coordinates takes its albedo
    /// from the texture instead of `albedo`.
    pub texture: Option<MeshTexture>,
}

/// The albedo texture of a [`TriMeshF32`] (a glTF base-colour texture reduced to one channel).
///
/// Sampler (SPEC §5.3): glTF texture coordinates, `(0, 0)` = the top-left corner of the image,
/// `v` down; texel `(i, j)` has its centre at `((i + 0.5) / width, (j + 0.5) / height)`;
/// bilinear between texel centres, clamped to the edge texels (`CLAMP_TO_EDGE`). The value at
/// a hit is that sample at the barycentrically interpolated coordinates, which for a ray caster
/// is the perspective-correct texture coordinate.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshTexture {
    /// Texture coordinates `(u, v)` per vertex (same indexing as `positions`); a missing or
    /// non-finite one leaves its triangles to the per-vertex albedo.
    pub uvs: Vec<[f32; 2]>,
    /// Image width in texels.
    pub width: usize,
    /// Image height in texels.
    pub height: usize,
    /// Albedo 0..1, row-major, row 0 at `v = 0` (non-finite values count as 0).
    pub value: Vec<f32>,
}

/// What to render.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// A height grid with its albedo raster.
    Heightfield {
        /// Heights.
        grid: HeightGrid,
        /// Albedo.
        albedo: AlbedoGrid,
    },
    /// A triangle mesh with per-vertex albedo or a texture.
    Mesh(TriMeshF32),
}

/// A camera and its pose.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Intrinsics; the output has `camera.width x camera.height` pixels.
    pub camera: CameraModel,
    /// Camera pose (camera axes: x right, y down, z forward).
    pub ground_from_camera: Pose,
}

impl View {
    /// A camera at `eye` looking at `target` with its image "up" toward ground +z (x right,
    /// y down, z forward). A vertical view direction (no defined "right") uses ground +x as the
    /// image right.
    pub fn look_at(camera: CameraModel, eye: [f64; 3], target: [f64; 3]) -> View {
        let f = normalise([target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]]);
        let mut right = normalise(cross(f, [0.0, 0.0, 1.0]));
        if !right.iter().all(|c| c.is_finite()) || right == [0.0; 3] {
            right = [1.0, 0.0, 0.0];
        }
        let down = cross(f, right);
        let r = [
            [right[0], down[0], f[0]],
            [right[1], down[1], f[1]],
            [right[2], down[2], f[2]],
        ];
        View {
            camera,
            ground_from_camera: Pose::from_matrix(r, eye),
        }
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalise(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 0.0 {
        [v[0] / n, v[1] / n, v[2] / n]
    } else {
        [0.0; 3]
    }
}

/// Rendering switches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderOptions {
    /// `true`: the raw (distorted) image of the camera model; `false`: the undistorted pinhole
    /// image of the same camera.
    pub distort: bool,
    /// Cast shadows of the light.
    pub shadows: bool,
    /// 1 = one sample at each pixel centre; `n` = `n x n` stratified samples, box-filtered.
    pub supersample: u32,
    /// Filter textures over each sample's footprint (mip levels, trilinear) where a sample
    /// spans more than one texel; `false` point-samples them bilinearly (magnified textures
    /// are sampled the same way either way).
    pub filter_textures: bool,
    /// With `supersample > 1`, take the `n x n` samples only at edge pixels — where a pixel's
    /// centre ray sees other geometry, light or shading than a neighbour's (an occlusion edge,
    /// the terrain's outline, a cast shadow's edge, a crease of more than one digital number)
    /// — and elsewhere shade the centre ray once, its texture filtered over the whole pixel.
    /// Not for [`Scene::primary_hits`], which keeps every sample.
    pub adaptive: bool,
}

/// How densely a render samples its pixels: `n x n` samples at every pixel, or only at its
/// edge pixels ([`RenderOptions::adaptive`]). A plain number is `Full`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampling {
    /// `n x n` samples at every pixel.
    Full(u32),
    /// `n x n` samples at edge pixels, one shaded sample elsewhere.
    Edges(u32),
}

impl From<u32> for Sampling {
    fn from(n: u32) -> Sampling {
        Sampling::Full(n)
    }
}

impl Sampling {
    /// Samples per axis where the most are taken.
    pub fn supersample(self) -> u32 {
        match self {
            Sampling::Full(n) | Sampling::Edges(n) => n,
        }
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            distort: true,
            shadows: false,
            supersample: 1,
            filter_textures: true,
            adaptive: false,
        }
    }
}

/// A rendered view.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear radiance, row-major (0 where nothing is seen).
    pub radiance: Vec<f32>,
    /// Camera-frame z of the surface seen at the pixel centre, metres; `NaN` where nothing is seen.
    pub depth: Vec<f32>,
    /// 255 where the pixel centre sees the surface, 0 otherwise.
    pub mask: Vec<u8>,
}

/// Geometry prepared for rendering (acceleration structure built once); reuse it to render
/// many views of the same terrain.
pub struct Scene<'a> {
    pub(crate) kind: SceneKind<'a>,
    /// Camera-ray tables of the cameras rendered so far, see [`RayTables`].
    rays: std::sync::Arc<RayTables>,
    /// Exact spheres standing on the geometry (survey marker balls), see [`Sphere`].
    pub(crate) spheres: Vec<Sphere>,
}

/// An exact sphere rendered beside the scene's geometry: a survey marker ball.
///
/// Why: a ball stamped into a height grid keeps only its cap, faceted to the grid's cells,
/// so its image's centre sits a tenth of a pixel or more from the projection of the ball's
/// centre, which no sighting can correct. Captures of a synthetic campaign render their balls
/// as spheres, so a ball's sighting is as exact as a real ball's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Ground-frame centre, metres.
    pub centre: [f64; 3],
    /// Radius, metres.
    pub radius: f64,
    /// Diffuse albedo of its surface.
    pub albedo: f32,
}

impl Sphere {
    /// The nearest hit of the ray `o + t d` (`d` need not be unit) with `t_min < t < t_max`;
    /// its normal points outward. A sphere of no (or no finite) radius is never hit.
    pub fn hit(&self, o: [f64; 3], d: [f64; 3], t_min: f64, t_max: f64) -> Option<Hit> {
        let oc: [f64; 3] = std::array::from_fn(|k| o[k] - self.centre[k]);
        let a: f64 = d.iter().map(|v| v * v).sum();
        let b: f64 = (0..3).map(|k| oc[k] * d[k]).sum();
        let c: f64 = oc.iter().map(|v| v * v).sum::<f64>() - self.radius * self.radius;
        let disc = b * b - a * c;
        if a <= 0.0 || disc < 0.0 || self.radius <= 0.0 || !self.radius.is_finite() {
            return None;
        }
        let root = disc.sqrt();
        let t = [(-b - root) / a, (-b + root) / a]
            .into_iter()
            .find(|t| *t > t_min && *t < t_max)?;
        let point: [f64; 3] = std::array::from_fn(|k| o[k] + t * d[k]);
        let normal = std::array::from_fn(|k| (point[k] - self.centre[k]) / self.radius);
        Some(Hit { t, point, normal })
    }
}

/// Ray tables kept (one per camera and sampling rate; a stereo rig needs two).
const RAY_TABLES: usize = 4;

/// The camera-ray tables of the cameras rendered so far, most recent last (see
/// `RayTable`). A scene keeps its own; scenes of different geometry seen by the same
/// cameras (the entries of one release) can share one ([`Scene::sharing_rays`]), so the rays
/// are computed once per camera, not once per entry (4 % of a release's validation).
#[derive(Default)]
pub struct RayTables(std::sync::Mutex<Vec<std::sync::Arc<raster::RayTable>>>);

pub(crate) enum SceneKind<'a> {
    Heightfield {
        tracer: HeightfieldTracer,
        albedo: &'a AlbedoGrid,
        mips: shading::MipChain,
    },
    Mesh {
        tracer: MeshTracer,
    },
}

impl<'a> Scene<'a> {
    /// Builds the acceleration structure of `geometry`.
    pub fn new(geometry: &'a Geometry) -> Scene<'a> {
        let kind = match geometry {
            Geometry::Heightfield { grid, albedo } => SceneKind::Heightfield {
                tracer: HeightfieldTracer::new(grid),
                albedo,
                mips: shading::MipChain::new(albedo.width, albedo.height, &albedo.value),
            },
            Geometry::Mesh(m) => SceneKind::Mesh {
                tracer: MeshTracer::new(m),
            },
        };
        Scene {
            kind,
            rays: std::sync::Arc::default(),
            spheres: Vec::new(),
        }
    }

    /// The scene taking its camera-ray tables from (and adding them to) `tables`, which
    /// other scenes may share: the tables depend on the camera only.
    pub fn sharing_rays(mut self, tables: std::sync::Arc<RayTables>) -> Scene<'a> {
        self.rays = tables;
        self
    }

    /// The scene with `spheres` standing on its geometry: they are seen, shaded and cast
    /// shadows like the geometry, and are nearer than it where a ray meets both.
    pub fn with_spheres(mut self, spheres: Vec<Sphere>) -> Scene<'a> {
        self.spheres = spheres;
        self
    }

    /// The ray table of `camera` at `supersample`, built on first use and kept for the next
    /// views of the same camera.
    pub(crate) fn ray_table(
        &self,
        camera: &CameraModel,
        supersample: u32,
    ) -> std::sync::Arc<raster::RayTable> {
        let n = supersample.max(1);
        let hit = |t: &std::sync::Arc<raster::RayTable>| t.camera == *camera && t.supersample == n;
        if let Ok(tables) = self.rays.0.lock() {
            if let Some(t) = tables.iter().find(|t| hit(t)) {
                return t.clone();
            }
        }
        let table = std::sync::Arc::new(raster::RayTable::new(camera, n));
        if let Ok(mut tables) = self.rays.0.lock() {
            if !tables.iter().any(hit) {
                if tables.len() == RAY_TABLES {
                    tables.remove(0);
                }
                tables.push(table.clone());
            }
        }
        table
    }

    /// Renders one view.
    pub fn render(&self, light: &Light, view: &View, opts: &RenderOptions) -> Rendered {
        raster::render_scene(self, light, view, opts)
    }

    /// The first hits of `view`'s camera rays (`opts.shadows` aside, the options of a render),
    /// to be shaded under several lights by [`Scene::relight`].
    pub fn primary_hits(&self, view: &View, opts: &RenderOptions) -> PrimaryHits {
        raster::primary_hits(self, view, opts)
    }

    /// [`Scene::render`] of `view` given `hits`, its first hits at one sample a pixel
    /// ([`Scene::primary_hits`] of the same view and options but the sampling): the same bytes,
    /// an adaptive render tracing only its edge pixels' samples.
    pub fn render_from_hits(
        &self,
        hits: &PrimaryHits,
        light: &Light,
        view: &View,
        opts: &RenderOptions,
    ) -> Rendered {
        raster::render_from_hits(self, hits, light, view, opts)
    }

    /// `hits` (traced in this scene) shaded under `light`, with cast shadows when `shadows`:
    /// the same bytes as [`Scene::render`] of their view.
    pub fn relight(&self, hits: &PrimaryHits, light: &Light, shadows: bool) -> Rendered {
        raster::relight(self, hits, light, shadows)
    }

    /// Which of `hits` lie in `light`'s cast shadow, kept to shade them again under the same
    /// light by [`Scene::relight_cast`] without tracing a shadow ray.
    pub fn cast_shadow(&self, hits: &PrimaryHits, light: &Light) -> CastShadow {
        raster::cast_shadow(self, hits, light)
    }

    /// `hits` shaded under `light` with its cast shadow `cast`: the same bytes as
    /// [`Scene::relight`] with shadows (traced again if `cast` is another direction's).
    pub fn relight_cast(&self, hits: &PrimaryHits, light: &Light, cast: &CastShadow) -> Rendered {
        raster::relight_cast(self, hits, light, cast)
    }
}

/// Renders `geometry` seen by `view` under `light`. Builds the acceleration structure on every
/// call; use [`Scene`] to render several views of the same geometry.
pub fn render(geometry: &Geometry, light: &Light, view: &View, opts: &RenderOptions) -> Rendered {
    Scene::new(geometry).render(light, view, opts)
}
