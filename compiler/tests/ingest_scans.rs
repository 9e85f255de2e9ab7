//! Integration tests for the laser-scan readers: real snippets (tests/data/scans, see its
//! PROVENANCE.md), the real third-party files of ../shared/realdata with their documented
//! facts, corrupt inputs (error names the place and what was expected), truncation sweeps and
//! write→read round trips.

// Test helpers unwrap; float literals are copied verbatim from the files they check.
#![allow(clippy::unwrap_used, clippy::excessive_precision)]

use proptest::prelude::*;
use regolith_compiler::ingest::types::{transform, PointCloud};
use regolith_compiler::ingest::{e57, las, ply, ptx, riscan_ascii, riscan_rsp, sop_dat, tiepoints};
use regolith_format::limits::Limits;

mod common;
use common::{realdata, scan_data as data};

fn bytes(name: &str) -> Vec<u8> {
    std::fs::read(data(name)).unwrap()
}

fn lim() -> Limits {
    Limits::default()
}

/// Asserts the error text contains every piece.
fn assert_err<T: std::fmt::Debug>(r: Result<T, regolith_compiler::IngestError>, pieces: &[&str]) {
    let msg = r.unwrap_err().to_string();
    for p in pieces {
        assert!(msg.contains(p), "{msg:?} lacks {p:?}");
    }
}

// ---- RiSCAN ASCII ----------------------------------------------------------------------

#[test]
fn rdb2_comma_header_above_space_rows() {
    let c = riscan_ascii::read_path(&data("riscan_rdb2.asc"), None, &lim()).unwrap();
    assert_eq!(c.points.len(), 3);
    assert_eq!(
        c.points[0],
        [-16.002730909121258, -7.7914503973701389, 11.430690765380859]
    );
    assert_eq!(
        c.points[2],
        [515632.66332186362, 5519682.7927730317, 3143447.4201939853]
    );
    assert_eq!(c.reflectance_db.unwrap(), vec![-12.53, 2.75, -0.01]);
    assert!(c.intensity.is_none() && c.rgb.is_none());
}

#[test]
fn v1_header_with_unit_interval_colour_and_crlf() {
    let c = riscan_ascii::read_path(&data("riscan_v1.txt"), None, &lim()).unwrap();
    assert_eq!(c.points, vec![[1.5, -2.25, 0.125], [-0.75, 3.5, -1.0]]);
    assert_eq!(c.rgb.unwrap(), vec![[255, 128, 0], [51, 102, 153]]);
    assert_eq!(c.intensity.unwrap(), vec![0.25, 0.75]);
}

#[test]
fn scanifc_semicolons_and_exponents() {
    let c = riscan_ascii::read_path(&data("scanifc.txt"), None, &lim()).unwrap();
    assert_eq!(c.points[1], [25.0, -3.0e-5, 12.0]);
    assert_eq!(c.reflectance_db.unwrap(), vec![-7.25, -22.5]);
}

#[test]
fn declared_columns_and_3dtk_count_line() {
    let cols = "x y z range theta phi reflectance";
    let c = riscan_ascii::read_path(&data("riegl_txt_3dtk.txt"), Some(cols), &lim()).unwrap();
    assert_eq!(c.points.len(), 3);
    assert_eq!(c.reflectance_db.unwrap(), vec![-9.5, -3.25, -28.0]);
    // Without a column list a 7-field file is refused rather than guessed.
    assert_err(
        riscan_ascii::read_path(&data("riegl_txt_3dtk.txt"), None, &lim()),
        &["line 2", "column list"],
    );
    // A wrong count line is reported on its line.
    let mut b = bytes("riegl_txt_3dtk.txt");
    b[0] = b'4';
    assert_err(
        riscan_ascii::read_ascii(&b, Some(cols), &lim()),
        &["line 1", "says 4 points", "has 3"],
    );
}

#[test]
fn ascii_bad_inputs_name_line_and_expectation() {
    let r = |n: &str| riscan_ascii::read_path(&data(n), None, &lim());
    assert_err(
        r("bad/nan_coordinate.asc"),
        &[
            "line 3",
            "expected a finite number for Y[m] in field 2",
            "NaN",
            "nan_coordinate.asc",
        ],
    );
    assert_err(
        r("bad/text_in_number.asc"),
        &["line 3", "expected a finite number for Y[m]", "\"abc\""],
    );
    assert_err(
        r("bad/mixed_delimiters.asc"),
        &["line 4", "separated by ','", "4.0;5.0;6.0;-1.0"],
    );
    assert_err(
        r("bad/comma_decimal.asc"),
        &["line 2", "expected a finite number for X[m]", "\"1,5\""],
    );
}

#[test]
fn line_numbers_survive_parallel_chunks() {
    // ~10 MB, so at least two 8 MB chunks; the bad row sits in the second chunk.
    let mut text = String::from("X[m] Y[m] Z[m]\n");
    let rows = 400_000;
    for i in 0..rows {
        text.push_str(&format!("{}.25 -{}.5 1234.125\n", i, i % 977));
    }
    let good = riscan_ascii::read_ascii(text.as_bytes(), None, &lim()).unwrap();
    assert_eq!(good.points.len(), rows);
    assert_eq!(
        good.points[rows - 1],
        [
            (rows - 1) as f64 + 0.25,
            -(((rows - 1) % 977) as f64) - 0.5,
            1234.125
        ]
    );
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let serial =
        one_thread.install(|| riscan_ascii::read_ascii(text.as_bytes(), None, &lim()).unwrap());
    assert_eq!(serial, good);
    text.push_str("1 2 x\n");
    assert_err(
        riscan_ascii::read_ascii(text.as_bytes(), None, &lim()),
        &[&format!("line {}", rows + 2), "Z[m]"],
    );
    let tight = Limits {
        max_points: 1000,
        ..lim()
    };
    assert_err(
        riscan_ascii::read_ascii(good_text(100_000).as_bytes(), None, &tight),
        &["points", "limit of 1000"],
    );
}

fn good_text(rows: usize) -> String {
    (0..rows).map(|i| format!("{i} 0 0\n")).collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn ascii_write_read_identity(pts in prop::collection::vec(
        (-1e6f64..1e6, -1e6f64..1e6, -1e4f64..1e4, -40f32..10.0, any::<[u8; 3]>()), 1..40))
    {
        let cloud = PointCloud {
            points: pts.iter().map(|p| [p.0, p.1, p.2]).collect(),
            reflectance_db: Some(pts.iter().map(|p| p.3).collect()),
            rgb: Some(pts.iter().map(|p| p.4).collect()),
            ..Default::default()
        };
        let text = riscan_ascii::write_ascii(&cloud, "x y z reflectance r g b").unwrap();
        prop_assert_eq!(riscan_ascii::read_ascii(text.as_bytes(), None, &lim()).unwrap(), cloud.clone());
        let ply_text = ply::write_ply_ascii(&cloud);
        prop_assert_eq!(ply::read_ply(ply_text.as_bytes(), &lim()).unwrap(), cloud);
    }
}

// ---- SOP .DAT, project.rsp, tie points -------------------------------------------------

#[test]
fn dat_with_tabs_double_spaces_crlf_and_exponents() {
    let m = sop_dat::read_path(&data("sop_scanpos057.dat"), &lim()).unwrap();
    assert_eq!(
        [m[0][3], m[1][3], m[2][3]],
        [-3.147017251, 0.687843580, -11.269398476]
    );
    assert_eq!(m[1][2], -3.78155e-4);
    assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0]);
    assert_err(
        sop_dat::read_path(&data("bad/ambiguous_rotation.dat"), &lim()),
        &["ambiguous", "ambiguous_rotation.dat"],
    );
    assert_err(
        sop_dat::read_path(&data("bad/truncated.dat"), &lim()),
        &["line 3", "expected 4 lines of 4 numbers"],
    );
    assert_err(
        sop_dat::read_sop_dat(b"1 0 0 1\n0 1 0 2\n0 0 1 3\n1 1 1 1\n"),
        &["last row or last column of 0 0 0 1"],
    );
}

#[test]
fn rsp_pop_sop_and_tie_points() {
    let p = riscan_rsp::read_path(&data("project.rsp"), &lim()).unwrap();
    assert_eq!(p.name, "2.2.1_Test_InfraTec_VZ1000_Calibration");
    let pop = p.pop.unwrap();
    assert_eq!(
        [pop[0][3], pop[1][3], pop[2][3]],
        [-515632.66332186362, -5519682.7927730317, 3143447.4201939853]
    );
    let sp = &p.scan_positions[0];
    assert_eq!(sp.name, "SP01");
    let sop = sp.sop.unwrap();
    assert_eq!(
        [sop[0][1], sop[0][3], sop[2][3]],
        [
            4.7632160018149184E-005,
            -3.1470172510255578,
            -11.26939847569156
        ]
    );
    assert_eq!(sp.tie_points.len(), 1);
    assert_eq!(sp.tie_points[0].name, "tp001");
    assert_eq!(
        sp.tie_points[0].xyz,
        [-16.002730909121258, -7.7914503973701389, 11.430690765380859]
    );
    assert_err(
        riscan_rsp::read_path(&data("bad/text_in_sop.rsp"), &lim()),
        &["line 15", "SOP of SP01", "\"abc\""],
    );
}

#[test]
fn rsp_refuses_entity_tricks_without_fetching() {
    let xml = br#"<?xml version="1.0"?><!DOCTYPE project SYSTEM "http://example.invalid/x.dtd" [
        <!ENTITY a "&b;&b;"><!ENTITY b "&a;">]><project name="&a;"/>"#;
    assert!(riscan_rsp::read_rsp(xml, &lim()).is_err());
}

#[test]
fn tie_point_table_and_duplicates() {
    let t = tiepoints::read_path(&data("tiepoints.csv"), &lim()).unwrap();
    assert_eq!(t.len(), 2);
    assert_eq!(
        t[0].xyz,
        [-16.002730909121258, -7.7914503973701389, 11.430690765380859]
    );
    assert_eq!(t[1].name, "GSE Flat 10 cm");
    assert_err(
        tiepoints::read_path(&data("bad/duplicate_names.csv"), &lim()),
        &["line 4", "duplicate", "tp001", "first on line 2"],
    );
    assert_err(
        tiepoints::read_tiepoints(b"a,1,2\n", &lim()),
        &["line 1", "4 fields"],
    );
}

// ---- PTX --------------------------------------------------------------------------------

#[test]
fn ptx_complex_transform_skips_missing_points() {
    let scans = ptx::read_path(&data("complex-transform.ptx"), &lim()).unwrap();
    assert_eq!(scans.len(), 1);
    let s = &scans[0];
    assert_eq!(s.points.len(), 4); // 2 x 6 grid, 8 missing returns
    assert_eq!(s.points[0], [-0.005630, 0.645218, -0.440506]);
    assert_eq!(s.rgb.as_ref().unwrap()[0], [33, 38, 24]);
    let pose = s.pose.unwrap();
    assert_eq!(
        [pose[0][3], pose[1][3], pose[2][3]],
        [-3.028748, -3.819741, -1.384333]
    );
    assert_eq!(pose[0][1], 0.003613); // transposed from the row-vector file
    assert_err(
        ptx::read_path(&data("bad/truncated.ptx"), &lim()),
        &["line 17", "7 fields like the first point of scan 1"],
    );
    let head: Vec<u8> = bytes("complex-transform.ptx")
        .split(|&b| b == b'\n')
        .take(14)
        .collect::<Vec<_>>()
        .join(&b'\n');
    assert_err(
        ptx::read_ptx(&head, &lim()),
        &[
            "line 14",
            "point line 5 of 12 (columns x rows) of scan 1",
            "end of file",
        ],
    );
}

#[test]
fn ptx_multiple_scans_pose_maps_scan1_onto_scan2() {
    let scans = ptx::read_path(&data("multiple-and-transform.ptx"), &lim()).unwrap();
    assert_eq!(
        scans.iter().map(|s| s.points.len()).collect::<Vec<_>>(),
        vec![4, 4]
    );
    for (a, b) in scans[0].points.iter().zip(&scans[1].points) {
        let t = transform(&scans[0].pose.unwrap(), *a);
        assert!((0..3).all(|k| (t[k] - b[k]).abs() < 1e-6), "{t:?} vs {b:?}");
    }
    assert!(scans[0].rgb.is_none());
}

// ---- E57, LAS, PLY (real files) ---------------------------------------------------------

#[test]
fn e57_real_files() {
    let pump = e57::read_path(&realdata("scans/pumpAVisualReferenceImage.e57"), &lim()).unwrap();
    assert_eq!(pump.iter().map(|c| c.points.len()).sum::<usize>(), 155_201);
    assert!(pump[0].rgb.is_some() && pump[0].intensity.is_some());
    let bunny = e57::read_path(&realdata("scans/bunnyDouble.e57"), &lim()).unwrap();
    assert_eq!(bunny[0].points.len(), 30_571);
    // 360 records (the documented fact); half are direction-only (no range) and are dropped.
    let path = realdata("scans/tiny_spherical.e57");
    let raw = ::e57::E57Reader::from_file(&path).unwrap();
    assert_eq!(raw.pointclouds()[0].records, 360);
    let sph = e57::read_path(&path, &lim()).unwrap();
    assert_eq!(sph[0].points.len(), 180);
    assert!(sph[0]
        .points
        .iter()
        .all(|p| p.iter().all(|v| v.is_finite())));
}

#[test]
fn las_and_laz_real_files() {
    let simple = las::read_path(&realdata("scans/simple.las"), &lim()).unwrap();
    assert_eq!(simple.points.len(), 1_065);
    assert!(simple.rgb.is_some());
    let veg = las::read_path(&realdata("scans/vegetation_1_3.las"), &lim()).unwrap();
    assert_eq!(veg.points.len(), 10_683);
    assert!(veg.rgb.is_none());
    let autzen = las::read_path(&realdata("scans/autzen_trim.laz"), &lim()).unwrap();
    assert_eq!(autzen.points.len(), 110_000);
}

#[test]
fn ply_real_sfm_cloud() {
    let c = ply::read_path(&realdata("sfm/Example.ply"), &lim()).unwrap();
    assert_eq!(c.points.len(), 7_817);
    assert_eq!(c.rgb.map(|v| v.len()), Some(7_817));
}

#[test]
fn ply_meshes() {
    let m = ply::read_mesh_path(&data("cmpmvs_quad_crlf.ply"), &lim()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.colors.unwrap()[3], [128, 128, 128]);
    let t = ply::read_mesh_path(&data("textured_st_uint_count.ply"), &lim()).unwrap();
    assert_eq!(t.texture.as_deref(), Some("texture_0.png"));
    assert_eq!(t.uvs.unwrap(), vec![[0.0, 1.0], [1.0, 1.0], [0.0, 0.75]]);
    assert_err(
        ply::read_mesh_path(&data("bad/face_index_out_of_range.ply"), &lim()),
        &["face 0", "below 3 vertices"],
    );
}

#[test]
fn ply_binary_big_endian_equals_ascii() {
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n".to_vec();
    for (p, c) in [
        ([1.5f64, -2.0, 3.25], [1u8, 2, 3]),
        ([1e6, 0.1, -7.0], [250, 0, 9]),
    ] {
        p.iter().for_each(|v| b.extend(v.to_be_bytes()));
        b.extend(c);
    }
    let c = ply::read_ply(&b, &lim()).unwrap();
    let ascii = "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n1.5 -2 3.25 1 2 3\n1000000 0.1 -7 250 0 9\n";
    assert_eq!(c, ply::read_ply(ascii.as_bytes(), &lim()).unwrap());
    assert_eq!(c.points[1], [1e6, 0.1, -7.0]);
}

#[test]
fn ply_meshlab_per_corner_texcoords_ascii_and_binary() {
    let a = ply::read_mesh_path(&data("meshlab_textured_ascii.ply"), &lim()).unwrap();
    assert_eq!(a.texture.as_deref(), Some("texture.png"));
    // MeshLab's per-wedge atlas puts a seam through vertices 1 and 2: one output vertex per
    // (vertex, uv) pair, so 6 vertices for 2 triangles.
    assert_eq!(a.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    let (p0, p1, p2, p3) = (
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.5],
    );
    assert_eq!(a.positions, vec![p0, p1, p2, p1, p3, p2]);
    let (r, g, b, w) = ([255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]);
    assert_eq!(a.colors, Some(vec![r, g, b, g, w, b]));
    // The face lines as written (u v per corner, v up), flipped to v down.
    let written: [[f32; 2]; 6] = [
        [0.007812, 0.992188],
        [0.007812, 0.018861],
        [0.981139, 0.992188],
        [0.018861, 0.007812],
        [0.992188, 0.007812],
        [0.992188, 0.981139],
    ];
    let flip = |uv: &[f32; 2]| [uv[0], (1.0 - f64::from(uv[1])) as f32];
    assert_eq!(
        a.uvs.clone().unwrap(),
        written.iter().map(flip).collect::<Vec<_>>()
    );

    let bin = ply::read_mesh_path(&data("meshlab_textured_binary.ply"), &lim()).unwrap();
    assert_eq!(
        (&bin.positions, &bin.triangles, &bin.colors, &bin.texture),
        (&a.positions, &a.triangles, &a.colors, &a.texture)
    );
    // Binary keeps MeshLab's float32 values: 0.5/64 = 0.0078125 and 63.5/64 = 0.9921875.
    let bu = bin.uvs.unwrap();
    assert_eq!(bu[0], [0.0078125, 1.0 - 0.9921875]);
    let au = a.uvs.unwrap();
    assert!(bu
        .iter()
        .zip(&au)
        .all(|(x, y)| (x[0] - y[0]).abs() < 1e-6 && (x[1] - y[1]).abs() < 1e-6));
}

#[test]
fn ply_texcoords_shared_corners_quads_texnumber_and_bad_counts() {
    let header = |texnumber: bool| {
        format!(
            "ply\nformat ascii 1.0\ncomment TextureFile a.png\ncomment TextureFile b.png\nelement vertex 5\n\
             property float x\nproperty float y\nproperty float z\nelement face 2\n\
             property list uchar int vertex_indices\nproperty list uchar float texcoord\n{}end_header\n\
             0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n",
            if texnumber { "property int texnumber\n" } else { "" }
        )
    };
    // A quad and a triangle sharing the edge 1-2 with the same UVs there.
    let quad = "4 0 1 2 3 8 0 0 0.5 0 0.5 0.5 0 0.5";
    let tri = "3 1 4 2 6 0.5 0 1 0 0.5 0.5";
    let m = ply::read_ply_mesh(
        format!("{}{quad} 1\n{tri} 1\n", header(true)).as_bytes(),
        &lim(),
    )
    .unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
    assert_eq!(m.positions.len(), 5);
    assert_eq!(m.positions[4], [2.0, 0.0, 0.0]);
    assert_eq!(m.uvs.as_ref().unwrap()[4], [1.0, 1.0]);
    assert_eq!(m.texture.as_deref(), Some("b.png"));
    let plain = ply::read_ply_mesh(
        format!("{}{quad}\n{tri}\n", header(false)).as_bytes(),
        &lim(),
    );
    assert_eq!(plain.unwrap().texture.as_deref(), Some("a.png"));
    assert_err(
        ply::read_ply_mesh(
            format!("{}{quad} 0\n{tri} 1\n", header(true)).as_bytes(),
            &lim(),
        ),
        &[
            "unsupported",
            "face 1 uses texture 1",
            "one texture per mesh",
        ],
    );
    assert_err(
        ply::read_ply_mesh(
            format!("{}{quad} 2\n{tri} 2\n", header(true)).as_bytes(),
            &lim(),
        ),
        &["texnumber 2", "2 `TextureFile`s"],
    );
    let nan = textured_ply(
        &[[0.0; 3]; 3],
        &[([0, 1, 2], [[0.5, f32::NAN], [0.0; 2], [1.0; 2]])],
        true,
    );
    assert_err(
        ply::read_ply_mesh(&nan, &lim()),
        &["face 0 has 6 texcoord values, expected 6 finite ones"],
    );
    assert_err(
        ply::read_mesh_path(&data("bad/texcoord_count.ply"), &lim()),
        &[
            "texcoord_count.ply",
            "face 1 has 4 texcoord values, expected 6",
        ],
    );
}

/// A textured triangle mesh as MeshLab writes it (`texcoord` per face), ascii or binary LE.
fn textured_ply(pos: &[[f64; 3]], faces: &[([u32; 3], [[f32; 2]; 3])], binary: bool) -> Vec<u8> {
    let format = if binary {
        "binary_little_endian"
    } else {
        "ascii"
    };
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment TextureFile atlas.png\nelement vertex {}\n\
         property double x\nproperty double y\nproperty double z\nelement face {}\n\
         property list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n",
        pos.len(),
        faces.len()
    )
    .into_bytes();
    for p in pos {
        if binary {
            p.iter().for_each(|v| out.extend(v.to_le_bytes()));
        } else {
            out.extend(format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]).bytes());
        }
    }
    for (idx, uv) in faces {
        if binary {
            out.push(3);
            idx.iter()
                .for_each(|i| out.extend((*i as i32).to_le_bytes()));
            out.push(6);
            uv.iter()
                .flatten()
                .for_each(|v| out.extend(v.to_le_bytes()));
        } else {
            let uvs: Vec<String> = uv.iter().flatten().map(|v| format!("{v:?}")).collect();
            out.extend(format!("3 {} {} {} 6 {}\n", idx[0], idx[1], idx[2], uvs.join(" ")).bytes());
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Every corner of every triangle reads back with the position and UV written for it, in
    /// ascii and binary alike.
    #[test]
    fn ply_per_corner_uv_round_trip(
        pos in prop::collection::vec(prop::array::uniform3(-1e3f64..1e3), 3..10),
        faces in prop::collection::vec(
            (prop::array::uniform3(0u32..10), prop::array::uniform3(prop::array::uniform2(
                prop_oneof![Just(0.0f32), Just(0.25), Just(1.0), 0.0f32..1.0]))),
            1..12),
    ) {
        let n = pos.len() as u32;
        let faces: Vec<_> = faces.into_iter().map(|(i, uv)| (i.map(|k| k % n), uv)).collect();
        let ascii = ply::read_ply_mesh(&textured_ply(&pos, &faces, false), &lim()).unwrap();
        let binary = ply::read_ply_mesh(&textured_ply(&pos, &faces, true), &lim()).unwrap();
        prop_assert_eq!(&ascii, &binary);
        prop_assert_eq!(ascii.triangles.len(), faces.len());
        let uvs = ascii.uvs.unwrap();
        prop_assert_eq!(uvs.len(), ascii.positions.len());
        for (t, (idx, uv)) in ascii.triangles.iter().zip(&faces) {
            for k in 0..3 {
                let v = t[k] as usize;
                prop_assert_eq!(ascii.positions[v], pos[idx[k] as usize]);
                prop_assert_eq!(uvs[v], [uv[k][0], (1.0 - f64::from(uv[k][1])) as f32]);
            }
        }
    }
}

// ---- Truncation sweep --------------------------------------------------------------------

#[test]
fn every_prefix_is_ok_or_err_never_a_panic() {
    let text_samples = [
        "riscan_rdb2.asc",
        "riscan_v1.txt",
        "scanifc.txt",
        "riegl_txt_3dtk.txt",
        "sop_scanpos057.dat",
        "tiepoints.csv",
        "complex-transform.ptx",
        "multiple-and-transform.ptx",
        "project.rsp",
        "cmpmvs_quad_crlf.ply",
        "textured_st_uint_count.ply",
        "meshlab_textured_ascii.ply",
        "meshlab_textured_binary.ply",
    ];
    let mut cases = 0;
    for name in text_samples {
        let b = bytes(name);
        for n in 0..=b.len() {
            let p = &b[..n];
            let _ = riscan_ascii::read_ascii(p, None, &lim());
            let _ = sop_dat::read_sop_dat(p);
            let _ = tiepoints::read_tiepoints(p, &lim());
            let _ = ptx::read_ptx(p, &lim());
            let _ = riscan_rsp::read_rsp(p, &lim());
            let _ = ply::read_ply(p, &lim());
            let _ = ply::read_ply_mesh(p, &lim());
            cases += 1;
        }
    }
    // Binary readers: prefixes of a real file at a coarse stride plus the whole header region.
    for (name, read) in [
        (
            "scans/simple.las",
            (|p: &[u8]| las::read_las(p, &lim()).is_ok()) as fn(&[u8]) -> bool,
        ),
        ("scans/tiny_spherical.e57", |p: &[u8]| {
            e57::read_e57(p, &lim()).is_ok()
        }),
    ] {
        let b = std::fs::read(realdata(name)).unwrap();
        let cuts = (0..b.len().min(2048)).chain((2048..b.len()).step_by(997));
        for n in cuts {
            let _ = read(&b[..n]);
            cases += 1;
        }
        assert!(read(&b));
    }
    assert!(cases > 5_000, "only {cases} truncation cases ran");
}
