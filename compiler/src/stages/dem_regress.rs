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
//! Vertices without albedo (NaN) do not count towards it.
//!
//! Determinism: each cell sums the vertices within its support in a fixed order (x-band, then
//! y-band, then the TIN's x order, index order among equal x; see below) and cells are
//! independent, so the result is bit-identical for any thread count. The Gaussian weight is pure
//! arithmetic: a tabulated `exp(−t)` at the nearest of 256 nodes per unit, times a 2nd-order step
//! (relative error < 1.3e-9), not libm's `exp`.
//!
//! Speed: the vertices are bucketed on a grid of about half the support (a cell visits the 5 × 5
//! buckets around it). `dem.tin` leaves its vertices x-sorted, so an x-band of buckets is a run of
//! them; each worker copies the x-bands of its strip of columns in y-band order (x, y, z, albedo:
//! 32 bytes a vertex, in a buffer it reuses), so that a cell's neighbours are 5 contiguous runs of
//! memory instead of random accesses into the whole TIN, which made the regression memory-bound.
//! A first pass over the runs keeps the vertices within the support without a branch per vertex;
//! a second sums them.

use std::borrow::Cow;
use std::sync::Mutex;

use rayon::prelude::*;

use super::dem_raster::Raster;
use super::dem_tin::Tin;
use super::geometry::median;

/// Residual RMS, in raster medians, above which a cell's neighbourhood is a discontinuity.
const DISCONTINUITY: f64 = 3.0;
/// Residual RMS below which a neighbourhood is never a discontinuity, m (a noise-free surface
/// has a median residual of ~0).
const MIN_STEP_M: f64 = 0.001;

/// Slack of the band tests, in band widths: wide enough that every vertex within the support of a
/// cell (as the fit computes `dx`, `dy`) lies in the bands the cell visits, however the
/// coordinates round.
const BAND_SLACK: f64 = 1e-3;
/// Raster columns per parallel task (cells of neighbouring columns share their bands).
const STRIP_COLS: usize = 8;

/// Bands of the plane along one axis of the raster: band `k` holds the coordinates `v` of
/// `u = (v − origin)·sign/width` in `[k − 0.5, k + 0.5)`, `width` the cell size times a power of
/// two, about half the support; the line (row or column) of cells `i` is centred on
/// `u = i·lines_per_band`. A line whose support is the cell (two band widths) visits 5 bands and
/// needs half of the outer two: half a band of margin for rounding.
struct Axis {
    origin: f64,
    /// ±1 / width (rows count southwards, towards smaller y).
    scale: f64,
    /// Band coordinate of line `i`'s centre: `i × lines_per_band`.
    lines_per_band: f64,
    /// The support, in band widths.
    reach: f64,
    /// Index `k` of band 0 (lower ones hold nothing a line reaches).
    first: f64,
    /// Number of bands.
    count: usize,
}

impl Axis {
    /// The bands across `lines` cell lines of `cell` from `origin` (the first line's centre).
    fn new(origin: f64, sign: f64, lines: usize, cell: f64, support: f64) -> Option<Axis> {
        let j = (support / (2.0 * cell)).log2().round().clamp(-3.0, 64.0) as i32;
        let width = cell * 2f64.powi(j);
        let lines_per_band = 2f64.powi(-j);
        let reach = support / width;
        let last = lines.checked_sub(1)? as f64 * lines_per_band;
        let first = (-reach + 0.5 - BAND_SLACK).floor();
        let count = (last + reach + 0.5 + BAND_SLACK).floor() - first + 1.0;
        // At most ~8 bands per line, unless the support or cell makes no sense.
        (width > 0.0 && count.is_finite() && count <= (lines as f64 + 64.0) * 8.0).then(|| Axis {
            origin,
            scale: sign / width,
            lines_per_band,
            reach,
            first,
            count: count as usize,
        })
    }

    /// Band coordinate of `v`, shifted so that band `b` is `[b, b + 1)`.
    fn coord(&self, v: f64) -> f64 {
        (v - self.origin) * self.scale + (0.5 - self.first)
    }

    /// The band of `v`, `count` when no line reaches it (or it is not finite).
    fn of(&self, v: f64) -> usize {
        let b = self.coord(v);
        // (`as i64`: one instruction, where `as usize` is a slow sequence on x86-64.)
        if b >= 0.0 && b < self.count as f64 {
            b as i64 as usize
        } else {
            self.count
        }
    }

    /// The bands line `i` visits: every vertex within the support of its centre is in one.
    fn of_line(&self, i: usize) -> std::ops::Range<usize> {
        let u = i as f64 * self.lines_per_band - self.first;
        let lo = (u - self.reach + 0.5 - BAND_SLACK).floor();
        let hi = (u + self.reach + 0.5 + BAND_SLACK).floor() + 1.0;
        let clamp = |v: f64| v.clamp(0.0, self.count as f64) as usize;
        clamp(lo)..clamp(hi)
    }
}

/// The vertices within reach of the raster as a grid of buckets: x-bands across the columns by
/// y-bands across the rows. An x-band is a run of the x-sorted source; a worker copies the x-bands
/// of its strip of columns in y-band order (x order, then index order, within a bucket), so that
/// the vertices around a cell are one contiguous run per x-band it visits.
struct Grid {
    xs: Axis,
    ys: Axis,
    /// x-band `b` is `src.xyz[band_start[b]..band_start[b + 1]]`.
    band_start: Vec<usize>,
}

impl Grid {
    fn new(src: &Source, raster: &Raster, support: f64) -> Option<Grid> {
        let (o, cell) = (raster.origin, raster.cell_m);
        let xs = Axis::new(o[0], 1.0, raster.cols, cell, support)?;
        let ys = Axis::new(o[1], -1.0, raster.rows, cell, support)?;
        // x-band b = the vertices of band coordinate in [b, b + 1): a run of the x-sorted source.
        let band_start: Vec<usize> = (0..=xs.count)
            .map(|b| src.xyz.partition_point(|p| xs.coord(p[0]) < b as f64))
            .collect();
        let longest = band_start.windows(2).map(|w| w[1] - w[0]).max();
        longest
            .is_some_and(|n| u32::try_from(n).is_ok())
            .then_some(Grid { xs, ys, band_start })
    }
}

/// x-bands `first..` of a [`Grid`] copied in bucket order (a worker's buffers, reused).
#[derive(Default)]
struct Buckets {
    first: usize,
    /// Where each x-band starts in `recs`.
    band_start: Vec<usize>,
    /// Per x-band, `ys.count + 1` offsets from its start: y-band `k` is `[at[k], at[k + 1])`.
    at: Vec<u32>,
    /// x, y, z and albedo (NaN where the TIN has none or it is not wanted) of each vertex.
    recs: Vec<[f64; 4]>,
    keys: Vec<u32>,
}

impl Buckets {
    /// Copies x-bands `bands` of `grid` (a stable counting sort by y-band per x-band; vertices
    /// no row reaches, or of non-finite y or z, are left out, at the end of their x-band).
    fn fill(&mut self, grid: &Grid, src: &Source, bands: std::ops::Range<usize>) {
        let (ys, rows) = (&grid.ys, grid.ys.count + 1);
        let i0 = grid.band_start[bands.start];
        let n = grid.band_start[bands.end] - i0;
        if self.recs.len() < n {
            self.recs.resize(n, [0.0; 4]);
        }
        self.first = bands.start;
        self.band_start.clear();
        self.band_start.extend(
            grid.band_start[bands.start..=bands.end]
                .iter()
                .map(|&s| s - i0),
        );
        self.at.clear();
        self.at.resize(bands.len() * rows, 0);
        for (b, at) in bands.zip(self.at.chunks_mut(rows)) {
            let (s0, s1) = (grid.band_start[b], grid.band_start[b + 1]);
            let xyz = &src.xyz[s0..s1];
            let albedo = src.albedo.get(s0..).unwrap_or(&[]);
            let out = &mut self.recs[s0 - i0..s1 - i0];
            self.keys.clear();
            self.keys.extend(xyz.iter().map(|p| {
                let k = if p[2].abs() < f64::INFINITY {
                    ys.of(p[1])
                } else {
                    ys.count
                };
                k as u32
            }));
            for &k in &self.keys {
                if let Some(c) = at.get_mut(k as usize + 1) {
                    *c += 1;
                }
            }
            for k in 1..rows {
                at[k] += at[k - 1];
            }
            // `at[k]` is the start of y-band k: fill from there, then shift back.
            let next = &mut at[..rows - 1];
            for (i, (p, &k)) in xyz.iter().zip(&self.keys).enumerate() {
                if let Some(slot) = next.get_mut(k as usize) {
                    if let Some(r) = out.get_mut(*slot as usize) {
                        let a = albedo.get(i).map_or(f64::NAN, |&a| f64::from(a));
                        *r = [p[0], p[1], p[2], a];
                    }
                    *slot += 1;
                }
            }
            at.copy_within(0..rows - 1, 1);
            at[0] = 0;
        }
    }

    /// The run of `recs` of x-band `b` over y-bands `ys`.
    fn run(&self, b: usize, ys: &std::ops::Range<usize>, rows: usize) -> (usize, usize) {
        let local = b - self.first;
        let base = self.band_start.get(local).copied().unwrap_or(0);
        let off = |k: usize| self.at.get(local * rows + k).map_or(0, |&v| v as usize);
        (base + off(ys.start), base + off(ys.end))
    }
}

/// The TIN vertices sorted by x (index order among equal x) with their albedo (empty when not
/// wanted; NaN where the TIN has none).
struct Source<'a> {
    xyz: Cow<'a, [[f64; 3]]>,
    albedo: Cow<'a, [f32]>,
}

impl<'a> Source<'a> {
    /// `tin` itself when its vertices are x-sorted (as `dem.tin` leaves them), else a sorted copy
    /// without the vertices of non-finite x.
    fn new(tin: &'a Tin, with_albedo: bool) -> Source<'a> {
        let albedo = tin.albedo.as_deref().filter(|_| with_albedo).unwrap_or(&[]);
        if tin.vertices.par_windows(2).all(|w| w[0][0] <= w[1][0])
            && tin.vertices.first().is_none_or(|p| p[0].is_finite())
        {
            return Source {
                xyz: Cow::Borrowed(&tin.vertices),
                albedo: Cow::Borrowed(albedo),
            };
        }
        let mut order: Vec<usize> = (0..tin.vertices.len())
            .filter(|&i| tin.vertices[i][0].is_finite())
            .collect();
        order.par_sort_unstable_by(|&a, &b| {
            tin.vertices[a][0]
                .total_cmp(&tin.vertices[b][0])
                .then(a.cmp(&b))
        });
        Source {
            xyz: Cow::Owned(order.iter().map(|&i| tin.vertices[i]).collect()),
            albedo: Cow::Owned(if with_albedo {
                order
                    .iter()
                    .map(|&i| albedo.get(i).copied().unwrap_or(f32::NAN))
                    .collect()
            } else {
                Vec::new()
            }),
        }
    }
}

/// Nodes per unit of the tabulated `exp(−t)`.
const GAUSS_NODES: f64 = 256.0;
/// Table length, a power of two: nodes for `t` in [0, 4) (within the support, `t ≤ 2`).
const GAUSS_LEN: usize = 1024;
/// 1.5 × 2⁵²: adding it rounds a small non-negative number to an integer held in the low bits.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

/// The constants of one `regress` call.
struct Params {
    support: f64,
    r2: f64,
    inv_2s2: f64,
    ra2: f64,
    inv_2a2: f64,
    /// The albedo support is the height support.
    same_support: bool,
    /// `exp(−i / GAUSS_NODES)`.
    gauss: [f64; GAUSS_LEN],
}

impl Params {
    fn new(support: f64, albedo_support: f64) -> Params {
        let inv_2s2 = 1.0 / (2.0 * (0.5 * support).powi(2));
        let inv_2a2 = 1.0 / (2.0 * (0.5 * albedo_support).powi(2));
        Params {
            support,
            r2: support * support,
            inv_2s2,
            ra2: albedo_support * albedo_support,
            inv_2a2,
            same_support: inv_2a2 == inv_2s2,
            gauss: std::array::from_fn(|i| (-(i as f64) / GAUSS_NODES).exp()),
        }
    }

    /// `exp(−t)` for `t ≥ 0` (a finite value of no meaning beyond the table): the nearest node
    /// times a 2nd-order Taylor step, relative error < 1.3e-9, pure arithmetic (deterministic).
    #[inline(always)]
    fn gauss(&self, t: f64) -> f64 {
        let v = t * GAUSS_NODES + ROUND_MAGIC;
        let i = (v.to_bits() as usize) & (GAUSS_LEN - 1);
        let d = t - (v - ROUND_MAGIC) * (1.0 / GAUSS_NODES);
        self.gauss[i] * (1.0 - d + 0.5 * d * d)
    }
}

/// Weighted sums of one cell's neighbourhood: the normal equations of the plane fit (heights
/// relative to the TIN value, for conditioning; offsets `dx`, `dy` from the cell centre), `Σ w·z²`
/// for the residual, the height range and the albedo sums.
struct Sums {
    w: f64,
    wx: f64,
    wy: f64,
    wxx: f64,
    wxy: f64,
    wyy: f64,
    wz: f64,
    wxz: f64,
    wyz: f64,
    wzz: f64,
    zmin: f64,
    zmax: f64,
    n: usize,
    aw: f64,
    asum: f64,
}

impl Sums {
    /// Sums the vertices of `runs` (of `recs`: x, y, z, albedo) within the support of cell
    /// `(x, y)` of TIN value `hz`, runs in order, then vertices in order. Two passes: the first
    /// lists the vertices within the support (and their `d²`) without a branch per vertex, the
    /// second sums them. `SAME`: the albedo support is the height support; `ALBEDO`: albedo is
    /// wanted.
    #[inline(always)]
    fn of<const SAME: bool, const ALBEDO: bool>(
        recs: &[[f64; 4]],
        runs: &[(usize, usize)],
        (x, y, hz): (f64, f64, f64),
        prm: &Params,
        within: &mut Vec<(usize, f64)>,
    ) -> Sums {
        let total: usize = runs.iter().map(|&(lo, hi)| hi - lo).sum();
        if within.len() < total {
            within.resize(total, (0, 0.0));
        }
        let mut n = 0;
        for &(lo, hi) in runs {
            for (k, p) in (lo..).zip(recs.get(lo..hi).unwrap_or(&[])) {
                let (dx, dy) = (p[0] - x, p[1] - y);
                let d2 = dx * dx + dy * dy;
                if let Some(slot) = within.get_mut(n) {
                    *slot = (k, d2);
                }
                n += usize::from(d2 <= prm.r2);
            }
        }
        let mut s = Sums {
            w: 0.0,
            wx: 0.0,
            wy: 0.0,
            wxx: 0.0,
            wxy: 0.0,
            wyy: 0.0,
            wz: 0.0,
            wxz: 0.0,
            wyz: 0.0,
            wzz: 0.0,
            zmin: f64::INFINITY,
            zmax: f64::NEG_INFINITY,
            n,
            aw: 0.0,
            asum: 0.0,
        };
        for &(k, d2) in within.get(..n).unwrap_or(&[]) {
            let Some(p) = recs.get(k) else { continue };
            let (dx, dy) = (p[0] - x, p[1] - y);
            let w = prm.gauss(d2 * prm.inv_2s2);
            let z = p[2] - hz;
            let (wdx, wdy, wz) = (w * dx, w * dy, w * z);
            s.w += w;
            s.wx += wdx;
            s.wy += wdy;
            s.wxx += wdx * dx;
            s.wxy += wdx * dy;
            s.wyy += wdy * dy;
            s.wz += wz;
            s.wxz += wdx * z;
            s.wyz += wdy * z;
            s.wzz += wz * z;
            s.zmin = if z < s.zmin { z } else { s.zmin };
            s.zmax = if z > s.zmax { z } else { s.zmax };
            if ALBEDO {
                // NaN: no albedo at this vertex.
                let keep = !p[3].is_nan() && (SAME || d2 <= prm.ra2);
                let wa = match (keep, SAME) {
                    (false, _) => 0.0,
                    (true, true) => w,
                    (true, false) => prm.gauss(d2 * prm.inv_2a2),
                };
                s.aw += wa;
                s.asum += wa * if keep { p[3] } else { 0.0 };
            }
        }
        s
    }

    /// The fitted height (relative to the TIN value) and weighted residual RMS, when well-posed.
    fn fit(&self, support: f64) -> Option<(f64, f64)> {
        let m = [
            [self.w, self.wx, self.wy],
            [self.wx, self.wxx, self.wxy],
            [self.wy, self.wxy, self.wyy],
        ];
        let rhs = [self.wz, self.wxz, self.wyz];
        // No extrapolation: the points must surround the cell (weighted centroid within half
        // the support) and the fitted height must lie within their range.
        let centred = self.w > 0.0
            && self.wx * self.wx + self.wy * self.wy <= (0.5 * support * self.w).powi(2);
        let beta = solve_plane(&m, &rhs, support)
            .filter(|beta| self.n >= 3 && centred && (self.zmin..=self.zmax).contains(&beta[0]))?;
        // Weighted residual sum of squares at the solution: Σwz² − βᵀ·XᵀWz.
        let rss = (self.wzz - (0..3).map(|k| beta[k] * rhs[k]).sum::<f64>()).max(0.0);
        Some((beta[0], (rss / self.w).sqrt()))
    }
}

/// Reusable buffers of one worker.
#[derive(Default)]
struct Scratch {
    buckets: Buckets,
    runs: Vec<(usize, usize)>,
    within: Vec<(usize, f64)>,
}

/// The estimates of the cells of columns `c0..c1`, row-major over those columns: fitted height
/// and residual RMS (NaN when ill-posed or nodata), albedo (NaN when none).
struct Strip {
    c0: usize,
    c1: usize,
    fits: Vec<(f64, f64)>,
    albedo: Vec<f32>,
}

/// Regresses the cells of columns `c0..c1`, row by row, from a copy of their x-bands.
fn regress_strip(
    (grid, src): (&Grid, &Source),
    prm: &Params,
    raster: &Raster,
    (c0, c1): (usize, usize),
    with_albedo: bool,
    scratch: &mut Scratch,
) -> Strip {
    let (origin, cell, cols) = (raster.origin, raster.cell_m, raster.cols);
    let Scratch {
        buckets,
        runs,
        within,
    } = scratch;
    let bands = grid.xs.of_line(c0).start..grid.xs.of_line(c1 - 1).end;
    buckets.fill(grid, src, bands);
    let rows = grid.ys.count + 1;
    let width = c1 - c0;
    let mut out = Strip {
        c0,
        c1,
        fits: vec![(f64::NAN, f64::NAN); raster.rows * width],
        albedo: vec![f32::NAN; if with_albedo { raster.rows * width } else { 0 }],
    };
    let recs = &buckets.recs;
    for row in 0..raster.rows {
        let y = origin[1] - row as f64 * cell;
        let ys = grid.ys.of_line(row);
        let heights = &raster.heights[row * cols + c0..row * cols + c1];
        for (k, &h) in heights.iter().enumerate() {
            if !h.is_finite() {
                continue;
            }
            let col = c0 + k;
            let x = origin[0] + col as f64 * cell;
            // x-bands in order, then y-bands, then x order: a fixed order per cell.
            runs.clear();
            runs.extend(grid.xs.of_line(col).map(|b| buckets.run(b, &ys, rows)));
            let cell_at = (x, y, f64::from(h));
            let s = match (with_albedo, prm.same_support) {
                (true, true) => Sums::of::<true, true>(recs, runs, cell_at, prm, within),
                (true, false) => Sums::of::<false, true>(recs, runs, cell_at, prm, within),
                (false, _) => Sums::of::<false, false>(recs, runs, cell_at, prm, within),
            };
            if let Some(a) = out.albedo.get_mut(row * width + k) {
                if s.aw > 0.0 {
                    *a = (s.asum / s.aw) as f32;
                }
            }
            if let Some((dz, rms)) = s.fit(prm.support) {
                out.fits[row * width + k] = (f64::from(h) + dz, rms);
            }
        }
    }
    out
}

/// Replaces the valid cells of `raster` by local-regression estimates over `tin`'s vertices (see
/// the module doc): heights by a plane fit within `support_m`, albedo (when both the TIN and the
/// raster have it) by a weighted mean within `albedo_support_m` (at most `support_m`). Returns the
/// number of valid cells that kept the TIN height (fit ill-posed, or a discontinuity).
pub fn regress(tin: &Tin, raster: &mut Raster, support_m: f64, albedo_support_m: f64) -> usize {
    let albedo_support_m = albedo_support_m.min(support_m);
    if !(support_m.is_finite() && support_m > 0.0 && albedo_support_m > 0.0)
        || raster.cols == 0
        || raster.heights.len() != raster.rows * raster.cols
    {
        return 0;
    }
    let with_albedo = tin.albedo.is_some()
        && raster
            .albedo
            .as_ref()
            .is_some_and(|a| a.len() == raster.heights.len());
    let prm = Params::new(support_m, albedo_support_m);
    let src = Source::new(tin, with_albedo);
    let Some(grid) = Grid::new(&src, raster, support_m) else {
        return 0;
    };
    let cols = raster.cols;
    let spans: Vec<(usize, usize)> = (0..cols)
        .step_by(STRIP_COLS)
        .map(|c0| (c0, (c0 + STRIP_COLS).min(cols)))
        .collect();
    // One scratch per worker at a time, all freed on return.
    let pool: Mutex<Vec<Scratch>> = Mutex::new(Vec::new());
    let strips: Vec<Strip> = {
        let r: &Raster = raster;
        spans
            .par_iter()
            .map(|&span| {
                let mut scratch = pool
                    .lock()
                    .ok()
                    .and_then(|mut p| p.pop())
                    .unwrap_or_default();
                let strip = regress_strip((&grid, &src), &prm, r, span, with_albedo, &mut scratch);
                if let Ok(mut p) = pool.lock() {
                    p.push(scratch);
                }
                strip
            })
            .collect()
    };
    drop(pool);
    drop((grid, src));
    // A discontinuity (a boulder's edge, a wall) is no noise to average: cells whose fit leaves
    // more than DISCONTINUITY × the raster's median residual keep the TIN value.
    let mut rms: Vec<f64> = strips
        .iter()
        .flat_map(|s| s.fits.iter().map(|f| f.1).filter(|r| !r.is_nan()))
        .collect();
    let limit = median(&mut rms).map_or(f64::INFINITY, |m| (DISCONTINUITY * m).max(MIN_STEP_M));
    drop(rms);
    if let Some(out) = raster.albedo.as_mut().filter(|_| with_albedo) {
        out.par_chunks_mut(cols).enumerate().for_each(|(row, out)| {
            for s in &strips {
                let w = s.c1 - s.c0;
                let cells = out[s.c0..s.c1].iter_mut();
                for (o, &a) in cells.zip(&s.albedo[row * w..(row + 1) * w]) {
                    if !a.is_nan() {
                        *o = a;
                    }
                }
            }
        });
    }
    raster
        .heights
        .par_chunks_mut(cols)
        .enumerate()
        .map(|(row, out)| {
            let mut kept = 0;
            for s in &strips {
                let w = s.c1 - s.c0;
                let cells = out[s.c0..s.c1].iter_mut();
                for (h, &(z, rms)) in cells.zip(&s.fits[row * w..(row + 1) * w]) {
                    if !h.is_finite() {
                        continue;
                    }
                    if rms <= limit {
                        *h = z as f32;
                    } else {
                        kept += 1;
                    }
                }
            }
            kept
        })
        .sum()
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
            max_edge_m: None,
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
            max_edge_m: None,
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
            max_edge_m: None,
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

    #[test]
    fn neither_the_thread_count_nor_the_vertex_order_changes_a_bit() {
        // Jittered noisy points ~1 cm apart with albedo, under a 1 cm raster with a nodata cell.
        let mut s = 99u64;
        let mut unit = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut vertices = Vec::new();
        let mut albedo = Vec::new();
        for j in 0..60 {
            for i in 0..60 {
                let (x, y) = ((i as f64 + unit()) * 0.01, (j as f64 + unit()) * 0.01);
                vertices.push([x, y, 0.1 * x + 0.004 * unit()]);
                albedo.push((0.2 + 0.1 * unit()) as f32);
            }
        }
        let yx = Tin {
            vertices: vertices.clone(),
            albedo: Some(albedo.clone()),
            triangles: vec![],
            duplicates_merged: 0,
            max_edge_m: None,
        };
        // The same TIN x-sorted, as `dem.tin` leaves it.
        let mut order: Vec<usize> = (0..vertices.len()).collect();
        order.sort_by(|&a, &b| vertices[a][0].total_cmp(&vertices[b][0]));
        let xs = Tin {
            vertices: order.iter().map(|&i| vertices[i]).collect(),
            albedo: Some(order.iter().map(|&i| albedo[i]).collect()),
            ..yx.clone()
        };
        let run = |tin: &Tin, threads: usize| {
            let mut r = raster_over(0.01, 0.6);
            r.heights[100] = f32::NAN;
            let kept = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| regress(tin, &mut r, 0.025, 0.01));
            let bits = |v: &[f32]| v.iter().map(|h| h.to_bits()).collect::<Vec<_>>();
            (kept, bits(&r.heights), bits(r.albedo.as_ref().unwrap()))
        };
        let reference = run(&xs, 1);
        assert!(
            reference.0 < 3600 / 2,
            "{} cells kept the TIN value",
            reference.0
        );
        assert_eq!(run(&xs, 3), reference);
        assert_eq!(run(&yx, 1), reference);
        assert_eq!(run(&yx, 4), reference);
    }
}
