//! The CLI on an object store (`moto_server`, see `regolith_tests::moto`): compile into
//! `s3://…` gives the release id a folder gets; verify, inspect, export, validate and gc (with
//! its grace period) work there; refused credentials are named and nothing is written.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::process::{Command, Output};

use regolith_tests::moto::MotoServer;

fn regolith(s3: &MotoServer, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_regolith"))
        .args(args)
        .envs(s3.env())
        .output()
        .unwrap()
}

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn json(out: &Output) -> serde_json::Value {
    serde_json::from_str(&ok(out)).unwrap()
}

#[test]
fn every_db_command_works_on_s3() {
    let s3 = MotoServer::start().unwrap_or_else(|e| panic!("{e}"));
    s3.create_bucket("terrain").unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("campaign");
    common::generate_mini(&camp, 3);
    let camp = camp.to_str().unwrap();
    let url = "s3://terrain/surveys/mini";
    let remote = json(&regolith(
        &s3,
        &["-q", "--json", "compile", camp, "--db", url],
    ));
    let folder = tmp.path().join("db");
    let local = json(&regolith(
        &s3,
        &[
            "-q",
            "--json",
            "compile",
            camp,
            "--db",
            folder.to_str().unwrap(),
        ],
    ));
    assert_eq!(remote["id"], local["id"], "same bytes, same release id");
    let id = remote["id"].as_str().unwrap();

    let verify = json(&regolith(&s3, &["--json", "verify", url]));
    assert_eq!(verify["ok"], true);
    let inspect = ok(&regolith(&s3, &["inspect", url]));
    assert!(
        inspect.contains(&id[..12]) && inspect.contains(url),
        "{inspect}"
    );
    let out = tmp.path().join("export");
    ok(&regolith(
        &s3,
        &[
            "export",
            url,
            "latest",
            "laser/0.02",
            "--to",
            out.to_str().unwrap(),
        ],
    ));
    assert!(out.join("height.exr").is_file());

    // validate writes its certificate into the object store (this entry fails the gate on a
    // model-rendered mini campaign: exit 1, certificate written all the same).
    let v = regolith(
        &s3,
        &[
            "-q",
            "validate",
            url,
            "--entry",
            "laser/0.02",
            "--detector",
            "harris",
        ],
    );
    assert!(
        matches!(v.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&v.stderr)
    );
    let keys = s3.all_keys().unwrap();
    assert!(
        keys.iter().any(|k| k.starts_with(&format!(
            "terrain/surveys/mini/refs/certificates/{id}/laser@s0.02"
        ))),
        "{keys:?}"
    );

    // gc: an unreachable object (as a writer that died leaves) is kept while younger than the
    // grace period, removed with --grace-seconds 0.
    let stray = "terrain/surveys/mini/objects/sha256/00/00000000000000000000000000000000000000000000000000000000000000";
    s3.put_object(stray, b"stray").unwrap();
    let gc = json(&regolith(&s3, &["--json", "gc", url]));
    assert_eq!(
        (gc["removed"].as_u64(), gc["kept_young"].as_u64()),
        (Some(0), Some(1))
    );
    let gc = json(&regolith(
        &s3,
        &["--json", "gc", url, "--grace-seconds", "0"],
    ));
    assert_eq!(gc["removed"].as_u64(), Some(1));
    assert!(!s3.all_keys().unwrap().contains(&stray.to_string()));
    assert_eq!(json(&regolith(&s3, &["--json", "verify", url]))["ok"], true);

    // Not a database, with the URL in the message.
    let e = regolith(&s3, &["inspect", "s3://terrain/elsewhere"]);
    let err = String::from_utf8_lossy(&e.stderr);
    assert_eq!(e.status.code(), Some(2));
    assert!(
        err.contains("s3://terrain/elsewhere is not a regolith database"),
        "{err}"
    );
}

#[test]
fn refused_credentials_fail_compile_before_writing() {
    let s3 = MotoServer::start_with_auth(1).unwrap_or_else(|e| panic!("{e}"));
    s3.create_bucket("locked").unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("campaign");
    common::generate_mini(&camp, 3);
    let out = regolith(
        &s3,
        &["compile", camp.to_str().unwrap(), "--db", "s3://locked/db"],
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("refused the credentials for s3://locked/db")
            && err.contains("nothing was written")
            && err.contains("AWS_ACCESS_KEY_ID"),
        "{err}"
    );
    assert_eq!(s3.all_keys().unwrap(), Vec::<String>::new());
}
