//! Encoders for the payloads of a release, exactly as `format-spec/SPEC.md` §5 defines them:
//! 16-bit and 8-bit PNG, single-channel float EXR, binary glTF and the captures MCAP.
//!
//! Every encoder is deterministic: fixed compression settings, no timestamps, no thread-count
//! dependence, so the same input always gives the same object id.

pub mod exr;
pub mod glb;
pub mod heightfield;
pub mod mcap;
pub mod mesh_lod;
pub mod png;
pub mod terrain;

/// An encoding failure (a bug or an impossible size, never bad user input).
#[derive(Debug, thiserror::Error)]
#[error("encoding {what}: {message}")]
pub struct EncodeError {
    /// What was being encoded.
    pub what: &'static str,
    /// The encoder's message.
    pub message: String,
}

impl EncodeError {
    pub(crate) fn new(what: &'static str, e: impl std::fmt::Display) -> EncodeError {
        EncodeError {
            what,
            message: e.to_string(),
        }
    }
}
