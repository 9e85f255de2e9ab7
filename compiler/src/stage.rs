//! The stage abstraction of `regolith compile` (house style practice 5, after PDAL's stages).
//!
//! A stage is a named, versioned, pure step: typed params validated before any work, a typed
//! input, a typed output. `NAME` is stable and dotted (`dem.raster`); `VERSION` changes whenever
//! the stage's output bytes change for the same input, which invalidates caches and is recorded
//! in the release's plan. Stages push partial failures (a marker with few frames, a scan with a
//! large residual) into the [`Reporter`] so they end up in the report objects, not in a log.

use std::sync::Mutex;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use sha2::{Digest, Sha256};

/// A stage failure: the stage's name and what went wrong.
#[derive(Debug, thiserror::Error)]
#[error("{stage}: {message}")]
pub struct StageError {
    /// The stage's dotted name.
    pub stage: &'static str,
    /// What went wrong, with the numbers that matter.
    pub message: String,
}

impl StageError {
    /// A new error.
    pub fn new(stage: &'static str, message: impl Into<String>) -> StageError {
        StageError {
            stage,
            message: message.into(),
        }
    }
}

/// A structured warning produced by a stage.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Warning {
    /// The stage that raised it.
    pub stage: &'static str,
    /// A stable kind, e.g. `marker-few-frames`.
    pub kind: &'static str,
    /// Human-readable detail.
    pub message: String,
}

/// Collects warnings from stages (thread-safe; stages may warn from rayon workers).
#[derive(Debug, Default)]
pub struct Reporter {
    warnings: Mutex<Vec<Warning>>,
}

impl Reporter {
    /// Records a warning.
    pub fn warn(&self, stage: &'static str, kind: &'static str, message: impl Into<String>) {
        if let Ok(mut w) = self.warnings.lock() {
            w.push(Warning {
                stage,
                kind,
                message: message.into(),
            });
        }
    }

    /// All warnings so far, sorted (stage, kind, message) so reports do not depend on thread timing.
    pub fn warnings(&self) -> Vec<Warning> {
        let mut w = self.warnings.lock().map(|w| w.clone()).unwrap_or_default();
        w.sort_by(|a, b| (a.stage, a.kind, &a.message).cmp(&(b.stage, b.kind, &b.message)));
        w
    }
}

/// What every stage receives besides its input.
#[derive(Debug, Default)]
pub struct StageCx {
    /// Warning sink.
    pub reporter: Reporter,
    /// The campaign seed (0 unless the campaign sets one).
    pub seed: u64,
}

impl StageCx {
    /// A deterministic RNG for one stage: ChaCha8 seeded from `sha256(seed, stage name)`.
    pub fn rng(&self, stage: &str) -> ChaCha8Rng {
        let mut h = Sha256::new();
        h.update(self.seed.to_le_bytes());
        h.update(stage.as_bytes());
        ChaCha8Rng::from_seed(h.finalize().into())
    }
}

/// One step of `regolith compile`: a pure function of its typed input and params.
pub trait Stage {
    /// Stable dotted name, e.g. `dem.raster`.
    const NAME: &'static str;
    /// Bumped when the output bytes change for the same input.
    const VERSION: u32;
    /// One line saying what the stage does.
    const DESCRIPTION: &'static str;
    /// The input.
    type Input: ?Sized;
    /// The output.
    type Output;
    /// The resolved parameters, as recorded in the release plan.
    fn params(&self) -> serde_json::Value;
    /// Runs the stage.
    fn run(&self, cx: &StageCx, input: &Self::Input) -> Result<Self::Output, StageError>;
}
