//! Stage `sfm.align`: put a multi-view-stereo (SfM) mesh, which lives in an arbitrary similarity
//! frame, onto the merged laser cloud in the ground frame, and report how well the two surfaces
//! agree (the automated version of the thesis' §6.1: ICP in Scanalyze, Figs 6.2 / 6.5).
//!
//! Design decisions:
//! - **No initial guess needed.** With ≥ 3 ground control points the start is their Umeyama
//!   similarity (least squares, with scale). Otherwise both clouds are thinned to uniform voxel
//!   centroids, a PCA frame gives "up" and the extent ratio gives the scale, and every
//!   candidate of `sfm_features::candidates` (both up signs × a yaw circle) runs a short
//!   *fixed-scale* ICP on a random subsample; the candidate with the lowest trimmed RMS wins.
//!   Scale is held fixed there because a free scale lets a wrong orientation shrink onto a
//!   small patch and score well.
//! - **Scaled ICP to convergence** from that start (fixed scale with control points, below):
//!   trimmed nearest-neighbour pairs, foot points on the laser's local planes, a Gauss–Newton
//!   step with scale per iteration (see `sfm_features`). Without control points it is followed
//!   by the height fit of `sfm_height_fit` (SfM heights against a smooth laser height surface),
//!   which settles where ICP on nearest samples jitters: on 18 mini seeds the laser-only scale
//!   error went from −0.96 … +0.29 % (3 beyond 0.5 %) to −0.16 … +0.38 %.
//! - **Control points fix the scale** (`control+laser`): the laser then refines rotation and
//!   translation only. Scaled ICP of a smoothed, noisy SfM surface onto the laser drifts the
//!   scale: on five `mini` corpus campaigns (seeds 7, 11, 42, 2024, 2025) the compiled laser
//!   alignment was 0.23–0.74 % small, while the Umeyama fit of the five markers (1.5 mm picking
//!   noise per axis) was within 0.21 %; letting ICP free the scale from that start fell back to
//!   the laser's −0.5 %. Without a laser cloud (`control`) the control-point similarity is the
//!   result. (No release used the earlier free-scale `control+laser`: the compiler did not read
//!   control-point files before, so the stage version stayed 1.)
//! - **Height comparison on one grid**: the `sfm − laser` grid over the overlap (NaN where either
//!   is missing, row 0 = north) is returned for the pipeline to write as an image, with its
//!   mean / std / RMS and histograms of both height distributions (thesis Fig 6.2) and of the
//!   differences.
//! - **Determinism.** The RNG is `cx.rng("sfm.align")`; parallel work is indexed
//!   `par_iter().map().collect()` and every sum is sequential, so results do not depend on the
//!   thread count.
//!
//! The geometry (thinning, PCA, candidates, ICP, the height grid) lives in `sfm_features`; this
//! file holds the public types, the orchestration and the report. The array form of
//! [`Similarity`] here is the serialisable sibling of `geometry::Similarity`
//! (nalgebra types, used for the Umeyama fit); `From` converts between them.

use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::seq::index::sample;
use rayon::prelude::*;
use regolith_format::frames::quat_from_matrix;
use serde::Serialize;

use super::geometry::{self, all_finite, fit_transform, rms};
use super::sfm_features::{
    candidates, compare_heights, thin, IcpRun, IcpSettings, PcaFrame, Target,
};
pub use super::sfm_features::{DifferenceGrid, HeightComparison, Histogram};
use super::sfm_height_fit::{fit, HeightFitSettings, HeightSurface};
use crate::ingest::types::{Matrix4, TriMesh};
use crate::stage::{Stage, StageCx, StageError};

/// Laser points per cell of the height surface of the final fit.
const HEIGHT_CELL_POINTS: f64 = 20.0;
/// Steepest laser cell (|∇h|) the height fit uses.
const MAX_SLOPE: f64 = 1.0;

/// SfM → ground similarity: `p_ground = scale · rotation · p_sfm + translation`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Similarity {
    /// Isotropic scale (ground metres per SfM unit).
    pub scale: f64,
    /// Proper rotation, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation, metres.
    pub translation: [f64; 3],
}

impl Similarity {
    /// The identity.
    pub const IDENTITY: Similarity = Similarity {
        scale: 1.0,
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    };

    /// From nalgebra parts.
    pub fn from_parts(
        scale: f64,
        rotation: &Matrix3<f64>,
        translation: &Vector3<f64>,
    ) -> Similarity {
        let row = |r: usize| [rotation[(r, 0)], rotation[(r, 1)], rotation[(r, 2)]];
        Similarity {
            scale,
            rotation: [row(0), row(1), row(2)],
            translation: (*translation).into(),
        }
    }

    /// The rotation as a nalgebra matrix.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|r, c| {
            self.rotation
                .get(r)
                .and_then(|row| row.get(c))
                .copied()
                .unwrap_or(0.0)
        })
    }

    /// `s R p + t`.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let [r0, r1, r2] = &self.rotation;
        let dot = |r: &[f64; 3]| self.scale * (r[0] * p[0] + r[1] * p[1] + r[2] * p[2]);
        let t = self.translation;
        [dot(r0) + t[0], dot(r1) + t[1], dot(r2) + t[2]]
    }

    /// The inverse map `p = (1/s) Rᵀ (q − t)` (infinite for a zero scale).
    pub fn inverse(&self) -> Similarity {
        let rt = self.rotation_matrix().transpose();
        let s = 1.0 / self.scale;
        Similarity::from_parts(s, &rt, &(-(rt * Vector3::from(self.translation)) * s))
    }

    /// `self ∘ inner`: first `inner`, then `self`.
    pub fn compose(&self, inner: &Similarity) -> Similarity {
        let r = self.rotation_matrix();
        let t = r * Vector3::from(inner.translation) * self.scale + Vector3::from(self.translation);
        Similarity::from_parts(self.scale * inner.scale, &(r * inner.rotation_matrix()), &t)
    }

    /// The transform as a row-major, column-vector [`Matrix4`].
    pub fn to_matrix4(&self) -> Matrix4 {
        geometry::Similarity::from(self).to_matrix4()
    }

    /// Angle of the relative rotation between `self` and `other`, degrees.
    pub fn angle_to_deg(&self, other: &Similarity) -> f64 {
        let r = self.rotation_matrix().transpose() * other.rotation_matrix();
        ((r.trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }
}

impl From<&geometry::Similarity> for Similarity {
    fn from(s: &geometry::Similarity) -> Similarity {
        Similarity::from_parts(s.scale, &s.rotation, &s.translation)
    }
}

impl From<&Similarity> for geometry::Similarity {
    fn from(s: &Similarity) -> geometry::Similarity {
        geometry::Similarity {
            scale: s.scale,
            rotation: s.rotation_matrix(),
            translation: s.translation.into(),
        }
    }
}

/// A point known in both frames (a ground control point).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ControlPoint {
    /// Name, for the report.
    pub name: String,
    /// Position in the SfM frame.
    pub sfm: [f64; 3],
    /// Position in the ground frame, metres.
    pub ground: [f64; 3],
}

/// The stage input (see [`AlignSfm::align`] for the borrowed form).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AlignInput {
    /// The SfM mesh, SfM frame.
    pub mesh: TriMesh,
    /// The merged laser points, ground frame (may be empty when control points are given).
    pub laser: Vec<[f64; 3]>,
    /// Ground control points (none, or ≥ 3).
    pub control: Vec<ControlPoint>,
}

/// Parameters of `sfm.align`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AlignParams {
    /// Voxel-centroid samples per cloud for ICP (both clouds are thinned to about this many).
    pub samples: usize,
    /// SfM samples per coarse candidate.
    pub coarse_samples: usize,
    /// Yaw step of the coarse search, degrees.
    pub yaw_step_deg: f64,
    /// Fixed-scale ICP iterations per coarse candidate.
    pub coarse_iterations: usize,
    /// Maximum scaled-ICP iterations.
    pub iterations: usize,
    /// Pairs farther than this × the median nearest distance are dropped.
    pub reject_factor: f64,
    /// Quantile of the nearest distances that scores a coarse candidate.
    pub score_fraction: f64,
    /// Neighbours for the laser normals.
    pub normal_k: usize,
    /// Convergence: RMS sample motion per iteration, as a fraction of the laser's planar radius.
    pub convergence: f64,
    /// Cell of the height-difference grid, metres.
    pub grid_cell_m: f64,
    /// Bins of the height and difference histograms.
    pub histogram_bins: usize,
    /// Upper bound on the difference-grid cells.
    pub max_cells: u64,
}

impl Default for AlignParams {
    fn default() -> Self {
        AlignParams {
            samples: 60_000,
            coarse_samples: 1_500,
            yaw_step_deg: 10.0,
            coarse_iterations: 10,
            iterations: 100,
            reject_factor: 3.0,
            score_fraction: 0.8,
            normal_k: 12,
            convergence: 5e-5,
            grid_cell_m: 0.02,
            histogram_bins: 64,
            max_cells: 1 << 26,
        }
    }
}

/// The `sfm.align` stage.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AlignSfm {
    params: AlignParams,
}

/// Result of the final ICP.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IcpReport {
    /// RMS point-to-plane distance of the inlier correspondences, metres.
    pub rms_point_to_plane_m: f64,
    /// RMS nearest-neighbour distance of the inliers, metres.
    pub rms_nearest_m: f64,
    /// Inlier correspondences (after trimming).
    pub inliers: usize,
    /// Iterations run.
    pub iterations: usize,
    /// True when the motion fell below the threshold before the iteration limit.
    pub converged: bool,
    /// Thinned samples (SfM, laser).
    pub samples: [usize; 2],
}

/// The final fit of the SfM heights to the laser height surface (see `sfm_height_fit`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeightFitReport {
    /// Cell of the laser height surface, metres.
    pub cell_m: f64,
    /// RMS height residual of the kept samples, metres.
    pub rms_m: f64,
    /// Kept samples.
    pub inliers: usize,
    /// Iterations run.
    pub iterations: usize,
    /// True when the motion fell below the threshold before the iteration limit.
    pub converged: bool,
}

/// How the start was found without control points.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoarseReport {
    /// Candidates tried.
    pub candidates: usize,
    /// Scale from the extent ratio.
    pub initial_scale: f64,
    /// Winning candidate: up flipped?
    pub flipped: bool,
    /// Winning candidate: yaw, degrees.
    pub yaw_deg: f64,
    /// Its score after the short ICP: the `score_fraction` quantile of the nearest distances, m.
    pub score_m: f64,
    /// Best score among candidates ending > 10° away from the winner (ambiguity), metres.
    pub runner_up_m: Option<f64>,
}

/// Control-point fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ControlReport {
    /// Residual per point after the final alignment, metres.
    pub residuals_m: Vec<(String, f64)>,
    /// Their RMS, metres.
    pub rms_m: f64,
}

/// Rotation angles (R = Rz(yaw) · Ry(pitch) · Rx(roll)), degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Angles {
    /// About x.
    pub roll_deg: f64,
    /// About y.
    pub pitch_deg: f64,
    /// About z.
    pub yaw_deg: f64,
    /// Total rotation angle.
    pub total_deg: f64,
}

/// The alignment report (serialised into the release's report object).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AlignReport {
    /// `sfm.align`.
    pub stage: &'static str,
    /// Stage version.
    pub version: u32,
    /// `laser`, `control` or `control+laser`.
    pub method: &'static str,
    /// The similarity.
    pub similarity: Similarity,
    /// Rotation as a quaternion `[x, y, z, w]`, w ≥ 0.
    pub rotation_xyzw: [f64; 4],
    /// Rotation angles.
    pub angles: Angles,
    /// Coarse search (laser alignment without control points).
    pub coarse: Option<CoarseReport>,
    /// Final ICP (when a laser cloud was given).
    pub icp: Option<IcpReport>,
    /// Final height fit (laser alignment without control points).
    pub height_fit: Option<HeightFitReport>,
    /// Control points (when given).
    pub control: Option<ControlReport>,
    /// Height comparison (when a laser cloud was given).
    pub heights: Option<HeightComparison>,
}

/// The stage output.
#[derive(Debug, Clone, PartialEq)]
pub struct AlignOutput {
    /// SfM → ground.
    pub similarity: Similarity,
    /// The report.
    pub report: AlignReport,
    /// The `sfm − laser` grid (when a laser cloud was given).
    pub difference: Option<DifferenceGrid>,
}

impl AlignSfm {
    /// Validated parameters.
    pub fn new(params: AlignParams) -> Result<AlignSfm, StageError> {
        let p = &params;
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let ok = p.samples >= 100
            && p.coarse_samples >= 10
            && pos(p.yaw_step_deg)
            && p.yaw_step_deg <= 90.0
            && p.iterations >= 1
            && p.reject_factor >= 1.0
            && p.score_fraction > 0.0
            && p.score_fraction <= 1.0
            && (3..=64).contains(&p.normal_k)
            && pos(p.convergence)
            && pos(p.grid_cell_m)
            && (1..=4096).contains(&p.histogram_bins);
        if !ok {
            return Err(StageError::new(
                Self::NAME,
                format!(
                    "expected samples ≥ 100, coarse_samples ≥ 10, 0 < yaw_step_deg ≤ 90, iterations ≥ 1, reject_factor ≥ 1, 0 < score_fraction ≤ 1, \
                     3 ≤ normal_k ≤ 64, positive convergence and grid_cell_m, 1 ≤ histogram_bins ≤ 4096; found {params:?}"
                ),
            ));
        }
        Ok(AlignSfm { params })
    }

    /// Aligns `mesh` (SfM frame) to `laser` (ground frame) and/or to the control points.
    pub fn align(
        &self,
        cx: &StageCx,
        mesh: &TriMesh,
        laser: &[[f64; 3]],
        control: &[ControlPoint],
    ) -> Result<AlignOutput, StageError> {
        let err = |m: String| StageError::new(Self::NAME, m);
        let p = &self.params;
        if mesh.positions.len() < 3 || !all_finite(&mesh.positions) {
            return Err(err(format!(
                "SfM mesh: expected ≥ 3 finite vertices, found {} (or non-finite ones)",
                mesh.positions.len()
            )));
        }
        if !all_finite(laser) {
            return Err(err(
                "laser cloud: non-finite coordinates, expected finite metres".into(),
            ));
        }
        let by_control = match control.len() {
            0 => None,
            1 | 2 => {
                return Err(err(format!(
                    "expected 0 or ≥ 3 control points, found {}",
                    control.len()
                )))
            }
            _ => {
                let (a, b): (Vec<_>, Vec<_>) = control.iter().map(|c| (c.sfm, c.ground)).unzip();
                let fit = fit_transform(&a, &b, true).filter(|f| f.scale > 0.0);
                Some(fit.map(|f| Similarity::from(&f)).ok_or_else(|| {
                    err(
                        "control points are collinear or coincident; expected ≥ 3 spread points"
                            .into(),
                    )
                })?)
            }
        };
        let (similarity, coarse, icp, height_fit, method) = if laser.is_empty() {
            let sim = by_control.ok_or_else(|| {
                err("no laser points and no control points; expected one of them".into())
            })?;
            (sim, None, None, None, "control")
        } else {
            let (src, _) = thin(&mesh.positions, p.samples)
                .ok_or_else(|| err("SfM mesh is degenerate (flat in two directions)".into()))?;
            let (tgt, _) = thin(laser, p.samples)
                .ok_or_else(|| err("laser cloud is degenerate (flat in two directions)".into()))?;
            let laser_frame =
                PcaFrame::of(&tgt).ok_or_else(|| err("laser cloud is degenerate".into()))?;
            let tol = p.convergence * laser_frame.planar_radius();
            let target = Target::new(tgt, p.normal_k)
                .ok_or_else(|| err("laser cloud is empty after thinning".into()))?;
            let (init, coarse, method) = match by_control {
                Some(sim) => (sim, None, "control+laser"),
                None => {
                    let (sim, report) = self.coarse(cx, &target, &src, &laser_frame, tol)?;
                    (sim, Some(report), "laser")
                }
            };
            // With control points their scale is kept: the laser refines rotation and
            // translation only (see the module notes).
            let run = target.icp(&src, init, &self.settings(false, by_control.is_none(), tol));
            if (run.sim.scale / init.scale - 1.0).abs() > 0.2 {
                cx.reporter.warn(Self::NAME, "sfm-scale-drift", format!("ICP moved the scale from {:.4} to {:.4}: do both clouds cover the same area?", init.scale, run.sim.scale));
            }
            let report = IcpReport {
                rms_point_to_plane_m: run.rms_plane,
                rms_nearest_m: run.rms_nearest,
                inliers: run.inliers,
                iterations: run.iterations,
                converged: run.converged,
                samples: [src.len(), target.points.len()],
            };
            // Without control points the scale comes from the laser: finish on its height
            // surface (see `sfm_height_fit`).
            let (sim, height_fit) = match by_control {
                Some(_) => (run.sim, None),
                None => self.height_fit(cx, laser, &src, run.sim, &target, tol),
            };
            (sim, coarse, Some(report), height_fit, method)
        };
        let control = (!control.is_empty()).then(|| {
            let residuals_m: Vec<(String, f64)> = control
                .iter()
                .map(|c| {
                    (
                        c.name.clone(),
                        (Vector3::from(similarity.apply(c.sfm)) - Vector3::from(c.ground)).norm(),
                    )
                })
                .collect();
            let d: Vec<f64> = residuals_m.iter().map(|r| r.1).collect();
            ControlReport {
                rms_m: rms(&d),
                residuals_m,
            }
        });
        let (heights, difference) = match laser.is_empty() {
            true => (None, None),
            false => self.heights(cx, mesh, &similarity, laser)?,
        };
        let r = similarity.rotation_matrix();
        let (roll, pitch, yaw) = Rotation3::from_matrix_unchecked(r).euler_angles();
        let angles = Angles {
            roll_deg: roll.to_degrees(),
            pitch_deg: pitch.to_degrees(),
            yaw_deg: yaw.to_degrees(),
            total_deg: similarity.angle_to_deg(&Similarity::IDENTITY),
        };
        let report = AlignReport {
            stage: Self::NAME,
            version: Self::VERSION,
            method,
            similarity,
            rotation_xyzw: quat_from_matrix(similarity.rotation),
            angles,
            coarse,
            icp,
            height_fit,
            control,
            heights,
        };
        Ok(AlignOutput {
            similarity,
            report,
            difference,
        })
    }

    /// The height fit from the scaled ICP's result `init`, on cells of about
    /// `HEIGHT_CELL_POINTS` laser points. Falls back to `init` (with a warning) when the surface
    /// cannot be built.
    fn height_fit(
        &self,
        cx: &StageCx,
        laser: &[[f64; 3]],
        src: &[[f64; 3]],
        init: Similarity,
        target: &Target,
        tol: f64,
    ) -> (Similarity, Option<HeightFitReport>) {
        let p = &self.params;
        let Some(surface) = HeightSurface::new(laser, HEIGHT_CELL_POINTS, MAX_SLOPE, p.max_cells)
        else {
            cx.reporter.warn(
                Self::NAME,
                "sfm-height-fit",
                "the laser height surface could not be built; keeping the ICP result",
            );
            return (init, None);
        };
        let settings = HeightFitSettings {
            iterations: p.iterations,
            with_scale: true,
            reject_factor: p.reject_factor,
            tol_m: tol,
        };
        let run = fit(&surface, src, init, &target.centroid(), &settings);
        let report = HeightFitReport {
            cell_m: surface.cell_m(),
            rms_m: run.rms_m,
            inliers: run.inliers,
            iterations: run.iterations,
            converged: run.converged,
        };
        (run.sim, Some(report))
    }

    /// ICP settings of a coarse candidate's short run or of the final run.
    fn settings(&self, coarse: bool, with_scale: bool, tol_m: f64) -> IcpSettings {
        let p = &self.params;
        IcpSettings {
            iterations: if coarse {
                p.coarse_iterations
            } else {
                p.iterations
            },
            with_scale,
            reject_factor: p.reject_factor,
            score_fraction: p.score_fraction,
            tol_m,
            horizontal: !coarse && with_scale,
        }
    }

    /// The coarse search: every candidate runs a short fixed-scale ICP on a random subsample.
    fn coarse(
        &self,
        cx: &StageCx,
        target: &Target,
        src: &[[f64; 3]],
        laser: &PcaFrame,
        tol: f64,
    ) -> Result<(Similarity, CoarseReport), StageError> {
        let p = &self.params;
        let sfm = PcaFrame::of(src)
            .ok_or_else(|| StageError::new(Self::NAME, "SfM samples are degenerate"))?;
        let laser = laser.oriented_up(&Vector3::z());
        let cands = candidates(&sfm, &laser, p.yaw_step_deg);
        let mut rng = cx.rng(Self::NAME);
        let mut idx = sample(&mut rng, src.len(), p.coarse_samples.min(src.len())).into_vec();
        idx.sort_unstable();
        let sub: Vec<[f64; 3]> = idx.iter().filter_map(|&i| src.get(i)).copied().collect();
        let runs: Vec<IcpRun> = cands
            .par_iter()
            .map(|c| target.icp(&sub, c.similarity, &self.settings(true, false, tol)))
            .collect();
        let (best_i, best) = runs
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.score.total_cmp(&b.1.score))
            .ok_or_else(|| StageError::new(Self::NAME, "no coarse candidates"))?;
        let runner_up_m = runs
            .iter()
            .filter(|r| r.sim.angle_to_deg(&best.sim) > 10.0)
            .map(|r| r.score)
            .min_by(f64::total_cmp);
        if runner_up_m.is_some_and(|r| r < 1.2 * best.score) {
            cx.reporter.warn(
                Self::NAME,
                "sfm-coarse-ambiguous",
                format!(
                    "two orientations fit almost equally well ({:.4} vs {:.4} m nearest-distance quantile)",
                    best.score,
                    runner_up_m.unwrap_or(0.0)
                ),
            );
        }
        let cand = cands
            .get(best_i)
            .ok_or_else(|| StageError::new(Self::NAME, "coarse candidate index out of range"))?;
        let report = CoarseReport {
            candidates: cands.len(),
            initial_scale: cand.similarity.scale,
            flipped: cand.flipped,
            yaw_deg: cand.yaw_deg,
            score_m: best.score,
            runner_up_m,
        };
        Ok((best.sim, report))
    }
}

impl AlignSfm {
    /// The height comparison of the aligned mesh (warns when the surfaces do not overlap).
    fn heights(
        &self,
        cx: &StageCx,
        mesh: &TriMesh,
        sim: &Similarity,
        laser: &[[f64; 3]],
    ) -> Result<(Option<HeightComparison>, Option<DifferenceGrid>), StageError> {
        let p = &self.params;
        let aligned = mesh.positions.par_iter().map(|q| sim.apply(*q)).collect();
        match compare_heights(
            aligned,
            &mesh.triangles,
            laser,
            p.grid_cell_m,
            p.histogram_bins,
            p.max_cells,
        ) {
            Ok(Some((h, g))) => Ok((Some(h), Some(g))),
            Ok(None) => {
                let m =
                    "the aligned SfM mesh and the laser cloud share no grid cell with both heights";
                cx.reporter.warn(Self::NAME, "sfm-no-overlap", m);
                Ok((None, None))
            }
            Err(e) => Err(StageError::new(
                Self::NAME,
                format!("height comparison: {e}"),
            )),
        }
    }
}

impl Stage for AlignSfm {
    const NAME: &'static str = "sfm.align";
    const VERSION: u32 = 3;
    const DESCRIPTION: &'static str =
        "Align an SfM mesh (arbitrary similarity frame) to the laser cloud or control points: coarse search + scaled ICP; height-difference report";
    type Input = AlignInput;
    type Output = AlignOutput;

    fn params(&self) -> serde_json::Value {
        serde_json::to_value(&self.params).unwrap_or(serde_json::Value::Null)
    }

    fn run(&self, cx: &StageCx, input: &AlignInput) -> Result<AlignOutput, StageError> {
        self.align(cx, &input.mesh, &input.laser, &input.control)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// An asymmetric synthetic terrain, 2.0 x 1.6 m: two hills, a pit and ripples.
    fn surface(x: f64, y: f64) -> f64 {
        let g = |cx: f64, cy: f64, w: f64| (-((x - cx).powi(2) + (y - cy).powi(2)) / w).exp();
        0.15 * g(0.5, 1.2, 0.08) + 0.08 * g(1.5, 0.4, 0.03) - 0.1 * g(1.3, 1.25, 0.05)
            + 0.02 * (7.0 * x).sin() * (5.0 * y).cos()
    }

    /// Laser-like points (1 cm, jittered, 3 mm noise, one occluded patch), ground frame.
    fn laser() -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut v = Vec::new();
        for i in 0..200 {
            for j in 0..160 {
                let x = (i as f64 + rng.gen_range(0.0..1.0)) * 0.01;
                let y = (j as f64 + rng.gen_range(0.0..1.0)) * 0.01;
                if (x - 1.7).hypot(y - 1.3) > 0.15 {
                    v.push([x, y, surface(x, y) + rng.gen_range(-0.005..0.005)]);
                }
            }
        }
        v
    }

    /// The SfM mesh (2 cm grid, 5 mm noise) mapped into the SfM frame by `ground_to_sfm`.
    fn sfm_mesh(ground_to_sfm: &Similarity) -> TriMesh {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (w, h) = (101u32, 81u32);
        let mut positions = Vec::new();
        for r in 0..h {
            for c in 0..w {
                let (x, y) = (c as f64 * 0.02, 1.6 - r as f64 * 0.02);
                let z = surface(x, y) + rng.gen_range(-0.008..0.008);
                positions.push(ground_to_sfm.apply([x, y, z]));
            }
        }
        let mut triangles = Vec::new();
        for r in 0..h - 1 {
            for c in 0..w - 1 {
                let nw = r * w + c;
                triangles.push([nw, nw + w + 1, nw + 1]);
                triangles.push([nw, nw + w, nw + w + 1]);
            }
        }
        TriMesh {
            positions,
            triangles,
            ..TriMesh::default()
        }
    }

    fn truth(roll: f64, pitch: f64, yaw: f64) -> Similarity {
        let r = Rotation3::from_euler_angles(roll, pitch, yaw).into_inner();
        Similarity::from_parts(1.0 / 0.68, &r, &Vector3::new(3.0, -4.0, 1.5))
    }

    fn params() -> AlignParams {
        AlignParams {
            samples: 15_000,
            ..AlignParams::default()
        }
    }

    /// Scale 0.5 %, rotation 0.5°, translation 1 cm at the terrain centre.
    fn assert_recovers(found: &Similarity, ground_to_sfm: &Similarity) {
        let want = ground_to_sfm.inverse();
        assert!(
            (found.scale / want.scale - 1.0).abs() < 0.005,
            "scale {} vs {}",
            found.scale,
            want.scale
        );
        assert!(
            found.angle_to_deg(&want) < 0.5,
            "rotation off by {}°",
            found.angle_to_deg(&want)
        );
        let centre = ground_to_sfm.apply([1.0, 0.8, 0.0]);
        let d = Vector3::from(found.apply(centre)) - Vector3::from(want.apply(centre));
        assert!(d.norm() < 0.01, "translation off by {} m", d.norm());
    }

    #[test]
    fn similarity_inverse_and_compose() {
        let t = truth(0.3, -1.1, 2.0);
        let p = [0.4, -2.0, 7.0];
        let back = t.inverse().apply(t.apply(p));
        assert!((Vector3::from(back) - Vector3::from(p)).norm() < 1e-12);
        let c = t.compose(&t.inverse());
        assert!((c.scale - 1.0).abs() < 1e-12 && c.angle_to_deg(&Similarity::IDENTITY) < 1e-6);
        assert!(Vector3::from(c.translation).norm() < 1e-12);
        let m = t.to_matrix4();
        let q = crate::ingest::types::transform(&m, p);
        assert!((Vector3::from(q) - Vector3::from(t.apply(p))).norm() < 1e-12);
    }

    #[test]
    fn aligns_from_arbitrary_rotations_without_a_guess() {
        let laser = laser();
        let stage = AlignSfm::new(params()).unwrap();
        // A generic rotation, an upside-down one and a 90° tilt with a yaw.
        for (roll, pitch, yaw) in [
            (0.7, -0.4, 2.2),
            (std::f64::consts::PI, 0.0, 0.65),
            (0.0, std::f64::consts::FRAC_PI_2, -2.4),
        ] {
            let t = truth(roll, pitch, yaw);
            let cx = StageCx::default();
            let out = stage.align(&cx, &sfm_mesh(&t), &laser, &[]).unwrap();
            assert_recovers(&out.similarity, &t);
            assert_eq!(out.report.method, "laser");
            let icp = out.report.icp.as_ref().unwrap();
            assert!(icp.converged && icp.inliers > 1000);
            // Noise: laser ±5 mm and SfM ±8 mm uniform → point-to-plane RMS ≈ 5 mm.
            assert!(icp.rms_point_to_plane_m < 0.008, "{icp:?}");
            let h = out.report.heights.as_ref().unwrap();
            assert!(h.mean_m.abs() < 0.003 && h.rms_m < 0.01, "{h:?}");
            let g = out.difference.as_ref().unwrap();
            assert_eq!(g.values.len(), g.cols * g.rows);
            // The occluded laser patch is NaN in the difference grid.
            let (c, r) = (
                ((1.7 - g.origin[0]) / g.cell_m).round(),
                ((g.origin[1] - 1.3) / g.cell_m).round(),
            );
            assert!(g.values[r as usize * g.cols + c as usize].is_nan());
            assert_eq!(
                h.laser_heights.counts.iter().sum::<u64>() as usize,
                h.cells_compared
            );
        }
    }

    #[test]
    fn deterministic_and_reported_as_json() {
        let t = truth(-0.2, 0.9, 0.1);
        let (mesh, laser) = (sfm_mesh(&t), laser());
        let stage = AlignSfm::new(params()).unwrap();
        let cx = StageCx {
            seed: 5,
            ..StageCx::default()
        };
        let a = stage
            .run(
                &cx,
                &AlignInput {
                    mesh: mesh.clone(),
                    laser: laser.clone(),
                    control: vec![],
                },
            )
            .unwrap();
        let b = stage.align(&cx, &mesh, &laser, &[]).unwrap();
        assert_eq!(a.similarity, b.similarity);
        let json = serde_json::to_value(&a.report).unwrap();
        assert_eq!(json["stage"], "sfm.align");
        let q = json["rotation_xyzw"].as_array().unwrap();
        let norm: f64 = q.iter().map(|v| v.as_f64().unwrap().powi(2)).sum();
        assert!((norm - 1.0).abs() < 1e-9);
        assert!(
            json["heights"]["differences"]["counts"]
                .as_array()
                .unwrap()
                .len()
                == 64
        );
    }

    #[test]
    fn control_points_fix_the_scale_and_the_laser_refines_the_pose() {
        let t = truth(0.4, -0.2, 1.3);
        let mesh = sfm_mesh(&t);
        // Four markers with ±2 mm picking noise (ground frame).
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let control: Vec<ControlPoint> = [
            [0.2, 0.2, 0.0],
            [1.8, 0.3, 0.05],
            [1.1, 1.4, 0.1],
            [0.3, 1.3, -0.02],
        ]
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let n = [(); 3].map(|_| rng.gen_range(-0.002..0.002));
            ControlPoint {
                name: format!("gcp{i}"),
                sfm: t.apply([g[0] + n[0], g[1] + n[1], g[2] + n[2]]),
                ground: *g,
            }
        })
        .collect();
        let stage = AlignSfm::new(params()).unwrap();
        let cx = StageCx::default();
        let only = stage.align(&cx, &mesh, &[], &control).unwrap();
        let both = stage.align(&cx, &mesh, &laser(), &control).unwrap();
        assert_eq!(both.report.method, "control+laser");
        assert_eq!(
            both.similarity.scale, only.similarity.scale,
            "the control points' scale is kept"
        );
        assert_recovers(&both.similarity, &t);
        let icp = both.report.icp.as_ref().unwrap();
        assert!(icp.converged && icp.rms_point_to_plane_m < 0.008, "{icp:?}");
        let c = both.report.control.as_ref().unwrap();
        assert_eq!(c.residuals_m.len(), 4);
        assert!(c.rms_m < 0.01, "{c:?}");
        assert!(both.report.heights.is_some() && only.report.heights.is_none());
    }

    #[test]
    fn control_points_give_the_similarity_directly() {
        let t = truth(2.0, 0.3, -1.0);
        let mesh = sfm_mesh(&t);
        let control: Vec<ControlPoint> = [
            [0.1, 0.1, 0.0],
            [1.9, 0.2, 0.05],
            [1.0, 1.5, 0.1],
            [0.3, 1.4, -0.02],
        ]
        .iter()
        .enumerate()
        .map(|(i, g)| ControlPoint {
            name: format!("gcp{i}"),
            sfm: t.apply(*g),
            ground: *g,
        })
        .collect();
        let stage = AlignSfm::default();
        let out = stage
            .align(&StageCx::default(), &mesh, &[], &control)
            .unwrap();
        assert_eq!(out.report.method, "control");
        assert!(out.report.control.as_ref().unwrap().rms_m < 1e-9);
        assert_recovers(&out.similarity, &t);
        let err = stage
            .align(&StageCx::default(), &mesh, &[], &control[..2])
            .unwrap_err();
        assert!(err.to_string().contains("found 2"), "{err}");
        let empty = TriMesh::default();
        assert!(stage
            .align(&StageCx::default(), &empty, &laser(), &[])
            .is_err());
        assert!(stage.align(&StageCx::default(), &mesh, &[], &[]).is_err());
        assert!(AlignSfm::new(AlignParams {
            score_fraction: 0.0,
            ..AlignParams::default()
        })
        .is_err());
    }
}
