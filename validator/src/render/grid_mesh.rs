//! A mesh that is a regular height grid, traced as one.
//!
//! Why: a heightfield entry's mesh (SPEC §5.3, `lod0`) is the grid itself — a vertex at every
//! cell centre, each quad split along its NW–SE diagonal, the texture's texel centres at the
//! vertices — and the renderer's heightfield tracer intersects exactly those triangles
//! ([`super::heightfield`]). Through the mesh tracer's bounding-volume hierarchy the same
//! surface cost a third more per view on a 5 mm grid and 4.9 s and a gigabyte to build before
//! the first view (6 M triangles). So a mesh is handed to the heightfield tracer when, and only
//! when, its decoded triangles *are* a grid's:
//!
//! * vertex `i` lies at column `i mod W`, row `i div W` of a lattice of `W × H` vertices
//!   (`W × H` the texture's size), within the rounding of the file's own `f32` coordinates;
//! * its texture coordinate is that texel's centre, within `f32` rounding;
//! * every triangle is one of a quad's two NW–SE halves, none twice, and every half whose
//!   three vertices some triangle uses is present — so the unused vertices are the grid's
//!   holes (`NaN`) and the tracer's rule (a triangle exists when its three heights are finite)
//!   gives back exactly the mesh's triangles. Winding is not compared: both tracers shade a
//!   terrain seen from above with its upward normal.
//!
//! Anything else (an SfM mesh, a simplified level, another split, a finer texture, a texture
//! missing on some triangles) stays a mesh. Heights are the mesh's own (`origin + f32 offset`,
//! rounded to the tracer's `f32`), the albedo its texture's texels, so the image is the mesh's;
//! what moves is only rounding below a micrometre and the texture filter's footprint, which
//! the heightfield tracer measures on the horizontal cell rather than the sloped triangle.

use super::{AlbedoGrid, HeightGrid, TriMeshF32};

/// Lattice positions may differ from the mesh's by this many units in the last place of the
/// largest coordinate: the file stores `f32` offsets, each rounded once (half a unit), and the
/// lattice step is estimated from two of them.
const POSITION_ULPS: f64 = 2.0;

/// The same for texture coordinates (values in 0..1, rounded once to `f32`).
const UV_ULPS: f64 = 4.0;

/// The height grid and albedo raster `m` is, when it is one (see the module docs).
pub fn as_height_grid(m: &TriMeshF32) -> Option<(HeightGrid, AlbedoGrid)> {
    let tex = m.texture.as_ref()?;
    let (w, h) = (tex.width, tex.height);
    let n = m.positions.len();
    if w < 2 || h < 2 || w.checked_mul(h)? != n || tex.uvs.len() != n || tex.value.len() != n {
        return None;
    }
    let xy = |i: usize| {
        m.positions
            .get(i)
            .map(|p| [f64::from(p[0]), f64::from(p[1])])
    };
    let first = xy(0)?;
    let cell = (xy(w - 1)?[0] - first[0]) / (w - 1) as f64;
    if !(cell > 0.0 && cell.is_finite()) {
        return None;
    }
    let largest = m
        .positions
        .iter()
        .flat_map(|p| [p[0].abs(), p[1].abs()])
        .fold(0.0f32, f32::max);
    let tol = POSITION_ULPS * f64::from(f32::EPSILON) * f64::from(largest).max(cell);
    let uv_tol = UV_ULPS * f64::from(f32::EPSILON);
    for (i, (p, uv)) in m.positions.iter().zip(&tex.uvs).enumerate() {
        let (c, r) = ((i % w) as f64, (i / w) as f64);
        let on_lattice = (f64::from(p[0]) - (first[0] + c * cell)).abs() <= tol
            && (f64::from(p[1]) - (first[1] - r * cell)).abs() <= tol
            && p[2].is_finite();
        let at_texel = (f64::from(uv[0]) - (c + 0.5) / w as f64).abs() <= uv_tol
            && (f64::from(uv[1]) - (r + 0.5) / h as f64).abs() <= uv_tol;
        if !on_lattice || !at_texel {
            return None;
        }
    }
    // Quad (c, r)'s halves: 0 = NW–SW–SE, 1 = NW–SE–NE.
    let quads = (w - 1) * (h - 1);
    let mut present = vec![false; 2 * quads];
    let mut used = vec![false; n];
    for t in &m.triangles {
        let mut cr = [(0usize, 0usize); 3];
        for (k, &v) in t.iter().enumerate() {
            let v = v as usize;
            if v >= n {
                return None;
            }
            cr[k] = (v % w, v / w);
        }
        let (c0, r0) = (cr.iter().map(|p| p.0).min()?, cr.iter().map(|p| p.1).min()?);
        if c0 + 1 >= w || r0 + 1 >= h {
            return None;
        }
        let mut corners = cr;
        corners.sort_unstable();
        let half = if corners == [(c0, r0), (c0, r0 + 1), (c0 + 1, r0 + 1)] {
            0
        } else if corners == [(c0, r0), (c0 + 1, r0), (c0 + 1, r0 + 1)] {
            1
        } else {
            return None;
        };
        let slot = present.get_mut(2 * (r0 * (w - 1) + c0) + half)?;
        if *slot {
            return None;
        }
        *slot = true;
        for &v in t {
            *used.get_mut(v as usize)? = true;
        }
    }
    let is_used = |c: usize, r: usize| used.get(r * w + c).copied().unwrap_or(false);
    for r in 0..h - 1 {
        for c in 0..w - 1 {
            let (nw, ne, sw, se) = (
                is_used(c, r),
                is_used(c + 1, r),
                is_used(c, r + 1),
                is_used(c + 1, r + 1),
            );
            let q = 2 * (r * (w - 1) + c);
            if present.get(q).copied() != Some(nw && sw && se)
                || present.get(q + 1).copied() != Some(nw && se && ne)
            {
                return None;
            }
        }
    }
    let origin_m = [m.origin_m[0] + first[0], m.origin_m[1] + first[1]];
    let z = m
        .positions
        .iter()
        .zip(&used)
        .map(|(p, &u)| {
            if u {
                (m.origin_m[2] + f64::from(p[2])) as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let value = tex
        .value
        .iter()
        .map(|v| if v.is_finite() { *v } else { 0.0 })
        .collect();
    Some((
        HeightGrid {
            origin_m,
            cell_m: cell,
            width: w,
            height: h,
            z,
        },
        AlbedoGrid {
            origin_m,
            cell_m: cell,
            width: w,
            height: h,
            value,
        },
    ))
}
