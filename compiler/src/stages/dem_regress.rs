//! Cell values of `dem.raster` by local regression over the TIN vertices around each cell.
//!
//! Why: interpolating the TIN at a cell centre hands every cell the noise of the one or two points
//! nearest to it. A terrestrial laser scan has a range noise of several millimetres and about one
//! point per cm² on a yard like ESTEC's, so a 1 cm raster interpolated from the TIN carries that
//! noise in full: its normals tilt by tens of degrees from cell to cell, a render of it is covered in
//! shading speckle that the real camera never sees, and the per-point reflectance noise becomes
//! texture speckle. Gridding by local regression (as PDAL's and GDAL's gridders do with a search
//! radius) averages the points that fall near a cell instead.
//!
//! How: for each valid cell (the TIN's long-edge rule still decides validity, so holes stay holes)
//! a plane `z = a + b·dx + c·dy` is fitted by weighted least squares to the vertices within the
//! support radius `s`, with Gaussian weights of σ = s/2 on the horizontal distance; the cell height
//! is `a`. A plane rather than a weighted mean keeps slopes unbiased (a mean pulls a slope's cells
//! towards the centroid of its points). Albedo is the Gaussian-weighted mean of the points within
//! its own, smaller support, the cell itself (σ = cell/2): albedo has sharp small features (dark
//! pebbles of 1–2 cm) that the height support would wash out, and needs no slope. Where the
//! fit is ill-posed (fewer than 3 points, collinear ones, points on one side of the cell only, or
//! a fitted height outside the points' range: no extrapolation) the TIN value is kept, and so it is
//! where the plane fits badly (weighted residual RMS above 3 × the raster's median): there the
//! neighbourhood spans a discontinuity — a boulder's edge, a wall — which is shape, not noise,
//! and a plane across it would bleed the boulder into the ground around it. The support is
//! `max(cell, factor × median TIN edge)`: never less than the cell itself (a coarse raster averages
//! its cell instead of sampling it), and at least a few points at fine cells, where the scan density
//! rather than the cell size bounds the resolution.
//!
//! Determinism: vertices are bucketed by a counting sort on a fixed grid, each cell sums its
//! neighbours in bucket order then index order, and cells are independent, so the result is
//! bit-identical for any thread count.

use rayon::prelude::*;

use super::dem_raster::Raster;
use super::dem_tin::Tin;
use super::geometry::median;

/// Residual RMS, in raster medians, above which a cell's neighbourhood is a discontinuity.
const DISCONTINUITY: f64 = 3.0;
/// Residual RMS below which a neighbourhood is never a discontinuity, m (a noise-free surface
/// has a median residual of ~0).
const MIN_STEP_M: f64 = 0.001;

/// Vertices bucketed on a square grid of side `size`.
struct Buckets {
    x0: f64,
    y0: f64,
    size: f64,
    nx: usize,
    ny: usize,
    /// `start[k]..start[k + 1]` indexes `order` for bucket `k` (row-major, `ny` rows).
    start: Vec<usize>,
    order: Vec<u32>,
}

impl Buckets {
    fn new(vertices: &[[f64; 3]], size: f64) -> Option<Buckets> {
        let first = vertices.first()?;
        let (mut x0, mut y0, mut x1, mut y1) = (first[0], first[1], first[0], first[1]);
        for p in vertices {
            x0 = x0.min(p[0]);
            y0 = y0.min(p[1]);
            x1 = x1.max(p[0]);
            y1 = y1.max(p[1]);
        }
        let nx = ((x1 - x0) / size).floor() as usize + 1;
        let ny = ((y1 - y0) / size).floor() as usize + 1;
        let cells = nx.checked_mul(ny)?;
        if cells > vertices.len().saturating_mul(4).max(1 << 20) {
            return None;
        }
        let key = |p: &[f64; 3]| {
            let bx = (((p[0] - x0) / size) as usize).min(nx - 1);
            let by = (((p[1] - y0) / size) as usize).min(ny - 1);
            by * nx + bx
        };
        let mut start = vec![0usize; cells + 1];
        for p in vertices {
            start[key(p) + 1] += 1;
        }
        for k in 0..cells {
            start[k + 1] += start[k];
        }
        let mut next = start.clone();
        let mut order = vec![0u32; vertices.len()];
        for (i, p) in (0u32..).zip(vertices) {
            let k = key(p);
            order[next[k]] = i;
            next[k] += 1;
        }
        Some(Buckets {
            x0,
            y0,
            size,
            nx,
            ny,
            start,
            order,
        })
    }

    /// Vertex indices in the 3 × 3 buckets around `(x, y)`, bucket order then index order.
    fn around(&self, x: f64, y: f64) -> impl Iterator<Item = u32> + '_ {
        let bx = ((x - self.x0) / self.size).floor() as i64;
        let by = ((y - self.y0) / self.size).floor() as i64;
        (by - 1..=by + 1)
            .flat_map(move |j| (bx - 1..=bx + 1).map(move |i| (i, j)))
            .filter(|&(i, j)| i >= 0 && j >= 0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .flat_map(move |(i, j)| {
                let k = j as usize * self.nx + i as usize;
                self.order[self.start[k]..self.start[k + 1]].iter().copied()
            })
    }
}

/// Replaces the valid cells of `raster` by local-regression estimates over `tin`'s vertices within
/// `support_m` (see the module doc). Returns the number of cells that kept the TIN value (fit
/// ill-posed, or a discontinuity).
pub(crate) fn regress(
    tin: &Tin,
    raster: &mut Raster,
    support_m: f64,
    albedo_support_m: f64,
) -> usize {
    let albedo_support_m = albedo_support_m.min(support_m);
    if !(support_m.is_finite() && support_m > 0.0 && albedo_support_m > 0.0) {
        return 0;
    }
    let Some(buckets) = Buckets::new(&tin.vertices, support_m) else {
        return 0;
    };
    let inv_2s2 = 1.0 / (2.0 * (0.5 * support_m).powi(2));
    let r2 = support_m * support_m;
    let inv_2a2 = 1.0 / (2.0 * (0.5 * albedo_support_m).powi(2));
    let ra2 = albedo_support_m * albedo_support_m;
    let cols = raster.cols;
    let (origin, cell) = (raster.origin, raster.cell_m);
    let albedo_in = tin.albedo.as_deref();
    // Per valid cell: (index, TIN height, fitted height and residual RMS if well-posed, albedo).
    #[allow(clippy::type_complexity)]
    let fits: Vec<(usize, f32, Option<(f64, f64)>, Option<f32>)> = raster
        .heights
        .par_iter()
        .enumerate()
        .filter(|(_, h)| h.is_finite())
        .map(|(i, &h)| {
            let (row, col) = (i / cols, i % cols);
            let x = origin[0] + col as f64 * cell;
            let y = origin[1] - row as f64 * cell;
            // Normal equations of the weighted plane fit (heights relative to the TIN value,
            // for conditioning), Σ w·z² for the residual, and the albedo sums.
            let mut m = [[0.0f64; 3]; 3];
            let mut rhs = [0.0f64; 3];
            let (mut wzz, mut aw, mut asum, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
            let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
            for v in buckets.around(x, y) {
                let p = tin.vertices[v as usize];
                let (dx, dy) = (p[0] - x, p[1] - y);
                let d2 = dx * dx + dy * dy;
                if d2 > r2 {
                    continue;
                }
                let w = (-d2 * inv_2s2).exp();
                let z = p[2] - f64::from(h);
                let f = [1.0, dx, dy];
                for a in 0..3 {
                    for b in 0..3 {
                        m[a][b] += w * f[a] * f[b];
                    }
                    rhs[a] += w * f[a] * z;
                }
                wzz += w * z * z;
                zmin = zmin.min(z);
                zmax = zmax.max(z);
                if let Some(al) = albedo_in
                    .and_then(|al| al.get(v as usize))
                    .filter(|_| d2 <= ra2)
                {
                    let wa = (-d2 * inv_2a2).exp();
                    aw += wa;
                    asum += wa * f64::from(*al);
                }
                n += 1;
            }
            let albedo = (aw > 0.0).then(|| (asum / aw) as f32);
            // No extrapolation: the points must surround the cell (weighted centroid within half
            // the support) and the fitted height must lie within their range.
            let centred = m[0][0] > 0.0 && m[0][1].hypot(m[0][2]) / m[0][0] <= 0.5 * support_m;
            let fit = solve_plane(&m, &rhs, support_m)
                .filter(|beta| n >= 3 && centred && (zmin..=zmax).contains(&beta[0]))
                .map(|beta| {
                    // Weighted residual sum of squares at the solution: Σwz² − βᵀ·XᵀWz.
                    let rss = (wzz - (0..3).map(|k| beta[k] * rhs[k]).sum::<f64>()).max(0.0);
                    (f64::from(h) + beta[0], (rss / m[0][0]).sqrt())
                });
            (i, h, fit, albedo)
        })
        .collect();
    // A discontinuity (a boulder's edge, a wall) is no noise to average: cells whose fit leaves
    // more than DISCONTINUITY × the raster's median residual keep the TIN value.
    let mut rms: Vec<f64> = fits.iter().filter_map(|f| f.2.map(|x| x.1)).collect();
    let limit = median(&mut rms).map_or(f64::INFINITY, |m| (DISCONTINUITY * m).max(MIN_STEP_M));
    let results: Vec<(usize, f32, Option<f32>, bool)> = fits
        .into_iter()
        .map(|(i, h, fit, albedo)| match fit.filter(|f| f.1 <= limit) {
            Some((z, _)) => (i, z as f32, albedo, false),
            None => (i, h, albedo, true),
        })
        .collect();
    let mut kept = 0;
    for (i, h, a, fallback) in results {
        raster.heights[i] = h;
        if let (Some(out), Some(a)) = (raster.albedo.as_mut(), a) {
            out[i] = a;
        }
        kept += usize::from(fallback);
    }
    kept
}

/// The solution `[a, b, c]` of the 3 × 3 system `m · [a, b, c] = rhs`, or `None` when it is
/// ill-conditioned (the points are collinear at the scale of the support).
fn solve_plane(m: &[[f64; 3]; 3], rhs: &[f64; 3], support: f64) -> Option<[f64; 3]> {
    // Measure the offsets in units of the support (D·M·D with D = diag(1, 1/s, 1/s)) so the
    // matrix entries are comparable; the solution is scaled back by D.
    let s = [1.0, 1.0 / support, 1.0 / support];
    let a: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| m[i][j] * s[i] * s[j]));
    let b: [f64; 3] = std::array::from_fn(|i| rhs[i] * s[i]);
    let det = |a: &[[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(&a);
    let scale = a[0][0].powi(3);
    if !(d.is_finite() && scale > 0.0 && d > 1e-6 * scale) {
        return None;
    }
    Some(std::array::from_fn(|k| {
        let mut ak = a;
        for (row, bi) in ak.iter_mut().zip(b) {
            row[k] = bi;
        }
        det(&ak) / d * s[k]
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_tin(f: impl Fn(f64, f64) -> f64, n: usize, step: f64) -> Tin {
        let mut vertices = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (i as f64 * step, j as f64 * step);
                vertices.push([x, y, f(x, y)]);
            }
        }
        Tin {
            albedo: Some(vertices.iter().map(|p| (0.2 + p[0]) as f32).collect()),
            vertices,
            triangles: vec![],
            duplicates_merged: 0,
        }
    }

    fn raster_over(cell: f64, extent: f64) -> Raster {
        let n = (extent / cell) as usize;
        Raster {
            cell_m: cell,
            rows: n,
            cols: n,
            origin: [0.5 * cell, extent - 0.5 * cell],
            bounds: [0.0, 0.0, extent, extent],
            heights: vec![0.0; n * n],
            albedo: Some(vec![0.0; n * n]),
            stats: Default::default(),
        }
    }

    #[test]
    fn a_plane_is_reproduced_exactly_and_a_linear_albedo_too() {
        let tin = grid_tin(|x, y| 0.3 + 0.5 * x - 0.25 * y, 60, 0.01);
        let mut r = raster_over(0.02, 0.5);
        // Supports off the 1 cm vertex spacing: a vertex exactly on the boundary could be kept
        // on one side and dropped on the other by rounding, which biases the mean.
        regress(&tin, &mut r, 0.033, 0.025);
        for row in 2..r.rows - 2 {
            for col in 2..r.cols - 2 {
                let [x, y] = r.cell_centre(row, col);
                let z = f64::from(r.heights[row * r.cols + col]);
                assert!(
                    (z - (0.3 + 0.5 * x - 0.25 * y)).abs() < 1e-5,
                    "{z} at {x},{y}"
                );
                let a = f64::from(r.albedo.as_ref().unwrap()[row * r.cols + col]);
                assert!((a - (0.2 + x)).abs() < 1e-4, "{a} at {x}");
            }
        }
    }

    #[test]
    fn noise_is_averaged_down() {
        // Deterministic pseudo-noise of σ ≈ 5 mm on a flat surface, 1 point per cm².
        let mut s = 12345u64;
        let mut noise = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.005 * 12f64.sqrt()
        };
        let noisy: Vec<f64> = (0..80 * 80).map(|_| noise()).collect();
        let tin = Tin {
            vertices: (0..80 * 80)
                .map(|k| [(k % 80) as f64 * 0.01, (k / 80) as f64 * 0.01, noisy[k]])
                .collect(),
            albedo: None,
            triangles: vec![],
            duplicates_merged: 0,
        };
        let mut r = raster_over(0.01, 0.8);
        r.albedo = None;
        regress(&tin, &mut r, 0.02, 0.02);
        let inner: Vec<f64> = (5..r.rows - 5)
            .flat_map(|row| (5..r.cols - 5).map(move |c| (row, c)))
            .map(|(row, c)| f64::from(r.heights[row * r.cols + c]))
            .collect();
        let rms = (inner.iter().map(|z| z * z).sum::<f64>() / inner.len() as f64).sqrt();
        assert!(rms < 0.0025, "rms {rms}, input σ 0.005");
    }

    #[test]
    fn a_step_stays_sharp_while_the_flat_ground_is_smoothed() {
        // 1 point per cm², ±2 mm pseudo-noise, a 10 cm step at x = 0.4 m (a boulder's edge).
        let mut s = 777u64;
        let mut noise = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.004
        };
        let step = |x: f64| if x < 0.4 { 0.0 } else { 0.1 };
        let vertices: Vec<[f64; 3]> = (0..80 * 80)
            .map(|k| {
                let (x, y) = (
                    (k % 80) as f64 * 0.01 + 0.005,
                    (k / 80) as f64 * 0.01 + 0.005,
                );
                [x, y, step(x) + noise()]
            })
            .collect();
        let tin = Tin {
            vertices,
            albedo: None,
            triangles: vec![],
            duplicates_merged: 0,
        };
        let mut r = raster_over(0.01, 0.8);
        r.albedo = None;
        // The TIN value of each cell: its true height (exact, to see what the fit changes).
        for row in 0..r.rows {
            for col in 0..r.cols {
                r.heights[row * r.cols + col] = step(r.cell_centre(row, col)[0]) as f32;
            }
        }
        let kept = regress(&tin, &mut r, 0.03, 0.01);
        let worst = (5..r.rows - 5)
            .flat_map(|row| (0..r.cols).map(move |c| (row, c)))
            .map(|(row, c)| {
                let x = r.cell_centre(row, c)[0];
                (f64::from(r.heights[row * r.cols + c]) - step(x)).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 0.01, "a cell off by {worst} m next to the step");
        assert!(
            kept > 0 && kept < r.rows * 8,
            "{kept} cells kept the TIN value"
        );
    }

    #[test]
    fn nodata_stays_nodata_and_sparse_cells_keep_the_tin_value() {
        let tin = grid_tin(|_, _| 1.0, 3, 0.5);
        let mut r = raster_over(0.1, 1.0);
        r.heights[0] = f32::NAN;
        r.heights[55] = 7.0;
        let kept = regress(&tin, &mut r, 0.05, 0.05);
        assert!(r.heights[0].is_nan());
        assert_eq!(r.heights[55], 7.0, "no vertex within the support");
        assert!(kept > 0);
    }
}
