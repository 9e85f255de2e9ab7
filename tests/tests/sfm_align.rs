//! `sfm.align` end to end on a generated `mini` campaign: the SfM mesh (PLY, checked against the
//! VRML copy) is aligned without any initial guess onto the laser scans mapped to the ground
//! frame with their true poses, and the result is compared with `truth/sfm.json`. The mesh is
//! then moved by extra random similarities (including upside-down flips and scale changes) and
//! must still be recovered: scale within 0.5 %, rotation within 0.5°, translation within 1 cm at
//! the terrain centre.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::time::Instant;

use regolith_compiler::ingest::types::{transform, Matrix4, TriMesh};
use regolith_compiler::ingest::{ply, riscan_ascii, vrml};
use regolith_compiler::stage::StageCx;
use regolith_compiler::stages::sfm_align::{AlignOutput, AlignParams, AlignSfm, Similarity};
use regolith_corpus::{generate, GenerateOptions, Preset};
use regolith_format::frames::{quat_from_axis_angle, Pose};
use regolith_format::limits::Limits;

/// The mini terrain is 2 x 2 m: its centre, ground frame.
const CENTRE: [f64; 3] = [1.0, 1.0, 0.1];

fn json(dir: &Path, rel: &str) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join(rel)).unwrap()).unwrap()
}

fn array<const N: usize>(v: &serde_json::Value) -> [f64; N] {
    let a: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    a.try_into().unwrap()
}

/// `truth/sfm.json` maps ground → SfM; returns SfM → ground.
fn true_sfm_to_ground(dir: &Path) -> Similarity {
    let t = json(dir, "truth/sfm.json");
    assert!(
        t["maps"].as_str().unwrap().starts_with("ground -> sfm"),
        "{}",
        t["maps"]
    );
    let r = t["rotation"].as_array().unwrap();
    Similarity {
        scale: t["scale"].as_f64().unwrap(),
        rotation: [array(&r[0]), array(&r[1]), array(&r[2])],
        translation: array(&t["translation"]),
    }
    .inverse()
}

/// Every scan of the campaign mapped to the ground frame with its true pose.
fn laser_ground(dir: &Path) -> Vec<[f64; 3]> {
    let scans = json(dir, "truth/scans.json");
    let mut out = Vec::new();
    for s in scans["scans"].as_array().unwrap() {
        let m = s["ground_from_socs_matrix"].as_array().unwrap();
        let m: Matrix4 = [array(&m[0]), array(&m[1]), array(&m[2]), array(&m[3])];
        let file = dir.join(s["file"].as_str().unwrap());
        let cloud =
            riscan_ascii::read_path(&file, Some("x y z reflectance"), &Limits::default()).unwrap();
        assert_eq!(
            cloud.points.len(),
            s["points"].as_u64().unwrap() as usize,
            "{}",
            file.display()
        );
        out.extend(cloud.points.iter().map(|p| transform(&m, *p)));
    }
    out
}

fn check(found: &Similarity, want: &Similarity, what: &str) {
    let ds = (found.scale / want.scale - 1.0).abs();
    let da = found.angle_to_deg(want);
    let c = want.inverse().apply(CENTRE);
    let (a, b) = (found.apply(c), want.apply(c));
    let dt = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    println!(
        "{what}: scale error {:.4} %, rotation error {da:.4}°, centre error {:.2} mm",
        ds * 100.0,
        dt * 1e3
    );
    assert!(
        ds < 0.005,
        "{what}: scale {} vs {}",
        found.scale,
        want.scale
    );
    assert!(da < 0.5, "{what}: rotation off by {da}°");
    assert!(dt < 0.01, "{what}: centre off by {dt} m");
}

fn align(stage: &AlignSfm, mesh: &TriMesh, laser: &[[f64; 3]], what: &str) -> AlignOutput {
    let t0 = Instant::now();
    let out = stage.align(&StageCx::default(), mesh, laser, &[]).unwrap();
    let icp = out.report.icp.as_ref().unwrap();
    println!(
        "{what}: {:.2} s, {} iterations, {} inliers, point-to-plane RMS {:.2} mm",
        t0.elapsed().as_secs_f64(),
        icp.iterations,
        icp.inliers,
        icp.rms_point_to_plane_m * 1e3
    );
    out
}

#[test]
fn aligns_the_mini_sfm_mesh_onto_the_laser_scans() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let opts = GenerateOptions {
        preset: Preset::Mini,
        seed: 2024,
        full: false,
        captures: None,
        hidden: vec![],
        auto_exposure: 0.0,
    };
    generate(
        &opts,
        dir,
        &regolith_model_captures::ModelCaptures,
        &|_, _| {},
    )
    .unwrap();
    let limits = Limits::default();
    let mesh = ply::read_mesh_path(&dir.join("sfm/mesh.ply"), &limits).unwrap();
    let wrl = vrml::read_path(&dir.join("sfm/mesh.wrl"), &limits).unwrap();
    assert_eq!(mesh.positions.len(), wrl.positions.len());
    assert_eq!(mesh.triangles.len(), wrl.triangles.len());
    // The mini SfM mesh: 2 cm vertex spacing over 2 x 2 m.
    assert!(mesh.positions.len() > 9_000, "{}", mesh.positions.len());
    let truth = true_sfm_to_ground(dir);
    let laser = laser_ground(dir);
    println!(
        "SfM vertices {}, laser points {}",
        mesh.positions.len(),
        laser.len()
    );

    let stage = AlignSfm::new(AlignParams::default()).unwrap();
    let out = align(&stage, &mesh, &laser, "corpus frame");
    check(&out.similarity, &truth, "corpus frame");
    let h = out.report.heights.as_ref().unwrap();
    println!(
        "height difference over {} cells of {} m: mean {:.2} mm, std {:.2} mm, RMS {:.2} mm, p95 |d| {:.2} mm",
        h.cells_compared,
        h.cell_m,
        h.mean_m * 1e3,
        h.std_m * 1e3,
        h.rms_m * 1e3,
        h.p95_abs_m * 1e3
    );
    // SfM noise is σ 1.2 cm (2.6 cm at the walls) and laser range noise σ 8 mm: the per-cell
    // difference must be of that order and unbiased.
    assert!(h.rms_m < 0.03 && h.mean_m.abs() < 0.005, "{h:?}");
    assert!(h.cells_compared > 5_000, "{}", h.cells_compared);
    let g = out.difference.as_ref().unwrap();
    assert_eq!(g.values.len(), g.cols * g.rows);
    assert_eq!(
        g.values.iter().filter(|v| v.is_finite()).count(),
        h.cells_compared
    );

    // Extra similarities (scale, rotation axis, angle, translation) on top of the corpus frame:
    // generic, two 180° flips, a quarter turn.
    let pi = std::f64::consts::PI;
    let extra = [
        (0.3, [0.4, -1.2, 2.9], 2.3, [10.0, -3.0, 7.0]),
        (2.5, [1.0, 0.0, 0.0], pi, [-4.0, 0.0, 1.0]),
        (1.0, [0.3, 1.0, 0.0], pi, [0.0, 50.0, 0.0]),
        (0.8, [0.0, 0.7, 0.7], pi / 2.0, [1.0, 2.0, 3.0]),
    ];
    for (k, (scale, axis, angle, t)) in extra.iter().enumerate() {
        let rotation = Pose {
            translation_m: [0.0; 3],
            rotation_xyzw: quat_from_axis_angle(*axis, *angle),
        }
        .rotation_matrix();
        let q = Similarity {
            scale: *scale,
            rotation,
            translation: *t,
        };
        let moved = TriMesh {
            positions: mesh.positions.iter().map(|p| q.apply(*p)).collect(),
            ..mesh.clone()
        };
        let what = format!("extra similarity {k}");
        let out = align(&stage, &moved, &laser, &what);
        check(&out.similarity, &truth.compose(&q.inverse()), &what);
    }
}

/// The scale from the laser alone, on more terrains: seeds 1 and 7 were 0.96 % and 0.57 % small
/// when ICP (nearest laser sample and its plane) ended the alignment; the height fit on the
/// laser surface brought 18 mini seeds within 0.38 % (see `sfm_height_fit`).
#[test]
fn laser_only_scale_within_half_a_percent_on_more_terrains() {
    let stage = AlignSfm::new(AlignParams::default()).unwrap();
    for seed in [1, 7, 11, 2025] {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let opts = GenerateOptions {
            preset: Preset::Mini,
            seed,
            full: false,
            captures: None,
            hidden: vec![],
            auto_exposure: 0.0,
        };
        generate(
            &opts,
            dir,
            &regolith_model_captures::ModelCaptures,
            &|_, _| {},
        )
        .unwrap();
        let mesh = ply::read_mesh_path(&dir.join("sfm/mesh.ply"), &Limits::default()).unwrap();
        let what = format!("seed {seed}");
        let out = align(&stage, &mesh, &laser_ground(dir), &what);
        let fit = out.report.height_fit.as_ref().unwrap();
        assert!(fit.converged && fit.inliers > 8_000, "{what}: {fit:?}");
        check(&out.similarity, &true_sfm_to_ground(dir), &what);
    }
}
