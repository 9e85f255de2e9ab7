//! Every malformed input kind of the ingest issue, fed through `regolith compile --check`: exit
//! code 2, a message naming the file and the place in it, never a panic. The malformed files are
//! the corpus generator's `--bad-inputs` set, swapped into an otherwise valid campaign.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::fs;
use std::path::Path;
use std::process::Command;

use regolith_corpus::{generate, write_bad_inputs, GenerateOptions, Preset};

mod common;
use common::copy_dir;

fn check(campaign: &Path) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_regolith"))
        .args(["compile", "--check"])
        .arg(campaign)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn every_malformed_input_gives_exit_2_naming_file_and_place() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("good");
    generate(
        &GenerateOptions {
            preset: Preset::Mini,
            seed: 5,
            full: false,
            captures: None,
            hidden: vec![],
            auto_exposure: 0.0,
        },
        &good,
        &regolith_model_captures::ModelCaptures,
        &|_, _| {},
    )
    .unwrap();
    let bad = tmp.path().join("bad");
    let written = write_bad_inputs(&bad).unwrap();
    assert!(written.len() >= 12, "{written:?}");
    assert_eq!(check(&good).0, Some(0), "the untouched campaign must pass");

    // (malformed file, the campaign file it replaces, words the message must contain)
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "nan_coordinates.asc",
            "scans/pos1.asc",
            &["scans/pos1.asc", "line 3"],
        ),
        (
            "mixed_delimiters.asc",
            "scans/pos1.asc",
            &["scans/pos1.asc", "line"],
        ),
        ("empty.asc", "scans/pos1.asc", &["scans/pos1.asc", "empty"]),
        (
            "empty.csv",
            "scans/pos1_tiepoints.csv",
            &["pos1_tiepoints.csv"],
        ),
        (
            "vrml_index_out_of_range.wrl",
            "sfm/mesh.wrl",
            &["sfm/mesh.wrl", "line"],
        ),
        (
            "vicon_no_units.csv",
            "vicon/markers.csv",
            &["vicon/markers.csv", "line"],
        ),
        (
            "vicon_text_in_numeric.csv",
            "vicon/markers.csv",
            &["vicon/markers.csv", "line"],
        ),
        (
            "camera_matrix_3x2.yaml",
            "calib/navcam_left.yaml",
            &["navcam_left.yaml", "line"],
        ),
        (
            "truncated.png",
            "captures/loc01_left_a.png",
            &["loc01_left_a.png"],
        ),
    ];
    for (file, replaces, words) in cases {
        let dir = tmp.path().join(format!("case-{file}"));
        copy_dir(&good, &dir);
        fs::copy(bad.join(file), dir.join(replaces)).unwrap();
        let (code, err) = check(&dir);
        assert_eq!(code, Some(2), "{file}: exit {code:?}, stderr: {err}");
        for w in *words {
            assert!(err.contains(w), "{file}: message must contain {w:?}: {err}");
        }
        assert!(
            !err.contains("panicked") && !err.contains("internal error"),
            "{file}: {err}"
        );
    }

    // A truncated PLY referenced as a scan.
    let dir = tmp.path().join("case-ply");
    copy_dir(&good, &dir);
    fs::copy(bad.join("truncated.ply"), dir.join("scans/pos2.ply")).unwrap();
    let toml = fs::read_to_string(dir.join("campaign.toml")).unwrap();
    fs::write(
        dir.join("campaign.toml"),
        toml.replacen(
            "file = \"scans/pos2.asc\"\ncolumns = \"x y z reflectance\"",
            "file = \"scans/pos2.ply\"",
            1,
        ),
    )
    .unwrap();
    assert!(fs::read_to_string(dir.join("campaign.toml"))
        .unwrap()
        .contains("scans/pos2.ply"));
    let (code, err) = check(&dir);
    assert_eq!(code, Some(2), "truncated.ply: {err}");
    assert!(err.contains("scans/pos2.ply"), "{err}");

    // Campaigns that reference a missing file or escape their folder.
    for (case, word) in [
        ("missing_file", "does not exist"),
        ("path_escape", "campaign folder"),
    ] {
        let (code, err) = check(&bad.join(case));
        assert_eq!(code, Some(2), "{case}: {err}");
        assert!(
            err.contains(word) && err.contains("campaign.toml"),
            "{case}: {err}"
        );
    }
}
