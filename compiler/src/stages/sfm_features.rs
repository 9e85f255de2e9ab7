//! The geometric engine of `sfm.align`: uniform thinning of large clouds, the PCA frame of a
//! terrain patch, the rotation/scale candidates that start ICP without any guess, and the
//! trimmed, scaled ICP itself, and the SfM − laser height grid (the stage file keeps the
//! orchestration and the report).
//!
//! Design decisions:
//! - **Uniform samples.** Laser clouds are dense near the stations and sparse far away; SfM
//!   vertices are regular. Both are thinned to voxel centroids so that every statistic below
//!   (centroid, covariance, ICP residuals) weights the *surface* evenly rather than the scanner
//!   geometry. Very large clouds are first strided down to `16 × target` points (deterministic, no
//!   RNG), so a 14 M point cloud costs one pass plus a sort of ~1 M keys. The voxel side is chosen
//!   from the PCA area estimate `12·σ1·σ2` (a rectangle of sides `L` has variance `L²/12`), so the
//!   same code works in metres and in arbitrary SfM units.
//! - **A terrain patch defines a frame.** Its smallest-variance axis is the surface normal ("up")
//!   and the two larger eigenvalues measure its horizontal extent. Both clouds cover the same area
//!   (that is the contract of `align = "laser"`), so `√((λ1+λ2)_laser / (λ1+λ2)_sfm)` is the scale up
//!   to a few percent, which scaled ICP then removes.
//! - **Candidates instead of descriptors.** The in-plane axes of a near-square patch are
//!   ill-defined (λ1 ≈ λ2) and the sign of the SfM "up" is unknown, so instead of trusting the
//!   eigenvectors we enumerate both up signs × a full yaw circle in fixed steps. Each candidate is
//!   scored by a short ICP run in `sfm_align`, which is more robust on smooth terrain than
//!   FPFH-style local descriptors and needs no tuning radius in unknown units.
//! - **ICP** is point-to-plane with scale, solved by Gauss–Newton (7 unknowns: rotation, translation,
//!   log-scale). Each iteration pairs every SfM sample with its nearest laser sample — in the
//!   final run, when it solves the scale, the nearest in (x, y), once "up" is the ground's z: the SfM noise is mostly
//!   vertical, and with 3-D pairing it picks the laser sample (on ten mini seeds the scale error
//!   went from −0.48 % mean, 7 of 10 beyond 0.5 %, to −0.21 %, 2 of 10; estec stays within
//!   0.005 %) — and that sample's local plane (normal and centroid of `normal_k` neighbours, computed once; the
//!   centroid averages the range noise: 0.76 % → 0.42 % scale error on the mini corpus) and drops pairs ending on the laser's
//!   boundary (outer edge, occlusion holes: an SfM point hanging over an edge would otherwise pull
//!   the scale down) and pairs beyond `reject_factor` × the median distance (SfM areas the laser
//!   never saw, noise). A fixed-fraction quantile trim was tried first: points crossing the
//!   quantile made the solution jitter by ~1e-4 of the extent and never converge; closed-form
//!   Umeyama on foot points converged too slowly along the surface (2° off after 100
//!   iterations). With `with_scale = false` the scale stays at the start value (the coarse search
//!   needs that, see `sfm_align`). Correspondences are an indexed parallel map and the normal
//!   equations are summed per fixed chunk in order, so runs are thread-count independent. The
//!   Gauss–Newton step (`solve_step`, `iterate`) is shared with `sfm_height_fit`, which finishes a
//!   laser-only alignment on a smooth laser height surface.
//! - **Height grid.** The aligned mesh goes through `dem.raster`'s rasteriser (one shared
//!   implementation of the grid convention, linear inside triangles, long-edge holes), while the
//!   laser points are binned to per-cell means in one sequential pass: rasterising a 14 M point
//!   cloud would first need its Delaunay triangulation, and at 1–2 cm cells the laser is dense
//!   enough that the mean is the better estimate of the cell height anyway.

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, SymmetricEigen, Vector3};
use rayon::prelude::*;

use serde::Serialize;

use super::dem_raster::{DemRaster, MaxEdge};
use super::dem_tin::Tin;
use super::geometry::{build_tree, fit_plane, knn, mean_std, rms, Tree3};
use super::sfm_align::Similarity;

/// The mean and principal axes of a cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct PcaFrame {
    /// Mean of the points.
    pub centroid: Vector3<f64>,
    /// Eigenvalues of the covariance, descending.
    pub eigenvalues: [f64; 3],
    /// Right-handed orthonormal axes (columns) matching `eigenvalues`; column 2 is the normal.
    pub axes: Matrix3<f64>,
}

impl PcaFrame {
    /// The PCA frame of `points` (`None` when empty, non-finite or flat in two directions).
    pub fn of(points: &[[f64; 3]]) -> Option<PcaFrame> {
        if points.len() < 3 {
            return None;
        }
        let n = points.len() as f64;
        let centroid = points
            .iter()
            .map(|p| Vector3::from(*p))
            .sum::<Vector3<f64>>()
            / n;
        let cov = points.iter().fold(Matrix3::zeros(), |acc, p| {
            let d = Vector3::from(*p) - centroid;
            acc + d * d.transpose()
        }) / n;
        if !cov.iter().all(|v| v.is_finite()) {
            return None;
        }
        let eig = SymmetricEigen::new(cov);
        let mut pairs: Vec<(f64, Vector3<f64>)> = eig
            .eigenvalues
            .iter()
            .zip(eig.eigenvectors.column_iter())
            .map(|(l, c)| (*l, c.normalize()))
            .collect();
        pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
        let [(l0, e0), (l1, e1), (l2, _)] = pairs.as_slice() else {
            return None;
        };
        if l1.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let eigenvalues = [*l0, *l1, *l2];
        let axes = Matrix3::from_columns(&[*e0, *e1, e0.cross(e1)]);
        Some(PcaFrame {
            centroid,
            eigenvalues,
            axes,
        })
    }

    /// `√(λ1 + λ2)`: the RMS horizontal radius of the patch about its centroid.
    pub fn planar_radius(&self) -> f64 {
        (self.eigenvalues[0] + self.eigenvalues[1]).sqrt()
    }

    /// The same frame turned 180° about its first axis when the normal points against `up`.
    pub fn oriented_up(&self, up: &Vector3<f64>) -> PcaFrame {
        let mut f = self.clone();
        if f.axes.column(2).dot(up) < 0.0 {
            f.axes = self.axes * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
        }
        f
    }
}

/// Neighbour-centroid offset (fraction of the neighbourhood radius) that marks a boundary sample.
const BOUNDARY_OFFSET: f64 = 0.25;

/// One coarse hypothesis: which way the SfM normal points and the yaw about the laser normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// True when the SfM normal (as PCA returned it) is mapped onto the laser's *down*.
    pub flipped: bool,
    /// Rotation about the laser normal, degrees.
    pub yaw_deg: f64,
    /// The resulting SfM → ground similarity.
    pub similarity: Similarity,
}

/// Both up signs × yaw steps of `yaw_step_deg`, each mapping the SfM centroid onto the laser
/// centroid with the extent-ratio scale. `laser` must be oriented with its normal up.
pub fn candidates(sfm: &PcaFrame, laser: &PcaFrame, yaw_step_deg: f64) -> Vec<Candidate> {
    let scale = laser.planar_radius() / sfm.planar_radius();
    let steps = (360.0 / yaw_step_deg).round().max(1.0) as usize;
    let flip = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    [false, true]
        .iter()
        .flat_map(|&flipped| (0..steps).map(move |k| (flipped, k as f64 * 360.0 / steps as f64)))
        .map(|(flipped, yaw_deg)| {
            let src_axes = if flipped { sfm.axes * flip } else { sfm.axes };
            let yaw = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians());
            let r = laser.axes * yaw.matrix() * src_axes.transpose();
            let t = laser.centroid - r * sfm.centroid * scale;
            Candidate {
                flipped,
                yaw_deg,
                similarity: Similarity::from_parts(scale, &r, &t),
            }
        })
        .collect()
}

/// Thins `points` to roughly `target` voxel centroids (see the module doc); output sorted by
/// voxel key, so it is independent of the thread count. Returns the points and the voxel side.
///
/// The voxel side comes from the area of the 1–99 % box of the points in their PCA plane (which,
/// unlike the variances, does not depend on where the points are dense), corrected once by the
/// ratio of the count obtained to the target when a folded surface gives far more voxels.
pub fn thin(points: &[[f64; 3]], target: usize) -> Option<(Vec<[f64; 3]>, f64)> {
    let target = target.max(1);
    let stride = (points.len() / target.saturating_mul(16)).max(1);
    let pre: Vec<[f64; 3]> = points.iter().step_by(stride).copied().collect();
    let frame = PcaFrame::of(&pre)?;
    let extent = |axis: usize| {
        let a = frame.axes.column(axis);
        let mut d: Vec<f64> = pre
            .iter()
            .map(|p| a.dot(&(Vector3::from(*p) - frame.centroid)))
            .collect();
        Some(quantile(&mut d, 0.99)? - quantile(&mut d, 0.01)?)
    };
    let mut voxel = (extent(0)? * extent(1)? / target as f64).sqrt();
    for pass in 0..2 {
        if !(voxel.is_finite() && voxel > 0.0) {
            return None;
        }
        let out = voxel_centroids(&pre, &frame.centroid, voxel);
        let ratio = out.len() as f64 / target as f64;
        if pass == 1 || (0.5..=2.0).contains(&ratio) {
            return Some((out, voxel));
        }
        voxel *= ratio.sqrt();
    }
    None
}

/// Centroids of the points in each occupied voxel of side `voxel` (grid anchored at `origin`).
fn voxel_centroids(points: &[[f64; 3]], origin: &Vector3<f64>, voxel: f64) -> Vec<[f64; 3]> {
    let mut keyed: Vec<([i64; 3], usize)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let d = (Vector3::from(*p) - origin) / voxel;
            (
                [d.x.floor() as i64, d.y.floor() as i64, d.z.floor() as i64],
                i,
            )
        })
        .collect();
    keyed.par_sort_unstable();
    keyed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|g| {
            let sum = g
                .iter()
                .filter_map(|(_, i)| points.get(*i))
                .fold(Vector3::zeros(), |s, p| s + Vector3::from(*p));
            (sum / g.len() as f64).into()
        })
        .collect()
}

/// The `q` quantile (0..=1, nearest rank) of `values` (reorders them); `None` when empty.
pub(super) fn quantile(values: &mut [f64], q: f64) -> Option<f64> {
    let last = values.len().checked_sub(1)?;
    let k = ((values.len() as f64 * q).ceil() as usize)
        .saturating_sub(1)
        .min(last);
    Some(*values.select_nth_unstable_by(k, f64::total_cmp).1)
}

/// The laser samples with their kd-tree, local normals and boundary flags.
pub struct Target {
    /// The samples, ground frame.
    pub points: Vec<[f64; 3]>,
    /// Local plane per sample: unit normal and neighbourhood centroid (`None` where the
    /// neighbourhood is not planar). Residuals are taken to the centroid's plane, which averages
    /// the laser range noise over `k` points.
    planes: Vec<Option<LocalPlane>>,
    /// True for samples on the edge of the cloud (outer edge or an occlusion hole).
    boundary: Vec<bool>,
    /// Centroid of the samples (the pivot of the Gauss–Newton steps).
    centroid: Vector3<f64>,
    tree: Tree3,
    /// The samples' (x, y), for horizontal pairing.
    tree_xy: kiddo::ImmutableKdTree<f64, 2>,
}

/// A laser sample's local plane: unit normal and neighbourhood centroid.
type LocalPlane = (Vector3<f64>, Vector3<f64>);

/// One correspondence: SfM sample index, its linearised residual, the nearest distance.
struct Pair {
    src: usize,
    row: Row,
    nearest: f64,
}

/// One linearised residual of a similarity fit: `r = n·(x − q)` for an SfM sample `x` mapped by the
/// current similarity and a surface point `q`, with `foot` the point the Jacobian is evaluated at.
///
/// The foot is on the target surface (the perpendicular's foot for point-to-plane pairs, the point
/// straight below or above `x` for height residuals), not the noisy `x`: the SfM noise lies mostly
/// along `n`, and in the scale column `n·(x − c)` it would correlate with the residual, so the
/// least-squares scale would shrink the mesh to shrink its noise (measured: −3 % on the mini
/// corpus, whose SfM noise σ is 1.2–2.6 cm on a relief of a few cm). At the foot the column is
/// noise-free (an instrumental variable); the fixed point is the same for noise-free data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Row {
    /// Where the Jacobian is evaluated.
    pub foot: Vector3<f64>,
    /// Residual direction (a unit normal, or `(−∂h/∂x, −∂h/∂y, 1)` for height residuals).
    pub n: Vector3<f64>,
    /// The residual.
    pub r: f64,
}

/// Gauss–Newton iterations of [`solve_step`] from `init`: `rows_at(sim)` linearises at `sim` and
/// names the samples of `src` whose motion decides convergence (RMS below `tol_m`). Returns the
/// similarity, the iterations run and whether it converged.
pub(super) fn iterate(
    init: Similarity,
    iterations: usize,
    tol_m: f64,
    pivot: &Vector3<f64>,
    with_scale: bool,
    mut rows_at: impl FnMut(&Similarity) -> (Vec<Row>, Vec<usize>),
    src: &[[f64; 3]],
) -> (Similarity, usize, bool) {
    let mut sim = init;
    let mut done = 0;
    while done < iterations {
        let (rows, moved) = rows_at(&sim);
        let Some(step) = solve_step(&rows, pivot, with_scale) else {
            break;
        };
        let next = step.compose(&sim);
        let motion: Vec<f64> = moved
            .iter()
            .filter_map(|&i| src.get(i))
            .map(|p| (Vector3::from(next.apply(*p)) - Vector3::from(sim.apply(*p))).norm())
            .collect();
        sim = next;
        done += 1;
        if rms(&motion) < tol_m {
            return (sim, done, true);
        }
    }
    (sim, done, false)
}

/// One Gauss–Newton step of a similarity fit to `rows`, as a similarity applied after the current
/// one: `x ↦ c + e^σ·R(ω)·(x − c) + v` about the pivot `c` (near the data centroid, which keeps
/// the scale and rotation columns well conditioned). Jacobian row `[(f − c) × n, n, n·(f − c)]`
/// at the foot `f` (see [`Row`]). Normal equations are summed per fixed chunk, then in chunk
/// order (thread-count independent). `None` when they are singular.
pub(super) fn solve_step(rows: &[Row], c: &Vector3<f64>, with_scale: bool) -> Option<Similarity> {
    let keep_scale = if with_scale { 1.0 } else { 0.0 };
    let parts: Vec<(SMatrix<f64, 7, 7>, SVector<f64, 7>)> = rows
        .par_chunks(4096)
        .map(|chunk| {
            chunk
                .iter()
                .fold((SMatrix::zeros(), SVector::zeros()), |(h, g), row| {
                    let fc = row.foot - c;
                    let a = fc.cross(&row.n);
                    let j = SVector::<f64, 7>::from([
                        a.x,
                        a.y,
                        a.z,
                        row.n.x,
                        row.n.y,
                        row.n.z,
                        keep_scale * row.n.dot(&fc),
                    ]);
                    (h + j * j.transpose(), g + j * row.r)
                })
        })
        .collect();
    let (mut h, g) = parts
        .iter()
        .fold((SMatrix::zeros(), SVector::zeros()), |(h, g), (ph, pg)| {
            (h + ph, g + pg)
        });
    if !with_scale {
        h += SMatrix::from_diagonal(&SVector::<f64, 7>::from([
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ]));
    }
    let d: [f64; 7] = h.cholesky()?.solve(&(-g)).into();
    let [wx, wy, wz, vx, vy, vz, sigma] = d;
    if !d.iter().all(|v| v.is_finite()) {
        return None;
    }
    let r = Rotation3::new(Vector3::new(wx, wy, wz)).into_inner();
    let s = sigma.exp();
    let t = c - r * c * s + Vector3::new(vx, vy, vz);
    Some(Similarity::from_parts(s, &r, &t))
}

/// One ICP run.
pub struct IcpRun {
    /// The final similarity.
    pub sim: Similarity,
    /// Iterations run.
    pub iterations: usize,
    /// True when the motion fell below the tolerance.
    pub converged: bool,
    /// RMS point-to-plane distance of the kept pairs.
    pub rms_plane: f64,
    /// RMS nearest distance of the kept pairs.
    pub rms_nearest: f64,
    /// Kept pairs.
    pub inliers: usize,
    /// The `score_fraction` quantile of every sample's nearest distance (no pair rejected), so
    /// candidates that keep few pairs cannot score well.
    pub score: f64,
}

/// How one ICP run iterates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpSettings {
    /// Maximum iterations.
    pub iterations: usize,
    /// Solve the scale too (else it stays at the start value).
    pub with_scale: bool,
    /// Pairs farther than this × the median nearest distance are dropped.
    pub reject_factor: f64,
    /// Quantile of the nearest distances reported as the score.
    pub score_fraction: f64,
    /// Convergence: RMS motion of the paired samples in one step, metres.
    pub tol_m: f64,
    /// Pair each sample with the laser sample nearest in (x, y) rather than in 3D (the final
    /// run when it solves the scale, once "up" is the ground's z): the SfM noise is mostly
    /// vertical, and with 3D pairing it decides which laser sample a point is paired with,
    /// which biases the scale.
    pub horizontal: bool,
}

impl Target {
    /// Builds the tree, the normals and the boundary flags from `k` neighbours. A sample is on
    /// the boundary when the centroid of its neighbours lies more than `BOUNDARY_OFFSET` × the
    /// neighbourhood radius away from it (about 0 inside, about 0.4 on an edge): pairs ending
    /// there are dropped, as Scanalyze's ICP culls mesh boundaries, because an SfM point beyond
    /// the laser's edge would otherwise pull the scale down.
    pub fn new(points: Vec<[f64; 3]>, k: usize) -> Option<Target> {
        let tree = build_tree(&points)?;
        let local: Vec<(Option<LocalPlane>, bool)> = points
            .par_iter()
            .map(|p| {
                let nn = knn(&tree, p, k);
                let radius = nn.last().map_or(0.0, |n| n.1);
                let nb: Vec<Vector3<f64>> = nn
                    .iter()
                    .filter_map(|(i, _)| points.get(*i))
                    .map(|q| Vector3::from(*q))
                    .collect();
                let Some(plane) = fit_plane(&nb) else {
                    return (None, true);
                };
                let offset = plane.centroid - Vector3::from(*p);
                let in_plane = (offset - plane.normal * plane.normal.dot(&offset)).norm();
                let local = (plane.variation < 0.2).then_some((plane.normal, plane.centroid));
                (local, in_plane > BOUNDARY_OFFSET * radius)
            })
            .collect();
        let (planes, boundary) = local.into_iter().unzip();
        let centroid = points
            .iter()
            .map(|p| Vector3::from(*p))
            .sum::<Vector3<f64>>()
            / points.len() as f64;
        let xy: Vec<[f64; 2]> = points.iter().map(|p| [p[0], p[1]]).collect();
        let tree_xy = kiddo::ImmutableKdTree::new_from_slice(&xy);
        Some(Target {
            points,
            planes,
            boundary,
            centroid,
            tree,
            tree_xy,
        })
    }

    /// Centroid of the samples.
    pub fn centroid(&self) -> Vector3<f64> {
        self.centroid
    }

    /// Correspondences of `src` mapped by `sim` with the nearest laser samples, dropping those that
    /// end on a boundary sample, on a sample without a normal, or farther than `reject_factor` ×
    /// the median nearest distance. Also returns every sample's nearest distance (for the score).
    fn pairs(
        &self,
        src: &[[f64; 3]],
        sim: &Similarity,
        reject_factor: f64,
        horizontal: bool,
    ) -> (Vec<Pair>, Vec<f64>) {
        let all: Vec<Option<(f64, Option<Pair>)>> = src
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let x = Vector3::from(sim.apply(*p));
                let (j, nearest) = if horizontal {
                    let nn = self
                        .tree_xy
                        .nearest_one::<kiddo::SquaredEuclidean>(&[x.x, x.y]);
                    let j = usize::try_from(nn.item).ok()?;
                    let q = Vector3::from(*self.points.get(j)?);
                    (j, (x - q).norm())
                } else {
                    *knn(&self.tree, &x.into(), 1).first()?
                };
                let interior = !self.boundary.get(j).copied().unwrap_or(true);
                let pair = self
                    .planes
                    .get(j)
                    .copied()
                    .flatten()
                    .filter(|_| interior)
                    .map(|(n, q)| {
                        let r = n.dot(&(x - q));
                        Pair {
                            src: i,
                            row: Row {
                                foot: x - n * r,
                                n,
                                r,
                            },
                            nearest,
                        }
                    });
                Some((nearest, pair))
            })
            .collect();
        let mut nearest: Vec<f64> = all.iter().flatten().map(|a| a.0).collect();
        let gate = reject_factor * quantile(&mut nearest, 0.5).unwrap_or(0.0);
        let pairs = all
            .into_iter()
            .flatten()
            .filter_map(|a| a.1)
            .filter(|p| p.nearest <= gate)
            .collect();
        (pairs, nearest)
    }

    /// Iterates from `init` until the samples move less than `s.tol_m` (RMS) in one step.
    pub fn icp(&self, src: &[[f64; 3]], init: Similarity, s: &IcpSettings) -> IcpRun {
        let (sim, done, converged) = iterate(
            init,
            s.iterations,
            s.tol_m,
            &self.centroid,
            s.with_scale,
            |sim| {
                let (pairs, _) = self.pairs(src, sim, s.reject_factor, s.horizontal);
                let moved = pairs.iter().map(|p| p.src).collect();
                (pairs.into_iter().map(|p| p.row).collect(), moved)
            },
            src,
        );
        let (pairs, mut nearest) = self.pairs(src, &sim, s.reject_factor, s.horizontal);
        let plane: Vec<f64> = pairs.iter().map(|p| p.row.r).collect();
        let near: Vec<f64> = pairs.iter().map(|p| p.nearest).collect();
        IcpRun {
            sim,
            iterations: done,
            converged,
            rms_plane: rms(&plane),
            rms_nearest: rms(&near),
            inliers: pairs.len(),
            score: quantile(&mut nearest, s.score_fraction).unwrap_or(f64::INFINITY),
        }
    }
}

/// A north-up grid of `sfm − laser` heights (row 0 = north, NaN where either is missing).
#[derive(Debug, Clone, PartialEq)]
pub struct DifferenceGrid {
    /// Centre of the north-west cell (x, y), ground frame.
    pub origin: [f64; 2],
    /// Cell size, metres.
    pub cell_m: f64,
    /// Columns (west to east).
    pub cols: usize,
    /// Rows (north to south).
    pub rows: usize,
    /// Differences in metres, row-major.
    pub values: Vec<f32>,
}

/// A histogram over `[min_m, max_m]` (values outside are counted in the end bins).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Histogram {
    /// Lower edge of the first bin.
    pub min_m: f64,
    /// Upper edge of the last bin.
    pub max_m: f64,
    /// Counts per bin.
    pub counts: Vec<u64>,
}

/// Height-map comparison (thesis Figs 6.2 and 6.5).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeightComparison {
    /// Grid cell, metres.
    pub cell_m: f64,
    /// Grid size (cols, rows).
    pub size: [usize; 2],
    /// Cells where both surfaces have a height.
    pub cells_compared: usize,
    /// Mean of `sfm − laser`, metres.
    pub mean_m: f64,
    /// Standard deviation of `sfm − laser`, metres.
    pub std_m: f64,
    /// RMS of `sfm − laser`, metres.
    pub rms_m: f64,
    /// 95th percentile of `|sfm − laser|`, metres.
    pub p95_abs_m: f64,
    /// Laser heights of the compared cells (same bins as `sfm_heights`).
    pub laser_heights: Histogram,
    /// SfM heights of the compared cells.
    pub sfm_heights: Histogram,
    /// Differences over mean ± 4 std.
    pub differences: Histogram,
}

/// Compares the aligned SfM mesh (`aligned` vertices, ground frame, with its `triangles`) with the
/// laser heights on one north-up grid of `cell_m` over the overlap of both extents.
///
/// `Ok(None)` when they share no cell with both heights (e.g. a mesh without triangles); `Err`
/// when the grid would exceed `max_cells`.
pub fn compare_heights(
    aligned: Vec<[f64; 3]>,
    triangles: &[[u32; 3]],
    laser: &[[f64; 3]],
    cell_m: f64,
    bins: usize,
    max_cells: u64,
) -> Result<Option<(HeightComparison, DifferenceGrid)>, String> {
    if triangles.is_empty() {
        return Ok(None);
    }
    let (Some(a), Some(b)) = (bounds(&aligned), bounds(laser)) else {
        return Ok(None);
    };
    let common = [
        a[0].max(b[0]),
        a[1].max(b[1]),
        a[2].min(b[2]),
        a[3].min(b[3]),
    ];
    if !(common[0] + cell_m <= common[2] && common[1] + cell_m <= common[3]) {
        return Ok(None);
    }
    let raster = DemRaster::new(
        vec![cell_m],
        Some(common),
        MaxEdge::SpacingFactor(4.0),
        0.0,
        max_cells,
    )
    .map_err(|e| e.message)?;
    let tin = Tin {
        vertices: aligned,
        albedo: None,
        triangles: triangles.to_vec(),
        duplicates_merged: 0,
        max_edge_m: None,
    };
    let sfm = raster
        .rasterize_all(&tin)
        .map_err(|e| e.message)?
        .into_iter()
        .next();
    let Some(sfm) = sfm else { return Ok(None) };
    // Per-cell laser means on the raster's grid (sequential: deterministic sums).
    let (cols, rows, cell) = (sfm.cols, sfm.rows, sfm.cell_m);
    let (x0, y0) = (sfm.origin[0] - 0.5 * cell, sfm.origin[1] + 0.5 * cell);
    let mut sum = vec![(0.0f64, 0u32); cols * rows];
    for q in laser {
        let (c, r) = (((q[0] - x0) / cell).floor(), ((y0 - q[1]) / cell).floor());
        if c >= 0.0 && r >= 0.0 && (c as usize) < cols && (r as usize) < rows {
            if let Some(s) = sum.get_mut(r as usize * cols + c as usize) {
                *s = (s.0 + q[2], s.1 + 1);
            }
        }
    }
    let laser_h: Vec<f64> = sum
        .iter()
        .map(|&(s, n)| if n > 0 { s / f64::from(n) } else { f64::NAN })
        .collect();
    let values: Vec<f32> = sfm
        .heights
        .iter()
        .zip(&laser_h)
        .map(|(&s, &l)| (f64::from(s) - l) as f32)
        .collect();
    let both: Vec<(f64, f64)> = sfm
        .heights
        .iter()
        .zip(&laser_h)
        .map(|(&s, &l)| (f64::from(s), l))
        .filter(|(s, l)| s.is_finite() && l.is_finite())
        .collect();
    if both.is_empty() {
        return Ok(None);
    }
    let diffs: Vec<f64> = both.iter().map(|(s, l)| s - l).collect();
    let (mean_m, std_m) = mean_std(&diffs);
    let mut abs: Vec<f64> = diffs.iter().map(|d| d.abs()).collect();
    let p95_abs_m = quantile(&mut abs, 0.95).unwrap_or(0.0);
    let (lo, hi) = both.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (s, l)| {
        (lo.min(*s).min(*l), hi.max(*s).max(*l))
    });
    let comparison = HeightComparison {
        cell_m: cell,
        size: [cols, rows],
        cells_compared: both.len(),
        mean_m,
        std_m,
        rms_m: rms(&diffs),
        p95_abs_m,
        laser_heights: histogram(both.iter().map(|b| b.1), lo, hi, bins),
        sfm_heights: histogram(both.iter().map(|b| b.0), lo, hi, bins),
        differences: histogram(
            diffs.iter().copied(),
            mean_m - 4.0 * std_m,
            mean_m + 4.0 * std_m,
            bins,
        ),
    };
    Ok(Some((
        comparison,
        DifferenceGrid {
            origin: sfm.origin,
            cell_m: cell,
            cols,
            rows,
            values,
        },
    )))
}

/// `[x_min, y_min, x_max, y_max]`.
fn bounds(points: &[[f64; 3]]) -> Option<[f64; 4]> {
    let f = points.first()?;
    Some(points.iter().fold([f[0], f[1], f[0], f[1]], |b, p| {
        [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ]
    }))
}

/// Counts `values` into `bins` equal bins over `[lo, hi]`, clamping outliers into the end bins.
fn histogram(values: impl Iterator<Item = f64>, lo: f64, hi: f64, bins: usize) -> Histogram {
    let mut counts = vec![0u64; bins];
    let width = (hi - lo) / bins as f64;
    for v in values {
        let i = if width > 0.0 {
            ((v - lo) / width).floor().clamp(0.0, bins as f64 - 1.0) as usize
        } else {
            0
        };
        if let Some(c) = counts.get_mut(i) {
            *c += 1;
        }
    }
    Histogram {
        min_m: lo,
        max_m: hi,
        counts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn patch() -> Vec<[f64; 3]> {
        let mut v = Vec::new();
        for i in 0..60 {
            for j in 0..40 {
                let (x, y) = (i as f64 * 0.05, j as f64 * 0.05);
                v.push([x, y, 0.1 * (3.0 * x).sin() * (2.0 * y).cos()]);
            }
        }
        v
    }

    #[test]
    fn pca_finds_the_normal_and_the_extent() {
        let f = PcaFrame::of(&patch()).unwrap().oriented_up(&Vector3::z());
        assert!(f.axes.column(2).dot(&Vector3::z()) > 0.99);
        assert!((f.axes.determinant() - 1.0).abs() < 1e-12);
        // A uniform 60 x 40 grid of step 0.05: variances (n² − 1)·h²/12 per axis.
        let expected = ((3600.0 - 1.0) * 0.0025 / 12.0 + (1600.0 - 1.0) * 0.0025 / 12.0f64).sqrt();
        assert!(
            (f.planar_radius() - expected).abs() < 1e-3 * expected,
            "{}",
            f.planar_radius()
        );
    }

    #[test]
    fn one_candidate_is_near_the_truth() {
        let pts = patch();
        let truth = Similarity::from_parts(
            0.68,
            &Rotation3::from_euler_angles(2.9, -0.4, 1.2).into_inner(),
            &Vector3::new(3.0, -1.0, 2.0),
        );
        let sfm: Vec<[f64; 3]> = pts.iter().map(|p| truth.inverse().apply(*p)).collect();
        let fs = PcaFrame::of(&sfm).unwrap();
        let fl = PcaFrame::of(&pts).unwrap().oriented_up(&Vector3::z());
        let c = candidates(&fs, &fl, 10.0);
        assert_eq!(c.len(), 72);
        let best = c
            .iter()
            .map(|c| c.similarity.angle_to_deg(&truth))
            .fold(f64::MAX, f64::min);
        assert!(best <= 5.0 + 1e-9, "closest candidate {best}°");
        assert!(c.iter().all(|c| (c.similarity.scale - 0.68).abs() < 1e-9));
    }

    #[test]
    fn thinning_is_uniform_and_near_the_target() {
        let mut dense = patch();
        // Add a dense clump: thinning must not let it dominate.
        dense.extend((0..20_000).map(|i| [0.5 + (i % 100) as f64 * 1e-4, 0.5, 0.0]));
        let (thin_pts, voxel) = thin(&dense, 600).unwrap();
        assert!(voxel > 0.05 && voxel < 0.2, "voxel {voxel}");
        assert!(
            thin_pts.len() > 300 && thin_pts.len() < 1200,
            "{}",
            thin_pts.len()
        );
        let near = |p: &&[f64; 3]| (p[0] - 0.505).hypot(p[1] - 0.5) < 0.02;
        assert!(thin_pts.iter().filter(near).count() <= 2);
        assert!(thin(&[], 10).is_none());
    }
}
