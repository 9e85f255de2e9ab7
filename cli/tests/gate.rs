//! The release gate end to end on a corpus campaign: the finest laser entry earns a passing
//! certificate, a deliberately coarse 0.05 m raster fails it with the metric and shortfall named,
//! `release --publish` refuses while it fails, the entries rank as their data predicts, and hidden
//! sensor effects move the metrics the way the effect predicts (blur, noise).
//! Seed 7 is one of the eight campaigns the default thresholds were calibrated on (see
//! `tools/calibrate/validate_thresholds.py` and `Thresholds`), run with a two-raster laser
//! terrain: the test pins that the gate keeps behaving on it as calibrated.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{certificate, regolith};
use serde_json::Value;

fn validate(db: &str, entry: &str) -> Value {
    let out = regolith(&["--json", "validate", db, "--entry", entry]);
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        out.status.code(),
        Some(if v["passed"] == true { 0 } else { 1 })
    );
    v["entries"][0].clone()
}

#[test]
fn a_coarse_raster_fails_its_certificate_and_blocks_publishing() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    let (camp_s, db) = (
        camp.to_str().unwrap(),
        dir.path().join("db").to_string_lossy().into_owned(),
    );
    let out = regolith(&[
        "corpus", "generate", "--preset", "mini", "--seed", "7", "--out", camp_s,
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let toml = std::fs::read_to_string(camp.join("campaign.toml")).unwrap();
    let degraded = toml.replacen("raster_m = [0.02, 0.01]", "raster_m = [0.05, 0.01]", 1);
    assert_ne!(toml, degraded, "the mini preset's laser rasters changed");
    std::fs::write(camp.join("campaign.toml"), degraded).unwrap();
    let out = regolith(&["compile", camp_s, "--db", &db, "--release", "gate@1.0.0"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The human summary says how the scans' reflectance was cross-calibrated (mini: two
    // stations at similar ranges, so offsets only).
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(
        summary.contains(
            "laser                    reflectance cross-calibration: range slope not determined"
        ),
        "{summary}"
    );

    let fine = validate(&db, "laser/0.01");
    let coarse = validate(&db, "laser/0.05");
    let sfm = validate(&db, "sfm/0.02");
    assert_eq!(fine["passed"], true, "{fine}");
    assert_eq!(coarse["passed"], false, "{coarse}");
    let failures = coarse["failures"].to_string();
    assert!(
        failures.contains("fine detail") && failures.contains("short by"),
        "{failures}"
    );

    // The entries rank as their data predicts: finer laser geometry keeps more of the real
    // image's fine detail than the coarse raster and the SfM mesh, and more of its keypoints
    // than the coarse raster (both held on all 8 calibration seeds; the keypoint ranking of
    // laser/0.01 over sfm/0.02 held on 6 of 8 only, so it is not asserted).
    let (cf, cc, cs) = (
        certificate(&db, &fine),
        certificate(&db, &coarse),
        certificate(&db, &sfm),
    );
    let band = |c: &Value| c["high_band_log_ratio"].as_f64().unwrap();
    let ratio = |c: &Value| c["mean_ratio_to_ceiling"]["mean"].as_f64().unwrap();
    assert!(
        band(&cf) > band(&cc) + 0.2,
        "{} vs {}",
        band(&cf),
        band(&cc)
    );
    assert!(band(&cf) > band(&cs), "{} vs {}", band(&cf), band(&cs));
    assert!(ratio(&cf) > ratio(&cc), "{} vs {}", ratio(&cf), ratio(&cc));

    // The gate: publishing is refused while laser/0.05 fails, naming the metric.
    let out = regolith(&["release", &db, "gate@1.0.0", "--publish"]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("laser/0.05") && text.contains("fine detail"),
        "{text}"
    );
}

/// Compiles a mini seed-7 campaign with `hidden` effects and returns laser/0.01's certificate.
fn certificate_with(dir: &std::path::Path, name: &str, hidden: &[&str]) -> Value {
    let camp = dir.join(name);
    let db = dir
        .join(format!("{name}-db"))
        .to_string_lossy()
        .into_owned();
    let mut args = vec!["corpus", "generate", "--preset", "mini", "--seed", "7"];
    args.extend_from_slice(hidden);
    args.extend_from_slice(&["--out", camp.to_str().unwrap()]);
    let out = regolith(&args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = regolith(&["compile", camp.to_str().unwrap(), "--db", &db]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    certificate(&db, &validate(&db, "laser/0.01"))
}

#[test]
fn hidden_effects_move_the_metrics_the_way_the_effect_predicts() {
    let dir = tempfile::tempdir().unwrap();
    let none = certificate_with(dir.path(), "none", &[]);
    let blur = certificate_with(
        dir.path(),
        "blur",
        &[
            "--hidden-effect",
            "blur",
            "--effect-param",
            "blur.sigma_px=1.5",
        ],
    );
    let noise = certificate_with(
        dir.path(),
        "noise",
        &[
            "--hidden-effect",
            "noise",
            "--effect-param",
            "noise.gain=0.4",
            "--effect-param",
            "noise.read_sigma=3",
        ],
    );
    let band = |c: &Value| c["high_band_log_ratio"].as_f64().unwrap();
    let ceiling = |c: &Value| c["summary"]["fast"]["ceiling"]["mean"].as_f64().unwrap();
    // Blur removes fine detail from the real images only: the render now has more of it.
    assert!(
        band(&blur) > band(&none) + 0.5,
        "{} vs {}",
        band(&blur),
        band(&none)
    );
    // Noise adds fine-scale power to the real images only, and makes two real frames of one
    // pose agree less: the render has relatively less fine detail, and the ceiling drops.
    assert!(
        band(&noise) < band(&none) - 0.15,
        "{} vs {}",
        band(&noise),
        band(&none)
    );
    assert!(
        ceiling(&noise) < 0.8 * ceiling(&none),
        "{} vs {}",
        ceiling(&noise),
        ceiling(&none)
    );
}
