//! Shared by the CLI integration tests: run the `regolith` binary as a user would.
#![allow(clippy::unwrap_used, dead_code)]

use std::process::{Command, Output};

/// Runs `regolith ARGS` and returns its output (status, stdout, stderr).
pub fn regolith(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_regolith"))
        .args(args)
        .output()
        .unwrap()
}

/// The certificate object a `validate --json` entry points at, read from the database folder.
pub fn certificate(db: &str, entry: &serde_json::Value) -> serde_json::Value {
    let h = entry["certificate"].as_str().unwrap();
    let path = std::path::Path::new(db).join(format!("objects/sha256/{}/{}", &h[..2], &h[2..]));
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Copies the directory tree `from` to `to`.
pub fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let dest = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &dest);
        } else {
            std::fs::copy(&p, &dest).unwrap();
        }
    }
}
