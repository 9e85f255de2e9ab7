//! One error type for the format crate: every variant says what was expected and what was found.

use thiserror::Error;

/// Errors raised while decoding or checking format-level data.
#[derive(Debug, Error)]
pub enum FormatError {
    /// A hex object id was malformed.
    #[error("bad object id {found:?}: expected 64 lowercase hex digits")]
    BadObjectId {
        /// The text that was found.
        found: String,
    },
    /// A manifest's `schema` field named a version this crate cannot read.
    #[error("unsupported schema {found:?}: expected \"regolith.db/1\" (same major version)")]
    UnsupportedSchema {
        /// The schema string found.
        found: String,
    },
    /// JSON did not match the expected structure.
    #[error("invalid {what}: {message}")]
    InvalidJson {
        /// What was being decoded (e.g. "release manifest").
        what: &'static str,
        /// The decoder's message (with line and column).
        message: String,
    },
    /// A manifest violates a rule of the spec.
    #[error("invalid manifest: {0}")]
    InvalidManifest(String),
    /// A length or count read from input exceeds a configured limit.
    #[error("{what} of {found} exceeds the limit of {limit}")]
    LimitExceeded {
        /// What was limited.
        what: &'static str,
        /// The value found.
        found: u64,
        /// The limit in force.
        limit: u64,
    },
    /// A camera model parameter is out of range.
    #[error("invalid camera model: {0}")]
    InvalidCamera(String),
}
