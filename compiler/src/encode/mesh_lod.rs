//! Levels of detail of a heightfield mesh (SPEC.md §5.3): lod0 is the full grid mesh of
//! [`glb::grid_mesh`]; lod n ≥ 1 is lod0 reduced by meshoptimizer's quadric-error edge-collapse
//! simplifier to about 1/4ⁿ of lod0's triangles (the budget of a stride-2ⁿ grid), with the
//! mesh border locked so neighbouring tiles and levels meet without gaps. Each level's
//! `max_height_error_m` is measured against the full grid, not taken from the simplifier.
//!
//! meshoptimizer is deterministic and the levels are measured independently, so the same grid
//! always gives the same bytes on any thread count.

use meshopt::{SimplifyOptions, VertexDataAdapter};
use rayon::prelude::*;

use super::glb::{self, GlbMesh};

/// Builds the levels of detail of one height grid.
#[derive(Debug)]
pub struct LodBuilder<'a> {
    heights: &'a [f32],
    width: usize,
    height: usize,
    cell_m: f64,
    lod0: GlbMesh,
    lod0_error_m: f64,
}

impl<'a> LodBuilder<'a> {
    /// Meshes the grid (row 0 north, NaN = hole) at full resolution; see [`glb::grid_mesh`].
    pub fn new(
        heights: &'a [f32],
        width: usize,
        height: usize,
        origin_m: [f64; 2],
        cell_m: f64,
    ) -> LodBuilder<'a> {
        let (lod0, lod0_error_m) = glb::grid_mesh(heights, width, height, origin_m, cell_m, 1);
        LodBuilder {
            heights,
            width,
            height,
            cell_m,
            lod0,
            lod0_error_m,
        }
    }

    /// Triangle budget of level `n`: lod0's triangle count over 4ⁿ, rounded up.
    pub fn target_triangles(&self, n: u32) -> usize {
        let tris = self.lod0.indices.len() / 3;
        tris.div_ceil(1usize << (2 * n.min(31)))
    }

    /// Levels `0..count` with their measured largest vertical distance to the full grid,
    /// metres. Level n ≥ 1 is simplified from level n − 1's triangles (over lod0's vertices),
    /// not from lod0 again: each pass then costs a quarter of the one before, which keeps the
    /// 0.005 m grid's levels (5.8 M triangles in lod0) to a few seconds. Compaction and the
    /// error measurement run in parallel per level; the bytes do not depend on thread count.
    pub fn lods(&self, count: u32) -> Vec<(GlbMesh, f64)> {
        let m = &self.lod0;
        let bytes: Vec<u8> = m
            .positions
            .iter()
            .flat_map(|p| p.iter().flat_map(|f| f.to_le_bytes()))
            .collect();
        let mut levels: Vec<Vec<u32>> = Vec::new();
        for n in 1..count {
            let previous = levels.last().unwrap_or(&m.indices);
            let simplified = match VertexDataAdapter::new(&bytes, 12, 0) {
                // Target error 1.0 (the whole mesh extent): the triangle budget alone stops it.
                Ok(v) => meshopt::simplify(
                    previous,
                    &v,
                    self.target_triangles(n) * 3,
                    1.0,
                    SimplifyOptions::LockBorder,
                    None,
                ),
                // Unreachable (12-byte stride, whole vertices); keep the mesh rather than fail.
                Err(_) => previous.clone(),
            };
            levels.push(drop_coincident(&m.positions, simplified));
        }
        let mut out = Vec::with_capacity(levels.len() + 1);
        if count > 0 {
            out.push((self.lod0.clone(), self.lod0_error_m));
        }
        out.par_extend(levels.par_iter().map(|indices| {
            let lod = compact(m, indices);
            let err = self.measure(&lod);
            (lod, err)
        }));
        out
    }

    /// Largest |z_lod(x, y) − z_grid(x, y)| over the grid vertices lod0 triangulates. Each
    /// simplified triangle is rasterised over the grid vertices it covers (exact integer edge
    /// tests: meshoptimizer's simplifier only collapses edges onto existing vertices, so every
    /// lod vertex is still a grid vertex) and z_lod interpolated barycentrically.
    /// Simplification keeps the surface a height function only approximately: a grid vertex
    /// covered by several triangles (a fold) counts its largest deviation, and one covered by
    /// none (a gap left by a fold) is measured against the plane of the triangle whose
    /// centroid is nearest, so the figure is never optimistic about either.
    fn measure(&self, lod: &GlbMesh) -> f64 {
        let (w, h) = (self.width, self.height);
        let z0 = lod.local_origin_m[2];
        // Grid coordinates of the lod's vertices, from their ground positions.
        let cell = if self.cell_m > 0.0 { self.cell_m } else { 1.0 };
        let grid_of = |p: [f32; 3]| -> (i64, i64) {
            (
                (f64::from(p[0]) / cell).round() as i64,
                (-f64::from(p[1]) / cell).round() as i64,
            )
        };
        let tris: Vec<[(i64, i64, f64); 3]> = lod
            .indices
            .chunks_exact(3)
            .map(|t| {
                [0, 1, 2].map(|k| {
                    let p = lod.positions[t[k] as usize];
                    let (c, r) = grid_of(p);
                    (c, r, f64::from(p[2]) + z0)
                })
            })
            .collect();
        let z_grid = |c: i64, r: i64| -> Option<f64> {
            if c < 0 || r < 0 || c as usize >= w || r as usize >= h {
                return None;
            }
            self.heights
                .get(r as usize * w + c as usize)
                .copied()
                .filter(|z| z.is_finite())
                .map(f64::from)
        };
        // Deviation per grid vertex; NaN = not covered by any lod triangle.
        let mut dev = vec![f64::NAN; w * h];
        for t in &tris {
            let [(xa, ya, za), (xb, yb, zb), (xc, yc, zc)] = *t;
            let area = (xb - xa) * (yc - ya) - (yb - ya) * (xc - xa);
            if area == 0 {
                continue;
            }
            let s = area.signum();
            for r in ya.min(yb).min(yc)..=ya.max(yb).max(yc) {
                for c in xa.min(xb).min(xc)..=xa.max(xb).max(xc) {
                    let wa = s * ((xb - c) * (yc - r) - (yb - r) * (xc - c));
                    let wb = s * ((xc - c) * (ya - r) - (yc - r) * (xa - c));
                    let wc = s * ((xa - c) * (yb - r) - (ya - r) * (xb - c));
                    if wa < 0 || wb < 0 || wc < 0 {
                        continue;
                    }
                    let Some(zg) = z_grid(c, r) else {
                        continue;
                    };
                    let zl = (wa as f64 * za + wb as f64 * zb + wc as f64 * zc) / (s * area) as f64;
                    let d = &mut dev[r as usize * w + c as usize];
                    let e = (zl - zg).abs();
                    if d.is_nan() || e > *d {
                        *d = e;
                    }
                }
            }
        }
        // The domain: grid vertices some lod0 triangle uses.
        let mut in_domain = vec![false; w * h];
        for &i in &self.lod0.indices {
            in_domain[i as usize] = true;
        }
        let mut worst = 0.0f64;
        for (i, d) in dev.iter().enumerate() {
            if !in_domain[i] {
                continue;
            }
            let (c, r) = ((i % w) as i64, (i / w) as i64);
            let e = if d.is_nan() {
                match z_grid(c, r) {
                    Some(zg) => nearest_plane_z(&tris, c, r).map_or(0.0, |zl| (zl - zg).abs()),
                    None => 0.0,
                }
            } else {
                *d
            };
            worst = worst.max(e);
        }
        worst
    }
}

/// z at grid point (c, r) of the plane through the non-degenerate triangle whose centroid is
/// nearest in plan (ties: first in index order).
fn nearest_plane_z(tris: &[[(i64, i64, f64); 3]], c: i64, r: i64) -> Option<f64> {
    let mut best: Option<(i64, f64)> = None;
    for t in tris {
        let [(xa, ya, za), (xb, yb, zb), (xc, yc, zc)] = *t;
        let area = (xb - xa) * (yc - ya) - (yb - ya) * (xc - xa);
        if area == 0 {
            continue;
        }
        let (dx, dy) = (xa + xb + xc - 3 * c, ya + yb + yc - 3 * r);
        let dist = dx * dx + dy * dy;
        if best.is_some_and(|(b, _)| b <= dist) {
            continue;
        }
        let wa = (xb - c) * (yc - r) - (yb - r) * (xc - c);
        let wb = (xc - c) * (ya - r) - (yc - r) * (xa - c);
        let wc = (xa - c) * (yb - r) - (ya - r) * (xb - c);
        let z = (wa as f64 * za + wb as f64 * zb + wc as f64 * zc) / area as f64;
        best = Some((dist, z));
    }
    best.map(|(_, z)| z)
}

/// The mesh of `indices` (into `m`'s vertices) with unused vertices dropped, the kept ones in
/// their original order, UVs kept and normals recomputed as [`glb::grid_mesh`] does.
/// Removes coincident triangles: the simplifier can fold two triangles onto the same three
/// vertices (a zero-volume pillow, usually with opposite windings). Blender's importer drops
/// such duplicates and renderers z-fight on them. Of each group the first upward-facing
/// (counter-clockwise seen from +z) triangle is kept, else the first; order is otherwise kept.
fn drop_coincident(positions: &[[f32; 3]], indices: Vec<u32>) -> Vec<u32> {
    let tris: Vec<[u32; 3]> = indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let mut keyed: Vec<([u32; 3], usize)> = tris
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let mut k = *t;
            k.sort_unstable();
            (k, i)
        })
        .collect();
    keyed.sort_unstable();
    if keyed.windows(2).all(|w| w[0].0 != w[1].0) {
        return indices;
    }
    let up = |t: &[u32; 3]| {
        let p = |k: usize| positions.get(t[k] as usize).copied().unwrap_or_default();
        let (a, b, c) = (p(0), p(1), p(2));
        let cross = f64::from(b[0] - a[0]) * f64::from(c[1] - a[1])
            - f64::from(b[1] - a[1]) * f64::from(c[0] - a[0]);
        cross > 0.0
    };
    let mut keep = vec![true; tris.len()];
    for group in keyed.chunk_by(|a, b| a.0 == b.0).filter(|g| g.len() > 1) {
        let chosen = group
            .iter()
            .find(|(_, i)| tris.get(*i).is_some_and(up))
            .unwrap_or(&group[0])
            .1;
        for &(_, i) in group {
            if let Some(k) = keep.get_mut(i) {
                *k = i == chosen;
            }
        }
    }
    tris.iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .flat_map(|(t, _)| *t)
        .collect()
}

fn compact(m: &GlbMesh, indices: &[u32]) -> GlbMesh {
    let mut used = vec![false; m.positions.len()];
    for &i in indices {
        used[i as usize] = true;
    }
    let mut remap = vec![u32::MAX; m.positions.len()];
    let mut out = GlbMesh {
        local_origin_m: m.local_origin_m,
        texture_png: m.texture_png.clone(),
        ..GlbMesh::default()
    };
    for (i, _) in used.iter().enumerate().filter(|(_, u)| **u) {
        remap[i] = out.positions.len() as u32;
        out.positions.push(m.positions[i]);
        if let Some(uv) = m.uvs.get(i) {
            out.uvs.push(*uv);
        }
    }
    out.indices = indices.iter().map(|&i| remap[i as usize]).collect();
    out.normals = glb::vertex_normals(&out.positions, &out.indices);
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;

    /// A rough 200 × 180 terrain: smooth bumps, a 0.3 m step, and small deterministic noise.
    fn terrain() -> (Vec<f32>, usize, usize) {
        let (w, h) = (200usize, 180usize);
        let mut z = Vec::with_capacity(w * h);
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        for r in 0..h {
            for c in 0..w {
                let (x, y) = (c as f64 * 0.05, r as f64 * 0.05);
                let bumps = 0.4 * (x * 0.9).sin() * (y * 1.3).cos()
                    + 0.25 * (-((x - 5.0).powi(2) + (y - 4.0).powi(2)) / 0.5).exp();
                let step = if x + 0.3 * y > 6.0 { 0.3 } else { 0.0 };
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let noise = ((s >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.01;
                z.push((bumps + step + noise) as f32);
            }
        }
        (z, w, h)
    }

    #[test]
    fn coincident_triangles_keep_one_upward_face() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.5],
        ];
        // Triangle 1 is triangle 2 folded back (clockwise from above).
        let fold = vec![1, 3, 2, 0, 2, 1, 0, 1, 2];
        assert_eq!(drop_coincident(&p, fold), vec![1, 3, 2, 0, 1, 2]);
        let both_down = vec![0, 2, 1, 2, 1, 0];
        assert_eq!(drop_coincident(&p, both_down), vec![0, 2, 1]);
        let clean = vec![0, 1, 2, 1, 3, 2];
        assert_eq!(drop_coincident(&p, clean.clone()), clean);
        // Every level of a real terrain is free of them.
        let (z, w, h) = terrain();
        for (m, _) in LodBuilder::new(&z, w, h, [0.0, 0.0], 0.05).lods(4) {
            let mut keys: Vec<[u32; 3]> = m
                .indices
                .chunks_exact(3)
                .map(|t| {
                    let mut k = [t[0], t[1], t[2]];
                    k.sort_unstable();
                    k
                })
                .collect();
            let n = keys.len();
            keys.sort_unstable();
            keys.dedup();
            assert_eq!(keys.len(), n);
        }
    }

    #[test]
    fn quadric_lods_beat_the_stride_grid() {
        let (z, w, h) = terrain();
        let b = LodBuilder::new(&z, w, h, [10.0, 20.0], 0.05);
        let levels = b.lods(4);
        let (lod0, e0) = levels[0].clone();
        assert!(e0 < 1e-6);
        // Border vertices of lod0 (the grid's outer ring), by position.
        let border: Vec<[f32; 3]> = (0..h)
            .flat_map(|r| (0..w).map(move |c| (c, r)))
            .filter(|&(c, r)| c == 0 || r == 0 || c == w - 1 || r == h - 1)
            .map(|(c, r)| lod0.positions[r * w + c])
            .collect();
        for n in 1..=3u32 {
            let (m, err) = levels[n as usize].clone();
            let tris = m.indices.len() / 3;
            let target = b.target_triangles(n);
            let (grid, grid_err) = glb::grid_mesh(&z, w, h, [10.0, 20.0], 0.05, 1 << n);
            eprintln!(
                "lod{n}: quadric {tris} triangles / {} vertices, max error {err:.5} m; \
                 stride-{} grid {} triangles, max error {grid_err:.5} m (target {target})",
                m.positions.len(),
                1 << n,
                grid.indices.len() / 3
            );
            assert!(
                tris as f64 <= 1.1 * target as f64,
                "lod{n}: {tris} > 1.1 × {target}"
            );
            assert!(err <= grid_err, "lod{n}: quadric {err} > grid {grid_err}");
            assert!(err > 0.0);
            for p in &border {
                assert!(m.positions.contains(p), "lod{n} lost border vertex {p:?}");
            }
            assert_eq!(m.uvs.len(), m.positions.len());
            assert_eq!(m.normals.len(), m.positions.len());
            assert!(m.indices.iter().all(|&i| (i as usize) < m.positions.len()));
        }
    }

    #[test]
    fn lods_are_deterministic() {
        let (z, w, h) = terrain();
        let run = || {
            let b = LodBuilder::new(&z, w, h, [0.0, 0.0], 0.05);
            b.lods(3)
                .iter()
                .map(|(m, e)| (glb::encode(m).unwrap(), e.to_bits()))
                .collect::<Vec<_>>()
        };
        let first = run();
        let second = std::thread::scope(|sc| sc.spawn(run).join().unwrap());
        assert!(first == second);
    }

    #[test]
    fn measured_error_is_exact_on_a_known_case() {
        // A flat 5 × 5 grid with one spike at the centre: any lod that drops the spike's
        // vertex is off by exactly the spike there.
        let mut z = vec![0.0f32; 25];
        z[12] = 1.0;
        let b = LodBuilder::new(&z, 5, 5, [0.0, 0.0], 1.0);
        let (m, err) = b.lods(2)[1].clone();
        let kept_spike = m.positions.iter().any(|p| p[2] > 0.5);
        if kept_spike {
            assert!(err < 1e-6);
        } else {
            assert!((err - 1.0).abs() < 1e-6, "{err}");
        }
    }
}
