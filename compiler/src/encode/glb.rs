//! Binary glTF 2.0 writer for terrain meshes (SPEC.md §5.3).
//!
//! Written by hand rather than through `gltf-json` because the layout is fixed and small and
//! the JSON chunk must be canonical for reproducible bytes. Axes: ground (x, y, z-up) maps to
//! glTF (+Y up) as `(x, z, -y)`; the local origin goes into the root node translation so the
//! f32 positions stay small.

use regolith_format::canonical_json;
use serde_json::{json, Value};

use super::EncodeError;

/// A triangle mesh in ground axes, relative to `local_origin_m`.
#[derive(Debug, Clone, Default)]
pub struct GlbMesh {
    /// Ground coordinates of the local origin.
    pub local_origin_m: [f64; 3],
    /// Positions relative to the origin (ground axes, metres).
    pub positions: Vec<[f32; 3]>,
    /// Unit normals (ground axes).
    pub normals: Vec<[f32; 3]>,
    /// Texture coordinates (origin top-left, v down).
    pub uvs: Vec<[f32; 2]>,
    /// Triangle list indices (counter-clockwise seen from above).
    pub indices: Vec<u32>,
    /// Embedded PNG texture.
    pub texture_png: Option<Vec<u8>>,
}

fn to_gltf(p: [f32; 3]) -> [f32; 3] {
    [p[0], p[2], -p[1]]
}

fn pad4(buf: &mut Vec<u8>, fill: u8) {
    while !buf.len().is_multiple_of(4) {
        buf.push(fill);
    }
}

/// Encodes the mesh as GLB bytes.
pub fn encode(m: &GlbMesh) -> Result<Vec<u8>, EncodeError> {
    let n = m.positions.len();
    if m.normals.len() != n
        || (!m.uvs.is_empty() && m.uvs.len() != n)
        || !m.indices.len().is_multiple_of(3)
    {
        return Err(EncodeError::new(
            "GLB",
            "attribute counts differ or indices not a triangle list",
        ));
    }
    if m.indices.iter().any(|&i| i as usize >= n) {
        return Err(EncodeError::new("GLB", "index out of range"));
    }
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, bytes: &[u8], target: Option<u32>| -> usize {
        pad4(bin, 0);
        let mut v = json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        bin.extend_from_slice(bytes);
        views.push(v);
        views.len() - 1
    };
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    let pos: Vec<u8> = m
        .positions
        .iter()
        .flat_map(|p| {
            let g = to_gltf(*p);
            for k in 0..3 {
                lo[k] = lo[k].min(g[k]);
                hi[k] = hi[k].max(g[k]);
            }
            g.into_iter().flat_map(f32::to_le_bytes)
        })
        .collect();
    if n == 0 {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    let v = push_view(&mut bin, &pos, Some(34962));
    accessors.push(
        json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3",
        "min": lo.map(f64::from), "max": hi.map(f64::from)}),
    );
    let nor: Vec<u8> = m
        .normals
        .iter()
        .flat_map(|p| to_gltf(*p).into_iter().flat_map(f32::to_le_bytes))
        .collect();
    let v = push_view(&mut bin, &nor, Some(34962));
    accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3"}));
    let mut attributes = json!({"POSITION": 0, "NORMAL": 1});
    if !m.uvs.is_empty() {
        let uv: Vec<u8> = m
            .uvs
            .iter()
            .flat_map(|p| p.iter().flat_map(|f| f.to_le_bytes()))
            .collect();
        let v = push_view(&mut bin, &uv, Some(34962));
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC2"}));
        attributes["TEXCOORD_0"] = json!(accessors.len() - 1);
    }
    let (idx, ctype): (Vec<u8>, u32) = if n <= 65_535 {
        (
            m.indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect(),
            5123,
        )
    } else {
        (
            m.indices.iter().flat_map(|&i| i.to_le_bytes()).collect(),
            5125,
        )
    };
    let v = push_view(&mut bin, &idx, Some(34963));
    accessors.push(json!({"bufferView": v, "componentType": ctype, "count": m.indices.len(), "type": "SCALAR"}));
    let primitive =
        json!({"attributes": attributes, "indices": accessors.len() - 1, "mode": 4, "material": 0});
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": "regolith"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [m.local_origin_m[0], m.local_origin_m[2], -m.local_origin_m[1]]}],
        "materials": [{"pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 1}}],
    });
    if let (Some(png), false) = (&m.texture_png, m.uvs.is_empty()) {
        let v = push_view(&mut bin, png, None);
        doc["images"] = json!([{"bufferView": v, "mimeType": "image/png"}]);
        doc["samplers"] =
            json!([{"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}]);
        doc["textures"] = json!([{"source": 0, "sampler": 0}]);
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
    }
    pad4(&mut bin, 0);
    doc["meshes"] = json!([{"primitives": [primitive]}]);
    doc["accessors"] = Value::Array(accessors);
    doc["bufferViews"] = Value::Array(views);
    doc["buffers"] = json!([{"byteLength": bin.len()}]);
    let mut js = canonical_json::to_string(&doc).into_bytes();
    pad4(&mut js, b' ');
    let total = 12 + 8 + js.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(js.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&js);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}

/// Builds the mesh of a height grid (row 0 north, NaN = hole) sampled every `step` cells:
/// vertices at cell centres, each quad split along its NW–SE diagonal, triangles touching a
/// hole dropped, UVs spanning the grid, area-weighted normals. Returns the mesh and the largest
/// vertical difference between the full grid and this mesh at the full grid's cells.
pub fn grid_mesh(
    heights: &[f32],
    width: usize,
    height: usize,
    origin_m: [f64; 2],
    cell_m: f64,
    step: usize,
) -> (GlbMesh, f64) {
    let step = step.max(1);
    let cols: Vec<usize> = (0..width)
        .step_by(step)
        .chain((width > 0 && !(width - 1).is_multiple_of(step)).then_some(width - 1))
        .collect();
    let rows: Vec<usize> = (0..height)
        .step_by(step)
        .chain((height > 0 && !(height - 1).is_multiple_of(step)).then_some(height - 1))
        .collect();
    let z_at = |c: usize, r: usize| heights.get(r * width + c).copied().unwrap_or(f32::NAN);
    let z0 = heights
        .iter()
        .copied()
        .filter(|z| z.is_finite())
        .fold(f32::INFINITY, f32::min);
    let z0 = if z0.is_finite() { f64::from(z0) } else { 0.0 };
    let mut m = GlbMesh {
        local_origin_m: [origin_m[0], origin_m[1], z0],
        ..GlbMesh::default()
    };
    let (nc, nr) = (cols.len(), rows.len());
    for &r in &rows {
        for &c in &cols {
            let z = z_at(c, r);
            let zr = if z.is_finite() {
                (f64::from(z) - z0) as f32
            } else {
                0.0
            };
            m.positions
                .push([(c as f64 * cell_m) as f32, -(r as f64 * cell_m) as f32, zr]);
            m.uvs.push([
                (c as f32 + 0.5) / width.max(1) as f32,
                (r as f32 + 0.5) / height.max(1) as f32,
            ]);
        }
    }
    let ok = |c: usize, r: usize| z_at(c, r).is_finite();
    for j in 0..nr.saturating_sub(1) {
        for i in 0..nc.saturating_sub(1) {
            let (c0, c1, r0, r1) = (cols[i], cols[i + 1], rows[j], rows[j + 1]);
            let nw = (j * nc + i) as u32;
            let ne = nw + 1;
            let sw = ((j + 1) * nc + i) as u32;
            let se = sw + 1;
            // NW–SE diagonal: triangles (nw, sw, se) and (nw, se, ne), counter-clockwise from above.
            if ok(c0, r0) && ok(c0, r1) && ok(c1, r1) {
                m.indices.extend([nw, sw, se]);
            }
            if ok(c0, r0) && ok(c1, r1) && ok(c1, r0) {
                m.indices.extend([nw, se, ne]);
            }
        }
    }
    m.normals = vertex_normals(&m.positions, &m.indices);
    let err = max_vertical_error(heights, width, height, &cols, &rows, z0, &m);
    (m, err)
}

/// Area-weighted unit vertex normals of a triangle list (up for unused vertices).
pub(crate) fn vertex_normals(p: &[[f32; 3]], idx: &[u32]) -> Vec<[f32; 3]> {
    let mut acc = vec![[0.0f64; 3]; p.len()];
    for t in idx.chunks_exact(3) {
        let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
        let u = [
            f64::from(b[0] - a[0]),
            f64::from(b[1] - a[1]),
            f64::from(b[2] - a[2]),
        ];
        let v = [
            f64::from(c[0] - a[0]),
            f64::from(c[1] - a[1]),
            f64::from(c[2] - a[2]),
        ];
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        for &k in t {
            for d in 0..3 {
                acc[k as usize][d] += n[d];
            }
        }
    }
    acc.iter()
        .map(|n| {
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if l > 0.0 {
                [(n[0] / l) as f32, (n[1] / l) as f32, (n[2] / l) as f32]
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

/// Largest |z_grid − z_mesh| over measured full-resolution cells inside the mesh's triangles.
fn max_vertical_error(
    heights: &[f32],
    width: usize,
    height: usize,
    cols: &[usize],
    rows: &[usize],
    z0: f64,
    m: &GlbMesh,
) -> f64 {
    let nc = cols.len();
    let mut worst = 0.0f64;
    for j in 0..rows.len().saturating_sub(1) {
        for i in 0..nc.saturating_sub(1) {
            let (c0, c1, r0, r1) = (cols[i], cols[i + 1], rows[j], rows[j + 1]);
            let zc = |ii: usize, jj: usize| f64::from(m.positions[jj * nc + ii][2]) + z0;
            let (znw, zne, zsw, zse) = (zc(i, j), zc(i + 1, j), zc(i, j + 1), zc(i + 1, j + 1));
            if ![znw, zne, zsw, zse].iter().all(|z| z.is_finite()) {
                continue;
            }
            for r in r0..=r1.min(height - 1) {
                for c in c0..=c1.min(width - 1) {
                    let Some(z) = heights
                        .get(r * width + c)
                        .copied()
                        .filter(|z| z.is_finite())
                    else {
                        continue;
                    };
                    let u = (c - c0) as f64 / (c1 - c0).max(1) as f64;
                    let v = (r - r0) as f64 / (r1 - r0).max(1) as f64;
                    // Barycentric interpolation on the NW–SE split.
                    let zm = if v >= u {
                        znw + v * (zsw - znw) + u * (zse - zsw)
                    } else {
                        znw + u * (zne - znw) + v * (zse - zne)
                    };
                    worst = worst.max((f64::from(z) - zm).abs());
                }
            }
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_mesh_counts_and_glb_header() {
        let heights: Vec<f32> = (0..20).map(|i| ((i % 5) * (i % 5)) as f32 * 0.01).collect();
        let (m, err) = grid_mesh(&heights, 5, 4, [1.0, 2.0], 0.1, 1);
        assert_eq!(m.positions.len(), 20);
        assert_eq!(m.indices.len() / 3, 2 * 4 * 3);
        assert!(err < 1e-6);
        let glb = encode(&m).unwrap();
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(
            u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize,
            glb.len()
        );
        let (coarse, err2) = grid_mesh(&heights, 5, 4, [1.0, 2.0], 0.1, 2);
        assert_eq!(coarse.positions.len(), 3 * 3);
        assert!(err2 > 0.0, "decimation of a sawtooth must have an error");
        // Upward normals for a flat grid.
        let (flat, _) = grid_mesh(&[0.0; 9], 3, 3, [0.0, 0.0], 1.0, 1);
        assert!(flat.normals.iter().all(|n| (n[2] - 1.0).abs() < 1e-6));
    }
}
