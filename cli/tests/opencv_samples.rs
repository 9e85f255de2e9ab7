//! OpenCV's own sample files, as OpenCV ships them (Debian's `opencv-doc`:
//! `/usr/share/doc/opencv-doc/examples/data/`, or `$OPENCV_SAMPLES_DATA`), through the one
//! FileStorage reader: the Oxford graffiti pair's homography `H1to3p.xml` (XML with tab-indented
//! data) gives `features repeat` the same result as the same numbers in the Oxford dataset's
//! plain-text form, and the calibration files read by the same reader hold the values OpenCV's
//! stereo sample computed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
// The expected values are the sample files' own digits, as OpenCV printed them.
#![allow(clippy::excessive_precision)]

mod common;

use std::path::PathBuf;

use regolith_compiler::ingest::{homography, opencv_storage};
use regolith_format::limits::Limits;
use serde_json::Value;

/// OpenCV's sample data folder; CI installs `opencv-doc` (`.ci/run`).
fn samples() -> PathBuf {
    let dir = std::env::var_os("OPENCV_SAMPLES_DATA").map_or_else(
        || PathBuf::from("/usr/share/doc/opencv-doc/examples/data"),
        PathBuf::from,
    );
    assert!(
        dir.join("H1to3p.xml").is_file(),
        "OpenCV's sample data is not at {}: `apt-get install opencv-doc`, or set \
         OPENCV_SAMPLES_DATA to a folder holding OpenCV's samples/data",
        dir.display()
    );
    dir
}

/// The homography `H1to3p.xml` holds, as printed in the file.
const H1TO3P: [f64; 9] = [
    7.6285898e-01,
    -2.9922929e-01,
    2.2567123e+02,
    3.3443473e-01,
    1.0143901e+00,
    -7.6999973e+01,
    3.4663091e-04,
    -1.4364524e-05,
    1.0000000e+00,
];

#[test]
fn h1to3p_xml_reads_as_the_matrix_it_prints() {
    let text = std::fs::read_to_string(samples().join("H1to3p.xml")).unwrap();
    assert!(
        text.contains("<data>\n\t"),
        "the sample's data block is tab-indented"
    );
    let h = homography::read_path(&samples().join("H1to3p.xml"), &Limits::default()).unwrap();
    assert_eq!(h, H1TO3P);
}

#[test]
fn features_repeat_reads_h1to3p_xml_as_it_reads_the_plain_text_form() {
    let dir = tempfile::tempdir().unwrap();
    let data = samples();
    let plain = dir.path().join("H1to3p");
    let rows: Vec<String> = H1TO3P
        .chunks(3)
        .map(|r| format!("{:e} {:e} {:e}", r[0], r[1], r[2]))
        .collect();
    std::fs::write(&plain, rows.join("\n") + "\n").unwrap();
    let repeat = |h: &std::path::Path| -> Value {
        let out = common::regolith(&[
            "features",
            "repeat",
            data.join("graf1.png").to_str().unwrap(),
            data.join("graf3.png").to_str().unwrap(),
            "--homography",
            h.to_str().unwrap(),
            "--detector",
            "fast",
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let xml = repeat(&data.join("H1to3p.xml"));
    assert_eq!(xml, repeat(&plain));
    // The mapping is the right one: graffiti 1 → 3 is a 40° viewpoint change, and FAST
    // corners repeat far above what an unrelated mapping gives.
    let at = |v: &Value, eps: f64| -> f64 {
        v["repeatability"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["epsilon_px"] == eps)
            .unwrap()["score"]
            .as_f64()
            .unwrap()
    };
    let identity = dir.path().join("identity");
    std::fs::write(&identity, "1 0 0\n0 1 0\n0 0 1\n").unwrap();
    let (with_h, without) = (at(&xml, 1.5), at(&repeat(&identity), 1.5));
    assert!(
        with_h > 0.2 && with_h > 3.0 * without,
        "repeatability through H1to3p {with_h}, through the identity {without}"
    );
}

#[test]
fn opencv_calibration_samples_read_through_the_same_reader() {
    let data = samples();
    let realdata = regolith_tests::workspace_root().join("../shared/realdata/calibration");
    // (file, matrix key, index, value) from the files' own text.
    let cases: &[(PathBuf, &str, usize, f64)] = &[
        (
            data.join("left_intrinsics.yml"),
            "camera_matrix",
            0,
            5.3591573396163199e+02,
        ),
        (data.join("intrinsics.yml"), "M1", 0, 5.3480326845051309e+02),
        (
            realdata.join("intrinsics.yml"),
            "D1",
            1,
            -1.0354662043042675e+00,
        ),
    ];
    for (path, key, i, want) in cases {
        let root = opencv_storage::read_path(path, &Limits::default()).unwrap();
        let m = opencv_storage::matrices(&root).unwrap();
        let (_, mat) = m
            .iter()
            .find(|(k, _)| k == key)
            .unwrap_or_else(|| panic!("{}: no {key}", path.display()));
        assert!(
            (mat.data[*i] - want).abs() < 1e-9 * want.abs(),
            "{}: {key}[{i}] = {}, file says {want}",
            path.display(),
            mat.data[*i]
        );
    }
    // The XML stereo sample is an image list, not a matrix: read, and no matrix found.
    let root =
        opencv_storage::read_path(&data.join("stereo_calib.xml"), &Limits::default()).unwrap();
    assert!(opencv_storage::matrices(&root).unwrap().is_empty());
    let msg = homography::read_path(&data.join("stereo_calib.xml"), &Limits::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("stereo_calib.xml") && msg.contains("no 3x3 matrix"),
        "{msg}"
    );
}
