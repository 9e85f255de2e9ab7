//! Stage `register.icp`: joint refinement of all scan poses with point-to-plane ICP on their
//! overlaps, with the ground markers as soft constraints so the block of scans cannot drift.
//!
//! Design decisions:
//! - **Joint, linearised least squares** over 6 parameters per scan (a small rotation ω and
//!   translation v applied on the left, in the ground frame). Every correspondence couples two
//!   scans: `r = n·(T_i p − T_j q)` with Jacobian `[(p×n)ᵀ, nᵀ]` for scan i and `−[(q×n)ᵀ, nᵀ]` for
//!   scan j. Each matched tie point adds `T_i t − m` (3 rows). Weights are inverse variances:
//!   `1/icp_sigma_m²` per correspondence and `1/marker_sigma_m²` per marker coordinate, so the
//!   balance between overlap and control has a physical meaning (range noise vs tie-point noise).
//!   The gauge is fixed by the markers, or by `fixed_scan`, whose pose is held exactly; if neither
//!   determines it, the normal matrix is singular and the stage says so.
//! - **Correspondences**: each scan keeps every `n`-th point (`n` chosen so about
//!   `samples_per_scan` remain: deterministic, no RNG). A sample of scan i is mapped into scan j's
//!   own frame and its `normal_k` nearest neighbours there (kiddo tree built once per scan in SOCS,
//!   since rigid motions preserve neighbourhoods) give a local plane. A pair is used when the nearest
//!   neighbour is within `max_correspondence_m`, the plane is planar (surface variation < 0.1) and
//!   the two local normals agree within 30°.
//! - **Termination**: at most `iterations` Gauss–Newton steps; stop early when every scan's step
//!   is below `convergence_m` in translation and `convergence_m / 1 m` in rotation (radians).
//! - **Determinism**: correspondences are evaluated by an indexed parallel map over fixed chunks of
//!   4096 and the per-chunk normal equations are summed in chunk order.

use nalgebra::{DMatrix, DVector, Rotation3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::geometry::{
    all_finite, build_tree, compose, invert_rigid, linear_part, local_plane, pose_difference, rms,
    translation_part, Tree3,
};
use crate::ingest::types::{transform, Matrix4, NamedPoint};
use crate::stage::{Stage, StageCx, StageError};

/// One scan for ICP.
#[derive(Debug, Clone, PartialEq)]
pub struct IcpScan {
    /// Scan name.
    pub name: String,
    /// Points in the scanner's own coordinate system.
    pub points: Vec<[f64; 3]>,
    /// Tie points (SOCS), matched by name to the markers.
    pub tiepoints: Vec<NamedPoint>,
    /// Initial SOCS → ground (from `register.tiepoints`).
    pub ground_from_socs: Matrix4,
}

/// The stage input.
#[derive(Debug, Clone, PartialEq)]
pub struct IcpInput {
    /// Ground markers.
    pub markers: Vec<NamedPoint>,
    /// The scans.
    pub scans: Vec<IcpScan>,
}

/// Before/after figures for one scan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IcpScanReport {
    /// Scan name.
    pub scan: String,
    /// Refined SOCS → ground.
    pub ground_from_socs: Matrix4,
    /// Point-to-plane RMS of this scan's samples against the other scans, before / after (m).
    pub overlap_rms_before_m: f64,
    /// See `overlap_rms_before_m`.
    pub overlap_rms_after_m: f64,
    /// Correspondences found for this scan's samples after refinement.
    pub correspondences: usize,
    /// Tie-point RMS against the markers, before / after (m; 0 without markers).
    pub marker_rms_before_m: f64,
    /// See `marker_rms_before_m`.
    pub marker_rms_after_m: f64,
    /// Translation change of the pose (m).
    pub shift_m: f64,
    /// Rotation change of the pose (degrees).
    pub rotation_deg: f64,
}

/// The stage output.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IcpOutput {
    /// One report per input scan, in input order.
    pub scans: Vec<IcpScanReport>,
    /// Gauss–Newton iterations run.
    pub iterations: usize,
    /// True when the step fell below the threshold.
    pub converged: bool,
}

/// Parameters of `register.icp`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegisterIcp {
    iterations: usize,
    convergence_m: f64,
    max_correspondence_m: f64,
    samples_per_scan: usize,
    normal_k: usize,
    icp_sigma_m: f64,
    marker_sigma_m: f64,
    fixed_scan: Option<String>,
}

impl Default for RegisterIcp {
    fn default() -> Self {
        RegisterIcp {
            iterations: 30,
            convergence_m: 1e-5,
            max_correspondence_m: 0.05,
            samples_per_scan: 5000,
            normal_k: 24,
            icp_sigma_m: 0.008,
            marker_sigma_m: 0.002,
            fixed_scan: None,
        }
    }
}

const CHUNK: usize = 4096;
const MAX_VARIATION: f64 = 0.1;
const MIN_NORMAL_COS: f64 = 0.866;

/// Per-scan sampled data, built once.
struct Prepared<'a> {
    scan: &'a IcpScan,
    tree: Tree3,
    samples: Vec<(usize, Vector3<f64>)>,
    ties: Vec<([f64; 3], [f64; 3])>,
}

/// Normal equations plus per-scan residual sums.
struct Normal {
    h: DMatrix<f64>,
    g: DVector<f64>,
    sumsq: Vec<f64>,
    count: Vec<usize>,
}

impl Normal {
    fn new(m: usize) -> Normal {
        Normal {
            h: DMatrix::zeros(6 * m, 6 * m),
            g: DVector::zeros(6 * m),
            sumsq: vec![0.0; m],
            count: vec![0; m],
        }
    }
    /// Adds one weighted residual row with sparse Jacobian blocks `(scan, [ω, v] coefficients)`.
    fn add(&mut self, r: f64, w: f64, blocks: &[(usize, [f64; 6])]) {
        for &(a, ja) in blocks {
            for (ka, va) in ja.iter().enumerate() {
                if let Some(g) = self.g.get_mut(6 * a + ka) {
                    *g += w * va * r;
                }
                for &(b, jb) in blocks {
                    for (kb, vb) in jb.iter().enumerate() {
                        if let Some(h) = self.h.get_mut((6 * a + ka, 6 * b + kb)) {
                            *h += w * va * vb;
                        }
                    }
                }
            }
        }
    }
    fn merge(&mut self, o: &Normal) {
        self.h += &o.h;
        self.g += &o.g;
        self.sumsq
            .iter_mut()
            .zip(&o.sumsq)
            .for_each(|(a, b)| *a += b);
        self.count
            .iter_mut()
            .zip(&o.count)
            .for_each(|(a, b)| *a += b);
    }
}

fn jac(x: &Vector3<f64>, n: &Vector3<f64>, sign: f64) -> [f64; 6] {
    let c = x.cross(n);
    [
        sign * c.x,
        sign * c.y,
        sign * c.z,
        sign * n.x,
        sign * n.y,
        sign * n.z,
    ]
}

impl RegisterIcp {
    /// Validated parameters.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        iterations: usize,
        convergence_m: f64,
        max_correspondence_m: f64,
        samples_per_scan: usize,
        normal_k: usize,
        icp_sigma_m: f64,
        marker_sigma_m: f64,
        fixed_scan: Option<String>,
    ) -> Result<Self, StageError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(pos(convergence_m)
            && pos(max_correspondence_m)
            && pos(icp_sigma_m)
            && pos(marker_sigma_m))
            || samples_per_scan == 0
            || !(3..=64).contains(&normal_k)
        {
            return Err(StageError::new(
                Self::NAME,
                format!(
                    "expected positive finite distances, samples_per_scan ≥ 1 and 3 ≤ normal_k ≤ 64; found convergence_m={convergence_m}, \
                     max_correspondence_m={max_correspondence_m}, icp_sigma_m={icp_sigma_m}, marker_sigma_m={marker_sigma_m}, \
                     samples_per_scan={samples_per_scan}, normal_k={normal_k}"
                ),
            ));
        }
        Ok(RegisterIcp {
            iterations,
            convergence_m,
            max_correspondence_m,
            samples_per_scan,
            normal_k,
            icp_sigma_m,
            marker_sigma_m,
            fixed_scan,
        })
    }

    fn prepare<'a>(
        &self,
        markers: &[NamedPoint],
        scans: &'a [IcpScan],
    ) -> Result<Vec<Prepared<'a>>, StageError> {
        let err = |m: String| StageError::new(Self::NAME, m);
        if let Some(f) = &self.fixed_scan {
            if !scans.iter().any(|s| &s.name == f) {
                return Err(err(format!(
                    "fixed scan {f:?} is not among the input scans"
                )));
            }
        }
        scans
            .par_iter()
            .map(|s| {
                if !all_finite(&s.points) {
                    return Err(err(format!(
                        "scan {}: non-finite point coordinates",
                        s.name
                    )));
                }
                let tree = build_tree(&s.points).ok_or_else(|| {
                    err(format!(
                        "scan {}: no points, expected at least {}",
                        s.name, self.normal_k
                    ))
                })?;
                let stride = (s.points.len() / self.samples_per_scan).max(1);
                let samples = (0..s.points.len())
                    .step_by(stride)
                    .filter_map(|i| {
                        let p = s.points.get(i)?;
                        let (plane, _) = local_plane(&tree, &s.points, p, self.normal_k)?;
                        (plane.variation < MAX_VARIATION).then_some((i, plane.normal))
                    })
                    .collect();
                let ties = s
                    .tiepoints
                    .iter()
                    .filter_map(|t| {
                        markers
                            .iter()
                            .find(|m| m.name == t.name)
                            .map(|m| (t.xyz, m.xyz))
                    })
                    .collect();
                Ok(Prepared {
                    scan: s,
                    tree,
                    samples,
                    ties,
                })
            })
            .collect()
    }

    /// Builds the normal equations for the current poses.
    fn accumulate(&self, prep: &[Prepared], poses: &[Matrix4]) -> Normal {
        let m = prep.len();
        let inv: Vec<Matrix4> = poses.iter().map(invert_rigid).collect();
        let tasks: Vec<(usize, usize, usize)> = (0..m)
            .flat_map(|i| (0..m).filter(move |&j| j != i).map(move |j| (i, j)))
            .flat_map(|(i, j)| {
                (0..prep.get(i).map_or(0, |p| p.samples.len())).map(move |s| (i, j, s))
            })
            .collect();
        let w = 1.0 / (self.icp_sigma_m * self.icp_sigma_m);
        let parts: Vec<Normal> = tasks
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut ne = Normal::new(m);
                for &(i, j, s) in chunk {
                    if let Some((r, jp, jq)) = self.correspond(prep, poses, &inv, i, j, s) {
                        ne.add(r, w, &[(i, jp), (j, jq)]);
                        if let (Some(a), Some(c)) = (ne.sumsq.get_mut(i), ne.count.get_mut(i)) {
                            *a += r * r;
                            *c += 1;
                        }
                    }
                }
                ne
            })
            .collect();
        let mut total = Normal::new(m);
        parts.iter().for_each(|p| total.merge(p));
        let wm = 1.0 / (self.marker_sigma_m * self.marker_sigma_m);
        for (i, (p, pose)) in prep.iter().zip(poses).enumerate() {
            for (t, mk) in &p.ties {
                let x = Vector3::from(transform(pose, *t));
                for (k, axis) in [Vector3::x(), Vector3::y(), Vector3::z()]
                    .iter()
                    .enumerate()
                {
                    let e = x.get(k).copied().unwrap_or(0.0) - mk.get(k).copied().unwrap_or(0.0);
                    total.add(e, wm, &[(i, jac(&x, axis, 1.0))]);
                }
            }
        }
        total
    }

    /// Residual and Jacobian blocks of sample `s` of scan `i` against scan `j`.
    fn correspond(
        &self,
        prep: &[Prepared],
        poses: &[Matrix4],
        inv: &[Matrix4],
        i: usize,
        j: usize,
        s: usize,
    ) -> Option<(f64, [f64; 6], [f64; 6])> {
        let (pi, pj) = (prep.get(i)?, prep.get(j)?);
        let (idx, n_src) = pi.samples.get(s)?;
        let (ti, tj) = (poses.get(i)?, poses.get(j)?);
        let pg = transform(ti, *pi.scan.points.get(*idx)?);
        let in_j = transform(inv.get(j)?, pg);
        let (plane, nearest) = local_plane(&pj.tree, &pj.scan.points, &in_j, self.normal_k)?;
        if nearest > self.max_correspondence_m || plane.variation >= MAX_VARIATION {
            return None;
        }
        let n = linear_part(tj) * plane.normal;
        if (linear_part(ti) * n_src).dot(&n).abs() < MIN_NORMAL_COS {
            return None;
        }
        let q = Vector3::from(transform(tj, plane.centroid.into()));
        let p = Vector3::from(pg);
        let r = n.dot(&(p - q));
        (r.abs() <= self.max_correspondence_m).then(|| (r, jac(&p, &n, 1.0), jac(&q, &n, -1.0)))
    }

    fn marker_rms(prep: &Prepared, pose: &Matrix4) -> f64 {
        let d: Vec<f64> = prep
            .ties
            .iter()
            .map(|(t, m)| {
                let x = transform(pose, *t);
                ((x[0] - m[0]).powi(2) + (x[1] - m[1]).powi(2) + (x[2] - m[2]).powi(2)).sqrt()
            })
            .collect();
        rms(&d)
    }

    /// Runs the joint refinement.
    pub fn refine(&self, input: &IcpInput) -> Result<IcpOutput, StageError> {
        let prep = self.prepare(&input.markers, &input.scans)?;
        let m = prep.len();
        let fixed = self
            .fixed_scan
            .as_ref()
            .and_then(|f| input.scans.iter().position(|s| &s.name == f));
        if fixed.is_none() && prep.iter().all(|p| p.ties.len() < 3) {
            return Err(StageError::new(
                Self::NAME,
                "no scan is fixed and no scan has ≥ 3 tie points matching markers, expected one or the other to anchor the block",
            ));
        }
        let initial: Vec<Matrix4> = input.scans.iter().map(|s| s.ground_from_socs).collect();
        let mut poses = initial.clone();
        let (mut iterations, mut converged, mut before) = (0, false, None);
        while iterations < self.iterations {
            let mut ne = self.accumulate(&prep, &poses);
            if before.is_none() {
                before = Some((ne.sumsq.clone(), ne.count.clone()));
            }
            if let Some(f) = fixed {
                for k in 6 * f..6 * f + 6 {
                    ne.h.row_mut(k).fill(0.0);
                    ne.h.column_mut(k).fill(0.0);
                    ne.h.get_mut((k, k)).into_iter().for_each(|v| *v = 1.0);
                    ne.g.get_mut(k).into_iter().for_each(|v| *v = 0.0);
                }
            }
            let delta = ne.h.clone().cholesky().map(|c| c.solve(&(-&ne.g))).ok_or_else(|| {
                StageError::new(
                    Self::NAME,
                    "the joint system is singular: some scan has neither overlap nor ≥ 3 markers, or no scan is fixed and there are no markers",
                )
            })?;
            iterations += 1;
            let mut largest: f64 = 0.0;
            for (k, pose) in poses.iter_mut().enumerate() {
                let Some(&[w0, w1, w2, v0, v1, v2]) = delta.as_slice().get(6 * k..6 * k + 6) else {
                    continue;
                };
                let (w, v) = (Vector3::new(w0, w1, w2), Vector3::new(v0, v1, v2));
                let rot = Rotation3::new(w).into_inner();
                *pose = compose(
                    &(rot * linear_part(pose)),
                    &(rot * translation_part(pose) + v),
                );
                largest = largest.max(v.norm()).max(w.norm());
            }
            if largest < self.convergence_m {
                converged = true;
                break;
            }
        }
        let after = self.accumulate(&prep, &poses);
        let before = before.unwrap_or_else(|| (after.sumsq.clone(), after.count.clone()));
        let rms_of = |s: f64, c: usize| if c == 0 { 0.0 } else { (s / c as f64).sqrt() };
        let scans = (0..m)
            .filter_map(|i| {
                let (p, pose, init) = (prep.get(i)?, poses.get(i)?, initial.get(i)?);
                let (shift_m, rotation_deg) = pose_difference(init, pose);
                Some(IcpScanReport {
                    scan: p.scan.name.clone(),
                    ground_from_socs: *pose,
                    overlap_rms_before_m: rms_of(*before.0.get(i)?, *before.1.get(i)?),
                    overlap_rms_after_m: rms_of(*after.sumsq.get(i)?, *after.count.get(i)?),
                    correspondences: *after.count.get(i)?,
                    marker_rms_before_m: Self::marker_rms(p, init),
                    marker_rms_after_m: Self::marker_rms(p, pose),
                    shift_m,
                    rotation_deg,
                })
            })
            .collect();
        Ok(IcpOutput {
            scans,
            iterations,
            converged,
        })
    }
}

impl Stage for RegisterIcp {
    const NAME: &'static str = "register.icp";
    const VERSION: u32 = 1;
    const DESCRIPTION: &'static str =
        "Joint point-to-plane ICP of all scans on their overlaps, markers as soft constraints";
    type Input = IcpInput;
    type Output = IcpOutput;

    fn params(&self) -> serde_json::Value {
        serde_json::json!({
            "iterations": self.iterations,
            "convergence_m": self.convergence_m,
            "max_correspondence_m": self.max_correspondence_m,
            "samples_per_scan": self.samples_per_scan,
            "normal_k": self.normal_k,
            "icp_sigma_m": self.icp_sigma_m,
            "marker_sigma_m": self.marker_sigma_m,
            "fixed_scan": self.fixed_scan,
        })
    }

    fn run(&self, cx: &StageCx, input: &IcpInput) -> Result<IcpOutput, StageError> {
        let out = self.refine(input)?;
        for s in out
            .scans
            .iter()
            .filter(|s| s.overlap_rms_after_m > s.overlap_rms_before_m)
        {
            cx.reporter.warn(
                Self::NAME,
                "icp-worse-overlap",
                format!(
                    "scan {}: overlap RMS grew from {:.4} m to {:.4} m",
                    s.scan, s.overlap_rms_before_m, s.overlap_rms_after_m
                ),
            );
        }
        Ok(out)
    }
}
