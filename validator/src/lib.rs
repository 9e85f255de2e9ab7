//! # regolith-validator
//!
//! Re-renders terrain entries at real capture poses and compares the renders with the real
//! images. [`render`] is a deterministic CPU renderer; [`sensor`] is the camera/sensor effect
//! model shared with the corpus generator (which applies hidden effects to "real" images) and
//! with the gap workflow (which fits them). [`report`] draws an offline HTML report of a
//! validation run (PNG figures, `regolith validate --report`).

mod child;
pub mod control;
pub mod features;
pub mod gap;
pub mod mesh_entry;
pub mod metrics;
pub mod render;
pub mod report;
pub mod sensor;
pub mod validate;
