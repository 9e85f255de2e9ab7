//! Crash safety: a writer killed between any two steps of a commit leaves the previous release
//! readable, `latest` unchanged and `verify` clean; `gc` then removes what it left behind.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

use regolith_reader::{verify, Database, Writer};

#[test]
fn a_killed_writer_leaves_the_previous_release_intact() {
    let exe = env!("CARGO_BIN_EXE_regolith-testwriter");
    for step in [
        "object-renamed",
        "objects-stored",
        "manifest-stored",
        "ref-temp-written",
    ] {
        let dir = tempfile::tempdir().unwrap();
        let ok = Command::new(exe)
            .arg(dir.path())
            .arg("1.0.0")
            .output()
            .unwrap();
        assert!(
            ok.status.success(),
            "{}",
            String::from_utf8_lossy(&ok.stderr)
        );
        let first = String::from_utf8(ok.stdout)
            .unwrap()
            .trim()
            .parse()
            .unwrap();
        let killed = Command::new(exe)
            .arg(dir.path())
            .arg("2.0.0")
            .env("REGOLITH_FAILPOINT", step)
            .output()
            .unwrap();
        assert!(!killed.status.success(), "failpoint {step} did not fire");
        let db = Database::open(dir.path()).unwrap();
        assert_eq!(db.resolve("latest").unwrap(), first, "{step}");
        assert!(db
            .release("sample@1.0.0")
            .unwrap()
            .heightfield("laser/0.05")
            .is_ok());
        assert!(verify(&db).unwrap().ok(), "{step}");
        let w = Writer::create_or_open(dir.path()).unwrap();
        w.gc().unwrap();
        assert!(std::fs::read_dir(dir.path().join("tmp"))
            .unwrap()
            .next()
            .is_none());
        drop(w);
        // A retry after the crash succeeds.
        let retry = Command::new(exe)
            .arg(dir.path())
            .arg("2.0.0")
            .output()
            .unwrap();
        assert!(
            retry.status.success(),
            "{step}: {}",
            String::from_utf8_lossy(&retry.stderr)
        );
        assert!(verify(&Database::open(dir.path()).unwrap()).unwrap().ok());
    }
}
