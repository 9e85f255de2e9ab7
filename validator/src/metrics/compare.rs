//! One detector on one view: real frame a against the render (the figure) and against real
//! frame b at the same pose (the ceiling), with every metric the certificate keeps for it.
//!
//! Why here: the detector-specific protocols differ (corners, which have no scale, are repeated
//! within ε pixels; the scale-covariant detectors' regions — MSER's ellipses, SIFT's and SURF's
//! circles of their keypoints' size — by overlap error < 40 % after scale normalisation, as the
//! Mikolajczyk protocol prescribes for them; SIFT additionally gets the matching score and a
//! RANSAC inlier ratio, the thesis's Table 6.1 analogue), and each detector must run once per
//! image, not once per metric. This module derives every metric from one detection per image
//! ([`detect`]).
//!
//! Why regions for SIFT and SURF: a scale-space keypoint's position is only as precise as its
//! scale, so a fixed ε judges a large blob by a corner's standard: between renders and
//! independently rendered photographs the best entry's SIFT and SURF keypoints were re-found
//! within ε barely above chance, no better than a degraded entry's, and by region overlap far
//! above them (figures in docs/validate.md).
//!
//! The views compared share the pose, so the mapping between them is the identity and the region
//! both see is the render's terrain mask. For SIFT + RANSAC the model is a homography (the
//! identity is one); a fundamental matrix is undetermined without a baseline.

use serde::{Deserialize, Serialize};

use super::matching::{
    match_descriptors, matching_score, verify_matches, Match, MatchParams, MatchReport,
    MatchingScore,
};
use super::ransac::RansacParams;
use super::region_overlap::{region_repeatability, Ellipse, RegionParams, RegionRepeatability};
use super::repeatability::{repeatability, repeated_pairs, Repeatability};
use crate::features::mser::{mser_keypoints, mser_regions};
use crate::features::sift::detect_and_describe_sift;
use crate::features::{self, Detector, DetectorParams, GreyF32, Keypoint};

/// SIFT matching figures of one pair of images.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchingFigures {
    /// Matching score (Mikolajczyk & Schmid) at the certified ε.
    pub score: MatchingScore,
    /// Ratio-test matches verified by a RANSAC homography.
    pub ransac: MatchReport,
}

/// Everything measured for one detector on one view.
#[derive(Debug, Clone)]
pub struct DetectorComparison {
    /// Keypoints of real frame a.
    pub real: Vec<Keypoint>,
    /// Keypoints of the render.
    pub render: Vec<Keypoint>,
    /// Point repeatability real → render over the ε curve.
    pub sim: Vec<Repeatability>,
    /// Point repeatability real a → real b at the certified ε.
    pub ceiling: Option<Repeatability>,
    /// `(real, render)` index pairs repeated at the certified ε (for overlays).
    pub repeated: Vec<(usize, usize)>,
    /// The scale-covariant detectors (MSER, SIFT, SURF): region repeatability real → render
    /// and real a → real b (overlap error).
    pub regions: Option<(RegionRepeatability, Option<RegionRepeatability>)>,
    /// SIFT only: matching real → render and real a → real b.
    pub matching: Option<(MatchingFigures, Option<MatchingFigures>)>,
}

/// A detector's output on one image: keypoints, plus descriptors (SIFT) or regions (MSER).
/// A real frame's is the same whatever entry it is compared with, so a validation of several
/// entries detects on each real frame once ([`crate::validate::Validator`]).
#[derive(Debug, Clone)]
pub struct Detected {
    kps: Vec<Keypoint>,
    descriptors: Vec<Vec<f32>>,
    ellipses: Vec<Ellipse>,
}

impl Detected {
    /// The keypoints found.
    pub fn keypoints(&self) -> &[Keypoint] {
        &self.kps
    }
}

/// Runs detector `d` on `img`.
pub fn detect(img: &GreyF32, d: Detector, params: &DetectorParams) -> Detected {
    match d {
        Detector::Sift => {
            let (kps, descriptors) = detect_and_describe_sift(img, &params.sift);
            Detected {
                ellipses: circles(&kps),
                kps,
                descriptors,
            }
        }
        Detector::Surf => {
            let kps = features::detect(img, d, params);
            Detected {
                ellipses: circles(&kps),
                kps,
                descriptors: Vec::new(),
            }
        }
        Detector::Mser => {
            let regions = mser_regions(img, &params.mser);
            Detected {
                kps: mser_keypoints(&regions),
                descriptors: Vec::new(),
                ellipses: regions.iter().map(Ellipse::from_region).collect(),
            }
        }
        _ => Detected {
            kps: features::detect(img, d, params),
            descriptors: Vec::new(),
            ellipses: Vec::new(),
        },
    }
}

/// The region of each scale-space keypoint: the circle of its size (the diameter of its
/// neighbourhood, OpenCV's `KeyPoint::size`).
fn circles(kps: &[Keypoint]) -> Vec<Ellipse> {
    kps.iter()
        .map(|k| Ellipse::circle([f64::from(k.x), f64::from(k.y)], 0.5 * f64::from(k.size)))
        .collect()
}

fn points(k: &[Keypoint]) -> Vec<[f64; 2]> {
    k.iter().map(|p| [f64::from(p.x), f64::from(p.y)]).collect()
}

/// Descriptor matches of `a` in `b` and their RANSAC verification: what SIFT's matching
/// figures need besides the region both images see.
#[derive(Debug, Clone)]
struct Matched {
    matches: Vec<Match>,
    ransac: MatchReport,
}

impl Matched {
    fn of(a: &Detected, b: &Detected) -> Matched {
        let matches = match_descriptors(&a.descriptors, &b.descriptors, &MatchParams::default());
        let ransac = verify_matches(&a.kps, &b.kps, &matches, &RansacParams::homography());
        Matched { matches, ransac }
    }

    fn figures(
        &self,
        a: &Detected,
        b: &Detected,
        seen: &impl Fn([f64; 2]) -> bool,
        eps: f64,
    ) -> MatchingFigures {
        let (pa, pb) = (points(&a.kps), points(&b.kps));
        MatchingFigures {
            score: matching_score(&pa, &pb, &self.matches, Some, seen, eps),
            ransac: self.ransac,
        }
    }
}

/// A detector's output on real frame b of a view, with what comparing it with real frame a
/// gives whatever a render is compared to (SIFT's matches a → b and their RANSAC check; empty
/// for detectors without descriptors, at no cost). Both frames are the same for every entry
/// validated, so this is made once per view.
#[derive(Debug, Clone)]
pub struct RepeatFrame {
    detected: Detected,
    matched: Matched,
}

impl RepeatFrame {
    /// Real frame b's detections `b`, compared with real frame a's `a` (same detector).
    pub fn new(a: &Detected, b: Detected) -> RepeatFrame {
        let matched = Matched::of(a, &b);
        RepeatFrame {
            detected: b,
            matched,
        }
    }

    /// Real frame b's detections.
    pub fn detected(&self) -> &Detected {
        &self.detected
    }
}

/// One detector's output on the images of one view, contrast-normalised alike.
#[derive(Debug, Clone, Copy)]
pub struct ViewDetections<'a> {
    /// On real frame a.
    pub real_a: &'a Detected,
    /// On the render at the same pose.
    pub render: &'a Detected,
    /// On real frame b at the same pose, when the campaign has repeat frames.
    pub real_b: Option<&'a RepeatFrame>,
}

/// Measures detector `d`'s output on one view (see [`detect`]): point repeatability over
/// `curve` (which contains `eps`), the ceiling at `eps`, and the detector-specific metrics.
/// `seen(p)` says whether pixel `p` shows terrain in the render, and `seen_px` is how many
/// pixels do (the area of the chance correction).
pub fn compare(
    found: ViewDetections<'_>,
    d: Detector,
    seen: impl Fn([f64; 2]) -> bool,
    seen_px: f64,
    curve: &[f64],
    eps: f64,
) -> DetectorComparison {
    let (a, s, repeat) = (found.real_a, found.render, found.real_b);
    let b = repeat.map(RepeatFrame::detected);
    let (pa, ps) = (points(&a.kps), points(&s.kps));
    let sim = repeatability(&pa, &ps, Some, &seen, seen_px, curve);
    let ceiling = b.map(|b| repeatability(&pa, &points(&b.kps), Some, &seen, seen_px, &[eps])[0]);
    let repeated = repeated_pairs(&pa, &ps, Some, &seen, eps);
    let regions = matches!(d, Detector::Mser | Detector::Sift | Detector::Surf).then(|| {
        let rp = RegionParams::default();
        (
            region_repeatability(&a.ellipses, &s.ellipses, Some, &seen, &rp),
            b.map(|b| region_repeatability(&a.ellipses, &b.ellipses, Some, &seen, &rp)),
        )
    });
    let matching = (d == Detector::Sift).then(|| {
        (
            Matched::of(a, s).figures(a, s, &seen, eps),
            repeat.map(|r| r.matched.figures(a, &r.detected, &seen, eps)),
        )
    });
    DetectorComparison {
        real: a.kps.clone(),
        render: s.kps.clone(),
        sim,
        ceiling,
        repeated,
        regions,
        matching,
    }
}
