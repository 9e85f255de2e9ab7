//! Cross-scan radiometric calibration of the laser reflectance (part of `merge.clean`).
//!
//! Why: a laser texture is stitched from several scans, and a cell of it holds whichever scans'
//! points fall there. If the instrument's reflectance drifts with range (its amplitude
//! calibration is never exact: a few hundredths of a dB per metre) or a scan session is offset,
//! the same ground comes out darker from a far station than from a near one: the texture shows
//! steps along the lines where one station's points take over from another's, and speckle
//! where their points interleave. A camera sees neither, so a renderer paints them into every
//! image, and the validator's gap workflow would mistake them for a camera effect.
//!
//! Model, in dB, for point `p` of scan `s` at range `r = |p − o_s|` from the scan's origin:
//! `L = 10·log10(albedo) = L_true(p) + a·r + c_s + noise`, with one range slope `a` (dB/m) for
//! the instrument and one offset `c_s` per scan, `Σ c_s = 0` (overlaps do not see the absolute
//! level; it stays the instrument's). Overlaps identify the rest: in a ground cell (side
//! [`CELL_M`]) seen by scans `i` and `j`, the difference of their mean `L` is
//! `a·(r̄_i − r̄_j) + c_i − c_j` plus noise, whatever the cell's true albedo. Every pair of scans
//! in every cell with at least [`MIN_POINTS`] points of each is one observation of a linear
//! least-squares problem, solved twice more without the pairs beyond 3 robust standard
//! deviations (pebbles seen from opposite sides, misregistered edges). Only points whose
//! incidence correction is trustworthy take part (`cos i ≥` [`MIN_COS_FIT`]): at grazing
//! incidence the correction's own error grows with range and would pass for a slope. The slope
//! is kept only when the overlaps determine it to [`MAX_SLOPE_STD_ERR_DB_PER_M`]; otherwise the
//! scans get offsets only, and the report says so. The correction divides every value by
//! `10^((a·r + c_s)/10)`, unless the fit is implausible for an instrument (a slope beyond
//! [`MAX_SLOPE_DB_PER_M`] or an offset beyond [`MAX_OFFSET_DB`]): then the scans disagree for
//! another reason, the values are left alone and `merge.clean` warns.
//!
//! Measured on the full-resolution estec corpus (6 stations, 18.7 M points, simulated slope
//! −0.05 dB/m, no offsets): slope −0.060 dB/m, offsets within ±0.02 dB, pair disagreement
//! 0.30 → 0.25 dB RMS. On the 2 × 2 m `mini` patch (two stations at similar ranges) the slope's
//! standard error is ~0.04 dB/m, so only offsets are fitted.
//!
//! Determinism: cells are binned with [`bin_sums`] and visited in key order, so the result does
//! not depend on the thread count.

use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::geometry::bin_sums;

/// Side of the ground cells in which scans are compared, metres.
pub const CELL_M: f64 = 0.03;
/// Points a scan needs in a cell for the cell to count for it.
pub const MIN_POINTS: u32 = 2;
/// Pairs needed per unknown for a fit.
const MIN_PAIRS_PER_UNKNOWN: usize = 50;
/// Largest standard error of a fitted range slope, dB/m: a survey whose overlaps determine the
/// slope worse than this (a small patch seen from similar ranges) gets offsets only, since a
/// poorly determined slope soaks up any range-correlated error of the incidence correction.
pub const MAX_SLOPE_STD_ERR_DB_PER_M: f64 = 0.01;
/// Largest range slope applied, dB/m (instruments drift by hundredths of a dB per metre).
pub const MAX_SLOPE_DB_PER_M: f64 = 0.2;
/// Largest per-scan offset applied, dB.
pub const MAX_OFFSET_DB: f64 = 1.5;
/// Smallest `cos i` of a point the fit uses: at grazing incidence the incidence correction is
/// unreliable (a few degrees of normal error swing `1 / cos i`), and such points are the far
/// ones, so they would pass their error off as a range slope.
pub const MIN_COS_FIT: f32 = 0.3;

/// The fitted calibration and how well the scans agree before and after it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RadiometricCalibration {
    /// Range slope `a` of the reflectance error, dB per metre (0 when not identifiable).
    pub range_slope_db_per_m: f64,
    /// Its standard error, dB per metre.
    pub range_slope_std_err_db_per_m: f64,
    /// Whether the overlaps determined the slope well enough to fit it.
    pub slope_fitted: bool,
    /// Whether the calibration is plausible for an instrument (|slope| ≤
    /// [`MAX_SLOPE_DB_PER_M`], every |offset| ≤ [`MAX_OFFSET_DB`]) and so was applied; scans that
    /// disagree beyond that disagree for another reason (reflectance that is not `albedo · cos i`,
    /// a misregistration), which this model must not paper over.
    pub applied: bool,
    /// Standard deviation of the range differences of the pairs, metres.
    pub range_difference_spread_m: f64,
    /// Offset `c_s` of each scan, dB, in scan order (sum zero).
    pub scan_offsets_db: Vec<ScanOffset>,
    /// Cells seen by at least two scans.
    pub cells: usize,
    /// Scan pairs used in the final fit.
    pub pairs: usize,
    /// Pairs left out as outliers.
    pub rejected_pairs: usize,
    /// RMS of the pair differences before the calibration (kept pairs), dB.
    pub disagreement_before_db: f64,
    /// RMS of the pair residuals after it, dB.
    pub disagreement_after_db: f64,
}

/// One scan's offset.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScanOffset {
    /// Scan name.
    pub scan: String,
    /// Offset `c_s`, dB.
    pub offset_db: f64,
}

/// Why no calibration was fitted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NotFitted {
    /// Fewer than two scans.
    OneScan,
    /// Too few overlapping cells for the unknowns.
    TooFewPairs {
        /// Pairs found.
        pairs: usize,
        /// Pairs needed.
        needed: usize,
    },
}

impl std::fmt::Display for NotFitted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotFitted::OneScan => write!(f, "one scan: nothing to compare"),
            NotFitted::TooFewPairs { pairs, needed } => write!(
                f,
                "{pairs} overlapping scan pairs in {CELL_M} m cells, expected at least {needed}"
            ),
        }
    }
}

/// Per (cell, scan) sums.
#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    sum_l: f64,
    sum_r: f64,
    n: u32,
}

impl std::ops::AddAssign for Acc {
    fn add_assign(&mut self, o: Acc) {
        self.sum_l += o.sum_l;
        self.sum_r += o.sum_r;
        self.n += o.n;
    }
}

/// One pair observation: `y = a·dr + c_i − c_j`.
#[derive(Debug, Clone, Copy)]
struct Pair {
    i: usize,
    j: usize,
    dr: f64,
    y: f64,
}

/// Fits the calibration from the points, their scan index, their albedo (linear, > 0 to
/// count) and the scans' origins (indexed by scan); `names` names the scans.
pub fn fit(
    points: &[[f64; 3]],
    scan: &[u32],
    albedo: &[f32],
    rho: &[f32],
    origins: &[Vector3<f64>],
    names: &[String],
) -> Result<RadiometricCalibration, NotFitted> {
    let n_scans = origins.len();
    if n_scans < 2 {
        return Err(NotFitted::OneScan);
    }
    let (pairs, cells_seen) = pairs(&cells(points, scan, albedo, rho, origins), n_scans);
    let needed = MIN_PAIRS_PER_UNKNOWN * (n_scans + 1);
    if pairs.len() < needed {
        return Err(NotFitted::TooFewPairs {
            pairs: pairs.len(),
            needed,
        });
    }
    let (_, sd_dr) = super::geometry::mean_std(&pairs.iter().map(|p| p.dr).collect::<Vec<_>>());
    let total = pairs.len();
    let (mut sol, mut kept) = robust_solve(pairs.clone(), n_scans, true, needed);
    let slope_fitted = sol.slope_std_err <= MAX_SLOPE_STD_ERR_DB_PER_M;
    if !slope_fitted {
        (sol, kept) = robust_solve(pairs, n_scans, false, needed);
    }
    let pairs = kept;
    let rms = |f: &dyn Fn(&Pair) -> f64| {
        (pairs.iter().map(|p| f(p).powi(2)).sum::<f64>() / pairs.len() as f64).sqrt()
    };
    let before = rms(&|p| p.y);
    let after = rms(&|p| residual(p, &sol.theta, slope_fitted));
    let offset = |s: usize| sol.theta.get(1 + s).copied().unwrap_or(0.0);
    let slope = if slope_fitted { sol.theta[0] } else { 0.0 };
    let applied =
        slope.abs() <= MAX_SLOPE_DB_PER_M && (0..n_scans).all(|s| offset(s).abs() <= MAX_OFFSET_DB);
    Ok(RadiometricCalibration {
        range_slope_db_per_m: slope,
        range_slope_std_err_db_per_m: if slope_fitted { sol.slope_std_err } else { 0.0 },
        slope_fitted,
        applied,
        range_difference_spread_m: sd_dr,
        scan_offsets_db: (0..n_scans)
            .map(|s| ScanOffset {
                scan: names.get(s).cloned().unwrap_or_else(|| format!("scan {s}")),
                offset_db: offset(s),
            })
            .collect(),
        cells: cells_seen,
        pairs: pairs.len(),
        rejected_pairs: total - pairs.len(),
        disagreement_before_db: before,
        disagreement_after_db: after,
    })
}

/// Divides every value by `10^((a·r + c_s)/10)` (`r` the point's range from its scan's origin);
/// nothing when the calibration is not [`applied`](RadiometricCalibration::applied).
pub fn apply(
    cal: &RadiometricCalibration,
    points: &[[f64; 3]],
    scan: &[u32],
    origins: &[Vector3<f64>],
    values: &mut [f32],
) {
    if !cal.applied {
        return;
    }
    let a = cal.range_slope_db_per_m;
    values
        .par_iter_mut()
        .zip(points.par_iter().zip(scan.par_iter()))
        .for_each(|(v, (p, &s))| {
            let (Some(o), Some(c)) = (origins.get(s as usize), cal.scan_offsets_db.get(s as usize))
            else {
                return;
            };
            let r = (Vector3::from(*p) - o).norm();
            *v = (f64::from(*v) * 10f64.powf(-(a * r + c.offset_db) / 10.0)) as f32;
        });
}

/// `(cell key, scan) → sums` of the points whose incidence is reliable, sorted by key then
/// scan.
fn cells(
    points: &[[f64; 3]],
    scan: &[u32],
    albedo: &[f32],
    rho: &[f32],
    origins: &[Vector3<f64>],
) -> Vec<((i64, i64), u32, Acc)> {
    let sums = bin_sums(points.len(), |i| {
        let (p, &s, &v, &r) = (points.get(i)?, scan.get(i)?, albedo.get(i)?, rho.get(i)?);
        let o = origins.get(s as usize)?;
        // `ρ / albedo` is the cos i the incidence correction used.
        if !(v > 0.0 && v.is_finite() && r >= MIN_COS_FIT * v) {
            return None;
        }
        let key = (
            (p[0] / CELL_M).floor() as i64,
            (p[1] / CELL_M).floor() as i64,
        );
        Some((
            (key, s),
            Acc {
                sum_l: 10.0 * f64::from(v).log10(),
                sum_r: (Vector3::from(*p) - o).norm(),
                n: 1,
            },
        ))
    });
    let mut out: Vec<((i64, i64), u32, Acc)> =
        sums.into_iter().map(|((c, s), a)| (c, s, a)).collect();
    out.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
    out
}

/// Pair observations of every cell seen by two scans or more, and the number of such cells.
fn pairs(cells: &[((i64, i64), u32, Acc)], n_scans: usize) -> (Vec<Pair>, usize) {
    let mut out = Vec::new();
    let mut seen = 0;
    let usable: Vec<&((i64, i64), u32, Acc)> = cells
        .iter()
        .filter(|c| c.2.n >= MIN_POINTS && (c.1 as usize) < n_scans)
        .collect();
    for group in usable.chunk_by(|a, b| a.0 == b.0) {
        if group.len() < 2 {
            continue;
        }
        seen += 1;
        let mean = |a: &Acc| (a.sum_l / f64::from(a.n), a.sum_r / f64::from(a.n));
        for (x, ci) in group.iter().enumerate() {
            for cj in group.iter().skip(x + 1) {
                let (li, ri) = mean(&ci.2);
                let (lj, rj) = mean(&cj.2);
                out.push(Pair {
                    i: ci.1 as usize,
                    j: cj.1 as usize,
                    dr: ri - rj,
                    y: li - lj,
                });
            }
        }
    }
    (out, seen)
}

/// [`solve`], then twice more without the pairs beyond 3 robust standard deviations (never
/// below `needed` pairs); returns the solution and the pairs it kept.
fn robust_solve(
    mut pairs: Vec<Pair>,
    n_scans: usize,
    slope: bool,
    needed: usize,
) -> (Solution, Vec<Pair>) {
    let mut sol = solve(&pairs, n_scans, slope);
    for _ in 0..2 {
        let res: Vec<f64> = pairs
            .iter()
            .map(|p| residual(p, &sol.theta, slope))
            .collect();
        let limit = 3.0 * 1.4826 * median_abs(&res);
        if limit.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        let kept: Vec<Pair> = pairs
            .iter()
            .zip(&res)
            .filter(|(_, r)| r.abs() <= limit)
            .map(|(p, _)| *p)
            .collect();
        if kept.len() < needed || kept.len() == pairs.len() {
            break;
        }
        pairs = kept;
        sol = solve(&pairs, n_scans, slope);
    }
    (sol, pairs)
}

/// A least-squares solution: `theta = [a, c_0, …]` and the slope's standard error.
struct Solution {
    theta: Vec<f64>,
    slope_std_err: f64,
}

/// `y − (a·dr + c_i − c_j)`.
fn residual(p: &Pair, theta: &[f64], slope: bool) -> f64 {
    let a = if slope { theta[0] } else { 0.0 };
    p.y - (a * p.dr + theta[1 + p.i] - theta[1 + p.j])
}

/// Normal equations of the pairs with the constraint `Σ c = 0` (weight 1 row, exact since the
/// pair rows do not see the common level); without `slope` the slope column is pinned to 0.
fn solve(pairs: &[Pair], n_scans: usize, slope: bool) -> Solution {
    let n = 1 + n_scans;
    let mut ata = DMatrix::<f64>::zeros(n, n);
    let mut atb = DVector::<f64>::zeros(n);
    let mut add = |row: &[(usize, f64)], y: f64| {
        for &(a, va) in row {
            atb[a] += va * y;
            for &(b, vb) in row {
                ata[(a, b)] += va * vb;
            }
        }
    };
    for p in pairs {
        let dr = if slope { p.dr } else { 0.0 };
        add(&[(0, dr), (1 + p.i, 1.0), (1 + p.j, -1.0)], p.y);
    }
    let sum_row: Vec<(usize, f64)> = (0..n_scans).map(|s| (1 + s, 1.0)).collect();
    add(&sum_row, 0.0);
    if !slope {
        ata[(0, 0)] = 1.0;
    }
    let inv = ata.clone().try_inverse();
    let theta = inv
        .as_ref()
        .map(|m| (m * &atb).iter().copied().collect())
        .unwrap_or_else(|| vec![0.0; n]);
    let dof = pairs.len().saturating_sub(n).max(1) as f64;
    let sigma2 = pairs
        .iter()
        .map(|p| residual(p, &theta, slope).powi(2))
        .sum::<f64>()
        / dof;
    let slope_std_err = inv.map_or(f64::INFINITY, |m| (sigma2 * m[(0, 0)]).sqrt());
    Solution {
        theta,
        slope_std_err,
    }
}

/// Median of `|v|`.
fn median_abs(v: &[f64]) -> f64 {
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    if a.is_empty() {
        return 0.0;
    }
    let mid = a.len() / 2;
    a.select_nth_unstable_by(mid, f64::total_cmp);
    a[mid]
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Points, their scan, their albedo and the scans' origins.
    type Survey = (Vec<[f64; 3]>, Vec<u32>, Vec<f32>, Vec<Vector3<f64>>);

    /// Three stations around a 4 m square of ground with a patchy albedo; each sees all of it.
    fn survey(slope: f64, offsets: &[f64], noise_db: f64) -> Survey {
        let origins = vec![
            Vector3::new(-1.0, -1.0, 1.5),
            Vector3::new(5.0, 0.5, 1.5),
            Vector3::new(2.0, 6.0, 1.5),
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (mut p, mut s, mut v) = (Vec::new(), Vec::new(), Vec::new());
        for (si, o) in origins.iter().enumerate() {
            for _ in 0..60_000 {
                let q = [rng.gen::<f64>() * 4.0, rng.gen::<f64>() * 4.0, 0.0];
                let truth = 0.2 + 0.15 * ((q[0] * 3.0).sin() * (q[1] * 2.0).cos());
                let r = (Vector3::from(q) - o).norm();
                let noise = (rng.gen::<f64>() - 0.5) * 2.0 * noise_db;
                let db = 10.0 * truth.log10() + slope * r + offsets[si] + noise;
                p.push(q);
                s.push(si as u32);
                v.push(10f64.powf(db / 10.0) as f32);
            }
        }
        (p, s, v, origins)
    }

    fn names() -> Vec<String> {
        ["a", "b", "c"].map(String::from).to_vec()
    }

    #[test]
    fn recovers_a_range_slope_and_scan_offsets() {
        let (p, s, v, o) = survey(-0.05, &[0.3, -0.1, -0.2], 0.3);
        let cal = fit(&p, &s, &v, &v, &o, &names()).unwrap();
        assert!(cal.slope_fitted && cal.applied);
        assert!((cal.range_slope_db_per_m + 0.05).abs() < 0.005, "{cal:?}");
        for (got, want) in cal.scan_offsets_db.iter().zip([0.3, -0.1, -0.2]) {
            assert!((got.offset_db - want).abs() < 0.03, "{cal:?}");
        }
        assert!(
            cal.disagreement_after_db < 0.6 * cal.disagreement_before_db,
            "{cal:?}"
        );
        assert!(cal.range_slope_std_err_db_per_m < 0.005);
        // Applying it makes the scans agree: refitting finds nothing left.
        let mut w = v.clone();
        apply(&cal, &p, &s, &o, &mut w);
        let again = fit(&p, &s, &w, &w, &o, &names()).unwrap();
        assert!(again.range_slope_db_per_m.abs() < 0.003, "{again:?}");
        assert!(again
            .scan_offsets_db
            .iter()
            .all(|c| c.offset_db.abs() < 0.02));
    }

    #[test]
    fn an_implausible_calibration_is_reported_but_not_applied() {
        let (p, s, v, o) = survey(-0.5, &[2.0, -1.0, -1.0], 0.3);
        let cal = fit(&p, &s, &v, &v, &o, &names()).unwrap();
        assert!(
            (cal.range_slope_db_per_m + 0.5).abs() < 0.01 && !cal.applied,
            "{cal:?}"
        );
        let mut w = v.clone();
        apply(&cal, &p, &s, &o, &mut w);
        assert_eq!(w, v);
    }

    #[test]
    fn consistent_scans_get_no_correction() {
        let (p, s, v, o) = survey(0.0, &[0.0, 0.0, 0.0], 0.3);
        let cal = fit(&p, &s, &v, &v, &o, &names()).unwrap();
        assert!(cal.range_slope_db_per_m.abs() < 0.005, "{cal:?}");
        assert!(cal.scan_offsets_db.iter().all(|c| c.offset_db.abs() < 0.03));
    }

    #[test]
    fn one_scan_or_no_overlap_is_not_fitted() {
        let (p, s, v, o) = survey(-0.05, &[0.0, 0.0, 0.0], 0.3);
        let n = 60_000;
        assert_eq!(
            fit(&p[..n], &s[..n], &v[..n], &v[..n], &o[..1], &names()),
            Err(NotFitted::OneScan)
        );
        // Two scans on disjoint ground: no cell holds both.
        let mut q = p[..2 * n].to_vec();
        for x in &mut q[n..] {
            x[0] += 10.0;
        }
        assert!(matches!(
            fit(&q, &s[..2 * n], &v[..2 * n], &v[..2 * n], &o[..2], &names()),
            Err(NotFitted::TooFewPairs { pairs: 0, .. })
        ));
    }

    #[test]
    fn thread_count_does_not_change_the_fit() {
        let (p, s, v, o) = survey(-0.03, &[0.1, 0.0, -0.1], 0.5);
        let run = |t: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .unwrap()
                .install(|| fit(&p, &s, &v, &v, &o, &names()).unwrap())
        };
        assert_eq!(run(1), run(3));
    }
}
