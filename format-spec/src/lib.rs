//! # regolith-format
//!
//! The types and rules of the regolith terrain database format, `regolith.db/1`, exactly as
//! `format-spec/SPEC.md` states them. This crate is the single source of truth that the
//! writer (compiler, validator) and every reader share, so it holds only pure data types and
//! pure functions: no file I/O and no heavy dependencies.
//!
//! * [`hash`]: SHA-256 object ids and their textual and path forms.
//! * [`canonical_json`]: the RFC 8785 (JCS) canonical JSON that release ids are computed over.
//! * [`manifest`]: the release manifest, entries, tiles and file references.
//! * [`kinds`]: the metadata of each entry kind (heightfield, mesh, texture, camera, rig,
//!   captures, report).
//! * [`camera_model`]: the pinhole + Brown–Conrady camera model and its pixel convention.
//! * [`frames`]: rigid poses (`ground_from_camera`) and quaternion helpers.
//! * [`grid`], [`lighting`], [`effects`]: the words the corpus generator and the validator
//!   share (terrain grids, the lab light, the catalogue of capture effects), so that neither
//!   borrows the other's implementation.
//!
//! ```
//! use regolith_format::canonical_json;
//! let v: serde_json::Value = serde_json::from_str(r#"{"b": 1.50, "a": [true, null]}"#).unwrap();
//! assert_eq!(canonical_json::to_string(&v), r#"{"a":[true,null],"b":1.5}"#);
//! ```
#![deny(missing_docs)]
#![deny(clippy::indexing_slicing)]

pub mod camera_model;
pub mod canonical_json;
pub mod effects;
pub mod error;
pub mod frames;
pub mod grid;
pub mod hash;
pub mod kinds;
pub mod lighting;
pub mod limits;
pub mod manifest;

pub use error::FormatError;
pub use hash::ObjectId;
pub use manifest::{Entry, FileRef, Release, Tile};

/// The schema id of this format version; it appears in every manifest and in `regolith.db`.
pub const SCHEMA: &str = "regolith.db/1";
/// The major version of the format this crate reads and writes.
pub const FORMAT_MAJOR: u32 = 1;
