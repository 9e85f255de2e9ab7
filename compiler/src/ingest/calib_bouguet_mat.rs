//! Bouguet toolbox results saved as MATLAB Level-5 binaries (`Calib_Results_stereo.mat`, also
//! a mono `Calib_Results.mat`), formats.md §12.2 → the same [`Pose`] and [`CameraModel`]s as
//! the text forms in [`calib_bouguet`].
//!
//! Design: numeric arrays are decoded by the `matfile` crate (0.5.0: Level 5, compressed or
//! not; not v7.3/HDF5), but the element framing is walked here first, because on its own
//! `matfile` names no place in an error, inflates `miCOMPRESSED` variables without a size
//! limit, computes sizes with `i32`/`u32` arithmetic that overflows (a panic in debug builds) on
//! hostile dimensions or tag lengths, prints to stdout on unknown element types, and rejects
//! `int32` arrays (it maps `mxINT32` to `miUINT32`). So this module:
//! 1. checks the 128-byte header (text, version `0x0100`, endian indicator `IM`/`MI`);
//! 2. walks the top-level data elements by byte offset; a `miCOMPRESSED` one is inflated
//!    through a reader capped at what is left of `Limits::max_object_bytes`;
//! 3. checks that every subelement tag of a matrix (flags, dimensions, name, real and
//!    imaginary parts) fits inside its element and that the element count fits
//!    `Limits::max_points`;
//! 4. hands `matfile` a one-variable file (the original header plus the uncompressed element),
//!    with an `int32` class relabelled `double` (its values convert exactly), only for the
//!    variables the conversion reads (see [`VARIABLES`]); others (strings, cells, per-image
//!    extrinsics) are framed but not decoded.
//!
//! Each variable becomes an [`Assignment`] (values row by row, placed by byte offset), and
//! [`calib_bouguet`]'s conversion does the rest, so errors read
//! `byte offset 1184: `T` must hold 3 finite values (in calib/Calib_Results_stereo.mat)`.

use std::io::Read as _;
use std::path::Path;

use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;
use regolith_format::limits::Limits;

use super::calib_bouguet::{self, Assignment, Form, Place};
use super::calib_opencv::NamedCamera;
use super::yaml_lite;
use crate::error::{IngestError, Result};

/// The variables the conversion reads; other variables are skipped after their framing is
/// checked.
pub const VARIABLES: &[&str] = &[
    "fc",
    "cc",
    "kc",
    "alpha_c",
    "fc_left",
    "cc_left",
    "kc_left",
    "alpha_c_left",
    "fc_right",
    "cc_right",
    "kc_right",
    "alpha_c_right",
    "om",
    "T",
    "R",
    "nx",
    "ny",
    "KK",
    "KK_left",
    "KK_right",
];

const HEADER_LEN: usize = 128;
const MI_INT8: u32 = 1;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const MX_DOUBLE: u32 = 6;
const MX_INT32: u32 = 12;

/// Reads a Bouguet `.mat` as `right_from_left` (`[rig].right_from_left`).
pub fn read_stereo_path(path: &Path, limits: &Limits) -> Result<Pose> {
    yaml_lite::read_with(path, limits, |b| parse_stereo(b, limits))
}

/// Reads the cameras of a Bouguet `.mat`: `"left"` and `"right"` for a stereo result, one
/// camera named `""` for a mono `Calib_Results.mat`.
pub fn read_cameras_path(path: &Path, limits: &Limits) -> Result<Vec<NamedCamera>> {
    yaml_lite::read_with(path, limits, |b| parse_cameras(b, limits))
}

/// `om` (Rodrigues, rad) and `T` (mm) → `right_from_left` in metres, as for the `.m` form.
pub fn parse_stereo(bytes: &[u8], limits: &Limits) -> Result<Pose> {
    calib_bouguet::stereo(&variables(bytes, limits)?, Form::Mat)
}

/// The cameras of a stereo (`fc_left`, `fc_right`, ...) or mono (`fc`, ...) result.
pub fn parse_cameras(bytes: &[u8], limits: &Limits) -> Result<Vec<NamedCamera>> {
    let a = variables(bytes, limits)?;
    let named = |name: &str, model: CameraModel| NamedCamera {
        name: name.to_string(),
        model,
        extrinsics: None,
    };
    if calib_bouguet::stereo_suffix(&a) == "_left" {
        let left = calib_bouguet::camera(&a, "_left", Form::Mat)?;
        let right = calib_bouguet::camera(&a, "_right", Form::Mat)?;
        let right_from_left = calib_bouguet::stereo(&a, Form::Mat).ok();
        let mut right = named("right", right);
        right.extrinsics = right_from_left;
        Ok(vec![named("left", left), right])
    } else {
        Ok(vec![named("", calib_bouguet::camera(&a, "", Form::Mat)?)])
    }
}

/// The numeric variables of [`VARIABLES`] present in the file, in file order.
pub fn variables(bytes: &[u8], limits: &Limits) -> Result<Vec<Assignment>> {
    Limits::check_len(
        "MAT-file bytes",
        bytes.len() as u64,
        limits.max_object_bytes,
    )?;
    let e = header(bytes)?;
    let mut budget = limits.max_object_bytes;
    let mut out = Vec::new();
    let mut off = HEADER_LEN;
    while off < bytes.len() {
        let top = top_level(bytes, off, e, &mut budget)?;
        if let Some(el) = &top.matrix {
            // Inside an uncompressed element a position is a file offset; inside an inflated one
            // the element's own offset is the closest place in the file.
            let place = |rel: usize| off as u64 + if top.compressed { 0 } else { rel as u64 };
            let m = matrix(el, e, limits).map_err(|(rel, err)| {
                let hint = name_hint(el, e).map_or(String::new(), |n| format!("`{n}`: "));
                IngestError::invalid(format!("{hint}{err}")).at_offset(place(rel))
            })?;
            if VARIABLES.contains(&m.name.as_str()) {
                let values = decode(bytes, el, &m, e).map_err(|err| err.at_offset(off as u64))?;
                out.push(Assignment {
                    name: m.name,
                    values,
                    at: Place::Offset(off as u64),
                });
            }
        }
        off = top.next;
    }
    Ok(out)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Endian {
    Little,
    Big,
}

impl Endian {
    fn u16(self, b: &[u8], at: usize) -> Option<u16> {
        let x: [u8; 2] = b.get(at..at.checked_add(2)?)?.try_into().ok()?;
        Some(match self {
            Endian::Little => u16::from_le_bytes(x),
            Endian::Big => u16::from_be_bytes(x),
        })
    }
    fn u32(self, b: &[u8], at: usize) -> Option<u32> {
        let x: [u8; 4] = b.get(at..at.checked_add(4)?)?.try_into().ok()?;
        Some(match self {
            Endian::Little => u32::from_le_bytes(x),
            Endian::Big => u32::from_be_bytes(x),
        })
    }
    fn put_u32(self, b: &mut [u8], at: usize, v: u32) {
        let x = match self {
            Endian::Little => v.to_le_bytes(),
            Endian::Big => v.to_be_bytes(),
        };
        if let Some(dst) = b.get_mut(at..at + 4) {
            dst.copy_from_slice(&x);
        }
    }
}

/// The header: Level-5 text, version `0x0100`, endian indicator.
fn header(b: &[u8]) -> Result<Endian> {
    let Some(h) = b.get(..HEADER_LEN) else {
        return Err(IngestError::syntax(
            "a 128-byte MATLAB Level-5 header",
            &format!("{} bytes", b.len()),
        )
        .at_offset(0));
    };
    if h.starts_with(b"MATLAB 7.3") {
        return Err(IngestError::Unsupported(
            "MATLAB v7.3 (HDF5) MAT-file; save it with `save -v7` (Level 5)".into(),
        )
        .at_offset(0));
    }
    let e = match h.get(126..128) {
        Some(b"IM") => Endian::Little,
        Some(b"MI") => Endian::Big,
        _ => {
            return Err(IngestError::syntax(
                "a MATLAB Level-5 header (endian indicator `IM` or `MI` at byte 126)",
                &String::from_utf8_lossy(h.get(..20).unwrap_or(h)),
            )
            .at_offset(126))
        }
    };
    match e.u16(h, 124) {
        Some(0x0100) => Ok(e),
        Some(0x0200) => Err(IngestError::Unsupported(
            "MATLAB v7.3 (HDF5) MAT-file; save it with `save -v7` (Level 5)".into(),
        )
        .at_offset(124)),
        v => Err(IngestError::syntax(
            "MAT-file version 0x0100",
            &format!("{:#06x}", v.unwrap_or(0)),
        )
        .at_offset(124)),
    }
}

/// A data element tag: type, data size, where the data starts and where the next element
/// starts (after the padding to 8 bytes).
struct Tag {
    ty: u32,
    size: usize,
    data: usize,
    padded_end: usize,
}

/// Reads the tag at `at` (long or small format); an error if its 8 bytes are not there.
fn tag(b: &[u8], at: usize, e: Endian) -> std::result::Result<Tag, IngestError> {
    let first = e
        .u32(b, at)
        .ok_or_else(|| IngestError::syntax("an 8-byte data element tag", "the end of data"))?;
    if first >> 16 != 0 {
        let size = (first >> 16) as usize;
        if size > 4 {
            return Err(IngestError::syntax(
                "a small data element of at most 4 bytes",
                &format!("{size} bytes"),
            ));
        }
        return Ok(Tag {
            ty: first & 0xFFFF,
            size,
            data: at + 4,
            padded_end: at + 8,
        });
    }
    let size = e
        .u32(b, at + 4)
        .ok_or_else(|| IngestError::syntax("an 8-byte data element tag", "the end of data"))?
        as usize;
    let data = at + 8;
    Ok(Tag {
        ty: first,
        size,
        data,
        padded_end: data.saturating_add(size.div_ceil(8) * 8),
    })
}

/// One top-level element.
struct TopLevel {
    /// The uncompressed `miMATRIX` element (tag included); `None` for other element types,
    /// which are skipped.
    matrix: Option<Vec<u8>>,
    /// Whether it was `miCOMPRESSED`.
    compressed: bool,
    /// Offset of the next element.
    next: usize,
}

/// Reads the top-level element at `off`, inflating it if it is compressed.
fn top_level(b: &[u8], off: usize, e: Endian, budget: &mut u64) -> Result<TopLevel> {
    let t = tag(b, off, e).map_err(|err| err.at_offset(off as u64))?;
    let end = t.data.saturating_add(t.size);
    let compressed = t.ty == MI_COMPRESSED;
    if end > b.len() {
        let rest = b.get(t.data..).unwrap_or(&[]);
        let inner = if compressed {
            inflate(rest, *budget).unwrap_or_else(|(partial, _)| partial)
        } else {
            b.get(off..).unwrap_or(&[]).to_vec()
        };
        let what = name_hint(&inner, e).map_or("a variable".to_string(), |n| format!("`{n}`"));
        return Err(IngestError::invalid(format!(
            "the data element of {what} needs {} bytes but the file ends after {} (truncated file)",
            end - off,
            b.len() - off
        ))
        .at_offset(off as u64));
    }
    let (matrix, next) = match t.ty {
        MI_MATRIX => (b.get(off..end).map(<[u8]>::to_vec), t.padded_end),
        MI_COMPRESSED => {
            let inner =
                inflate(b.get(t.data..end).unwrap_or(&[]), *budget).map_err(|(partial, err)| {
                    let what = name_hint(&partial, e).map_or(String::new(), |n| format!("`{n}`: "));
                    IngestError::invalid(format!("{what}{err}")).at_offset(off as u64)
                })?;
            *budget = budget.saturating_sub(inner.len() as u64);
            let it = tag(&inner, 0, e).map_err(|err| err.at_offset(off as u64))?;
            if it.ty != MI_MATRIX || it.data.saturating_add(it.size) > inner.len() {
                return Err(IngestError::syntax(
                    "one whole miMATRIX element (type 14) inside the compressed element",
                    &format!(
                        "type {} of {} bytes in {} inflated bytes",
                        it.ty,
                        it.size,
                        inner.len()
                    ),
                )
                .at_offset(off as u64));
            }
            // Compressed elements are not padded.
            (Some(inner), end)
        }
        _ => (None, t.padded_end),
    };
    Ok(TopLevel {
        matrix,
        compressed,
        next,
    })
}

/// Inflates a zlib stream, at most `cap` bytes; on error, what was inflated so far.
fn inflate(z: &[u8], cap: u64) -> std::result::Result<Vec<u8>, (Vec<u8>, IngestError)> {
    let mut out = Vec::new();
    let mut r = flate2::read::ZlibDecoder::new(z).take(cap.saturating_add(1));
    if let Err(err) = r.read_to_end(&mut out) {
        return Err((
            out,
            IngestError::syntax("a complete zlib stream", &err.to_string()),
        ));
    }
    if out.len() as u64 > cap {
        let err = Limits::check_len("inflated MAT-file bytes", out.len() as u64, cap)
            .err()
            .map_or_else(
                || IngestError::invalid("inflated data too large"),
                Into::into,
            );
        return Err((out, err));
    }
    Ok(out)
}

/// The framing of one matrix element.
struct MatrixInfo {
    name: String,
    class: u32,
    complex: bool,
    dims: Vec<usize>,
    /// Offset of the flags word (to relabel `int32` as `double`).
    flags_at: usize,
}

/// The name of a (possibly partial) matrix element, if its name subelement is complete.
fn name_hint(el: &[u8], e: Endian) -> Option<String> {
    let t = tag(el, 0, e).ok()?;
    let flags = tag(el, t.data, e).ok()?;
    let dims = tag(el, flags.padded_end, e).ok()?;
    let name = tag(el, dims.padded_end, e).ok()?;
    let bytes = el.get(name.data..name.data.checked_add(name.size)?)?;
    std::str::from_utf8(bytes)
        .ok()
        .filter(|s| !s.is_empty())
        .map(str::to_string)
}

fn class_name(class: u32) -> &'static str {
    match class {
        1 => "a cell array",
        2 => "a struct",
        3 => "an object",
        4 => "a char array (text)",
        5 => "a sparse matrix",
        6..=15 => "numeric",
        _ => "of an unknown class",
    }
}

/// Checks the subelements of a matrix element; errors carry the position inside `el`.
fn matrix(
    el: &[u8],
    e: Endian,
    limits: &Limits,
) -> std::result::Result<MatrixInfo, (usize, IngestError)> {
    let t = tag(el, 0, e).map_err(|err| (0, err))?;
    let end = t.data.saturating_add(t.size).min(el.len());
    // Every subelement, with its padding, must end inside the element: `matfile` reads the
    // padding, and its size arithmetic overflows on lengths no real element can have.
    let sub = |at: usize, what: &str| -> std::result::Result<Tag, (usize, IngestError)> {
        let s = tag(el, at, e).map_err(|err| (at, err))?;
        if s.padded_end > end {
            return Err((
                at,
                IngestError::syntax(
                    format!("the {what} subelement to end inside its matrix element"),
                    &format!("{} bytes past its end", s.padded_end - end),
                ),
            ));
        }
        Ok(s)
    };
    let f = sub(t.data, "array flags")?;
    let flags = e.u32(el, f.data).unwrap_or(0);
    if f.ty != MI_UINT32 || f.size != 8 {
        return Err((
            t.data,
            IngestError::syntax(
                "an 8-byte miUINT32 array-flags subelement",
                &format!("type {}", f.ty),
            ),
        ));
    }
    let d = sub(f.padded_end, "dimensions")?;
    if d.ty != MI_INT32 || d.size < 8 || d.size % 4 != 0 {
        return Err((
            f.padded_end,
            IngestError::syntax(
                "an miINT32 dimensions subelement",
                &format!("type {}", d.ty),
            ),
        ));
    }
    let mut dims = Vec::new();
    let mut count: u64 = 1;
    for k in 0..d.size / 4 {
        let v = e.u32(el, d.data + 4 * k).unwrap_or(0) as i32;
        let v = usize::try_from(v).map_err(|_| {
            (
                d.data,
                IngestError::syntax("non-negative dimensions", &v.to_string()),
            )
        })?;
        count = count.saturating_mul(v as u64);
        dims.push(v);
    }
    // `matfile` multiplies the dimensions as `i32`.
    Limits::check_len(
        "MAT-file array elements",
        count,
        limits.max_points.min(i32::MAX as u64),
    )
    .map_err(|err| (d.data, err.into()))?;
    let n = sub(d.padded_end, "name")?;
    let name = el
        .get(n.data..n.data + n.size)
        .and_then(|b| std::str::from_utf8(b).ok())
        .filter(|s| n.ty == MI_INT8 && !s.is_empty())
        .ok_or_else(|| {
            (
                d.padded_end,
                IngestError::syntax("an miINT8 variable name", "none"),
            )
        })?
        .to_string();
    let class = flags & 0xFF;
    let complex = flags & 0x0800 != 0;
    if (6..=15).contains(&class) {
        let real = sub(n.padded_end, "real part")?;
        if complex {
            sub(real.padded_end, "imaginary part")?;
        }
    }
    Ok(MatrixInfo {
        name,
        class,
        complex,
        dims,
        flags_at: f.data,
    })
}

/// Decodes a checked numeric matrix with `matfile`; values come out row by row.
fn decode(file: &[u8], el: &[u8], m: &MatrixInfo, e: Endian) -> Result<Vec<f64>> {
    let name = &m.name;
    if !(6..=15).contains(&m.class) {
        return Err(IngestError::invalid(format!(
            "`{name}` is {}; expected a numeric (double) array",
            class_name(m.class)
        )));
    }
    if m.complex {
        return Err(IngestError::invalid(format!(
            "`{name}` is complex; expected a real array"
        )));
    }
    if m.dims.len() != 2 {
        return Err(IngestError::invalid(format!(
            "`{name}` has {} dimensions; expected a vector or a matrix",
            m.dims.len()
        )));
    }
    let mut one = file.get(..HEADER_LEN).unwrap_or(&[]).to_vec();
    let at = one.len();
    one.extend_from_slice(el);
    if m.class == MX_INT32 {
        let flags = e.u32(&one, at + m.flags_at).unwrap_or(0);
        e.put_u32(&mut one, at + m.flags_at, (flags & !0xFF) | MX_DOUBLE);
    }
    let decoded = matfile::MatFile::parse(one.as_slice()).map_err(|err| {
        IngestError::invalid(format!(
            "`{name}`: matfile could not decode the array ({err})"
        ))
    })?;
    let Some(array) = decoded.find_by_name(name) else {
        return Err(IngestError::invalid(format!(
            "`{name}`: matfile could not decode the array"
        )));
    };
    let column_major = real_values(array.data());
    let (rows, cols) = match array.size().as_slice() {
        [r, c] => (*r, *c),
        _ => (column_major.len(), 1),
    };
    let mut out = Vec::new();
    for i in 0..rows {
        for j in 0..cols {
            out.push(column_major.get(i + j * rows).copied().unwrap_or(f64::NAN));
        }
    }
    Ok(out)
}

fn real_values(d: &matfile::NumericData) -> Vec<f64> {
    use matfile::NumericData as N;
    match d {
        N::Int8 { real, .. } => real.iter().map(|&v| f64::from(v)).collect(),
        N::UInt8 { real, .. } => real.iter().map(|&v| f64::from(v)).collect(),
        N::Int16 { real, .. } => real.iter().map(|&v| f64::from(v)).collect(),
        N::UInt16 { real, .. } => real.iter().map(|&v| f64::from(v)).collect(),
        N::Int32 { real, .. } => real.iter().map(|&v| f64::from(v)).collect(),
        N::UInt32 { real, .. } => real.iter().map(|&v| f64::from(v)).collect(),
        N::Int64 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::UInt64 { real, .. } => real.iter().map(|&v| v as f64).collect(),
        N::Single { real, .. } => real.iter().map(|&v| f64::from(v)).collect(),
        N::Double { real, .. } => real.clone(),
    }
}
