//! The normative test vectors (`format-spec/test-vectors/`): regenerated from the sample
//! builder and compared byte for byte with the committed copy. `REGOLITH_BLESS=1` rewrites them
//! after an intended format change (which must also update SPEC.md and CHANGES.md).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

use regolith_reader::{Database, Writer};
use regolith_tests::{sample, workspace_root};
use serde_json::json;

/// Files of a database that are part of the format (not the lock, temp files or the ref log).
fn db_files(root: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            if rel == "lock" || rel.starts_with("tmp") || rel.starts_with("logs") {
                continue;
            }
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(rel, fs::read(&p).unwrap());
            }
        }
    }
    out
}

fn expected_json(db: &Path) -> serde_json::Value {
    let d = Database::open(db).unwrap();
    let r = d.release("latest").unwrap();
    let mut entries = serde_json::Map::new();
    for e in r.entries() {
        let files: BTreeMap<String, String> = r
            .manifest
            .file_refs()
            .into_iter()
            .filter(|(n, _, _)| *n == e.name)
            .map(|(_, role, f)| (role, f.object.to_hex()))
            .collect();
        entries.insert(
            e.name.clone(),
            json!({"kind": e.kind, "entry_hash": e.hash().unwrap().to_hex(), "files": files}),
        );
    }
    let hf = r.heightfield("laser/0.05").unwrap();
    json!({
        "schema": regolith_format::SCHEMA,
        "release": r.label(),
        "release_id": r.id.to_hex(),
        "entries": entries,
        "facts": {
            "heightfield": {"entry": "laser/0.05", "width": hf.meta.width, "height": hf.meta.height,
                "valid_cells": hf.meta.valid_cells, "hole_col_row": [sample::HOLE.0, sample::HOLE.1]},
            "captures": {"entry": "captures", "images": 8},
        },
    })
}

fn vectors_dir() -> PathBuf {
    workspace_root().join("format-spec/test-vectors/basic")
}

#[test]
fn test_vectors_are_up_to_date() {
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("db");
    sample::build(&Writer::create_or_open(&db).unwrap(), "1.0.0").unwrap();
    let fresh = db_files(&db);
    let expected = serde_json::to_string_pretty(&expected_json(&db)).unwrap() + "\n";
    let dir = vectors_dir();
    if std::env::var("REGOLITH_BLESS").is_ok_and(|v| v == "1") {
        let _ = fs::remove_dir_all(&dir);
        for (rel, bytes) in &fresh {
            let p = dir.join("db").join(rel);
            fs::create_dir_all(p.parent().unwrap()).unwrap();
            fs::write(p, bytes).unwrap();
        }
        fs::write(dir.join("expected.json"), &expected).unwrap();
        return;
    }
    let committed = db_files(&dir.join("db"));
    let actual_dir = workspace_root().join("target/golden-actual/test-vectors");
    let outdated: Vec<&String> = fresh
        .keys()
        .filter(|k| committed.get(*k) != fresh.get(*k))
        .collect();
    let unexpected: Vec<&String> = committed
        .keys()
        .filter(|k| !fresh.contains_key(*k))
        .collect();
    let expected_committed = fs::read_to_string(dir.join("expected.json")).unwrap_or_default();
    if !outdated.is_empty() || !unexpected.is_empty() || expected_committed != expected {
        let _ = fs::remove_dir_all(&actual_dir);
        fs::create_dir_all(&actual_dir).unwrap();
        fs::write(actual_dir.join("expected.json"), &expected).unwrap();
        panic!(
            "test vectors differ: outdated {outdated:?}, unexpected {unexpected:?}, expected.json {} \
             (actual expected.json in {}; rerun with REGOLITH_BLESS=1 only for an intended format change)",
            if expected_committed == expected { "ok" } else { "outdated" },
            actual_dir.display()
        );
    }
}
