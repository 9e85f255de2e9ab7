//! Incidence correction of the laser reflectance (part of `merge.clean`): `albedo = ρ / max(cos i,
//! MIN_COS_INCIDENCE)`, with `i` the angle between the beam and the surface normal.
//!
//! Why the normal comes from a fixed ground window and not from the `k` nearest points: `1 / cos i`
//! amplifies every error of the normal, and a normal fitted to a few nearby points of a dense
//! scan is mostly range noise. On the full-resolution estec corpus (points ~4 mm apart, 8 mm
//! range noise) the PCA normal of the 16 nearest points left the per-point albedo off by
//! 2.7 dB RMS, biased by −2.6 dB where it thought the beam was head-on and +2.3 dB where it
//! thought it grazing; the texture showed it as speckle and as steps where one station's points
//! take over from another's. The normal here is that of the height plane fitted to all cleaned
//! points in a square ground window of [`WINDOW_CELLS`]² cells of [`NORMAL_CELL_M`] (6 cm):
//! dozens to hundreds of points at scan density, so range noise averages out, while the window
//! stays below the size of the rocks whose shading the texture must not carry.
//!
//! Why a height plane (least squares of `z` on the ground position) and not the principal-
//! component plane: range noise lies along the beam, but the window is chosen by the points'
//! *noisy* ground positions, so within it the ground positions stay uniform and the noise shows
//! only in `z`, independent of them — unbiased for a height regression, while a principal-
//! component (total least squares) plane treats that `z` noise as spread and steepens every
//! slope by about `σ_z² / L²` (`L²` the window's in-plane spread; 12 % for 8 mm of noise on a
//! 60°-oblique slope in the unit test). On the estec corpus (seed 2, laser/0.015) the principal-
//! component normal left the texture 4.0 % brighter than the true albedo (median 2.2 %), from
//! 2.6 % head-on to 5.7 % grazing, and the cross-scan calibration took the far points' excess
//! for a range slope of −0.071 dB/m (the instrument's: −0.05); a response curve fitted by the
//! gap workflow absorbed that level (γ 1.968 for 2.033). The height plane: 1.7 % (median
//! 0.07 %), −0.049 dB/m, correlation with the true albedo 0.875 → 0.877, γ 2.006. What remains
//! grows with the distance from the stations (1.2 % within 2 m, 3.0 % at 5–7 m) and with
//! grazing: a normal's random error raises `1 / cos i` on average (it is convex), the more the
//! fewer points and the more grazing the beam. Tried: multiplying `1 / cos i` by
//! `1 − Var(cos i) / cos² i`, `Var(cos i)` propagated from the height plane's slope covariance
//! `s² (Xᵀ X)⁻¹`: estec 1.2 % (0.0 % within 2 m, 2.5 % at 5–7 m), γ 2.015, but mini's
//! response curves then read +0.028 and +0.022 high (seed 101) — the residual `s²` holds the
//! ground's roughness as well as the noise, so the correction overshoots on rough ground; it
//! needs the range noise measured apart from the relief.
//!
//! Tried before: larger windows (8, 10, 12.5, 14 cm: 2.4, 1.5, 1.1, 1.0 % with the principal-
//! component plane) smooth the texture, which cost the gap workflow's dense alignment on mini;
//! subtracting an assumed beam-noise scatter `σ² Σ d dᵀ` from the window's moments
//! over-corrected (−6 % at the true 8 mm), because within a window chosen by noisy position the
//! noise is not spread along the beam.
//!
//! How: one pass bins the points by ground cell and keeps per cell the count, the sum and the
//! second moments of the coordinates relative to the cell corner (z relative to the first
//! point's z), so precision does not depend on how far the survey is from the origin. A cell's
//! window moments are the sums of its neighbours' moments moved to its corner (exact: the
//! parallel-axis shift), whose covariance gives the height plane. Where points are sparse (far
//! from every station) a window with fewer than [`MIN_WINDOW_POINTS`] points or no plane (a
//! footprint thinner than [`MIN_FOOTPRINT_RATIO`]) grows ring by ring up to
//! [`MAX_WINDOW_CELLS`]² cells; past that, `albedo = ρ`. Cells are binned in fixed chunks merged
//! in chunk order, so the result does not depend on the thread count. Near-vertical faces are
//! seen through a 2.5-D window: their normal mixes the face with the ground around it; they are
//! a small share of a terrain.

use std::collections::HashMap;
use std::ops::AddAssign;

use nalgebra::Vector3;
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
/// Smallest ratio of the window footprint's two ground spreads (eigenvalues of the points'
/// x, y covariance) for a height plane.
pub const MIN_FOOTPRINT_RATIO: f64 = 0.05;
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

    /// Unit normal of the least-squares height plane `z = a x + b y + c` (ordinary least
    /// squares of `z` on the ground position, module docs), `None` where the points' ground
    /// footprint is not two-dimensional.
    fn normal(&self) -> Option<Vector3<f64>> {
        if self.n < 3 {
            return None;
        }
        let n = f64::from(self.n);
        let m = [self.s[0] / n, self.s[1] / n, self.s[2] / n];
        let c = |k: usize, a: usize, b: usize| self.ss[k] / n - m[a] * m[b];
        let (xx, xy, yy, xz, yz) = (c(0, 0, 0), c(1, 0, 1), c(3, 1, 1), c(2, 0, 2), c(4, 1, 2));
        // The footprint's smaller spread must be a fair share of the larger: a strip of points
        // (a scan line, an occlusion edge) leaves the slope across it undetermined.
        let det = xx * yy - xy * xy;
        let half_trace = 0.5 * (xx + yy);
        let small = half_trace - (half_trace * half_trace - det).max(0.0).sqrt();
        if !(small > 1e-12 && small > MIN_FOOTPRINT_RATIO * (xx + yy - small)) {
            return None;
        }
        let a = (yy * xz - xy * yz) / det;
        let b = (xx * yz - xy * xz) / det;
        let v = Vector3::new(-a, -b, 1.0).normalize();
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

    /// A scanner's range noise lies along the beam; the ground cell a point is binned by is its
    /// noisy position. On a slope seen obliquely (the beam 60° from vertical, 8 mm range noise)
    /// the height-plane normal keeps the slope; a principal-component plane of the same windows
    /// reads it 12 % steeper (module docs).
    #[test]
    fn range_noise_along_an_oblique_beam_does_not_tilt_the_normal() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (sx, sy) = (0.3, 0.0);
        let beam = Vector3::new(60f64.to_radians().sin(), 0.0, -60f64.to_radians().cos());
        let pts: Vec<[f64; 3]> = (0..80_000)
            .map(|_| {
                let x = rng.gen::<f64>() * 0.6;
                let y = rng.gen::<f64>() * 0.6;
                // Gaussian, 8 mm (Box–Muller).
                let (u, w): (f64, f64) = (rng.gen::<f64>().max(1e-12), rng.gen());
                let e = 0.008 * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * w).cos();
                [x + e * beam.x, y + e * beam.y, sx * x + sy * y + e * beam.z]
            })
            .collect();
        let normals = window_normals(&pts);
        let (mut slope, mut n) = (0.0, 0.0);
        // Away from the sample's border, where the noise decides which points are in.
        let inside = |p: &[f64; 3]| p[0] > 0.1 && p[0] < 0.5 && p[1] > 0.1 && p[1] < 0.5;
        for (p, v) in pts.iter().zip(&normals) {
            if let (true, Some(v)) = (inside(p), v) {
                slope += -v.x / v.z;
                n += 1.0;
            }
        }
        let slope = slope / n;
        assert!(
            (slope / sx - 1.0).abs() < 0.02,
            "mean slope {slope} for {sx}"
        );
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
