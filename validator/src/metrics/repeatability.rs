//! Keypoint repeatability between two images of the same scene (Mikolajczyk & Schmid 2005).
//!
//! Keypoints of image A are mapped into image B by a caller-supplied function (identity when both
//! were taken from the same pose; through the rendered depth otherwise). Only points that fall in
//! the region both images see count. Points are paired one-to-one, greedily by increasing
//! distance, so one keypoint is never credited twice; a pair within ε pixels is a repeat.
//! Repeatability = repeats / min(n_A, n_B) over the common region.
//!
//! Both that score and the thesis's one-directional ratio (repeats / n_A) grow with B's keypoint
//! density by chance alone: a render covered in speckle corners "re-detects" many real corners
//! that it does not see. [`Repeatability::excess`] removes the chance part, taking B's keypoints as
//! spread uniformly over the common region: an A keypoint finds one within ε by chance with
//! probability `p = 1 − exp(−n_B π ε² / area)`, and `excess = (one_directional − p) / (1 − p)`
//! (Cohen's kappa form: 0 = no better than chance, 1 = every A keypoint re-detected). It neither
//! rewards a render with few keypoints (as min(n) does) nor one with many.

use serde::{Deserialize, Serialize};

/// The figures of one comparison at one ε.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Repeatability {
    /// Tolerance in pixels.
    pub epsilon_px: f64,
    /// Keypoints of A inside the common region (after mapping).
    pub n_a: usize,
    /// Keypoints of B inside the common region.
    pub n_b: usize,
    /// One-to-one pairs within ε.
    pub repeated: usize,
    /// `repeated / min(n_a, n_b)` (0 when either is empty).
    pub score: f64,
    /// `repeated / n_a`: the thesis's one-directional ratio (A re-detected in B).
    pub one_directional: f64,
    /// Probability that an A keypoint has a B keypoint within ε by chance, B's keypoints spread
    /// uniformly over the common region: `1 − exp(−n_b π ε² / area)`.
    pub chance: f64,
    /// The one-directional ratio with chance repeats removed: `(one_directional − chance) /
    /// (1 − chance)`; 0 when A is empty or chance is 1. Negative when below chance.
    pub excess: f64,
}

/// The chance probability `1 − exp(−n_b π ε² / area)` of [`Repeatability::chance`] (0 for an
/// empty region).
pub fn chance_probability(n_b: usize, epsilon_px: f64, area_px: f64) -> f64 {
    if area_px <= 0.0 {
        return 0.0;
    }
    1.0 - (-(n_b as f64) * std::f64::consts::PI * epsilon_px * epsilon_px / area_px).exp()
}

/// `(one_directional − chance) / (1 − chance)`, 0 when `n_a` is 0 or chance is (numerically) 1.
pub fn excess_over_chance(one_directional: f64, chance: f64, n_a: usize) -> f64 {
    if n_a == 0 || chance >= 1.0 - 1e-12 {
        0.0
    } else {
        (one_directional - chance) / (1.0 - chance)
    }
}

/// Pairs points one-to-one greedily by distance, returning `(distance, index in a, index in b)`
/// sorted by distance.
fn greedy_pairs(a: &[[f64; 2]], b: &[[f64; 2]], max_dist: f64) -> Vec<(f64, usize, usize)> {
    // Candidate pairs within max_dist, via a uniform grid over B.
    let cell = max_dist.max(1e-9);
    let mut grid: std::collections::BTreeMap<(i64, i64), Vec<usize>> =
        std::collections::BTreeMap::new();
    for (j, p) in b.iter().enumerate() {
        grid.entry(((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64))
            .or_default()
            .push(j);
    }
    let mut cand: Vec<(f64, usize, usize)> = Vec::new();
    for (i, p) in a.iter().enumerate() {
        let (cx, cy) = ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for &j in grid
                    .get(&(cx + dx, cy + dy))
                    .map(Vec::as_slice)
                    .unwrap_or(&[])
                {
                    let d = (p[0] - b[j][0]).hypot(p[1] - b[j][1]);
                    if d <= max_dist {
                        cand.push((d, i, j));
                    }
                }
            }
        }
    }
    greedy_one_to_one(cand, a.len(), b.len())
}

/// One-to-one greedy bipartite matching: candidates `(cost, index in a, index in b)` are taken
/// in increasing cost (ties by `i`, then `j`), each skipped if either side is already used.
/// Returns the kept candidates in that order. Indices `≥ n_a` / `≥ n_b` are ignored.
///
/// Shared by point repeatability (cost = distance), the matching score (cost = descriptor
/// distance) and region repeatability (cost = overlap error), so all three pair the same way.
pub(super) fn greedy_one_to_one(
    mut cand: Vec<(f64, usize, usize)>,
    n_a: usize,
    n_b: usize,
) -> Vec<(f64, usize, usize)> {
    cand.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let (mut used_a, mut used_b) = (vec![false; n_a], vec![false; n_b]);
    let mut out = Vec::new();
    for (d, i, j) in cand {
        if let (Some(ua), Some(ub)) = (used_a.get_mut(i), used_b.get_mut(j)) {
            if !*ua && !*ub {
                *ua = true;
                *ub = true;
                out.push((d, i, j));
            }
        }
    }
    out
}

/// `num / den`, or 0 when `den` is 0: every score here is a count over a count that may be empty.
pub(super) fn fraction(num: usize, den: usize) -> f64 {
    if den == 0 {
        0.0
    } else {
        num as f64 / den as f64
    }
}

/// Repeatability of `a` (mapped by `map_a_to_b`, `None` = not visible in B) against `b`, at
/// every ε of `epsilons`. `in_common(x, y)` says whether a B pixel is seen by both images, and
/// `area_px` is the size of that common region in B pixels (for the chance correction).
pub fn repeatability(
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    map_a_to_b: impl Fn([f64; 2]) -> Option<[f64; 2]>,
    in_common: impl Fn([f64; 2]) -> bool,
    area_px: f64,
    epsilons: &[f64],
) -> Vec<Repeatability> {
    let (a_mapped, b_in) = common_points(a, b, map_a_to_b, in_common);
    let a_mapped: Vec<[f64; 2]> = a_mapped.into_iter().map(|(_, p)| p).collect();
    let b_in: Vec<[f64; 2]> = b_in.into_iter().map(|(_, p)| p).collect();
    let max_eps = epsilons.iter().copied().fold(0.0, f64::max);
    let pairs = greedy_pairs(&a_mapped, &b_in, max_eps);
    epsilons
        .iter()
        .map(|&eps| {
            // Greedy pairing is redone per ε so a pair beyond ε cannot block a closer one.
            let repeated = if (eps - max_eps).abs() < 1e-12 {
                pairs.len()
            } else {
                greedy_pairs(&a_mapped, &b_in, eps).len()
            };
            let (n_a, n_b) = (a_mapped.len(), b_in.len());
            let one_directional = fraction(repeated, n_a);
            let chance = chance_probability(n_b, eps, area_px);
            Repeatability {
                epsilon_px: eps,
                n_a,
                n_b,
                repeated,
                score: fraction(repeated, n_a.min(n_b)),
                one_directional,
                chance,
                excess: excess_over_chance(one_directional, chance, n_a),
            }
        })
        .collect()
}

/// The features of `a` (mapped into B) and of `b` that lie in the common region, each with its
/// index in the input. Generic over the feature (a point here, an ellipse for region
/// repeatability) so every metric applies the mapping and the common region the same way.
#[allow(clippy::type_complexity)]
pub(super) fn common_points<P: Copy>(
    a: &[P],
    b: &[P],
    map_a_to_b: impl Fn(P) -> Option<P>,
    in_common: impl Fn(P) -> bool,
) -> (Vec<(usize, P)>, Vec<(usize, P)>) {
    let a_mapped = a
        .iter()
        .enumerate()
        .filter_map(|(i, p)| Some((i, map_a_to_b(*p)?)))
        .filter(|(_, p)| in_common(*p))
        .collect();
    let b_in = b
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, p)| in_common(*p))
        .collect();
    (a_mapped, b_in)
}

/// The repeated pairs behind [`repeatability`] at one ε: `(index in a, index in b)` of each
/// one-to-one pair within ε, by increasing distance (for drawing which keypoints repeated; the
/// count equals [`Repeatability::repeated`] at that ε).
pub fn repeated_pairs(
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    map_a_to_b: impl Fn([f64; 2]) -> Option<[f64; 2]>,
    in_common: impl Fn([f64; 2]) -> bool,
    epsilon_px: f64,
) -> Vec<(usize, usize)> {
    let (a_in, b_in) = common_points(a, b, map_a_to_b, in_common);
    let pa: Vec<[f64; 2]> = a_in.iter().map(|(_, p)| *p).collect();
    let pb: Vec<[f64; 2]> = b_in.iter().map(|(_, p)| *p).collect();
    greedy_pairs(&pa, &pb, epsilon_px)
        .into_iter()
        .map(|(_, i, j)| (a_in[i].0, b_in[j].0))
        .collect()
}

/// The default ε curve: 1, 1.5, 2, 3, 4, 5 px (1.5 px is the certified value).
pub const EPSILONS: [f64; 6] = [1.0, 1.5, 2.0, 3.0, 4.0, 5.0];

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixed test vector: 4 points in A, 5 in B, at known distances.
    const FIXED_A: [[f64; 2]; 4] = [[10.0, 10.0], [20.0, 20.0], [30.0, 30.0], [40.0, 40.0]];
    const FIXED_B: [[f64; 2]; 5] = [
        [10.5, 10.0],
        [21.2, 20.0],
        [30.0, 33.0],
        [100.0, 100.0],
        [10.0, 11.0],
    ];

    /// Fixed test vector: 4 points in A, 5 in B; known distances.
    #[test]
    fn fixed_vector() {
        let (a, b) = (FIXED_A, FIXED_B);
        let r = repeatability(&a, &b, Some, |_| true, 200.0 * 200.0, &EPSILONS);
        let at = |e: f64| r.iter().find(|x| (x.epsilon_px - e).abs() < 1e-9).unwrap();
        // ε = 1: only (10,10)-(10.5,10); the (10,11) point is the second-closest to the same A.
        assert_eq!(at(1.0).repeated, 1);
        assert_eq!(at(1.5).repeated, 2);
        assert_eq!(at(3.0).repeated, 3);
        assert_eq!(at(5.0).n_a, 4);
        assert_eq!(at(5.0).n_b, 5);
        assert!((at(1.5).score - 2.0 / 4.0).abs() < 1e-12);
        assert!((at(3.0).one_directional - 3.0 / 4.0).abs() < 1e-12);
        // The pairs behind the counts, in input indices.
        assert_eq!(
            repeated_pairs(&a, &b, Some, |_| true, 1.5),
            vec![(0, 0), (1, 1)]
        );
        assert_eq!(repeated_pairs(&a, &b, Some, |_| true, 3.0).len(), 3);
    }

    #[test]
    fn common_region_and_mapping() {
        let a = [[10.0, 10.0], [200.0, 10.0]];
        let b = [[12.0, 10.0], [202.0, 10.0]];
        // A shifted by +2 px in B; only x < 100 is common.
        let r = repeatability(
            &a,
            &b,
            |p| Some([p[0] + 2.0, p[1]]),
            |p| p[0] < 100.0,
            100.0 * 20.0,
            &[1.0],
        );
        assert_eq!((r[0].n_a, r[0].n_b, r[0].repeated), (1, 1, 1));
        assert_eq!(r[0].score, 1.0);
        let pairs = repeated_pairs(&a, &b, |p| Some([p[0] + 2.0, p[1]]), |p| p[0] < 100.0, 1.0);
        assert_eq!(pairs, vec![(0, 0)]);
        let none = repeatability(&a, &[], Some, |_| true, 1e4, &[1.5]);
        assert_eq!(none[0].score, 0.0);
        assert_eq!((none[0].chance, none[0].excess), (0.0, 0.0));
    }

    /// Fixed test vector for the chance correction: the fixed vector's 5 B points in a region of
    /// `5 π 1.5² / ln 2` px make a chance repeat exactly as likely as not, so its one-directional
    /// ratio 2/4 at ε = 1.5 is no better than chance.
    #[test]
    fn chance_correction_fixed_vector() {
        let (a, b) = (FIXED_A, FIXED_B);
        let area = 5.0 * std::f64::consts::PI * 2.25 / std::f64::consts::LN_2;
        let r = repeatability(&a, &b, Some, |_| true, area, &[1.5, 3.0]);
        assert!((r[0].chance - 0.5).abs() < 1e-12, "{}", r[0].chance);
        assert!(r[0].excess.abs() < 1e-12, "{}", r[0].excess);
        // ε = 3: chance 1 − 2^−4 = 0.9375, 3 of 4 repeated → (0.75 − 0.9375) / 0.0625 = −3.
        assert!((r[1].chance - 0.9375).abs() < 1e-12);
        assert!((r[1].excess + 3.0).abs() < 1e-9, "{}", r[1].excess);
    }

    /// Unrelated uniform point sets repeat only by chance: the one-directional ratio grows with
    /// B's density, the excess stays at 0; a B that contains A's points gets an excess near 1.
    #[test]
    fn unrelated_points_have_no_excess_at_any_density() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 1000.0
        };
        let a: Vec<[f64; 2]> = (0..3000).map(|_| [next(), next()]).collect();
        for n_b in [2000, 20_000, 60_000] {
            let b: Vec<[f64; 2]> = (0..n_b).map(|_| [next(), next()]).collect();
            let r = repeatability(&a, &b, Some, |_| true, 1e6, &[1.5])[0];
            assert!(
                r.excess.abs() < 0.03,
                "n_b {n_b}: one-directional {} chance {} excess {}",
                r.one_directional,
                r.chance,
                r.excess
            );
            let mut with_a = b.clone();
            with_a.extend(a.iter().map(|p| [p[0] + 0.3, p[1]]));
            let r = repeatability(&a, &with_a, Some, |_| true, 1e6, &[1.5])[0];
            assert!(r.excess > 0.97, "n_b {n_b}: excess {}", r.excess);
        }
    }
}
