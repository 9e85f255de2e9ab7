//! # regolith-corpus
//!
//! Generates synthetic survey campaigns with full ground truth and hidden sensor effects
//! (`regolith corpus generate`). A campaign folder holds every raw file in its real format —
//! RiSCAN ASCII / PLY / E57 / LAS scans with tie-point lists, Vicon Nexus CSVs, OpenCV and
//! Bouguet calibrations, an SfM mesh in VRML and PLY, raw 8-bit stereo captures — plus a
//! `truth/` folder the campaign never references.
//!
//! Design decisions:
//! * **No code shared with the validator.** The corpus makes the data that test the
//!   validator, so it never uses the validator's forward model: the true surface is a fine
//!   [`HeightGrid`] (the format's type) traced by this crate's own caster
//!   ([`terrain::raycast`]) for laser rays and marker visibility, and the NavCam frames come
//!   from a [`captures::CaptureRenderer`]: an existing physically based renderer (Mitsuba 3)
//!   plus this crate's own camera ([`camera`]), or — for fast unit tests of the fitting code
//!   only, from another crate — the validator's own model, recorded as such in
//!   `truth/renderer.json`.
//! * **Deterministic per seed.** Each stage has its own `ChaCha8Rng` from `hash(seed, stage)`
//!   ([`seeding`]); parallel loops use indexed `par_iter().map().collect()` with one RNG per
//!   item; nothing reads the clock. Files are byte-identical for any thread count.
//! * **Hidden effects are shared words.** [`effects`] draws them from the format's effect
//!   catalogue (`regolith_format::effects`), applies them with this crate's own code and
//!   records them only in `truth/hidden.json`.
//!
//! Layout: [`terrain`] (relief, materials, ray casting), [`instruments`] (one module per
//! device/format), [`captures`] + [`camera`] (the NavCam frames),
//! [`campaign`] (campaign.toml + README), [`truth`], [`bad_inputs`], [`generate`] here.

pub mod bad_inputs;
pub mod camera;
pub mod campaign;
pub mod captures;
pub mod effects;
mod error;
mod generate;
pub mod instruments;
pub mod lab;
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
pub use regolith_format::grid::HeightGrid;
