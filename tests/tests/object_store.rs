//! Databases on an object store, against a real S3-compatible server (`moto_server`): the same
//! release id as in a folder, verified and ranged reads, gc's grace period, a writer killed at
//! every failpoint, two writers racing for `latest`, and refused credentials. The CLI on
//! `s3://` is covered in `cli/tests/object_store.rs`.
//!
//! moto must be installed (`pip install 'moto[server]'`, which `.ci/run` does): without it
//! these tests fail saying so rather than skip.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Command, Output};
use std::time::Duration;

use regolith_format::kinds::roles;
use regolith_format::ObjectId;
use regolith_reader::{verify, Database, Writer};
use regolith_tests::moto::MotoServer;
use regolith_tests::sample;

fn server() -> MotoServer {
    MotoServer::start().unwrap_or_else(|e| panic!("{e}"))
}

/// Runs the test writer (`regolith-testwriter DB VERSION`) against `server`.
fn testwriter(server: &MotoServer, db: &str, version: &str, failpoint: Option<&str>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_regolith-testwriter"));
    cmd.args([db, version]).envs(server.env());
    if let Some(step) = failpoint {
        cmd.env("REGOLITH_FAILPOINT", step);
    }
    cmd.output().unwrap()
}

fn id_of(out: &Output) -> ObjectId {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
}

/// One test, because the in-process reader takes its endpoint and keys from the process
/// environment, which parallel tests would share.
#[test]
fn a_database_on_s3_behaves_like_a_folder() {
    let s3 = server();
    s3.create_bucket("terrain").unwrap();
    for (k, v) in s3.env() {
        // Edition 2021: not unsafe; no other test of this binary reads these variables.
        std::env::set_var(k, v);
    }
    let url = "s3://terrain/db";

    // Same bytes as a folder: the release id is the same.
    let dir = tempfile::tempdir().unwrap();
    let local_id = sample::build(&Writer::create_or_open(dir.path()).unwrap(), "1.0.0").unwrap();
    let w = Writer::create_or_open(url).unwrap();
    let id = sample::build(&w, "1.0.0").unwrap();
    assert_eq!(id, local_id);
    drop(w);
    let keys = s3.all_keys().unwrap();
    assert!(keys.contains(&"terrain/db/regolith.db".to_string()));
    assert!(keys.contains(&format!("terrain/db/{}", id.object_path())));
    assert!(keys.contains(&"terrain/db/refs/releases/sample@1.0.0".to_string()));
    assert!(keys.contains(&"terrain/db/refs/latest".to_string()));
    assert!(
        keys.iter()
            .filter(|k| k.starts_with("terrain/db/logs/refs/") && k.ends_with(".json"))
            .count()
            >= 2,
        "one log object per ref change: {keys:?}"
    );

    // Reads: verified whole objects, and ranged reads equal to the slices of them.
    let db = Database::open(url).unwrap();
    let local = Database::open(dir.path()).unwrap();
    let r = db.release("latest").unwrap();
    assert_eq!(r.id, id);
    let hf = r.heightfield("laser/0.05").unwrap();
    assert_eq!(
        hf.heights.iter().map(|h| h.to_bits()).collect::<Vec<_>>(),
        local
            .release("latest")
            .unwrap()
            .heightfield("laser/0.05")
            .unwrap()
            .heights
            .iter()
            .map(|h| h.to_bits())
            .collect::<Vec<_>>()
    );
    let whole = r.read_file("laser/0.05", roles::HEIGHT_F32).unwrap();
    let n = whole.len() as u64;
    assert_eq!(
        r.read_file_range("laser/0.05", roles::HEIGHT_F32, 7..n / 2)
            .unwrap(),
        &whole[7..(n / 2) as usize]
    );
    assert!(r
        .read_file_range("laser/0.05", roles::HEIGHT_F32, 0..n + 1)
        .is_err());
    let captures = r.captures("captures").unwrap();
    assert!(!captures.images().unwrap().is_empty());
    let report = verify(&db).unwrap();
    assert!(report.ok(), "{:?}", report.problems);

    // gc: a fresh unreachable object survives the default grace period, not a zero one.
    let w = Writer::create_or_open(url).unwrap();
    let stray = w
        .put(b"an object no release references", "text/plain")
        .unwrap();
    let stray_key = format!("terrain/db/{}", stray.object.object_path());
    let kept = w.gc().unwrap();
    assert_eq!((kept.removed, kept.kept_young), (0, 1));
    assert!(s3.all_keys().unwrap().contains(&stray_key));
    let swept = w.gc_with_grace(Duration::ZERO).unwrap();
    assert_eq!(swept.removed, 1);
    assert!(!s3.all_keys().unwrap().contains(&stray_key));
    assert!(verify(&db).unwrap().ok());
    assert_eq!(db.resolve("latest").unwrap(), id);

    // A writer killed at every step of a commit leaves the previous release intact.
    for step in [
        "object-renamed",
        "objects-stored",
        "manifest-stored",
        "ref-temp-written",
    ] {
        let crash_url = format!("s3://terrain/crash-{step}");
        let first = id_of(&testwriter(&s3, &crash_url, "1.0.0", None));
        let killed = testwriter(&s3, &crash_url, "2.0.0", Some(step));
        assert!(!killed.status.success(), "failpoint {step} did not fire");
        let db = Database::open(crash_url.as_str()).unwrap();
        assert_eq!(db.resolve("latest").unwrap(), first, "{step}");
        assert!(db
            .release("sample@1.0.0")
            .unwrap()
            .heightfield("laser/0.05")
            .is_ok());
        assert!(verify(&db).unwrap().ok(), "{step}");
        let retry = id_of(&testwriter(&s3, &crash_url, "2.0.0", None));
        assert_eq!(db.resolve("latest").unwrap(), retry, "{step}");
        assert!(verify(&db).unwrap().ok(), "{step}");
    }

    // Two writers racing, on a new prefix and then on an existing database: both releases
    // exist, `latest` names one of them, nothing is corrupt.
    let race_url = "s3://terrain/race";
    for round in 0..3 {
        let (va, vb) = (format!("{round}.1.0"), format!("{round}.2.0"));
        let spawn = |v: &str| {
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_regolith-testwriter"));
            cmd.args([race_url, v])
                .envs(s3.env())
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped());
            cmd.spawn().unwrap()
        };
        let (a, b) = (spawn(&va), spawn(&vb));
        let (a, b) = (
            id_of(&a.wait_with_output().unwrap()),
            id_of(&b.wait_with_output().unwrap()),
        );
        let db = Database::open(race_url).unwrap();
        assert_eq!(db.resolve(&format!("sample@{va}")).unwrap(), a);
        assert_eq!(db.resolve(&format!("sample@{vb}")).unwrap(), b);
        let latest = db.resolve("latest").unwrap();
        assert!(latest == a || latest == b, "round {round}");
        let report = verify(&db).unwrap();
        assert!(report.ok(), "round {round}: {:?}", report.problems);
        assert_eq!(report.releases.len(), 2 * (round + 1));
    }
}

#[test]
fn refused_credentials_are_named_and_nothing_is_written() {
    // Checks credentials after one free request (the bucket's creation).
    let s3 = MotoServer::start_with_auth(1).unwrap_or_else(|e| panic!("{e}"));
    s3.create_bucket("locked").unwrap();
    let out = testwriter(&s3, "s3://locked/db", "1.0.0", None);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("refused the credentials")
            && err.contains("s3://locked/db")
            && err.contains("AWS_ACCESS_KEY_ID")
            && err.contains("AWS_SECRET_ACCESS_KEY"),
        "{err}"
    );
    assert_eq!(s3.all_keys().unwrap(), Vec::<String>::new());
}
