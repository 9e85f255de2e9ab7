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
//! - **One neighbour index** ([`KnnIndex`]) over the merged cloud serves both passes: SOR queries
//!   every point, the normals query the kept points with a keep mask (without voxel thinning the
//!   cleaned cloud is exactly the kept subset in merged order; with thinning the thinned cloud
//!   gets its own index). Queries run in the index's leaf order and are put back in merged order,
//!   so results do not depend on the thread count. The SOR means depend on the neighbour
//!   distances only, which are kiddo's bit for bit. A normal also depends on the order and, at
//!   the `NORMAL_K`-th neighbour, the choice among points at exactly equal distance: for the few
//!   points whose `NORMAL_K + 1` nearest contain such a tie between distinct points (about 1 in
//!   16 000 on the estec campaign: scan grids give symmetric neighbours), the albedo is
//!   recomputed with kiddo's tree over the cleaned cloud, as versions before the index did, so a
//!   campaign compiles to the same bytes (release id) as before.

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use super::geometry::{
    build_tree, fit_plane, local_plane, mean_std, translation_part, KnnIndex, Neighbour,
};
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
        // One index for both neighbourhood passes (the points are finite: checked above).
        let index = KnnIndex::new(&all.points);
        if index.is_none() && !all.points.is_empty() {
            return Err(StageError::new(
                Self::NAME,
                format!(
                    "{} merged points, expected at most {}",
                    all.points.len(),
                    u32::MAX
                ),
            ));
        }
        let keep = self.outlier_mask(index.as_ref(), all.points.len(), &mut all.stats);
        let mut idx: Vec<usize> = (0..all.points.len())
            .filter(|&i| keep.get(i) == Some(&true))
            .collect();
        all.stats.outliers_removed = all.points.len() - idx.len();
        let origins: Vec<Vector3<f64>> = scans
            .iter()
            .map(|s| translation_part(&s.ground_from_socs))
            .collect();
        if let Some(v) = self.voxel_m {
            drop(index);
            let before = idx.len();
            idx = voxel_thin(&all.points, idx, v);
            all.stats.thinned = before - idx.len();
            let mut out = select(all, &idx);
            out.albedo = out
                .reflectance
                .as_deref()
                .map(|rho| incidence_albedo(&out.points, &out.scan, rho, &origins));
            return Ok(out);
        }
        // Without thinning the cleaned cloud is the kept subset in merged order: its neighbours
        // are the kept neighbours in the merged index.
        let mut ties = Vec::new();
        all.albedo = match (&all.reflectance, &index) {
            (Some(rho), Some(ix)) => {
                let keep_leaf: Vec<bool> = ix
                    .ids()
                    .par_iter()
                    .map(|&id| keep.get(id as usize) == Some(&true))
                    .collect();
                let (albedo, t) = albedo_indexed(ix, Some(&keep_leaf), &all.scan, rho, &origins);
                ties = t;
                Some(albedo)
            }
            (Some(rho), None) => Some(rho.clone()),
            (None, _) => None,
        };
        drop(index);
        drop(keep);
        let mut out = select(all, &idx);
        // Tied points, as indices of the cleaned cloud (`idx` is ascending without thinning).
        let ties: Vec<usize> = ties
            .iter()
            .filter_map(|&id| idx.binary_search(&(id as usize)).ok())
            .collect();
        if let (Some(albedo), Some(rho)) = (out.albedo.as_mut(), out.reflectance.as_deref()) {
            resolve_ties(&out.points, &out.scan, rho, &origins, &ties, albedo);
        }
        Ok(out)
    }

    /// `true` for points kept by the statistical outlier filter (`n` points, `index` over them).
    fn outlier_mask(
        &self,
        index: Option<&KnnIndex>,
        n: usize,
        stats: &mut MergeStats,
    ) -> Vec<bool> {
        let Some(index) = index.filter(|ix| self.sor_k > 0 && ix.len() > self.sor_k) else {
            return vec![true; n];
        };
        let k = self.sor_k + 1;
        // Queries in leaf order (memory touched in order), results back in merged order.
        let leaf_means: Vec<f64> = index
            .points()
            .par_iter()
            .map_init(
                || Vec::with_capacity(k),
                |nb: &mut Vec<Neighbour>, p| {
                    index.knn(p, k, None, nb);
                    nb.iter().skip(1).map(|x| x.d2.sqrt()).sum::<f64>() / self.sor_k as f64
                },
            )
            .collect();
        let means = index.to_build_order(&leaf_means);
        drop(leaf_means);
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
    match KnnIndex::new(points) {
        Some(ix) if rho.len() == points.len() && scan.len() == points.len() => {
            let (mut albedo, ties) = albedo_indexed(&ix, None, scan, rho, origins);
            let ties: Vec<usize> = ties.iter().map(|&i| i as usize).collect();
            resolve_ties(points, scan, rho, origins, &ties, &mut albedo);
            albedo
        }
        _ => rho.to_vec(),
    }
}

/// Recomputes the albedo of the points `ties` (indices into `points`) whose normal
/// neighbourhood has a distance tie between distinct points, with the neighbours of a kiddo
/// tree over `points`: the neighbourhoods `merge.clean` has always used, tie order included, so
/// releases keep their bytes (see the module doc).
fn resolve_ties(
    points: &[[f64; 3]],
    scan: &[u32],
    rho: &[f32],
    origins: &[Vector3<f64>],
    ties: &[usize],
    albedo: &mut [f32],
) {
    if ties.is_empty() {
        return;
    }
    let Some(tree) = build_tree(points) else {
        return;
    };
    let fixed: Vec<(usize, f32)> = ties
        .par_iter()
        .filter_map(|&i| {
            let p = points.get(i)?;
            let r = rho.get(i).copied()?;
            let cos = scan
                .get(i)
                .and_then(|&s| origins.get(s as usize))
                .and_then(|o| {
                    let (plane, _) = local_plane(&tree, points, p, NORMAL_K)?;
                    cos_from_normal(&plane.normal, p, o)
                })
                .unwrap_or(1.0);
            Some((i, (f64::from(r) / cos.max(MIN_COS_INCIDENCE)) as f32))
        })
        .collect();
    for (i, a) in fixed {
        if let Some(v) = albedo.get_mut(i) {
            *v = a;
        }
    }
}

/// [`incidence_albedo`] of the points of `index` that `keep` (leaf order) marks, among
/// themselves; `scan` and `rho` in build order, result in build order (0 where not kept),
/// together with the build indices of the points whose neighbourhood has a tie (ascending),
/// left for [`resolve_ties`].
fn albedo_indexed(
    index: &KnnIndex,
    keep: Option<&[bool]>,
    scan: &[u32],
    rho: &[f32],
    origins: &[Vector3<f64>],
) -> (Vec<f32>, Vec<u32>) {
    let leaf: Vec<(f32, bool)> = index
        .points()
        .par_iter()
        .zip(index.ids().par_iter())
        .enumerate()
        .map_init(
            || {
                (
                    Vec::with_capacity(NORMAL_K + 1),
                    Vec::with_capacity(NORMAL_K),
                )
            },
            |(nb, pv), (pos, (p, &id))| {
                if keep.is_some_and(|m| m.get(pos) != Some(&true)) {
                    return (0.0, false);
                }
                let r = rho.get(id as usize).copied().unwrap_or(0.0);
                let Some(o) = scan.get(id as usize).and_then(|&s| origins.get(s as usize)) else {
                    return (r, false);
                };
                let (cos, tie) = cos_incidence(index, keep, nb, pv, p, o);
                let cos = cos.unwrap_or(1.0);
                ((f64::from(r) / cos.max(MIN_COS_INCIDENCE)) as f32, tie)
            },
        )
        .collect();
    let ties: Vec<u32> = {
        let mut t: Vec<u32> = index
            .ids()
            .iter()
            .zip(&leaf)
            .filter(|(_, v)| v.1)
            .map(|(&id, _)| id)
            .collect();
        t.sort_unstable();
        t
    };
    let leaf: Vec<f32> = leaf.into_iter().map(|v| v.0).collect();
    (index.to_build_order(&leaf), ties)
}

/// `|n·(o − p)| / |o − p|` with `n` the PCA normal of the [`NORMAL_K`] nearest kept points of
/// `p`, nearest first (`None` when no plane fits or `p` is the origin), and whether the
/// neighbourhood is tied: two distinct points at the same distance among the first
/// `NORMAL_K + 1`, where the order or the set would depend on the tie rule. `nb` and `pv` are
/// scratch buffers.
fn cos_incidence(
    index: &KnnIndex,
    keep: Option<&[bool]>,
    nb: &mut Vec<Neighbour>,
    pv: &mut Vec<Vector3<f64>>,
    p: &[f64; 3],
    origin: &Vector3<f64>,
) -> (Option<f64>, bool) {
    index.knn(p, NORMAL_K + 1, keep, nb);
    let pts = index.points();
    let at = |n: &Neighbour| pts.get(n.pos as usize);
    let tie = nb
        .windows(2)
        .any(|w| matches!(w, [a, b] if a.d2 == b.d2 && at(a) != at(b)));
    pv.clear();
    pv.extend(
        nb.iter()
            .take(NORMAL_K)
            .filter_map(at)
            .map(|q| Vector3::from(*q)),
    );
    let cos = fit_plane(pv).and_then(|plane| cos_from_normal(&plane.normal, p, origin));
    (cos, tie)
}

/// `|n·(o − p)| / |o − p|`; `None` when not finite (`p` is the origin).
fn cos_from_normal(normal: &Vector3<f64>, p: &[f64; 3], origin: &Vector3<f64>) -> Option<f64> {
    let beam = origin - Vector3::from(*p);
    let cos = normal.dot(&beam).abs() / beam.norm();
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
