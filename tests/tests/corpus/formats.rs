//! The E57, LAS and VRML writers round-trip through independent readers (the `e57` and `las`
//! crates' readers; the VRML structure counted by hand).

use regolith_corpus::instruments::{e57 as e57w, las as lasw};

fn sample() -> (Vec<[f64; 3]>, Vec<f32>) {
    let pts: Vec<[f64; 3]> = (0..500)
        .map(|i| {
            let t = i as f64 * 0.01;
            [3.0 * t.cos(), -2.0 + t, -1.2 + 0.1 * t.sin()]
        })
        .collect();
    let refl: Vec<f32> = (0..500).map(|i| -25.0 + (i % 29) as f32).collect();
    (pts, refl)
}

#[test]
fn e57_round_trips_points_and_reflectance() {
    let (pts, refl) = sample();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.e57");
    e57w::write(&path, "pos3", &pts, &refl, 9).unwrap();
    let mut r = e57::E57Reader::from_file(&path).unwrap();
    let pcs = r.pointclouds();
    assert_eq!(pcs.len(), 1);
    assert_eq!(pcs[0].records, 500);
    assert!(pcs[0].transform.is_none(), "written in SOCS, no pose");
    let read: Vec<e57::Point> = r
        .pointcloud_simple(&pcs[0])
        .unwrap()
        .map(|p| p.unwrap())
        .collect();
    for ((p, q), db) in read.iter().zip(&pts).zip(&refl) {
        match p.cartesian {
            e57::CartesianCoordinate::Valid { x, y, z } => assert_eq!([x, y, z], *q),
            ref c => panic!("{c:?}"),
        }
        let back = e57w::DB_RANGE[0]
            + f64::from(p.intensity.unwrap()) * (e57w::DB_RANGE[1] - e57w::DB_RANGE[0]);
        assert!((back - f64::from(*db)).abs() < 1e-4, "{back} vs {db}");
    }
}

#[test]
fn las_round_trips_at_a_tenth_of_a_millimetre() {
    let (pts, refl) = sample();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.las");
    lasw::write(&path, &pts, &refl).unwrap();
    let mut r = las::Reader::from_path(&path).unwrap();
    assert_eq!(r.header().number_of_points(), 500);
    let pd = r.read_all().unwrap();
    let data: Vec<las::Point> = pd.points().map(|p| p.unwrap()).collect();
    for ((p, q), db) in data.iter().zip(&pts).zip(&refl) {
        assert!(
            (p.x - q[0]).abs() <= 0.5e-4 + 1e-12
                && (p.y - q[1]).abs() <= 0.5e-4 + 1e-12
                && (p.z - q[2]).abs() <= 0.5e-4 + 1e-12
        );
        let back = e57w::DB_RANGE[0]
            + f64::from(p.intensity) / 65535.0 * (e57w::DB_RANGE[1] - e57w::DB_RANGE[0]);
        assert!((back - f64::from(*db)).abs() < 1e-3);
    }
}

#[test]
fn vrml_mesh_counts_match_the_ply_twin() {
    let dir = tempfile::tempdir().unwrap();
    let opts = regolith_corpus::GenerateOptions {
        preset: regolith_corpus::Preset::Mini,
        seed: 3,
        full: false,
        captures: None,
        hidden: vec![],
        auto_exposure: 0.0,
    };
    regolith_corpus::generate(
        &opts,
        dir.path(),
        &regolith_model_captures::ModelCaptures,
        &|_, _| {},
    )
    .unwrap();
    let wrl = std::fs::read_to_string(dir.path().join("sfm/mesh.wrl")).unwrap();
    assert!(wrl.starts_with("#VRML V2.0 utf8\n"));
    let section = |start: &str| -> Vec<&str> {
        let body = wrl.split(start).nth(1).unwrap().split(']').next().unwrap();
        body.split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .collect()
    };
    let points = section("point [");
    let colours = section("color [");
    let faces = section("coordIndex [");
    let ply = std::fs::read(dir.path().join("sfm/mesh.ply")).unwrap();
    let header =
        String::from_utf8_lossy(&ply[..ply.windows(10).position(|w| w == b"end_header").unwrap()])
            .to_string();
    let count = |el: &str| -> usize {
        header
            .lines()
            .find(|l| l.starts_with(el))
            .unwrap()
            .rsplit(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    assert_eq!(points.len(), count("element vertex"));
    assert_eq!(colours.len(), points.len());
    assert_eq!(faces.len(), count("element face"));
    // 2 m / 2 cm grid: 101 x 101 vertices, 2 triangles per quad.
    assert_eq!(points.len(), 101 * 101);
    assert_eq!(faces.len(), 2 * 100 * 100);
    let n = points.len();
    for f in &faces {
        let idx: Vec<i64> = f.split_whitespace().map(|t| t.parse().unwrap()).collect();
        assert_eq!(idx.len(), 4);
        assert_eq!(idx[3], -1);
        assert!(idx[..3].iter().all(|&i| i >= 0 && (i as usize) < n));
    }
    // The SfM frame is the true surface under the recorded similarity: scale 1/0.68.
    let sfm = serde_json::from_slice::<serde_json::Value>(
        &std::fs::read(dir.path().join("truth/sfm.json")).unwrap(),
    )
    .unwrap();
    assert!((sfm["scale"].as_f64().unwrap() - 1.0 / 0.68).abs() < 1e-12);
    let p = |i: usize| -> [f64; 3] {
        let v: Vec<f64> = points[i]
            .split_whitespace()
            .map(|t| t.parse().unwrap())
            .collect();
        [v[0], v[1], v[2]]
    };
    let (a, b) = (p(0), p(100));
    let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    assert!(
        (d / (1.0 / 0.68) - 2.0).abs() < 0.1,
        "a 2 m row spans {d} SfM units"
    );
}
