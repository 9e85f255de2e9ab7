//! The stages of `regolith compile`, one file each, in pipeline order (see `stage.rs`).
pub mod captures;
