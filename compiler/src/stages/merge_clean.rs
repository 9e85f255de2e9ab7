//! Stage `merge.clean`: transform every registered scan to the ground frame, merge, remove
//! statistical outliers and optionally thin to one point per voxel, keeping reflectance and an
//! incidence-corrected albedo estimate.
//!
//! Design decisions:
//! - **Statistical outlier removal** (as PCL/PDAL `filters.outlier` "statistical"): for every point
//!   the mean distance to its `sor_k` nearest neighbours; points whose mean exceeds
//!   `mean + sor_n_std · std` of all means are dropped (`sor_k = 0` disables it). The means are
//!   computed by an indexed parallel map and reduced sequentially, so the result is thread-count
//!   independent.
//! - **Voxel thinning** keeps, per voxel of side `voxel_m`, the point closest to the voxel centre
//!   (ties: lowest merged index), and outputs points sorted by voxel key: a deterministic choice that
//!   keeps real measured points (no averaging across surfaces).
//! - **Range-normalised reflectance** (`reflectance`, linear, dimensionless): RIEGL's
//!   `Reflectance[dB]` is already range-corrected by the instrument (it is the echo amplitude
//!   relative to a white diffuse target *at the same range*), so it is only linearised:
//!   `ρ = 10^(dB/10)`. Scans that only carry a raw intensity `I` are normalised with the
//!   inverse-square law of an extended diffuse target: `ρ = I · (r / r_ref)²`, with `r` the range
//!   (distance to the SOCS origin) and `r_ref = reference_range_m`.
//!   The merged cloud has `reflectance` only when every scan provides one of the two (otherwise a
//!   warning), and keeps the raw `reflectance_db` only when every scan has it.
//! - **Incidence correction** (`albedo`): `ρ` is relative to a white Lambertian target facing the
//!   beam, so for a Lambertian surface it is `albedo · cos i`, with `i` the angle between the beam
//!   and the surface normal — left alone, the texture would carry the scanner's own shading. Per
//!   point of the *cleaned* cloud (outliers would tilt normals), the normal is the PCA normal of
//!   its [`NORMAL_K`] nearest neighbours in the merged ground-frame cloud (independent of any DEM,
//!   and several scans densify the neighbourhood); the beam comes from the point's scanner origin
//!   `o` (the translation of its scan's `ground_from_socs`): `cos i = |n·(o − p)| / |o − p|` (the
//!   PCA normal has no sign) and `albedo = ρ / max(cos i, MIN_COS_INCIDENCE)`. The floor (i ≈ 78°)
//!   bounds the gain where a few degrees of normal error would swing `1 / cos i` wildly. A point
//!   whose neighbourhood fits no plane keeps `albedo = ρ`. Computed by an indexed parallel map, so
//!   thread-count independent. Not modelled: non-Lambertian (e.g. retro-reflective) surfaces and any
//!   residual range dependence of the instrument's calibration.

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use super::geometry::{build_tree, knn, local_plane, mean_std, translation_part, Tree3};
use crate::ingest::types::{transform, Matrix4, PointCloud};
use crate::stage::{Stage, StageCx, StageError};

/// Neighbours of the PCA normal of the incidence correction (with the point itself).
pub const NORMAL_K: usize = 16;
/// Floor of `cos i` in the incidence correction: the gain `1 / cos i` is at most 5.
pub const MIN_COS_INCIDENCE: f64 = 0.2;

/// One registered scan.
#[derive(Debug, Clone, PartialEq)]
pub struct MergeScan {
    /// Scan name.
    pub name: String,
    /// Points in the scanner's own coordinate system.
    pub cloud: PointCloud,
    /// SOCS → ground (from `register.tiepoints` / `register.icp`).
    pub ground_from_socs: Matrix4,
}

/// Counts and thresholds of a merge.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct MergeStats {
    /// Points in all scans.
    pub input_points: usize,
    /// Points removed by the statistical outlier filter.
    pub outliers_removed: usize,
    /// Points removed by voxel thinning.
    pub thinned: usize,
    /// Mean over points of the mean k-neighbour distance, metres.
    pub sor_mean_m: f64,
    /// Standard deviation of those means, metres.
    pub sor_std_m: f64,
}

/// The merged, cleaned cloud in the ground frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MergedCloud {
    /// Points, ground frame, metres.
    pub points: Vec<[f64; 3]>,
    /// RIEGL reflectance in dB, when every scan had it.
    pub reflectance_db: Option<Vec<f32>>,
    /// Range-normalised linear reflectance `ρ ≈ albedo · cos i` (see the module doc).
    pub reflectance: Option<Vec<f32>>,
    /// Incidence-corrected albedo estimate `ρ / max(cos i, MIN_COS_INCIDENCE)`, when
    /// `reflectance` exists; the value the laser texture holds.
    pub albedo: Option<Vec<f32>>,
    /// Index of the source scan of each point.
    pub scan: Vec<u32>,
    /// Counts.
    pub stats: MergeStats,
}

/// Parameters of `merge.clean`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergeClean {
    sor_k: usize,
    sor_n_std: f64,
    voxel_m: Option<f64>,
    reference_range_m: f64,
}

impl Default for MergeClean {
    fn default() -> Self {
        MergeClean {
            sor_k: 8,
            sor_n_std: 3.0,
            voxel_m: None,
            reference_range_m: 10.0,
        }
    }
}

impl MergeClean {
    /// Validated parameters.
    pub fn new(
        sor_k: usize,
        sor_n_std: f64,
        voxel_m: Option<f64>,
        reference_range_m: f64,
    ) -> Result<Self, StageError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(sor_n_std)
            || !pos(reference_range_m)
            || voxel_m.is_some_and(|v| !pos(v))
            || sor_k > 256
        {
            return Err(StageError::new(
                Self::NAME,
                format!(
                    "expected sor_k ≤ 256 and finite positive sor_n_std, voxel_m, reference_range_m; found \
                     sor_k={sor_k}, sor_n_std={sor_n_std}, voxel_m={voxel_m:?}, reference_range_m={reference_range_m}"
                ),
            ));
        }
        Ok(MergeClean {
            sor_k,
            sor_n_std,
            voxel_m,
            reference_range_m,
        })
    }

    /// Transforms, merges, filters and thins.
    pub fn merge(&self, cx: &StageCx, scans: &[MergeScan]) -> Result<MergedCloud, StageError> {
        let mut all = MergedCloud::default();
        let mut db: Option<Vec<f32>> = Some(Vec::new());
        let mut rho: Option<Vec<f32>> = Some(Vec::new());
        for (si, s) in (0u32..).zip(scans) {
            let c = &s.cloud;
            let n = c.points.len();
            let err = |what: &str, len: usize| {
                StageError::new(
                    Self::NAME,
                    format!(
                        "scan {}: {len} {what} values for {n} points, expected {n}",
                        s.name
                    ),
                )
            };
            if let Some(v) = c.reflectance_db.as_ref().filter(|v| v.len() != n) {
                return Err(err("reflectance", v.len()));
            }
            if let Some(v) = c.intensity.as_ref().filter(|v| v.len() != n) {
                return Err(err("intensity", v.len()));
            }
            let m = s.ground_from_socs;
            all.points
                .par_extend(c.points.par_iter().map(|p| transform(&m, *p)));
            all.scan.extend(std::iter::repeat_n(si, n));
            db = db.zip(c.reflectance_db.as_ref()).map(|(mut a, b)| {
                a.extend_from_slice(b);
                a
            });
            let r_ref2 = self.reference_range_m * self.reference_range_m;
            let lin: Option<Vec<f32>> = match (&c.reflectance_db, &c.intensity) {
                (Some(d), _) => Some(d.par_iter().map(|v| 10f32.powf(v / 10.0)).collect()),
                (None, Some(i)) => Some(
                    c.points
                        .par_iter()
                        .zip(i.par_iter())
                        .map(|(p, v)| {
                            (f64::from(*v) * (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) / r_ref2)
                                as f32
                        })
                        .collect(),
                ),
                (None, None) => None,
            };
            if lin.is_none() && n > 0 {
                cx.reporter.warn(
                    Self::NAME,
                    "no-reflectance",
                    format!("scan {} has neither reflectance nor intensity; the merged cloud has no reflectance", s.name),
                );
            }
            rho = rho.zip(lin).map(|(mut a, b)| {
                a.extend(b);
                a
            });
        }
        if let Some(i) = all
            .points
            .iter()
            .position(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(StageError::new(
                Self::NAME,
                format!("merged point {i} is not finite, expected finite coordinates"),
            ));
        }
        all.reflectance_db = db;
        all.reflectance = rho;
        all.stats.input_points = all.points.len();
        let keep = self.outlier_mask(&all.points, &mut all.stats);
        let mut idx: Vec<usize> = (0..all.points.len())
            .filter(|&i| keep.get(i) == Some(&true))
            .collect();
        all.stats.outliers_removed = all.points.len() - idx.len();
        if let Some(v) = self.voxel_m {
            let before = idx.len();
            idx = voxel_thin(&all.points, idx, v);
            all.stats.thinned = before - idx.len();
        }
        let mut out = select(all, &idx);
        let origins: Vec<Vector3<f64>> = scans
            .iter()
            .map(|s| translation_part(&s.ground_from_socs))
            .collect();
        out.albedo = out
            .reflectance
            .as_deref()
            .map(|rho| incidence_albedo(&out.points, &out.scan, rho, &origins));
        Ok(out)
    }

    /// `true` for points kept by the statistical outlier filter.
    fn outlier_mask(&self, points: &[[f64; 3]], stats: &mut MergeStats) -> Vec<bool> {
        let Some(tree) = build_tree(points).filter(|_| self.sor_k > 0 && points.len() > self.sor_k)
        else {
            return vec![true; points.len()];
        };
        let means: Vec<f64> = points
            .par_iter()
            .map(|p| {
                let nn = knn(&tree, p, self.sor_k + 1);
                nn.iter().skip(1).map(|x| x.1).sum::<f64>() / self.sor_k as f64
            })
            .collect();
        let (mean, std) = mean_std(&means);
        stats.sor_mean_m = mean;
        stats.sor_std_m = std;
        let limit = mean + self.sor_n_std * std;
        means.iter().map(|&m| m <= limit).collect()
    }
}

/// `ρ / max(cos i, MIN_COS_INCIDENCE)` per point (module doc); `origins` indexed by scan.
pub fn incidence_albedo(
    points: &[[f64; 3]],
    scan: &[u32],
    rho: &[f32],
    origins: &[Vector3<f64>],
) -> Vec<f32> {
    let Some(tree) = build_tree(points) else {
        return rho.to_vec();
    };
    points
        .par_iter()
        .zip(rho.par_iter())
        .zip(scan.par_iter())
        .map(|((p, &r), &s)| {
            let cos = origins
                .get(s as usize)
                .and_then(|o| cos_incidence(&tree, points, p, o))
                .unwrap_or(1.0);
            (f64::from(r) / cos.max(MIN_COS_INCIDENCE)) as f32
        })
        .collect()
}

/// `|n·(o − p)| / |o − p|` with `n` the PCA normal of the neighbourhood of `p`; `None` when no
/// plane fits or `p` is the origin.
fn cos_incidence(
    tree: &Tree3,
    points: &[[f64; 3]],
    p: &[f64; 3],
    origin: &Vector3<f64>,
) -> Option<f64> {
    let (plane, _) = local_plane(tree, points, p, NORMAL_K)?;
    let beam = origin - Vector3::from(*p);
    let cos = plane.normal.dot(&beam).abs() / beam.norm();
    cos.is_finite().then_some(cos)
}

/// Keeps per voxel the point nearest to the voxel centre; output sorted by voxel key.
fn voxel_thin(points: &[[f64; 3]], idx: Vec<usize>, voxel: f64) -> Vec<usize> {
    let keyed: Vec<([i64; 3], f64, usize)> = idx
        .par_iter()
        .map(|&i| {
            let p = points.get(i).copied().unwrap_or([0.0; 3]);
            let k = p.map(|v| (v / voxel).floor() as i64);
            let d2: f64 = (0..3)
                .map(|a| {
                    let c = (k.get(a).copied().unwrap_or(0) as f64 + 0.5) * voxel;
                    (p.get(a).copied().unwrap_or(0.0) - c).powi(2)
                })
                .sum();
            (k, d2, i)
        })
        .collect();
    let mut keyed = keyed;
    keyed.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut out = Vec::new();
    let mut last: Option<[i64; 3]> = None;
    for (k, _, i) in keyed {
        if last != Some(k) {
            out.push(i);
            last = Some(k);
        }
    }
    out
}

/// The subset `idx` of a merged cloud (all per-point arrays together).
fn select(all: MergedCloud, idx: &[usize]) -> MergedCloud {
    fn pick<T: Copy + Send + Sync>(v: &[T], idx: &[usize]) -> Vec<T> {
        idx.par_iter().filter_map(|&i| v.get(i).copied()).collect()
    }
    MergedCloud {
        points: pick(&all.points, idx),
        reflectance_db: all.reflectance_db.as_deref().map(|v| pick(v, idx)),
        reflectance: all.reflectance.as_deref().map(|v| pick(v, idx)),
        albedo: all.albedo.as_deref().map(|v| pick(v, idx)),
        scan: pick(&all.scan, idx),
        stats: all.stats,
    }
}

impl Stage for MergeClean {
    const NAME: &'static str = "merge.clean";
    const VERSION: u32 = 2;
    const DESCRIPTION: &'static str =
        "Transform scans to ground, merge, remove statistical outliers, optional voxel thinning; keep reflectance and its incidence-corrected albedo";
    type Input = [MergeScan];
    type Output = MergedCloud;

    fn params(&self) -> serde_json::Value {
        serde_json::json!({
            "sor_k": self.sor_k,
            "sor_n_std": self.sor_n_std,
            "voxel_m": self.voxel_m,
            "reference_range_m": self.reference_range_m,
            "normal_k": NORMAL_K,
            "min_cos_incidence": MIN_COS_INCIDENCE,
        })
    }

    fn run(&self, cx: &StageCx, input: &[MergeScan]) -> Result<MergedCloud, StageError> {
        self.merge(cx, input)
    }
}
