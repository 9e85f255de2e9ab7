//! Campaign, Vicon and calibration readers against real third-party files
//! (`../shared/realdata`, facts from its PROVENANCE.md), the fixtures in `tests/data/`
//! (PROVENANCE.md there), hostile variants in `bad/`, and a truncation sweep.

// Helpers outside `#[test]` functions are test code too: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};

use regolith_compiler::ingest::calib_opencv::{self, CalibrationFormat};
use regolith_compiler::ingest::{
    c3d, calib_bouguet, calib_kalibr, calib_ros, campaign, markers, vicon_csv, vicon_tracker,
    yaml_lite,
};
use regolith_format::limits::Limits;

fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
fn real(rel: &str) -> PathBuf {
    crate_dir().join("../../shared/realdata").join(rel)
}
fn data(rel: &str) -> PathBuf {
    crate_dir().join("tests/data").join(rel)
}
fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}
/// The error message, which must name `file` and contain every part.
fn assert_err<T: std::fmt::Debug>(
    r: Result<T, regolith_compiler::IngestError>,
    file: &str,
    parts: &[&str],
) -> String {
    let msg = r.expect_err("expected an error").to_string();
    assert!(msg.contains(file), "{msg:?} does not name {file}");
    for p in parts {
        assert!(msg.contains(p), "{msg:?} does not contain {p:?}");
    }
    msg
}

#[test]
fn nexus_csv_real_export() {
    let t = vicon_csv::read_path(&real("vicon/pyomeca_markers.csv"), &Limits::default()).unwrap();
    assert_eq!((t.rate_hz, t.first_frame, t.markers.len()), (100.0, 1, 51));
    assert!(t.markers.iter().all(|m| m.frames.len() == 580));
    let boite: Vec<_> = t
        .markers
        .iter()
        .filter(|m| m.subject.as_deref() == Some("boite"))
        .collect();
    assert_eq!(boite.len(), 8);
    assert_eq!(
        t.markers
            .iter()
            .filter(|m| m.subject.as_deref() == Some("Daphnee"))
            .count(),
        43
    );
    // Line 6 of the file: `1,0,44.1628,-276.862,675.697,...` (mm) for boite:gauche_ext.
    assert_eq!(boite[0].name, "gauche_ext");
    let p = boite[0].frames[0].unwrap();
    assert!(
        close(p[0], 0.0441628, 1e-12)
            && close(p[1], -0.276862, 1e-12)
            && close(p[2], 0.675697, 1e-12)
    );
}

fn mm(x: f64) -> f64 {
    x * 1e-3
}

/// The hand-written export of tests/data/vicon (PROVENANCE.md there): Segments, Trajectories,
/// Model Outputs in that order, frames 101..103, gaps as empty cells.
#[test]
fn nexus_segments_and_model_outputs_fixture() {
    let l = Limits::default();
    let path = data("vicon/nexus_sections.csv");
    let x = vicon_csv::read_export_path(&path, &l).unwrap();

    let s = x.segments.clone().unwrap();
    assert_eq!(
        (s.rate_hz, s.first_frame, s.segments.len()),
        (100.0, 101, 2)
    );
    let (head, pelvis) = (&s.segments[0], &s.segments[1]);
    assert_eq!(
        (head.name.as_str(), head.subject.as_deref()),
        ("Head", Some("Subject01"))
    );
    assert_eq!(pelvis.name, "Pelvis");
    let h0 = head.frames[0].unwrap();
    assert_eq!(h0.rotation_deg, [1.5, -2.25, 90.0]);
    assert_eq!(h0.translation_m, [mm(100.5), mm(200.0), mm(1500.0)]);
    assert_eq!(pelvis.frames.len(), 3);
    assert_eq!(pelvis.frames[1], None);
    let p2 = pelvis.frames[2].unwrap();
    assert_eq!(
        (p2.rotation_deg, p2.translation_m),
        ([0.5, 0.0, -44.0], [mm(11.0), mm(-19.0), mm(951.0)])
    );
    assert_eq!(
        vicon_csv::parse_segments(&std::fs::read(&path).unwrap(), &l).unwrap(),
        s
    );

    let m = x.model_outputs.clone().unwrap();
    assert_eq!((m.rate_hz, m.first_frame), (100.0, 101));
    let shape: Vec<(&str, usize)> = m
        .outputs
        .iter()
        .map(|o| (o.name.as_str(), o.columns.len()))
        .collect();
    assert_eq!(
        shape,
        [
            ("LAnkleAngles", 3),
            ("LAnklePower", 3),
            ("StepWidth", 1),
            ("LGRFPeak", 4)
        ]
    );
    let col = |o: usize, c: usize| &m.outputs[o].columns[c];
    assert_eq!(
        (col(0, 0).label.as_str(), col(0, 0).unit.as_str()),
        ("X", "deg")
    );
    assert_eq!(col(0, 0).values, vec![Some(10.5), Some(11.0), Some(11.5)]);
    assert_eq!(col(1, 2).unit, "W/kg");
    assert_eq!(col(1, 2).values, vec![Some(0.35), None, Some(0.4)]);
    assert_eq!((col(2, 0).unit.as_str(), col(2, 0).values[2]), ("mm", None));
    assert_eq!(
        (col(3, 3).label.as_str(), col(3, 3).unit.as_str()),
        ("Count", "")
    );
    assert_eq!(col(3, 2).values, vec![Some(9.8), Some(9.9), Some(10.1)]);

    let t = x.trajectories.unwrap();
    assert_eq!(t, vicon_csv::read_path(&path, &l).unwrap());
    let names: Vec<_> = t.markers.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["LASI", "RASI", "*12"]);
    assert_eq!(t.markers[2].subject, None);
    assert_eq!(t.markers[1].frames[1], None);
    assert_eq!(
        t.markers[0].frames[2],
        Some([mm(121.5), mm(-79.75), mm(951.0)])
    );
}

#[test]
fn nexus_sections_in_any_order_with_devices_semicolons_and_radians() {
    let l = Limits::default();
    let text = std::fs::read_to_string(data("vicon/nexus_sections.csv")).unwrap();
    let reference = vicon_csv::parse_export(text.as_bytes(), &l).unwrap();
    let blocks: Vec<&str> = text
        .split("\r\n\r\n")
        .map(|b| b.trim_matches(['\r', '\n']))
        .filter(|b| !b.is_empty())
        .collect();
    assert_eq!(blocks.len(), 3);
    let devices = "Devices\r\n1000\r\n,,Plate,,\r\nFrame,Sub Frame,Fx,Fy,Fz\r\n,,N,N,N\r\n101,0,1,2,3\r\n101,1,1,2,3";
    let orders = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    for (k, order) in orders.iter().enumerate() {
        let mut parts: Vec<&str> = order.iter().map(|&i| blocks[i]).collect();
        parts.insert(k % 4, devices);
        let file = format!("\u{feff}\r\n{}\r\n", parts.join("\r\n\r\n"));
        assert_eq!(
            vicon_csv::parse_export(file.as_bytes(), &l).unwrap(),
            reference,
            "{order:?}"
        );
        let semi = file.replace(',', ";").replace("0.5", "0,5");
        let got = vicon_csv::parse_export(semi.as_bytes(), &l).unwrap();
        assert_eq!(got, reference, "semicolons, {order:?}");
    }
    // Each section alone is enough for parse_export; the others are then None.
    let only = vicon_csv::parse_export(blocks[2].as_bytes(), &l).unwrap();
    assert_eq!((only.trajectories, only.segments), (None, None));
    assert_eq!(only.model_outputs, reference.model_outputs);

    let rad = "Segments\n100\n,,S:Root,,,,,\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,rad,rad,rad,m,m,m\n1,0,3.141592653589793,0,-1.5707963267948966,1,2,3\n";
    let s = vicon_csv::parse_segments(rad.as_bytes(), &l).unwrap();
    let f = s.segments[0].frames[0].unwrap();
    assert!((f.rotation_deg[0] - 180.0).abs() < 1e-12 && (f.rotation_deg[2] + 90.0).abs() < 1e-12);
    assert_eq!(f.translation_m, [1.0, 2.0, 3.0]);
}

#[test]
fn bad_nexus_sections_name_line_and_object() {
    let l = Limits::default();
    let seg = |roles: &str, units: &str, row: &str| {
        format!("Segments\n100\n,,S:Head,,,,,\nFrame,Sub Frame,{roles}\n,,{units}\n{row}\n")
    };
    let (roles, units) = ("RX,RY,RZ,TX,TY,TZ", "deg,deg,deg,mm,mm,mm");
    let e = vicon_csv::parse_segments(
        seg("RX,RY,RZ,TX,TY,X", units, "1,0,1,2,3,4,5,6").as_bytes(),
        &l,
    );
    assert_eq!(
        e.unwrap_err().to_string(),
        "line 4: expected RX, RY, RZ, TX, TY, TZ columns under segment `S:Head`, found \"RX\""
    );
    let e = vicon_csv::parse_segments(
        seg(roles, "mm,deg,deg,mm,mm,mm", "1,0,1,2,3,4,5,6").as_bytes(),
        &l,
    );
    assert!(e
        .unwrap_err()
        .to_string()
        .starts_with("line 5: expected an angle unit (deg, rad) for segment `S:Head`"));
    let e = vicon_csv::parse_segments(seg(roles, units, "1,0,1,2,x,4,5,6").as_bytes(), &l);
    assert_eq!(
        e.unwrap_err().to_string(),
        "line 6: expected a value of segment `S:Head`, found \"x\""
    );
    let out = "Model Outputs\n100\n,,S:Out,,\nFrame,Sub Frame,X,Y\n,,deg,deg\n7,0,1,abc\n";
    let e = vicon_csv::parse_model_outputs(out.as_bytes(), &l)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "line 6: expected a value of model output `S:Out`, found \"abc\""
    );
    let unlabelled = "Model Outputs\n100\n,,S:Out,,\nFrame,Sub Frame,,\n,,deg,deg\n";
    assert!(vicon_csv::parse_model_outputs(unlabelled.as_bytes(), &l)
        .unwrap_err()
        .to_string()
        .contains("at least one labelled column under model output `S:Out`"));
    let no_units = "Model Outputs\n100\n,,S:Out,,\nFrame,Sub Frame,X,Y\n7,0,1,2\n";
    assert!(vicon_csv::parse_model_outputs(no_units.as_bytes(), &l)
        .unwrap_err()
        .to_string()
        .starts_with("line 5: expected a units row"));
    assert_err(
        vicon_csv::read_export_path(&data("vicon/bad/no_trajectories.csv"), &l),
        "no_trajectories.csv",
        &[
            "line 1",
            "a `Trajectories`, `Segments` or `Model Outputs` section",
        ],
    );
    let e = vicon_csv::parse_segments(b"Trajectories\n100\n", &l).unwrap_err();
    assert_eq!(
        e.to_string(),
        "line 1: expected a `Segments` section, found \"none\""
    );
    // Reading trajectories does not depend on the other sections being readable.
    let broken = format!(
        "{}\n{}",
        seg(roles, units, "1,0,1,2,x,4,5,6"),
        "Trajectories\n100\n,,s:m,,\nFrame,Sub Frame,X,Y,Z\n,,mm,mm,mm\n1,0,1,2,3\n"
    );
    assert_eq!(
        vicon_csv::parse(broken.as_bytes(), &l).unwrap().markers[0].frames,
        vec![Some([mm(1.0), mm(2.0), mm(3.0)])]
    );
    assert!(vicon_csv::parse_export(broken.as_bytes(), &l).is_err());
}

#[test]
fn c3d_first_frame_matches_csv() {
    let csv = vicon_csv::read_path(&real("vicon/pyomeca_markers.csv"), &Limits::default()).unwrap();
    let c = c3d::read_path(
        &real("vicon/pyomeca_markers_analogs.c3d"),
        &Limits::default(),
    )
    .unwrap();
    assert_eq!(c.rate_hz, 100.0);
    let mut compared = 0;
    for m in &csv.markers {
        let Some(p) = m.frames[0] else { continue };
        let other = c
            .markers
            .iter()
            .find(|o| o.name == m.name && o.subject == m.subject);
        let other = other
            .or_else(|| c.markers.iter().find(|o| o.name == m.name))
            .unwrap_or_else(|| panic!("{} missing in C3D", m.name));
        let q = other.frames[0].unwrap();
        for a in 0..3 {
            // The CSV prints 6 significant digits; C3D stores f32.
            assert!(close(p[a], q[a], 1e-5), "{}: {p:?} vs {q:?}", m.name);
        }
        compared += 1;
    }
    assert!(compared >= 40, "only {compared} markers compared");
}

#[test]
fn tracker_fixture_poses() {
    let t = vicon_tracker::read_path(&data("vicon/tracker_rover.csv"), 250.0, &Limits::default())
        .unwrap();
    let names: Vec<_> = t.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["rover:rover", "rig:rig"]);
    assert_eq!((t.rate_hz, t.first_frame), (250.0, 1));
    // Frame 1: helical (0, 0, π/2) and (1000, 2000, 300) mm: x axis maps to y, shifted.
    let p = t.objects[0].poses[0]
        .unwrap()
        .transform_point([1.0, 0.0, 0.0]);
    assert!(
        close(p[0], 1.0, 1e-12) && close(p[1], 3.0, 1e-12) && close(p[2], 0.3, 1e-12),
        "{p:?}"
    );
    assert_eq!(
        t.objects[1].poses,
        vec![Some(regolith_format::frames::Pose::IDENTITY), None, None]
    );
    assert!(close(
        t.objects[0].poses[2]
            .unwrap()
            .angle_to_deg(&Default::default()),
        (0.14f64).sqrt().to_degrees(),
        1e-9
    ));
    assert!(vicon_tracker::parse(b"Frame,Sub Frame,RX\n", 0.0, &Limits::default()).is_err());
}

#[test]
fn static_markers_from_campaign_fixture() {
    let t =
        vicon_csv::read_path(&data("campaign/ok/vicon/markers.csv"), &Limits::default()).unwrap();
    let (m, w) = markers::static_markers(&t, 2);
    assert_eq!(m.len(), 2);
    assert!(
        close(m[0].mean[0], 0.00005, 1e-12)
            && close(m[0].std[0], 0.00005, 1e-12)
            && m[0].frames == 2
    );
    assert_eq!(
        w,
        vec![markers::MarkerWarning::FewFrames {
            marker: "G3".into(),
            frames: 1,
            min: 2
        }]
    );
    // The capture CSV and the rig CSV: balls 0.1 m along each axis, seen translated by (1, 2, 0.5).
    let rig = markers::read_rig_markers(
        &data("campaign/ok/calib/rig_markers.csv"),
        &Limits::default(),
    )
    .unwrap();
    let cap =
        vicon_csv::read_path(&data("campaign/ok/vicon/loc01.csv"), &Limits::default()).unwrap();
    let pose = markers::fit_rig_pose(&rig, &cap).unwrap();
    let t = pose.ground_from_left.translation_m;
    assert!(
        close(t[0], 1.0, 1e-9) && close(t[1], 2.0, 1e-9) && close(t[2], 0.5, 1e-9),
        "{pose:?}"
    );
    assert!(pose.ground_from_left.angle_to_deg(&Default::default()) < 1e-6);
}

#[test]
fn opencv_yaml_and_xml_twin() {
    let y = calib_opencv::read_any_calibration(&real("calibration/left_intrinsics.yml")).unwrap();
    assert!(close(y.fx, 535.92, 0.01) && close(y.fy, 535.92, 0.01));
    assert!(
        close(y.cx, 342.28, 0.01)
            && close(y.cy, 235.57, 0.01)
            && close(y.distortion.k1, -0.266, 0.001)
    );
    assert_eq!((y.width, y.height), (640, 480));
    assert!(y.validate().is_ok());
    let x = calib_opencv::read_any_calibration(&data("calibration/left_intrinsics.xml")).unwrap();
    assert_eq!(x, y);
}

#[test]
fn opencv_stereo_and_rig_files() {
    let l = Limits::default();
    let euroc = calib_opencv::read_path(&real("calibration/euroc_stereo_opencv.yaml"), &l).unwrap();
    let left = euroc.cameras.iter().find(|c| c.name == "LEFT").unwrap();
    assert_eq!(
        (left.model.fx, left.model.cy, left.model.width),
        (458.654, 248.375, 752)
    );
    assert_eq!(left.model.distortion.k1, -0.28340811); // written as `data:[` with no space
    let right = euroc.cameras.iter().find(|c| c.name == "RIGHT").unwrap();
    assert_eq!(right.model.distortion.p2, -3.555907e-05);
    let rect = euroc.cameras.iter().find(|c| c.name == "Camera").unwrap();
    assert_eq!((rect.model.fx, rect.model.height), (435.2046959714599, 480));

    let pair = real("calibration/intrinsics.yml");
    let cams = calib_opencv::read_path(&pair, &l).unwrap().cameras;
    assert_eq!(
        cams.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
        ["1", "2"]
    );
    assert_eq!(
        (cams[0].model.cx, cams[0].model.width),
        (335.686_432_043_948_9, 0)
    );
    assert_eq!(cams[1].model.distortion.k1, -1.6916358306948096e-01);
    assert_err(
        calib_opencv::read_any_calibration(&pair),
        "intrinsics.yml",
        &["exactly one camera", "\"1\", \"2\""],
    );
    let m2 = calib_opencv::read_calibration_entry(&pair, Some("2"), &l).unwrap();
    assert_eq!(m2.cy, 242.053_245_733_766); // written 2.4205324573376600e+02

    let rig = calib_opencv::read_path(&real("calibration/enav_rover_rig.yaml"), &l).unwrap();
    assert_eq!(rig.cameras.len(), 10);
    let o0 = &rig.cameras[0];
    assert_eq!(
        (
            o0.name.as_str(),
            o0.model.fx,
            o0.model.distortion.k3,
            o0.model.width
        ),
        ("omni0", 482.047, -0.0416498, 752)
    );
    let t = o0.extrinsics.unwrap().translation_m; // |T| = 56.6 > 10: millimetres
    assert!(close(t[2], -0.0564338, 1e-12) && close(t[0], 0.00010017, 1e-12));

    for f in ["stereo_calib.xml", "calibration.yml"] {
        assert_err(
            calib_opencv::read_path(&real(&format!("calibration/{f}")), &l),
            f,
            &["line ", "no camera matrix"],
        );
    }
    let s = calib_opencv::read_any_stereo(&data("campaign/ok/calib/stereo.yaml")).unwrap();
    assert!(close(s.translation_m[0], -0.12, 1e-12));
}

#[test]
fn ros_bouguet_kalibr() {
    let l = Limits::default();
    let ros_path = real("calibration/ros_camera_info.yaml");
    let bytes = std::fs::read(&ros_path).unwrap();
    assert_eq!(
        calib_opencv::detect_format(&ros_path, &bytes, &l).unwrap(),
        CalibrationFormat::Ros
    );
    let r = calib_ros::read_path(&ros_path, &l).unwrap();
    assert_eq!(
        (r.fx, r.cy, r.width, r.distortion.k1, r.distortion.p2),
        (438.783367, 243.738352, 640, -0.361976, 0.000505)
    );

    let b =
        calib_opencv::read_any_calibration(&real("calibration/bouguet_Calib_Results.m")).unwrap();
    assert!(
        close(b.fx, 657.6, 0.05)
            && close(b.fy, 658.0, 0.05)
            && close(b.cx, 303.2, 0.05)
            && close(b.cy, 242.6, 0.05)
    );
    assert!(close(b.distortion.k1, -0.256, 0.001) && close(b.distortion.k2, 0.131, 0.001));
    assert_eq!((b.width, b.height, b.skew), (640, 480, 0.0));

    let k = calib_kalibr::read_path(&data("calibration/kalibr_camchain.yaml"), &l).unwrap();
    assert_eq!(
        (k.cameras[1].model.fx, k.cameras[1].model.width),
        (457.587, 752)
    );
    let s = calib_opencv::read_any_stereo(&data("calibration/kalibr_camchain.yaml")).unwrap();
    assert!(close(s.translation_m[0], -0.11003785, 1e-12));

    let printed = data("calibration/stereo_printed.m");
    let p = calib_opencv::read_any_stereo(&printed).unwrap();
    assert!(close(p.translation_m[0], -0.1201, 1e-12) && close(p.translation_m[2], 0.00192, 1e-12));
    let left = calib_bouguet::read_path(&printed, &l).unwrap();
    assert_eq!((left.fx, left.cy, left.width), (1150.24, 479.5, 0));
}

#[test]
fn bad_calibrations_name_file_and_line() {
    let l = Limits::default();
    assert_err(
        calib_opencv::read_path(&data("calibration/bad/camera_3x2.yml"), &l),
        "camera_3x2.yml",
        &["line 2", "`camera_matrix` is 3x2"],
    );
    assert_err(
        calib_opencv::read_path(&data("calibration/bad/rational_model.yml"), &l),
        "rational_model.yml",
        &["line 9", "unsupported", "rational"],
    );
    assert_err(
        calib_opencv::read_path(&data("calibration/bad/empty.yml"), &l),
        "empty.yml",
        &["line 1"],
    );
    assert_err(
        calib_bouguet::read_path(&data("calibration/bad/bouguet_bad_number.m"), &l),
        "bouguet_bad_number.m",
        &["line 2", "\"2x42.6\""],
    );
    assert_err(
        calib_kalibr::read_path(&data("calibration/bad/empty.yml"), &l),
        "empty.yml",
        &["line 1", "cam0"],
    );
}

#[test]
fn bad_vicon_files_name_file_and_line() {
    let l = Limits::default();
    assert_err(
        vicon_csv::read_path(&data("vicon/bad/no_units_row.csv"), &l),
        "no_units_row.csv",
        &["line 5", "units row"],
    );
    assert_err(
        vicon_csv::read_path(&data("vicon/bad/text_in_cell.csv"), &l),
        "text_in_cell.csv",
        &["line 7", "marker `s:m1`", "\"abc\""],
    );
    assert_err(
        vicon_csv::read_path(&data("vicon/bad/empty.csv"), &l),
        "empty.csv",
        &["line 1", "Trajectories"],
    );
    assert_err(
        vicon_csv::read_path(&data("vicon/bad/no_trajectories.csv"), &l),
        "no_trajectories.csv",
        &["`Trajectories` section"],
    );
    assert_err(
        c3d::read_path(&data("vicon/bad/empty.csv"), &l),
        "empty.csv",
        &["byte offset 0"],
    );
}

#[test]
fn campaign_fixture_resolves() {
    let c = campaign::load(&data("campaign/ok")).unwrap();
    assert_eq!(
        (
            c.name.as_str(),
            c.scans.len(),
            c.cameras.len(),
            c.terrains.len()
        ),
        ("mini-lab", 1, 2, 2)
    );
    assert_eq!(
        c.scans[0].columns.as_deref(),
        Some(&["x", "y", "z", "reflectance"].map(String::from)[..])
    );
    assert_eq!(c.rig.as_ref().map(|r| (r.left, r.right)), Some((0, 1)));
    assert_eq!(
        c.captures[0].right,
        vec![PathBuf::from("captures/loc01_right_a.png")]
    );
    assert_eq!(c.terrains[0].from, campaign::TerrainSource::Scans(vec![0]));
    assert_eq!(c.terrains[1].texture, campaign::Texture::VertexColor);
    let expected = [
        "calib/navcam_left.yaml",
        "calib/navcam_right.yaml",
        "calib/rig_markers.csv",
        "calib/stereo.yaml",
        "captures/loc01_left_a.png",
        "captures/loc01_left_b.png",
        "captures/loc01_right_a.png",
        "scans/pos1.asc",
        "scans/pos1_tiepoints.csv",
        "sfm/mesh.wrl",
        "vicon/loc01.csv",
        "vicon/markers.csv",
    ];
    assert_eq!(c.input_files(), expected.map(PathBuf::from));
    for f in c.input_files() {
        assert!(c.root.join(f).is_file());
    }
    let cam = calib_opencv::read_any_calibration(&c.root.join(&c.cameras[0].calibration)).unwrap();
    assert_eq!(cam.width, 640);
}

/// Copies the good campaign into a temporary folder with `toml` as its campaign.toml.
fn temp_campaign(toml: &Path) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    fn copy(from: &Path, to: &Path) {
        for e in std::fs::read_dir(from).unwrap() {
            let e = e.unwrap();
            let dest = to.join(e.file_name());
            if e.path().is_dir() {
                std::fs::create_dir_all(&dest).unwrap();
                copy(&e.path(), &dest);
            } else {
                std::fs::copy(e.path(), dest).unwrap();
            }
        }
    }
    copy(&data("campaign/ok"), dir.path());
    std::fs::copy(toml, dir.path().join("campaign.toml")).unwrap();
    dir
}

#[test]
fn bad_campaigns_name_file_and_problem() {
    let cases: [(&str, &[&str]); 10] = [
        (
            "unknown_key",
            &["line 14", "unknown key `nmae`: did you mean `name`?"],
        ),
        (
            "escapes_folder",
            &["[[scan]] \"pos1\"", "must be relative and stay inside"],
        ),
        ("absolute_path", &["\"/etc/hostname\"", "must be relative"]),
        (
            "missing_file",
            &[
                "[[camera]] \"navcam_right\"",
                "\"calib/navcam_rihgt.yaml\" does not exist",
            ],
        ),
        ("unknown_terrain_source", &["\"pos2\" names no [[scan]]"]),
        ("zero_raster", &["raster_m[0] must be a positive number"]),
        ("empty", &["line 1", "missing field `schema`"]),
        (
            "drape_on_scans",
            &[
                "[[terrain]] \"laser\"",
                "drape_on is for reconstruction terrains",
            ],
        ),
        (
            "drape_unknown",
            &["drape_on = \"lazer\"", "names no laser (scans) terrain"],
        ),
        (
            "drape_missing_step",
            &[
                "[[terrain]] \"sfm\"",
                "the laser terrain has no raster_m 0.015",
            ],
        ),
    ];
    for (name, parts) in cases {
        let dir = temp_campaign(&data(&format!("campaign/bad/{name}.toml")));
        assert_err(campaign::load(dir.path()), "campaign.toml", parts);
    }
    #[cfg(unix)]
    {
        let dir = temp_campaign(&data("campaign/ok/campaign.toml"));
        let outside = tempfile::tempdir().unwrap();
        std::fs::write(outside.path().join("x.asc"), "1 2 3 4\n").unwrap();
        std::fs::remove_file(dir.path().join("scans/pos1.asc")).unwrap();
        std::os::unix::fs::symlink(
            outside.path().join("x.asc"),
            dir.path().join("scans/pos1.asc"),
        )
        .unwrap();
        assert_err(
            campaign::load(dir.path()),
            "campaign.toml",
            &["leads outside the campaign folder"],
        );
    }
}

/// Every prefix of every sample is parsed without a panic (errors are fine).
#[test]
fn truncation_sweep_never_panics() {
    let l = Limits::default();
    type Parser = fn(&[u8], &Limits) -> bool;
    let samples: Vec<(PathBuf, Parser)> = vec![
        (real("vicon/pyomeca_markers.csv"), |b, l| {
            vicon_csv::parse(b, l).is_ok()
        }),
        (data("vicon/nexus_sections.csv"), |b, l| {
            vicon_csv::parse_export(b, l).is_ok()
        }),
        (real("vicon/pyomeca_markers_analogs.c3d"), |b, l| {
            c3d::parse(b, l).is_ok()
        }),
        (data("vicon/tracker_rover.csv"), |b, l| {
            vicon_tracker::parse(b, 100.0, l).is_ok()
        }),
        (data("campaign/ok/calib/rig_markers.csv"), |b, l| {
            markers::parse_rig_markers(b, l).is_ok()
        }),
        (data("campaign/ok/campaign.toml"), |b, _| {
            std::str::from_utf8(b)
                .map(|s| campaign::parse_str(s).is_ok())
                .unwrap_or(false)
        }),
        (real("calibration/left_intrinsics.yml"), |b, l| {
            calib_opencv::parse(b, l).is_ok()
        }),
        (real("calibration/euroc_stereo_opencv.yaml"), |b, l| {
            calib_opencv::parse(b, l).is_ok()
        }),
        (real("calibration/enav_rover_rig.yaml"), |b, l| {
            yaml_lite::parse(b, l).is_ok()
        }),
        (data("calibration/left_intrinsics.xml"), |b, l| {
            calib_opencv::parse(b, l).is_ok()
        }),
        (real("calibration/ros_camera_info.yaml"), |b, l| {
            calib_ros::parse(b, l).is_ok()
        }),
        (real("calibration/bouguet_Calib_Results.m"), |b, l| {
            calib_bouguet::parse(b, l).is_ok()
        }),
        (data("calibration/stereo_printed.m"), |b, l| {
            calib_bouguet::parse_stereo(b, l).is_ok()
        }),
        (data("calibration/kalibr_camchain.yaml"), |b, l| {
            calib_kalibr::parse(b, l).is_ok()
        }),
    ];
    assert!(samples.len() >= 14);
    for (path, parse) in samples {
        let bytes = std::fs::read(&path).unwrap();
        assert!(parse(&bytes, &l), "{} does not parse whole", path.display());
        let step = (bytes.len() / 300).max(1);
        for n in (0..bytes.len()).step_by(step) {
            let _ = parse(&bytes[..n], &l);
        }
    }
}
