//! The release gate end to end on a corpus campaign: the finest laser entry earns a passing
//! certificate, a deliberately coarse 0.05 m raster and a negative control with a blurred texture
//! (`regolith control`) fail it with the metric and shortfall named, `release --publish` refuses
//! while they fail, the entries rank as their data predicts, and hidden sensor effects move the
//! metrics the way the effect predicts (blur, noise).
//! Seed 7 is one of the eight campaigns the default thresholds were calibrated on (see
//! `tools/calibrate/validate_thresholds.py` and `Thresholds`), run with a two-raster laser
//! terrain: the test pins that the gate keeps behaving on it as calibrated.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{certificate, regolith};
use serde_json::Value;

fn validate(db: &str, entry: &str) -> Value {
    validate_in(db, "latest", entry)
}

fn validate_in(db: &str, release: &str, entry: &str) -> Value {
    let out = regolith(&[
        "--json",
        "validate",
        db,
        "--release",
        release,
        "--entry",
        entry,
    ]);
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
    common::assert_matches_doc_schema("validate", &v);
    v["entries"][0].clone()
}

#[test]
fn degraded_entries_fail_their_certificates_and_block_publishing() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    let (camp_s, db) = (
        camp.to_str().unwrap(),
        dir.path().join("db").to_string_lossy().into_owned(),
    );
    let out = regolith(&[
        "corpus",
        "generate",
        "--renderer",
        "model",
        "--preset",
        "mini",
        "--seed",
        "7",
        "--out",
        camp_s,
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

    // The negative control: laser/0.01 with its texture blurred by σ = 2 cm, in a child
    // release; same geometry, so only the texture's fine detail is lost.
    let out = regolith(&[
        "--json",
        "control",
        &db,
        "--entry",
        "laser/0.01",
        "--texture-blur-m",
        "0.02",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ctl: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(ctl["entry"], "laser/0.01-blur20mm", "{ctl}");
    assert_eq!(ctl["parent"], "gate@1.0.0", "{ctl}");
    let control_release = ctl["release"].as_str().unwrap().to_string();
    let blurred = validate_in(&db, &control_release, "laser/0.01-blur20mm");
    assert_eq!(blurred["passed"], false, "{blurred}");
    let failures = blurred["failures"].to_string();
    assert!(
        failures.contains("fast: repeatability over chance") && failures.contains("short by"),
        "{failures}"
    );
    // Writing the same control again reuses the child release.
    let again = regolith(&[
        "--json",
        "control",
        &db,
        "--release",
        "gate@1.0.0",
        "--entry",
        "laser/0.01",
        "--texture-blur-m",
        "0.02",
    ]);
    let again: Value = serde_json::from_slice(&again.stdout).unwrap();
    assert_eq!(again["id"], ctl["id"]);
    // A control of something that is not a textured heightfield, or with a blur out of range,
    // is a clear error (exit 2) and writes nothing.
    for (entry, sigma, expected) in [
        ("captures", "0.02", "expected a heightfield"),
        ("laser/0.01", "0", "must be in (0, 1] m"),
        ("laser/0.01", "NaN", "must be in (0, 1] m"),
    ] {
        let out = regolith(&[
            "control",
            &db,
            "--entry",
            entry,
            &format!("--texture-blur-m={sigma}"),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(expected), "{err}");
    }

    // The entries rank as their data predicts: finer laser geometry keeps more of the real
    // image's fine detail than the coarse raster and the SfM mesh, and the corner detectors
    // re-find more of the real keypoints (over chance, relative to the ceiling) in the finest
    // laser raster than in the coarse raster, the SfM raster and the blurred control (all held
    // on the 8 calibration seeds).
    let (cf, cc, cs, cb) = (
        certificate(&db, &fine),
        certificate(&db, &coarse),
        certificate(&db, &sfm),
        certificate(&db, &blurred),
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
    assert!(band(&cf) > band(&cb), "{} vs {}", band(&cf), band(&cb));
    assert!(ratio(&cf) > ratio(&cc), "{} vs {}", ratio(&cf), ratio(&cc));
    for d in ["fast", "harris"] {
        let r = |c: &Value| c["summary"][d]["ratio"]["mean"].as_f64().unwrap();
        for (other, name) in [(&cc, "laser/0.05"), (&cs, "sfm/0.02"), (&cb, "blurred")] {
            assert!(
                r(&cf) > 1.5 * r(other),
                "{d}: laser/0.01 {} vs {name} {}",
                r(&cf),
                r(other)
            );
        }
    }

    // The gate: publishing is refused while laser/0.05 fails, naming the metric.
    let out = regolith(&["release", &db, "gate@1.0.0", "--publish"]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("laser/0.05") && text.contains("fine detail"),
        "{text}"
    );
    let out = regolith(&["release", &db, &control_release, "--publish"]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("laser/0.01-blur20mm"), "{text}");
}

/// Compiles a mini seed-7 campaign with `hidden` effects and returns laser/0.01's certificate.
fn certificate_with(dir: &std::path::Path, name: &str, hidden: &[&str]) -> Value {
    let camp = dir.join(name);
    let db = dir
        .join(format!("{name}-db"))
        .to_string_lossy()
        .into_owned();
    let mut args = vec![
        "corpus",
        "generate",
        "--renderer",
        "model",
        "--preset",
        "mini",
        "--seed",
        "7",
    ];
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
