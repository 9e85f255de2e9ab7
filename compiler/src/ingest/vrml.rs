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

use std::collections::{HashMap, VecDeque};
use std::fmt::Write as _;
use std::path::Path;
use std::rc::Rc;

use nalgebra::{Matrix4, Point3, Rotation3, Unit, Vector3};
use regolith_format::limits::Limits;

use crate::error::{IngestError, Result};
use crate::ingest::types::TriMesh;

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

// ---------------------------------------------------------------------------------- tokens

#[derive(Debug, Clone, PartialEq)]
enum Tok<'a> {
    Open,
    Close,
    LBracket,
    RBracket,
    Word(&'a str),
    Str(String),
}

type Token<'a> = (usize, Tok<'a>);
/// Parser errors carry the byte offset; [`locate`] turns it into line + offset.
type PResult<T> = std::result::Result<T, (usize, IngestError)>;

struct Lexer<'a> {
    src: &'a [u8],
    pos: usize,
}

impl<'a> Lexer<'a> {
    fn byte(&self, i: usize) -> Option<u8> {
        self.src.get(i).copied()
    }

    fn next_token(&mut self) -> PResult<Option<Token<'a>>> {
        loop {
            match self.byte(self.pos) {
                None => return Ok(None),
                Some(b' ' | b'\t' | b'\r' | b'\n' | b',') => self.pos += 1,
                Some(b'#') => {
                    let rest = self.src.get(self.pos..).unwrap_or_default();
                    self.pos += memchr::memchr(b'\n', rest).unwrap_or(rest.len());
                }
                Some(_) => break,
            }
        }
        let start = self.pos;
        let tok = match self.byte(start) {
            Some(b'{') => Tok::Open,
            Some(b'}') => Tok::Close,
            Some(b'[') => Tok::LBracket,
            Some(b']') => Tok::RBracket,
            Some(b'"') => return self.string(start),
            _ => return self.word(start),
        };
        self.pos += 1;
        Ok(Some((start, tok)))
    }

    fn word(&mut self, start: usize) -> PResult<Option<Token<'a>>> {
        while let Some(b) = self.byte(self.pos) {
            if matches!(
                b,
                b' ' | b'\t' | b'\r' | b'\n' | b',' | b'{' | b'}' | b'[' | b']' | b'#' | b'"'
            ) {
                break;
            }
            self.pos += 1;
        }
        let word = self.src.get(start..self.pos).unwrap_or_default();
        let word = std::str::from_utf8(word).map_err(|_| {
            (
                start,
                IngestError::syntax("a UTF-8 word", &String::from_utf8_lossy(word)),
            )
        })?;
        Ok(Some((start, Tok::Word(word))))
    }

    fn string(&mut self, start: usize) -> PResult<Option<Token<'a>>> {
        let mut out = Vec::new();
        self.pos = start + 1;
        loop {
            match self.byte(self.pos) {
                None => return Err((start, IngestError::syntax("a closing '\"'", "end of file"))),
                Some(b'"') => break,
                Some(b'\\') => {
                    out.extend(self.byte(self.pos + 1));
                    self.pos += 2;
                }
                Some(b) => {
                    out.push(b);
                    self.pos += 1;
                }
            }
        }
        self.pos += 1;
        Ok(Some((
            start,
            Tok::Str(String::from_utf8_lossy(&out).into_owned()),
        )))
    }
}

// ---------------------------------------------------------------------------------- tree

/// A parsed node: type name and fields in file order. Skipped (unknown) nodes have no fields.
#[derive(Debug, Default)]
struct Node {
    kind: String,
    fields: Vec<(String, Value)>,
}

/// A field value: whatever the file put there.
#[derive(Debug, Default)]
struct Value {
    offset: usize,
    nums: Vec<f64>,
    strs: Vec<String>,
    words: Vec<String>,
    nodes: Vec<Rc<Node>>,
}

impl Node {
    fn field(&self, name: &str) -> Option<&Value> {
        self.fields
            .iter()
            .rev()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v)
    }
    fn node(&self, name: &str) -> Option<&Rc<Node>> {
        self.field(name).and_then(|v| v.nodes.first())
    }
    fn nums(&self, name: &str) -> Option<&Value> {
        self.field(name).filter(|v| !v.nums.is_empty())
    }
    fn vec<const N: usize>(&self, name: &str, default: [f64; N]) -> [f64; N] {
        let mut out = default;
        if let Some(v) = self.field(name) {
            for (o, n) in out.iter_mut().zip(&v.nums) {
                *o = *n;
            }
        }
        out
    }
    fn flag(&self, name: &str, default: bool) -> bool {
        match self.field(name).and_then(|v| v.words.first()) {
            Some(w) => w == "TRUE",
            None => default,
        }
    }
}

struct Parser<'a> {
    lex: Lexer<'a>,
    ahead: VecDeque<Token<'a>>,
    /// `DEF` names; `None` for nodes that were skipped.
    defs: HashMap<String, Option<Rc<Node>>>,
}

impl<'a> Parser<'a> {
    fn peek(&mut self, k: usize) -> PResult<Option<&Token<'a>>> {
        while self.ahead.len() <= k {
            match self.lex.next_token()? {
                Some(t) => self.ahead.push_back(t),
                None => break,
            }
        }
        Ok(self.ahead.get(k))
    }

    fn next(&mut self) -> PResult<Token<'a>> {
        self.peek(0)?;
        let end = self.lex.pos;
        self.ahead
            .pop_front()
            .ok_or((end, IngestError::syntax("more input", "end of file")))
    }

    fn word(&mut self, what: &str) -> PResult<(usize, &'a str)> {
        match self.next()? {
            (off, Tok::Word(w)) => Ok((off, w)),
            (off, t) => Err((off, IngestError::syntax(what, &format!("{t:?}")))),
        }
    }

    fn expect(&mut self, tok: Tok<'a>) -> PResult<()> {
        let (off, t) = self.next()?;
        if t != tok {
            return Err((
                off,
                IngestError::syntax(format!("{tok:?}"), &format!("{t:?}")),
            ));
        }
        Ok(())
    }

    fn parse_file(&mut self) -> PResult<Vec<Rc<Node>>> {
        let mut roots = Vec::new();
        while self.peek(0)?.is_some() {
            if !self.statement()? {
                roots.extend(self.node(0)?);
            }
        }
        Ok(roots)
    }

    /// Skips `ROUTE`, `PROTO` and `EXTERNPROTO`; returns whether one was consumed.
    fn statement(&mut self) -> PResult<bool> {
        let Some((_, Tok::Word(w))) = self.peek(0)?.cloned() else {
            return Ok(false);
        };
        match w {
            "ROUTE" => {
                for _ in 0..4 {
                    self.next()?;
                }
            }
            "PROTO" | "EXTERNPROTO" => {
                self.next()?;
                self.word("a PROTO name")?;
                self.skip_balanced()?;
                if w == "PROTO" {
                    self.skip_balanced()?;
                } else if let Some((_, Tok::Str(_))) = self.peek(0)? {
                    self.next()?;
                } else {
                    self.skip_balanced()?;
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// Skips one `{...}` or `[...]` group, recording `DEF` names inside as skipped.
    fn skip_balanced(&mut self) -> PResult<()> {
        let mut depth = 0usize;
        loop {
            let (off, t) = self.next()?;
            match t {
                Tok::Open | Tok::LBracket => depth += 1,
                _ if depth == 0 => {
                    return Err((off, IngestError::syntax("'{' or '['", &format!("{t:?}"))))
                }
                Tok::Close | Tok::RBracket => depth -= 1,
                Tok::Word("DEF") => {
                    let (_, name) = self.word("a DEF name")?;
                    self.defs.insert(name.to_string(), None);
                }
                _ => {}
            }
            if depth == 0 {
                return Ok(());
            }
        }
    }

    /// `DEF name Node`, `USE name`, `NULL` or `Type { ... }`; `None` for NULL and skipped nodes.
    fn node(&mut self, depth: usize) -> PResult<Option<Rc<Node>>> {
        let (off, w) = self.word("a node type, DEF, USE or NULL")?;
        if depth > MAX_DEPTH {
            return Err((
                off,
                IngestError::invalid(format!("nodes nested deeper than {MAX_DEPTH}")),
            ));
        }
        match w {
            "NULL" => Ok(None),
            "USE" => {
                let (off, name) = self.word("a USE name")?;
                match self.defs.get(name) {
                    Some(n) => Ok(n.clone()),
                    None => Err((
                        off,
                        IngestError::invalid(format!("USE {name}: no DEF {name} before it")),
                    )),
                }
            }
            "DEF" => {
                let (_, name) = self.word("a DEF name")?;
                let n = self.node(depth)?;
                self.defs.insert(name.to_string(), n.clone());
                Ok(n)
            }
            kind => {
                if !KNOWN.contains(&kind) {
                    self.skip_balanced()?;
                    return Ok(None);
                }
                self.expect(Tok::Open)?;
                let mut node = Node {
                    kind: kind.to_string(),
                    fields: Vec::new(),
                };
                loop {
                    if let Some((_, Tok::Close)) = self.peek(0)? {
                        self.next()?;
                        return Ok(Some(Rc::new(node)));
                    }
                    if self.statement()? {
                        continue;
                    }
                    let (_, field) = self.word("a field name or '}'")?;
                    let value = self.value(depth + 1)?;
                    node.fields.push((field.to_string(), value));
                }
            }
        }
    }

    fn starts_node(&mut self) -> PResult<bool> {
        let Some((_, Tok::Word(w))) = self.peek(0)?.cloned() else {
            return Ok(false);
        };
        Ok(matches!(w, "DEF" | "USE" | "NULL") || matches!(self.peek(1)?, Some((_, Tok::Open))))
    }

    fn value(&mut self, depth: usize) -> PResult<Value> {
        let end = self.lex.pos;
        let offset = self.peek(0)?.map_or(end, |t| t.0);
        let mut v = Value {
            offset,
            ..Value::default()
        };
        let list = matches!(self.peek(0)?, Some((_, Tok::LBracket)));
        if list {
            self.next()?;
        }
        loop {
            if self.starts_node()? {
                v.nodes.extend(self.node(depth)?);
            } else {
                match self.peek(0)?.cloned() {
                    Some((_, Tok::RBracket)) if list => {
                        self.next()?;
                        return Ok(v);
                    }
                    Some((_, Tok::Str(s))) => {
                        self.next()?;
                        v.strs.push(s);
                    }
                    Some((off, Tok::Word(w))) => {
                        let num = number(w);
                        if num.is_none()
                            && w.starts_with(|c: char| c.is_ascii_digit() || "+-.".contains(c))
                        {
                            return Err((off, IngestError::syntax("a number", w)));
                        }
                        if !list && num.is_none() && !v.nums.is_empty() {
                            return Ok(v); // the next field name ends a run of numbers
                        }
                        self.next()?;
                        match num {
                            Some(n) => v.nums.push(n),
                            None if list || v.words.is_empty() => v.words.push(w.to_string()),
                            None => return Err((off, IngestError::syntax("a value", w))),
                        }
                    }
                    Some((off, t)) => {
                        return Err((off, IngestError::syntax("a field value", &format!("{t:?}"))))
                    }
                    None => {
                        return Err((self.lex.pos, IngestError::syntax("a value", "end of file")))
                    }
                }
            }
            if !list && (!v.words.is_empty() || !v.strs.is_empty() || !v.nodes.is_empty()) {
                return Ok(v);
            }
            if !list && !matches!(self.peek(0)?, Some((_, Tok::Word(w))) if number(w).is_some()) {
                return Ok(v);
            }
        }
    }
}

/// A VRML number (decimal, exponent, `0x` hex; Rust also accepts `nan`/`inf`, which the
/// interpreter then rejects with a location).
fn number(w: &str) -> Option<f64> {
    let first = w.bytes().next()?;
    let numeric = first.is_ascii_digit() || matches!(first, b'-' | b'+' | b'.');
    if let Some(hex) = w.strip_prefix("0x").or_else(|| w.strip_prefix("0X")) {
        return i64::from_str_radix(hex, 16).ok().map(|v| v as f64);
    }
    if numeric || w.eq_ignore_ascii_case("nan") || w.eq_ignore_ascii_case("inf") {
        return w.parse().ok();
    }
    None
}

// ---------------------------------------------------------------------------------- scene

struct Walker<'a, 'b> {
    out: Piece,
    limits: &'a Limits,
    visits: u64,
    src: &'a [u8],
    inline: &'b mut dyn FnMut(&str) -> Result<Option<TriMesh>>,
}

impl Walker<'_, '_> {
    fn walk(&mut self, node: &Node, m: &Mat4, depth: usize) -> Result<()> {
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

// ---------------------------------------------------------------------------------- output

/// One shape (or inlined file) before it is transformed into the merged mesh.
#[derive(Default)]
struct Piece {
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

    fn finish(self) -> TriMesh {
        TriMesh {
            positions: self.positions,
            triangles: self.triangles,
            uvs: self.has_uv.then_some(self.uvs),
            colors: self.has_color.then_some(self.colors),
            texture: self.texture,
        }
    }
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
