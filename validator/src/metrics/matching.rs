//! Descriptor matching between a real frame and its render, the matching score of
//! Mikolajczyk & Schmid (2005), and the thesis's SIFT + RANSAC figures (Table 6.1 analogue:
//! keypoints, matches, inliers, iterations).
//!
//! * [`match_descriptors`]: nearest neighbour in L2 with Lowe's ratio test (0.8) and an
//!   optional mutual (cross) check. Ties go to the lower index, queries run in parallel with
//!   an indexed rayon iterator and the output is in query order, so results are identical on
//!   any thread count. With `mutual = false` it returns the same pairs as
//!   [`crate::features::brute_force_match`], which is this matcher without the distances.
//! * [`matching_score`]: matches made one-to-one greedily by increasing descriptor distance
//!   (as VLBenchmarks does), restricted to keypoints in the region both images see; a match
//!   is correct when A's keypoint, mapped into B, lies within ε px of its match. Score =
//!   correct / min(n_A, n_B) over the common region. It uses the same `map` / `in_common`
//!   closures, common-region filter and one-to-one pairing as point repeatability
//!   ([`super::repeatability`]), so the two figures are directly comparable.
//! * [`sift_ransac`] / [`match_and_verify`]: detect and describe, match, then fit a
//!   fundamental matrix or homography with [`super::ransac`]; the [`MatchReport`] holds the
//!   counts (timing is the caller's business).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::ransac::{ransac, ModelKind, RansacParams};
use super::repeatability::{common_points, fraction, greedy_one_to_one};
use crate::features::sift::{detect_and_describe_sift, SiftParams};
use crate::features::{GreyF32, Keypoint};

/// Matching parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MatchParams {
    /// Lowe's ratio: keep a match when `d₁ < ratio · d₂` (Euclidean; 0.8). A query with a
    /// single candidate has no second distance and passes.
    pub ratio: f32,
    /// Also require that A's query is B's nearest neighbour in A (cross check; off).
    pub mutual: bool,
}

impl Default for MatchParams {
    fn default() -> Self {
        MatchParams {
            ratio: 0.8,
            mutual: false,
        }
    }
}

/// One descriptor match.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Match {
    /// Index in A (the query set).
    pub a: usize,
    /// Index in B.
    pub b: usize,
    /// Euclidean descriptor distance.
    pub distance: f32,
}

/// Lanes of [`dist2`]'s partial sums.
const LANES: usize = 8;

/// Squared Euclidean distance; `∞` when the lengths differ (never a match). Summed in
/// [`LANES`] interleaved partial sums, then those in order: a fixed order (so the same on any
/// machine and thread count) that the compiler can keep in one vector register. A single
/// running sum must be added element by element, which made matching 7 % of a release's
/// validation.
#[inline]
fn dist2(a: &[f32], b: &[f32]) -> f32 {
    if a.len() != b.len() {
        return f32::INFINITY;
    }
    let mut acc = [0.0f32; LANES];
    let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let tail: f32 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| (x - y) * (x - y))
        .sum();
    for (xa, xb) in ca.zip(cb) {
        for ((s, x), y) in acc.iter_mut().zip(xa).zip(xb) {
            *s += (x - y) * (x - y);
        }
    }
    acc.iter().sum::<f32>() + tail
}

/// `(index, nearest d², second-nearest d²)` of `q` in `set`; the first index wins ties.
fn nearest_two(q: &[f32], set: &[Vec<f32>]) -> Option<(usize, f32, f32)> {
    let (mut best, mut second, mut bj) = (f32::INFINITY, f32::INFINITY, None);
    for (j, d) in set.iter().enumerate() {
        let d = dist2(q, d);
        if d < best {
            second = best;
            best = d;
            bj = Some(j);
        } else if d < second {
            second = d;
        }
    }
    bj.map(|j| (j, best, second))
}

/// Matches every descriptor of `a` to its nearest neighbour in `b` (see the module docs);
/// the output is in increasing `a` index.
pub fn match_descriptors(a: &[Vec<f32>], b: &[Vec<f32>], p: &MatchParams) -> Vec<Match> {
    let r2 = p.ratio * p.ratio;
    let reverse: Vec<Option<usize>> = if p.mutual {
        b.par_iter()
            .map(|q| nearest_two(q, a).map(|(i, _, _)| i))
            .collect()
    } else {
        Vec::new()
    };
    a.par_iter()
        .enumerate()
        .filter_map(|(i, q)| {
            let (j, best, second) = nearest_two(q, b)?;
            let ratio_ok = second.is_infinite() || best < r2 * second;
            let mutual_ok = !p.mutual || reverse.get(j).copied().flatten() == Some(i);
            (ratio_ok && mutual_ok).then(|| Match {
                a: i,
                b: j,
                distance: best.sqrt(),
            })
        })
        .collect()
}

/// The matching score at one ε.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchingScore {
    /// Tolerance, px.
    pub epsilon_px: f64,
    /// Keypoints of A inside the common region (after mapping).
    pub n_a: usize,
    /// Keypoints of B inside the common region.
    pub n_b: usize,
    /// One-to-one matches between those keypoints.
    pub matches: usize,
    /// Matches whose mapped A keypoint lies within ε of its B keypoint.
    pub correct: usize,
    /// `correct / min(n_a, n_b)` (0 when either is empty).
    pub score: f64,
}

/// Matching score of `matches` between keypoints `a` and `b` (positions; indices as in the
/// matches). `map_a_to_b` and `in_common` as for
/// [`super::repeatability::repeatability`].
pub fn matching_score(
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    matches: &[Match],
    map_a_to_b: impl Fn([f64; 2]) -> Option<[f64; 2]>,
    in_common: impl Fn([f64; 2]) -> bool,
    epsilon_px: f64,
) -> MatchingScore {
    let (a_in, b_in) = common_points(a, b, map_a_to_b, in_common);
    // Input index → position in the common lists.
    let local = |n: usize, list: &[(usize, [f64; 2])]| {
        let mut at = vec![None; n];
        for (k, (i, _)) in list.iter().enumerate() {
            if let Some(slot) = at.get_mut(*i) {
                *slot = Some(k);
            }
        }
        at
    };
    let (la, lb) = (local(a.len(), &a_in), local(b.len(), &b_in));
    let cand: Vec<(f64, usize, usize)> = matches
        .iter()
        .filter_map(|m| {
            let i = la.get(m.a).copied().flatten()?;
            let j = lb.get(m.b).copied().flatten()?;
            Some((f64::from(m.distance), i, j))
        })
        .collect();
    let one_to_one = greedy_one_to_one(cand, a_in.len(), b_in.len());
    let correct = one_to_one
        .iter()
        .filter(|(_, i, j)| match (a_in.get(*i), b_in.get(*j)) {
            (Some((_, p)), Some((_, q))) => (p[0] - q[0]).hypot(p[1] - q[1]) <= epsilon_px,
            _ => false,
        })
        .count();
    let (n_a, n_b) = (a_in.len(), b_in.len());
    MatchingScore {
        epsilon_px,
        n_a,
        n_b,
        matches: one_to_one.len(),
        correct,
        score: fraction(correct, n_a.min(n_b)),
    }
}

/// The thesis's Table 6.1 figures for one image pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchReport {
    /// Model fitted by RANSAC.
    pub model: ModelKind,
    /// Inlier threshold used, px.
    pub threshold_px: f64,
    /// Keypoints in A (the real frame).
    pub keypoints_a: usize,
    /// Keypoints in B (the render).
    pub keypoints_b: usize,
    /// Descriptor matches (ratio test, optional cross check).
    pub matches: usize,
    /// Matches consistent with the fitted model.
    pub inliers: usize,
    /// `inliers / matches` (0 without matches).
    pub inlier_ratio: f64,
    /// RANSAC hypotheses evaluated.
    pub iterations: usize,
}

/// Matches described keypoints of A and B and verifies the matches with RANSAC. Degenerate
/// input (no keypoints, fewer than [`super::ransac::MIN_MATCHES`] matches, collinear points)
/// gives zero inliers and iterations, never a panic.
pub fn match_and_verify(
    ka: &[Keypoint],
    da: &[Vec<f32>],
    kb: &[Keypoint],
    db: &[Vec<f32>],
    matching: &MatchParams,
    geometry: &RansacParams,
) -> MatchReport {
    verify_matches(ka, kb, &match_descriptors(da, db, matching), geometry)
}

/// Verifies already computed `matches` between keypoints `ka` and `kb` with RANSAC (the second
/// half of [`match_and_verify`], for callers that also need the matches themselves).
pub fn verify_matches(
    ka: &[Keypoint],
    kb: &[Keypoint],
    matches: &[Match],
    geometry: &RansacParams,
) -> MatchReport {
    let (pa, pb): (Vec<[f64; 2]>, Vec<[f64; 2]>) = matches
        .iter()
        .filter_map(|m| {
            let (p, q) = (ka.get(m.a)?, kb.get(m.b)?);
            Some((
                [f64::from(p.x), f64::from(p.y)],
                [f64::from(q.x), f64::from(q.y)],
            ))
        })
        .unzip();
    let fit = ransac(&pa, &pb, geometry);
    let inliers = fit.inlier_count();
    MatchReport {
        model: geometry.model,
        threshold_px: geometry.threshold_px,
        keypoints_a: ka.len(),
        keypoints_b: kb.len(),
        matches: pa.len(),
        inliers,
        inlier_ratio: fraction(inliers, pa.len()),
        iterations: fit.iterations,
    }
}

/// SIFT on both images (detect + describe, `sift` parameters), ratio-test matching, and
/// RANSAC: the thesis's Table 6.1 for one real frame and its render.
pub fn sift_ransac(
    real: &GreyF32,
    render: &GreyF32,
    sift: &SiftParams,
    matching: &MatchParams,
    geometry: &RansacParams,
) -> MatchReport {
    let (ka, da) = detect_and_describe_sift(real, sift);
    let (kb, db) = detect_and_describe_sift(render, sift);
    match_and_verify(&ka, &da, &kb, &db, matching, geometry)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ties_go_to_the_lower_index() {
        let a = vec![vec![0.0, 0.0]];
        let b = vec![vec![5.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0]];
        // b1 and b2 tie: the ratio test rejects the ambiguous match either way...
        assert!(match_descriptors(&a, &b, &MatchParams::default()).is_empty());
        // ...and with the ratio test off the lower index wins.
        let off = MatchParams {
            ratio: 2.0,
            mutual: false,
        };
        let m = match_descriptors(&a, &b, &off);
        assert_eq!((m[0].a, m[0].b, m[0].distance), (0, 1, 1.0));
    }

    #[test]
    fn mismatched_lengths_never_match() {
        let a = vec![vec![0.0, 0.0]];
        let b = vec![vec![0.0, 0.0, 0.0]];
        assert!(match_descriptors(&a, &b, &MatchParams::default()).is_empty());
    }
}
