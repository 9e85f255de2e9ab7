//! Keypoints and MSER regions: the detector outputs.
//!
//! Pixel convention (shared with `regolith_format::camera_model`): `(0, 0)` is the centre of
//! the top-left pixel, `x` to the right, `y` down. `size` is a diameter in pixels and `angle`
//! is in degrees in `[0, 360)`, measured as OpenCV does (from +x towards +y, i.e. clockwise
//! on screen), or `-1` when the detector assigns none. Keeping OpenCV's meaning for every
//! field lets the peer script compare outputs field by field.
//!
//! Output order is part of the contract: [`sort_keypoints`] sorts by response (descending),
//! then `y`, then `x`, then size (total order on floats), so results are deterministic and
//! identical on any thread count.

use serde::{Deserialize, Serialize};
use std::cmp::Ordering;

/// One detected keypoint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Keypoint {
    /// Column, pixels ((0,0) = centre of the top-left pixel).
    pub x: f32,
    /// Row, pixels.
    pub y: f32,
    /// Diameter of the meaningful neighbourhood, pixels.
    pub size: f32,
    /// Orientation, degrees in `[0, 360)`; `-1` when not computed.
    pub angle: f32,
    /// Detector strength (detector-specific units, larger is stronger).
    pub response: f32,
    /// Octave (scale-space detectors; `-1` = the doubled base image of SIFT), else 0.
    pub octave: i32,
}

impl Keypoint {
    /// A keypoint at `(x, y)` with no orientation, octave 0.
    pub fn at(x: f32, y: f32, size: f32, response: f32) -> Keypoint {
        Keypoint {
            x,
            y,
            size,
            angle: -1.0,
            response,
            octave: 0,
        }
    }
}

/// An MSER region summarised by its first and second moments.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Region {
    /// Centroid column, pixels.
    pub x: f64,
    /// Centroid row, pixels.
    pub y: f64,
    /// Pixel count of the region.
    pub area: usize,
    /// Second-moment covariance `[[cxx, cxy], [cxy, cyy]]` in px² (a filled ellipse with
    /// semi-axes `a, b` has eigenvalues `a²/4, b²/4`).
    pub cov: [[f64; 2]; 2],
    /// `true` for a bright region (brighter than its boundary), `false` for a dark one.
    pub bright: bool,
    /// Grey level (0..=255, in the pass's own polarity) at which the region is stable.
    pub level: u8,
    /// MSER variation at that level.
    pub variation: f32,
}

impl Region {
    /// Semi-axes `(major, minor)` of the ellipse with the same second moments, pixels.
    pub fn semi_axes(&self) -> (f64, f64) {
        let [[a, b], [_, c]] = self.cov;
        let half_trace = 0.5 * (a + c);
        let disc = (0.25 * (a - c) * (a - c) + b * b).sqrt();
        let l1 = (half_trace + disc).max(0.0);
        let l2 = (half_trace - disc).max(0.0);
        (2.0 * l1.sqrt(), 2.0 * l2.sqrt())
    }

    /// The keypoint that stands for this region: centroid, and the diameter of the circle
    /// with the area of the moment ellipse.
    pub fn keypoint(&self) -> Keypoint {
        let (a, b) = self.semi_axes();
        Keypoint::at(
            self.x as f32,
            self.y as f32,
            (2.0 * (a * b).sqrt()) as f32,
            1.0 - self.variation,
        )
    }
}

/// Total order used for every detector's output: response descending, then `y`, `x`, size.
pub fn keypoint_order(a: &Keypoint, b: &Keypoint) -> Ordering {
    b.response
        .total_cmp(&a.response)
        .then(a.y.total_cmp(&b.y))
        .then(a.x.total_cmp(&b.x))
        .then(a.size.total_cmp(&b.size))
        .then(a.angle.total_cmp(&b.angle))
        .then(a.octave.cmp(&b.octave))
}

/// Sorts keypoints into the canonical order (see the module docs).
pub fn sort_keypoints(kps: &mut [Keypoint]) {
    kps.sort_by(keypoint_order);
}
