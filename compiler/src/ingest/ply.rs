//! PLY point clouds and meshes via `ply-rs-bw` (formats.md §9), and an ASCII PLY writer for
//! round-trip tests.
//!
//! Design decisions:
//! - One parse (ascii, binary little or big endian, CRLF headers) feeds both readers; they
//!   differ only in what they require: [`read_ply`] needs a `vertex` element with x, y, z;
//!   [`read_ply_mesh`] also needs a `face` element.
//! - Property names vary by producer, so they are matched by role: colour is `red/green/blue`
//!   or CMPMVS's `diffuse_red/...` (integers 0..255, floats 0..1); faces are `vertex_indices`
//!   or `vertex_index`; per-vertex UVs are `texture_u/texture_v`, `s/t` or `u/v`, flipped to
//!   the glTF convention (v down); names containing `reflectance` fill `reflectance_db`,
//!   `intensity` or `scalar*` fill `intensity`.
//! - Per-corner UVs (MeshLab / COLMAP textured meshes: `comment TextureFile texture.png` and a
//!   face `property list uchar float texcoord`, u v per corner) split vertices per distinct
//!   (vertex, uv) pair, as the VRML reader does for `texCoordIndex`, so [`TriMesh`] keeps one
//!   uv per vertex; `texnumber` picks the `TextureFile` (one texture per mesh).
//! - Polygons with more than three corners are fan-triangulated; an index outside the vertex
//!   list or a face with fewer than three corners is an error naming the face.
//! - Element counts from the header are checked against [`Limits`] before the payload is
//!   read. The generic `ply-rs-bw` element maps cost ~10x a typed reader; that is fine for SfM
//!   outputs (10^5–10^6 vertices) and is the place to optimise if huge PLYs show up.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, Header, Property};
use regolith_format::limits::Limits;

use super::riscan_ascii::{color_byte, read_file};
use super::types::{PointCloud, TriMesh};
use crate::error::{IngestError, Result};

fn ply_err(e: ply_rs_bw::parser::ParseError) -> IngestError {
    let msg = e
        .to_string()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    let err = IngestError::invalid(format!("PLY: {msg}"));
    match e.line() {
        Some(line) => err.at_line(line as u64),
        None => err,
    }
}

struct Parsed {
    header: Header,
    vertices: Vec<DefaultElement>,
    faces: Option<Vec<DefaultElement>>,
}

fn parse(bytes: &[u8], limits: &Limits) -> Result<Parsed> {
    let parser = Parser::<DefaultElement>::new();
    let mut reader = Reader::new(bytes);
    let header = parser.read_header(&mut reader).map_err(ply_err)?;
    for (name, def) in &header.elements {
        let what = if name == "face" {
            "PLY faces"
        } else {
            "PLY elements"
        };
        Limits::check_len(what, def.count as u64, limits.max_points)?;
    }
    let mut payload = parser.read_payload(&mut reader, &header).map_err(ply_err)?;
    let Some(vertices) = payload.shift_remove("vertex") else {
        return Err(IngestError::syntax(
            "an `element vertex` in the PLY header",
            "none",
        ));
    };
    let faces = payload.shift_remove("face");
    Ok(Parsed {
        header,
        vertices,
        faces,
    })
}

/// A scalar property as `f64`, and whether it is a float type (colours 0..1).
fn scalar(p: &Property) -> Option<(f64, bool)> {
    Some(match *p {
        Property::Char(v) => (f64::from(v), false),
        Property::UChar(v) => (f64::from(v), false),
        Property::Short(v) => (f64::from(v), false),
        Property::UShort(v) => (f64::from(v), false),
        Property::Int(v) => (f64::from(v), false),
        Property::UInt(v) => (f64::from(v), false),
        Property::Float(v) => (f64::from(v), true),
        Property::Double(v) => (v, true),
        _ => return None,
    })
}

fn get(e: &DefaultElement, names: &[&str], what: &str, i: usize) -> Result<Option<(f64, bool)>> {
    let Some(p) = names.iter().find_map(|n| e.get(*n)) else {
        return Ok(None);
    };
    match scalar(p) {
        Some((v, f)) if v.is_finite() => Ok(Some((v, f))),
        _ => Err(IngestError::syntax(
            format!("a finite number for {what} of vertex {i}"),
            &format!("{p:?}"),
        )),
    }
}

fn position(e: &DefaultElement, i: usize) -> Result<[f64; 3]> {
    let mut p = [0.0; 3];
    for (slot, axis) in p.iter_mut().zip(["x", "y", "z"]) {
        let what = format!("PLY property {axis}");
        *slot = get(e, &[axis], &what, i)?
            .ok_or_else(|| IngestError::syntax(format!("{what} on vertex {i}"), "none"))?
            .0;
    }
    Ok(p)
}

const RED: [&str; 2] = ["red", "diffuse_red"];
const GREEN: [&str; 2] = ["green", "diffuse_green"];
const BLUE: [&str; 2] = ["blue", "diffuse_blue"];

fn color(e: &DefaultElement, i: usize) -> Result<Option<[u8; 3]>> {
    let mut c = [0u8; 3];
    for (slot, (names, what)) in c
        .iter_mut()
        .zip([(RED, "red"), (GREEN, "green"), (BLUE, "blue")])
    {
        let Some((v, is_float)) = get(e, &names, what, i)? else {
            return Ok(None);
        };
        *slot = color_byte(v, is_float, || format!("{what} of vertex {i}"))?;
    }
    Ok(Some(c))
}

/// Names of the first property whose name matches `pred`, from the vertex definition.
fn property_named(header: &Header, pred: impl Fn(&str) -> bool) -> Option<String> {
    let def = header.elements.get("vertex")?;
    def.properties
        .keys()
        .find(|k| pred(&k.to_ascii_lowercase()))
        .cloned()
}

/// Reads a PLY point cloud (faces, if any, are ignored).
pub fn read_ply(bytes: &[u8], limits: &Limits) -> Result<PointCloud> {
    let parsed = parse(bytes, limits)?;
    let refl_name = property_named(&parsed.header, |k| k.contains("reflectance"));
    let int_name = property_named(&parsed.header, |k| {
        k == "intensity" || k.starts_with("scalar")
    })
    .filter(|n| Some(n) != refl_name.as_ref());
    let mut cloud = PointCloud {
        points: limits.vec_with_capacity("points", parsed.vertices.len() as u64)?,
        ..Default::default()
    };
    let mut rgb = Vec::new();
    let mut refl = Vec::new();
    let mut int = Vec::new();
    for (i, v) in parsed.vertices.iter().enumerate() {
        cloud.points.push(position(v, i)?);
        if let Some(c) = color(v, i)? {
            rgb.push(c);
        }
        for (name, out) in [(&refl_name, &mut refl), (&int_name, &mut int)] {
            if let Some(name) = name {
                out.push(get(v, &[name.as_str()], name, i)?.map_or(0.0, |x| x.0) as f32);
            }
        }
    }
    cloud.rgb = (!rgb.is_empty() && rgb.len() == cloud.points.len()).then_some(rgb);
    cloud.reflectance_db = refl_name.map(|_| refl);
    cloud.intensity = int_name.map(|_| int);
    Ok(cloud)
}

/// Face corner indices as `i64` from any integer list type.
fn corner_list(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListUChar(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListShort(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListUShort(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListInt(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListUInt(v) => v.iter().map(|&x| i64::from(x)).collect(),
        _ => return None,
    })
}

/// Face texture coordinates as `f64` from any numeric list type.
fn number_list(p: &Property) -> Option<Vec<f64>> {
    Some(match p {
        Property::ListFloat(v) => v.iter().map(|&x| f64::from(x)).collect(),
        Property::ListDouble(v) => v.clone(),
        other => corner_list(other)?.into_iter().map(|x| x as f64).collect(),
    })
}

const TEXCOORD: [&str; 2] = ["texcoord", "texcoords"];

/// The checked corner indices of face `f`.
fn face_corners(face: &DefaultElement, f: usize, n: usize) -> Result<Vec<u32>> {
    let corners = ["vertex_indices", "vertex_index"]
        .iter()
        .find_map(|k| face.get(*k))
        .and_then(corner_list);
    let Some(corners) = corners else {
        return Err(IngestError::syntax(
            format!("an integer list vertex_indices on face {f}"),
            "none",
        ));
    };
    let idx = corners
        .iter()
        .map(|&c| u32::try_from(c).ok().filter(|&c| (c as usize) < n))
        .collect::<Option<Vec<u32>>>()
        .ok_or_else(|| {
            IngestError::invalid(format!(
                "face {f} has corners {corners:?}, expected indices below {n} vertices"
            ))
        })?;
    if idx.len() < 3 {
        return Err(IngestError::invalid(format!(
            "face {f} has {} corners, expected at least 3",
            idx.len()
        )));
    }
    Ok(idx)
}

/// The per-corner UVs of face `f` (`texcoord`: u0 v0 u1 v1 ...), v flipped to glTF's convention.
fn face_uvs(face: &DefaultElement, f: usize, corners: usize) -> Result<Vec<[f32; 2]>> {
    let list = TEXCOORD
        .iter()
        .find_map(|k| face.get(*k))
        .and_then(number_list)
        .unwrap_or_default();
    if list.len() != 2 * corners || !list.iter().all(|v| v.is_finite()) {
        return Err(IngestError::invalid(format!(
            "face {f} has {} texcoord values, expected {} finite ones (u v per corner)",
            list.len(),
            2 * corners
        )));
    }
    Ok(list
        .chunks_exact(2)
        .map(|c| match c {
            [u, v] => [*u as f32, (1.0 - v) as f32],
            _ => [0.0; 2],
        })
        .collect())
}

/// The texture of a mesh: the `comment TextureFile` the faces' `texnumber` selects (the first
/// one without `texnumber`); faces using two textures are unsupported (one texture per mesh,
/// as for VRML).
fn face_texture(header: &Header, faces: &[DefaultElement]) -> Result<Option<String>> {
    let files: Vec<String> = header
        .comments
        .iter()
        .filter_map(|c| {
            let rest = c.trim().strip_prefix("TextureFile")?;
            Some(rest.trim().to_string()).filter(|s| !s.is_empty())
        })
        .collect();
    let mut used: Option<i64> = None;
    for (f, face) in faces.iter().enumerate() {
        let Some(n) = face.get("texnumber").and_then(scalar) else {
            continue;
        };
        let n = n.0 as i64;
        match used {
            Some(u) if u != n => {
                return Err(IngestError::Unsupported(format!(
                "face {f} uses texture {n} and an earlier face texture {u}: one texture per mesh"
            )))
            }
            _ => used = Some(n),
        }
    }
    match used {
        None => Ok(files.into_iter().next()),
        Some(n) => usize::try_from(n)
            .ok()
            .and_then(|i| files.get(i).cloned())
            .map(Some)
            .ok_or_else(|| {
                IngestError::invalid(format!(
                    "faces use texnumber {n} but the header names {} `TextureFile`s",
                    files.len()
                ))
            }),
    }
}

/// Reads a PLY triangle mesh (e.g. an SfM reconstruction).
///
/// Per-corner texture coordinates (`property list uchar float texcoord` on faces, MeshLab and
/// COLMAP textured meshes) are represented as the VRML reader represents them: a vertex per
/// distinct (vertex, uv) pair, in order of first use, with per-vertex `uvs`; vertices no face
/// uses are dropped in that case.
pub fn read_ply_mesh(bytes: &[u8], limits: &Limits) -> Result<TriMesh> {
    let parsed = parse(bytes, limits)?;
    let Some(faces) = parsed.faces else {
        return Err(IngestError::syntax(
            "an `element face` in the PLY header",
            "none",
        ));
    };
    let n = parsed.vertices.len();
    let mut positions = limits.vec_with_capacity("vertices", n as u64)?;
    let (mut colors, mut uvs) = (Vec::new(), Vec::new());
    for (i, v) in parsed.vertices.iter().enumerate() {
        positions.push(position(v, i)?);
        if let Some(c) = color(v, i)? {
            colors.push(c);
        }
        let u = get(v, &["texture_u", "s", "u"], "texture u", i)?;
        let w = get(v, &["texture_v", "t", "v"], "texture v", i)?;
        if let (Some((u, _)), Some((w, _))) = (u, w) {
            uvs.push([u as f32, (1.0 - w) as f32]);
        }
    }
    let colors = (!colors.is_empty() && colors.len() == n).then_some(colors);
    let per_corner = parsed
        .header
        .elements
        .get("face")
        .is_some_and(|d| TEXCOORD.iter().any(|k| d.properties.contains_key(*k)));
    let mut mesh = TriMesh {
        texture: face_texture(&parsed.header, &faces)?,
        ..Default::default()
    };
    let mut split = CornerSplit::default();
    for (f, face) in faces.iter().enumerate() {
        let mut idx = face_corners(face, f, n)?;
        if per_corner {
            let corner_uvs = face_uvs(face, f, idx.len())?;
            for (c, uv) in idx.iter_mut().zip(corner_uvs) {
                *c = split.vertex(*c, uv, limits)?;
            }
        }
        if let [first, rest @ ..] = idx.as_slice() {
            mesh.triangles
                .extend(rest.windows(2).filter_map(|w| match w {
                    [b, c] => Some([*first, *b, *c]),
                    _ => None,
                }));
        }
    }
    if per_corner {
        let pick = |i: &u32| positions.get(*i as usize).copied().unwrap_or_default();
        mesh.positions = split.source.iter().map(pick).collect();
        mesh.colors = colors.map(|c| {
            let pick = |i: &u32| c.get(*i as usize).copied().unwrap_or_default();
            split.source.iter().map(pick).collect()
        });
        mesh.uvs = Some(split.uvs);
    } else {
        mesh.positions = positions;
        mesh.colors = colors;
        mesh.uvs = (!uvs.is_empty() && uvs.len() == n).then_some(uvs);
    }
    Ok(mesh)
}

/// Output vertices made per distinct (file vertex, uv) pair.
#[derive(Default)]
struct CornerSplit {
    seen: HashMap<(u32, u32, u32), u32>,
    /// File vertex of each output vertex.
    source: Vec<u32>,
    uvs: Vec<[f32; 2]>,
}

impl CornerSplit {
    fn vertex(&mut self, v: u32, uv: [f32; 2], limits: &Limits) -> Result<u32> {
        let next = self.source.len() as u32;
        let id = *self
            .seen
            .entry((v, uv[0].to_bits(), uv[1].to_bits()))
            .or_insert(next);
        if id == next {
            Limits::check_len(
                "mesh vertices",
                u64::from(next) + 1,
                limits.max_points.min(u64::from(u32::MAX)),
            )?;
            self.source.push(v);
            self.uvs.push(uv);
        }
        Ok(id)
    }
}

/// Reads a PLY point cloud from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<PointCloud> {
    let bytes = read_file(path, limits)?;
    read_ply(&bytes, limits).map_err(|e| e.in_file(path))
}

/// Reads a PLY mesh from disk; errors name the path.
pub fn read_mesh_path(path: &Path, limits: &Limits) -> Result<TriMesh> {
    let bytes = read_file(path, limits)?;
    read_ply_mesh(&bytes, limits).map_err(|e| e.in_file(path))
}

/// Writes a point cloud as ASCII PLY (`double` coordinates, `float` reflectance/intensity,
/// `uchar` colour), in Rust's shortest round-trip number form.
pub fn write_ply_ascii(cloud: &PointCloud) -> String {
    let n = cloud.points.len();
    let aligned = |len: Option<usize>| len == Some(n);
    let refl = cloud
        .reflectance_db
        .as_ref()
        .filter(|v| aligned(Some(v.len())));
    let int = cloud.intensity.as_ref().filter(|v| aligned(Some(v.len())));
    let rgb = cloud.rgb.as_ref().filter(|v| aligned(Some(v.len())));
    let mut s = format!("ply\nformat ascii 1.0\ncomment written by regolith\nelement vertex {n}\n");
    s.push_str("property double x\nproperty double y\nproperty double z\n");
    if refl.is_some() {
        s.push_str("property float reflectance\n");
    }
    if int.is_some() {
        s.push_str("property float intensity\n");
    }
    if rgb.is_some() {
        s.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    s.push_str("end_header\n");
    for (i, p) in cloud.points.iter().enumerate() {
        let _ = write!(s, "{} {} {}", p[0], p[1], p[2]);
        for v in [refl, int].into_iter().flatten() {
            let _ = write!(s, " {}", v.get(i).copied().unwrap_or_default());
        }
        if let Some(c) = rgb.and_then(|c| c.get(i)) {
            let _ = write!(s, " {} {} {}", c[0], c[1], c[2]);
        }
        s.push('\n');
    }
    s
}
