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
//!   and the surface normal — left alone, the texture would carry the scanner's own shading.
//!   [`incidence`] divides it out per point of the *cleaned* cloud (outliers would tilt
//!   normals), with the height-plane normal of a fixed 6 cm ground window of the merged cloud
//!   (several scans densify it, and it does not depend on any DEM) and the beam from the point's
//!   scanner origin; see that module for why not the nearest neighbours nor a principal-component
//!   plane.
//! - **Cross-scan radiometric calibration**: [`radiometry`] fits the instrument's residual range
//!   dependence of the reflectance and a per-scan offset on the overlaps and divides them out of
//!   `reflectance` and `albedo`, so stations agree where they see the same ground.
//! - **The SOR neighbours come from a grid of vertical columns** ([`map_self_knn`]): a terrain
//!   cloud is a 2.5-D surface, and reading the 3 × 3 cells around each point beats a kd-tree
//!   descent per point; the distances are exact (bit for bit those of a kd-tree), so the means
//!   do not depend on the method or the thread count.

use std::borrow::Borrow;

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use super::geometry::{mean_std, translation_part};
use super::incidence::{self, incidence_albedo};
use super::radiometry::{self, RadiometricCalibration};
use super::self_knn::map_self_knn;
use crate::ingest::types::{transform, Matrix4, PointCloud};
use crate::stage::{Stage, StageCx, StageError};

pub use super::incidence::MIN_COS_INCIDENCE;

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
    /// The cross-scan radiometric calibration applied to `reflectance` and `albedo`, when the
    /// scans overlapped enough to fit one.
    pub radiometry: Option<RadiometricCalibration>,
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
        self.merge_from(cx, scans.iter())
    }

    /// [`MergeClean::merge`] of scans it may free: each scan's points are dropped once merged, so
    /// a full survey is not held twice while its outliers are found.
    pub fn merge_owned(
        &self,
        cx: &StageCx,
        scans: Vec<MergeScan>,
    ) -> Result<MergedCloud, StageError> {
        self.merge_from(cx, scans.into_iter())
    }

    fn merge_from<S: Borrow<MergeScan>>(
        &self,
        cx: &StageCx,
        scans: impl Iterator<Item = S>,
    ) -> Result<MergedCloud, StageError> {
        let mut all = MergedCloud::default();
        let mut db: Option<Vec<f32>> = Some(Vec::new());
        let mut rho: Option<Vec<f32>> = Some(Vec::new());
        let (mut names, mut origins) = (Vec::new(), Vec::new());
        for (si, s) in (0u32..).zip(scans) {
            let s = s.borrow();
            names.push(s.name.clone());
            origins.push(translation_part(&s.ground_from_socs));
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
        let keep = self.outlier_mask(&all.points, &mut all.stats)?;
        all.stats.outliers_removed = keep.iter().filter(|&&k| !k).count();
        retain_kept(&mut all, &keep);
        drop(keep);
        let mut out = match self.voxel_m {
            Some(v) => {
                let idx = voxel_thin(&all.points, v);
                all.stats.thinned = all.points.len() - idx.len();
                select(all, &idx)
            }
            None => all,
        };
        out.albedo = out
            .reflectance
            .as_deref()
            .map(|rho| incidence_albedo(&out.points, &out.scan, rho, &origins));
        calibrate(cx, &names, &origins, &mut out);
        Ok(out)
    }

    /// `true` for points kept by the statistical outlier filter.
    fn outlier_mask(
        &self,
        points: &[[f64; 3]],
        stats: &mut MergeStats,
    ) -> Result<Vec<bool>, StageError> {
        if self.sor_k == 0 || points.len() <= self.sor_k {
            return Ok(vec![true; points.len()]);
        }
        let means = map_self_knn(points, self.sor_k + 1, |d2| {
            d2.iter().skip(1).map(|d| d.sqrt()).sum::<f64>() / self.sor_k as f64
        })
        .ok_or_else(|| {
            StageError::new(
                Self::NAME,
                format!(
                    "{} merged points, expected at most {}",
                    points.len(),
                    u32::MAX
                ),
            )
        })?;
        let (mean, std) = mean_std(&means);
        stats.sor_mean_m = mean;
        stats.sor_std_m = std;
        let limit = mean + self.sor_n_std * std;
        Ok(means.iter().map(|&m| m <= limit).collect())
    }
}

/// Fits the cross-scan radiometric calibration on the albedo and applies it to the albedo and
/// the reflectance (module doc); a campaign whose scans do not overlap enough keeps its values
/// and gets a warning.
fn calibrate(cx: &StageCx, names: &[String], origins: &[Vector3<f64>], out: &mut MergedCloud) {
    let (Some(albedo), Some(rho)) = (out.albedo.as_mut(), out.reflectance.as_deref()) else {
        return;
    };
    match radiometry::fit(&out.points, &out.scan, albedo, rho, origins, names) {
        Ok(cal) => {
            if !cal.applied {
                cx.reporter.warn(
                    MergeClean::NAME,
                    "radiometry-implausible",
                    format!(
                        "scans' reflectance disagrees beyond an instrument calibration (range slope {:.3} dB/m, \
                         offsets up to {:.2} dB; expected within {} dB/m and {} dB): left uncorrected",
                        cal.range_slope_db_per_m,
                        cal.scan_offsets_db.iter().map(|c| c.offset_db.abs()).fold(0.0, f64::max),
                        radiometry::MAX_SLOPE_DB_PER_M,
                        radiometry::MAX_OFFSET_DB,
                    ),
                );
            }
            radiometry::apply(&cal, &out.points, &out.scan, origins, albedo);
            if let Some(rho) = out.reflectance.as_mut() {
                radiometry::apply(&cal, &out.points, &out.scan, origins, rho);
            }
            out.radiometry = Some(cal);
        }
        Err(radiometry::NotFitted::OneScan) => {}
        Err(e) => cx.reporter.warn(
            MergeClean::NAME,
            "radiometry-not-fitted",
            format!("reflectance not cross-calibrated between scans: {e}"),
        ),
    }
}

/// Keeps per voxel the point nearest to the voxel centre; output sorted by voxel key.
fn voxel_thin(points: &[[f64; 3]], voxel: f64) -> Vec<usize> {
    let keyed: Vec<([i64; 3], f64, usize)> = points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
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

/// Keeps the points whose `keep` is true, in place (every per-point array together, in order):
/// the cloud is not copied, which on a full survey would hold a second one in memory.
fn retain_kept(all: &mut MergedCloud, keep: &[bool]) {
    fn retain<T>(v: &mut Vec<T>, keep: &[bool]) {
        // `Vec::retain` visits every element once, in order.
        let mut k = keep.iter();
        v.retain(|_| k.next().copied().unwrap_or(false));
    }
    retain(&mut all.points, keep);
    retain(&mut all.scan, keep);
    for v in [
        &mut all.reflectance_db,
        &mut all.reflectance,
        &mut all.albedo,
    ]
    .into_iter()
    .flatten()
    {
        retain(v, keep);
    }
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
        radiometry: all.radiometry,
    }
}

impl Stage for MergeClean {
    const NAME: &'static str = "merge.clean";
    const VERSION: u32 = 4;
    const DESCRIPTION: &'static str =
        "Transform scans to ground, merge, remove statistical outliers, optional voxel thinning; keep reflectance and its incidence-corrected albedo, cross-calibrated between scans";
    type Input = [MergeScan];
    type Output = MergedCloud;

    fn params(&self) -> serde_json::Value {
        serde_json::json!({
            "sor_k": self.sor_k,
            "sor_n_std": self.sor_n_std,
            "voxel_m": self.voxel_m,
            "reference_range_m": self.reference_range_m,
            "normal_cell_m": incidence::NORMAL_CELL_M,
            "normal_window_cells": incidence::WINDOW_CELLS,
            "normal_max_window_cells": incidence::MAX_WINDOW_CELLS,
            "normal_min_points": incidence::MIN_WINDOW_POINTS,
            "normal_min_footprint_ratio": incidence::MIN_FOOTPRINT_RATIO,
            "min_cos_incidence": MIN_COS_INCIDENCE,
            "radiometry_cell_m": radiometry::CELL_M,
            "radiometry_min_points": radiometry::MIN_POINTS,
            "radiometry_min_cos": radiometry::MIN_COS_FIT,
            "radiometry_max_slope_std_err_db_per_m": radiometry::MAX_SLOPE_STD_ERR_DB_PER_M,
            "radiometry_max_slope_db_per_m": radiometry::MAX_SLOPE_DB_PER_M,
            "radiometry_max_offset_db": radiometry::MAX_OFFSET_DB,
        })
    }

    fn run(&self, cx: &StageCx, input: &[MergeScan]) -> Result<MergedCloud, StageError> {
        self.merge(cx, input)
    }
}
