//! Bouguet stereo `.mat` (MATLAB Level 5 written by scipy, `tools/fixtures/bouguet_stereo_mat.py`)
//! and OpenCV FileStorage JSON (written by cv2.FileStorage, `tools/fixtures/opencv_json.py`):
//! values read equal the values written, hostile variants name the file and the variable or
//! key, property tests round-trip generated files, and prefix / byte-flip sweeps never panic.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::Write as _;
use std::path::PathBuf;

use proptest::prelude::*;
use regolith_compiler::ingest::calib_bouguet::Place;
use regolith_compiler::ingest::calib_opencv::{self, CalibrationFormat};
use regolith_compiler::ingest::{calib_bouguet, calib_bouguet_mat, opencv_json};
use regolith_format::limits::Limits;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(rel)
}
fn real(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/realdata")
        .join(rel)
}
fn err_of<T: std::fmt::Debug>(r: Result<T, regolith_compiler::IngestError>, parts: &[&str]) {
    let msg = r.expect_err("expected an error").to_string();
    for p in parts {
        assert!(msg.contains(p), "{msg:?} does not contain {p:?}");
    }
}
const MAT: [&str; 2] = [
    "calibration/Calib_Results_stereo.mat",
    "calibration/Calib_Results_stereo_compressed.mat",
];

// ---- Bouguet .mat ------------------------------------------------------------------------

#[test]
fn bouguet_mat_values_read_equal_values_written() {
    let l = Limits::default();
    let (fx, alpha) = (1150.24, 0.0012);
    // The generator's values (tools/fixtures/bouguet_stereo_mat.py), matrices row by row.
    let written: [(&str, Vec<f64>); 14] = [
        ("fc_left", vec![1150.24, 1151.78]),
        ("cc_left", vec![639.5, 479.5]),
        ("kc_left", vec![-0.21, 0.17, 0.0004, -0.0002, 0.0]),
        ("alpha_c_left", vec![alpha]),
        ("fc_right", vec![1148.9, 1150.1]),
        ("cc_right", vec![641.25, 477.75]),
        ("kc_right", vec![-0.205, 0.162, -0.0003, 0.0001, 0.011]),
        ("alpha_c_right", vec![0.0]),
        ("om", vec![0.00312, -0.01045, 0.00151]),
        ("T", vec![-120.1, 0.35, 1.92]),
        ("nx", vec![1280.0]),
        ("ny", vec![960.0]),
        (
            "KK_left",
            vec![fx, alpha * fx, 639.5, 0.0, 1151.78, 479.5, 0.0, 0.0, 1.0],
        ),
        (
            "KK_right",
            vec![1148.9, 0.0, 641.25, 0.0, 1150.1, 477.75, 0.0, 0.0, 1.0],
        ),
    ];
    let mut poses = Vec::new();
    for f in MAT {
        let bytes = std::fs::read(data(f)).unwrap();
        let vars = calib_bouguet_mat::variables(&bytes, &l).unwrap();
        for (name, values) in &written {
            let v = vars.iter().find(|v| v.name == *name).unwrap();
            assert_eq!(&v.values, values, "{f}: {name}");
            assert!(matches!(v.at, Place::Offset(o) if o >= 128));
        }
        // The string variable `calib_name_left` is framed and skipped.
        assert!(vars.iter().all(|v| v.name != "calib_name_left"));

        let path = data(f);
        assert_eq!(
            calib_opencv::detect_format(&path, &bytes, &l).unwrap(),
            CalibrationFormat::BouguetMat
        );
        let pose = calib_opencv::read_any_stereo(&path).unwrap();
        let t = pose.translation_m;
        assert!((t[0] + 0.1201).abs() < 1e-15 && (t[2] - 0.00192).abs() < 1e-15);
        // R saved beside om is rodrigues(om): the conversion from om reproduces it.
        let r = &vars.iter().find(|v| v.name == "R").unwrap().values;
        let m = pose.rotation_matrix();
        for (i, row) in m.iter().enumerate() {
            for (j, x) in row.iter().enumerate() {
                assert!((x - r[3 * i + j]).abs() < 1e-12, "R[{i}][{j}]");
            }
        }
        let cams = calib_opencv::read_any_cameras(&path, &l).unwrap();
        let names: Vec<_> = cams.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["left", "right"]);
        let (left, right) = (&cams[0].model, &cams[1].model);
        assert_eq!(
            (left.fx, left.fy, left.cx, left.cy, left.skew),
            (fx, 1151.78, 639.5, 479.5, alpha * fx)
        );
        assert_eq!(
            (left.width, left.height, left.distortion.k1),
            (1280, 960, -0.21)
        );
        assert_eq!(
            (right.fx, right.cy, right.distortion.k3),
            (1148.9, 477.75, 0.011)
        );
        assert_eq!(cams[1].extrinsics, Some(pose));
        let r2 = calib_opencv::read_calibration_entry(&path, Some("right"), &l).unwrap();
        assert_eq!(&r2, right);
        poses.push(pose);
    }
    assert_eq!(poses[0], poses[1], "compressed and uncompressed differ");
    // Same om and T as the printed text form: the shared conversion gives the same pose.
    let printed = calib_bouguet::read_stereo_path(&data("calibration/stereo_printed.m"), &l);
    assert_eq!(printed.unwrap(), poses[0]);
}

#[test]
fn bouguet_mat_bad_files_name_file_and_variable() {
    let l = Limits::default();
    err_of(
        calib_opencv::read_any_stereo(&data("calibration/bad/stereo_truncated.mat")),
        &[
            "stereo_truncated.mat",
            "byte offset 1184",
            "`T`",
            "truncated",
        ],
    );
    err_of(
        calib_opencv::read_any_stereo(&data("calibration/bad/stereo_om_is_text.mat")),
        &[
            "stereo_om_is_text.mat",
            "byte offset 976",
            "`om` is a char array",
        ],
    );
    // A compressed file cut inside `T`: the name comes from the partly inflated element.
    let z = std::fs::read(data(MAT[1])).unwrap();
    let at = calib_bouguet_mat::variables(&z, &l)
        .unwrap()
        .iter()
        .find_map(|v| match (v.name.as_str(), v.at) {
            ("T", Place::Offset(o)) => Some(o as usize),
            _ => None,
        })
        .unwrap();
    err_of(
        calib_bouguet_mat::parse_stereo(&z[..at + 40], &l),
        &[&format!("byte offset {at}"), "`T`", "truncated"],
    );
    // Missing variables, other MAT versions, not a MAT-file.
    let header = &z[..128];
    err_of(
        calib_bouguet_mat::parse_stereo(header, &l),
        &["a numeric variable `om`"],
    );
    err_of(
        calib_bouguet_mat::parse_cameras(header, &l),
        &["a numeric variable `fc`"],
    );
    let mut v73 = header.to_vec();
    v73[..10].copy_from_slice(b"MATLAB 7.3");
    err_of(
        calib_bouguet_mat::parse_stereo(&v73, &l),
        &["byte offset 0", "unsupported", "v7.3"],
    );
    err_of(
        calib_bouguet_mat::parse_stereo(b"om = [1 2 3];\n", &l),
        &["byte offset 0", "128-byte MATLAB Level-5 header"],
    );
    err_of(
        calib_bouguet_mat::parse_stereo(&[b'x'; 200], &l),
        &["byte offset 126", "endian indicator"],
    );
}

/// MATLAB array classes the property test writes, with their data type and byte width.
#[derive(Debug, Clone, Copy)]
enum Class {
    Double,
    Single,
    Int32,
    Int16,
    UInt8,
}

impl Class {
    /// (mxCLASS, miTYPE, bytes per value)
    fn codes(self) -> (u32, u32, usize) {
        match self {
            Class::Double => (6, 9, 8),
            Class::Single => (7, 7, 4),
            Class::Int32 => (12, 5, 4),
            Class::Int16 => (10, 3, 2),
            Class::UInt8 => (9, 2, 1),
        }
    }
    fn value(self, x: f64) -> f64 {
        match self {
            Class::Double => x,
            Class::Single => f64::from(x as f32),
            Class::Int32 => x.round().clamp(-2e9, 2e9),
            Class::Int16 => x.round().clamp(-32768.0, 32767.0),
            Class::UInt8 => x.round().clamp(0.0, 255.0),
        }
    }
    fn bytes(self, x: f64, big: bool) -> Vec<u8> {
        macro_rules! e {
            ($v:expr) => {
                if big {
                    $v.to_be_bytes().to_vec()
                } else {
                    $v.to_le_bytes().to_vec()
                }
            };
        }
        match self {
            Class::Double => e!(x),
            Class::Single => e!(x as f32),
            Class::Int32 => e!(x as i32),
            Class::Int16 => e!(x as i16),
            Class::UInt8 => vec![x as u8],
        }
    }
}

/// A minimal MATLAB Level-5 writer (one real matrix per variable, column-major data).
fn mat_file(vars: &[(String, usize, usize, Class, Vec<f64>)], big: bool, zip: bool) -> Vec<u8> {
    let u32b = |v: u32| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let sub = |ty: u32, body: &[u8]| {
        let mut out = Vec::new();
        if body.len() <= 4 && !body.is_empty() {
            out.extend(u32b(((body.len() as u32) << 16) | ty));
            out.extend(body);
            out.resize(8, 0);
        } else {
            out.extend(u32b(ty));
            out.extend(u32b(body.len() as u32));
            out.extend(body);
            out.resize(8 + body.len().div_ceil(8) * 8, 0);
        }
        out
    };
    let mut file = b"MATLAB 5.0 MAT-file, written by the regolith tests".to_vec();
    file.resize(124, b' ');
    file.extend(if big { [1u8, 0] } else { [0u8, 1] });
    file.extend(if big { b"MI" } else { b"IM" });
    for (name, rows, cols, class, values) in vars {
        let (mx, mi, _) = class.codes();
        let mut body = sub(6, &[u32b(mx), u32b(0)].concat());
        body.extend(sub(5, &[u32b(*rows as u32), u32b(*cols as u32)].concat()));
        body.extend(sub(1, name.as_bytes()));
        let mut col_major = Vec::new();
        for j in 0..*cols {
            for i in 0..*rows {
                col_major.extend(class.bytes(values[i * cols + j], big));
            }
        }
        body.extend(sub(mi, &col_major));
        let element = [u32b(14).to_vec(), u32b(body.len() as u32).to_vec(), body].concat();
        if zip {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
            z.write_all(&element).unwrap();
            let z = z.finish().unwrap();
            file.extend(u32b(15));
            file.extend(u32b(z.len() as u32));
            file.extend(z);
        } else {
            file.extend(element);
        }
    }
    file
}

fn class() -> impl Strategy<Value = Class> {
    prop_oneof![
        Just(Class::Double),
        Just(Class::Single),
        Just(Class::Int32),
        Just(Class::Int16),
        Just(Class::UInt8),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Any real matrix of the classes MATLAB and scipy write, little or big endian, compressed
    /// or not, reads back row by row with the values written.
    #[test]
    fn mat_write_read_round_trip(
        rows in 1usize..5,
        cols in 1usize..5,
        class in class(),
        raw in proptest::collection::vec(-300.0..300.0f64, 16),
        big in any::<bool>(),
        zip in any::<bool>(),
    ) {
        let values: Vec<f64> = raw.iter().take(rows * cols).map(|x| class.value(*x)).collect();
        let vars = vec![
            ("note".to_string(), 1, 1, Class::Double, vec![1.0]),
            ("KK_left".to_string(), rows, cols, class, values.clone()),
            ("T".to_string(), 3, 1, Class::Double, vec![-120.0, 0.5, 2.0]),
        ];
        let file = mat_file(&vars, big, zip);
        let read = calib_bouguet_mat::variables(&file, &Limits::default()).unwrap();
        prop_assert_eq!(read.len(), 2);
        prop_assert_eq!(&read[0].name, "KK_left");
        prop_assert_eq!(&read[0].values, &values);
        prop_assert_eq!(&read[1].values, &vec![-120.0, 0.5, 2.0]);
    }
}

#[test]
fn mat_hostile_sizes_are_errors_not_panics() {
    let l = Limits::default();
    let ok = mat_file(
        &[("om".into(), 3, 1, Class::Double, vec![0.1, 0.2, 0.3])],
        false,
        false,
    );
    assert!(calib_bouguet_mat::variables(&ok, &l).is_ok());
    // Layout: header 0..128, matrix tag 128 (size at 132), flags 136..152, dimensions tag 152
    // (size at 156) with rows at 160 and columns at 164. Patches: dimensions whose product
    // overflows i32, a negative dimension, a huge element size, a huge subelement size.
    let patches: [&[(usize, u32)]; 4] = [
        &[(160, 0x7FFF_FFFF), (164, 0x7FFF_FFFF)],
        &[(160, 0xFFFF_FFFF)],
        &[(132, 0xFFFF_FFF0)],
        &[(156, 0xFFFF_FFF8)],
    ];
    for patch in patches {
        let mut bad = ok.clone();
        for (at, value) in patch {
            bad[*at..at + 4].copy_from_slice(&value.to_le_bytes());
        }
        let e = calib_bouguet_mat::variables(&bad, &l)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("byte offset 1"), "{patch:?}: {e}");
    }
    // A zlib bomb is stopped at the byte budget.
    let zeros = vec![0u8; 1 << 20];
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(&zeros).unwrap();
    let z = z.finish().unwrap();
    let mut bomb = ok[..128].to_vec();
    bomb.extend(15u32.to_le_bytes());
    bomb.extend((z.len() as u32).to_le_bytes());
    bomb.extend(&z);
    let small = Limits {
        max_object_bytes: 64 << 10,
        ..Limits::default()
    };
    err_of(
        calib_bouguet_mat::variables(&bomb, &small),
        &["byte offset 128", "inflated MAT-file bytes"],
    );
}

// ---- OpenCV FileStorage JSON ---------------------------------------------------------------

#[test]
fn opencv_json_twin_reads_like_the_yaml() {
    let l = Limits::default();
    let json = data("calibration/left_intrinsics.json");
    let bytes = std::fs::read(&json).unwrap();
    assert_eq!(
        calib_opencv::detect_format(&json, &bytes, &l).unwrap(),
        CalibrationFormat::Opencv
    );
    let j = calib_opencv::read_any_calibration(&json).unwrap();
    let y = calib_opencv::read_any_calibration(&real("calibration/left_intrinsics.yml")).unwrap();
    assert_eq!(j, y);
    assert_eq!(
        (j.fx, j.cx, j.width),
        (535.915_733_961_632, 342.283_154_733_083_73, 640)
    );

    let pair = calib_opencv::read_path(&data("calibration/stereo_pair.json"), &l).unwrap();
    let names: Vec<_> = pair.cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["1", "2", "LEFT"]);
    let yaml = calib_opencv::read_path(&real("calibration/intrinsics.yml"), &l).unwrap();
    assert_eq!(pair.cameras[..2], yaml.cameras[..]);
    let left = &pair.cameras[2].model;
    assert_eq!((left.width, left.height), (640, 480));
    assert_eq!(left.fx, pair.cameras[0].model.fx);
    // T = [-120.1, 0.35, 1.92] with |T| > 10: millimetres; R = Rodrigues(om) of the .mat fixture.
    let s = pair.stereo.unwrap().right_from_left;
    assert!((s.translation_m[0] + 0.1201).abs() < 1e-15);
    let mat = calib_opencv::read_any_stereo(&data(MAT[0])).unwrap();
    let (a, b) = (s.rotation_matrix(), mat.rotation_matrix());
    assert!((0..9).all(|k| (a[k / 3][k % 3] - b[k / 3][k % 3]).abs() < 1e-12));
    let via_dispatch = calib_opencv::read_any_stereo(&data("calibration/stereo_pair.json"));
    assert_eq!(via_dispatch.unwrap(), s);
}

#[test]
fn opencv_json_bad_inputs_name_file_line_and_key() {
    let l = Limits::default();
    err_of(
        calib_opencv::read_path(&data("calibration/bad/camera_3x2.json"), &l),
        &["camera_3x2.json", "line 4", "`camera_matrix` is 3x2"],
    );
    err_of(
        calib_opencv::parse(
            b"{\n  \"camera_matrix\": {\"rows\": 3,\n  \"cols\" 3 }\n}",
            &l,
        ),
        &["line 3", "well-formed JSON"],
    );
    err_of(
        calib_opencv::parse(
            b"{\n \"K\": {\"type_id\": \"opencv-matrix\", \"rows\": 3, \"cols\": 3, \"dt\": \"d\",\n  \"data\": [1, 2]}\n}",
            &l,
        ),
        &["line 2", "3x3 with 1 channel(s) but `data` has 2 values"],
    );
    err_of(
        calib_opencv::parse(b"{\"image_width\": 640}", &l),
        &["line 1", "no camera matrix"],
    );
}

/// A FileStorage JSON document laid out as cv2 writes it.
fn cv2_json(k: &[f64; 4], d: &[f64; 5], size: (u32, u32)) -> String {
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:?}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "{{\n    \"image_width\": {},\n    \"image_height\": {},\n    \"camera_matrix\": {{\n        \"type_id\": \"opencv-matrix\",\n        \"rows\": 3,\n        \"cols\": 3,\n        \"dt\": \"d\",\n        \"data\": [ {} ]\n    }},\n    \"distortion_coefficients\": {{\n        \"type_id\": \"opencv-matrix\",\n        \"rows\": 1,\n        \"cols\": 5,\n        \"dt\": \"d\",\n        \"data\": [ {} ]\n    }}\n}}\n",
        size.0,
        size.1,
        list(&[k[0], 0.0, k[2], 0.0, k[1], k[3], 0.0, 0.0, 1.0]),
        list(d)
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn opencv_json_write_read_round_trip(
        f in proptest::array::uniform2(1.0..5000.0f64),
        c in proptest::array::uniform2(0.0..4000.0f64),
        d in proptest::array::uniform5(-1.0..1.0f64),
        w in 1u32..10_000,
        h in 1u32..10_000,
    ) {
        let text = cv2_json(&[f[0], f[1], c[0], c[1]], &d, (w, h));
        let cal = calib_opencv::parse(text.as_bytes(), &Limits::default()).unwrap();
        let m = &cal.cameras[0].model;
        prop_assert_eq!((m.fx, m.fy, m.cx, m.cy, m.width, m.height), (f[0], f[1], c[0], c[1], w, h));
        let got = [m.distortion.k1, m.distortion.k2, m.distortion.p1, m.distortion.p2, m.distortion.k3];
        prop_assert_eq!(got, d);
    }
}

// ---- Sweeps --------------------------------------------------------------------------------

/// Every prefix of every fixture parses or fails without a panic; so does every single-byte
/// corruption of the `.mat` files (three values per byte).
#[test]
fn prefix_and_byte_flip_sweeps_never_panic() {
    let l = Limits::default();
    let mut cases = 0;
    let mats = MAT.iter().chain(&["calibration/bad/stereo_om_is_text.mat"]);
    for f in mats {
        let b = std::fs::read(data(f)).unwrap();
        for n in 0..=b.len() {
            let _ = calib_bouguet_mat::parse_stereo(&b[..n], &l);
            let _ = calib_bouguet_mat::parse_cameras(&b[..n], &l);
            cases += 1;
        }
        for i in 0..b.len() {
            for v in [0x00, 0xFF, b[i] ^ 0x80] {
                let mut c = b.clone();
                c[i] = v;
                let _ = calib_bouguet_mat::variables(&c, &l);
                cases += 1;
            }
        }
    }
    for f in [
        "calibration/left_intrinsics.json",
        "calibration/stereo_pair.json",
    ] {
        let b = std::fs::read(data(f)).unwrap();
        assert!(calib_opencv::parse(&b, &l).is_ok());
        for n in 0..=b.len() {
            let _ = calib_opencv::parse(&b[..n], &l);
            let _ = opencv_json::parse(&b[..n], &l);
            cases += 1;
        }
    }
    assert!(cases > 15_000, "only {cases} cases ran");
}
