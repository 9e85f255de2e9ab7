//! RANSAC estimation of the geometry between matched keypoints: a fundamental matrix
//! (normalised 8-point algorithm, rank 2 enforced, Sampson distance) or a homography
//! (normalised DLT, symmetric transfer error). The inlier ratio is the thesis's "valid RANSAC
//! inliers" figure (Table 6.1).
//!
//! Design decisions:
//! * **Deterministic.** Samples come from a `ChaCha8Rng` seeded by [`RansacParams::seed`].
//!   Hypotheses are drawn in fixed batches of [`BATCH`] samples, fitted and scored in parallel
//!   with an indexed rayon iterator, then consumed in draw order: the best model, the adaptive
//!   iteration count and the reported iterations are those of a sequential run, identical on
//!   any thread count.
//! * **Adaptive iteration count.** After each better hypothesis, the number of iterations
//!   needed for `confidence` (0.99) with the current inlier fraction `w` is
//!   `log(1 − p) / log(1 − wˢ)` (`s` = sample size), capped at `max_iterations` (2000).
//! * **Refit.** The best hypothesis is refitted by least squares on its inliers (same
//!   normalised linear algorithm) while that does not lose inliers (at most 3 rounds).
//! * **Degenerate input gives an empty fit, never a panic**: fewer than [`MIN_MATCHES`]
//!   correspondences, a non-finite coordinate, or all points of one image on a line.
//!   Linear algebra uses nalgebra's iteration-capped `try_*` decompositions.

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Fewer correspondences than this give an empty fit, for both models, so that a fit always
/// rests on more data than a minimal sample.
pub const MIN_MATCHES: usize = 8;
/// Hypotheses drawn, then fitted in parallel, per batch.
pub const BATCH: usize = 32;
/// Iteration cap of nalgebra's eigen/SVD solvers.
const MAX_SOLVER_ITERS: usize = 1000;

/// The geometric model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// Fundamental matrix `F`, `x_bᵀ F x_a = 0` (general scene, two poses).
    Fundamental,
    /// Homography `H`, `x_b ~ H x_a` (planar scene, pure rotation, or the same pose).
    Homography,
}

impl ModelKind {
    /// Points per minimal sample: 8 (8-point algorithm) or 4.
    pub fn sample_size(self) -> usize {
        match self {
            ModelKind::Fundamental => 8,
            ModelKind::Homography => 4,
        }
    }
}

/// RANSAC parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RansacParams {
    /// Model to fit.
    pub model: ModelKind,
    /// Inlier threshold, px: on the Sampson distance for `F` (default 1 px), on the RMS of
    /// the two transfer distances for `H` (default 3 px).
    pub threshold_px: f64,
    /// Probability that at least one sample is outlier-free (0.99).
    pub confidence: f64,
    /// Iteration cap (2000).
    pub max_iterations: usize,
    /// RNG seed.
    pub seed: u64,
}

impl RansacParams {
    /// Fundamental matrix, 1 px Sampson threshold.
    pub fn fundamental() -> RansacParams {
        RansacParams {
            model: ModelKind::Fundamental,
            threshold_px: 1.0,
            confidence: 0.99,
            max_iterations: 2000,
            seed: 0x5EED_2012,
        }
    }

    /// Homography, 3 px symmetric transfer threshold.
    pub fn homography() -> RansacParams {
        RansacParams {
            model: ModelKind::Homography,
            threshold_px: 3.0,
            ..RansacParams::fundamental()
        }
    }
}

impl Default for RansacParams {
    fn default() -> Self {
        RansacParams::fundamental()
    }
}

/// The outcome of [`ransac`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RansacFit {
    /// Model kind.
    pub model: ModelKind,
    /// The fitted matrix (row-major; `F` with unit Frobenius norm, `H` with `H₃₃ = 1` when
    /// possible), or `None` for degenerate input.
    pub matrix: Option<[[f64; 3]; 3]>,
    /// One flag per correspondence.
    pub inliers: Vec<bool>,
    /// Hypotheses evaluated.
    pub iterations: usize,
}

impl RansacFit {
    /// Number of inliers.
    pub fn inlier_count(&self) -> usize {
        self.inliers.iter().filter(|v| **v).count()
    }

    fn empty(model: ModelKind, n: usize) -> RansacFit {
        RansacFit {
            model,
            matrix: None,
            inliers: vec![false; n],
            iterations: 0,
        }
    }
}

fn to_array(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

fn from_array(a: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| a[i][j])
}

/// Hartley normalisation of the selected points: centroid to the origin, mean distance √2.
fn normaliser<'a>(pts: impl Iterator<Item = &'a [f64; 2]> + Clone) -> Option<Matrix3<f64>> {
    let n = pts.clone().count() as f64;
    if n == 0.0 {
        return None;
    }
    let (sx, sy) = pts
        .clone()
        .fold((0.0, 0.0), |s, p| (s.0 + p[0], s.1 + p[1]));
    let (cx, cy) = (sx / n, sy / n);
    let mean = pts.map(|p| (p[0] - cx).hypot(p[1] - cy)).sum::<f64>() / n;
    if !(mean > 1e-12 && mean.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean;
    Some(Matrix3::new(
        s,
        0.0,
        -s * cx,
        0.0,
        s,
        -s * cy,
        0.0,
        0.0,
        1.0,
    ))
}

fn apply(t: &Matrix3<f64>, p: &[f64; 2]) -> [f64; 2] {
    [t[(0, 0)] * p[0] + t[(0, 2)], t[(1, 1)] * p[1] + t[(1, 2)]]
}

/// The unit vector minimising `‖A f‖` given `AᵀA`: the eigenvector of the smallest eigenvalue.
fn null_vector(ata: SMatrix<f64, 9, 9>) -> Option<[f64; 9]> {
    if !ata.iter().all(|v| v.is_finite()) {
        return None;
    }
    let eig = SymmetricEigen::try_new(ata, f64::EPSILON, MAX_SOLVER_ITERS)?;
    let k = eig.eigenvalues.imin();
    let v = eig.eigenvectors.column(k);
    let mut out = [0.0; 9];
    for (o, x) in out.iter_mut().zip(v.iter()) {
        *o = *x;
    }
    Some(out)
}

fn add_row(ata: &mut SMatrix<f64, 9, 9>, r: &[f64; 9]) {
    for i in 0..9 {
        for j in 0..9 {
            ata[(i, j)] += r[i] * r[j];
        }
    }
}

/// The normalised direct linear transform shared by F and H: Hartley-normalises both point sets
/// over `idx`, accumulates `AᵀA` from the rows `rows(p, q, ·)` adds for each normalised pair,
/// and returns the two normalising transforms and the unit null vector of `A`.
fn normalised_dlt(
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    idx: &[usize],
    rows: impl Fn([f64; 2], [f64; 2], &mut SMatrix<f64, 9, 9>),
) -> Option<(Matrix3<f64>, Matrix3<f64>, [f64; 9])> {
    let ta = normaliser(idx.iter().filter_map(|&i| a.get(i)))?;
    let tb = normaliser(idx.iter().filter_map(|&i| b.get(i)))?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for &i in idx {
        rows(apply(&ta, a.get(i)?), apply(&tb, b.get(i)?), &mut ata);
    }
    Some((ta, tb, null_vector(ata)?))
}

/// Least-squares fundamental matrix (normalised 8-point, rank 2) from the correspondences
/// `a[i] ↔ b[i]`, `i` in `idx` (at least 8), with `x_bᵀ F x_a = 0`.
pub fn fit_fundamental(a: &[[f64; 2]], b: &[[f64; 2]], idx: &[usize]) -> Option<[[f64; 3]; 3]> {
    if idx.len() < 8 {
        return None;
    }
    let (ta, tb, f) = normalised_dlt(a, b, idx, |[x, y], [u, v], ata| {
        add_row(ata, &[u * x, u * y, u, v * x, v * y, v, x, y, 1.0]);
    })?;
    let fh = Matrix3::new(f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8]);
    let svd = fh.try_svd(true, true, f64::EPSILON, MAX_SOLVER_ITERS)?;
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut sv = svd.singular_values;
    let k = sv.imin();
    sv[k] = 0.0;
    let f2 = u * Matrix3::from_diagonal(&sv) * vt;
    let f = tb.transpose() * f2 * ta;
    let norm = f.norm();
    (norm > 0.0 && norm.is_finite()).then(|| to_array(&(f / norm)))
}

/// Least-squares homography (normalised DLT) from the correspondences `a[i] ↔ b[i]`, `i` in
/// `idx` (at least 4), with `x_b ~ H x_a`.
pub fn fit_homography(a: &[[f64; 2]], b: &[[f64; 2]], idx: &[usize]) -> Option<[[f64; 3]; 3]> {
    if idx.len() < 4 {
        return None;
    }
    let (ta, tb, h) = normalised_dlt(a, b, idx, |[x, y], [u, v], ata| {
        add_row(ata, &[0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]);
        add_row(ata, &[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u]);
    })?;
    let hh = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let h = tb.try_inverse()? * hh * ta;
    let s = if h[(2, 2)].abs() > 1e-12 * h.norm() {
        h[(2, 2)]
    } else {
        h.norm()
    };
    let h = h / s;
    h.iter().all(|v| v.is_finite()).then(|| to_array(&h))
}

/// Sampson distance of `a ↔ b` to `F`, px (the first-order geometric error; `∞` when the
/// epipolar lines are undefined).
pub fn sampson_distance(f: &[[f64; 3]; 3], a: [f64; 2], b: [f64; 2]) -> f64 {
    sampson_sq(&from_array(f), a, b).sqrt()
}

fn sampson_sq(f: &Matrix3<f64>, a: [f64; 2], b: [f64; 2]) -> f64 {
    let (xa, xb) = (Vector3::new(a[0], a[1], 1.0), Vector3::new(b[0], b[1], 1.0));
    let fa = f * xa;
    let ftb = f.transpose() * xb;
    let e = xb.dot(&fa);
    let den = fa[0] * fa[0] + fa[1] * fa[1] + ftb[0] * ftb[0] + ftb[1] * ftb[1];
    if den > 0.0 {
        e * e / den
    } else {
        f64::INFINITY
    }
}

fn project(h: &Matrix3<f64>, p: [f64; 2]) -> Option<[f64; 2]> {
    let v = h * Vector3::new(p[0], p[1], 1.0);
    (v[2].abs() > 1e-300).then(|| [v[0] / v[2], v[1] / v[2]])
}

/// Squared symmetric transfer error `(‖b − H a‖² + ‖a − H⁻¹ b‖²) / 2`, px².
fn transfer_sq(h: &Matrix3<f64>, h_inv: &Matrix3<f64>, a: [f64; 2], b: [f64; 2]) -> f64 {
    match (project(h, a), project(h_inv, b)) {
        (Some(hb), Some(ha)) => {
            let df = (hb[0] - b[0]).powi(2) + (hb[1] - b[1]).powi(2);
            let db = (ha[0] - a[0]).powi(2) + (ha[1] - a[1]).powi(2);
            0.5 * (df + db)
        }
        _ => f64::INFINITY,
    }
}

/// Symmetric transfer error of `a ↔ b` under `H`, px: the RMS of the forward and backward
/// transfer distances (`∞` if `H` is singular).
pub fn transfer_error(h: &[[f64; 3]; 3], a: [f64; 2], b: [f64; 2]) -> f64 {
    let h = from_array(h);
    match h.try_inverse() {
        Some(hi) => transfer_sq(&h, &hi, a, b).sqrt(),
        None => f64::INFINITY,
    }
}

/// Inlier flags of every correspondence under a model.
fn inliers_of(
    model: ModelKind,
    m: &[[f64; 3]; 3],
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    thr: f64,
) -> Vec<bool> {
    let mm = from_array(m);
    let t2 = thr * thr;
    match model {
        ModelKind::Fundamental => a
            .iter()
            .zip(b)
            .map(|(p, q)| sampson_sq(&mm, *p, *q) <= t2)
            .collect(),
        ModelKind::Homography => match mm.try_inverse() {
            Some(hi) => a
                .iter()
                .zip(b)
                .map(|(p, q)| transfer_sq(&mm, &hi, *p, *q) <= t2)
                .collect(),
            None => vec![false; a.len()],
        },
    }
}

fn fit(model: ModelKind, a: &[[f64; 2]], b: &[[f64; 2]], idx: &[usize]) -> Option<[[f64; 3]; 3]> {
    match model {
        ModelKind::Fundamental => fit_fundamental(a, b, idx),
        ModelKind::Homography => fit_homography(a, b, idx),
    }
}

/// True when the points do not all lie on one line (nor on one point).
fn spread(pts: &[[f64; 2]]) -> bool {
    let n = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |s, p| (s.0 + p[0], s.1 + p[1]));
    let (cx, cy) = (sx / n, sy / n);
    let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] - cx, p[1] - cy);
        xx += dx * dx;
        xy += dx * dy;
        yy += dy * dy;
    }
    let half_trace = 0.5 * (xx + yy);
    let disc = (0.25 * (xx - yy) * (xx - yy) + xy * xy).sqrt();
    let (hi, lo) = (half_trace + disc, half_trace - disc);
    hi > 0.0 && lo > 1e-10 * hi
}

/// True when no three of the sample's points are (nearly) collinear in either image: a
/// homography from such a sample is degenerate.
fn sample_ok(model: ModelKind, a: &[[f64; 2]], b: &[[f64; 2]], idx: &[usize]) -> bool {
    if model != ModelKind::Homography {
        return true;
    }
    let collinear = |pts: &[[f64; 2]], i: usize, j: usize, k: usize| -> bool {
        let (Some(p), Some(q), Some(r)) = (pts.get(i), pts.get(j), pts.get(k)) else {
            return true;
        };
        let (ux, uy, vx, vy) = (q[0] - p[0], q[1] - p[1], r[0] - p[0], r[1] - p[1]);
        let cross = (ux * vy - uy * vx).abs();
        let scale = (ux * ux + uy * uy).max(vx * vx + vy * vy);
        cross <= 1e-9 * scale
    };
    for x in 0..idx.len() {
        for y in x + 1..idx.len() {
            for z in y + 1..idx.len() {
                let (i, j, k) = (idx[x], idx[y], idx[z]);
                if collinear(a, i, j, k) || collinear(b, i, j, k) {
                    return false;
                }
            }
        }
    }
    true
}

/// Iterations needed for `confidence` with inlier fraction `w` and sample size `s`, capped.
fn needed_iterations(confidence: f64, w: f64, s: usize, cap: usize) -> usize {
    let num = (1.0 - confidence).max(f64::MIN_POSITIVE).ln();
    let p_good = w.powi(s as i32);
    let den = (1.0 - p_good).max(0.0);
    if den <= f64::MIN_POSITIVE {
        return 0;
    }
    let den = den.ln();
    if den >= 0.0 || -num >= cap as f64 * -den {
        cap
    } else {
        ((num / den).ceil() as usize).min(cap)
    }
}

/// Robustly fits `p.model` to the correspondences `a[i] ↔ b[i]` (extra entries of the
/// longer slice are ignored). See the module docs.
pub fn ransac(a: &[[f64; 2]], b: &[[f64; 2]], p: &RansacParams) -> RansacFit {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let all_finite = a
        .iter()
        .chain(b)
        .all(|q| q[0].is_finite() && q[1].is_finite());
    if n < MIN_MATCHES || !all_finite || !spread(a) || !spread(b) {
        return RansacFit::empty(p.model, n);
    }
    let s = p.model.sample_size();
    let thr = p.threshold_px;
    let count = |m: &[[f64; 3]; 3]| {
        inliers_of(p.model, m, a, b, thr)
            .iter()
            .filter(|v| **v)
            .count()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    let mut best: Option<([[f64; 3]; 3], usize)> = None;
    let mut needed = p.max_iterations;
    let mut iterations = 0;
    while iterations < needed {
        let samples: Vec<Vec<usize>> = (0..BATCH)
            .map(|_| rand::seq::index::sample(&mut rng, n, s).into_vec())
            .collect();
        let scored: Vec<Option<([[f64; 3]; 3], usize)>> = samples
            .par_iter()
            .map(|idx| {
                if !sample_ok(p.model, a, b, idx) {
                    return None;
                }
                let m = fit(p.model, a, b, idx)?;
                Some((m, count(&m)))
            })
            .collect();
        for h in scored {
            if iterations >= needed {
                break;
            }
            iterations += 1;
            if let Some((m, c)) = h {
                if best.is_none_or(|(_, bc)| c > bc) {
                    best = Some((m, c));
                    let w = c as f64 / n as f64;
                    needed =
                        needed_iterations(p.confidence, w, s, p.max_iterations).max(iterations);
                }
            }
        }
    }
    let Some((mut model, mut best_count)) = best else {
        return RansacFit {
            iterations,
            ..RansacFit::empty(p.model, n)
        };
    };
    let mut flags = inliers_of(p.model, &model, a, b, thr);
    for _ in 0..3 {
        let idx: Vec<usize> = (0..n).filter(|&i| flags[i]).collect();
        let Some(refit) = fit(p.model, a, b, &idx) else {
            break;
        };
        let rf = inliers_of(p.model, &refit, a, b, thr);
        let rc = rf.iter().filter(|v| **v).count();
        if rc < best_count {
            break;
        }
        let grew = rc > best_count;
        (model, best_count, flags) = (refit, rc, rf);
        if !grew {
            break;
        }
    }
    RansacFit {
        model: p.model,
        matrix: Some(model),
        inliers: flags,
        iterations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iteration_count_formula() {
        // OpenCV's RANSACUpdateNumIters: ln(0.01) / ln(1 − 0.5⁴) = 71.4 → 72.
        assert_eq!(needed_iterations(0.99, 0.5, 4, 2000), 72);
        assert_eq!(needed_iterations(0.99, 1.0, 8, 2000), 0);
        assert_eq!(needed_iterations(0.99, 0.1, 8, 2000), 2000);
        assert_eq!(needed_iterations(0.99, 0.0, 8, 2000), 2000);
    }

    #[test]
    fn collinear_samples_are_rejected() {
        let a = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [0.0, 5.0]];
        let b = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        assert!(!sample_ok(ModelKind::Homography, &a, &b, &[0, 1, 2, 3]));
        assert!(sample_ok(ModelKind::Homography, &b, &b, &[0, 1, 2, 3]));
        assert!(!spread(&a[..3]));
        assert!(spread(&a));
    }
}
