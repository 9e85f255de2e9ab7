//! A small bounded Levenberg–Marquardt solver for the effect fits.
//!
//! Every gap fit has at most eight parameters and up to ~10⁵ residuals, so the normal
//! equations (`JᵀJ`, 8×8) are cheap and a forward-difference Jacobian is fast enough; it keeps
//! each effect model a plain function (no hand-written derivatives to get wrong). Bounds are
//! enforced by clamping every trial step (the catalogue's plausible ranges, widened). The
//! standard errors are `sqrt(diag((JᵀJ)⁻¹) · SSE / (n − k))` at the solution.

use nalgebra::{DMatrix, DVector};

/// A least-squares problem: `residuals(params, out)` fills `out` (same length every call).
pub struct Problem<'a> {
    /// The residual function.
    pub residuals: &'a (dyn Fn(&[f64], &mut Vec<f64>) + Sync),
    /// Start values.
    pub start: Vec<f64>,
    /// Lower bounds.
    pub lower: Vec<f64>,
    /// Upper bounds.
    pub upper: Vec<f64>,
    /// Forward-difference step per parameter.
    pub step: Vec<f64>,
}

/// The solution of a [`Problem`].
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Fitted parameters.
    pub params: Vec<f64>,
    /// Sum of squared residuals at the solution.
    pub sse: f64,
    /// Number of residuals.
    pub n: usize,
    /// Standard error per parameter (`NaN` when not identifiable).
    pub std_err: Vec<f64>,
}

fn sse(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

fn clamp(p: &mut [f64], lo: &[f64], hi: &[f64]) {
    for ((v, l), h) in p.iter_mut().zip(lo).zip(hi) {
        *v = v.clamp(*l, *h);
    }
}

fn jacobian(pb: &Problem<'_>, p: &[f64], r0: &[f64]) -> DMatrix<f64> {
    let k = p.len();
    let mut j = DMatrix::<f64>::zeros(r0.len(), k);
    let mut r = Vec::with_capacity(r0.len());
    for c in 0..k {
        let mut q = p.to_vec();
        // Step away from the nearer bound so the trial stays inside.
        let h = if q[c] + pb.step[c] > pb.upper[c] {
            -pb.step[c]
        } else {
            pb.step[c]
        };
        q[c] += h;
        (pb.residuals)(&q, &mut r);
        for (i, (a, b)) in r.iter().zip(r0).enumerate() {
            j[(i, c)] = (a - b) / h;
        }
    }
    j
}

/// Minimises the sum of squared residuals of `pb`.
pub fn solve(pb: &Problem<'_>, max_iter: usize) -> Solution {
    let mut p = pb.start.clone();
    clamp(&mut p, &pb.lower, &pb.upper);
    let k = p.len();
    let mut r = Vec::new();
    (pb.residuals)(&p, &mut r);
    let mut cost = sse(&r);
    if k == 0 || r.is_empty() {
        return Solution {
            params: p,
            sse: cost,
            n: r.len(),
            std_err: vec![f64::NAN; k],
        };
    }
    let mut lambda = 1e-3;
    let mut jtj = DMatrix::<f64>::zeros(k, k);
    for _ in 0..max_iter {
        let j = jacobian(pb, &p, &r);
        jtj = j.transpose() * &j;
        let g = j.transpose() * DVector::from_column_slice(&r);
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for d in 0..k {
                a[(d, d)] += lambda * (jtj[(d, d)].abs() + 1e-12);
            }
            let Some(delta) = a.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let mut trial: Vec<f64> = p.iter().zip(delta.iter()).map(|(a, d)| a + d).collect();
            clamp(&mut trial, &pb.lower, &pb.upper);
            let mut rt = Vec::new();
            (pb.residuals)(&trial, &mut rt);
            let ct = sse(&rt);
            if ct.is_finite() && ct < cost {
                let gain = (cost - ct) / cost.max(1e-300);
                p = trial;
                r = rt;
                cost = ct;
                lambda = (lambda * 0.3).max(1e-9);
                improved = gain > 1e-10;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let n = r.len();
    let dof = n.saturating_sub(k).max(1) as f64;
    let std_err = match jtj.clone().try_inverse() {
        Some(inv) => (0..k)
            .map(|d| (inv[(d, d)].max(0.0) * cost / dof).sqrt())
            .collect(),
        None => vec![f64::NAN; k],
    };
    Solution {
        params: p,
        sse: cost,
        n,
        std_err,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential_within_bounds() {
        let xs: Vec<f64> = (0..50).map(|i| f64::from(i) / 10.0).collect();
        let ys: Vec<f64> = xs.iter().map(|x| 2.0 * (-0.7 * x).exp() + 0.1).collect();
        let f = |p: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend(
                xs.iter()
                    .zip(&ys)
                    .map(|(x, y)| p[0] * (-p[1] * x).exp() + p[2] - y),
            );
        };
        let s = solve(
            &Problem {
                residuals: &f,
                start: vec![1.0, 0.1, 0.0],
                lower: vec![0.0, 0.0, -1.0],
                upper: vec![5.0, 5.0, 1.0],
                step: vec![1e-6; 3],
            },
            100,
        );
        assert!((s.params[0] - 2.0).abs() < 1e-5, "{:?}", s.params);
        assert!((s.params[1] - 0.7).abs() < 1e-5);
        assert!((s.params[2] - 0.1).abs() < 1e-5);
        // A bound that excludes the truth is respected.
        let s = solve(
            &Problem {
                residuals: &f,
                start: vec![1.0, 0.1, 0.0],
                lower: vec![0.0, 0.0, -1.0],
                upper: vec![1.5, 5.0, 1.0],
                step: vec![1e-6; 3],
            },
            100,
        );
        assert!(s.params[0] <= 1.5);
    }
}
