//! Sharded validation end to end: shards run as concurrent processes on one database, a merge
//! with a shard missing names the missing units and writes nothing, a re-run shard skips what it
//! stored, and the merged certificates are byte-identical (the same object ids) to those of one
//! `validate` process on a copy of the same database; the database verifies and `gc` keeps the
//! unit results.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::{assert_matches_doc_schema, certificate_ids, copy_dir, generate_mini, regolith};
use serde_json::Value;

const ENTRIES: [&str; 4] = ["--entry", "laser/0.01", "--entry", "laser/0.02"];

fn ok(out: &Output) -> Value {
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_matches_doc_schema("validate", &v);
    v
}

fn validate(db: &str, extra: &[&str]) -> Output {
    let mut args = vec!["--json", "validate", db];
    args.extend(ENTRIES);
    args.extend(extra);
    regolith(&args)
}

fn certificate_refs(db: &Path) -> Vec<String> {
    let dir = db.join("refs/certificates");
    if !dir.exists() {
        return Vec::new();
    }
    let mut out = Vec::new();
    for release in std::fs::read_dir(dir).unwrap() {
        for c in std::fs::read_dir(release.unwrap().path()).unwrap() {
            out.push(c.unwrap().file_name().to_string_lossy().into_owned());
        }
    }
    out
}

#[test]
fn merged_shards_give_the_certificates_of_one_process() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    let one = dir.path().join("one");
    let sharded = dir.path().join("sharded");
    generate_mini(&camp, 7);
    let out = regolith(&[
        "compile",
        camp.to_str().unwrap(),
        "--db",
        one.to_str().unwrap(),
        "--release",
        "shard@1.0.0",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    copy_dir(&one, &sharded);
    let (one_s, sh) = (one.to_str().unwrap(), sharded.to_str().unwrap());

    let whole = ok(&validate(one_s, &[]));

    // Two shards at once, as separate processes on one database.
    let spawn = |shard: &str| {
        let mut args = vec!["--json", "validate", sh];
        args.extend(ENTRIES);
        args.extend(["--shard", shard]);
        Command::new(env!("CARGO_BIN_EXE_regolith"))
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (spawn("1/3"), spawn("2/3"));
    let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    let (a, b) = (ok(&a), ok(&b));
    let units_ab = a["units"].as_u64().unwrap() + b["units"].as_u64().unwrap();
    assert_eq!(a["computed"], a["units"]);
    assert_eq!(b["reused"], 0);

    // Shard 3 has not run: the merge names what is missing and writes nothing.
    let out = validate(sh, &["--merge"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("have no stored result") && err.contains("--shard I/N"),
        "{err}"
    );
    assert!(certificate_refs(&sharded).is_empty());

    let c = ok(&validate(sh, &["--shard", "3/3"]));
    let total = units_ab + c["units"].as_u64().unwrap();
    // 2 entries × every view of the mini campaign, each in exactly one shard.
    assert_eq!(total as usize % 2, 0);
    assert!(c["computed"].as_u64().unwrap() > 0);
    // Run again (as after a killed worker): everything is found, nothing recomputed.
    let again = ok(&validate(sh, &["--shard", "3/3"]));
    assert_eq!(again["computed"], 0);
    assert_eq!(again["reused"], c["units"]);

    let merged = ok(&validate(sh, &["--merge"]));
    assert_eq!(
        certificate_ids(&merged),
        certificate_ids(&whole),
        "merged certificates differ from one process's"
    );
    assert_eq!(merged["passed"], whole["passed"]);

    // The unit results are reachable objects: verify is clean and gc keeps them.
    let out = regolith(&["verify", sh]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let out = regolith(&["gc", sh]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let remerged = ok(&validate(sh, &["--merge"]));
    assert_eq!(certificate_ids(&remerged), certificate_ids(&whole));
}

#[test]
fn shard_arguments_are_checked() {
    for (args, says) in [
        (vec!["validate", "db", "--shard", "0/2"], "expected I/N"),
        (vec!["validate", "db", "--shard", "3/2"], "expected I/N"),
        (
            vec!["validate", "db", "--shard", "1/2", "--merge"],
            "cannot be used with",
        ),
        (
            vec!["validate", "db", "--merge", "--report", "r"],
            "cannot be used with",
        ),
    ] {
        let out = regolith(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
