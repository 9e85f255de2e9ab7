//! A Bouguet stereo result (`Calib_Results_stereo.mat`, written by scipy's `savemat`, see
//! `compiler/tests/data/calibration/PROVENANCE.md`) serving as the calibration of both rig
//! cameras, each picking its half with `[[camera]].entry`, through `regolith compile --check`
//! on the demo campaign; an entry the file does not have is a clear error.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::fs;
use std::path::Path;

use common::{copy_dir, regolith};
use serde_json::Value;

fn campaign(dir: &Path, left: &str, right: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    copy_dir(&root.join("corpus/demo"), dir);
    fs::copy(
        root.join("compiler/tests/data/calibration/Calib_Results_stereo.mat"),
        dir.join("calib/Calib_Results_stereo.mat"),
    )
    .unwrap();
    let toml = fs::read_to_string(dir.join("campaign.toml")).unwrap();
    let toml = toml
        .replacen(
            "calibration = \"calib/navcam_left.yaml\"",
            &format!("calibration = \"calib/Calib_Results_stereo.mat\"\nentry = \"{left}\""),
            1,
        )
        .replacen(
            "calibration = \"calib/navcam_right.yaml\"",
            &format!("calibration = \"calib/Calib_Results_stereo.mat\"\nentry = \"{right}\""),
            1,
        );
    assert_eq!(toml.matches("Calib_Results_stereo.mat").count(), 2);
    fs::write(dir.join("campaign.toml"), toml).unwrap();
}

#[test]
fn a_stereo_mat_calibrates_both_cameras_by_entry() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("camp");
    campaign(&dir, "left", "right");
    let out = regolith(&["--json", "compile", "--check", dir.to_str().unwrap()]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let cams: Vec<&Value> = v["files"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["path"] == "calib/Calib_Results_stereo.mat")
        .map(|f| &f["summary"])
        .collect();
    assert_eq!(cams.len(), 2);
    // PROVENANCE facts: fc_left = [1150.24; 1151.78], alpha_c_left = 0.0012 (skew = alpha·fx),
    // kc_right(5) = 0.011, nx × ny = 1280 × 960.
    let (left, right) = (cams[0], cams[1]);
    assert_eq!(left["fx"], 1150.24);
    assert_eq!(left["fy"], 1151.78);
    assert!((left["skew"].as_f64().unwrap() - 0.0012 * 1150.24).abs() < 1e-9);
    assert_eq!(right["distortion"]["k3"], 0.011);
    assert_ne!(left["fx"], right["fx"], "each camera got its own half");
    for c in [left, right] {
        assert_eq!(
            (c["width"].as_u64(), c["height"].as_u64()),
            (Some(1280), Some(960))
        );
    }
}

#[test]
fn an_entry_the_file_lacks_is_an_error_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("camp");
    campaign(&dir, "left", "middle");
    let out = regolith(&["compile", "--check", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("Calib_Results_stereo.mat") && err.contains("\"middle\""),
        "{err}"
    );
}
