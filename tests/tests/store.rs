//! The database contract end to end: round trip of every kind, corruption detection,
//! immutable and atomic refs, determinism, gc.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::fs;
use std::path::Path;

use regolith_format::kinds::{self, roles};
use regolith_reader::captures::ImageKind;
use regolith_reader::{verify, Database, ReaderError, Writer};
use regolith_tests::sample;

fn build(dir: &Path, version: &str) -> regolith_format::ObjectId {
    let w = Writer::create_or_open(dir).unwrap();
    sample::build(&w, version).unwrap()
}

#[test]
fn round_trip_every_kind() {
    let dir = tempfile::tempdir().unwrap();
    let id = build(dir.path(), "1.0.0");
    let db = Database::open(dir.path()).unwrap();
    let r = db.release("sample@1.0.0").unwrap();
    assert_eq!(r.id, id);
    assert_eq!(db.resolve("latest").unwrap(), id);
    assert_eq!(db.resolve(&id.to_hex()[..8]).unwrap(), id);
    let kinds_seen: std::collections::BTreeSet<&str> =
        r.entries().iter().map(|e| e.kind.as_str()).collect();
    for k in [
        kinds::HEIGHTFIELD,
        kinds::TEXTURE,
        kinds::MESH,
        kinds::CAMERA,
        kinds::RIG,
        kinds::CAPTURES,
        kinds::REPORT,
    ] {
        assert!(kinds_seen.contains(k), "missing kind {k}");
    }

    // Heightfield: heights equal the input within the stated quantisation error, the hole is
    // flagged in the mask, and the EXR keeps exact floats with NaN.
    let hf = r.heightfield("laser/0.05").unwrap();
    let z = sample::heights();
    for (i, (&want, &got)) in z.iter().zip(&hf.heights).enumerate() {
        if want.is_nan() {
            assert_eq!(hf.valid[i], 0);
        } else {
            assert_eq!(hf.valid[i], 255);
            assert!(
                (f64::from(want) - f64::from(got)).abs()
                    <= hf.meta.quantisation_error_m * 1.0001 + 1e-7
            );
        }
    }
    let (w, h, exr) = regolith_compiler::encode::exr::read_grey_f32(
        &r.read_file("laser/0.05", roles::HEIGHT_F32).unwrap(),
    )
    .unwrap();
    assert_eq!((w as u32, h as u32), (sample::W, sample::H));
    for (a, b) in z.iter().zip(&exr) {
        assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
    }

    // Mesh (built from the hole-filled surface): LODs parse, lod0 has 2 triangles per quad.
    let lods = r.mesh("laser/0.05/mesh").unwrap();
    assert_eq!(lods.len(), 2);
    let quads = u64::from((sample::W - 1) * (sample::H - 1));
    assert_eq!(lods[0].summary.triangles, 2 * quads);
    assert_eq!(lods[0].summary.vertices, u64::from(sample::W * sample::H));
    assert!(lods[0].summary.normals && lods[0].summary.uvs && lods[0].summary.images == 1);
    assert!(lods[1].summary.triangles < lods[0].summary.triangles);

    // Cameras and rig read back equal.
    assert_eq!(
        r.camera("cameras/navcam_left").unwrap(),
        sample::camera_left()
    );
    let rig = r.rig("rig").unwrap();
    assert_eq!(rig.left, "cameras/navcam_left");

    // Captures: 2 cameras x 2 frames x (raw, rect), poses from the index.
    let caps = r.captures("captures").unwrap();
    let imgs = caps.images().unwrap();
    assert_eq!(imgs.len(), 8);
    assert_eq!(imgs.iter().filter(|i| i.kind == ImageKind::Raw).count(), 4);
    let left0 = imgs
        .iter()
        .find(|i| i.camera == "navcam_left" && i.frame == 1 && i.kind == ImageKind::Raw)
        .unwrap();
    assert_eq!(&left0.data[1..4], b"PNG");
    assert_eq!(left0.ground_from_camera.translation_m, [0.4, -0.5, 0.9]);
    assert_eq!(&caps.mcap_bytes()[..8], b"\x89MCAP0\r\n");

    assert_eq!(
        r.report("reports/dem").unwrap()["valid_cells"],
        sample::W * sample::H - 1
    );
    assert!(matches!(
        r.camera("rig"),
        Err(ReaderError::WrongKind { .. })
    ));
    assert!(matches!(
        r.entry("nope"),
        Err(ReaderError::NoSuchEntry { .. })
    ));
    assert!(verify(&db).unwrap().ok());
}

#[test]
fn every_single_bit_flip_in_any_object_is_detected() {
    let dir = tempfile::tempdir().unwrap();
    build(dir.path(), "1.0.0");
    let db = Database::open(dir.path()).unwrap();
    let r = db.release("latest").unwrap();
    let mut objects: Vec<(String, String, regolith_format::FileRef)> = r
        .manifest
        .file_refs()
        .into_iter()
        .map(|(e, role, f)| (e.to_string(), role, f.clone()))
        .collect();
    objects.sort_by_key(|o| o.2.object);
    objects.dedup_by_key(|o| o.2.object);
    assert!(objects.len() >= 10);
    for (entry, role, f) in &objects {
        let path = dir.path().join(f.object.object_path());
        let original = fs::read(&path).unwrap();
        // Flip a bit at several positions, including the first and last byte.
        for pos in [0, original.len() / 2, original.len() - 1] {
            let mut bad = original.clone();
            bad[pos] ^= 0x10;
            fs::write(&path, &bad).unwrap();
            let report = verify(&db).unwrap();
            assert_eq!(report.problems.len(), 1, "{entry} {role} at {pos}");
            assert_eq!(&report.problems[0].entry, entry);
            assert!(report.problems[0].message.contains("corrupt"));
        }
        fs::write(&path, &original[..original.len() - 1]).unwrap();
        let p = &verify(&db).unwrap().problems;
        assert!(p.len() == 1 && p[0].message.contains("expected"), "{p:?}");
        fs::remove_file(&path).unwrap();
        assert_eq!(verify(&db).unwrap().problems[0].message, "missing");
        let err = r
            .read_file(entry, role.rsplit('/').next().unwrap())
            .unwrap_err();
        assert!(err.to_string().contains(&f.object.to_hex()), "{err}");
        fs::write(&path, &original).unwrap();
    }
    assert!(verify(&db).unwrap().ok());
}

#[test]
fn an_edited_manifest_is_detected() {
    let dir = tempfile::tempdir().unwrap();
    let id = build(dir.path(), "1.0.0");
    let path = dir.path().join(id.object_path());
    let text = fs::read_to_string(&path).unwrap();
    fs::write(&path, text.replace("\"laser\"", "\"laxer\"")).unwrap();
    let db = Database::open(dir.path()).unwrap();
    let err = db.release("latest").unwrap_err();
    assert!(matches!(err, ReaderError::CorruptObject { .. }), "{err}");
    assert!(!verify(&db).unwrap().ok());
}

#[test]
fn releases_are_immutable_and_refs_move_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let a = build(dir.path(), "1.0.0");
    let again = build(dir.path(), "1.0.0");
    assert_eq!(a, again, "recompiling identical content is idempotent");
    let b = build(dir.path(), "1.1.0");
    assert_ne!(a, b);
    let db = Database::open(dir.path()).unwrap();
    assert_eq!(db.resolve("latest").unwrap(), b);
    assert_eq!(db.releases().unwrap().len(), 2);
    // Pointing an existing release name at other content is refused.
    let w = Writer::create_or_open(dir.path()).unwrap();
    let mut m = db.release_by_id(&a).unwrap().manifest;
    m.entries.retain(|e| e.kind != kinds::REPORT);
    assert!(matches!(
        w.commit(m, false),
        Err(ReaderError::ReleaseExists { .. })
    ));
    // The ref log records every move, with time outside the hashed objects.
    let log = fs::read_to_string(dir.path().join("logs/refs.jsonl")).unwrap();
    assert!(
        log.lines()
            .filter(|l| l.contains("\"ref\":\"latest\""))
            .count()
            >= 2
    );
    assert!(!fs::read_dir(dir.path().join("refs")).unwrap().any(|e| e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .starts_with('.')));
}

#[test]
fn same_content_same_id_across_runs_and_threads() {
    let ids: Vec<_> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..3)
            .map(|_| {
                s.spawn(|| {
                    let dir = tempfile::tempdir().unwrap();
                    build(dir.path(), "1.0.0")
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert!(ids.windows(2).all(|w| w[0] == w[1]));
}

#[test]
fn gc_removes_only_unreachable_objects() {
    let dir = tempfile::tempdir().unwrap();
    build(dir.path(), "1.0.0");
    let w = Writer::create_or_open(dir.path()).unwrap();
    let stray = w
        .put(b"nobody references me", "application/octet-stream")
        .unwrap();
    let report = w.gc().unwrap();
    assert_eq!(report.removed, 1);
    assert!(!dir.path().join(stray.object.object_path()).exists());
    drop(w);
    assert!(verify(&Database::open(dir.path()).unwrap()).unwrap().ok());
}

#[test]
fn roll_back_takes_back_only_the_new_unreferenced_objects() {
    let dir = tempfile::tempdir().unwrap();
    build(dir.path(), "1.0.0");
    let listing = |p: &Path| {
        let mut v: Vec<_> = walk(p);
        v.sort();
        v
    };
    fn walk(p: &Path) -> Vec<std::path::PathBuf> {
        let mut out = Vec::new();
        for e in fs::read_dir(p).unwrap() {
            let path = e.unwrap().path();
            if path.is_dir() {
                out.extend(walk(&path));
            }
            out.push(path);
        }
        out
    }
    let before = listing(dir.path());
    let w = Writer::create_or_open(dir.path()).unwrap();
    let stray = w.put(b"a failed compile stored me", "text/plain").unwrap();
    assert!(dir.path().join(stray.object.object_path()).is_file());
    // The same bytes again, and an object that was there already: nothing new to take back.
    w.put(b"a failed compile stored me", "text/plain").unwrap();
    assert_eq!(w.roll_back().unwrap(), 1);
    assert_eq!(listing(dir.path()), before, "the store is as it was");
    // A committed release keeps its objects.
    let id = sample::build(&w, "1.1.0").unwrap();
    w.roll_back().unwrap();
    drop(w);
    let db = Database::open(dir.path()).unwrap();
    assert_eq!(db.resolve("sample@1.1.0").unwrap(), id);
    assert!(verify(&db).unwrap().ok());
}
