//! Shared helpers of the end-to-end tests: [`sample`] builds a small release with one entry of
//! every kind, deterministically, through the real encoders and the real writer. The test vectors
//! in `format-spec/test-vectors/` are this release, and the crash, corruption and CLI tests use it.
//! [`albedo_truth`] compares an entry's texture with a corpus campaign's true albedo;
//! [`gap_case`] runs one case of the gap workflow's proof on hidden effects; [`moto`] runs an
//! S3-compatible server for the object-store tests.

pub mod albedo_truth;
pub mod gap_case;
pub mod height_truth;
pub mod moto;
pub mod sample;

/// The workspace root (for finding `format-spec/`, `../shared/` and the binaries).
pub fn workspace_root() -> std::path::PathBuf {
    let here = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_else(|| here.to_path_buf())
}
