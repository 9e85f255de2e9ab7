//! Stage `dem.raster`: rasterise the TIN at one or more cell sizes into north-up height grids
//! (and albedo grids), with the statistics of the thesis' Table 5.3.
//!
//! Grid convention: row 0 is north (max y); `origin` is the centre of the north-west cell; cell
//! `(r, c)` has its centre at `(origin.x + c·cell, origin.y − r·cell)`. Bounds are the TIN's (x, y)
//! extent or a given crop `[x_min, y_min, x_max, y_max]`; `cols = ceil((x_max − x_min)/cell)`.
//!
//! Each cell centre gets the linear (barycentric) interpolation of the TIN triangle containing it.
//! **Holes**: triangles whose longest *horizontal* edge exceeds the limit are skipped, so cells under
//! them are NaN (nodata) instead of a "long sharp" interpolation across missing data. The limit is
//! absolute (default 0.1 m, about 10× the spacing of the thesis' 0.030° scans at 5–10 m range, and
//! larger than every raster size used) or a factor × the median TIN edge length (estimated on a
//! deterministic sample of triangles). Horizontal length is used so steep but densely sampled faces
//! stay valid. Reflectance is interpolated with the same weights.
//!
//! Speed: triangles are binned into fixed bands of `BAND_ROWS` rows, bands are rasterised in
//! parallel (each triangle scans only its bounding box), and within a band triangles are visited in
//! a fixed order (by lowest vertex index, which is west to east on an x-sorted TIN, see `prepare`)
//! with "first writer wins" on shared edges, so the grid is bit-identical for any thread count.
//! Only the indices of the valid triangles are kept; corners are read from the TIN.
//!
//! Statistics (per raster; Table 5.3 counts the points and polygons of the *raster* mesh, which is
//! why its counts scale with 1/cell²):
//! - `surface_area_m2`: area of the raster surface, Σ over valid cells of `cell²·√(1 + gx² + gy²)`
//!   with central-difference gradients (one-sided next to nodata); exact for planes, and growing
//!   with roughness at finer cells as in the thesis. `tin_surface_area_m2` is the 3D area of the
//!   valid TIN triangles whose centroid lies inside the bounds.
//! - `volume_m3`: Σ over valid cells of `cell²·(z − base_z)` (the thesis closed the surface with a
//!   plane at z = −0.1 m, the default base).
//! - `points` = valid cells, `triangles` = 2 × cell quads whose four corners are valid.

use rayon::prelude::*;
use serde::Serialize;

use super::delaunay::longest_edge;
use super::dem_regress::regress;
use super::dem_tin::Tin;
use super::geometry::median;
use crate::stage::{Stage, StageCx, StageError};

/// Rows per parallel band (fixed, so results do not depend on the thread count).
const BAND_ROWS: usize = 16;

/// How the long-edge (hole) limit is set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MaxEdge {
    /// A fixed horizontal edge length in metres.
    Absolute(f64),
    /// A factor × the median horizontal TIN edge length.
    SpacingFactor(f64),
}

/// Table 5.3 statistics of one raster.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RasterStats {
    /// Raster surface area, m² (see the module doc).
    pub surface_area_m2: f64,
    /// Volume above `base_z_m`, m³.
    pub volume_m3: f64,
    /// The base plane height, m.
    pub base_z_m: f64,
    /// Valid cells (raster mesh points).
    pub points: usize,
    /// Raster mesh triangles.
    pub triangles: usize,
    /// Cells without data.
    pub nodata_cells: usize,
    /// TIN vertices.
    pub tin_points: usize,
    /// TIN triangles.
    pub tin_triangles: usize,
    /// 3D area of the valid TIN triangles inside the bounds, m².
    pub tin_surface_area_m2: f64,
    /// The long-edge limit used, m.
    pub max_edge_m: f64,
    /// Support radius of the local-regression cell estimate, m (0 = TIN interpolation only).
    pub regression_support_m: f64,
    /// Valid cells that kept the TIN value (regression ill-posed, or across a discontinuity).
    pub regression_fallback_cells: usize,
}

/// A north-up height grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Raster {
    /// Cell size, metres.
    pub cell_m: f64,
    /// Number of rows (north to south).
    pub rows: usize,
    /// Number of columns (west to east).
    pub cols: usize,
    /// Centre of the north-west cell (x, y).
    pub origin: [f64; 2],
    /// `[x_min, y_min, x_max, y_max]` the grid covers.
    pub bounds: [f64; 4],
    /// Heights, row-major, NaN = nodata.
    pub heights: Vec<f32>,
    /// Linear albedo estimate, same layout, when the TIN has it.
    pub albedo: Option<Vec<f32>>,
    /// Statistics.
    pub stats: RasterStats,
}

impl Raster {
    /// Height at `(row, col)`, `None` outside the grid.
    pub fn get(&self, row: usize, col: usize) -> Option<f32> {
        if col >= self.cols {
            return None;
        }
        self.heights.get(row * self.cols + col).copied()
    }

    /// Centre of cell `(row, col)`.
    pub fn cell_centre(&self, row: usize, col: usize) -> [f64; 2] {
        [
            self.origin[0] + col as f64 * self.cell_m,
            self.origin[1] - row as f64 * self.cell_m,
        ]
    }
}

/// Parameters of `dem.raster`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemRaster {
    cell_sizes_m: Vec<f64>,
    crop: Option<[f64; 4]>,
    max_edge: MaxEdge,
    base_z_m: f64,
    max_cells: u64,
    regression: Option<f64>,
}

impl Default for DemRaster {
    fn default() -> Self {
        DemRaster {
            cell_sizes_m: vec![0.030, 0.020, 0.015, 0.010, 0.005],
            crop: None,
            max_edge: MaxEdge::Absolute(0.1),
            base_z_m: -0.1,
            max_cells: 1 << 28,
            regression: None,
        }
    }
}

impl DemRaster {
    /// Validated parameters (`max_cells` bounds each grid's allocation).
    pub fn new(
        cell_sizes_m: Vec<f64>,
        crop: Option<[f64; 4]>,
        max_edge: MaxEdge,
        base_z_m: f64,
        max_cells: u64,
    ) -> Result<Self, StageError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let edge_ok = match max_edge {
            MaxEdge::Absolute(v) | MaxEdge::SpacingFactor(v) => pos(v),
        };
        let crop_ok =
            crop.is_none_or(|c| c.iter().all(|v| v.is_finite()) && c[0] < c[2] && c[1] < c[3]);
        if cell_sizes_m.is_empty()
            || !cell_sizes_m.iter().all(|&c| pos(c))
            || !edge_ok
            || !crop_ok
            || !base_z_m.is_finite()
        {
            return Err(StageError::new(
                Self::NAME,
                format!(
                    "expected ≥ 1 positive cell size, a positive edge limit, a crop with min < max and a finite base; \
                     found cells {cell_sizes_m:?}, max_edge {max_edge:?}, crop {crop:?}, base {base_z_m}"
                ),
            ));
        }
        Ok(DemRaster {
            cell_sizes_m,
            crop,
            max_edge,
            base_z_m,
            max_cells,
            regression: None,
        })
    }

    /// Estimates each valid cell by local regression over the TIN vertices within
    /// `max(cell, factor × median TIN edge)` instead of interpolating the TIN at its centre (see
    /// `dem_regress`); `None` keeps pure TIN interpolation.
    pub fn with_regression(mut self, factor: Option<f64>) -> Self {
        self.regression = factor.filter(|f| f.is_finite() && *f > 0.0);
        self
    }

    /// Rasterises `tin` at every cell size.
    pub fn rasterize_all(&self, tin: &Tin) -> Result<Vec<Raster>, StageError> {
        let err = |m: String| StageError::new(Self::NAME, m);
        let bounds = match self.crop {
            Some(c) => c,
            None => tin_bounds(tin)
                .ok_or_else(|| err("the TIN has no vertices, expected at least 3".into()))?,
        };
        let max_edge_m = match self.max_edge {
            MaxEdge::Absolute(v) => v,
            MaxEdge::SpacingFactor(f) => {
                f * median_edge(tin).ok_or_else(|| err("the TIN has no triangles".into()))?
            }
        };
        let tris = prepare(tin, max_edge_m);
        let tin_area = tin_area_inside(tin, &tris, bounds);
        let spacing = match self.regression {
            Some(_) => median_edge(tin).unwrap_or(0.0),
            None => 0.0,
        };
        self.cell_sizes_m
            .iter()
            .map(|&cell| {
                let mut r = rasterize(tin, &tris, bounds, cell, self.max_cells).map_err(err)?;
                r.stats.base_z_m = self.base_z_m;
                r.stats.tin_points = tin.vertices.len();
                r.stats.tin_triangles = tin.triangles.len();
                r.stats.tin_surface_area_m2 = tin_area;
                r.stats.max_edge_m = max_edge_m;
                if let Some(f) = self.regression {
                    let support = cell.max(f * spacing);
                    r.stats.regression_fallback_cells = regress(tin, &mut r, support, cell);
                    r.stats.regression_support_m = support;
                }
                surface_stats(&mut r);
                Ok(r)
            })
            .collect()
    }
}

/// `[x_min, y_min, x_max, y_max]` of the TIN vertices.
fn tin_bounds(tin: &Tin) -> Option<[f64; 4]> {
    let first = tin.vertices.first()?;
    Some(
        tin.vertices
            .iter()
            .fold([first[0], first[1], first[0], first[1]], |b, p| {
                [
                    b[0].min(p[0]),
                    b[1].min(p[1]),
                    b[2].max(p[0]),
                    b[3].max(p[1]),
                ]
            }),
    )
}

/// Median horizontal edge length over a deterministic sample of ≤ ~100 000 triangles.
fn median_edge(tin: &Tin) -> Option<f64> {
    let step = (tin.triangles.len() / 100_000).max(1);
    let mut lens: Vec<f64> = tin
        .triangles
        .iter()
        .step_by(step)
        .filter_map(|t| corners(tin, t))
        .flat_map(|[a, b, c]| [dist2d(a, b), dist2d(b, c), dist2d(c, a)])
        .collect();
    median(&mut lens)
}

fn dist2d(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn corners(tin: &Tin, t: &[u32; 3]) -> Option<[[f64; 3]; 3]> {
    let v = |i: u32| tin.vertices.get(i as usize).copied();
    Some([v(t[0])?, v(t[1])?, v(t[2])?])
}

/// The valid triangles (every horizontal edge within the limit, non-degenerate), as TIN
/// indices ordered by their lowest vertex index, then their own index.
///
/// Why this order: `dem.tin` leaves its vertices x-sorted, so visiting a band's triangles in
/// this order sweeps the vertex array once from west to east and the corners a triangle reads
/// are near those the previous one read (in cache), where the TIN's own triangle order sends
/// every read to a random place of a vertex array of hundreds of megabytes. Only an index is
/// kept per triangle (not a copy of its corners: 4 bytes instead of ~100, 3.7 GB on ESTEC).
fn prepare(tin: &Tin, max_edge_m: f64) -> Vec<u32> {
    // The TIN's own bound already keeps every edge within the limit (same measure).
    let checked = tin.max_edge_m.is_some_and(|m| m <= max_edge_m);
    let mut keys: Vec<u64> = tin
        .triangles
        .par_iter()
        .enumerate()
        .filter_map(|(i, t)| {
            // A TIN of over 2³² triangles would not fit in memory (its vertices are u32-indexed).
            let i = u32::try_from(i).ok()?;
            let p = corners(tin, t)?;
            let [a, b, c] = p;
            if !checked && longest_edge(a, b, c) > max_edge_m {
                return None;
            }
            inv_det(&p)?;
            let lowest = t[0].min(t[1]).min(t[2]);
            Some(u64::from(lowest) << 32 | u64::from(i))
        })
        .collect();
    keys.par_sort_unstable();
    keys.into_par_iter().map(|k| k as u32).collect()
}

/// `1 / det` of the barycentric system of a triangle, `None` when it is degenerate.
fn inv_det([a, b, c]: &[[f64; 3]; 3]) -> Option<f64> {
    let det = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1]);
    (det.abs() > 0.0).then(|| 1.0 / det)
}

/// The corners of a triangle `prepare` kept.
fn tri_corners(tin: &Tin, i: u32) -> Option<[[f64; 3]; 3]> {
    corners(tin, tin.triangles.get(i as usize)?)
}

fn tri_area3d([a, b, c]: &[[f64; 3]; 3]) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

fn tin_area_inside(tin: &Tin, tris: &[u32], b: [f64; 4]) -> f64 {
    let parts: Vec<f64> = tris
        .par_chunks(65_536)
        .map(|chunk| {
            chunk
                .iter()
                .filter_map(|&i| tri_corners(tin, i))
                .filter(|p| {
                    let cx = (p[0][0] + p[1][0] + p[2][0]) / 3.0;
                    let cy = (p[0][1] + p[1][1] + p[2][1]) / 3.0;
                    cx >= b[0] && cx <= b[2] && cy >= b[1] && cy <= b[3]
                })
                .map(|p| tri_area3d(&p))
                .sum::<f64>()
        })
        .collect();
    parts.iter().sum()
}

/// Rasterises the prepared triangles into a grid of `cell` over `bounds`.
fn rasterize(
    tin: &Tin,
    tris: &[u32],
    bounds: [f64; 4],
    cell: f64,
    max_cells: u64,
) -> Result<Raster, String> {
    let count = |span: f64| ((span / cell) - 1e-9).ceil().max(1.0);
    let (cols_f, rows_f) = (count(bounds[2] - bounds[0]), count(bounds[3] - bounds[1]));
    if cols_f * rows_f > max_cells as f64 {
        return Err(format!(
            "{cols_f} x {rows_f} cells at {cell} m exceed the limit of {max_cells} cells"
        ));
    }
    let (cols, rows) = (cols_f as usize, rows_f as usize);
    let origin = [bounds[0] + 0.5 * cell, bounds[3] - 0.5 * cell];
    let n_bands = rows.div_ceil(BAND_ROWS);
    let row_of = |y: f64| (origin[1] - y) / cell;
    let col_of = |x: f64| (x - origin[0]) / cell;
    // Band lists built per chunk of triangles in parallel, then joined in chunk order: each band
    // lists its triangles in `tris` order, whatever the thread count.
    let per_chunk: Vec<Vec<Vec<u32>>> = tris
        .par_chunks(1 << 18)
        .map(|chunk| {
            let mut bands: Vec<Vec<u32>> = vec![Vec::new(); n_bands];
            for &i in chunk {
                let Some(p) = tri_corners(tin, i) else {
                    continue;
                };
                let (xmin, xmax) = (
                    p[0][0].min(p[1][0]).min(p[2][0]),
                    p[0][0].max(p[1][0]).max(p[2][0]),
                );
                let (ymin, ymax) = (
                    p[0][1].min(p[1][1]).min(p[2][1]),
                    p[0][1].max(p[1][1]).max(p[2][1]),
                );
                let (r0, r1) = (
                    row_of(ymax).ceil().max(0.0),
                    row_of(ymin).floor().min(rows as f64 - 1.0),
                );
                // A triangle whose bounding box holds no cell centre writes nothing (most of
                // them on a coarse raster of a dense TIN): not listed at all.
                let (c0, c1) = (
                    col_of(xmin).ceil().max(0.0),
                    col_of(xmax).floor().min(cols as f64 - 1.0),
                );
                if r1 < r0 || c1 < c0 {
                    continue;
                }
                for band in bands
                    .iter_mut()
                    .take(r1 as usize / BAND_ROWS + 1)
                    .skip(r0 as usize / BAND_ROWS)
                {
                    band.push(i);
                }
            }
            bands
        })
        .collect();
    let bands: Vec<Vec<u32>> = (0..n_bands)
        .into_par_iter()
        .map(|b| {
            per_chunk
                .iter()
                .filter_map(|c| c.get(b))
                .flatten()
                .copied()
                .collect()
        })
        .collect();
    drop(per_chunk);
    let mut heights = vec![f32::NAN; rows * cols];
    let mut refl = tin.albedo.as_ref().map(|_| vec![f32::NAN; rows * cols]);
    let band_len = BAND_ROWS * cols;
    let grid = Grid {
        origin,
        cell,
        cols,
        rows,
    };
    match refl.as_mut() {
        Some(rv) => heights
            .par_chunks_mut(band_len)
            .zip(rv.par_chunks_mut(band_len))
            .zip(bands.par_iter())
            .enumerate()
            .for_each(|(b, ((h, r), list))| fill_band(&grid, tin, list, b * BAND_ROWS, h, Some(r))),
        None => heights
            .par_chunks_mut(band_len)
            .zip(bands.par_iter())
            .enumerate()
            .for_each(|(b, (h, list))| fill_band(&grid, tin, list, b * BAND_ROWS, h, None)),
    }
    Ok(Raster {
        cell_m: cell,
        rows,
        cols,
        origin,
        bounds,
        heights,
        albedo: refl,
        stats: RasterStats::default(),
    })
}

struct Grid {
    origin: [f64; 2],
    cell: f64,
    cols: usize,
    rows: usize,
}

/// Fills one band (`row0..row0 + BAND_ROWS`) from the triangles listed for it.
fn fill_band(
    g: &Grid,
    tin: &Tin,
    list: &[u32],
    row0: usize,
    h: &mut [f32],
    mut r: Option<&mut [f32]>,
) {
    const EPS: f64 = -1e-10;
    let row_end = (row0 + BAND_ROWS).min(g.rows);
    for &i in list {
        let Some(idx) = tin.triangles.get(i as usize) else {
            continue;
        };
        let Some(p) = corners(tin, idx) else { continue };
        let Some(inv_det) = inv_det(&p) else { continue };
        let [a, b, c] = p;
        let (xmin, xmax) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
        let (ymin, ymax) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
        let c0 = ((xmin - g.origin[0]) / g.cell).ceil().max(0.0) as usize;
        let c1 = ((xmax - g.origin[0]) / g.cell)
            .floor()
            .min(g.cols as f64 - 1.0);
        let r0 = (((g.origin[1] - ymax) / g.cell).ceil().max(0.0) as usize).max(row0);
        let r1 = ((g.origin[1] - ymin) / g.cell).floor();
        if c1 < 0.0 || r1 < 0.0 {
            continue;
        }
        let (c1, r1) = (c1 as usize, (r1 as usize).min(row_end.saturating_sub(1)));
        let refl = tin.albedo.as_deref();
        let att = |k: usize| {
            refl.and_then(|v| v.get(idx[k] as usize))
                .map_or(0.0, |x| f64::from(*x))
        };
        for row in r0..=r1 {
            let py = g.origin[1] - row as f64 * g.cell;
            for col in c0..=c1 {
                let px = g.origin[0] + col as f64 * g.cell;
                let l1 = ((b[1] - c[1]) * (px - c[0]) + (c[0] - b[0]) * (py - c[1])) * inv_det;
                let l2 = ((c[1] - a[1]) * (px - c[0]) + (a[0] - c[0]) * (py - c[1])) * inv_det;
                let l3 = 1.0 - l1 - l2;
                if l1 < EPS || l2 < EPS || l3 < EPS {
                    continue;
                }
                let k = (row - row0) * g.cols + col;
                if let Some(cell) = h.get_mut(k).filter(|v| v.is_nan()) {
                    *cell = (l1 * a[2] + l2 * b[2] + l3 * c[2]) as f32;
                    if let Some(rc) = r.as_deref_mut().and_then(|r| r.get_mut(k)) {
                        *rc = (l1 * att(0) + l2 * att(1) + l3 * att(2)) as f32;
                    }
                }
            }
        }
    }
}

/// Fills the Table 5.3 statistics of `r` (see the module doc).
fn surface_stats(r: &mut Raster) {
    let (cols, cell, base) = (r.cols, r.cell_m, r.stats.base_z_m);
    let h = &r.heights;
    let z = |row: usize, col: usize| {
        h.get(row * cols + col)
            .map(|v| f64::from(*v))
            .filter(|v| v.is_finite())
    };
    let slope = |here: f64, lo: Option<f64>, hi: Option<f64>| match (lo, hi) {
        (Some(l), Some(u)) => (u - l) / (2.0 * cell),
        (Some(l), None) => (here - l) / cell,
        (None, Some(u)) => (u - here) / cell,
        (None, None) => 0.0,
    };
    let per_row: Vec<(f64, f64, usize, usize)> = (0..r.rows)
        .into_par_iter()
        .map(|row| {
            let (mut area, mut vol, mut valid, mut quads) = (0.0, 0.0, 0, 0);
            for col in 0..cols {
                let Some(here) = z(row, col) else { continue };
                let left = col.checked_sub(1).and_then(|c| z(row, c));
                let right = if col + 1 < cols {
                    z(row, col + 1)
                } else {
                    None
                };
                let up = row.checked_sub(1).and_then(|rr| z(rr, col));
                let down = z(row + 1, col);
                let (gx, gy) = (slope(here, left, right), slope(here, down, up));
                area += cell * cell * (1.0 + gx * gx + gy * gy).sqrt();
                vol += cell * cell * (here - base);
                valid += 1;
                if right.is_some()
                    && down.is_some()
                    && col + 1 < cols
                    && z(row + 1, col + 1).is_some()
                {
                    quads += 1;
                }
            }
            (area, vol, valid, quads)
        })
        .collect();
    r.stats.surface_area_m2 = per_row.iter().map(|x| x.0).sum();
    r.stats.volume_m3 = per_row.iter().map(|x| x.1).sum();
    r.stats.points = per_row.iter().map(|x| x.2).sum();
    r.stats.triangles = 2 * per_row.iter().map(|x| x.3).sum::<usize>();
    r.stats.nodata_cells = r.rows * r.cols - r.stats.points;
}

impl Stage for DemRaster {
    const NAME: &'static str = "dem.raster";
    const VERSION: u32 = 4;
    const DESCRIPTION: &'static str =
        "Rasterise the TIN into north-up height and albedo grids; long-edge triangles become nodata; \
         optionally estimate cells by local regression over the TIN vertices";
    type Input = Tin;
    type Output = Vec<Raster>;

    fn params(&self) -> serde_json::Value {
        serde_json::json!({
            "cell_sizes_m": self.cell_sizes_m,
            "crop": self.crop,
            "max_edge": self.max_edge,
            "base_z_m": self.base_z_m,
            "max_cells": self.max_cells,
            "regression_support_factor": self.regression,
        })
    }

    fn run(&self, _cx: &StageCx, input: &Tin) -> Result<Vec<Raster>, StageError> {
        self.rasterize_all(input)
    }
}
