//! Feature detectors and descriptors for comparing real and rendered images.
//!
//! The validator runs the same detector on a real NavCam frame and on the render at the same
//! pose, then measures repeatability (see `shared/reference/validation.md`). The detectors are
//! the thesis set (Harris, SIFT, SURF, MSER) plus FAST, and each follows OpenCV's algorithm and
//! defaults closely enough that `tools/peers/features_opencv.py` can compare keypoints one by
//! one: repeatability numbers then mean what they mean in the literature, not "what our
//! re-implementation happens to do". Where we depart from OpenCV it is documented in the
//! detector's module (SIFT's quarter-pixel shift, MSER's `min_diversity`).
//!
//! Every detector takes a [`GreyF32`] in `[0, 1]` and returns keypoints in the canonical order
//! of [`keypoint::sort_keypoints`]. Parallel work uses indexed rayon iterators and the output is
//! sorted, so results are bit-identical on any thread count. A degenerate image (no pixels, or a
//! buffer shorter than `width × height`) gives an empty result, never a panic.

pub mod contrast;
pub mod fast;
pub mod harris;
pub mod image;
pub mod keypoint;
pub mod mser;
pub mod sift;
pub mod surf;
pub mod synthetic;

use std::str::FromStr;

use serde::{Deserialize, Serialize};

pub use self::image::GreyF32;
pub use fast::FastParams;
pub use harris::HarrisParams;
pub use keypoint::{Keypoint, Region};
pub use mser::MserParams;
pub use sift::SiftParams;
pub use surf::SurfParams;

/// The detectors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Detector {
    /// Harris corners (OpenCV `goodFeaturesToTrack` with the Harris measure).
    Harris,
    /// FAST-9 corners.
    Fast,
    /// SIFT blobs (difference of Gaussians), 128-d descriptor.
    Sift,
    /// SURF blobs (fast Hessian), 64-d descriptor.
    Surf,
    /// Maximally stable extremal regions.
    Mser,
}

impl Detector {
    /// Every detector, in declaration order.
    pub const ALL: [Detector; 5] = [
        Detector::Harris,
        Detector::Fast,
        Detector::Sift,
        Detector::Surf,
        Detector::Mser,
    ];

    /// The kebab-case name (as in serde and [`FromStr`]).
    pub fn name(self) -> &'static str {
        match self {
            Detector::Harris => "harris",
            Detector::Fast => "fast",
            Detector::Sift => "sift",
            Detector::Surf => "surf",
            Detector::Mser => "mser",
        }
    }

    /// Descriptor length, or `None` for detectors without a descriptor.
    pub fn descriptor_len(self) -> Option<usize> {
        match self {
            Detector::Sift => Some(128),
            Detector::Surf => Some(64),
            _ => None,
        }
    }
}

impl std::fmt::Display for Detector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown detector name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown detector {found:?}, expected one of harris, fast, sift, surf, mser")]
pub struct UnknownDetector {
    /// The name given.
    pub found: String,
}

impl FromStr for Detector {
    type Err = UnknownDetector;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Detector::ALL
            .into_iter()
            .find(|d| d.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| UnknownDetector {
                found: s.to_string(),
            })
    }
}

/// Parameters of every detector; each default is OpenCV's (see each struct).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectorParams {
    /// Harris.
    pub harris: HarrisParams,
    /// FAST.
    pub fast: FastParams,
    /// SIFT.
    pub sift: SiftParams,
    /// SURF.
    pub surf: SurfParams,
    /// MSER.
    pub mser: MserParams,
}

/// Runs detector `d`; deterministic, sorted by response (descending) then position.
pub fn detect(img: &GreyF32, d: Detector, params: &DetectorParams) -> Vec<Keypoint> {
    match d {
        Detector::Harris => harris::detect_harris(img, &params.harris),
        Detector::Fast => fast::detect_fast(img, &params.fast),
        Detector::Sift => sift::detect_sift(img, &params.sift),
        Detector::Surf => surf::detect_surf(img, &params.surf),
        Detector::Mser => mser::detect_mser(img, &params.mser),
    }
}

/// Descriptors of `kps` (as returned by [`detect`] with the same detector and default
/// parameters): 128-d for SIFT, 64-d for SURF, one per keypoint; empty for detectors without
/// a descriptor.
pub fn describe(img: &GreyF32, kps: &[Keypoint], d: Detector) -> Vec<Vec<f32>> {
    describe_with(img, kps, d, &DetectorParams::default())
}

/// [`describe`] for keypoints detected with `params` (SIFT rebuilds the same scale space).
pub fn describe_with(
    img: &GreyF32,
    kps: &[Keypoint],
    d: Detector,
    params: &DetectorParams,
) -> Vec<Vec<f32>> {
    match d {
        Detector::Sift => sift::describe_sift(img, kps, &params.sift),
        Detector::Surf => surf::describe_surf(img, kps),
        _ => Vec::new(),
    }
}

/// Nearest-neighbour matching of `a` against `b` with Lowe's ratio test: `(i, j)` is kept when
/// `b[j]` is the nearest to `a[i]` and `‖a_i − b_j‖ < ratio · ‖a_i − b_second‖` (Euclidean
/// distances; Lowe used 0.8). Ties go to the lower index; the output is in `i` order.
pub fn brute_force_match(a: &[Vec<f32>], b: &[Vec<f32>], ratio: f32) -> Vec<(usize, usize)> {
    let params = crate::metrics::matching::MatchParams {
        ratio,
        mutual: false,
    };
    crate::metrics::matching::match_descriptors(a, b, &params)
        .into_iter()
        .map(|m| (m.a, m.b))
        .collect()
}
