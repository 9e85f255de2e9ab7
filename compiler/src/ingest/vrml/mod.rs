//! VRML 2.0 / VRML97 (`.wrl`) meshes, as written by 3ds Max, CMPMVS and the CMP SfM service
//! (formats.md §8), into one merged [`TriMesh`] in the file's frame.
//!
//! No mature crate exists, so this is a hand-written streaming tokenizer plus a recursive parser.
//! Design decisions:
//!
//! - **Generic tree, then interpretation.** The parser builds a small untyped node tree (a node
//!   is a type name plus `field -> value` pairs; a value is a bag of numbers, strings, words and
//!   nodes) so it never needs the VRML field-type table. Only the node types we interpret are
//!   parsed; any other node (`Script`, `Viewpoint`, `Box`, `PROTO` instances, ...) is skipped by
//!   balanced braces and brackets, remembering the `DEF` names inside so a later `USE` resolves
//!   to "skipped" rather than failing. `ROUTE`, `PROTO` and `EXTERNPROTO` statements are skipped.
//! - **Transforms** are composed down the tree as 4x4 matrices in the order of ISO/IEC 14772
//!   §6.52: `T · C · R · SR · S · −SR · −C`. A mirroring transform (negative determinant) or
//!   `ccw FALSE` reverses the triangle order so every output triangle is counter-clockwise.
//! - **Faces** (`coordIndex`, separated by `-1`, final `-1` optional) are fanned into triangles;
//!   faces with fewer than 3 corners are ignored, as the spec says. A missing `texCoordIndex`
//!   (or `colorIndex`) reuses `coordIndex`. When the texture/colour indices equal the coordinate
//!   indices, output vertices are the file's points in order; otherwise a vertex is made per
//!   distinct (point, uv, colour) index triple.
//! - **Texture coordinates**: `TextureTransform` is applied as the spec writes it,
//!   `Tc' = −C · S · R · C · T · Tc` (translation applied first, then scaled). formats.md §8.3
//!   writes `scale·uv + translation` for CMPMVS; that contradicts ISO 14772 §6.50 and every VRML
//!   browser we checked, so we follow the spec. VRML's v axis points up, glTF's down: `v' = 1 − v`.
//! - `Color` values (0..1) become `u8`; a shape without `Color` in a mesh where another shape has
//!   one gets its `Material.diffuseColor` (default 0.8 grey). One texture per mesh: a second,
//!   different `ImageTexture.url` is reported as unsupported rather than silently dropped.
//! - `Inline { url }` (CMPMVS aggregators) is resolved by [`read_path`] relative to the file's
//!   folder, at most [`MAX_INLINE_DEPTH`] levels deep; [`read_bytes`] ignores inlines.
//! - Hostile input: nesting deeper than [`MAX_DEPTH`] and more than [`MAX_VISITS`] node
//!   instances (exponential `USE` fan-out) are errors; point counts go through `Limits`.
//!
//! Layout: `lexer` (tokens), `parser` (the generic node tree, `DEF`/`USE`), `geometry`
//! (transforms, faces, texture coordinates, the merged mesh); this file holds the entry points
//! and the writer.

mod geometry;
mod lexer;
mod parser;

use std::collections::{HashMap, VecDeque};
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Matrix4;
use regolith_format::limits::Limits;

use crate::error::{IngestError, Result};
use crate::ingest::types::TriMesh;
use geometry::{Piece, Walker};
use lexer::Lexer;
use parser::Parser;

type Mat4 = Matrix4<f64>;

/// Deepest node nesting accepted.
pub const MAX_DEPTH: usize = 128;
/// Most node instances visited while flattening the scene (guards against `USE` fan-out).
pub const MAX_VISITS: u64 = 10_000_000;
/// Deepest chain of `Inline` files followed by [`read_path`].
pub const MAX_INLINE_DEPTH: usize = 4;

const HEADER: &[u8] = b"#VRML V2.0 utf8";
/// Node types whose fields are parsed; everything else is skipped by brace matching.
#[rustfmt::skip]
const KNOWN: &[&str] = &[
    "Transform", "Group", "Collision", "Anchor", "Billboard", "Switch", "LOD", "Shape",
    "Appearance", "Material", "ImageTexture", "TextureTransform", "IndexedFaceSet",
    "Coordinate", "TextureCoordinate", "Color", "Normal", "Inline",
];

/// Reads a `.wrl` file, following `Inline` nodes relative to its folder.
pub fn read_path(path: &Path, limits: &Limits) -> Result<TriMesh> {
    read_path_depth(path, limits, 0)
}

/// Parses VRML 2.0 bytes into one merged mesh; `Inline` nodes are ignored.
pub fn read_bytes(bytes: &[u8], limits: &Limits) -> Result<TriMesh> {
    parse(bytes, limits, &mut |_| Ok(None))
}

fn read_path_depth(path: &Path, limits: &Limits, depth: usize) -> Result<TriMesh> {
    let bytes = crate::ingest::images::read_file(path, limits)?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut inline = |url: &str| -> Result<Option<TriMesh>> {
        if depth >= MAX_INLINE_DEPTH {
            return Err(IngestError::invalid(format!(
                "Inline {url:?} nested deeper than {MAX_INLINE_DEPTH} files"
            )));
        }
        let mut mesh = read_path_depth(&dir.join(url), limits, depth + 1)?;
        // The inlined file's texture is relative to its own folder.
        if let (Some(t), Some(parent)) = (&mesh.texture, Path::new(url).parent()) {
            mesh.texture = Some(parent.join(t).to_string_lossy().replace('\\', "/"));
        }
        Ok(Some(mesh))
    };
    parse(&bytes, limits, &mut inline).map_err(|e| e.in_file(path))
}

fn parse(
    bytes: &[u8],
    limits: &Limits,
    inline: &mut dyn FnMut(&str) -> Result<Option<TriMesh>>,
) -> Result<TriMesh> {
    let body = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    if !body.starts_with(HEADER) {
        let first = body.split(|&b| b == b'\n').next().unwrap_or_default();
        let found = String::from_utf8_lossy(first);
        return Err(IngestError::syntax("header \"#VRML V2.0 utf8\"", found.trim_end()).at_line(1));
    }
    let mut p = Parser {
        lex: Lexer { src: body, pos: 0 },
        ahead: VecDeque::new(),
        defs: HashMap::new(),
    };
    let roots = p.parse_file().map_err(|(off, e)| locate(body, off, e))?;
    let mut w = Walker {
        out: Piece::default(),
        limits,
        visits: 0,
        src: body,
        inline,
    };
    for root in &roots {
        w.walk(root, &Mat4::identity(), 0)?;
    }
    Ok(w.out.finish())
}

/// Wraps an error with its line and byte offset.
fn locate(src: &[u8], offset: usize, err: IngestError) -> IngestError {
    let line = memchr::memchr_iter(b'\n', src.get(..offset).unwrap_or(src)).count() as u64 + 1;
    err.at_offset(offset as u64).at_line(line)
}

/// Writes a mesh as VRML 2.0: one `Shape` with an `IndexedFaceSet` (uvs converted back to
/// VRML's v-up convention, no `texCoordIndex` since uvs are per vertex). [`read_bytes`] reads
/// it back to the same mesh.
pub fn write_vrml(mesh: &TriMesh) -> String {
    let mut s = String::from("#VRML V2.0 utf8\n# written by regolith\nShape {\n");
    if let Some(t) = &mesh.texture {
        let _ = writeln!(
            s,
            "  appearance Appearance {{ texture ImageTexture {{ url \"{t}\" }} }}"
        );
    }
    s.push_str("  geometry IndexedFaceSet {\n    coord Coordinate { point [\n");
    for p in &mesh.positions {
        let _ = writeln!(s, "      {} {} {},", p[0], p[1], p[2]);
    }
    s.push_str("    ] }\n    coordIndex [\n");
    for t in &mesh.triangles {
        let _ = writeln!(s, "      {} {} {} -1,", t[0], t[1], t[2]);
    }
    s.push_str("    ]\n");
    if let Some(uvs) = &mesh.uvs {
        s.push_str("    texCoord TextureCoordinate { point [\n");
        for uv in uvs {
            let _ = writeln!(s, "      {} {},", uv[0], 1.0 - f64::from(uv[1]));
        }
        s.push_str("    ] }\n");
    }
    if let Some(colors) = &mesh.colors {
        s.push_str("    color Color { color [\n");
        for c in colors {
            let f = c.map(|v| f64::from(v) / 255.0);
            let _ = writeln!(s, "      {} {} {},", f[0], f[1], f[2]);
        }
        s.push_str("    ] }\n");
    }
    s.push_str("  }\n}\n");
    s
}
