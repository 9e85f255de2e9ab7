//! Integration tests of the mesh/SfM and image readers: VRML, COLMAP, CMPMVS DEM, images and
//! undistortion, on real samples (`../shared/realdata`), the fixtures of `tests/data/` (see
//! their `PROVENANCE.md`), hostile inputs and a truncation sweep over every sample.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use regolith_compiler::ingest::types::TriMesh;
use regolith_compiler::ingest::{cmpmvs, colmap, images, undistort, vrml};
use regolith_format::camera_model::CameraModel;
use regolith_format::limits::Limits;

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(rel)
}

fn realdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/realdata")
        .join(rel)
}

fn lim() -> Limits {
    Limits::default()
}

fn normal(m: &TriMesh, t: [u32; 3]) -> [f64; 3] {
    let p = t.map(|i| m.positions[i as usize]);
    let a = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
    let b = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

// ------------------------------------------------------------------------------------ VRML

#[test]
fn vrml_three_js_mesh_with_texture() {
    let m = vrml::read_path(&data("vrml/meshWithTexture.wrl"), &lim()).unwrap();
    // 25 grid points, 32 triangles; texCoordIndex = coordIndex + 10 so each point has one uv.
    assert_eq!(m.positions.len(), 25);
    assert_eq!(m.triangles.len(), 32);
    assert_eq!(m.texture.as_deref(), Some("map.gif"));
    // scale 0.1 and a +90° turn about x map (x, 0, z) to 0.1 * (x, -z, ~0).
    let max = |i: usize| m.positions.iter().map(|p| p[i]).fold(f64::MIN, f64::max);
    let min = |i: usize| m.positions.iter().map(|p| p[i]).fold(f64::MAX, f64::min);
    assert!((max(0) - 2.027).abs() < 1e-9 && (min(0) + 2.027).abs() < 1e-9);
    assert!((max(1) - 2.137).abs() < 1e-5 && (min(1) + 2.137).abs() < 1e-5);
    assert!(max(2).abs() < 1e-3 && min(2).abs() < 1e-3);
    // The file's normal is +y; rotated by the Transform it is +z: every triangle faces +z.
    for &t in &m.triangles {
        let n = normal(&m, t);
        assert!(
            n[2] > 0.0 && n[2] > 100.0 * (n[0].abs() + n[1].abs()),
            "{n:?}"
        );
    }
    // Point 0 (-20.27, 0, 21.37) has texCoord 10 = (0, 0): glTF (0, 1); point 24 has (1, 1).
    let uvs = m.uvs.as_ref().unwrap();
    let find = |x: f64, y: f64| {
        m.positions
            .iter()
            .position(|p| (p[0] - x).abs() < 1e-6 && (p[1] - y).abs() < 1e-4)
            .unwrap()
    };
    assert_eq!(uvs[find(-2.027, -2.137)], [0.0, 1.0]);
    assert_eq!(uvs[find(2.027, 2.137)], [1.0, 0.0]);
    assert!(m.colors.is_none());
}

#[test]
fn vrml_cmpmvs_inline_transform_and_texture_transform() {
    let m = vrml::read_path(&data("vrml/cmpmvs_top.wrl"), &lim()).unwrap();
    assert_eq!(m.triangles.len(), 2);
    assert_eq!(m.texture.as_deref(), Some("meshAvImgTex_0.png"));
    // Top Transform: translation (1, 2, 3), scale 2 baked into the vertices.
    assert!(m.positions.contains(&[1.0, 2.0, 3.0]) && m.positions.contains(&[3.0, 4.0, 3.0]));
    // ISO 14772 TextureTransform: uv' = S·(uv + T) with S = (0.5, 0.25), T = (0.5, 0.5);
    // then v flipped. (-0.5, -0.5) -> (0, 0) -> glTF (0, 1); (0, 0) -> (0.25, 0.125) -> (0.25, 0.875).
    let uvs = m.uvs.as_ref().unwrap();
    let at = |p: [f64; 3]| uvs[m.positions.iter().position(|q| *q == p).unwrap()];
    assert_eq!(at([1.0, 2.0, 3.0]), [0.0, 1.0]);
    assert!(uvs.contains(&[0.25, 0.875]), "{uvs:?}");
    // (0.5, -0.5) -> (0.5, 0) -> glTF (0.5, 1).
    assert_eq!(at([3.0, 2.0, 3.0]), [0.5, 1.0]);
    // texCoordIndex differs from coordIndex: one vertex per distinct (point, uv) pair.
    assert_eq!(m.positions.len(), 4);
}

#[test]
fn vrml_def_use_trailing_commas_missing_final_separator() {
    let m = vrml::read_path(&data("vrml/synthetic_def_use.wrl"), &lim()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    assert_eq!(m.positions[3], [5.0, 0.0, 0.0]);
    assert_eq!(m.positions[5], [5.0, 1.0, 0.0]);
    // No texCoordIndex: coordIndex is reused; url lists take the first entry.
    assert_eq!(m.uvs.as_ref().unwrap()[1], [1.0, 1.0]);
    assert_eq!(m.uvs.as_ref().unwrap()[2], [0.0, 0.0]);
    assert_eq!(m.texture.as_deref(), Some("tex.png"));
}

#[test]
fn vrml_quad_per_face_colours_and_cw_faces() {
    let m = vrml::read_path(&data("vrml/synthetic_quad_colors.wrl"), &lim()).unwrap();
    assert_eq!(
        m.triangles.len(),
        3,
        "a quad fans into 2 triangles, plus one triangle"
    );
    for &t in &m.triangles {
        assert!(
            normal(&m, t)[2] > 0.0,
            "ccw FALSE faces are flipped to counter-clockwise"
        );
    }
    let colors = m.colors.as_ref().unwrap();
    // Face 0 uses colour 1 (blue), face 1 colour 0 (red): vertices split per (point, colour).
    assert_eq!(m.positions.len(), 7);
    let first = m.triangles[0].map(|i| colors[i as usize]);
    assert_eq!(first, [[0, 0, 255]; 3]);
    assert_eq!(m.triangles[2].map(|i| colors[i as usize]), [[255, 0, 0]; 3]);
}

#[test]
fn vrml_index_out_of_range_names_file_line_and_offset() {
    let p = data("vrml/bad/index_out_of_range.wrl");
    let e = vrml::read_path(&p, &lim()).unwrap_err().to_string();
    assert!(e.contains("coordIndex[6] = 7 is out of range"), "{e}");
    assert!(e.starts_with("line 5: byte offset"), "{e}");
    assert!(e.ends_with("index_out_of_range.wrl)"), "{e}");
}

#[test]
fn vrml_bad_inputs_are_errors_naming_the_problem() {
    let cases = [
        ("empty.wrl", "line 1: expected header"),
        ("vrml1_header.wrl", "#VRML V1.0 ascii"),
        ("nan_coordinate.wrl", "Coordinate point 1 is not finite"),
        ("unbalanced.wrl", "end of file"),
        ("use_before_def.wrl", "USE Missing: no DEF Missing"),
    ];
    for (name, want) in cases {
        let e = vrml::read_path(&data(&format!("vrml/bad/{name}")), &lim())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want) && e.contains(name), "{name}: {e}");
    }
    let nan = vrml::read_path(&data("vrml/bad/nan_coordinate.wrl"), &lim()).unwrap_err();
    assert!(nan.to_string().starts_with("line 4:"), "{nan}");
}

#[test]
fn vrml_hostile_nesting_and_use_fan_out_are_errors() {
    let deep = format!("#VRML V2.0 utf8\n{}", "Group { children [ ".repeat(100_000));
    assert!(vrml::read_bytes(deep.as_bytes(), &lim()).is_err());
    let mut fan = String::from("#VRML V2.0 utf8\nDEF A0 Group { }\n");
    for i in 1..40 {
        fan += &format!(
            "DEF A{i} Group {{ children [ USE A{0} USE A{0} ] }}\n",
            i - 1
        );
    }
    let e = vrml::read_bytes(fan.as_bytes(), &lim())
        .unwrap_err()
        .to_string();
    assert!(e.contains("DEF/USE fan-out"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn vrml_write_read_round_trip(
        pts in proptest::collection::vec(proptest::array::uniform3(-1e6..1e6f64), 3..12),
        tris in proptest::collection::vec(proptest::array::uniform3(0u32..3), 1..8),
        colored in any::<bool>(), textured in any::<bool>(), seed in 0u8..255,
    ) {
        let n = pts.len();
        let mesh = TriMesh {
            triangles: tris.iter().map(|t| t.map(|i| (i + u32::from(seed)) % n as u32)).collect(),
            colors: colored.then(|| (0..n).map(|i| [i as u8, seed, 255 - seed]).collect()),
            uvs: textured.then(|| (0..n).map(|i| [i as f32 / 16.0, f32::from(seed) / 255.0]).collect()),
            texture: textured.then(|| "atlas 0.png".to_string()),
            positions: pts,
        };
        let back = vrml::read_bytes(vrml::write_vrml(&mesh).as_bytes(), &lim()).unwrap();
        prop_assert_eq!(&back.positions, &mesh.positions);
        prop_assert_eq!(&back.triangles, &mesh.triangles);
        prop_assert_eq!(&back.colors, &mesh.colors);
        prop_assert_eq!(&back.texture, &mesh.texture);
        if let (Some(a), Some(b)) = (&back.uvs, &mesh.uvs) {
            for (x, y) in a.iter().zip(b) {
                prop_assert!((x[0] - y[0]).abs() < 1e-6 && (x[1] - y[1]).abs() < 1e-6);
            }
        }
        prop_assert_eq!(back.uvs.is_some(), mesh.uvs.is_some());
    }
}

// ------------------------------------------------------------------------------------ COLMAP

#[test]
fn colmap_real_sceaux_castle_model() {
    let m = colmap::read_dir(&realdata("sfm"), &lim()).unwrap();
    assert_eq!(m.images.len(), 11);
    assert_eq!(m.cameras.len(), 1);
    let cam = &m.cameras[&1];
    assert_eq!(cam.model_name, "SIMPLE_RADIAL");
    assert!((cam.camera.fx - 2971.71).abs() < 1e-9 && cam.camera.fy == cam.camera.fx);
    assert!((cam.camera.distortion.k1 + 0.164224).abs() < 1e-12);
    // COLMAP writes cx = 1416, cy = 1064 with (0.5, 0.5) at the first pixel's centre.
    assert_eq!((cam.camera.cx, cam.camera.cy), (1415.5, 1063.5));
    assert_eq!(
        m.points.cloud.points.len(),
        7862,
        "the header says 7862 points"
    );
    assert_eq!(m.points.cloud.rgb.as_ref().unwrap()[0], [66, 61, 42]);
    let img = &m.images[&10];
    assert_eq!(img.name, "100_7109.JPG");
    // Camera centre C = -Rᵀt, computed here with nalgebra from the file's QW QX QY QZ, T.
    let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        0.935286, -0.0186376, 0.349606, -0.0516467,
    ));
    let c = -(q.inverse() * nalgebra::Vector3::new(-5.18498, -0.238152, 0.0467711));
    let t = img.world_from_camera.translation_m;
    assert!((t[0] - c.x).abs() < 1e-9 && (t[1] - c.y).abs() < 1e-9 && (t[2] - c.z).abs() < 1e-9);
}

#[test]
fn colmap_real_points_reproject_onto_their_observations() {
    // Projects every track of the first 500 points with our camera and pose: the median error
    // must be near COLMAP's own ERROR column (sub-pixel), which checks the quaternion order, the
    // pose inversion, the distortion mapping and the 0.5 px shift applied to both sides.
    let m = colmap::read_dir(&realdata("sfm"), &lim()).unwrap();
    let mut errs = Vec::new();
    for (i, track) in m.points.tracks.iter().enumerate().take(500) {
        let p = m.points.cloud.points[i];
        for &(image_id, idx) in track {
            let img = &m.images[&image_id];
            let cam = &m.cameras[&img.camera_id].camera;
            let pc = img.world_from_camera.inverse().transform_point(p);
            let uv = cam.project(pc).unwrap();
            let obs = img.observations[idx as usize];
            assert_eq!(obs.point3d_id, Some(m.points.ids[i]));
            errs.push(((uv[0] - obs.xy[0]).powi(2) + (uv[1] - obs.xy[1]).powi(2)).sqrt());
        }
    }
    errs.sort_by(f64::total_cmp);
    let median = errs[errs.len() / 2];
    assert!(
        errs.len() > 1000 && median < 1.0,
        "median reprojection error {median} px"
    );
}

#[test]
fn colmap_synthetic_subfolders_empty_lines_non_contiguous_ids() {
    let m = colmap::read_dir(&data("colmap/subfolders"), &lim()).unwrap();
    assert_eq!(
        m.images.keys().copied().collect::<Vec<_>>(),
        vec![5, 17, 42]
    );
    assert_eq!(m.images[&42].name, "cam0/000001.png");
    assert!(m.images[&42].observations.is_empty() && m.images[&17].observations.is_empty());
    assert_eq!(m.images[&5].name, "cam1/left image 2.png");
    assert_eq!(m.cameras[&7].camera.distortion.p1, 0.0004);
    assert_eq!(
        (m.cameras[&2].camera.cx, m.cameras[&1].camera.cy),
        (1535.5, 1151.5)
    );
    // Point 900 lies on the optical axis of image 5: it projects to the principal point, which
    // is the observation 640 512 in COLMAP's convention, (639.5, 511.5) in ours.
    let img = &m.images[&5];
    let uv = m.cameras[&7].camera.project(
        img.world_from_camera
            .inverse()
            .transform_point([-3.0, 0.0, -1.0]),
    );
    let uv = uv.unwrap();
    assert!(
        (uv[0] - 639.5).abs() < 1e-9 && (uv[1] - 511.5).abs() < 1e-9,
        "{uv:?}"
    );
    assert_eq!(img.observations[0].xy, [639.5, 511.5]);
    assert_eq!(img.observations[1].point3d_id, None);
}

#[test]
fn colmap_bad_inputs_name_line_and_problem() {
    let cam =
        |f: &str| colmap::parse_cameras(&std::fs::read(data(&format!("colmap/bad/{f}"))).unwrap());
    let e = cam("cameras_fisheye.txt").unwrap_err().to_string();
    assert!(
        e.starts_with("line 1: unsupported: COLMAP camera model \"OPENCV_FISHEYE\""),
        "{e}"
    );
    let e = cam("cameras_missing_param.txt").unwrap_err().to_string();
    assert!(e.contains("4 parameters for PINHOLE, found 3"), "{e}");
    let bytes = |f: &str| std::fs::read(data(&format!("colmap/bad/{f}"))).unwrap();
    let e = colmap::parse_images(&bytes("images_ragged_points2d.txt"), &lim()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("line 2: 2 values: expected triples"),
        "{e}"
    );
    let e = colmap::parse_images(&bytes("images_bad_quaternion.txt"), &lim()).unwrap_err();
    assert!(
        e.to_string()
            .contains("expected QZ (a number), found \"zero\""),
        "{e}"
    );
    let e = colmap::parse_points3d(&bytes("points3D_nan.txt"), &lim()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("line 1: expected Y (a number), found \"nan\""),
        "{e}"
    );
    let e = colmap::read_dir(&data("colmap/bad"), &lim())
        .unwrap_err()
        .to_string();
    assert!(e.contains("cameras.txt"), "a missing file is named: {e}");
}

// ------------------------------------------------------------------------------------ CMPMVS

#[test]
fn cmpmvs_dem_maps_values_through_the_box() {
    let d = cmpmvs::read_path(&data("cmpmvs/DEM.png"), &lim()).unwrap();
    let g = &d.grid;
    assert_eq!((g.width, g.height), (4, 3));
    assert_eq!(g.cell_size, [1.0, 0.5]);
    assert_eq!(g.origin, [10.0, 21.5]);
    assert_eq!(g.get(0, 0), None, "0 is nodata");
    // v = 10000*col + 1000*row, height = -1 + v * 6.5535 / 65535.
    for (col, row) in [(1, 0), (3, 2), (0, 1)] {
        let v = f64::from(10000 * col + 1000 * row);
        assert!((g.get(col, row).unwrap() - (-1.0 + v * 1e-4)).abs() < 1e-12);
    }
    assert_eq!(g.cell_centre(0, 0), [10.5, 21.25]);
    assert_eq!(
        d.orthophoto.unwrap().file_name().unwrap(),
        "DEM_ortoPhoto.tiff"
    );
}

#[test]
fn cmpmvs_bad_boxes_name_the_assumption() {
    let e = cmpmvs::read_path(&data("cmpmvs/bad/rotated/DEM.png"), &lim())
        .unwrap_err()
        .to_string();
    assert!(e.contains("axis-aligned") && e.ends_with("DEM.txt)"), "{e}");
    let e = cmpmvs::read_path(&data("cmpmvs/bad/wrong_size/DEM.png"), &lim())
        .unwrap_err()
        .to_string();
    assert!(e.contains("4x3 but DEM.txt says W: 5 H: 3"), "{e}");
    let e = cmpmvs::parse_dem_txt(b"0: 1 2\nX: 1 0 0\n")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("line 1: expected `0:`"), "{e}");
    let e = cmpmvs::read_path(&data("images/grey8.png"), &lim())
        .unwrap_err()
        .to_string();
    assert!(e.contains("DEM.txt is required"), "{e}");
}

// ------------------------------------------------------------------------------------ images

#[test]
fn images_decode_formulas_of_the_generator() {
    let grey8 = images::read_path(&data("images/grey8.png"), &lim()).unwrap();
    assert_eq!((grey8.width, grey8.height, grey8.bit_depth), (5, 4, 8));
    assert_eq!(grey8.get(3, 2).unwrap(), (10.0 * 3.0 + 50.0 * 2.0) / 255.0);
    for name in ["images/grey16.png", "images/grey16.tif"] {
        let g = images::read_path(&data(name), &lim()).unwrap();
        assert_eq!(g.bit_depth, 16, "{name}");
        assert_eq!(
            g.get(4, 3).unwrap(),
            (1000.0 * 4.0 + 10000.0 * 3.0 + 7.0) / 65535.0,
            "{name}"
        );
    }
    let luma = |r: f64, g: f64, b: f64| 0.299 * r + 0.587 * g + 0.114 * b;
    for name in ["images/rgb8.png", "images/rgb8.tif"] {
        let g = images::read_path(&data(name), &lim()).unwrap();
        let want = luma(40.0 * 4.0, 60.0 * 1.0, 200.0 - 30.0 * 4.0) / 255.0;
        assert!(
            (f64::from(g.get(4, 1).unwrap()) - want).abs() < 1e-6,
            "{name}"
        );
    }
    let rgba = images::read_path(&data("images/rgba16.png"), &lim()).unwrap();
    assert_eq!(rgba.bit_depth, 16);
    let want = luma(12000.0 * 2.0, 20000.0 * 3.0, 3000.0) / 65535.0;
    assert!(
        (f64::from(rgba.get(2, 3).unwrap()) - want).abs() < 1e-6,
        "alpha is ignored"
    );
}

#[test]
fn images_real_curiosity_navcam_pair() {
    for name in [
        "NLB_524534514EDR_F0562034NCAM00280M_.jpeg",
        "NRB_524534514EDR_F0562034NCAM00280M_.jpeg",
    ] {
        let g = images::read_path(&realdata(&format!("rover/{name}")), &lim()).unwrap();
        assert_eq!((g.width, g.height, g.bit_depth), (1024, 1024, 8));
        let mean = g.data.iter().map(|&v| f64::from(v)).sum::<f64>() / g.data.len() as f64;
        assert!(mean > 0.05 && mean < 0.95, "{name}: mean {mean}");
        assert!(g.data.iter().all(|v| (0.0..=1.0).contains(v)));
    }
    let small = Limits {
        max_image_side: 1023,
        ..lim()
    };
    let e = images::read_path(
        &realdata("rover/NLB_524534514EDR_F0562034NCAM00280M_.jpeg"),
        &small,
    );
    assert!(e.unwrap_err().to_string().contains("image side"));
}

#[test]
fn images_bad_files_name_the_file() {
    for (name, want) in [
        ("truncated.png", "cannot decode Png"),
        ("empty.png", "expected a PNG, TIFF or JPEG signature"),
        ("not_an_image.png", "expected a PNG, TIFF or JPEG signature"),
    ] {
        let e = images::read_path(&data(&format!("images/bad/{name}")), &lim()).unwrap_err();
        let e = e.to_string();
        assert!(
            e.contains(want) && e.ends_with(&format!("{name})")),
            "{name}: {e}"
        );
    }
}

// ------------------------------------------------------------------------------------ undistort

#[test]
fn undistort_matches_opencv_peer() {
    // raw.png, camera.json and opencv.png (= cv2.undistort(raw, K, D, newCameraMatrix=K)) come
    // from tools/peers/undistort_opencv.py; compare away from the invalid border.
    let dir = data("images/undistort");
    let cam: CameraModel =
        serde_json::from_slice(&std::fs::read(dir.join("camera.json")).unwrap()).unwrap();
    let raw = images::read_path(&dir.join("raw.png"), &lim()).unwrap();
    let reference = images::read_path(&dir.join("opencv.png"), &lim()).unwrap();
    let out = undistort::UndistortMap::new(&cam, &lim())
        .unwrap()
        .apply(&raw)
        .unwrap();
    if let Ok(target) = std::env::var("REGOLITH_UNDISTORT_OUT") {
        std::fs::write(
            Path::new(&target).join("ours.png"),
            out.image.to_u8().unwrap(),
        )
        .unwrap();
    }
    let (w, h) = (cam.width as i64, cam.height as i64);
    let interior = |x: i64, y: i64| {
        (-2..=2).all(|dy| {
            (-2..=2).all(|dx| {
                let (u, v) = (x + dx, y + dy);
                u >= 0 && v >= 0 && u < w && v < h && out.valid[(v * w + u) as usize]
            })
        })
    };
    let (mut sum, mut n) = (0.0, 0usize);
    for y in 0..h {
        for x in 0..w {
            if interior(x, y) {
                let ours = (f64::from(out.image.data[(y * w + x) as usize]) * 255.0).round();
                let theirs = (f64::from(reference.data[(y * w + x) as usize]) * 255.0).round();
                sum += (ours - theirs).powi(2);
                n += 1;
            }
        }
    }
    let rms = (sum / n as f64).sqrt();
    eprintln!("undistort vs OpenCV: {n} interior pixels, RMS {rms:.4} grey levels");
    assert!(n > (w * h / 2) as usize, "enough interior pixels: {n}");
    assert!(rms <= 0.05, "RMS {rms} grey levels");
}

// ------------------------------------------------------------------------------------ sweep

#[test]
fn truncation_sweep_never_panics() {
    let files: Vec<PathBuf> = ["vrml", "images", "cmpmvs", "colmap/subfolders"]
        .iter()
        .flat_map(|d| {
            std::fs::read_dir(data(d))
                .unwrap()
                .map(|e| e.unwrap().path())
        })
        .chain(["sfm/cameras.txt", "sfm/images.txt", "sfm/points3D.txt"].map(realdata))
        .filter(|p| p.is_file())
        .collect();
    assert!(files.len() >= 20, "samples went missing: {}", files.len());
    let dem = cmpmvs::parse_dem_txt(&std::fs::read(data("cmpmvs/DEM.txt")).unwrap()).unwrap();
    for path in files {
        let bytes = std::fs::read(&path).unwrap();
        let step = (bytes.len() / 97).max(1);
        for len in (0..bytes.len()).step_by(step) {
            let cut = &bytes[..len];
            let _ = vrml::read_bytes(cut, &lim());
            let _ = images::decode(cut, &lim());
            let _ = colmap::parse_cameras(cut);
            let _ = colmap::parse_images(cut, &lim());
            let _ = colmap::parse_points3d(cut, &lim());
            let _ = cmpmvs::parse_dem_txt(cut);
            let _ = cmpmvs::height_grid(&dem, cut, &lim());
        }
    }
}
