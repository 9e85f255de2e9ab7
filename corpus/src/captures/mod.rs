//! The "real" NavCam frames of a campaign, and who makes them.
//!
//! The generator decides *what* the cameras saw — the true terrain and albedo, the marker balls,
//! the true lab light, each camera's true intrinsics (calibration + hidden distortion) and true
//! pose (Vicon rig pose · hidden bias) — and hands that to a [`CaptureRenderer`], which decides
//! *how* the image is formed. Two renderers exist, on purpose in different crates:
//!
//! * [`physical::PhysicalCaptures`] (this crate): an existing physically based path tracer
//!   (Mitsuba 3, driven by `tools/render/mitsuba_captures.py`) renders the testbed inside a lab
//!   hall, and this crate's own camera ([`crate::camera`]) forms the frames. It shares no code
//!   with the validator, so the validator's figures on such captures mean something.
//! * `regolith-model-captures` (a separate crate): the validator's own renderer and sensor
//!   model. Images made that way are, by construction, a catalogue effect away from a
//!   validator render — the "inverse crime"; it exists for fast unit tests of the fitting code
//!   and is named for what it is. This crate cannot depend on it (the layering test forbids
//!   `regolith-corpus → regolith-validator`).

pub mod physical;

use regolith_format::camera_model::CameraModel;
use regolith_format::effects::Effect;
use regolith_format::frames::Pose;
use regolith_format::lighting::Light;
use serde::Serialize;

use crate::presets::PresetConfig;
use crate::terrain::Terrain;
use crate::CorpusError;

/// One camera at one capture location: what it truly is and where it truly was.
#[derive(Debug, Clone, PartialEq)]
pub struct Shot {
    /// `<location>_<side>` (`loc01_left`).
    pub name: String,
    /// The true intrinsics (calibration + hidden distortion).
    pub camera: CameraModel,
    /// The calibrated intrinsics (what `calib/` says).
    pub calibrated: CameraModel,
    /// The true `ground_from_camera` (Vicon rig pose · hidden bias, the right camera following
    /// the left rigidly).
    pub ground_from_camera: Pose,
    /// Left (0) or right (1) camera of the head: the fixed pattern of a sensor is its own.
    pub camera_index: usize,
    /// Seed of the temporal noise of frame a; frame b uses `noise_seed + 1`.
    pub noise_seed: u64,
    /// The capture's exposure gain factor on top of the hidden exposure (an auto-exposing
    /// camera, [`crate::effects::Hidden::capture_gain`]; 1 otherwise): renderers scale the
    /// shot's radiance by it before the camera, which is the same as scaling the exposure's
    /// gain (every optical effect before the exposure is linear in radiance).
    pub exposure_gain: f64,
}

/// Everything a renderer may look at besides the shots.
pub struct CaptureScene<'a> {
    /// The preset.
    pub cfg: &'a PresetConfig,
    /// The campaign seed.
    pub seed: u64,
    /// The true terrain (heights, albedo, markers).
    pub terrain: &'a Terrain,
    /// The true lab light (the campaign file records a surveyed copy of it).
    pub light: Light,
    /// The effects of the real images: the hidden ones plus the baseline sensor noise
    /// ([`crate::effects::real_model`]).
    pub effects: &'a [Effect],
}

/// What made the frames, recorded in `truth/renderer.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RendererInfo {
    /// `mitsuba` or `validator-model`.
    pub name: String,
    /// Whether the frames come from a forward model independent of the validator.
    pub independent_of_validator: bool,
    /// Free-form, sorted details (versions, samples, BSDF, camera physics...).
    pub details: serde_json::Value,
}

/// Makes the frames of every shot.
pub trait CaptureRenderer: Sync {
    /// Frames a and b (8-bit grey, row-major, `camera.width × camera.height`) of each shot, in
    /// order. `progress` receives the fraction done.
    fn frames(
        &self,
        scene: &CaptureScene<'_>,
        shots: &[Shot],
        progress: &dyn Fn(f64),
    ) -> Result<Vec<[Vec<u8>; 2]>, CorpusError>;

    /// What made them (called after [`CaptureRenderer::frames`]).
    fn info(&self) -> RendererInfo;

    /// The nuisances of the world these frames belong to ([`crate::lab`]).
    fn world(&self) -> crate::lab::World {
        crate::lab::World::IDEAL
    }
}
