//! RiSCAN PRO ASCII point-cloud exports (`.asc`, `.txt`, `.xyz`, `.csv`), plus the small text
//! helpers (line iteration, field splitting, fast number scanning) that the other text readers
//! of laser-scan data (`sop_dat`, `tiepoints`, `ptx`) share.
//!
//! RiSCAN lets the user choose columns, delimiter and header (formats.md §1.4), so the reader
//! works out the layout instead of assuming one:
//! - The column list comes from the caller (`campaign.toml`, e.g. `"x y z reflectance"`), else
//!   from a header line (`X[m] Y[m] Z[m] Reflectance[dB]`, `XYZ[0][m],XYZ[1][m],...`), else a
//!   3-field file is `x y z`. Anything else is an error: we do not guess what a 4th column means.
//! - The header and the data delimiter are sniffed separately (RIEGL writes comma headers above
//!   space-separated rows). The data delimiter is fixed by the first data row; a row that uses
//!   another one fails with its line number instead of being mis-split. Comma decimals therefore
//!   fail too, which is what we want (formats.md §1.4 rule 6).
//! - A leading lone integer (3DTK `riegl_txt`) is a point count and is checked.
//!
//! Speed: exports reach gigabytes, so the data part is cut into ~8 MB chunks at newline
//! boundaries and parsed with rayon's indexed `par_iter`, which keeps the output order (and so
//! the result) independent of the thread count. Each chunk counts its lines so error line
//! numbers stay exact. Numbers go through a hand-written scanner that handles plain decimals
//! exactly (Clinger's fast path: a ≤ 2^53 mantissa and a power of ten ≤ 10^22 are both exact
//! in `f64`) and falls back to `f64::from_str` for everything else, so results are always
//! correctly rounded.

use std::fmt::Write as _;
use std::path::Path;

use memchr::memchr;
use rayon::prelude::*;
use regolith_format::limits::Limits;

use super::types::PointCloud;
use crate::error::{IngestError, Result};

/// Target chunk size for parallel parsing.
const CHUNK_BYTES: usize = 8 << 20;

/// What one column of an ASCII export holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Column {
    /// X coordinate, metres.
    X,
    /// Y coordinate, metres.
    Y,
    /// Z coordinate, metres.
    Z,
    /// RIEGL reflectance, dB (signed).
    Reflectance,
    /// Intensity or amplitude as stored.
    Intensity,
    /// Red channel (0..255, or 0..1 when the unit says `[0..1]`).
    Red,
    /// Green channel.
    Green,
    /// Blue channel.
    Blue,
    /// A column regolith does not use (ID, range, angles, timestamps, ...).
    Skip,
}

impl Column {
    /// Maps a column name such as `X[m]`, `XYZ[1][m]`, `Reflectance[dB]` or `r` to a role.
    /// Returns the role and whether the unit is the normalised `0..1`.
    pub fn from_name(token: &str) -> (Column, bool) {
        let lower = token.trim().trim_matches('"').to_ascii_lowercase();
        if let Some(rest) = lower.strip_prefix("xyz[") {
            let axis = match rest.split_once(']').map(|(a, _)| a.trim()) {
                Some("0") => Column::X,
                Some("1") => Column::Y,
                Some("2") => Column::Z,
                _ => Column::Skip,
            };
            return (axis, false);
        }
        let (name, unit) = match lower.split_once('[') {
            Some((name, unit)) => (name.trim(), unit.trim_end_matches(']')),
            None => (lower.as_str(), ""),
        };
        let role = match name {
            "x" => Column::X,
            "y" => Column::Y,
            "z" => Column::Z,
            "reflectance" => Column::Reflectance,
            "intensity" | "i" => Column::Intensity,
            "r" | "red" => Column::Red,
            "g" | "green" => Column::Green,
            "b" | "blue" => Column::Blue,
            _ => Column::Skip,
        };
        (role, unit == "0..1")
    }

    fn label(self) -> &'static str {
        match self {
            Column::X => "X[m]",
            Column::Y => "Y[m]",
            Column::Z => "Z[m]",
            Column::Reflectance => "Reflectance[dB]",
            Column::Intensity => "Intensity[]",
            Column::Red => "R[]",
            Column::Green => "G[]",
            Column::Blue => "B[]",
            Column::Skip => "-",
        }
    }
}

/// The resolved column layout of one file.
#[derive(Debug, Clone)]
struct Layout {
    roles: Vec<Column>,
    /// Colour values are 0..1 and must be scaled by 255.
    color_unit: bool,
    has_refl: bool,
    has_int: bool,
    has_rgb: bool,
    delim: Delim,
}

impl Layout {
    fn from_names<'a>(names: impl Iterator<Item = &'a str>) -> Result<Layout> {
        let mut roles = Vec::new();
        let mut color_unit = false;
        for name in names {
            let (role, unit) = Column::from_name(name);
            if role != Column::Skip && roles.contains(&role) {
                return Err(IngestError::syntax("each column name at most once", name));
            }
            color_unit |= unit && matches!(role, Column::Red | Column::Green | Column::Blue);
            roles.push(role);
        }
        let has = |c: Column| roles.contains(&c);
        for axis in [Column::X, Column::Y, Column::Z] {
            if !has(axis) {
                let names = roles
                    .iter()
                    .map(|r| r.label())
                    .collect::<Vec<_>>()
                    .join(" ");
                return Err(IngestError::syntax(
                    format!("columns naming X, Y and Z (no {})", axis.label()),
                    &names,
                ));
            }
        }
        let rgb = [has(Column::Red), has(Column::Green), has(Column::Blue)];
        if rgb.iter().any(|&c| c) && !rgb.iter().all(|&c| c) {
            return Err(IngestError::invalid(
                "expected all three colour columns R, G and B",
            ));
        }
        let has_refl = has(Column::Reflectance);
        Ok(Layout {
            has_int: has(Column::Intensity) && !has_refl,
            has_refl,
            has_rgb: rgb[0],
            color_unit,
            roles,
            delim: Delim::Whitespace,
        })
    }
}

/// Field delimiter of a text table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delim {
    /// Runs of spaces and tabs.
    Whitespace,
    /// One byte (`,` `;` or tab); spaces around fields are trimmed.
    Byte(u8),
}

impl Delim {
    /// Picks the delimiter a line uses: `,`, then `;`, then tab, else whitespace.
    pub(crate) fn sniff(line: &[u8]) -> Delim {
        for d in [b',', b';', b'\t'] {
            if memchr(d, line).is_some() {
                return Delim::Byte(d);
            }
        }
        Delim::Whitespace
    }

    /// Picks among `order` only (for tables whose names may contain spaces).
    pub(crate) fn sniff_among(line: &[u8], order: &[u8]) -> Option<Delim> {
        order
            .iter()
            .find(|&&d| memchr(d, line).is_some())
            .map(|&d| Delim::Byte(d))
    }

    /// How the delimiter reads in messages: `','`, `tabs`, `whitespace`.
    pub(crate) fn describe(self) -> String {
        match self {
            Delim::Whitespace => "whitespace".into(),
            Delim::Byte(b'\t') => "tabs".into(),
            Delim::Byte(d) => format!("'{}'", char::from(d)),
        }
    }
}

fn is_ws(b: u8) -> bool {
    b == b' ' || b == b'\t'
}

fn trim_ws(mut s: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = s {
        if !is_ws(*first) {
            break;
        }
        s = rest;
    }
    while let [rest @ .., last] = s {
        if !is_ws(*last) {
            break;
        }
        s = rest;
    }
    s
}

/// Iterator over the fields of one line.
pub(crate) struct Fields<'a> {
    rest: Option<&'a [u8]>,
    delim: Delim,
}

/// Splits a line (without its end-of-line bytes) into fields.
pub(crate) fn fields(line: &[u8], delim: Delim) -> Fields<'_> {
    let line = match delim {
        Delim::Whitespace => line,
        Delim::Byte(_) => trim_ws(line),
    };
    Fields {
        rest: if line.is_empty() { None } else { Some(line) },
        delim,
    }
}

impl<'a> Iterator for Fields<'a> {
    type Item = &'a [u8];
    fn next(&mut self) -> Option<&'a [u8]> {
        let rest = self.rest?;
        match self.delim {
            Delim::Whitespace => {
                let start = rest.iter().position(|&b| !is_ws(b))?;
                let tail = rest.get(start..)?;
                let end = tail.iter().position(|&b| is_ws(b)).unwrap_or(tail.len());
                self.rest = tail.get(end..);
                tail.get(..end)
            }
            Delim::Byte(d) => match memchr(d, rest) {
                Some(i) => {
                    self.rest = rest.get(i + 1..);
                    rest.get(..i).map(trim_ws)
                }
                None => {
                    self.rest = None;
                    Some(trim_ws(rest))
                }
            },
        }
    }
}

#[derive(Clone)]
/// Iterator over lines: `(1-based line number, byte offset, content without "\n" / "\r\n")`.
pub(crate) struct Lines<'a> {
    rest: &'a [u8],
    line: u64,
    offset: usize,
}

/// Iterates over the lines of `bytes`.
pub(crate) fn lines(bytes: &[u8]) -> Lines<'_> {
    Lines {
        rest: bytes,
        line: 0,
        offset: 0,
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (u64, usize, &'a [u8]);
    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() {
            return None;
        }
        let (line, consumed) = match memchr(b'\n', self.rest) {
            Some(i) => (self.rest.get(..i)?, i + 1),
            None => (self.rest, self.rest.len()),
        };
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        let start = self.offset;
        self.rest = self.rest.get(consumed..).unwrap_or_default();
        self.offset += consumed;
        self.line += 1;
        Some((self.line, start, line))
    }
}

/// True for lines with nothing but whitespace.
pub(crate) fn is_blank(line: &[u8]) -> bool {
    line.iter().all(|&b| is_ws(b))
}

/// Lossy text of a field for error messages.
pub(crate) fn show(field: &[u8]) -> String {
    String::from_utf8_lossy(field).into_owned()
}

const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Exact decimal fast path; `None` means "let `f64::from_str` decide".
fn parse_fast(s: &[u8]) -> Option<f64> {
    let (neg, s) = match s.first() {
        Some(b'-') => (true, s.get(1..)?),
        Some(b'+') => (false, s.get(1..)?),
        _ => (false, s),
    };
    let (mut mant, mut digits, mut exp, mut i) = (0u64, 0u32, 0i32, 0usize);
    let mut seen_dot = false;
    while let Some(&c) = s.get(i) {
        let d = c.wrapping_sub(b'0');
        if d <= 9 {
            if digits == 19 {
                return None;
            }
            mant = mant * 10 + u64::from(d);
            digits += 1;
            exp -= i32::from(seen_dot);
        } else if c == b'.' && !seen_dot {
            seen_dot = true;
        } else {
            break;
        }
        i += 1;
    }
    if digits == 0 {
        return None;
    }
    if let Some(b'e' | b'E') = s.get(i) {
        i += 1;
        let eneg = match s.get(i) {
            Some(b'-') => {
                i += 1;
                true
            }
            Some(b'+') => {
                i += 1;
                false
            }
            _ => false,
        };
        let (mut e, start) = (0i32, i);
        while let Some(d) = s.get(i).map(|c| c.wrapping_sub(b'0')).filter(|&d| d <= 9) {
            e = e.checked_mul(10)?.checked_add(i32::from(d))?;
            i += 1;
        }
        if i == start || e > 1000 {
            return None;
        }
        exp += if eneg { -e } else { e };
    }
    if i != s.len() || mant > (1u64 << 53) {
        return None;
    }
    let m = mant as f64;
    let v = if exp >= 0 {
        m * *POW10.get(usize::try_from(exp).ok()?)?
    } else {
        m / *POW10.get(usize::try_from(-exp).ok()?)?
    };
    Some(if neg { -v } else { v })
}

/// Parses a decimal number (correctly rounded); `None` if the field is not a number.
pub(crate) fn parse_f64(field: &[u8]) -> Option<f64> {
    parse_fast(field).or_else(|| std::str::from_utf8(field).ok()?.parse::<f64>().ok())
}

/// Parses a finite number, or says what was expected.
pub(crate) fn number(field: &[u8], what: &str) -> Result<f64> {
    match parse_f64(field) {
        Some(v) if v.is_finite() => Ok(v),
        Some(_) => Err(IngestError::syntax(
            format!("a finite number for {what}"),
            &show(field),
        )),
        None => Err(IngestError::syntax(
            format!("a number for {what}"),
            &show(field),
        )),
    }
}

/// Converts a colour value (0..255, or 0..1 scaled by 255) to a byte; `what` names the field.
pub(crate) fn color_byte(v: f64, unit_interval: bool, what: impl FnOnce() -> String) -> Result<u8> {
    let scaled = if unit_interval { v * 255.0 } else { v };
    if !(-0.5..255.5).contains(&scaled) {
        let range = if unit_interval { "0..1" } else { "0..255" };
        return Err(IngestError::invalid(format!(
            "{} is {v}, expected a value in {range}",
            what()
        )));
    }
    Ok(scaled.round().clamp(0.0, 255.0) as u8)
}

/// Parsed columns of one chunk.
#[derive(Default)]
struct Chunk {
    points: Vec<[f64; 3]>,
    refl: Vec<f32>,
    int: Vec<f32>,
    rgb: Vec<[u8; 3]>,
    lines: u64,
}

fn parse_row(line: &[u8], layout: &Layout, out: &mut Chunk) -> Result<()> {
    let line = match layout.delim {
        Delim::Byte(d) => trim_ws(line).strip_suffix(&[d]).unwrap_or(line),
        Delim::Whitespace => line,
    };
    let (mut p, mut refl, mut int, mut rgb) = ([0.0f64; 3], 0.0, 0.0, [0u8; 3]);
    let mut n = 0usize;
    for field in fields(line, layout.delim) {
        n += 1;
        let role = match layout.roles.get(n - 1) {
            Some(Column::Skip) => continue,
            Some(role) => *role,
            None => break,
        };
        let what = || {
            format!(
                "{} in field {n} (fields separated by {})",
                role.label(),
                layout.delim.describe()
            )
        };
        let v = parse_f64(field).filter(|v| v.is_finite()).ok_or_else(|| {
            IngestError::syntax(format!("a finite number for {}", what()), &show(field))
        })?;
        match role {
            Column::X => p[0] = v,
            Column::Y => p[1] = v,
            Column::Z => p[2] = v,
            Column::Reflectance => refl = v as f32,
            Column::Intensity => int = v as f32,
            Column::Red => rgb[0] = color_byte(v, layout.color_unit, what)?,
            Column::Green => rgb[1] = color_byte(v, layout.color_unit, what)?,
            Column::Blue => rgb[2] = color_byte(v, layout.color_unit, what)?,
            Column::Skip => {}
        }
    }
    if n != layout.roles.len() {
        let n = fields(line, layout.delim).count();
        return Err(IngestError::syntax(
            format!(
                "{} fields separated by {}",
                layout.roles.len(),
                layout.delim.describe()
            ),
            &format!("{n} fields: {}", show(line)),
        ));
    }
    out.points.push(p);
    if layout.has_refl {
        out.refl.push(refl);
    }
    if layout.has_int {
        out.int.push(int);
    }
    if layout.has_rgb {
        out.rgb.push(rgb);
    }
    Ok(())
}

/// Parses one chunk; errors carry the chunk-local line number.
fn parse_chunk(chunk: &[u8], layout: &Layout) -> std::result::Result<Chunk, (u64, IngestError)> {
    let mut out = Chunk::default();
    for (line_no, _, line) in lines(chunk) {
        out.lines = line_no;
        if is_blank(line) || line.first() == Some(&b'#') {
            continue;
        }
        parse_row(line, layout, &mut out).map_err(|e| (line_no, e))?;
    }
    Ok(out)
}

/// Cuts `data` into chunks of about [`CHUNK_BYTES`] that end after a newline.
fn split_chunks(data: &[u8]) -> Vec<&[u8]> {
    let mut chunks = Vec::new();
    let mut rest = data;
    while rest.len() > CHUNK_BYTES {
        let cut = rest
            .get(CHUNK_BYTES..)
            .and_then(|t| memchr(b'\n', t))
            .map(|i| CHUNK_BYTES + i + 1);
        match cut.and_then(|c| Some((rest.get(..c)?, rest.get(c..)?))) {
            Some((head, tail)) => {
                chunks.push(head);
                rest = tail;
            }
            None => break,
        }
    }
    if !rest.is_empty() {
        chunks.push(rest);
    }
    chunks
}

/// Reads a RiSCAN ASCII export. `columns` (e.g. `"x y z reflectance"`) overrides the header.
pub fn read_ascii(bytes: &[u8], columns: Option<&str>, limits: &Limits) -> Result<PointCloud> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut it = lines(bytes).filter(|(_, _, l)| !is_blank(l));
    let Some((mut line_no, mut offset, mut first)) = it.next() else {
        return Err(IngestError::syntax(
            "a header or a point line",
            "end of file",
        ));
    };
    let mut expected_count = None;
    let mut header = None;
    let mut tokens = fields(first, Delim::Whitespace);
    if let (Some(tok), None) = (tokens.next(), tokens.next()) {
        if let Some(n) = show(tok)
            .parse::<u64>()
            .ok()
            .filter(|_| it.clone().next().is_some())
        {
            expected_count = Some((line_no, n));
            (line_no, offset, first) = it.next().unwrap_or((line_no, offset, first));
        }
    }
    let first_tok = fields(first, Delim::sniff(first))
        .next()
        .unwrap_or_default();
    if parse_f64(first_tok).is_none() {
        header = Some((line_no, first));
        match it.next() {
            Some(next) => (line_no, offset, first) = next,
            None => offset = bytes.len(),
        }
    }
    // A data row containing the header's delimiter uses it (`1,5;2,0` is `;` with comma decimals).
    let delim = match header.map(|(_, h)| Delim::sniff(h)) {
        Some(Delim::Byte(d)) if memchr(d, first).is_some() => Delim::Byte(d),
        _ => Delim::sniff(first),
    };
    let mut layout = match (columns, header) {
        (Some(spec), header) => {
            let names = spec
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty());
            let layout = Layout::from_names(names)?;
            if let Some((hl, h)) = header {
                let n = fields(h, Delim::sniff(h)).count();
                if n != layout.roles.len() {
                    return Err(IngestError::syntax(
                        format!(
                            "a header with {} columns as declared ({spec})",
                            layout.roles.len()
                        ),
                        &show(h),
                    )
                    .at_line(hl));
                }
            }
            layout
        }
        (None, Some((hl, h))) => {
            let names: Vec<String> = fields(h, Delim::sniff(h)).map(show).collect();
            Layout::from_names(names.iter().map(String::as_str)).map_err(|e| e.at_line(hl))?
        }
        (None, None) if fields(first, delim).count() == 3 => {
            Layout::from_names(["x", "y", "z"].into_iter())?
        }
        (None, None) => {
            return Err(IngestError::syntax(
                "a header line naming the columns, or a column list in campaign.toml",
                &show(first),
            )
            .at_line(line_no))
        }
    };
    layout.delim = delim;
    let data = bytes.get(offset..).unwrap_or_default();
    let chunks: Vec<_> = split_chunks(data)
        .into_par_iter()
        .map(|c| parse_chunk(c, &layout))
        .collect();
    let mut base = line_no - 1;
    let mut total = 0u64;
    let mut parsed = Vec::new();
    for chunk in chunks {
        let chunk = chunk.map_err(|(l, e)| e.at_line(base + l))?;
        base += chunk.lines;
        total += chunk.points.len() as u64;
        Limits::check_len("points", total, limits.max_points)?;
        parsed.push(chunk);
    }
    if let Some((l, n)) = expected_count.filter(|&(_, n)| n != total) {
        return Err(IngestError::invalid(format!(
            "the count line says {n} points, the file has {total}"
        ))
        .at_line(l));
    }
    let mut cloud = PointCloud {
        points: limits.vec_with_capacity("points", total)?,
        ..Default::default()
    };
    let (mut refl, mut int, mut rgb) = (Vec::new(), Vec::new(), Vec::new());
    for c in parsed {
        cloud.points.extend_from_slice(&c.points);
        refl.extend_from_slice(&c.refl);
        int.extend_from_slice(&c.int);
        rgb.extend_from_slice(&c.rgb);
    }
    cloud.reflectance_db = layout.has_refl.then_some(refl);
    cloud.intensity = layout.has_int.then_some(int);
    cloud.rgb = layout.has_rgb.then_some(rgb);
    Ok(cloud)
}

/// Reads a RiSCAN ASCII export from a file; errors name the path.
pub fn read_path(path: &Path, columns: Option<&str>, limits: &Limits) -> Result<PointCloud> {
    let bytes = read_file(path, limits)?;
    read_ascii(&bytes, columns, limits).map_err(|e| e.in_file(path))
}

/// Reads a whole file after checking its size against `limits.max_object_bytes`.
pub(crate) fn read_file(path: &Path, limits: &Limits) -> Result<Vec<u8>> {
    let wrap = |e: std::io::Error| IngestError::from(e).in_file(path);
    let len = std::fs::metadata(path).map_err(wrap)?.len();
    Limits::check_len("file bytes", len, limits.max_object_bytes)
        .map_err(|e| IngestError::from(e).in_file(path))?;
    std::fs::read(path).map_err(wrap)
}

/// Writes `cloud` as a space-separated export with a RiSCAN-style header, for the columns in
/// `columns` (same names as [`read_ascii`] accepts). Numbers use Rust's shortest round-trip form.
pub fn write_ascii(cloud: &PointCloud, columns: &str) -> Result<String> {
    let layout = Layout::from_names(columns.split_whitespace())?;
    let n = cloud.points.len();
    let need = |v: Option<usize>, what: &str| match v {
        Some(len) if len == n => Ok(()),
        _ => Err(IngestError::invalid(format!(
            "cannot write {what}: the cloud has no such values per point"
        ))),
    };
    let mut header = Vec::new();
    for role in &layout.roles {
        match role {
            Column::Skip => {
                return Err(IngestError::syntax("a column regolith can write", columns))
            }
            Column::Reflectance => {
                need(cloud.reflectance_db.as_ref().map(Vec::len), "reflectance")?
            }
            Column::Intensity => need(cloud.intensity.as_ref().map(Vec::len), "intensity")?,
            Column::Red | Column::Green | Column::Blue => {
                need(cloud.rgb.as_ref().map(Vec::len), "colour")?
            }
            _ => {}
        }
        header.push(role.label());
    }
    let mut s = header.join(" ");
    s.push('\n');
    for (i, p) in cloud.points.iter().enumerate() {
        for (k, role) in layout.roles.iter().enumerate() {
            let sep = if k == 0 { "" } else { " " };
            let rgb = cloud
                .rgb
                .as_ref()
                .and_then(|c| c.get(i))
                .copied()
                .unwrap_or_default();
            let scalar = |v: &Option<Vec<f32>>| {
                v.as_ref()
                    .and_then(|v| v.get(i))
                    .copied()
                    .unwrap_or_default()
            };
            let _ = match role {
                Column::X => write!(s, "{sep}{}", p[0]),
                Column::Y => write!(s, "{sep}{}", p[1]),
                Column::Z => write!(s, "{sep}{}", p[2]),
                Column::Reflectance => write!(s, "{sep}{}", scalar(&cloud.reflectance_db)),
                Column::Intensity => write!(s, "{sep}{}", scalar(&cloud.intensity)),
                Column::Red => write!(s, "{sep}{}", rgb[0]),
                Column::Green => write!(s, "{sep}{}", rgb[1]),
                Column::Blue => write!(s, "{sep}{}", rgb[2]),
                Column::Skip => Ok(()),
            };
        }
        s.push('\n');
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_path_matches_std() {
        for s in [
            "0",
            "-0.5",
            "12.345678",
            "1e5",
            "-3.1470172510255578",
            "4.7632160018149184E-005",
            "515632.66332186362",
            "0.1",
            "123456789012345678",
            "9007199254740993",
            ".5",
            "5.",
            "1e-22",
        ] {
            let want: f64 = s.parse().unwrap();
            assert_eq!(
                parse_f64(s.as_bytes()).unwrap().to_bits(),
                want.to_bits(),
                "{s}"
            );
        }
        for s in ["", "-", ".", "1.2.3", "1e", "abc", "1,5", "0x10"] {
            assert!(parse_f64(s.as_bytes()).is_none(), "{s}");
        }
    }

    #[test]
    fn column_names_from_real_headers() {
        assert_eq!(Column::from_name("XYZ[1][m]"), (Column::Y, false));
        assert_eq!(
            Column::from_name("Reflectance[dB]"),
            (Column::Reflectance, false)
        );
        assert_eq!(Column::from_name("R[0..1]"), (Column::Red, true));
        assert_eq!(Column::from_name("Amplitude[dB]"), (Column::Skip, false));
        assert_eq!(Column::from_name("Target Index[]"), (Column::Skip, false));
    }

    #[test]
    fn chunks_end_at_newlines_and_cover_everything() {
        let data: Vec<u8> = (0..CHUNK_BYTES / 5)
            .flat_map(|i| format!("{i} 1 2\n").into_bytes())
            .collect();
        let chunks = split_chunks(&data);
        assert!(chunks.len() > 1);
        assert!(chunks.iter().all(|c| c.ends_with(b"\n")));
        assert_eq!(chunks.concat(), data);
    }
}
