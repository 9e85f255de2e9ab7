//! The `regolith` binary as a user runs it: exit codes, JSON output, export files.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;

use common::regolith;
use regolith_reader::Writer;
use serde_json::Value;

fn sample_db(dir: &Path) -> String {
    let db = dir.join("db");
    regolith_tests::sample::build(&Writer::create_or_open(&db).unwrap(), "1.0.0").unwrap();
    db.to_string_lossy().into_owned()
}

#[test]
fn verify_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let db = sample_db(dir.path());
    let ok = regolith(&["verify", &db, "--json"]);
    assert_eq!(ok.status.code(), Some(0));
    let v: Value = serde_json::from_slice(&ok.stdout).unwrap();
    assert_eq!(v["ok"], true);
    // Corrupt one object: exit 1 naming it.
    let release = regolith_reader::Database::open(&db)
        .unwrap()
        .release("latest")
        .unwrap();
    let f = release
        .manifest
        .entry("laser/0.05")
        .unwrap()
        .file("height")
        .unwrap()
        .clone();
    let path = Path::new(&db).join(f.object.object_path());
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[20] ^= 1;
    std::fs::write(&path, bytes).unwrap();
    let bad = regolith(&["verify", &db]);
    assert_eq!(bad.status.code(), Some(1));
    let text = String::from_utf8_lossy(&bad.stdout);
    assert!(
        text.contains(&f.object.to_hex()) && text.contains("laser/0.05"),
        "{text}"
    );
    // Not a database: exit 2 with a message, no panic.
    let none = regolith(&["verify", dir.path().to_str().unwrap()]);
    assert_eq!(none.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&none.stderr).contains("not a regolith database"));
    assert_eq!(regolith(&["verify"]).status.code(), Some(2), "usage error");
}

#[test]
fn inspect_lists_releases_and_entries() {
    let dir = tempfile::tempdir().unwrap();
    let db = sample_db(dir.path());
    let out = regolith(&["inspect", &db, "--json"]);
    assert!(out.status.success());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["releases"][0]["release"], "sample@1.0.0");
    let out = regolith(&["inspect", &db, "latest"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("laser/0.05") && text.contains("heightfield") && text.contains("captures"),
        "{text}"
    );
    let out = regolith(&["inspect", &db, "sample@1.0.0", "reports/dem", "--json"]);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["body"]["report"], "dem");
    assert_eq!(regolith(&["inspect", &db, "nope@1"]).status.code(), Some(2));
}

#[test]
fn export_writes_fixed_names_and_engine_variants() {
    let dir = tempfile::tempdir().unwrap();
    let db = sample_db(dir.path());
    let to = dir.path().join("out");
    let out = regolith(&[
        "export",
        &db,
        "latest",
        "laser/0.05",
        "--to",
        to.to_str().unwrap(),
        "--profile",
        "gazebo",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "height.png",
        "height.exr",
        "mask.png",
        "height.json",
        "height_gazebo.png",
        "height_gazebo.json",
    ] {
        assert!(to.join(f).is_file(), "{f}");
    }
    let side: Value =
        serde_json::from_slice(&std::fs::read(to.join("height.json")).unwrap()).unwrap();
    assert_eq!(side["width"], regolith_tests::sample::W);
    assert_eq!(side["row_order"], "north-up");
    let gz: Value =
        serde_json::from_slice(&std::fs::read(to.join("height_gazebo.json")).unwrap()).unwrap();
    let n = gz["size_px"].as_u64().unwrap();
    assert_eq!(n, 17, "smallest 2^n+1 >= the larger side (17)");
    let img = regolith_reader::heightfield::decode_grey_png(
        &std::fs::read(to.join("height_gazebo.png")).unwrap(),
        4097,
    )
    .unwrap();
    assert_eq!((img.width, img.height, img.bit_depth), (17, 17, 16));
    // A second export into the now non-empty folder is refused and changes nothing.
    let again = regolith(&[
        "export",
        &db,
        "latest",
        "laser/0.05",
        "--to",
        to.to_str().unwrap(),
    ]);
    assert_eq!(again.status.code(), Some(2));
    // Other kinds export their roles.
    let cam = dir.path().join("cam");
    assert!(regolith(&[
        "export",
        &db,
        "latest",
        "cameras/navcam_left",
        "--to",
        cam.to_str().unwrap()
    ])
    .status
    .success());
    assert!(cam.join("calibration.json").is_file() && cam.join("entry.json").is_file());
}

#[test]
fn gc_keeps_everything_reachable() {
    let dir = tempfile::tempdir().unwrap();
    let db = sample_db(dir.path());
    let out = regolith(&["gc", &db, "--json"]);
    assert!(out.status.success());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["removed"], 0);
    assert_eq!(regolith(&["verify", &db]).status.code(), Some(0));
}

#[test]
fn features_repeat_follows_the_homography() {
    use regolith_compiler::ingest::images::{self, GreyImage};
    let dir = tempfile::tempdir().unwrap();
    let root = regolith_tests::workspace_root();
    let src = root.join("corpus/demo/captures/loc01_left_a.png");
    let a = images::read_path(&src, &Default::default()).unwrap();
    // B = A shifted by (+3, -2) pixels.
    let mut b = GreyImage::new(a.width, a.height, 8, &Default::default()).unwrap();
    for y in 0..a.height {
        for x in 0..a.width {
            let (sx, sy) = (x as i64 - 3, y as i64 + 2);
            if sx >= 0 && sy >= 0 && (sx as u32) < a.width && (sy as u32) < a.height {
                b.data[(y * a.width + x) as usize] = a.get(sx as u32, sy as u32).unwrap();
            }
        }
    }
    let pb = dir.path().join("b.png");
    std::fs::write(&pb, b.to_u8().unwrap()).unwrap();
    let h = dir.path().join("h.txt");
    std::fs::write(&h, "1 0 3\n0 1 -2\n0 0 1\n").unwrap();
    let score = |extra: &[&str]| -> f64 {
        let mut args = vec![
            "features",
            "repeat",
            src.to_str().unwrap(),
            pb.to_str().unwrap(),
            "--detector",
            "harris",
            "--json",
        ];
        args.extend_from_slice(extra);
        let out = regolith(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        v["repeatability"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["epsilon_px"] == 1.5)
            .unwrap()["score"]
            .as_f64()
            .unwrap()
    };
    let with_h = score(&["--homography", h.to_str().unwrap()]);
    let identity = score(&["--same-pose"]);
    assert!(with_h > 0.8, "homography-mapped repeatability {with_h}");
    assert!(identity < 0.3, "unmapped repeatability {identity}");
    let detect = regolith(&[
        "features",
        "detect",
        src.to_str().unwrap(),
        "--detector",
        "fast",
        "--json",
    ]);
    let v: Value = serde_json::from_slice(&detect.stdout).unwrap();
    assert!(v["keypoints"].as_array().unwrap().len() > 50);
    assert_eq!(
        regolith(&[
            "features",
            "detect",
            src.to_str().unwrap(),
            "--detector",
            "nope"
        ])
        .status
        .code(),
        Some(2)
    );
}

/// A writer on `db` right after this process dropped the one it held. The lock is released
/// when its file closes, but a sibling test that forks a `regolith` child at that moment holds a
/// copy of the descriptor until the child execs (close-on-exec); on a loaded machine that can
/// outlast the drop (seen once in a CI rehearsal), so a refusal is retried for up to 2 s.
fn writer_after_release(db: &str) -> Writer {
    for _ in 0..100 {
        match Writer::create_or_open(db) {
            Err(regolith_reader::ReaderError::Locked { .. }) => {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            other => return other.unwrap(),
        }
    }
    Writer::create_or_open(db).unwrap()
}

#[test]
fn publishing_requires_passing_certificates() {
    let dir = tempfile::tempdir().unwrap();
    let db = sample_db(dir.path());
    // No certificate: refused with exit 1, naming the entry.
    let out = regolith(&["release", &db, "sample@1.0.0", "--publish"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("laser/0.05: no certificate"));
    let database = regolith_reader::Database::open(&db).unwrap();
    let view = database.release("sample@1.0.0").unwrap();
    // Every terrain entry needs one: the raster and the mesh built from it.
    let terrain = regolith_validator::validate::certified_entries(&view);
    assert_eq!(terrain, ["laser/0.05", "laser/0.05/mesh"]);
    let certify = |entry: &str, passed: bool, failures: &[&str]| {
        let hash = view.entry(entry).unwrap().hash().unwrap().to_hex();
        let body = serde_json::json!({"entry_hash": hash, "passed": passed, "failures": failures});
        let w = writer_after_release(&db);
        w.put_certificate(&view.id, entry, &body).unwrap();
    };
    // While another writer holds the database, a second one is refused, not blocked.
    {
        let _held = Writer::create_or_open(&db).unwrap();
        let out = regolith(&["gc", &db]);
        assert_eq!(out.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&out.stderr).contains("another process"));
    }
    // A failing certificate: refused, with its failure in the message; the raster passing
    // does not cover its mesh.
    certify(
        "laser/0.05",
        false,
        &["sift: ratio 0.10 < 0.35, short by 0.25"],
    );
    let out = regolith(&["release", &db, "sample@1.0.0", "--publish"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("short by 0.25"));
    certify("laser/0.05", true, &[]);
    let out = regolith(&["release", &db, "sample@1.0.0", "--publish"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("laser/0.05/mesh: no certificate"));
    // --allow-uncertified: a child release records the exception in its manifest.
    let out = regolith(&[
        "release",
        &db,
        "sample@1.0.0",
        "--publish",
        "--allow-uncertified",
        "--json",
    ]);
    assert_eq!(out.status.code(), Some(0));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let child = database.release(v["id"].as_str().unwrap()).unwrap();
    assert_eq!(child.manifest.allow_uncertified, Some(true));
    assert_eq!(child.manifest.parent, Some(view.id));
    // Passing certificates for both: published as is.
    certify("laser/0.05/mesh", true, &[]);
    assert_eq!(
        regolith(&["release", &db, "sample@1.0.0", "--publish"])
            .status
            .code(),
        Some(0)
    );
    assert_eq!(
        database.read_ref("published/sample@1.0.0").unwrap(),
        Some(view.id)
    );
    assert_eq!(regolith(&["verify", &db]).status.code(), Some(0));
}

/// `regolith … | head`: output into a pipe nobody reads any more ends the command quietly with
/// status 0 (it used to panic on the broken pipe and report an internal error, status 3).
#[test]
fn a_closed_stdout_pipe_ends_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let db = sample_db(dir.path());
    for args in [
        vec!["inspect", db.as_str(), "latest", "--json"],
        vec!["inspect", db.as_str(), "latest"],
    ] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_regolith"))
            .args(&args)
            .stdout(writer)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
        assert!(!stderr.contains("internal error"), "{args:?}: {stderr}");
    }
}

/// A validation computes without the database's lock and takes it to write its certificate,
/// waiting for another writer instead of refusing: two validations (or a validation and a
/// compile) of one database run side by side.
#[test]
fn validate_holds_the_lock_only_to_write_its_certificate() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("db");
    let db = db.to_str().unwrap();
    let demo = regolith_tests::workspace_root().join("corpus/demo");
    let compiled = regolith(&["compile", demo.to_str().unwrap(), "--db", db, "-q"]);
    assert!(compiled.status.success(), "{compiled:?}");
    let entry = "laser/0.02";
    let held = writer_after_release(db);
    let mut child = Command::new(env!("CARGO_BIN_EXE_regolith"))
        .args([
            "validate",
            db,
            "--entry",
            entry,
            "--detector",
            "fast",
            "--json",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The child validates while this process holds the lock, then says it waits.
    let stderr = child.stderr.take().unwrap();
    let mut lines = BufReader::new(stderr).lines();
    let mut seen = Vec::new();
    let waited = loop {
        match lines.next() {
            Some(Ok(line)) => {
                let waiting = line.contains("waiting for another process writing to");
                seen.push(line);
                if waiting {
                    break true;
                }
            }
            _ => break false,
        }
    };
    assert!(waited, "validate did not wait for the lock: {seen:#?}");
    drop(held);
    let out = child.wait_with_output().unwrap();
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "exit {:?}; stderr before: {seen:#?}",
        out.status.code()
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let cert = v["entries"][0]["certificate"].as_str().unwrap();
    let database = regolith_reader::Database::open(db).unwrap();
    let id = database.release("latest").unwrap().id;
    let refs = database.refs().unwrap();
    let r = refs
        .iter()
        .find(|(name, _)| name.starts_with(&format!("certificates/{}", id.to_hex())))
        .unwrap();
    assert_eq!(r.1.to_hex(), cert);
}
