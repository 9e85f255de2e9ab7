//! # regolith-compiler
//!
//! Turns a campaign folder (`campaign.toml` plus the raw files real instruments write) into a
//! release of the terrain database. The data flows one way: [`ingest`] parses every raw
//! format into typed data, the stages register, grid, align and encode it, and the result is
//! written into the object store through `regolith_reader::write`.

pub mod compile;
pub mod encode;
pub mod error;
pub mod export;
pub mod ingest;
pub mod inventory;
pub mod stage;
pub mod stages;

pub use error::IngestError;
