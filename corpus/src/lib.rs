//! # regolith-corpus
//!
//! Generates synthetic survey campaigns with full ground truth and hidden sensor effects
//! (`regolith corpus generate`). A campaign folder holds every raw file in its real format —
//! RiSCAN ASCII / PLY / E57 / LAS scans with tie-point lists, Vicon Nexus CSVs, OpenCV and
//! Bouguet calibrations, an SfM mesh in VRML and PLY, raw 8-bit stereo captures — plus a
//! `truth/` folder the campaign never references.
//!
//! Design decisions:
//! * **One truth, traced by everyone.** The true surface is a fine [`HeightGrid`] of the
//!   renderer's own type; laser rays, marker visibility and captures all go through the
//!   validator's tracer/renderer, so the truth files describe exactly what was measured.
//! * **Deterministic per seed.** Each stage has its own `ChaCha8Rng` from `hash(seed, stage)`
//!   ([`seeding`]); parallel loops use indexed `par_iter().map().collect()` with one RNG per
//!   item; nothing reads the clock. Files are byte-identical for any thread count.
//! * **Hidden effects are shared definitions.** [`effects`] draws them from the validator's
//!   sensor catalogue and records them only in `truth/hidden.json`.
//!
//! Layout: [`terrain`] (relief, materials), [`instruments`] (one module per device/format),
//! [`campaign`] (campaign.toml + README), [`truth`], [`bad_inputs`], [`generate`] here.

pub mod bad_inputs;
pub mod campaign;
pub mod effects;
mod error;
mod generate;
pub mod instruments;
pub mod presets;
pub mod seeding;
pub mod sink;
pub mod terrain;
pub mod truth;

pub use bad_inputs::write_bad_inputs;
pub use effects::HiddenSpec;
pub use error::CorpusError;
pub use generate::{generate, GenerateOptions, Summary};
pub use presets::Preset;
#[doc(no_inline)]
pub use regolith_validator::render::HeightGrid;
