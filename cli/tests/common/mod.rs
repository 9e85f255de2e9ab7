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
