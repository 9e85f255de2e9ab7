//! The Delaunay triangulation of `dem.tin`, built strip by strip in parallel.
//!
//! Why: spade's `bulk_load` is single-threaded, and on a full laser survey (~19 M points) its one
//! big structure misses cache and costs several GB. The plane is therefore cut into vertical
//! strips of equal point count (the count is fixed by the number of points, never by the thread
//! count), each strip plus a margin on both sides is triangulated on its own, and the strips run
//! in parallel.
//!
//! What is built: every Delaunay triangle whose longest horizontal edge is at most `max_edge`
//! (all of them when `max_edge` is infinite). `dem.raster` skips longer triangles anyway (they
//! span holes), and the bound is what makes strips exact: the margin is at least `max_edge`, so
//! such a triangle's corners are all among the points of the strip whose *core* (x range) holds
//! its centroid. A triangle with an empty circumcircle is Delaunay in every subset holding its
//! corners, so that strip's own triangulation contains it. A strip keeps the triangles whose
//! centroid lies in its core, whose edges are short enough, and whose circumcircle is empty of
//! *all* points: proven cheaply when the circle stays inside the x range of the points the strip
//! triangulated (the strip's triangulation is Delaunay), otherwise checked against a uniform grid
//! of all points (rare: obtuse triangles by holes and at the outline). The union is exactly the
//! set above, up to the choice among co-circular points (a strip and its neighbour may then pick
//! different diagonals; the rasteriser's "first writer wins" makes that harmless and the output
//! stays deterministic). A cloud of at most `STRIP_POINTS` points, or an infinite `max_edge`, is
//! one spade triangulation filtered by edge length.
//!
//! Order: the triangles proven within their strip, strips left to right, each in spade's face
//! order, then those the grid check kept, in the same order; bit-identical for any thread count
//! (`dem.tin` sorts them anyway). Each strip's list is freed as it is copied into the result, so
//! the strips' lists and the result are never both whole in memory.

use rayon::prelude::*;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

/// Points per strip core (a cloud up to this size is one spade triangulation). Spade's
/// structure for a strip in flight is a few hundred bytes a point, and the strips in flight
/// (one per thread) come on top of the vertices and the triangles kept so far: at 1 M points
/// the estec survey's `dem.tin` peaked 0.17 GB lower than at 2 M in the same time (0.5 M was
/// slower, with no lower peak). The result does not depend on it.
const STRIP_POINTS: usize = 1_000_000;
/// Margin on each side of a strip core, in mean point spacings.
const MARGIN_SPACINGS: f64 = 16.0;
/// Grid cell of the emptiness check, in mean point spacings.
const GRID_SPACINGS: f64 = 8.0;

#[derive(Clone, Copy)]
struct Vertex {
    pos: Point2<f64>,
    index: u32,
}

impl HasPosition for Vertex {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.pos
    }
}

/// spade's triangulation of `vertices[range]`: each counter-clockwise triangle, with global
/// indices, handed with its corners' (x, y) to `keep`, which files it (or drops it). The
/// corners come from spade's own vertex records, which the face walk reads anyway for the
/// indices: looking them up again in `vertices` in spade's face order is a random access a
/// corner, which made filtering the triangles a seventh of `dem.tin`.
fn spade_triangles(
    vertices: &[[f64; 3]],
    range: std::ops::Range<usize>,
    mut keep: impl FnMut([u32; 3], [[f64; 2]; 3]),
) -> Result<(), String> {
    let start = range.start;
    let part = vertices.get(range).unwrap_or(&[]);
    let spade_vertices: Vec<Vertex> = part
        .iter()
        .enumerate()
        .map(|(k, p)| Vertex {
            pos: Point2::new(p[0], p[1]),
            index: (start + k) as u32,
        })
        .collect();
    let dt: DelaunayTriangulation<Vertex> = DelaunayTriangulation::bulk_load(spade_vertices)
        .map_err(|e| format!("triangulation failed: {e:?}"))?;
    for f in dt.inner_faces() {
        let v = f.vertices().map(|v| *v.data());
        keep(v.map(|v| v.index), v.map(|v| [v.pos.x, v.pos.y]));
    }
    Ok(())
}

/// Circumcentre and squared radius of a triangle (None when degenerate).
fn circumcircle(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<([f64; 2], f64)> {
    let (bx, by) = (b[0] - a[0], b[1] - a[1]);
    let (cx, cy) = (c[0] - a[0], c[1] - a[1]);
    let d = 2.0 * (bx * cy - by * cx);
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    let (b2, c2) = (bx * bx + by * by, cx * cx + cy * cy);
    let ux = (cy * b2 - by * c2) / d;
    let uy = (bx * c2 - cx * b2) / d;
    Some(([a[0] + ux, a[1] + uy], ux * ux + uy * uy))
}

/// A uniform grid of all vertex indices, for "is this circle empty" queries.
struct PointGrid {
    min: [f64; 2],
    cell: f64,
    cols: usize,
    rows: usize,
    /// `starts[k]..starts[k + 1]` indexes `items` for cell k (row-major).
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl PointGrid {
    fn new(vertices: &[[f64; 3]], cell: f64) -> PointGrid {
        let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in vertices {
            for k in 0..2 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        let count = |k: usize| (((max[k] - min[k]) / cell).floor() as usize).saturating_add(1);
        let (cols, rows) = (count(0).min(1 << 15), count(1).min(1 << 15));
        let mut grid = PointGrid {
            min,
            cell,
            cols,
            rows,
            starts: vec![0; cols * rows + 1],
            items: vec![0; vertices.len()],
        };
        let keys: Vec<usize> = vertices.iter().map(|p| grid.key(p[0], p[1])).collect();
        for &k in &keys {
            if let Some(s) = grid.starts.get_mut(k + 1) {
                *s += 1;
            }
        }
        for k in 1..grid.starts.len() {
            let prev = grid.starts.get(k - 1).copied().unwrap_or(0);
            if let Some(s) = grid.starts.get_mut(k) {
                *s += prev;
            }
        }
        let mut fill = grid.starts.clone();
        for (i, &k) in keys.iter().enumerate() {
            if let Some(f) = fill.get_mut(k) {
                if let Some(slot) = grid.items.get_mut(*f as usize) {
                    *slot = i as u32;
                }
                *f += 1;
            }
        }
        grid
    }

    fn col(&self, x: f64) -> usize {
        (((x - self.min[0]) / self.cell).max(0.0) as usize).min(self.cols - 1)
    }

    fn row(&self, y: f64) -> usize {
        (((y - self.min[1]) / self.cell).max(0.0) as usize).min(self.rows - 1)
    }

    fn key(&self, x: f64, y: f64) -> usize {
        self.row(y) * self.cols + self.col(x)
    }

    /// True when no vertex other than the triangle's own lies strictly inside the circle.
    fn circle_is_empty(&self, vertices: &[[f64; 3]], tri: [u32; 3], c: [f64; 2], r2: f64) -> bool {
        let r = r2.sqrt();
        // Strictly inside, with a relative tolerance so co-circular points count as outside.
        let limit = r2 * (1.0 - 1e-12);
        let (r0, r1) = (self.row(c[1] - r), self.row(c[1] + r));
        for row in r0..=r1 {
            // The circle's widest extent over this row's y span.
            let (y0, y1) = (
                self.min[1] + row as f64 * self.cell,
                self.min[1] + (row + 1) as f64 * self.cell,
            );
            let dy = if c[1] < y0 {
                y0 - c[1]
            } else if c[1] > y1 {
                c[1] - y1
            } else {
                0.0
            };
            if dy > r {
                continue;
            }
            let half = (r2 - dy * dy).max(0.0).sqrt();
            let (c0, c1) = (self.col(c[0] - half), self.col(c[0] + half));
            let lo = self.starts.get(row * self.cols + c0).copied().unwrap_or(0) as usize;
            let hi = self
                .starts
                .get(row * self.cols + c1 + 1)
                .copied()
                .unwrap_or(0) as usize;
            for &i in self.items.get(lo..hi).unwrap_or(&[]) {
                if tri.contains(&i) {
                    continue;
                }
                let Some(p) = vertices.get(i as usize) else {
                    continue;
                };
                let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
                if dx * dx + dy * dy < limit {
                    return false;
                }
            }
        }
        true
    }
}

/// One strip's triangles: those kept outright, and those whose circumcircle reaches past the
/// points the strip triangulated (kept only if the grid check finds the circle empty).
struct StripTriangles {
    kept: Vec<[u32; 3]>,
    unproven: Vec<[u32; 3]>,
}

/// The longest horizontal edge of a triangle (the hole rule of `dem.tin` and `dem.raster`).
pub(super) fn longest_edge(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    longest_edge_xy([a[0], a[1]], [b[0], b[1]], [c[0], c[1]])
}

/// [`longest_edge`] of corners given by (x, y).
fn longest_edge_xy(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let d = |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).hypot(p[1] - q[1]);
    d(a, b).max(d(b, c)).max(d(c, a))
}

/// The Delaunay triangles of `vertices` in (x, y) whose longest horizontal edge is at most
/// `max_edge` (see the module doc): counter-clockwise, as vertex indices.
///
/// `vertices` must be sorted by x and hold unique (x, y) (as `dem.tin` leaves them) and number at
/// most `u32::MAX`.
pub fn triangulate(vertices: &[[f64; 3]], max_edge: f64) -> Result<Vec<[u32; 3]>, String> {
    triangulate_in_strips(vertices, max_edge, STRIP_POINTS)
}

fn triangulate_in_strips(
    vertices: &[[f64; 3]],
    max_edge: f64,
    strip_points: usize,
) -> Result<Vec<[u32; 3]>, String> {
    let n = vertices.len();
    let corner = |i: u32| {
        let p = vertices.get(i as usize).copied().unwrap_or([0.0; 3]);
        [p[0], p[1]]
    };
    if n <= strip_points || !max_edge.is_finite() {
        let mut tris = Vec::new();
        spade_triangles(vertices, 0..n, |t, [a, b, c]| {
            if longest_edge_xy(a, b, c) <= max_edge {
                tris.push(t);
            }
        })?;
        return Ok(tris);
    }
    let x = |i: usize| vertices.get(i).map_or(0.0, |p| p[0]);
    let (mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in vertices {
        ymin = ymin.min(p[1]);
        ymax = ymax.max(p[1]);
    }
    let area = ((x(n - 1) - x(0)) * (ymax - ymin)).max(f64::MIN_POSITIVE);
    let spacing = (area / n as f64).sqrt();
    let margin = (MARGIN_SPACINGS * spacing).max(max_edge);
    let strips = n.div_ceil(strip_points);
    // Core boundaries as x values (the x of the strip's first vertex); cores are half-open.
    let bounds: Vec<f64> = (0..=strips)
        .map(|s| match s {
            0 => f64::NEG_INFINITY,
            s if s == strips => f64::INFINITY,
            s => x(s * n / strips),
        })
        .collect();
    let per_strip: Vec<Result<StripTriangles, String>> = (0..strips)
        .into_par_iter()
        .map(|s| {
            let core0 = bounds.get(s).copied().unwrap_or(f64::NEG_INFINITY);
            let core1 = bounds.get(s + 1).copied().unwrap_or(f64::INFINITY);
            let lo = vertices.partition_point(|p| p[0] < core0 - margin);
            let hi = vertices.partition_point(|p| p[0] <= core1 + margin);
            // Every point left out has x ≤ `left` or x ≥ `right`.
            let left = if lo == 0 {
                f64::NEG_INFINITY
            } else {
                x(lo - 1)
            };
            let right = if hi == n { f64::INFINITY } else { x(hi) };
            // A triangulation of m points has fewer than 2m faces: one allocation, as the
            // list of all faces had, not a growing one with its doubling peaks.
            let (mut kept, mut unproven) = (Vec::with_capacity(2 * (hi - lo)), Vec::new());
            spade_triangles(vertices, lo..hi, |t, [a, b, c]| {
                let cx = (a[0] + b[0] + c[0]) / 3.0;
                if cx < core0 || cx >= core1 || longest_edge_xy(a, b, c) > max_edge {
                    return;
                }
                let proven = circumcircle(a, b, c).is_some_and(|(centre, r2)| {
                    let r = r2.sqrt() * (1.0 + 1e-9);
                    centre[0] - r > left && centre[0] + r < right
                });
                if proven {
                    kept.push(t);
                } else {
                    unproven.push(t);
                }
            })?;
            kept.shrink_to_fit();
            Ok(StripTriangles { kept, unproven })
        })
        .collect();
    let per_strip: Vec<StripTriangles> = per_strip.into_iter().collect::<Result<_, _>>()?;
    let unproven: Vec<[u32; 3]> = per_strip
        .iter()
        .flat_map(|s| s.unproven.iter().copied())
        .collect();
    let checked: Vec<[u32; 3]> = if unproven.is_empty() {
        Vec::new()
    } else {
        let grid = PointGrid::new(vertices, GRID_SPACINGS * spacing);
        unproven
            .into_par_iter()
            .filter(|&t| {
                let [a, b, c] = t.map(corner);
                circumcircle(a, b, c)
                    .is_some_and(|(centre, r2)| grid.circle_is_empty(vertices, t, centre, r2))
            })
            .collect()
    };
    // One list, each strip's freed once copied (the strips and the list are never both whole).
    let total = per_strip.iter().map(|s| s.kept.len()).sum::<usize>() + checked.len();
    let mut all = Vec::with_capacity(total);
    for strip in per_strip {
        all.extend_from_slice(&strip.kept);
    }
    all.extend(checked);
    Ok(all)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::collections::BTreeSet;

    /// Canonical set of triangles (rotated so the smallest index comes first; orientation kept).
    fn canonical(tris: &[[u32; 3]]) -> BTreeSet<[u32; 3]> {
        tris.iter()
            .map(|&[a, b, c]| {
                let m = a.min(b).min(c);
                if m == a {
                    [a, b, c]
                } else if m == b {
                    [b, c, a]
                } else {
                    [c, a, b]
                }
            })
            .collect()
    }

    /// A cloud with holes (empty discs wider than the margin) and a ragged outline, x-sorted.
    fn holey_cloud(n: usize, seed: u64) -> Vec<[f64; 3]> {
        let holes = [[2.0, 1.5, 0.4], [5.1, 3.0, 0.25], [7.0, 0.5, 0.6]];
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut pts: Vec<[f64; 3]> = (0..n)
            .map(|_| {
                [
                    rng.gen::<f64>() * 8.0,
                    rng.gen::<f64>() * 4.0,
                    rng.gen::<f64>(),
                ]
            })
            .filter(|p| {
                let ragged = p[1] < 3.6 + 0.4 * (p[0] * 3.0).sin();
                ragged
                    && holes
                        .iter()
                        .all(|h| (p[0] - h[0]).hypot(p[1] - h[1]) > h[2])
            })
            .collect();
        pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        pts
    }

    #[test]
    fn strips_give_the_global_triangulation() {
        // Small strips so the test cloud is cut many times (same code path as the big case).
        let pts = holey_cloud(60_000, 7);
        for max_edge in [0.05, 0.2] {
            let whole = triangulate_in_strips(&pts, max_edge, usize::MAX).unwrap();
            let strips = triangulate_in_strips(&pts, max_edge, 4_000).unwrap();
            assert!(whole.len() > 90_000, "{}", whole.len());
            assert_eq!(strips.len(), whole.len());
            assert_eq!(canonical(&strips), canonical(&whole));
        }
        // An infinite limit keeps every triangle, including the hull's slivers.
        let all = triangulate_in_strips(&pts, f64::INFINITY, 4_000).unwrap();
        let mut spade = Vec::new();
        spade_triangles(&pts, 0..pts.len(), |t, _| spade.push(t)).unwrap();
        assert_eq!(all, spade);
    }

    #[test]
    fn the_thread_count_changes_nothing() {
        let pts = holey_cloud(30_000, 3);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| triangulate_in_strips(&pts, 0.1, 3_000).unwrap())
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn circle_emptiness_matches_brute_force() {
        let pts = holey_cloud(5_000, 11);
        let grid = PointGrid::new(&pts, 0.05);
        let mut rng = ChaCha8Rng::seed_from_u64(90);
        for k in 0..400u64 {
            let c = [rng.gen::<f64>() * 10.0 - 1.0, rng.gen::<f64>() * 6.0 - 1.0];
            let r2 = (rng.gen::<f64>() * 2.0).powi(2);
            let brute = pts
                .iter()
                .all(|p| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) >= r2 * (1.0 - 1e-12));
            assert_eq!(
                grid.circle_is_empty(&pts, [u32::MAX; 3], c, r2),
                brute,
                "{k}"
            );
        }
    }
}
