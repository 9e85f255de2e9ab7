//! Stage `register.tiepoints`: per scan, the SOCS → ground rigid transform from tie points.
//!
//! Each scan's tie points (reflector centres in the scanner's own coordinate system) are matched
//! by name to the ground markers (Vicon ball centres in the ground frame) and a least-squares rigid
//! transform is fitted (Umeyama/Horn, no scale: both instruments measure in metres). A scan may
//! instead carry a given SOP matrix, which is passed through and only checked against whatever
//! tie points match.
//!
//! Outlier rejection (only with ≥ 4 matched tie points, so that 3 always remain): each tie point's
//! *leave-one-out* residual is computed (fit without it, measure it), because a gross outlier pulls
//! an all-points fit towards itself and hides in its own residual. The worst one is rejected when
//! its leave-one-out residual exceeds both `outlier_factor` × the median leave-one-out residual and
//! `outlier_min_m`; then the fit is redone and the test repeated. Rejected names are reported.
//!
//! A scan whose final RMS exceeds `max_rms_m`, or with fewer than 3 usable tie points and no SOP, is
//! an error naming the scan, its RMS and the threshold: a bad registration must not silently
//! produce a DEM.

use serde::Serialize;

use super::geometry::{all_finite, fit_transform, rms};
use crate::ingest::types::{transform, Matrix4, NamedPoint};
use crate::stage::{Stage, StageCx, StageError};

/// One scan to register.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanTiepoints {
    /// Scan (position) name, e.g. `ScanPos001`.
    pub scan: String,
    /// Tie points in the scanner's own coordinate system.
    pub tiepoints: Vec<NamedPoint>,
    /// A given SOCS → ground matrix; when set, no fit is made.
    pub sop: Option<Matrix4>,
}

/// The stage input.
#[derive(Debug, Clone, PartialEq)]
pub struct TiepointInput {
    /// Ground control: marker centres in the ground frame.
    pub markers: Vec<NamedPoint>,
    /// The scans.
    pub scans: Vec<ScanTiepoints>,
}

/// Residual of one tie point after registration (ground frame, `transformed - marker`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerResidual {
    /// Marker name.
    pub name: String,
    /// Residual vector, metres.
    pub residual_m: [f64; 3],
    /// Residual length, metres.
    pub distance_m: f64,
    /// True when the tie point was rejected as an outlier (residual against the final fit).
    pub rejected: bool,
}

/// The registration of one scan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScanRegistration {
    /// Scan name.
    pub scan: String,
    /// SOCS → ground.
    pub ground_from_socs: Matrix4,
    /// `"tiepoints"` or `"sop"`.
    pub method: &'static str,
    /// One residual per matched tie point, sorted by name.
    pub residuals: Vec<MarkerResidual>,
    /// RMS of the residuals of the tie points used (not rejected), metres; 0 when none.
    pub rms_m: f64,
    /// Largest residual among the tie points used, metres.
    pub max_m: f64,
    /// Number of tie points used.
    pub n_tiepoints: usize,
    /// Names of rejected tie points, sorted.
    pub rejected: Vec<String>,
}

/// Parameters of `register.tiepoints`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegisterTiepoints {
    max_rms_m: f64,
    outlier_factor: f64,
    outlier_min_m: f64,
}

impl Default for RegisterTiepoints {
    fn default() -> Self {
        RegisterTiepoints {
            max_rms_m: 0.01,
            outlier_factor: 3.0,
            outlier_min_m: 0.005,
        }
    }
}

impl RegisterTiepoints {
    /// Validated parameters: RMS threshold, outlier factor (× median), outlier floor (m).
    pub fn new(
        max_rms_m: f64,
        outlier_factor: f64,
        outlier_min_m: f64,
    ) -> Result<Self, StageError> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !ok(max_rms_m) || !ok(outlier_factor) || !ok(outlier_min_m) {
            return Err(StageError::new(
                Self::NAME,
                format!(
                    "parameters must be finite and > 0, found max_rms_m={max_rms_m}, \
                     outlier_factor={outlier_factor}, outlier_min_m={outlier_min_m}"
                ),
            ));
        }
        Ok(RegisterTiepoints {
            max_rms_m,
            outlier_factor,
            outlier_min_m,
        })
    }

    /// Registers one scan against the markers.
    pub fn register_scan(
        &self,
        cx: &StageCx,
        markers: &[NamedPoint],
        scan: &ScanTiepoints,
    ) -> Result<ScanRegistration, StageError> {
        let err = |m: String| StageError::new(Self::NAME, format!("scan {}: {m}", scan.scan));
        let pairs = match_tiepoints(markers, &scan.tiepoints).map_err(err)?;
        let unmatched = scan.tiepoints.len() - pairs.len();
        if unmatched > 0 {
            cx.reporter.warn(
                Self::NAME,
                "tiepoint-unmatched",
                format!(
                    "scan {}: {unmatched} tie point(s) have no ground marker of the same name",
                    scan.scan
                ),
            );
        }
        let (matrix, used, method) = match scan.sop {
            Some(sop) => (sop, vec![true; pairs.len()], "sop"),
            None => {
                if pairs.len() < 3 {
                    let names = |v: &[NamedPoint]| {
                        let mut n: Vec<&str> = v.iter().map(|p| p.name.as_str()).collect();
                        n.sort_unstable();
                        n.join(", ")
                    };
                    return Err(err(format!(
                        "{} tie point(s) match a ground marker, expected at least 3 (or a SOP \
                         matrix); the tie points are named {} and the ground markers {}: name \
                         each tie point exactly as the ground marker at the same reflector \
                         (the Vicon name without its `Subject:` part), or register the scan \
                         with `sop = \"<file>.DAT\"`",
                        pairs.len(),
                        names(&scan.tiepoints),
                        names(markers)
                    )));
                }
                let (m, used) = self.fit_with_rejection(&pairs).ok_or_else(|| {
                    err("tie points are degenerate (collinear or coincident), the rotation is undetermined".into())
                })?;
                (m, used, "tiepoints")
            }
        };
        let residuals: Vec<MarkerResidual> = pairs
            .iter()
            .zip(&used)
            .map(|(p, &u)| {
                let t = transform(&matrix, p.socs);
                let r = [t[0] - p.ground[0], t[1] - p.ground[1], t[2] - p.ground[2]];
                let d = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
                MarkerResidual {
                    name: p.name.clone(),
                    residual_m: r,
                    distance_m: d,
                    rejected: !u,
                }
            })
            .collect();
        let kept: Vec<f64> = residuals
            .iter()
            .filter(|r| !r.rejected)
            .map(|r| r.distance_m)
            .collect();
        let rms_m = rms(&kept);
        let max_m = kept.iter().fold(0.0f64, |a, &b| a.max(b));
        if rms_m > self.max_rms_m {
            return Err(err(format!(
                "tie-point RMS {rms_m:.4} m over {} marker(s) exceeds the threshold {:.4} m",
                kept.len(),
                self.max_rms_m
            )));
        }
        let rejected: Vec<String> = residuals
            .iter()
            .filter(|r| r.rejected)
            .map(|r| r.name.clone())
            .collect();
        if !rejected.is_empty() {
            cx.reporter.warn(
                Self::NAME,
                "tiepoint-rejected",
                format!(
                    "scan {}: rejected outlier tie point(s) {}",
                    scan.scan,
                    rejected.join(", ")
                ),
            );
        }
        Ok(ScanRegistration {
            scan: scan.scan.clone(),
            ground_from_socs: matrix,
            method,
            n_tiepoints: kept.len(),
            residuals,
            rms_m,
            max_m,
            rejected,
        })
    }

    /// Rigid fit with iterative leave-one-out rejection; returns the matrix and the used flags.
    fn fit_with_rejection(&self, pairs: &[Pair]) -> Option<(Matrix4, Vec<bool>)> {
        let mut used = vec![true; pairs.len()];
        loop {
            let idx: Vec<usize> = (0..pairs.len())
                .filter(|&i| used.get(i) == Some(&true))
                .collect();
            let fit = fit_pairs(pairs, &idx)?;
            if idx.len() < 4 {
                return Some((fit, used));
            }
            let loo: Vec<(usize, f64)> = idx
                .iter()
                .map(|&i| {
                    let rest: Vec<usize> = idx.iter().copied().filter(|&j| j != i).collect();
                    let d =
                        fit_pairs(pairs, &rest).and_then(|m| pairs.get(i).map(|p| p.distance(&m)));
                    (i, d.unwrap_or(f64::INFINITY))
                })
                .collect();
            let mut ds: Vec<f64> = loo.iter().map(|x| x.1).collect();
            let med = super::geometry::median(&mut ds)?;
            let worst = loo
                .iter()
                .fold((usize::MAX, -1.0), |a, &b| if b.1 > a.1 { b } else { a });
            if worst.1 > self.outlier_factor * med && worst.1 > self.outlier_min_m {
                if let Some(u) = used.get_mut(worst.0) {
                    *u = false;
                }
            } else {
                return Some((fit, used));
            }
        }
    }
}

/// A tie point matched to its ground marker.
#[derive(Debug, Clone)]
struct Pair {
    name: String,
    socs: [f64; 3],
    ground: [f64; 3],
}

impl Pair {
    fn distance(&self, m: &Matrix4) -> f64 {
        let t = transform(m, self.socs);
        ((t[0] - self.ground[0]).powi(2)
            + (t[1] - self.ground[1]).powi(2)
            + (t[2] - self.ground[2]).powi(2))
        .sqrt()
    }
}

fn fit_pairs(pairs: &[Pair], idx: &[usize]) -> Option<Matrix4> {
    let sel: Vec<&Pair> = idx.iter().filter_map(|&i| pairs.get(i)).collect();
    let src: Vec<[f64; 3]> = sel.iter().map(|p| p.socs).collect();
    let dst: Vec<[f64; 3]> = sel.iter().map(|p| p.ground).collect();
    fit_transform(&src, &dst, false).map(|s| s.to_matrix4())
}

/// Matches tie points to markers by exact name, sorted by name; duplicates and non-finite
/// coordinates are errors.
fn match_tiepoints(markers: &[NamedPoint], tiepoints: &[NamedPoint]) -> Result<Vec<Pair>, String> {
    let mut ground: Vec<&NamedPoint> = markers.iter().collect();
    ground.sort_by(|a, b| a.name.cmp(&b.name));
    let mut tps: Vec<&NamedPoint> = tiepoints.iter().collect();
    tps.sort_by(|a, b| a.name.cmp(&b.name));
    for w in [&ground, &tps] {
        if let Some(d) = w.windows(2).find_map(|p| match p {
            [a, b] if a.name == b.name => Some(a.name.clone()),
            _ => None,
        }) {
            return Err(format!(
                "point name {d:?} appears twice, expected unique names"
            ));
        }
        if let Some(bad) = w.iter().find(|p| !all_finite(&[p.xyz])) {
            return Err(format!(
                "point {:?} has non-finite coordinates {:?}",
                bad.name, bad.xyz
            ));
        }
    }
    Ok(tps
        .iter()
        .filter_map(|t| {
            let g = ground
                .binary_search_by(|g| g.name.cmp(&t.name))
                .ok()
                .and_then(|i| ground.get(i))?;
            Some(Pair {
                name: t.name.clone(),
                socs: t.xyz,
                ground: g.xyz,
            })
        })
        .collect())
}

impl Stage for RegisterTiepoints {
    const NAME: &'static str = "register.tiepoints";
    const VERSION: u32 = 1;
    const DESCRIPTION: &'static str =
        "Per-scan SOCS to ground rigid transform from tie points matched to ground markers (or a given SOP)";
    type Input = TiepointInput;
    type Output = Vec<ScanRegistration>;

    fn params(&self) -> serde_json::Value {
        serde_json::json!({
            "max_rms_m": self.max_rms_m,
            "outlier_factor": self.outlier_factor,
            "outlier_min_m": self.outlier_min_m,
        })
    }

    fn run(
        &self,
        cx: &StageCx,
        input: &TiepointInput,
    ) -> Result<Vec<ScanRegistration>, StageError> {
        input
            .scans
            .iter()
            .map(|s| self.register_scan(cx, &input.markers, s))
            .collect()
    }
}
