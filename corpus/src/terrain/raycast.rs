//! The corpus' own ray caster against the true terrain.
//!
//! **Why a separate caster.** The corpus' files are the test data of the validator, so the
//! corpus must not share code with it: a bug in a shared ray caster would be present on both
//! sides of the comparison and cancel out. This caster is written independently of the
//! validator's renderer but intersects the *same* surface, so campaigns come out (up to
//! rounding) as they did when the corpus borrowed the validator's tracer.
//!
//! **The surface** (normative). Cell `(c, r)` of a [`HeightGrid`] has its centre at
//! `x = origin_m[0] + c * cell_m`, `y = origin_m[1] - r * cell_m` (row 0 = north). The quad
//! between the centres of cells `(c, r)`, `(c+1, r)`, `(c, r+1)` and `(c+1, r+1)` is split
//! along its NW–SE diagonal (from `(c, r)` to `(c+1, r+1)`) into two planar triangles,
//! NW–NE–SE and NW–SE–SW. A triangle exists only when its three heights are finite, so a
//! `NaN` cell removes exactly the (up to six) triangles touching it. Normals point up.
//!
//! **Algorithm: a hierarchical 2-D DDA over min/max blocks.** Level 0 is the quads; level
//! `k + 1` groups 8 x 8 nodes of level `k` and stores the `[zmin, zmax]` of the finite heights
//! it covers; levels are added until one node covers the whole grid. A ray is converted to
//! grid units (`u` = column, `v` = row, in cells from cell (0, 0); `z` stays in metres) and
//! clipped to the grid's box (domain x `[zmin, zmax]`) and to `0 < t <= t_max`. The walk
//! starts on the finest level whose nodes are at least half as wide as the clipped ray's
//! footprint (short rays need not descend from the root). On every level an Amanatides & Woo
//! walk steps through the nodes the ray crosses inside its parent, in ray order, with each
//! node's entry/exit `t` computed directly from the origin (no accumulated increments). A node is skipped when the ray's `z` range over `[t_entry, t_exit]`
//! misses the node's padded `[zmin, zmax]`, and walked one level down otherwise. At level 0 the
//! two triangles of the quad are intersected (plane + barycentric tests in `f64`, with a 1e-9
//! cell slack so rays through shared edges cannot slip through); since quads are visited front
//! to back, the first quad with a hit holds the nearest hit. Using both the minimum and the
//! maximum makes rays from any direction cheap: camera rays looking down, near-horizontal
//! laser rays, and rays leaving the surface upwards. The caster is read-only after
//! [`TerrainCaster::new`], hence `Sync`, and shared by all threads.

use crate::HeightGrid;

/// Log2 of the fan-out of a level: a node of level `k + 1` covers 8 x 8 nodes of level `k`.
const BLOCK_SHIFT: u32 = 3;

/// Slack of the barycentric tests, in cells, so a ray through a shared edge or vertex hits.
const EDGE_EPS: f64 = 1e-9;

/// Slack on the node height ranges, metres, so rounding cannot skip a flat node.
const Z_PAD: f64 = 1e-7;

/// A ray/terrain intersection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    /// Ray parameter: the point is `origin + t * dir`.
    pub t: f64,
    /// Ground-frame intersection point.
    pub point: [f64; 3],
    /// Unit normal of the triangle hit, pointing up (z > 0).
    pub normal: [f64; 3],
}

/// `[zmin, zmax]` of the nodes of one level (a node of level `k` covers `8^k x 8^k` quads).
#[derive(Debug, Clone)]
struct Level {
    /// Nodes per row.
    nx: usize,
    /// Rows of nodes.
    ny: usize,
    /// `[zmin, zmax]` per node, row-major; `[+inf, -inf]` when the node has no finite height.
    range: Vec<[f32; 2]>,
}

impl Level {
    fn range(&self, i: usize, j: usize) -> [f32; 2] {
        self.range
            .get(j * self.nx + i)
            .copied()
            .unwrap_or([f32::INFINITY, f32::NEG_INFINITY])
    }
}

/// Casts rays against a [`HeightGrid`]; build once, share across threads.
#[derive(Debug, Clone)]
pub struct TerrainCaster {
    /// Ground x, y of the centre of cell (0, 0).
    origin_m: [f64; 2],
    /// Cell size, metres.
    cell_m: f64,
    /// Columns of cells.
    width: usize,
    /// Heights, row-major.
    z: Vec<f32>,
    /// Quads per row (`width - 1`).
    quads_x: usize,
    /// Rows of quads (`height - 1`).
    quads_y: usize,
    /// `levels[k]` is level `k + 1` (level 0, the quads, is read from `z`); the last has one
    /// node. Empty when the grid has no quad.
    levels: Vec<Level>,
    /// `[zmin, zmax]` of all finite heights.
    z_range: [f64; 2],
}

/// A ray in grid units.
#[derive(Debug, Clone, Copy)]
struct Ray {
    u0: f64,
    v0: f64,
    z0: f64,
    du: f64,
    dv: f64,
    dz: f64,
    inv_du: f64,
    inv_dv: f64,
    t_max: f64,
}

impl Ray {
    fn z_at(&self, t: f64) -> f64 {
        self.z0 + t * self.dz
    }
}

/// Which triangle of a quad.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Half {
    /// NW–NE–SE (local `a >= b`).
    Upper,
    /// NW–SE–SW (local `a <= b`).
    Lower,
}

impl TerrainCaster {
    /// Builds the min/max levels of `grid`.
    pub fn new(grid: &HeightGrid) -> TerrainCaster {
        let width = grid.width;
        let height = grid.height;
        let mut z = grid.z.clone();
        z.resize(width * height, f32::NAN);
        let quads_x = width.saturating_sub(1);
        let quads_y = height.saturating_sub(1);
        let mut z_range = [f64::INFINITY, f64::NEG_INFINITY];
        for &h in z.iter().filter(|h| h.is_finite()) {
            z_range[0] = z_range[0].min(f64::from(h));
            z_range[1] = z_range[1].max(f64::from(h));
        }
        let mut levels: Vec<Level> = Vec::new();
        if quads_x > 0 && quads_y > 0 {
            levels.push(first_level(&z, width, quads_x, quads_y));
            while let Some(last) = levels.last() {
                if last.nx <= 1 && last.ny <= 1 {
                    break;
                }
                let next = coarser_level(last);
                levels.push(next);
            }
        }
        TerrainCaster {
            origin_m: grid.origin_m,
            cell_m: grid.cell_m,
            width,
            z,
            quads_x,
            quads_y,
            levels,
            z_range,
        }
    }

    /// The first hit along `origin + t * dir` with `0 < t <= t_max` (`dir` need not be unit;
    /// `t` is in the caller's units).
    pub fn trace(&self, origin: [f64; 3], dir: [f64; 3], t_max: f64) -> Option<SurfaceHit> {
        let (ray, t0, t1) = self.clip(origin, dir, t_max)?;
        let (t, [p, q]) = self.first_hit(&ray, t0, t1)?;
        // Surface slopes per cell along u (east) and v (south) -> ground gradient.
        let n = [-p / self.cell_m, q / self.cell_m, 1.0];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        Some(SurfaceHit {
            t,
            point: [
                origin[0] + t * dir[0],
                origin[1] + t * dir[1],
                origin[2] + t * dir[2],
            ],
            normal: [n[0] / len, n[1] / len, n[2] / len],
        })
    }

    /// Whether the ray hits the terrain with `0 < t <= t_max`.
    pub fn occluded(&self, origin: [f64; 3], dir: [f64; 3], t_max: f64) -> bool {
        self.clip(origin, dir, t_max)
            .is_some_and(|(ray, t0, t1)| self.first_hit(&ray, t0, t1).is_some())
    }

    /// The ray in grid units and its `t` interval inside the grid's box, if not empty.
    fn clip(&self, origin: [f64; 3], dir: [f64; 3], t_max: f64) -> Option<(Ray, f64, f64)> {
        let finite = origin.iter().chain(dir.iter()).all(|v| v.is_finite());
        if !finite || t_max.is_nan() || t_max <= 0.0 || self.cell_m.is_nan() || self.cell_m <= 0.0 {
            return None;
        }
        if dir == [0.0; 3] || self.z_range[0] > self.z_range[1] {
            return None;
        }
        let du = dir[0] / self.cell_m;
        let dv = -dir[1] / self.cell_m;
        let ray = Ray {
            u0: (origin[0] - self.origin_m[0]) / self.cell_m,
            v0: (self.origin_m[1] - origin[1]) / self.cell_m,
            z0: origin[2],
            du,
            dv,
            dz: dir[2],
            inv_du: 1.0 / du,
            inv_dv: 1.0 / dv,
            t_max,
        };
        let mut t0 = 0.0f64;
        let mut t1 = t_max;
        let slabs = [
            (ray.u0, du, -EDGE_EPS, self.quads_x as f64 + EDGE_EPS),
            (ray.v0, dv, -EDGE_EPS, self.quads_y as f64 + EDGE_EPS),
            (
                ray.z0,
                ray.dz,
                self.z_range[0] - Z_PAD,
                self.z_range[1] + Z_PAD,
            ),
        ];
        for (o, d, lo, hi) in slabs {
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
            } else {
                let (a, b) = ((lo - o) / d, (hi - o) / d);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        (t0 <= t1).then_some((ray, t0, t1))
    }

    /// The first hit of the ray for `t` in `[t0, t1]` (its span inside the grid's box): the
    /// walk starts on the finest level whose nodes are at least half the ray's extent, so a
    /// short ray does not descend from the root and a long one takes few steps up there.
    fn first_hit(&self, ray: &Ray, t0: f64, t1: f64) -> Option<(f64, [f64; 2])> {
        let extent = ray.du.abs().max(ray.dv.abs()) * (t1 - t0);
        let mut lvl = 1;
        while lvl < self.levels.len()
            && ((1u64 << (BLOCK_SHIFT * lvl as u32)) as f64) < extent / 2.0
        {
            lvl += 1;
        }
        let level = self.levels.get(lvl - 1)?;
        self.walk_nodes(ray, lvl, [0, 0], [level.nx, level.ny], t0, t1)
    }

    /// Walks the nodes of level `lvl >= 1` with indices in `[lo, hi)` that the ray crosses for
    /// `t` in `[t_in, t_out]`, front to back, descending into those whose `[zmin, zmax]` the
    /// ray's `z` meets; returns the first hit's `t` and the hit triangle's slopes (height change
    /// per cell along `u` and `v`).
    fn walk_nodes(
        &self,
        ray: &Ray,
        lvl: usize,
        lo: [usize; 2],
        hi: [usize; 2],
        t_in: f64,
        t_out: f64,
    ) -> Option<(f64, [f64; 2])> {
        let level = self.levels.get(lvl.checked_sub(1)?)?;
        // Children: nodes of level `lvl - 1`, or quads.
        let (cx, cy) = match lvl.checked_sub(2).and_then(|k| self.levels.get(k)) {
            Some(child) => (child.nx, child.ny),
            None => (self.quads_x, self.quads_y),
        };
        let size = (1u64 << (BLOCK_SHIFT * lvl as u32)) as f64;
        let mut dda = Dda::new(ray, size, lo, hi, t_in)?;
        let mut z_a = ray.z_at(t_in);
        loop {
            let (t_b, last) = dda.exit(t_out);
            let z_b = ray.z_at(t_b);
            let [zmin, zmax] = level.range(dda.i, dda.j);
            if z_a.min(z_b) <= f64::from(zmax) + Z_PAD && z_a.max(z_b) >= f64::from(zmin) - Z_PAD {
                let clo = [dda.i << BLOCK_SHIFT, dda.j << BLOCK_SHIFT];
                let chi = [
                    ((dda.i + 1) << BLOCK_SHIFT).min(cx),
                    ((dda.j + 1) << BLOCK_SHIFT).min(cy),
                ];
                let hit = if lvl == 1 {
                    self.walk_quads(ray, clo, chi, dda.t_a, t_b)
                } else {
                    self.walk_nodes(ray, lvl - 1, clo, chi, dda.t_a, t_b)
                };
                if hit.is_some() {
                    return hit;
                }
            }
            if last || !dda.step(t_b) {
                return None;
            }
            z_a = z_b;
        }
    }

    /// Walks the quads with indices in `[lo, hi)` that the ray crosses for `t` in
    /// `[t_in, t_out]`, front to back, and intersects their triangles.
    fn walk_quads(
        &self,
        ray: &Ray,
        lo: [usize; 2],
        hi: [usize; 2],
        t_in: f64,
        t_out: f64,
    ) -> Option<(f64, [f64; 2])> {
        let mut dda = Dda::new(ray, 1.0, lo, hi, t_in)?;
        let mut z_a = ray.z_at(t_in);
        loop {
            let (t_b, last) = dda.exit(t_out);
            let z_b = ray.z_at(t_b);
            let hit = self.quad_hit(ray, dda.i, dda.j, z_a.min(z_b), z_a.max(z_b));
            if hit.is_some() {
                return hit;
            }
            if last || !dda.step(t_b) {
                return None;
            }
            z_a = z_b;
        }
    }

    /// The nearest hit of the ray with the triangles of quad `(i, j)`, over which the ray's
    /// height spans `[z_lo, z_hi]`.
    fn quad_hit(
        &self,
        ray: &Ray,
        i: usize,
        j: usize,
        z_lo: f64,
        z_hi: f64,
    ) -> Option<(f64, [f64; 2])> {
        let k = j * self.width + i;
        let (Some(&[nw, ne]), Some(&[sw, se])) = (
            self.z.get(k..k + 2),
            self.z.get(k + self.width..k + self.width + 2),
        ) else {
            return None;
        };
        // NaN-ignoring min/max: NaN only when all four are holes.
        let zmin = f64::from(nw.min(ne).min(sw).min(se));
        let zmax = f64::from(nw.max(ne).max(sw).max(se));
        if !(z_lo <= zmax + Z_PAD && z_hi >= zmin - Z_PAD) {
            return None;
        }
        if !(nw.is_finite() && se.is_finite()) {
            return None;
        }
        let (nw, ne, sw, se) = (f64::from(nw), f64::from(ne), f64::from(sw), f64::from(se));
        let a0 = ray.u0 - i as f64;
        let b0 = ray.v0 - j as f64;
        let upper = if ne.is_finite() {
            triangle(ray, a0, b0, nw, ne - nw, se - ne, Half::Upper)
        } else {
            None
        };
        let lower = if sw.is_finite() {
            triangle(ray, a0, b0, nw, se - sw, sw - nw, Half::Lower)
        } else {
            None
        };
        match (upper, lower) {
            (Some(u), Some(l)) => Some(if l.0 < u.0 { l } else { u }),
            (u, l) => u.or(l),
        }
    }
}

/// Amanatides & Woo stepping through square nodes of `size` quads, indices in `[lo, hi)`.
/// Every boundary's `t` is computed from the ray's origin, so no error accumulates.
#[derive(Debug, Clone, Copy)]
struct Dda {
    /// Current node.
    i: usize,
    j: usize,
    /// `t` at which the ray entered the current node.
    t_a: f64,
    /// Boundary `t` of the next column / row crossing.
    tu: f64,
    tv: f64,
    lo: [usize; 2],
    hi: [usize; 2],
    size: f64,
    u0: f64,
    v0: f64,
    inv_du: f64,
    inv_dv: f64,
    /// Direction of travel: +1, -1 or 0 per axis.
    su: i8,
    sv: i8,
}

impl Dda {
    /// Starts in the node holding the ray point at `t_in` (clamped to the index range).
    fn new(ray: &Ray, size: f64, lo: [usize; 2], hi: [usize; 2], t_in: f64) -> Option<Dda> {
        if lo[0] >= hi[0] || lo[1] >= hi[1] {
            return None;
        }
        let inv_size = 1.0 / size;
        // Truncation equals `floor` for the non-negative values that are not clamped to
        // `lo` anyway (and avoids a libm call on baseline x86-64).
        let start = |o: f64, d: f64, lo: usize, hi: usize| -> usize {
            let c = (o + t_in * d) * inv_size;
            if c <= lo as f64 {
                lo
            } else if c >= (hi - 1) as f64 {
                hi - 1
            } else {
                c as usize
            }
        };
        let sign = |d: f64| -> i8 {
            if d > 0.0 {
                1
            } else if d < 0.0 {
                -1
            } else {
                0
            }
        };
        let mut dda = Dda {
            i: start(ray.u0, ray.du, lo[0], hi[0]),
            j: start(ray.v0, ray.dv, lo[1], hi[1]),
            t_a: t_in,
            tu: f64::INFINITY,
            tv: f64::INFINITY,
            lo,
            hi,
            size,
            u0: ray.u0,
            v0: ray.v0,
            inv_du: ray.inv_du,
            inv_dv: ray.inv_dv,
            su: sign(ray.du),
            sv: sign(ray.dv),
        };
        dda.tu = dda.boundary(dda.i, dda.su, dda.u0, dda.inv_du);
        dda.tv = dda.boundary(dda.j, dda.sv, dda.v0, dda.inv_dv);
        Some(dda)
    }

    /// `t` at which the ray leaves node index `idx` along one axis.
    fn boundary(&self, idx: usize, s: i8, o: f64, inv: f64) -> f64 {
        match s {
            1 => ((idx + 1) as f64 * self.size - o) * inv,
            -1 => (idx as f64 * self.size - o) * inv,
            _ => f64::INFINITY,
        }
    }

    /// Exit `t` of the current node (not before its entry), and whether it is the last node
    /// before `t_out`.
    fn exit(&self, t_out: f64) -> (f64, bool) {
        let t = self.tu.min(self.tv);
        if t >= t_out {
            (t_out.max(self.t_a), true)
        } else {
            (t.max(self.t_a), false)
        }
    }

    /// Moves to the next node, entered at `t_b`; false when it is outside the index range.
    fn step(&mut self, t_b: f64) -> bool {
        self.t_a = t_b;
        if self.tu <= self.tv {
            match self.su {
                1 if self.i + 1 < self.hi[0] => self.i += 1,
                -1 if self.i > self.lo[0] => self.i -= 1,
                _ => return false,
            }
            self.tu = self.boundary(self.i, self.su, self.u0, self.inv_du);
        } else {
            match self.sv {
                1 if self.j + 1 < self.hi[1] => self.j += 1,
                -1 if self.j > self.lo[1] => self.j -= 1,
                _ => return false,
            }
            self.tv = self.boundary(self.j, self.sv, self.v0, self.inv_dv);
        }
        true
    }
}

/// Intersects the ray with the plane `z = z_nw + a * p + b * q` over one triangle of a quad
/// (`a`, `b` = local grid coordinates from the quad's NW corner; the ray's local start is
/// `(a0, b0)`); returns `t` and the slopes `[p, q]`.
fn triangle(
    ray: &Ray,
    a0: f64,
    b0: f64,
    z_nw: f64,
    p: f64,
    q: f64,
    half: Half,
) -> Option<(f64, [f64; 2])> {
    let denom = ray.dz - ray.du * p - ray.dv * q;
    if denom == 0.0 {
        return None;
    }
    let t = (z_nw + a0 * p + b0 * q - ray.z0) / denom;
    if !(t > 0.0 && t <= ray.t_max) {
        return None;
    }
    let a = a0 + t * ray.du;
    let b = b0 + t * ray.dv;
    let inside = match half {
        Half::Upper => b >= -EDGE_EPS && a <= 1.0 + EDGE_EPS && a - b >= -EDGE_EPS,
        Half::Lower => a >= -EDGE_EPS && b <= 1.0 + EDGE_EPS && b - a >= -EDGE_EPS,
    };
    inside.then_some((t, [p, q]))
}

/// Level 1: the `[zmin, zmax]` of the finite heights of every 8 x 8 block of quads.
fn first_level(z: &[f32], width: usize, quads_x: usize, quads_y: usize) -> Level {
    let block = 1usize << BLOCK_SHIFT;
    let nx = quads_x.div_ceil(block);
    let ny = quads_y.div_ceil(block);
    let mut range = Vec::with_capacity(nx * ny);
    for bj in 0..ny {
        // Quads j in [bj*8, min(bj*8+8, quads_y)) touch cell rows up to the end bound.
        let rows = bj * block..=((bj + 1) * block).min(quads_y);
        for bi in 0..nx {
            let cols = bi * block..=((bi + 1) * block).min(quads_x);
            let mut r = [f32::INFINITY, f32::NEG_INFINITY];
            for row in rows.clone() {
                let start = row * width;
                let Some(cells) = z.get(start + cols.start()..=start + cols.end()) else {
                    continue;
                };
                for &h in cells.iter().filter(|h| h.is_finite()) {
                    r[0] = r[0].min(h);
                    r[1] = r[1].max(h);
                }
            }
            range.push(r);
        }
    }
    Level { nx, ny, range }
}

/// The next level: `[zmin, zmax]` over 8 x 8 nodes of `fine`.
fn coarser_level(fine: &Level) -> Level {
    let block = 1usize << BLOCK_SHIFT;
    let nx = fine.nx.div_ceil(block);
    let ny = fine.ny.div_ceil(block);
    let mut range = Vec::with_capacity(nx * ny);
    for bj in 0..ny {
        for bi in 0..nx {
            let mut r = [f32::INFINITY, f32::NEG_INFINITY];
            for j in bj * block..((bj + 1) * block).min(fine.ny) {
                for i in bi * block..((bi + 1) * block).min(fine.nx) {
                    let [lo, hi] = fine.range(i, j);
                    r[0] = r[0].min(lo);
                    r[1] = r[1].max(hi);
                }
            }
            range.push(r);
        }
    }
    Level { nx, ny, range }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of `w x h` cells of `cell` metres with origin `origin` and heights `f(x, y)`.
    fn grid(
        w: usize,
        h: usize,
        cell: f64,
        origin: [f64; 2],
        f: impl Fn(f64, f64) -> f64,
    ) -> HeightGrid {
        let mut z = Vec::with_capacity(w * h);
        for r in 0..h {
            for c in 0..w {
                z.push(f(origin[0] + c as f64 * cell, origin[1] - r as f64 * cell) as f32);
            }
        }
        HeightGrid {
            origin_m: origin,
            cell_m: cell,
            width: w,
            height: h,
            z,
        }
    }

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        a.iter().zip(b.iter()).all(|(x, y)| (x - y).abs() <= tol)
    }

    /// Brute force: every triangle of the grid, nearest `t`.
    fn brute(g: &HeightGrid, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<f64> {
        let mut best: Option<f64> = None;
        let at = |c: usize, r: usize| -> [f64; 3] {
            [
                g.origin_m[0] + c as f64 * g.cell_m,
                g.origin_m[1] - r as f64 * g.cell_m,
                f64::from(g.z[r * g.width + c]),
            ]
        };
        for r in 0..g.height - 1 {
            for c in 0..g.width - 1 {
                let (nw, ne, sw, se) = (at(c, r), at(c + 1, r), at(c, r + 1), at(c + 1, r + 1));
                for tri in [[nw, ne, se], [nw, se, sw]] {
                    if tri.iter().any(|p| !p[2].is_finite()) {
                        continue;
                    }
                    if let Some(t) = moller_trumbore(o, d, tri) {
                        if t > 0.0 && t <= t_max && best.is_none_or(|b| t < b) {
                            best = Some(t);
                        }
                    }
                }
            }
        }
        best
    }

    fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }
    fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    fn moller_trumbore(o: [f64; 3], d: [f64; 3], [p0, p1, p2]: [[f64; 3]; 3]) -> Option<f64> {
        let e1 = sub(p1, p0);
        let e2 = sub(p2, p0);
        let pv = cross(d, e2);
        let det = dot(e1, pv);
        if det.abs() < 1e-300 {
            return None;
        }
        let tv = sub(o, p0);
        let u = dot(tv, pv) / det;
        let qv = cross(tv, e1);
        let v = dot(d, qv) / det;
        let eps = 1e-12;
        (u >= -eps && v >= -eps && u + v <= 1.0 + eps).then(|| dot(e2, qv) / det)
    }

    /// Tiny deterministic generator (splitmix64) for the randomized tests.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
    }

    #[test]
    fn caster_is_shareable_across_threads() {
        fn sync_send<T: Sync + Send>() {}
        sync_send::<TerrainCaster>();
    }

    #[test]
    fn flat_plane() {
        let g = grid(20, 20, 0.1, [0.0, 1.9], |_, _| 1.0);
        let c = TerrainCaster::new(&g);
        let hit = c.trace([0.5, 0.7, 5.0], [0.1, 0.2, -1.0], 100.0).unwrap();
        assert!((hit.t - 4.0).abs() < 1e-12, "{hit:?}");
        assert!(close(hit.point, [0.9, 1.5, 1.0], 1e-12), "{hit:?}");
        assert!(close(hit.normal, [0.0, 0.0, 1.0], 1e-15));
        // Non-unit direction: t scales.
        let hit2 = c.trace([0.5, 0.7, 5.0], [0.2, 0.4, -2.0], 100.0).unwrap();
        assert!((hit2.t - 2.0).abs() < 1e-12);
        // t_max cuts.
        assert!(c.trace([0.5, 0.7, 5.0], [0.1, 0.2, -1.0], 3.999).is_none());
        assert!(c.occluded([0.5, 0.7, 5.0], [0.1, 0.2, -1.0], 4.001));
        assert!(!c.occluded([0.5, 0.7, 5.0], [0.1, 0.2, -1.0], 3.999));
        // Outside the domain (x > 1.9) there is nothing.
        assert!(c.trace([2.5, 0.7, 5.0], [0.0, 0.0, -1.0], 100.0).is_none());
    }

    #[test]
    fn tilted_plane_analytic() {
        // z = 0.5 x - 0.25 y + 1, exact in f32 on a 0.25 m grid.
        let (a, b, z0) = (0.5, -0.25, 1.0);
        let g = grid(41, 33, 0.25, [-3.0, 5.0], |x, y| a * x + b * y + z0);
        let c = TerrainCaster::new(&g);
        let mut rng = Rng(7);
        let n_expected = {
            let n = [-a, -b, 1.0];
            let l = dot(n, n).sqrt();
            [n[0] / l, n[1] / l, n[2] / l]
        };
        let mut hits = 0;
        for _ in 0..5000 {
            let o = [
                rng.range(-6.0, 10.0),
                rng.range(-6.0, 8.0),
                rng.range(-2.0, 12.0),
            ];
            let d = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ];
            // Analytic: o_z + t d_z = a (o_x + t d_x) + b (o_y + t d_y) + z0.
            let t = (a * o[0] + b * o[1] + z0 - o[2]) / (d[2] - a * d[0] - b * d[1]);
            let p = [o[0] + t * d[0], o[1] + t * d[1]];
            let inside = t > 0.0
                && (-3.0 + 1e-6..7.0 - 1e-6).contains(&p[0])
                && (-3.0 + 1e-6..5.0 - 1e-6).contains(&p[1]);
            let got = c.trace(o, d, 1e9);
            let outside_margin = !(-3.0 - 1e-6..=7.0 + 1e-6).contains(&p[0])
                || !(-3.0 - 1e-6..=5.0 + 1e-6).contains(&p[1])
                || t <= 0.0;
            if inside {
                let h = got.unwrap_or_else(|| panic!("miss {o:?} {d:?} t={t}"));
                assert!((h.t - t).abs() <= 1e-9 * t.abs().max(1.0), "{} vs {t}", h.t);
                assert!(close(h.normal, n_expected, 1e-12));
                hits += 1;
            } else if outside_margin {
                assert!(got.is_none(), "{o:?} {d:?} {got:?}");
            }
        }
        assert!(hits > 500, "{hits}");
    }

    #[test]
    fn single_spike() {
        // Flat 0 with one cell at 1 m: a pyramid of 6 triangles around cell (10, 10).
        let g = grid(21, 21, 1.0, [0.0, 20.0], |x, y| {
            if x == 10.0 && y == 10.0 {
                1.0
            } else {
                0.0
            }
        });
        let c = TerrainCaster::new(&g);
        // Straight down on the apex.
        let h = c.trace([10.0, 10.0, 5.0], [0.0, 0.0, -1.0], 10.0).unwrap();
        assert!((h.t - 4.0).abs() < 1e-12);
        // Straight down at local (a, b) = (0.25, 0.9) of quad (10, 9), whose SW corner is the
        // spike: NW–SE–SW, z = b (SW - NW) + a (SE - SW) = 0.9 - 0.25.
        let h = c.trace([10.25, 10.1, 5.0], [0.0, 0.0, -1.0], 10.0).unwrap();
        assert!((h.point[2] - 0.65).abs() < 1e-12, "{h:?}");
        let s = 1.0 / 3.0f64.sqrt();
        assert!(close(h.normal, [s, s, s], 1e-12), "{h:?}");
        // A horizontal ray at 0.5 m along the row y = 10.2 from the west: the western face
        // (NW–SE–SW of quad (9, 9): z = 1 - (10 - x) - ... ) is first hit where the pyramid is
        // 0.5 high. Check against brute force instead of the face algebra.
        for (y, z) in [(10.2, 0.5), (9.7, 0.3), (10.0, 0.5), (10.9, 0.05)] {
            let o = [-3.0, y, z];
            let d = [1.0, 0.0, 0.0];
            let want = brute(&g, o, d, 100.0).unwrap();
            let got = c.trace(o, d, 100.0).unwrap();
            assert!((got.t - want).abs() < 1e-9, "{y} {z}: {} vs {want}", got.t);
            assert!(got.normal[0] < 0.0 && got.normal[2] > 0.0, "{got:?}");
        }
        // Above the apex height or two cells off the row: nothing.
        assert!(c
            .trace([-3.0, 10.0, 1.01], [1.0, 0.0, 0.0], 100.0)
            .is_none());
        assert!(c.trace([-3.0, 12.0, 0.3], [1.0, 0.0, 0.0], 100.0).is_none());
    }

    #[test]
    fn holes_remove_exactly_the_touching_triangles() {
        let n = 10;
        let mut g = grid(n, n, 0.5, [1.0, 8.0], |_, _| 0.0);
        let hole = (5usize, 5usize);
        g.z[hole.1 * n + hole.0] = f32::NAN;
        let c = TerrainCaster::new(&g);
        let mut removed = 0;
        for r in 0..n - 1 {
            for col in 0..n - 1 {
                let nw = (col, r);
                let ne = (col + 1, r);
                let sw = (col, r + 1);
                let se = (col + 1, r + 1);
                // Centroids in local (a, b): upper (2/3, 1/3), lower (1/3, 2/3).
                for (corners, (a, b)) in [
                    ([nw, ne, se], (2.0 / 3.0, 1.0 / 3.0)),
                    ([nw, se, sw], (1.0 / 3.0, 2.0 / 3.0)),
                ] {
                    let x = 1.0 + (col as f64 + a) * 0.5;
                    let y = 8.0 - (r as f64 + b) * 0.5;
                    let expect = !corners.contains(&hole);
                    removed += usize::from(!expect);
                    let got = c.trace([x, y, 3.0], [0.0, 0.0, -1.0], 10.0);
                    assert_eq!(got.is_some(), expect, "quad ({col}, {r}) {corners:?}");
                    // Slanted rays agree too.
                    let got = c.trace([x - 0.3, y + 0.2, 3.0], [0.1, -0.2 / 3.0, -1.0], 10.0);
                    assert_eq!(got.is_some(), expect, "slanted ({col}, {r}) {corners:?}");
                }
            }
        }
        assert_eq!(removed, 6);
    }

    #[test]
    fn rays_starting_outside_and_leaving() {
        let g = grid(50, 40, 0.02, [0.0, 0.78], |x, y| 0.1 * x + 0.05 * y);
        let c = TerrainCaster::new(&g);
        // A scanner 3 m west, 1 m up, aimed at a point of the surface.
        let target = [0.5, 0.4, 0.1 * 0.5 + 0.05 * 0.4];
        let o = [-3.0, 0.2, 1.0];
        let d = sub(target, o);
        let h = c.trace(o, d, 2.0).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6, "{h:?}");
        assert!(close(h.point, target, 1e-6));
        // Same ray pointing away.
        assert!(c.trace(o, [-d[0], -d[1], -d[2]], 10.0).is_none());
        // From every side, steeply down onto the centre.
        for o in [
            [5.0, 0.4, 3.0],
            [-5.0, 0.4, 3.0],
            [0.5, 6.0, 3.0],
            [0.5, -6.0, 3.0],
        ] {
            let t = [0.5, 0.39, 0.1 * 0.5 + 0.05 * 0.39];
            let h = c.trace(o, sub(t, o), 2.0).unwrap();
            assert!((h.t - 1.0).abs() < 1e-6, "{o:?} {h:?}");
        }
        // Passing over the grid from outside without touching.
        assert!(c.trace([-1.0, 0.4, 0.5], [1.0, 0.0, 0.0], 10.0).is_none());
        // Below the grid, going up: hits the underside.
        let h = c.trace([0.5, 0.4, -1.0], [0.0, 0.0, 1.0], 10.0).unwrap();
        assert!((h.point[2] - (0.05 + 0.02)).abs() < 1e-6, "{h:?}");
    }

    #[test]
    fn vertical_rays_on_vertices_edges_and_faces() {
        let g = grid(12, 9, 0.25, [0.0, 2.0], |x, y| {
            (3.0 * x).sin() + (2.0 * y).cos()
        });
        let c = TerrainCaster::new(&g);
        for r in 0..16 {
            for col in 0..22 {
                let x = col as f64 * 0.125;
                let y = 2.0 - r as f64 * 0.125;
                let got = c.trace([x, y, 10.0], [0.0, 0.0, -1.0], 20.0);
                let want = brute(&g, [x, y, 10.0], [0.0, 0.0, -1.0], 20.0);
                match (got, want) {
                    (Some(h), Some(t)) => assert!((h.t - t).abs() < 1e-9, "{x} {y}"),
                    (None, None) => {}
                    other => panic!("{x} {y}: {other:?}"),
                }
            }
        }
        // Exactly on a cell centre: the height is the cell's.
        let h = c.trace([0.5, 1.5, 10.0], [0.0, 0.0, -1.0], 20.0).unwrap();
        assert!((h.point[2] - f64::from(g.z[2 * 12 + 2])).abs() < 1e-12);
    }

    #[test]
    fn grazing_rays() {
        let g = grid(30, 30, 0.1, [0.0, 2.9], |_, _| 0.0);
        let c = TerrainCaster::new(&g);
        // Parallel just above and exactly in the plane: no hit.
        assert!(c.trace([-1.0, 1.0, 1e-9], [1.0, 0.3, 0.0], 10.0).is_none());
        assert!(c.trace([-1.0, 1.0, 0.0], [1.0, 0.3, 0.0], 10.0).is_none());
        // Very shallow descent: analytic t.
        for slope in [1e-3, 1e-5, 1e-7] {
            let o = [0.05, 0.05, 1.5 * slope];
            let d = [1.0, 1.0, -slope];
            let h = c.trace(o, d, 10.0).unwrap();
            assert!((h.t - 1.5).abs() < 1e-9, "{slope}: {h:?}");
        }
        // Skimming a ridge: heights 0 except a row at 1; ray at 1 - 1e-9 along x crosses it.
        let g = grid(30, 30, 0.1, [0.0, 2.9], |_, y| {
            if (y - 1.5).abs() < 1e-9 {
                1.0
            } else {
                0.0
            }
        });
        let c = TerrainCaster::new(&g);
        let o = [1.03, 0.0, 1.0 - 1e-6];
        let d = [0.0, 1.0, 0.0];
        let want = brute(&g, o, d, 10.0).unwrap();
        let h = c.trace(o, d, 10.0).unwrap();
        assert!((h.t - want).abs() < 1e-9, "{} vs {want}", h.t);
        assert!(c.trace([1.03, 0.0, 1.0 + 1e-6], d, 10.0).is_none());
    }

    #[test]
    fn hits_the_correct_half_of_the_split() {
        // One quad, NW = NE = SW = 0, SE = 1: NW–NE–SE is z = b (rises southwards), NW–SE–SW is
        // z = a (rises eastwards). The other split (NE–SW) would give different heights.
        let g = HeightGrid {
            origin_m: [0.0, 1.0],
            cell_m: 1.0,
            width: 2,
            height: 2,
            z: vec![0.0, 0.0, 0.0, 1.0],
        };
        let c = TerrainCaster::new(&g);
        // Local (a, b) = (0.7, 0.2): a > b, upper triangle, z = b = 0.2.
        let h = c.trace([0.7, 0.8, 2.0], [0.0, 0.0, -1.0], 5.0).unwrap();
        assert!((h.point[2] - 0.2).abs() < 1e-12, "{h:?}");
        let s = 0.5f64.sqrt();
        assert!(close(h.normal, [0.0, s, s], 1e-12), "{h:?}");
        // (a, b) = (0.2, 0.7): lower triangle, z = a = 0.2, normal tilted west.
        let h = c.trace([0.2, 0.3, 2.0], [0.0, 0.0, -1.0], 5.0).unwrap();
        assert!((h.point[2] - 0.2).abs() < 1e-12, "{h:?}");
        assert!(close(h.normal, [-s, 0.0, s], 1e-12), "{h:?}");
        // On the diagonal (a = b = 0.4): both give 0.4.
        let h = c.trace([0.4, 0.6, 2.0], [0.0, 0.0, -1.0], 5.0).unwrap();
        assert!((h.point[2] - 0.4).abs() < 1e-12, "{h:?}");
        // A slanted ray crossing the diagonal from the lower into the upper triangle at z 0.3.
        let o = [0.1, 0.1, 0.3];
        let h = c.trace(o, [1.0, 1.0, 0.0], 5.0).unwrap();
        // Lower triangle: z = a -> a = 0.3 at x = 0.3 (b = 0.7 > a): t = 0.2.
        assert!((h.t - 0.2).abs() < 1e-12, "{h:?}");
    }

    #[test]
    fn upward_rays_miss() {
        let g = grid(40, 40, 0.05, [0.0, 1.95], |x, y| {
            0.2 * (5.0 * x).sin() * (4.0 * y).cos()
        });
        let c = TerrainCaster::new(&g);
        let mut rng = Rng(3);
        for _ in 0..2000 {
            let o = [
                rng.range(0.0, 1.95),
                rng.range(0.0, 1.95),
                rng.range(0.21, 1.0),
            ];
            let d = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(0.0, 1.0),
            ];
            assert!(c.trace(o, d, 100.0).is_none());
            assert!(!c.occluded(o, d, 100.0));
        }
    }

    #[test]
    fn random_rays_match_brute_force_with_holes() {
        let mut rng = Rng(11);
        let mut g = grid(37, 29, 0.01, [0.2, 0.5], |_, _| 0.0);
        for v in &mut g.z {
            *v = (rng.range(-0.02, 0.02)) as f32;
        }
        for k in [40, 41, 300, 301, 302, 700] {
            g.z[k] = f32::NAN;
        }
        let c = TerrainCaster::new(&g);
        let (x0, x1, y0, y1) = (0.2, 0.2 + 0.36, 0.5 - 0.28, 0.5);
        let mut hits = 0;
        for k in 0..3000 {
            let target = [
                rng.range(x0 - 0.02, x1 + 0.02),
                rng.range(y0 - 0.02, y1 + 0.02),
                0.0,
            ];
            let o = match k % 3 {
                0 => [
                    target[0] + rng.range(-0.1, 0.1),
                    target[1] + rng.range(-0.1, 0.1),
                    0.3,
                ],
                1 => [
                    target[0] + rng.range(-2.0, 2.0),
                    target[1] + rng.range(-2.0, 2.0),
                    0.05,
                ],
                _ => [target[0], target[1], rng.range(-0.03, 0.03)],
            };
            let d = if k % 3 == 2 {
                [
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                ]
            } else {
                sub(target, o)
            };
            let got = c.trace(o, d, 10.0);
            let want = brute(&g, o, d, 10.0);
            match (got, want) {
                (Some(h), Some(t)) => {
                    assert!((h.t - t).abs() <= 1e-9 * t.max(1e-3), "{k}: {} vs {t}", h.t);
                    hits += 1;
                }
                (None, None) => {}
                other => panic!("{k} {o:?} {d:?}: {other:?}"),
            }
            assert_eq!(c.occluded(o, d, 10.0), got.is_some());
        }
        assert!(hits > 1000, "{hits}");
    }

    #[test]
    fn degenerate_grids_and_rays() {
        let empty = HeightGrid {
            origin_m: [0.0, 0.0],
            cell_m: 1.0,
            width: 1,
            height: 5,
            z: vec![0.0; 5],
        };
        let c = TerrainCaster::new(&empty);
        assert!(c.trace([0.0, -1.0, 1.0], [0.0, 0.0, -1.0], 10.0).is_none());
        let g = grid(5, 5, 1.0, [0.0, 4.0], |_, _| 0.0);
        let c = TerrainCaster::new(&g);
        assert!(c.trace([1.0, 1.0, 1.0], [0.0, 0.0, 0.0], 10.0).is_none());
        assert!(c
            .trace([1.0, 1.0, 1.0], [f64::NAN, 0.0, -1.0], 10.0)
            .is_none());
        assert!(c
            .trace([1.0, 1.0, 1.0], [0.0, 0.0, -1.0], f64::INFINITY)
            .is_some());
    }
}
