//! The generation pipeline: terrain → scans → Vicon → calibrations → captures → SfM → truth.
//!
//! Stages run in a fixed order, each with its own seeded RNG, and report progress as
//! `(stage, fraction)`. Work inside a stage is parallel but order-independent, so the output
//! bytes depend only on the options. The hidden model is resolved up front (parse → resolve)
//! so a bad effect name fails before anything is written.

use std::path::Path;
use std::time::Instant;

use rand::Rng;
use regolith_format::frames::Pose;
use regolith_format::grid::AlbedoGrid;
use regolith_format::lighting::Light;

use crate::campaign::{self, CampaignPlan};
use crate::captures::{CaptureRenderer, CaptureScene};
use crate::effects::{self, Hidden, HiddenSpec};
use crate::instruments::{bouguet, e57, las, navcam, opencv, ply, riegl, sfm, vicon};
use crate::presets::{Preset, PresetConfig};
use crate::seeding::{stage_hash, stage_rng};
use crate::sink::Sink;
use crate::terrain::raycast::TerrainCaster;
use crate::terrain::Terrain;
use crate::truth::{self, CaptureTruth, ScanTruth};
use crate::CorpusError;

/// What to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerateOptions {
    /// Which campaign.
    pub preset: Preset,
    /// The seed (required on the command line).
    pub seed: u64,
    /// Full resolution: 2.5 mm truth grid and the real 0.030° scan step.
    pub full: bool,
    /// Capture locations, if not the preset's own count. The first locations are the same
    /// whatever the count (poses are drawn one after the other from the captures' stream).
    pub captures: Option<usize>,
    /// Hidden effects and their parameter overrides.
    pub hidden: Vec<HiddenSpec>,
    /// An auto-exposing camera's spread (0: one exposure for every capture; see
    /// [`effects::Hidden::auto_exposure`]).
    pub auto_exposure: f64,
}

/// What was generated.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Files written, relative to the output folder, sorted.
    pub files: Vec<String>,
    /// Points per scan, in scan order.
    pub scan_points: Vec<(String, usize)>,
    /// Number of capture locations.
    pub captures: usize,
    /// Wall time per stage, seconds (informational; not written to any file).
    pub stage_seconds: Vec<(String, f64)>,
}

/// Generates a campaign into `out`, its NavCam frames made by `renderer`.
pub fn generate(
    opts: &GenerateOptions,
    out: &Path,
    renderer: &dyn CaptureRenderer,
    progress: &dyn Fn(&str, f64),
) -> Result<Summary, CorpusError> {
    let mut cfg = PresetConfig::of(opts.preset);
    if let Some(n) = opts.captures {
        cfg.captures = n;
    }
    let seed = opts.seed;
    let mut times = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &str, times: &mut Vec<(String, f64)>| {
        times.push((name.to_string(), clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };
    let mut lrng = stage_rng(seed, "lighting");
    let round = |v: f64| (v * 10.0).round() / 10.0;
    let mut light = Light {
        azimuth_deg: round(lrng.gen_range(0.0..360.0)),
        elevation_deg: round(lrng.gen_range(45.0..70.0)),
        ambient: (lrng.gen_range(0.25..0.4f64) * 100.0).round() / 100.0,
    };
    let mut hidden = effects::resolve(&opts.hidden, seed)?;
    hidden.auto_exposure = opts.auto_exposure;
    // A hidden `shadows` is cast by the lab light itself: the lab light (and so `[lighting]`)
    // takes its direction (see `effects`).
    if let Some((azimuth_deg, elevation_deg)) = hidden.shadow_light() {
        light.azimuth_deg = azimuth_deg;
        light.elevation_deg = elevation_deg;
    }
    // What the campaign file records: the lab light as surveyed, a few degrees off the true
    // one when it casts hidden shadows (see `effects::recorded_light`).
    let recorded = effects::recorded_light(&light, &hidden, seed);
    let mut sink = Sink::new(out)?;

    progress("terrain", 0.0);
    let cell = if opts.full {
        cfg.cell_full_m
    } else {
        cfg.cell_m
    };
    let terrain = Terrain::build(&cfg, cell, seed);
    let tracer = TerrainCaster::new(&terrain.height);
    let world = renderer.world();
    let texture_albedo = hidden.albedo(&terrain.albedo);
    let laser_albedo = hidden.albedo(&world.laser_albedo(&terrain, &terrain.albedo));
    lap("terrain", &mut times);

    let scans = write_scans(
        &cfg,
        opts,
        &terrain,
        &tracer,
        &laser_albedo,
        world.laser.incidence_exponent,
        &mut sink,
        progress,
    )?;
    lap("scans", &mut times);

    progress("vicon", 0.0);
    let mut vrng = stage_rng(seed, "vicon.markers");
    let centres: Vec<[f64; 3]> = terrain.markers.iter().map(|m| m.centre_m).collect();
    let names: Vec<&str> = terrain.markers.iter().map(|m| m.name.as_str()).collect();
    let tracks = vicon::tracks(&centres, cfg.vicon_frames, true, &mut vrng);
    let first = vrng.gen_range(2..400);
    sink.write(
        "vicon/markers.csv",
        vicon::nexus_csv("Testbed", &names, &tracks, first).as_bytes(),
    )?;

    progress("calibration", 0.0);
    let mut crng = stage_rng(seed, "calibration");
    let head = navcam::stereo_head(&cfg, &mut crng);
    sink.write(
        "calib/navcam_left.yaml",
        opencv::camera_yaml(&head.left, 0.21).as_bytes(),
    )?;
    sink.write(
        "calib/navcam_right.yaml",
        opencv::camera_yaml(&head.right, 0.23).as_bytes(),
    )?;
    sink.write(
        "calib/stereo.yaml",
        opencv::stereo_yaml(&head.right_from_left).as_bytes(),
    )?;
    let tc = cfg.texture_camera;
    let k = cfg.texture_kc;
    let texture_cam = regolith_format::camera_model::CameraModel {
        distortion: regolith_format::camera_model::Distortion {
            k1: k[0],
            k2: k[1],
            p1: k[2],
            p2: k[3],
            k3: k[4],
        },
        ..regolith_format::camera_model::CameraModel::pinhole(
            tc.size[0], tc.size[1], tc.f[0], tc.f[1], tc.c[0], tc.c[1],
        )
    };
    sink.write(
        "calib/texture_camera_Calib_Results.m",
        bouguet::calib_results_m(&texture_cam, 25, &mut crng).as_bytes(),
    )?;
    let mut rig = String::from("Name,X,Y,Z\n");
    for (n, p) in navcam::RIG_BALLS {
        rig.push_str(&format!("{n},{},{},{}\n", p[0], p[1], p[2]));
    }
    sink.write("calib/rig_markers.csv", rig.as_bytes())?;
    lap("vicon+calibration", &mut times);

    let scene = CaptureScene {
        cfg: &cfg,
        seed,
        terrain: &terrain,
        light,
        effects: &effects::real_model(&hidden),
    };
    let captures = write_captures(
        &scene, &tracer, &head, &hidden, renderer, &mut sink, progress,
    )?;
    lap("captures", &mut times);

    progress("sfm", 0.0);
    let mesh = sfm::reconstruct(
        &cfg,
        &terrain,
        &texture_albedo,
        &world,
        seed,
        &mut stage_rng(seed, "sfm"),
    );
    sink.write("sfm/mesh.wrl", &sfm::vrml(&mesh))?;
    let comment = "multi-view stereo reconstruction (simulated by regolith-corpus)";
    sink.write(
        "sfm/mesh.ply",
        &ply::mesh(&mesh.positions, &mesh.colors, &mesh.triangles, comment),
    )?;
    let marker_centres: Vec<(String, [f64; 3])> = terrain
        .markers
        .iter()
        .map(|m| (m.name.clone(), m.centre_m))
        .collect();
    let gcps = sfm::ground_control_points(
        &marker_centres,
        &mesh.similarity,
        &mut stage_rng(seed, "sfm.gcp"),
    );
    sink.write(truth::GCP_FILE, &sfm::gcp_csv(&gcps))?;
    lap("sfm", &mut times);

    progress("truth", 0.0);
    let plan = CampaignPlan {
        cfg: &cfg,
        light: &recorded,
        scans: scans.iter().map(|s| s.name.clone()).collect(),
        captures: captures.iter().map(|c| c.name.clone()).collect(),
        truth_cell_m: cell,
    };
    sink.write("campaign.toml", campaign::campaign_toml(&plan).as_bytes())?;
    sink.write("README.md", campaign::README.as_bytes())?;
    let mut hidden_truth = truth::HiddenTruth::new(&hidden, &effects::real_model(&hidden));
    if hidden.auto_exposure > 0.0 {
        hidden_truth.capture_exposure = captures
            .iter()
            .enumerate()
            .map(|(i, c)| (c.name.clone(), hidden.capture_gain(seed, i)))
            .collect();
    }
    sink.write_json("truth/renderer.json", &renderer.info())?;
    sink.write_json("truth/lab.json", &world)?;
    let cams = truth::CamerasTruth::new(&head, &hidden, &texture_cam);
    truth::write_all(
        &mut sink,
        &terrain,
        &light,
        &scans,
        &mesh.similarity,
        &gcps,
        &cams,
        &captures,
        &hidden_truth,
        cfg.range_noise_m,
    )?;
    lap("truth", &mut times);
    progress("done", 1.0);
    Ok(Summary {
        files: sink.files(),
        scan_points: scans.iter().map(|s| (s.name.clone(), s.points)).collect(),
        captures: captures.len(),
        stage_seconds: times,
    })
}

#[allow(clippy::too_many_arguments)]
fn write_scans(
    cfg: &PresetConfig,
    opts: &GenerateOptions,
    terrain: &Terrain,
    tracer: &TerrainCaster,
    laser_albedo: &AlbedoGrid,
    incidence_exponent: f64,
    sink: &mut Sink,
    progress: &dyn Fn(&str, f64),
) -> Result<Vec<ScanTruth>, CorpusError> {
    let setup = riegl::ScanSetup {
        tracer,
        albedo: laser_albedo,
        incidence_exponent,
        markers: &terrain.markers,
        bed_centre: [0.5 * cfg.extent_m[0], 0.5 * cfg.extent_m[1]],
        step_deg: if opts.full {
            cfg.scan_step_full_deg
        } else {
            cfg.scan_step_deg
        },
        range_noise_m: cfg.range_noise_m,
        seed: opts.seed,
    };
    let mut out = Vec::new();
    for (i, spec) in cfg.scanners.iter().enumerate() {
        progress("scans", i as f64 / cfg.scanners.len() as f64);
        let scan = riegl::simulate(&setup, spec);
        let name = &scan.name;
        sink.write(&format!("scans/{name}.asc"), &riegl::ascii(&scan))?;
        sink.write(
            &format!("scans/{name}_tiepoints.csv"),
            &riegl::tiepoint_csv(&scan),
        )?;
        let mut extra = None;
        match name.as_str() {
            "pos2" => {
                let rel = "scans/pos2.ply";
                sink.write(
                    rel,
                    &ply::points(&scan.points, &scan.reflectance_db, "RIEGL scan pos2, SOCS"),
                )?;
                extra = Some(rel);
            }
            "pos3" => {
                let rel = "scans/pos3.e57";
                e57::write(
                    &sink.path(rel)?,
                    name,
                    &scan.points,
                    &scan.reflectance_db,
                    opts.seed,
                )?;
                extra = Some(rel);
            }
            "pos4" => {
                let rel = "scans/pos4.las";
                las::write(&sink.path(rel)?, &scan.points, &scan.reflectance_db)?;
                extra = Some(rel);
            }
            _ => {}
        }
        out.push(ScanTruth::new(&scan, spec, extra));
    }
    Ok(out)
}

/// Draws the capture locations, writes their Vicon files, has `renderer` make the frames of
/// every shot and writes them.
fn write_captures(
    scene: &CaptureScene<'_>,
    tracer: &TerrainCaster,
    head: &navcam::StereoHead,
    hidden: &Hidden,
    renderer: &dyn CaptureRenderer,
    sink: &mut Sink,
    progress: &dyn Fn(&str, f64),
) -> Result<Vec<CaptureTruth>, CorpusError> {
    let (cfg, seed) = (scene.cfg, scene.seed);
    let mut prng = stage_rng(seed, "captures");
    let poses = navcam::capture_poses(cfg, scene.terrain, tracer, &mut prng);
    let mut shots = Vec::new();
    for (i, cap) in poses.iter().enumerate() {
        let mut rrng = stage_rng(seed, &format!("vicon.{}", cap.name));
        let balls: Vec<[f64; 3]> = navcam::RIG_BALLS
            .iter()
            .map(|(_, p)| cap.ground_from_rig.transform_point(*p))
            .collect();
        let names: Vec<&str> = navcam::RIG_BALLS.iter().map(|(n, _)| *n).collect();
        let tracks = vicon::tracks(&balls, cfg.rig_frames, false, &mut rrng);
        let first = rrng.gen_range(2..400);
        sink.write(
            &format!("vicon/{}.csv", cap.name),
            vicon::nexus_csv("Rig", &names, &tracks, first).as_bytes(),
        )?;
        let noise_seed = stage_hash(seed, "captures.noise", i as u64);
        let gain = hidden.capture_gain(seed, i);
        shots.extend(navcam::shots(head, cap, hidden, noise_seed, gain));
    }
    let frames = renderer.frames(scene, &shots, &|f| progress("captures", f))?;
    let mut out = Vec::new();
    for (cap, pair) in poses.iter().zip(shots.chunks(2).zip(frames.chunks(2))) {
        let (pair_shots, pair_frames) = pair;
        let mut files = Vec::new();
        let mut true_poses = [Pose::IDENTITY; 2];
        for (k, (shot, images)) in pair_shots.iter().zip(pair_frames).enumerate() {
            let side = if k == 0 { "left" } else { "right" };
            if let Some(p) = true_poses.get_mut(k) {
                *p = shot.ground_from_camera;
            }
            for (frame, pixels) in ["a", "b"].iter().zip(images) {
                let rel = format!("captures/{}_{side}_{frame}.png", cap.name);
                let bytes = navcam::png_grey(pixels, shot.camera.width, shot.camera.height)
                    .map_err(CorpusError::encode("PNG", Path::new(&rel)))?;
                sink.write(&rel, &bytes)?;
                files.push(rel);
            }
        }
        out.push(CaptureTruth::new(cap, true_poses, files));
    }
    Ok(out)
}
