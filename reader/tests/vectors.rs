//! The reader against the normative test vectors and the frozen v1 database: release id, entry
//! hashes and object ids as `expected.json` states, and every kind decodes to the stated facts.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};

use regolith_reader::{verify, Database};
use serde_json::Value;

fn spec_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../format-spec")
}

fn check(case: &Path) {
    let expected: Value =
        serde_json::from_slice(&std::fs::read(case.join("expected.json")).unwrap()).unwrap();
    let db = Database::open(case.join("db")).unwrap();
    let release = db.release(expected["release"].as_str().unwrap()).unwrap();
    assert_eq!(
        release.id.to_hex(),
        expected["release_id"].as_str().unwrap()
    );
    assert_eq!(db.resolve("latest").unwrap(), release.id);
    let entries = expected["entries"].as_object().unwrap();
    assert_eq!(entries.len(), release.entries().len());
    for e in release.entries() {
        let want = &entries[&e.name];
        assert_eq!(e.kind, want["kind"].as_str().unwrap());
        assert_eq!(
            e.hash().unwrap().to_hex(),
            want["entry_hash"].as_str().unwrap(),
            "{}",
            e.name
        );
    }
    let facts = &expected["facts"];
    let hf = release
        .heightfield(facts["heightfield"]["entry"].as_str().unwrap())
        .unwrap();
    assert_eq!(
        u64::from(hf.meta.width),
        facts["heightfield"]["width"].as_u64().unwrap()
    );
    assert_eq!(
        hf.meta.valid_cells,
        facts["heightfield"]["valid_cells"].as_u64().unwrap()
    );
    let hole = &facts["heightfield"]["hole_col_row"];
    let (c, r) = (
        hole[0].as_u64().unwrap() as usize,
        hole[1].as_u64().unwrap() as usize,
    );
    assert_eq!(hf.valid[r * hf.meta.width as usize + c], 0);
    let caps = release
        .captures(facts["captures"]["entry"].as_str().unwrap())
        .unwrap();
    assert_eq!(
        caps.images().unwrap().len() as u64,
        facts["captures"]["images"].as_u64().unwrap()
    );
    for e in release.entries().iter().filter(|e| e.kind == "mesh") {
        assert!(!release.mesh(&e.name).unwrap().is_empty());
    }
    // Refs that name objects, not releases (certificates; since 1.10 validation units).
    if let Some(n) = facts["object_refs"].as_u64() {
        let refs = db.refs().unwrap();
        let objects = refs
            .keys()
            .filter(|k| regolith_reader::database::is_object_ref(k))
            .count();
        assert_eq!(objects as u64, n, "{refs:?}");
    }
    let report = verify(&db).unwrap();
    assert!(report.ok(), "{:?}", report.problems);
    assert!(report.objects_checked >= 10);
}

#[test]
fn reads_the_test_vectors() {
    check(&spec_dir().join("test-vectors/basic"));
}

#[test]
fn reads_every_frozen_format_version() {
    let compat = spec_dir().join("compat");
    let mut n = 0;
    for v in std::fs::read_dir(&compat).unwrap() {
        check(&v.unwrap().path());
        n += 1;
    }
    assert!(
        n >= 1,
        "no frozen database found under {}",
        compat.display()
    );
}
