//! Incidence correction of the laser reflectance (part of `merge.clean`): `albedo = ρ / max(cos i,
//! MIN_COS_INCIDENCE)`, with `i` the angle between the beam and the surface normal.
//!
//! Why the normal comes from a fixed ground window and not from the `k` nearest points: `1 / cos i`
//! amplifies every error of the normal, and a normal fitted to a few nearby points of a dense
//! scan is mostly range noise. On the full-resolution estec corpus (points ~4 mm apart, 8 mm
//! range noise) the PCA normal of the 16 nearest points left the per-point albedo off by
//! 2.7 dB RMS, biased by −2.6 dB where it thought the beam was head-on and +2.3 dB where it
//! thought it grazing; the texture showed it as speckle and as steps where one station's points
//! take over from another's. The normal here is the PCA normal of all cleaned points in a
//! square ground window of [`WINDOW_CELLS`]² cells of [`NORMAL_CELL_M`] (6 cm): hundreds of
//! points at scan density, so range noise averages out, while the window stays below the size
//! of the rocks whose shading the texture must not carry.
//!
//! Known limit, the window's size: range noise lies along the beam, so it adds the beam
//! direction to the window's scatter and tilts the fitted plane towards containing the beam (by
//! about `σ² sin i cos i / L²` for an in-plane spread `L²`); `cos i` then reads low and the
//! albedo high, the more so the more grazing the beam. With this 6 cm window (8 mm range noise)
//! the estec corpus's texture comes out 4.0 % brighter than the true albedo (median 2.2 %), from
//! 2.6 % where the beam is head-on to 5.7 % where it grazes, and the cross-scan calibration takes
//! the grazing far points' excess for a range slope (−0.071 dB/m for the instrument's −0.05); a
//! response curve fitted by the gap workflow absorbs that level (estec seed 2: γ 1.968 for
//! 2.033). A 10 cm window measured better on the texture itself — estec 1.5 % (median −0.4 %),
//! slope −0.044 dB/m, stations agreeing 0.47 dB RMS instead of 0.51, that γ 2.012; mini's
//! correlation with the true albedo 0.773/0.781 → 0.781/0.798 (seeds 101/103), its stations'
//! disagreement 0.88–0.90 → 0.71 dB — but the smoother texture cost the gap workflow's dense
//! alignment precision on mini (a lone camera's distortion 13 → 18 % off, seed 101's `dk1` with
//! both cameras −5.1 → −7.1 %) and two weak vignettings next to another effect. Subtracting the
//! expected noise scatter (`σ² Σ d dᵀ`, the beams `d`) from the window's moments instead moved
//! the level monotonically with the assumed σ (+4.0 % at 0, −1 % at 5 mm, −6 % at 8 mm), so it
//! needs σ measured, not assumed. 8, 12.5 and 14 cm windows: 2.4, 1.1 and 1.0 % on estec.
//!
//! How: one pass bins the points by ground cell and keeps per cell the count, the sum and the
//! second moments of the coordinates relative to the cell corner (z relative to the first
//! point's z), so precision does not depend on how far the survey is from the origin. A cell's
//! window moments are the sums of its neighbours' moments moved to its corner (exact: the
//! parallel-axis shift), whose covariance's smallest eigenvector is the normal. Where points are
//! sparse (far from every station) a window with fewer than [`MIN_WINDOW_POINTS`] points or no
//! plane grows ring by ring up to [`MAX_WINDOW_CELLS`]² cells; past that, `albedo = ρ`. Cells are binned in fixed chunks merged in chunk order, so the result does
//! not depend on the thread count. Near-vertical faces are seen through a 2.5-D window: their
//! normal mixes the face with the ground around it; they are a small share of a terrain.

use std::collections::HashMap;
use std::ops::AddAssign;

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;

use super::geometry::bin_sums;

/// Side of the ground cells of the normal window, metres.
pub const NORMAL_CELL_M: f64 = 0.02;
/// Cells per side of the normal window (odd; the point's cell in the middle): 6 cm (module docs).
pub const WINDOW_CELLS: i64 = 3;
/// Cells per side of the largest window, grown to where points are sparse (odd; 18 cm).
pub const MAX_WINDOW_CELLS: i64 = 9;
/// Points a window needs for a normal.
pub const MIN_WINDOW_POINTS: u32 = 10;
/// Floor of `cos i`: the gain `1 / cos i` is at most 5 (i ≈ 78°).
pub const MIN_COS_INCIDENCE: f64 = 0.2;

/// Count, sum and second moments of points relative to a reference corner.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    n: u32,
    s: [f64; 3],
    /// xx, xy, xz, yy, yz, zz.
    ss: [f64; 6],
}

impl Moments {
    fn of(d: [f64; 3]) -> Moments {
        Moments {
            n: 1,
            s: d,
            ss: [
                d[0] * d[0],
                d[0] * d[1],
                d[0] * d[2],
                d[1] * d[1],
                d[1] * d[2],
                d[2] * d[2],
            ],
        }
    }

    /// The same points with the reference moved by `-t` (every `d` becomes `d + t`).
    fn shifted(&self, t: [f64; 3]) -> Moments {
        let n = f64::from(self.n);
        let s = self.s;
        let pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        let mut ss = self.ss;
        for (k, &(a, b)) in pairs.iter().enumerate() {
            ss[k] += s[a] * t[b] + t[a] * s[b] + n * t[a] * t[b];
        }
        Moments {
            n: self.n,
            s: [s[0] + n * t[0], s[1] + n * t[1], s[2] + n * t[2]],
            ss,
        }
    }

    /// Unit normal of the least-squares plane, `None` without a plane.
    fn normal(&self) -> Option<Vector3<f64>> {
        if self.n < 3 {
            return None;
        }
        let n = f64::from(self.n);
        let m = [self.s[0] / n, self.s[1] / n, self.s[2] / n];
        let c = |k: usize, a: usize, b: usize| self.ss[k] / n - m[a] * m[b];
        let cov = Matrix3::new(
            c(0, 0, 0),
            c(1, 0, 1),
            c(2, 0, 2),
            c(1, 0, 1),
            c(3, 1, 1),
            c(4, 1, 2),
            c(2, 0, 2),
            c(4, 1, 2),
            c(5, 2, 2),
        );
        let eig = SymmetricEigen::new(cov);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        // A plane needs two clearly non-zero spreads; a line of points has one.
        let (lmin, lmid) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]]);
        if !(lmid > 1e-12 && lmid > 4.0 * lmin.max(0.0)) {
            return None;
        }
        let v = eig.eigenvectors.column(order[0]).into_owned();
        v.iter().all(|x| x.is_finite()).then_some(v)
    }
}

impl AddAssign for Moments {
    fn add_assign(&mut self, o: Moments) {
        self.n += o.n;
        for (a, b) in self.s.iter_mut().zip(o.s) {
            *a += b;
        }
        for (a, b) in self.ss.iter_mut().zip(o.ss) {
            *a += b;
        }
    }
}

/// The ground cell of `p`.
fn cell(p: &[f64; 3]) -> (i64, i64) {
    (
        (p[0] / NORMAL_CELL_M).floor() as i64,
        (p[1] / NORMAL_CELL_M).floor() as i64,
    )
}

/// The normal of the window around cell `(cx, cy)`: [`WINDOW_CELLS`]² cells, grown ring by ring
/// up to [`MAX_WINDOW_CELLS`]² while it holds fewer than [`MIN_WINDOW_POINTS`] points or no
/// plane.
fn window_normal(cells: &HashMap<(i64, i64), Moments>, cx: i64, cy: i64) -> Option<Vector3<f64>> {
    let mut w = Moments::default();
    for h in 0..=MAX_WINDOW_CELLS / 2 {
        for dy in -h..=h {
            for dx in -h..=h {
                if dx.abs().max(dy.abs()) != h {
                    continue;
                }
                if let Some(m) = cells.get(&(cx + dx, cy + dy)) {
                    // Neighbour corner → this corner: d grows by (dx, dy) cells.
                    w += m.shifted([dx as f64 * NORMAL_CELL_M, dy as f64 * NORMAL_CELL_M, 0.0]);
                }
            }
        }
        if h >= WINDOW_CELLS / 2 && w.n >= MIN_WINDOW_POINTS {
            if let Some(n) = w.normal() {
                return Some(n);
            }
        }
    }
    None
}

/// Per point, the window normal of its cell (`None` where no plane fits).
pub fn window_normals(points: &[[f64; 3]]) -> Vec<Option<Vector3<f64>>> {
    let Some(z0) = points.first().map(|p| p[2]) else {
        return Vec::new();
    };
    let local = |p: &[f64; 3], c: (i64, i64)| {
        [
            p[0] - c.0 as f64 * NORMAL_CELL_M,
            p[1] - c.1 as f64 * NORMAL_CELL_M,
            p[2] - z0,
        ]
    };
    let cells: HashMap<(i64, i64), Moments> = bin_sums(points.len(), |i| {
        let p = points.get(i)?;
        let c = cell(p);
        Some((c, Moments::of(local(p, c))))
    });
    // Each cell's normal is a pure function of the binned moments: no order to fix.
    let normals: HashMap<(i64, i64), Vector3<f64>> = cells
        .par_iter()
        .filter_map(|(&(cx, cy), _)| window_normal(&cells, cx, cy).map(|n| ((cx, cy), n)))
        .collect();
    points
        .par_iter()
        .map(|p| normals.get(&cell(p)).copied())
        .collect()
}

/// `ρ / max(cos i, MIN_COS_INCIDENCE)` per point with `cos i = |n·(o − p)| / |o − p|`, `n` the
/// window normal and `o` the point's scan origin (`origins` indexed by `scan`); `ρ` itself
/// where there is no normal, no origin, or `p` is the origin.
pub fn incidence_albedo(
    points: &[[f64; 3]],
    scan: &[u32],
    rho: &[f32],
    origins: &[Vector3<f64>],
) -> Vec<f32> {
    let normals = window_normals(points);
    points
        .par_iter()
        .zip(normals.par_iter())
        .zip(scan.par_iter().zip(rho.par_iter()))
        .map(|((p, n), (&s, &r))| {
            let cos = n
                .as_ref()
                .zip(origins.get(s as usize))
                .and_then(|(n, o)| {
                    let beam = o - Vector3::from(*p);
                    let cos = n.dot(&beam).abs() / beam.norm();
                    cos.is_finite().then_some(cos)
                })
                .unwrap_or(1.0);
            (f64::from(r) / cos.max(MIN_COS_INCIDENCE)) as f32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Random points on the plane `z = a x + b y + c` with vertical noise, far from the origin.
    fn plane(a: f64, b: f64, noise: f64, offset: [f64; 2]) -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        (0..40_000)
            .map(|_| {
                let x = offset[0] + rng.gen::<f64>() * 0.5;
                let y = offset[1] + rng.gen::<f64>() * 0.5;
                let z = a * x + b * y + 3.0 + (rng.gen::<f64>() - 0.5) * 2.0 * noise;
                [x, y, z]
            })
            .collect()
    }

    fn angle_deg(n: &Vector3<f64>, a: f64, b: f64) -> f64 {
        let t = Vector3::new(-a, -b, 1.0).normalize();
        n.dot(&t).abs().min(1.0).acos().to_degrees()
    }

    #[test]
    fn window_normals_recover_a_noisy_plane_far_from_the_origin() {
        for offset in [[0.0, 0.0], [4.5e5, 5.2e6]] {
            let pts = plane(0.3, -0.2, 0.008, offset);
            let normals = window_normals(&pts);
            let worst = normals
                .iter()
                .map(|n| angle_deg(n.as_ref().unwrap(), 0.3, -0.2))
                .fold(0.0, f64::max);
            // 160 points per window, ±8 mm uniform noise: a few degrees at worst.
            assert!(worst < 6.0, "offset {offset:?}: worst {worst}°");
        }
    }

    #[test]
    fn moments_shift_equals_recomputing_from_the_new_corner() {
        let pts = [[0.1, 0.2, 0.3], [0.5, -0.1, 0.2], [0.05, 0.07, -0.4]];
        let t = [0.02, -0.04, 0.0];
        let mut a = Moments::default();
        let mut b = Moments::default();
        for p in pts {
            a += Moments::of(p);
            b += Moments::of([p[0] + t[0], p[1] + t[1], p[2] + t[2]]);
        }
        let s = a.shifted(t);
        for (x, y) in s.ss.iter().zip(b.ss).chain(s.s.iter().zip(b.s)) {
            assert!((x - y).abs() < 1e-12);
        }
    }

    #[test]
    fn too_few_points_or_a_line_give_no_normal() {
        assert_eq!(
            window_normals(&[[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]]),
            vec![None, None]
        );
        let line: Vec<[f64; 3]> = (0..20)
            .map(|i| [f64::from(i) * 0.002, 0.001, 0.0])
            .collect();
        assert!(window_normals(&line).iter().all(Option::is_none));
        assert!(window_normals(&[]).is_empty());
    }

    #[test]
    fn albedo_divides_by_the_incidence_and_keeps_rho_without_a_normal() {
        let pts = plane(0.0, 0.0, 0.0005, [0.0, 0.0]);
        let origin = Vector3::new(0.25, 0.25, 3.0 + 2.0);
        let rho: Vec<f32> = vec![0.3; pts.len()];
        let albedo = incidence_albedo(&pts, &vec![0; pts.len()], &rho, &[origin]);
        for (p, a) in pts.iter().zip(&albedo) {
            let beam = origin - Vector3::from(*p);
            let cos = beam.z.abs() / beam.norm();
            assert!(
                (f64::from(*a) - 0.3 / cos).abs() < 0.003,
                "{a} vs {}",
                0.3 / cos
            );
        }
        // A point of an unknown scan keeps ρ.
        let a = incidence_albedo(&pts[..10], &[7; 10], &rho[..10], &[origin]);
        assert!(a.iter().all(|&v| v == 0.3));
    }

    #[test]
    fn thread_count_does_not_change_the_normals() {
        let pts = plane(0.1, 0.4, 0.01, [2.0, 3.0]);
        let run = |t: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .unwrap()
                .install(|| window_normals(&pts))
        };
        assert_eq!(run(1), run(2));
    }
}
