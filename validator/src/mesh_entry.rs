//! Mesh entries (SPEC §5.3) as render geometry: the `lod0` GLB decoded into a [`TriMeshF32`].
//!
//! Design decisions:
//! * **Own parser, not the `gltf` crate.** The reader already parses the GLB container by hand
//!   (`regolith_reader::mesh`), the subset regolith writes is small, and every malformed input
//!   must come back as an error naming the entry, never a panic: every offset and length from
//!   the file is bounds-checked with checked arithmetic before it is used, so a forged count
//!   cannot make the decoder allocate more than the file's own size.
//! * **Frames.** glTF is +Y up with `gltf = (x_ground, z_ground, −y_ground)`; a node's
//!   transform (TRS or matrix, composed down the node tree in `f64`) is applied to its
//!   positions, and the global translation of the first node with a mesh becomes the
//!   [`TriMeshF32::origin_m`] (regolith's root node translation is the entry's local origin), so
//!   positions stay small `f32` offsets and depth is exact to the `f32` resolution of the file.
//! * **Supported glTF.** Triangle lists, strips and fans (points and lines have no surface and
//!   are skipped); `POSITION` as float `VEC3`; indices `u8`/`u16`/`u32` or none; `TEXCOORD_0`
//!   as float or normalised `u8`/`u16`; `COLOR_0` as float or normalised `u8`/`u16`, `VEC3` or
//!   `VEC4`; buffers only in the GLB's BIN chunk; images only embedded PNGs. Anything else a
//!   file needs (a required extension, a sparse accessor, an external URI, a second texture)
//!   is a decode error rather than a silently wrong render.
//! * **Albedo.** The base-colour texture is reduced to one channel like a texture entry
//!   (SPEC §5.2): value / (2^bit_depth − 1), **linear** (regolith embeds the texture entry's
//!   PNG, not an sRGB-encoded one), RGB through the Rec. 601 luma `0.299 R + 0.587 G +
//!   0.114 B`, alpha ignored; a material's `baseColorFactor` multiplies it (through its luma,
//!   exact for a grey factor). Triangles without
//!   a texture take `COLOR_0 × baseColorFactor` per vertex (SfM vertex colours), and a
//!   primitive with neither colours nor an explicit factor a uniform grey 0.5, as a heightfield
//!   without texture is rendered ([`crate::validate::entry_geometry`]). The sampler is always
//!   bilinear with `CLAMP_TO_EDGE` (SPEC §5.3), see [`crate::render::MeshTexture`].

use regolith_format::kinds::{self, roles};
use regolith_reader::mesh::glb_container;
use regolith_reader::{ReaderError, ReleaseView};
use serde_json::Value;

use crate::render::{Geometry, MeshTexture, TriMeshF32};

/// Largest texture side accepted, as for texture entries.
const MAX_TEXTURE_SIDE: u32 = 32_768;
/// Albedo of a primitive without texture, vertex colours or explicit base colour.
const DEFAULT_ALBEDO: f32 = 0.5;

/// The render geometry of a mesh entry: its `lod0` GLB (full detail), verified and decoded.
pub fn mesh_geometry(view: &ReleaseView, entry: &str) -> Result<Geometry, ReaderError> {
    view.entry_of_kind(entry, kinds::MESH)?;
    let glb = view.read_file(entry, &roles::lod(0))?;
    Ok(Geometry::Mesh(decode_glb(&glb, entry)?))
}

/// Decodes GLB bytes into a ground-frame mesh (see the module docs); errors name `entry`.
pub fn decode_glb(bytes: &[u8], entry: &str) -> Result<TriMeshF32, ReaderError> {
    decode(bytes).map_err(|message| ReaderError::Decode {
        entry: entry.to_string(),
        what: "GLB",
        message,
    })
}

type R<T> = Result<T, String>;

fn array<'a>(v: &'a Value, key: &str) -> &'a [Value] {
    v.get(key)
        .and_then(Value::as_array)
        .map_or(&[], Vec::as_slice)
}

/// `v[key]` as an index or count, `None` when absent.
fn opt_usize(v: &Value, key: &str, what: &str) -> R<Option<usize>> {
    match v.get(key) {
        None => Ok(None),
        Some(x) => x
            .as_u64()
            .and_then(|n| usize::try_from(n).ok())
            .map(Some)
            .ok_or(format!("{what}: `{key}` is not a non-negative integer")),
    }
}

fn req_usize(v: &Value, key: &str, what: &str) -> R<usize> {
    opt_usize(v, key, what)?.ok_or(format!("{what}: `{key}` missing"))
}

fn numbers<const N: usize>(v: &Value, key: &str, what: &str) -> R<Option<[f64; N]>> {
    let Some(x) = v.get(key) else {
        return Ok(None);
    };
    let a = x
        .as_array()
        .filter(|a| a.len() == N)
        .ok_or(format!("{what}: `{key}` must be {N} numbers"))?;
    let mut out = [0.0; N];
    for (o, n) in out.iter_mut().zip(a) {
        *o = n
            .as_f64()
            .filter(|f| f.is_finite())
            .ok_or(format!("{what}: `{key}` must be {N} finite numbers"))?;
    }
    Ok(Some(out))
}

/// A parsed document with its binary buffer.
struct Doc<'a> {
    json: Value,
    bin: &'a [u8],
}

impl Doc<'_> {
    fn item(&self, list: &str, i: usize) -> R<&Value> {
        array(&self.json, list)
            .get(i)
            .ok_or(format!("{list}[{i}] does not exist"))
    }

    /// The bytes of a buffer view and its stride (0 = tightly packed).
    fn view(&self, i: usize) -> R<(&[u8], usize)> {
        let what = format!("bufferViews[{i}]");
        let v = self.item("bufferViews", i)?;
        let buffer = req_usize(v, "buffer", &what)?;
        let b = self.item("buffers", buffer)?;
        if b.get("uri").is_some() {
            return Err(format!(
                "buffers[{buffer}] has a URI: only the GLB's BIN chunk is supported"
            ));
        }
        if buffer != 0 {
            return Err(format!(
                "{what} uses buffers[{buffer}]: only buffer 0 (the BIN chunk) is embedded"
            ));
        }
        let off = opt_usize(v, "byteOffset", &what)?.unwrap_or(0);
        let len = req_usize(v, "byteLength", &what)?;
        let bytes = off
            .checked_add(len)
            .and_then(|e| self.bin.get(off..e))
            .ok_or(format!(
                "{what} (bytes {off}+{len}) runs past the BIN chunk ({} bytes)",
                self.bin.len()
            ))?;
        Ok((bytes, opt_usize(v, "byteStride", &what)?.unwrap_or(0)))
    }

    /// Accessor `i` as `count` rows of `width` numbers (normalised integers mapped to 0–1 or
    /// −1–1), checked against the allowed element types and component types.
    fn accessor(&self, i: usize, types: &[&str], components: &[u64]) -> R<(usize, Vec<f64>)> {
        let what = format!("accessors[{i}]");
        let a = self.item("accessors", i)?;
        if a.get("sparse").is_some() {
            return Err(format!("{what}: sparse accessors are not supported"));
        }
        let ty = a.get("type").and_then(Value::as_str).unwrap_or("");
        if !types.contains(&ty) {
            return Err(format!("{what}: type {ty:?}, expected one of {types:?}"));
        }
        let width = match ty {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            _ => 4,
        };
        let ct = a.get("componentType").and_then(Value::as_u64).unwrap_or(0);
        if !components.contains(&ct) {
            return Err(format!(
                "{what}: componentType {ct}, expected one of {components:?}"
            ));
        }
        let size = match ct {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            _ => 4,
        };
        let normalized = a.get("normalized").and_then(Value::as_bool) == Some(true);
        let count = req_usize(a, "count", &what)?;
        let elem = size * width;
        let view = opt_usize(a, "bufferView", &what)?.ok_or(format!(
            "{what}: no bufferView (zero-filled accessors are not supported)"
        ))?;
        let (bytes, stride) = self.view(view)?;
        let stride = if stride == 0 { elem } else { stride };
        if stride < elem {
            return Err(format!(
                "bufferViews[{view}]: byteStride {stride} < element size {elem}"
            ));
        }
        let off = opt_usize(a, "byteOffset", &what)?.unwrap_or(0);
        if count == 0 {
            return Ok((width, Vec::new()));
        }
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(off))
            .and_then(|x| x.checked_add(elem));
        if end.is_none_or(|e| e > bytes.len()) {
            return Err(format!(
                "{what}: {count} elements of {elem} bytes (stride {stride}, offset {off}) run past bufferViews[{view}] ({} bytes)",
                bytes.len()
            ));
        }
        let mut out = Vec::with_capacity(count * width);
        for k in 0..count {
            let base = off + k * stride;
            for c in 0..width {
                let p = base + c * size;
                let b = bytes
                    .get(p..p + size)
                    .ok_or("accessor read out of bounds")?;
                let x = match ct {
                    5120 => {
                        let v = f64::from(b[0] as i8);
                        if normalized {
                            (v / 127.0).max(-1.0)
                        } else {
                            v
                        }
                    }
                    5121 => f64::from(b[0]) / if normalized { 255.0 } else { 1.0 },
                    5122 => {
                        let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
                        if normalized {
                            (v / 32767.0).max(-1.0)
                        } else {
                            v
                        }
                    }
                    5123 => {
                        f64::from(u16::from_le_bytes([b[0], b[1]]))
                            / if normalized { 65535.0 } else { 1.0 }
                    }
                    5125 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    _ => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                };
                out.push(x);
            }
        }
        Ok((width, out))
    }
}

/// An affine transform `x ↦ m · x + t` (glTF axes).
#[derive(Clone, Copy)]
struct Affine {
    m: [[f64; 3]; 3],
    t: [f64; 3],
}

impl Affine {
    const IDENTITY: Affine = Affine {
        m: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        t: [0.0; 3],
    };

    fn apply_linear(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|r| (0..3).map(|c| self.m[r][c] * p[c]).sum())
    }

    /// `self ∘ other`.
    fn then(&self, other: &Affine) -> Affine {
        let m = std::array::from_fn(|r| {
            std::array::from_fn(|c| (0..3).map(|k| self.m[r][k] * other.m[k][c]).sum())
        });
        let lt = self.apply_linear(other.t);
        Affine {
            m,
            t: std::array::from_fn(|k| lt[k] + self.t[k]),
        }
    }

    /// A node's local transform: `matrix` (column-major) or translation · rotation · scale.
    fn of_node(n: &Value, what: &str) -> R<Affine> {
        if let Some(m) = numbers::<16>(n, "matrix", what)? {
            return Ok(Affine {
                m: std::array::from_fn(|r| std::array::from_fn(|c| m[c * 4 + r])),
                t: [m[12], m[13], m[14]],
            });
        }
        let t = numbers::<3>(n, "translation", what)?.unwrap_or([0.0; 3]);
        let [x, y, z, w] = numbers::<4>(n, "rotation", what)?.unwrap_or([0.0, 0.0, 0.0, 1.0]);
        let s = numbers::<3>(n, "scale", what)?.unwrap_or([1.0; 3]);
        let q = (x * x + y * y + z * z + w * w).sqrt();
        if q == 0.0 {
            return Err(format!("{what}: zero rotation quaternion"));
        }
        let rot = regolith_format::frames::Pose {
            translation_m: [0.0; 3],
            rotation_xyzw: [x / q, y / q, z / q, w / q],
        }
        .rotation_matrix();
        Ok(Affine {
            m: std::array::from_fn(|r| std::array::from_fn(|c| rot[r][c] * s[c])),
            t,
        })
    }
}

/// glTF (+Y up) to ground (z up): `ground = (x, −z, y)`.
fn to_ground(p: [f64; 3]) -> [f64; 3] {
    [p[0], -p[2], p[1]]
}

/// Rec. 601 luma of a linear RGB triple (SPEC §5.2 for RGB colours).
fn luma(rgb: &[f64]) -> f64 {
    match rgb {
        [r, g, b, ..] => 0.299 * r + 0.587 * g + 0.114 * b,
        [v, ..] => *v,
        [] => 0.0,
    }
}

/// What a primitive's material says about its albedo.
struct Material {
    /// Luma of `baseColorFactor`, if given.
    factor: Option<f64>,
    /// Image index of the base-colour texture.
    image: Option<usize>,
}

fn material(doc: &Doc<'_>, prim: &Value, what: &str) -> R<Material> {
    let Some(mi) = opt_usize(prim, "material", what)? else {
        return Ok(Material {
            factor: None,
            image: None,
        });
    };
    let m = doc.item("materials", mi)?;
    let pbr = m.get("pbrMetallicRoughness").unwrap_or(&Value::Null);
    let mw = format!("materials[{mi}]");
    let factor = numbers::<4>(pbr, "baseColorFactor", &mw)?.map(|f| luma(&f));
    let image = match pbr.get("baseColorTexture") {
        None => None,
        Some(t) => {
            if opt_usize(t, "texCoord", &mw)?.unwrap_or(0) != 0 {
                return Err(format!(
                    "{mw}: base colour from a texCoord set other than TEXCOORD_0 is not supported"
                ));
            }
            let ti = req_usize(t, "index", &mw)?;
            let tex = doc.item("textures", ti)?;
            Some(
                opt_usize(tex, "source", &format!("textures[{ti}]"))?
                    .ok_or(format!("textures[{ti}] has no PNG `source`"))?,
            )
        }
    };
    Ok(Material { factor, image })
}

/// Decodes an embedded PNG to one albedo channel: (width, height, values).
fn image(doc: &Doc<'_>, i: usize) -> R<(usize, usize, Vec<f32>)> {
    let what = format!("images[{i}]");
    let img = doc.item("images", i)?;
    if img.get("uri").is_some() {
        return Err(format!(
            "{what} has a URI: only images embedded in the BIN chunk are supported"
        ));
    }
    let mime = img.get("mimeType").and_then(Value::as_str).unwrap_or("");
    if mime != "image/png" {
        return Err(format!(
            "{what}: mimeType {mime:?}, only image/png is supported"
        ));
    }
    let (bytes, _) = doc.view(req_usize(img, "bufferView", &what)?)?;
    png_albedo(bytes).map_err(|e| format!("{what}: {e}"))
}

/// An 8- or 16-bit PNG (grey, grey+alpha, RGB, RGBA or palette) as linear albedo 0–1: grey as
/// is, colour through the Rec. 601 luma, alpha ignored. For a grey PNG these are the values of
/// [`crate::validate`]'s texture decoding.
pub fn png_albedo(bytes: &[u8]) -> R<(usize, usize, Vec<f32>)> {
    let max = MAX_TEXTURE_SIDE as usize;
    let mut decoder = png::Decoder::new_with_limits(
        std::io::Cursor::new(bytes),
        png::Limits {
            bytes: max.saturating_mul(max).saturating_mul(2),
        },
    );
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let (w, h) = (reader.info().width, reader.info().height);
    if w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
        return Err(format!("image side {w}x{h} exceeds {MAX_TEXTURE_SIDE}"));
    }
    let (ct, depth) = reader.output_color_type();
    let channels = match ct {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err("palette PNG not expanded".into()),
    };
    let (bps, scale) = match depth {
        png::BitDepth::Eight => (1, 255.0),
        png::BitDepth::Sixteen => (2, 65535.0),
        d => return Err(format!("expected 8- or 16-bit samples, found {d:?}")),
    };
    let mut buf = vec![0u8; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    let (w, h) = (info.width as usize, info.height as usize);
    let mut out = Vec::with_capacity(w * h);
    let mut px = [0.0f64; 4];
    for row in buf.chunks(info.line_size.max(1)).take(h) {
        for p in row.chunks_exact(channels * bps).take(w) {
            for (c, s) in p.chunks_exact(bps).enumerate() {
                let v = match s {
                    [a, b] => f64::from(u16::from_be_bytes([*a, *b])),
                    [a] => f64::from(*a),
                    _ => 0.0,
                };
                if let Some(slot) = px.get_mut(c) {
                    *slot = v / scale;
                }
            }
            out.push(if channels >= 3 { luma(&px[..3]) } else { px[0] } as f32);
        }
    }
    if out.len() != w * h || out.is_empty() {
        return Err("image data shorter than its header says, or empty".into());
    }
    Ok((w, h, out))
}

/// Triangle list of a primitive's vertex indices.
fn triangles(idx: &[u32], mode: u64) -> Vec<[u32; 3]> {
    match mode {
        4 => idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        5 => idx
            .windows(3)
            .enumerate()
            .map(|(k, t)| {
                if k % 2 == 0 {
                    [t[0], t[1], t[2]]
                } else {
                    [t[1], t[0], t[2]]
                }
            })
            .collect(),
        6 => match idx.split_first() {
            Some((&c, rest)) => rest.windows(2).map(|t| [c, t[0], t[1]]).collect(),
            None => Vec::new(),
        },
        _ => Vec::new(),
    }
}

/// The node tree of the default scene, as (node index, global transform) of every node with a
/// mesh, in depth-first scene order.
fn mesh_nodes(json: &Value) -> R<Vec<(usize, Affine)>> {
    let nodes = array(json, "nodes");
    let roots: Vec<usize> = match opt_usize(json, "scene", "glTF")? {
        Some(s) => scene_roots(json, s)?,
        None if !array(json, "scenes").is_empty() => scene_roots(json, 0)?,
        None => {
            let mut child = vec![false; nodes.len()];
            for (i, n) in nodes.iter().enumerate() {
                for c in array(n, "children") {
                    let c = c
                        .as_u64()
                        .and_then(|c| usize::try_from(c).ok())
                        .ok_or(format!("nodes[{i}]: bad child index"))?;
                    if let Some(f) = child.get_mut(c) {
                        *f = true;
                    }
                }
            }
            (0..nodes.len()).filter(|&i| !child[i]).collect()
        }
    };
    let mut out = Vec::new();
    let mut seen = vec![false; nodes.len()];
    let mut stack: Vec<(usize, Affine)> = roots
        .into_iter()
        .rev()
        .map(|r| (r, Affine::IDENTITY))
        .collect();
    while let Some((i, parent)) = stack.pop() {
        let what = format!("nodes[{i}]");
        let n = nodes.get(i).ok_or(format!("{what} does not exist"))?;
        // glTF node hierarchies are disjoint trees: a node reached twice is a cycle or a shared
        // child, either of which could make the walk endless or exponential.
        match seen.get_mut(i) {
            Some(s) if !*s => *s = true,
            _ => {
                return Err(format!(
                    "{what} is reached twice: the node hierarchy is not a tree"
                ))
            }
        }
        let global = parent.then(&Affine::of_node(n, &what)?);
        if n.get("mesh").is_some() {
            out.push((i, global));
        }
        for c in array(n, "children").iter().rev() {
            let c = c
                .as_u64()
                .and_then(|c| usize::try_from(c).ok())
                .ok_or(format!("{what}: bad child index"))?;
            stack.push((c, global));
        }
    }
    Ok(out)
}

fn scene_roots(json: &Value, s: usize) -> R<Vec<usize>> {
    let scene = array(json, "scenes")
        .get(s)
        .ok_or(format!("scenes[{s}] does not exist"))?;
    array(scene, "nodes")
        .iter()
        .map(|n| {
            n.as_u64()
                .and_then(|n| usize::try_from(n).ok())
                .ok_or(format!("scenes[{s}]: bad node index"))
        })
        .collect()
}

fn decode(bytes: &[u8]) -> R<TriMeshF32> {
    let (json, bin) = glb_container(bytes)?;
    let required: Vec<&str> = array(&json, "extensionsRequired")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    if !required.is_empty() {
        return Err(format!("required extensions not supported: {required:?}"));
    }
    let version = json
        .get("asset")
        .and_then(|a| a.get("version"))
        .and_then(Value::as_str);
    if !version.is_some_and(|v| v.starts_with("2.")) {
        return Err(format!("asset.version {version:?}, expected 2.x"));
    }
    let doc = Doc { json, bin };
    let mut mesh = TriMeshF32 {
        origin_m: [0.0; 3],
        positions: Vec::new(),
        triangles: Vec::new(),
        albedo: Vec::new(),
        texture: None,
    };
    let mut uvs: Vec<[f32; 2]> = Vec::new();
    // The one texture (image index, colour factor) of all textured primitives.
    let mut texture: Option<(usize, f64)> = None;
    let mut origin: Option<[f64; 3]> = None;
    for (ni, global) in mesh_nodes(&doc.json)? {
        let node_what = format!("nodes[{ni}]");
        let node = doc.item("nodes", ni)?;
        let mi = req_usize(node, "mesh", &node_what)?;
        let o = *origin.get_or_insert(global.t);
        for (pi, prim) in array(doc.item("meshes", mi)?, "primitives")
            .iter()
            .enumerate()
        {
            let what = format!("meshes[{mi}].primitives[{pi}]");
            let mode = prim.get("mode").map_or(Some(4), Value::as_u64);
            let mode = match mode {
                Some(m @ 4..=6) => m,
                Some(0..=3) => continue, // points and lines: no surface
                m => return Err(format!("{what}: unknown mode {m:?}")),
            };
            let attrs = prim.get("attributes").unwrap_or(&Value::Null);
            let pos = opt_usize(attrs, "POSITION", &what)?.ok_or(format!("{what}: no POSITION"))?;
            let (_, p) = doc.accessor(pos, &["VEC3"], &[5126])?;
            let n = p.len() / 3;
            let base = mesh.positions.len();
            if base + n > u32::MAX as usize {
                return Err("more than 2^32 vertices".into());
            }
            let offset = [global.t[0] - o[0], global.t[1] - o[1], global.t[2] - o[2]];
            for v in p.chunks_exact(3) {
                let q = global.apply_linear([v[0], v[1], v[2]]);
                let g = to_ground(std::array::from_fn(|k| q[k] + offset[k]));
                mesh.positions.push(g.map(|c| c as f32));
            }
            let idx: Vec<u32> = match opt_usize(prim, "indices", &what)? {
                Some(a) => {
                    let (_, ix) = doc.accessor(a, &["SCALAR"], &[5121, 5123, 5125])?;
                    let mut out = Vec::with_capacity(ix.len());
                    for &i in &ix {
                        if i >= n as f64 {
                            return Err(format!("{what}: index {i} out of range ({n} vertices)"));
                        }
                        out.push(i as u32);
                    }
                    out
                }
                None => (0..n as u32).collect(),
            };
            mesh.triangles.extend(
                triangles(&idx, mode)
                    .into_iter()
                    .map(|t| t.map(|i| i + base as u32)),
            );
            let mat = material(&doc, prim, &what)?;
            let tc = opt_usize(attrs, "TEXCOORD_0", &what)?;
            match (mat.image, tc) {
                (Some(img), Some(tc)) => {
                    let factor = mat.factor.unwrap_or(1.0);
                    match texture {
                        None => texture = Some((img, factor)),
                        Some(t) if t == (img, factor) => {}
                        Some(_) => {
                            return Err(format!(
                                "{what}: a second base-colour texture or factor; one texture per mesh is supported"
                            ))
                        }
                    }
                    let (_, t) = doc.accessor(tc, &["VEC2"], &[5126, 5121, 5123])?;
                    if t.len() / 2 != n {
                        return Err(format!(
                            "{what}: {} TEXCOORD_0 for {n} positions",
                            t.len() / 2
                        ));
                    }
                    uvs.resize(base, [f32::NAN; 2]);
                    uvs.extend(t.chunks_exact(2).map(|c| [c[0] as f32, c[1] as f32]));
                    mesh.albedo.resize(base + n, 0.0);
                }
                _ => {
                    let colours = match opt_usize(attrs, "COLOR_0", &what)? {
                        Some(c) => {
                            let (w, c) = doc.accessor(c, &["VEC3", "VEC4"], &[5126, 5121, 5123])?;
                            if c.len() / w != n {
                                return Err(format!(
                                    "{what}: {} COLOR_0 for {n} positions",
                                    c.len() / w
                                ));
                            }
                            Some(c.chunks_exact(w).map(luma).collect::<Vec<f64>>())
                        }
                        None => None,
                    };
                    let factor = mat.factor;
                    mesh.albedo.extend((0..n).map(|k| {
                        match (colours.as_ref().and_then(|c| c.get(k)), factor) {
                            (Some(c), f) => (c * f.unwrap_or(1.0)) as f32,
                            (None, Some(f)) => f as f32,
                            (None, None) => DEFAULT_ALBEDO,
                        }
                    }));
                }
            }
        }
    }
    if let Some((img, factor)) = texture {
        let (width, height, mut value) = image(&doc, img)?;
        if factor != 1.0 {
            value
                .iter_mut()
                .for_each(|v| *v = (f64::from(*v) * factor) as f32);
        }
        uvs.resize(mesh.positions.len(), [f32::NAN; 2]);
        mesh.texture = Some(MeshTexture {
            uvs,
            width,
            height,
            value,
        });
    }
    if mesh.triangles.is_empty() {
        return Err("no triangles".into());
    }
    mesh.origin_m = to_ground(origin.unwrap_or([0.0; 3]));
    Ok(mesh)
}
