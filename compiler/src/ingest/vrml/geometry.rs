//! Flattening the scene into one mesh: transforms composed down the tree, faces fanned into
//! triangles, per-corner texture/colour indices turned into vertices, `TextureTransform`
//! applied, shapes merged into one [`TriMesh`] (see the module docs of `vrml`).

use std::collections::HashMap;

use nalgebra::{Point3, Rotation3, Unit, Vector3};
use regolith_format::limits::Limits;

use super::lexer::PResult;
use super::parser::{Node, Value};
use super::{locate, Mat4, MAX_DEPTH, MAX_VISITS};
use crate::error::{IngestError, Result};
use crate::ingest::types::TriMesh;

pub(super) struct Walker<'a, 'b> {
    pub(super) out: Piece,
    pub(super) limits: &'a Limits,
    pub(super) visits: u64,
    pub(super) src: &'a [u8],
    pub(super) inline: &'b mut dyn FnMut(&str) -> Result<Option<TriMesh>>,
}

impl Walker<'_, '_> {
    pub(super) fn walk(&mut self, node: &Node, m: &Mat4, depth: usize) -> Result<()> {
        self.visits += 1;
        if self.visits > MAX_VISITS || depth > MAX_DEPTH {
            return Err(IngestError::invalid(format!(
                "scene expands to more than {MAX_VISITS} nodes or {MAX_DEPTH} levels (DEF/USE fan-out)"
            )));
        }
        let kids = |name: &str| {
            node.field(name)
                .map(|v| v.nodes.clone())
                .unwrap_or_default()
        };
        let (children, m) = match node.kind.as_str() {
            "Transform" => (kids("children"), m * local_transform(node)),
            "Group" | "Collision" | "Anchor" | "Billboard" => (kids("children"), *m),
            "Switch" => {
                let which = node.vec("whichChoice", [-1.0])[0];
                let all = kids("choice");
                (
                    all.into_iter()
                        .skip(which.max(0.0) as usize)
                        .take(usize::from(which >= 0.0))
                        .collect(),
                    *m,
                )
            }
            "LOD" => (kids("level").into_iter().take(1).collect(), *m),
            "Shape" => {
                let piece = self
                    .shape(node)
                    .map_err(|(off, e)| locate(self.src, off, e))?;
                return self.out.append(piece, m, self.limits);
            }
            "Inline" => {
                let url = node.field("url").and_then(|v| v.strs.first().cloned());
                if let Some(mesh) = url.map(|u| (self.inline)(&u)).transpose()?.flatten() {
                    return self.out.append(Piece::from_mesh(mesh), m, self.limits);
                }
                return Ok(());
            }
            _ => return Ok(()),
        };
        for child in &children {
            self.walk(child, &m, depth + 1)?;
        }
        Ok(())
    }

    /// One `Shape` as a mesh piece in the shape's local frame.
    fn shape(&self, shape: &Node) -> PResult<Piece> {
        let mut piece = Piece::default();
        let appearance = shape.node("appearance");
        let material = appearance.and_then(|a| a.node("material"));
        piece.diffuse = to_rgb(&material.map_or([0.8; 3], |m| m.vec("diffuseColor", [0.8; 3])));
        let texture = appearance.and_then(|a| a.node("texture"));
        piece.texture = texture
            .and_then(|t| t.field("url"))
            .and_then(|u| u.strs.first().cloned());
        let Some(ifs) = shape
            .node("geometry")
            .filter(|g| g.kind == "IndexedFaceSet")
        else {
            return Ok(piece);
        };
        let points = ifs.node("coord").and_then(|c| c.nums("point"));
        let (Some(points), Some(coord_index)) = (points, ifs.nums("coordIndex")) else {
            return Ok(piece);
        };
        let positions = tuples::<3>(points, "Coordinate point")?;
        let faces = split_faces(coord_index, positions.len(), "coordIndex")?;
        let tex = ifs.node("texCoord").and_then(|t| t.nums("point"));
        let uvs = tex
            .map(|t| tuples::<2>(t, "TextureCoordinate point"))
            .transpose()?;
        let colors = ifs.node("color").and_then(|c| c.nums("color"));
        let colors = colors.map(|c| tuples::<3>(c, "Color color")).transpose()?;
        let per_vertex = ifs.flag("colorPerVertex", true);
        // Per-corner attribute indices, in the same face structure as coordIndex.
        // A missing texCoordIndex/colorIndex reuses coordIndex (checked against its own list).
        let corner_index = |field: &str, n: usize| -> PResult<Vec<Vec<u32>>> {
            match ifs.nums(field) {
                Some(v) => faces_like(v, &faces, n, field),
                None => split_faces(coord_index, n, &format!("coordIndex (as {field})")),
            }
        };
        let tex_faces = uvs
            .as_ref()
            .map(|u| corner_index("texCoordIndex", u.len()))
            .transpose()?;
        let color_faces = match (&colors, per_vertex) {
            (Some(c), true) => Some(corner_index("colorIndex", c.len())?),
            _ => None,
        };
        let face_colors = match (&colors, per_vertex) {
            (Some(c), false) => Some(per_face_colors(ifs, c.len(), faces.len())?),
            _ => None,
        };
        let xf = appearance.and_then(|a| a.node("textureTransform"));
        let uv_of = |i: u32| {
            let t = uvs
                .as_ref()
                .and_then(|u| u.get(i as usize))
                .copied()
                .unwrap_or_default();
            texture_uv(xf.map(|x| &**x), t)
        };
        let color_of = |i: u32| colors.as_ref().and_then(|c| c.get(i as usize)).map(to_rgb);
        let simple = tex_faces.as_ref().is_none_or(|t| *t == faces)
            && color_faces.as_ref().is_none_or(|c| *c == faces)
            && face_colors.is_none();
        piece.has_uv = uvs.is_some();
        piece.has_color = colors.is_some();
        if simple {
            for (i, p) in positions.iter().enumerate() {
                piece.push_vertex(*p, uv_of(i as u32), color_of(i as u32));
            }
        }
        let mut seen: HashMap<(u32, u32, u32), u32> = HashMap::new();
        for (f, face) in faces.iter().enumerate() {
            let mut corners = Vec::new();
            for (k, &p) in face.iter().enumerate() {
                if simple {
                    corners.push(p);
                    continue;
                }
                let at =
                    |x: &Option<Vec<Vec<u32>>>| x.as_ref().and_then(|x| x.get(f)?.get(k)).copied();
                let t = at(&tex_faces).unwrap_or(p);
                let c = match &face_colors {
                    Some(fc) => fc.get(f).copied().unwrap_or(0),
                    None => at(&color_faces).unwrap_or(p),
                };
                let pos = positions.get(p as usize).copied().unwrap_or_default();
                let next = piece.positions.len() as u32;
                let id = *seen.entry((p, t, c)).or_insert(next);
                if id == next {
                    piece.push_vertex(pos, uv_of(t), color_of(c));
                }
                corners.push(id);
            }
            for i in 1..corners.len().saturating_sub(1) {
                if let (Some(&a), Some(&b), Some(&c)) =
                    (corners.first(), corners.get(i), corners.get(i + 1))
                {
                    piece.triangles.push([a, b, c]);
                }
            }
        }
        piece.flip = !ifs.flag("ccw", true);
        Ok(piece)
    }
}

/// Groups a flat list into `N`-tuples, rejecting a ragged tail and non-finite values.
fn tuples<const N: usize>(v: &Value, what: &str) -> PResult<Vec<[f64; N]>> {
    if !v.nums.len().is_multiple_of(N) {
        let msg = format!("{what}: {} numbers is not a multiple of {N}", v.nums.len());
        return Err((v.offset, IngestError::invalid(msg)));
    }
    let mut out = Vec::new();
    for (i, c) in v.nums.chunks_exact(N).enumerate() {
        if !c.iter().all(|x| x.is_finite()) {
            return Err((
                v.offset,
                IngestError::invalid(format!("{what} {i} is not finite: {c:?}")),
            ));
        }
        let mut a = [0.0; N];
        a.copy_from_slice(c);
        out.push(a);
    }
    Ok(out)
}

/// Splits an index list at `-1` into faces, checking every index against `n`.
fn split_faces(v: &Value, n: usize, what: &str) -> PResult<Vec<Vec<u32>>> {
    let mut out = vec![Vec::new()];
    for (i, &x) in v.nums.iter().enumerate() {
        if x == -1.0 {
            out.push(Vec::new());
        } else if x.fract() != 0.0 || x < 0.0 || x >= n as f64 {
            let msg = format!("{what}[{i}] = {x} is out of range: expected -1 or 0..{n}");
            return Err((v.offset, IngestError::invalid(msg)));
        } else if let Some(f) = out.last_mut() {
            f.push(x as u32);
        }
    }
    out.retain(|f| !f.is_empty());
    Ok(out)
}

/// Reads a per-corner index list and checks it has the shape of `coord_faces`.
fn faces_like(v: &Value, coord_faces: &[Vec<u32>], n: usize, what: &str) -> PResult<Vec<Vec<u32>>> {
    let f = split_faces(v, n, what)?;
    let same =
        f.len() == coord_faces.len() && f.iter().zip(coord_faces).all(|(a, b)| a.len() == b.len());
    if !same {
        let msg = format!("{what} does not have the same faces as coordIndex");
        return Err((v.offset, IngestError::invalid(msg)));
    }
    Ok(f)
}

fn per_face_colors(ifs: &Node, n_colors: usize, n_faces: usize) -> PResult<Vec<u32>> {
    let (idx, offset): (Vec<u32>, usize) = match ifs.nums("colorIndex") {
        Some(v) => (
            split_faces(v, n_colors, "colorIndex")?
                .into_iter()
                .flatten()
                .collect(),
            v.offset,
        ),
        None if n_colors >= n_faces => ((0..n_faces as u32).collect(), 0),
        None => (Vec::new(), ifs.field("color").map_or(0, |v| v.offset)),
    };
    if idx.len() < n_faces {
        let msg = format!(
            "colorPerVertex FALSE: {n_faces} faces but {} face colours",
            idx.len()
        );
        return Err((offset, IngestError::invalid(msg)));
    }
    Ok(idx)
}

fn to_rgb(c: &[f64; 3]) -> [u8; 3] {
    c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// Applies a `TextureTransform` (`Tc' = −C·S·R·C·T·Tc`) and flips v to the glTF convention.
fn texture_uv(xf: Option<&Node>, uv: [f64; 2]) -> [f32; 2] {
    let [mut u, mut v] = uv;
    if let Some(x) = xf {
        let [cx, cy] = x.vec("center", [0.0; 2]);
        let [tx, ty] = x.vec("translation", [0.0; 2]);
        let [sx, sy] = x.vec("scale", [1.0; 2]);
        let [r] = x.vec("rotation", [0.0]);
        let (pu, pv) = (u + tx + cx, v + ty + cy);
        let (ru, rv) = (r.cos() * pu - r.sin() * pv, r.sin() * pu + r.cos() * pv);
        (u, v) = (sx * ru - cx, sy * rv - cy);
    }
    [u as f32, (1.0 - v) as f32]
}

/// The local matrix of a `Transform`: `T · C · R · SR · S · −SR · −C`.
fn local_transform(n: &Node) -> Mat4 {
    let v3 = |name: &str, d: f64| Vector3::from(n.vec(name, [d; 3]));
    let (t, c, s) = (v3("translation", 0.0), v3("center", 0.0), v3("scale", 1.0));
    let rot = |name: &str, sign: f64| {
        let [x, y, z, a] = n.vec(name, [0.0, 0.0, 1.0, 0.0]);
        Unit::try_new(Vector3::new(x, y, z), 1e-12).map_or(Mat4::identity(), |axis| {
            Rotation3::from_axis_angle(&axis, sign * a).to_homogeneous()
        })
    };
    Mat4::new_translation(&(t + c))
        * rot("rotation", 1.0)
        * rot("scaleOrientation", 1.0)
        * Mat4::new_nonuniform_scaling(&s)
        * rot("scaleOrientation", -1.0)
        * Mat4::new_translation(&-c)
}

/// One shape (or inlined file) before it is transformed into the merged mesh.
#[derive(Default)]
pub(super) struct Piece {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    uvs: Vec<[f32; 2]>,
    colors: Vec<[u8; 3]>,
    has_uv: bool,
    has_color: bool,
    diffuse: [u8; 3],
    texture: Option<String>,
    flip: bool,
}

impl Piece {
    fn push_vertex(&mut self, p: [f64; 3], uv: [f32; 2], color: Option<[u8; 3]>) {
        self.positions.push(p);
        self.uvs.push(uv);
        self.colors.push(color.unwrap_or(self.diffuse));
    }

    fn from_mesh(m: TriMesh) -> Piece {
        let n = m.positions.len();
        Piece {
            has_uv: m.uvs.is_some(),
            has_color: m.colors.is_some(),
            uvs: m.uvs.unwrap_or_else(|| vec![[0.0; 2]; n]),
            colors: m.colors.unwrap_or_else(|| vec![[204; 3]; n]),
            positions: m.positions,
            triangles: m.triangles,
            diffuse: [204; 3],
            texture: m.texture,
            flip: false,
        }
    }

    /// Appends `piece` transformed by `m` (this piece is the merged mesh being built).
    fn append(&mut self, piece: Piece, m: &Mat4, limits: &Limits) -> Result<()> {
        let base = self.positions.len();
        let total = (base + piece.positions.len()) as u64;
        Limits::check_len(
            "mesh vertices",
            total,
            limits.max_points.min(u64::from(u32::MAX)),
        )?;
        if let Some(t) = piece.texture.filter(|_| piece.has_uv) {
            match &self.texture {
                Some(old) if *old != t => {
                    return Err(IngestError::Unsupported(format!(
                        "a second texture {t:?} besides {old:?}: one texture per mesh"
                    )))
                }
                _ => self.texture = Some(t),
            }
        }
        let flip = piece.flip != (m.fixed_view::<3, 3>(0, 0).determinant() < 0.0);
        let moved = piece
            .positions
            .iter()
            .map(|p| m.transform_point(&Point3::from(*p)));
        self.positions
            .extend(moved.map(|p| <[f64; 3]>::from(p.coords)));
        let b = base as u32;
        self.triangles
            .extend(piece.triangles.iter().map(|&[x, y, z]| {
                if flip {
                    [x + b, z + b, y + b]
                } else {
                    [x + b, y + b, z + b]
                }
            }));
        self.uvs.extend(piece.uvs);
        self.colors.extend(piece.colors);
        self.has_uv |= piece.has_uv;
        self.has_color |= piece.has_color;
        Ok(())
    }

    pub(super) fn finish(self) -> TriMesh {
        TriMesh {
            positions: self.positions,
            triangles: self.triangles,
            uvs: self.has_uv.then_some(self.uvs),
            colors: self.has_color.then_some(self.colors),
            texture: self.texture,
        }
    }
}
