//! Shared by the compiler's integration tests: where the fixtures live.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A scan fixture of this repository (`compiler/tests/data/scans/NAME`).
pub fn scan_data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/scans")
        .join(name)
}

/// A real sample file of `../shared/realdata/` (see its PROVENANCE.md).
pub fn realdata(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/realdata")
        .join(name)
}
