//! NavCam frames from an existing physically based renderer plus this crate's own camera.
//!
//! **The renderer.** Mitsuba 3 (`tools/render/mitsuba_captures.py`, pinned by
//! `tools/render/install.sh`) path-traces the true terrain — a triangle mesh of the truth grid,
//! split as the format splits it, textured with the true albedo and given an Oren–Nayar rough
//! diffuse reflectance — with the marker balls as spheres, inside a lab hall: the bed's wooden
//! border, the floor, four textured walls, a lamp stand and cases. The lab lamp is a square
//! area light of finite size at finite distance in the campaign light's direction, plus an
//! ambient sky through the open top of the hall; light bounces between rocks, walls and floor.
//! The renderer draws an ideal pinhole image (no distortion) slightly wider than the real
//! camera's view, in linear radiance (1.0 = 255 DN at unit exposure).
//!
//! **The camera** ([`crate::camera`]) turns that radiance into the 8-bit frames: the true lens
//! distortion by remapping, a defocus + diffraction PSF, fixed-pattern and temporal noise, the
//! hidden image effects of the catalogue, quantisation.
//!
//! **The render cache.** A render depends on the scene (terrain, albedo, markers, room, lamp),
//! the shot (canvas intrinsics, pose) and the sample count. Each render is stored as `<key>.png`
//! (8-bit square-root codes, [`cache_code`]) under the cache folder, `key` = SHA-256 of all of it,
//! beside `<key>.json` (renderer, version, variant, seconds). A campaign whose renders are all in
//! the cache needs no renderer: the repository keeps the renders of its reference campaigns
//! (`corpus/renders/`), so CI regenerates those campaigns without Mitsuba. Image effects act
//! after the render, so every image-effect variant of a seed shares its renders; only a moved
//! lamp (`shadows`) or camera (`pose-bias`) renders anew. The canvas is sized for the widest
//! distortion the catalogue can hide, so a hidden `distortion` shares the renders too.

use std::path::{Path, PathBuf};
use std::process::Command;

use regolith_format::camera_model::CameraModel;
use regolith_format::effects::Effect;
use regolith_format::lighting::Light;
use serde::Serialize;
use sha2::{Digest, Sha256};

use super::{CaptureRenderer, CaptureScene, RendererInfo, Shot};
use crate::camera::{self, CameraPhysics, HiddenOptics, PinholeImage};
use crate::seeding::{item_rng, stage_hash};
use crate::terrain::materials::MARKER_ALBEDO;
use crate::terrain::Terrain;
use crate::CorpusError;

/// Version of the scene description and of the way this module builds it: part of every
/// render's cache key.
pub const SCENE_FORMAT: &str = "regolith-corpus-scene/1";

/// Roughness of the regolith's Oren–Nayar reflectance, degrees: the slope spread of a sandy
/// soil's grains (Oren & Nayar 1994 fit 20–40° to sand and plaster; the lower end, since the
/// relief itself is in the mesh).
pub const REGOLITH_ROUGHNESS_DEG: f64 = 20.0;
/// Side of the lab lamp's square emitting face, metres (a studio flood light).
pub const LAMP_SIZE_M: f64 = 0.4;
/// Horizontal clearance between the bed and the hall's walls, metres.
const WALL_CLEARANCE_M: f64 = 1.5;
/// The largest barrel distortion the catalogue can hide (`distortion` dk1, dk2 at their
/// ranges' negative ends): the canvas is sized for it, so every distortion shares renders.
const WIDEST_DK: [f64; 2] = [-0.05, -0.02];
/// Margin around the canvas for the PSF, real pixels.
const PSF_MARGIN_PX: f64 = 6.0;

/// How the physical captures are made.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalOptions {
    /// The render cache folder (created if absent).
    pub renders: PathBuf,
    /// The Mitsuba driver script; `None`: use the cache only, and say which renders are
    /// missing.
    pub driver: Option<PathBuf>,
    /// Python interpreter that runs the driver.
    pub python: PathBuf,
    /// Samples per canvas pixel.
    pub spp: u32,
    /// Canvas pixels per real pixel, per axis.
    pub oversample: u32,
    /// The camera's fixed properties.
    pub physics: CameraPhysics,
}

impl PhysicalOptions {
    /// Defaults: a canvas at the real pixel pitch, 256 samples per pixel (see
    /// `corpus/renders/README.md` for the measured render noise against the sensor's), the
    /// NavCam's physics, `python3`.
    pub fn new(renders: PathBuf, driver: Option<PathBuf>) -> PhysicalOptions {
        PhysicalOptions {
            renders,
            driver,
            python: PathBuf::from("python3"),
            spp: 128,
            oversample: 1,
            physics: CameraPhysics::NAVCAM,
        }
    }
}

/// Mitsuba-rendered frames through the corpus's camera (see the module docs).
#[derive(Debug)]
pub struct PhysicalCaptures {
    opts: PhysicalOptions,
    used: std::sync::Mutex<Vec<RenderRecord>>,
}

/// One render used by a campaign, for `truth/renderer.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct RenderRecord {
    shot: String,
    key: String,
    renderer: serde_json::Value,
}

impl PhysicalCaptures {
    /// A renderer with these options.
    pub fn new(opts: PhysicalOptions) -> PhysicalCaptures {
        PhysicalCaptures {
            opts,
            used: std::sync::Mutex::new(Vec::new()),
        }
    }
}

/// The scene files and description the driver reads.
struct SceneFiles {
    json: serde_json::Value,
    ply: Vec<u8>,
    albedo_exr: Vec<u8>,
    /// SHA-256 over the description and the files.
    hash: String,
}

/// One shot as the renderer sees it: the pinhole canvas and the pose.
#[derive(Debug, Clone, Serialize)]
struct CanvasShot {
    name: String,
    seed: u64,
    width: usize,
    height: usize,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    ground_from_camera: [[f64; 4]; 4],
}

impl CaptureRenderer for PhysicalCaptures {
    fn frames(
        &self,
        scene: &CaptureScene<'_>,
        shots: &[Shot],
        progress: &dyn Fn(f64),
    ) -> Result<Vec<[Vec<u8>; 2]>, CorpusError> {
        let files = scene_files(scene)?;
        let canvases: Vec<CanvasShot> = shots
            .iter()
            .map(|s| canvas_shot(s, self.opts.oversample, scene.seed))
            .collect();
        let keys: Vec<String> = canvases
            .iter()
            .map(|c| render_key(&files.hash, c, self.opts.spp))
            .collect();
        std::fs::create_dir_all(&self.opts.renders)
            .map_err(CorpusError::io("the render cache", &self.opts.renders))?;
        let missing: Vec<usize> = (0..shots.len())
            .filter(|&i| {
                keys.get(i)
                    .is_none_or(|k| !self.opts.renders.join(format!("{k}.png")).is_file())
            })
            .collect();
        if !missing.is_empty() {
            self.render_missing(&files, &canvases, &keys, &missing, progress)?;
        }
        let hidden = hidden_optics(scene.effects);
        let mut out = Vec::with_capacity(shots.len());
        let mut used = Vec::new();
        for ((shot, canvas), key) in shots.iter().zip(&canvases).zip(&keys) {
            let path = self.opts.renders.join(format!("{key}.png"));
            let (w, h, radiance) = read_cached(&path)?;
            if (w, h) != (canvas.width, canvas.height) {
                return Err(CorpusError::Option {
                    option: "--renders",
                    expected: format!(
                        "a {}x{} render in {}",
                        canvas.width,
                        canvas.height,
                        path.display()
                    ),
                    found: format!("{w}x{h}"),
                });
            }
            let mut radiance = radiance;
            if shot.exposure_gain != 1.0 {
                let g = shot.exposure_gain as f32;
                radiance.iter_mut().for_each(|r| *r *= g);
            }
            let pinhole = PinholeImage {
                width: canvas.width,
                height: canvas.height,
                fx: canvas.fx,
                fy: canvas.fy,
                cx: canvas.cx,
                cy: canvas.cy,
                radiance,
            };
            let fixed = stage_hash(scene.seed, "camera.fixed-pattern", shot.camera_index as u64);
            let mut frames = camera::expose_frames(
                &pinhole,
                &shot.camera,
                &self.opts.physics,
                &hidden,
                fixed,
                &[shot.noise_seed, shot.noise_seed.wrapping_add(1)],
            )
            .into_iter();
            let mut next = || frames.next().unwrap_or_default();
            out.push([next(), next()]);
            let meta = std::fs::read(self.opts.renders.join(format!("{key}.json")))
                .ok()
                .and_then(|b| serde_json::from_slice(&b).ok())
                .unwrap_or(serde_json::Value::Null);
            used.push(RenderRecord {
                shot: shot.name.clone(),
                key: key.clone(),
                renderer: meta,
            });
        }
        if let Ok(mut u) = self.used.lock() {
            *u = used;
        }
        Ok(out)
    }

    fn world(&self) -> crate::lab::World {
        crate::lab::World::LAB
    }

    fn info(&self) -> RendererInfo {
        let used = self.used.lock().map(|u| u.clone()).unwrap_or_default();
        RendererInfo {
            name: "mitsuba".into(),
            independent_of_validator: true,
            details: serde_json::json!({
                "scene_format": SCENE_FORMAT,
                "driver": "tools/render/mitsuba_captures.py",
                "samples_per_canvas_pixel": self.opts.spp,
                "oversample": self.opts.oversample,
                "terrain_bsdf": {"model": "oren-nayar", "roughness_deg": REGOLITH_ROUGHNESS_DEG},
                "markers_bsdf": {"model": "lambert", "albedo": MARKER_ALBEDO},
                "lamp": {"shape": "square area light facing the bed centre", "size_m": LAMP_SIZE_M},
                "room": "open-topped hall: floor, four textured walls, the bed's wooden border, a lamp stand, cases (scene.json)",
                "camera": camera_details(&self.opts.physics),
                "renders": used,
            }),
        }
    }
}

impl PhysicalCaptures {
    /// Writes the scene into a work folder of the cache, runs the driver on the missing
    /// shots, and stores each result under its key.
    fn render_missing(
        &self,
        files: &SceneFiles,
        canvases: &[CanvasShot],
        keys: &[String],
        missing: &[usize],
        progress: &dyn Fn(f64),
    ) -> Result<(), CorpusError> {
        let names: Vec<&str> = missing
            .iter()
            .filter_map(|&i| canvases.get(i).map(|c| c.name.as_str()))
            .collect();
        let Some(driver) = &self.opts.driver else {
            return Err(CorpusError::Option {
                option: "--renders",
                expected: format!(
                    "renders of shots {} in {} (to make them, install Mitsuba with tools/render/install.sh and run without --no-render; a binary outside its source tree also needs REGOLITH_MITSUBA_DRIVER=<path of tools/render/mitsuba_captures.py>)",
                    names.join(", "),
                    self.opts.renders.display()
                ),
                found: "no such renders".into(),
            });
        };
        let work = self
            .opts
            .renders
            .join(format!("scene-{}", &files.hash[..16]));
        let out_dir = work.join("out");
        std::fs::create_dir_all(&out_dir).map_err(CorpusError::io("a render folder", &out_dir))?;
        let write = |name: &str, bytes: &[u8]| {
            let p = work.join(name);
            std::fs::write(&p, bytes).map_err(CorpusError::io("a scene file", &p))
        };
        write("terrain.ply", &files.ply)?;
        write("albedo.exr", &files.albedo_exr)?;
        let mut json = files.json.clone();
        json["shots"] = serde_json::to_value(
            missing
                .iter()
                .filter_map(|&i| canvases.get(i))
                .collect::<Vec<_>>(),
        )
        .unwrap_or_default();
        let scene_path = work.join("scene.json");
        write(
            "scene.json",
            serde_json::to_string_pretty(&json)
                .unwrap_or_default()
                .as_bytes(),
        )?;
        progress(0.0);
        let status = Command::new(&self.opts.python)
            .arg(driver)
            .arg(&scene_path)
            .arg(&out_dir)
            .arg("--spp")
            .arg(self.opts.spp.to_string())
            .status()
            .map_err(CorpusError::io("the Mitsuba driver (python3)", driver))?;
        if !status.success() {
            return Err(CorpusError::Option {
                option: "--renderer",
                expected: format!(
                    "a working Mitsuba driver (tools/render/install.sh; {} exited with {status})",
                    driver.display()
                ),
                found: driver.display().to_string(),
            });
        }
        let manifest: serde_json::Value = std::fs::read(out_dir.join("renders.json"))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or(serde_json::Value::Null);
        for &i in missing {
            let (Some(c), Some(key)) = (canvases.get(i), keys.get(i)) else {
                continue;
            };
            let y = read_y(&out_dir.join(format!("{}.exr", c.name)))?;
            if y.len() != c.width * c.height {
                return Err(CorpusError::Option {
                    option: "--renderer",
                    expected: format!(
                        "a {}x{} render of {} from the driver",
                        c.width, c.height, c.name
                    ),
                    found: format!("{} samples", y.len()),
                });
            }
            let dst = self.opts.renders.join(format!("{key}.png"));
            write_cached(&dst, c.width, c.height, &y)?;
            let shot_meta = manifest["shots"]
                .as_array()
                .and_then(|a| a.iter().find(|s| s["name"] == c.name.as_str()))
                .cloned()
                .unwrap_or(serde_json::Value::Null);
            let meta = serde_json::json!({
                "renderer": manifest["renderer"],
                "mitsuba_version": manifest["mitsuba_version"],
                "variant": manifest["variant"],
                "spp": manifest["spp"],
                "integrator": manifest["integrator"],
                "bsdf": manifest["bsdf"],
                "seconds": shot_meta["seconds"],
            });
            let p = self.opts.renders.join(format!("{key}.json"));
            std::fs::write(&p, serde_json::to_string_pretty(&meta).unwrap_or_default())
                .map_err(CorpusError::io("a render record", &p))?;
        }
        let _ = std::fs::remove_dir_all(&work);
        progress(1.0);
        Ok(())
    }
}

/// The canvas of a shot: the calibrated camera made as barrel as the catalogue allows, so the
/// canvas covers every hidden distortion; the true pose.
fn canvas_shot(shot: &Shot, oversample: u32, seed: u64) -> CanvasShot {
    let mut widest: CameraModel = shot.calibrated.clone();
    widest.distortion.k1 += WIDEST_DK[0];
    widest.distortion.k2 += WIDEST_DK[1];
    let spec = camera::pinhole_canvas(&widest, oversample, PSF_MARGIN_PX);
    // Renderers draw square pixels: the finer focal length on both axes, the canvas stretched
    // to cover the same field.
    let f = spec.fx.max(spec.fy);
    let stretch = |n: usize, c: f64, fa: f64| {
        let k = f / fa;
        ((((n.max(1) - 1) as f64) * k).ceil() as usize + 1, c * k)
    };
    let (width, cx) = stretch(spec.width, spec.cx, spec.fx);
    let (height, cy) = stretch(spec.height, spec.cy, spec.fy);
    let r = shot.ground_from_camera.rotation_matrix();
    let t = shot.ground_from_camera.translation_m;
    let row = |i: usize| [r[i][0], r[i][1], r[i][2], t[i]];
    CanvasShot {
        name: shot.name.clone(),
        // Every shot its own sample stream, so no two renders share a noise pattern.
        seed: stage_hash(seed, &format!("render.{}", shot.name), 0) % 1_000_000_007,
        width,
        height,
        fx: f,
        fy: f,
        cx,
        cy,
        ground_from_camera: [row(0), row(1), row(2), [0.0, 0.0, 0.0, 1.0]],
    }
}

/// The cache key of one render.
fn render_key(scene_hash: &str, canvas: &CanvasShot, spp: u32) -> String {
    let mut h = Sha256::new();
    h.update(scene_hash.as_bytes());
    h.update(serde_json::to_vec(canvas).unwrap_or_default());
    h.update(spp.to_le_bytes());
    hex::encode(h.finalize())
}

/// The catalogue's image effects as the camera takes them; the noise is always present (the
/// baseline unless a hidden `noise` replaces it).
fn hidden_optics(effects: &[Effect]) -> HiddenOptics {
    let mut h = HiddenOptics {
        vignetting_strength: None,
        blur_sigma_px: None,
        exposure: None,
        noise: (0.0, 0.0),
        gamma: None,
    };
    for e in effects {
        match *e {
            Effect::Vignetting { strength } => h.vignetting_strength = Some(strength),
            Effect::Blur { sigma_px } => h.blur_sigma_px = Some(sigma_px),
            Effect::Exposure { gain, offset } => h.exposure = Some((gain, offset)),
            Effect::Noise { gain, read_sigma } => h.noise = (gain, read_sigma),
            Effect::Gamma { gamma } => h.gamma = Some(gamma),
            _ => {}
        }
    }
    h
}

fn camera_details(p: &CameraPhysics) -> serde_json::Value {
    serde_json::json!({
        "module": "regolith_corpus::camera",
        "order": "distortion remap with pixel integration, vignetting (hidden), PSF (defocus disc * Airy, + hidden Gaussian blur), exposure (hidden), PRNU, shot noise, DSNU + column FPN + black level, read noise, response curve (hidden), 8-bit quantisation",
        "defocus_radius_px": p.defocus_radius_px,
        "f_number": p.f_number,
        "wavelength_um": p.wavelength_um,
        "pixel_pitch_um": p.pixel_pitch_um,
        "prnu_sigma": p.prnu_sigma,
        "dsnu_sigma_dn": p.dsnu_sigma_dn,
        "column_fpn_sigma_dn": p.column_fpn_sigma_dn,
        "black_level_dn": p.black_level_dn,
    })
}

/// Builds the scene description, the terrain mesh and the albedo texture, and hashes them.
fn scene_files(scene: &CaptureScene<'_>) -> Result<SceneFiles, CorpusError> {
    let terrain = scene.terrain;
    let ply = terrain_ply(terrain);
    let albedo_exr = albedo_exr(terrain)?;
    let json = describe(scene);
    let mut h = Sha256::new();
    h.update(SCENE_FORMAT.as_bytes());
    h.update(serde_json::to_vec(&json).unwrap_or_default());
    h.update(Sha256::digest(&ply));
    h.update(Sha256::digest(&albedo_exr));
    Ok(SceneFiles {
        json,
        ply,
        albedo_exr,
        hash: hex::encode(h.finalize()),
    })
}

/// The scene description without its shots (see `tools/render/README.md` for the schema).
fn describe(scene: &CaptureScene<'_>) -> serde_json::Value {
    let cfg = scene.cfg;
    let [ex, ey] = cfg.extent_m;
    let centre = [0.5 * ex, 0.5 * ey];
    let z = &scene.terrain.height.z;
    let zmin = z
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f32, f32::min);
    let floor_z = f64::from(zmin) - 0.05;
    let spheres: Vec<serde_json::Value> = scene
        .terrain
        .markers
        .iter()
        .map(|m| serde_json::json!({"centre": m.centre_m, "radius": m.radius_m, "albedo": MARKER_ALBEDO}))
        .collect();
    let lamp_distance = 0.5 * (ex * ex + ey * ey).sqrt() + 2.0;
    let lamp = lamp_position(&scene.light, centre, lamp_distance);
    let walls = [
        -(lamp_distance - 0.5 * ex).max(0.0) - WALL_CLEARANCE_M,
        -(lamp_distance - 0.5 * ey).max(0.0) - WALL_CLEARANCE_M,
        ex + (lamp_distance - 0.5 * ex).max(0.0) + WALL_CLEARANCE_M,
        ey + (lamp_distance - 0.5 * ey).max(0.0) + WALL_CLEARANCE_M,
    ];
    let objects = room_objects(scene.seed, lamp, floor_z, walls, [ex, ey]);
    serde_json::json!({
        "format": SCENE_FORMAT,
        "terrain": {
            "mesh": "terrain.ply",
            "albedo": "albedo.exr",
            "bsdf": {"model": "oren-nayar", "sigma_deg": REGOLITH_ROUGHNESS_DEG},
        },
        "spheres": spheres,
        "room": {
            "floor_z": floor_z,
            "bed": [0.0, 0.0, ex, ey],
            "border_height": 0.10,
            "border_width": 0.15,
            "border_albedo": 0.35,
            "walls": walls,
            "wall_height": 4.0,
            "wall_albedo": 0.55,
            "floor_albedo": 0.25,
            "objects": objects,
            "texture_seed": stage_hash(scene.seed, "room.texture", 0) % 1_000_000_007,
        },
        "lamp": {
            "position": lamp,
            "target": [centre[0], centre[1], 0.0],
            "size_m": LAMP_SIZE_M,
            "irradiance": std::f64::consts::PI * (1.0 - scene.light.ambient),
        },
        "ambient": {"radiance": scene.light.ambient},
    })
}

/// The lamp at `distance` from the bed centre toward the light's direction.
fn lamp_position(light: &Light, centre: [f64; 2], distance: f64) -> [f64; 3] {
    let (az, el) = (
        light.azimuth_deg.to_radians(),
        light.elevation_deg.to_radians(),
    );
    [
        centre[0] + distance * el.cos() * az.cos(),
        centre[1] + distance * el.cos() * az.sin(),
        distance * el.sin(),
    ]
}

/// What stands in the hall: the lamp's stand, and a few cases and a table along the walls,
/// placed from the seed.
fn room_objects(
    seed: u64,
    lamp: [f64; 3],
    floor_z: f64,
    walls: [f64; 4],
    bed: [f64; 2],
) -> Vec<serde_json::Value> {
    use rand::Rng;
    let mut out = vec![serde_json::json!({
        "type": "cylinder", "p0": [lamp[0], lamp[1], floor_z], "p1": [lamp[0], lamp[1], lamp[2] - 0.25],
        "radius": 0.03, "albedo": 0.15,
    })];
    let mut rng = item_rng(seed, "room.objects", 0);
    for k in 0..6 {
        // Somewhere between the bed and a wall, on the floor.
        let side = k % 4;
        let along: f64 = rng.gen_range(0.1..0.9);
        let (w, d, h): (f64, f64, f64) = (
            rng.gen_range(0.3..1.2),
            rng.gen_range(0.3..0.8),
            rng.gen_range(0.3..1.1),
        );
        let gap_lo = |wall: f64, edge: f64| 0.5 * (wall + edge);
        let (x, y) = match side {
            0 => (
                walls[0] + along * (walls[2] - walls[0]),
                gap_lo(walls[1], 0.0),
            ),
            1 => (
                walls[0] + along * (walls[2] - walls[0]),
                gap_lo(walls[3], bed[1]),
            ),
            2 => (
                gap_lo(walls[0], 0.0),
                walls[1] + along * (walls[3] - walls[1]),
            ),
            _ => (
                gap_lo(walls[2], bed[0]),
                walls[1] + along * (walls[3] - walls[1]),
            ),
        };
        let albedo: f64 = rng.gen_range(0.1..0.7);
        out.push(serde_json::json!({
            "type": "box",
            "min": [x - 0.5 * w, y - 0.5 * d, floor_z],
            "max": [x + 0.5 * w, y + 0.5 * d, floor_z + h],
            "albedo": (albedo * 100.0).round() / 100.0,
        }));
    }
    out
}

/// The truth surface as a binary little-endian PLY: one vertex per finite cell (x, y, z, and
/// the albedo texture's u, v at the cell centre), the format's NW–SE split of every quad whose
/// triangle has three finite corners.
fn terrain_ply(terrain: &Terrain) -> Vec<u8> {
    let g = &terrain.height;
    let (w, h) = (g.width, g.height);
    let mut index = vec![u32::MAX; w * h];
    let mut verts: Vec<u8> = Vec::new();
    let mut n = 0u32;
    for r in 0..h {
        for c in 0..w {
            let Some(&z) = g.z.get(r * w + c) else {
                continue;
            };
            if !z.is_finite() {
                continue;
            }
            if let Some(slot) = index.get_mut(r * w + c) {
                *slot = n;
            }
            n += 1;
            let x = g.origin_m[0] + c as f64 * g.cell_m;
            let y = g.origin_m[1] - r as f64 * g.cell_m;
            let u = (c as f64 + 0.5) / w as f64;
            let v = (r as f64 + 0.5) / h as f64;
            for val in [x as f32, y as f32, z, u as f32, v as f32] {
                verts.extend_from_slice(&val.to_le_bytes());
            }
        }
    }
    let mut faces: Vec<u8> = Vec::new();
    let mut nf = 0u64;
    let at = |c: usize, r: usize| index.get(r * w + c).copied().unwrap_or(u32::MAX);
    for r in 0..h.saturating_sub(1) {
        for c in 0..w.saturating_sub(1) {
            let (nw, ne, sw, se) = (at(c, r), at(c + 1, r), at(c, r + 1), at(c + 1, r + 1));
            // Counter-clockwise seen from above (+z): NW → SE → NE and NW → SW → SE.
            for tri in [[nw, se, ne], [nw, sw, se]] {
                if tri.contains(&u32::MAX) {
                    continue;
                }
                faces.push(3);
                for i in tri {
                    faces.extend_from_slice(&i.to_le_bytes());
                }
                nf += 1;
            }
        }
    }
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment regolith-corpus truth surface\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\nelement face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
    );
    let mut out = header.into_bytes();
    out.extend_from_slice(&verts);
    out.extend_from_slice(&faces);
    out
}

/// The true albedo as a one-channel (`Y`) float32 EXR, row 0 = north = texture v 0.
fn albedo_exr(terrain: &Terrain) -> Result<Vec<u8>, CorpusError> {
    use exr::prelude::*;
    let a = &terrain.albedo;
    let w = a.width;
    let channels = SpecificChannels::build()
        .with_channel("Y")
        .with_pixel_fn(|p: Vec2<usize>| (a.value.get(p.y() * w + p.x()).copied().unwrap_or(0.0),));
    let mut buf = std::io::Cursor::new(Vec::new());
    Image::from_channels((a.width, a.height), channels)
        .write()
        .non_parallel()
        .to_buffered(&mut buf)
        .map_err(CorpusError::encode("EXR", Path::new("albedo.exr")))?;
    Ok(buf.into_inner())
}

/// Reads the `Y` channel of a one-layer EXR as f32.
fn read_y(path: &Path) -> Result<Vec<f32>, CorpusError> {
    use exr::prelude::*;
    let bad = |m: String| CorpusError::Option {
        option: "--renders",
        expected: format!("a one-channel (Y) EXR render at {}", path.display()),
        found: m,
    };
    let img = read_first_flat_layer_from_file(path).map_err(|e| bad(e.to_string()))?;
    let ch = img
        .layer_data
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "Y")
        .ok_or_else(|| bad("no Y channel".into()))?;
    Ok(match &ch.sample_data {
        FlatSamples::F32(v) => v.clone(),
        FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
        FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
    })
}

/// Radiance a cached render's code 255 stands for (510 DN at unit exposure).
pub const CACHE_FULL_SCALE: f64 = 2.0;

/// A radiance as a cached render's code: `round(255 · sqrt(radiance / CACHE_FULL_SCALE))`.
/// The square root makes the step grow like photon noise: 0.6 DN at 10 DN, 1.4 DN at 60 DN,
/// 2.5 DN at 200 DN, so the rounding's σ (step/√12) stays near a fifth of the sensor's shot
/// noise at every level, and a render costs ~2.4 bits a pixel less than linear 16-bit steps.
pub fn cache_code(radiance: f64) -> u8 {
    (255.0 * (radiance.max(0.0) / CACHE_FULL_SCALE).sqrt())
        .round()
        .clamp(0.0, 255.0) as u8
}

/// The radiance a cached render's code stands for (the inverse of [`cache_code`]).
pub fn cache_radiance(code: u8) -> f64 {
    CACHE_FULL_SCALE * (f64::from(code) / 255.0).powi(2)
}

/// Stores a render as an 8-bit grey PNG of [`cache_code`]s.
fn write_cached(path: &Path, width: usize, height: usize, y: &[f32]) -> Result<(), CorpusError> {
    let codes: Vec<u8> = y.iter().map(|&v| cache_code(f64::from(v))).collect();
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width as u32, height as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Best);
        let mut w = enc
            .write_header()
            .map_err(CorpusError::encode("PNG", path))?;
        w.write_image_data(&codes)
            .map_err(CorpusError::encode("PNG", path))?;
    }
    std::fs::write(path, out).map_err(CorpusError::io("a cached render", path))
}

/// Reads a cached render back as radiance.
fn read_cached(path: &Path) -> Result<(usize, usize, Vec<f32>), CorpusError> {
    let bad = |m: String| CorpusError::Option {
        option: "--renders",
        expected: format!("an 8-bit grey PNG render at {}", path.display()),
        found: m,
    };
    let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| bad(e.to_string()))?;
    let mut buf = vec![0u8; reader.output_buffer_size()];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| bad(e.to_string()))?;
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Eight {
        return Err(bad(format!("{:?} {:?}", info.color_type, info.bit_depth)));
    }
    let values = buf
        .get(..info.buffer_size())
        .unwrap_or_default()
        .iter()
        .map(|&c| cache_radiance(c) as f32)
        .collect();
    Ok((info.width as usize, info.height as usize, values))
}
