//! # regolith-reader
//!
//! Load a regolith terrain database (`regolith.db/1`, see `format-spec/SPEC.md`) from a
//! simulator or a script. Every byte handed out has been checked against the SHA-256 that
//! names it; corruption is an error naming the object, the entry and the role.
//!
//! ```no_run
//! use regolith_reader::Database;
//!
//! let db = Database::open("terrain.db")?;
//! let release = db.release("latest")?;            // or "estec@1.0.0", or an id prefix
//! for entry in release.entries() {
//!     println!("{} ({})", entry.name, entry.kind);
//! }
//! let hf = release.heightfield("laser/0.015")?;     // f32 heights + validity mask
//! let cam = release.camera("cameras/navcam_left")?; // pinhole + Brown–Conrady
//! println!("{} cells, fx = {}", hf.heights.len(), cam.fx);
//! # Ok::<(), regolith_reader::ReaderError>(())
//! ```
//!
//! The crate also holds the one writer ([`write::Writer`]) so the compiler, the validator and
//! the gap workflow share the same crash-safe write path; it adds no dependency.
//!
//! A database lives in a local folder or, with the `object-store` cargo feature, under a
//! prefix of an object store (`Database::open("s3://bucket/terrain")`); [`store`] holds both
//! backends and says how each keeps the writer's guarantees.
#![deny(missing_docs)]

#[cfg(feature = "captures")]
pub mod captures;
pub mod database;
pub mod error;
pub mod heightfield;
pub mod mesh;
pub mod object;
pub mod store;
pub mod verify;
pub mod write;

pub use database::{Database, ReleaseView};
pub use error::ReaderError;
pub use heightfield::Heightfield;
pub use store::Location;
pub use verify::{verify, VerifyReport};
pub use write::Writer;
