//! Tie-point / control-point tables: `Name,X,Y,Z` per line (formats.md §1.5).
//!
//! No public sample of RiSCAN's TPL text export exists, so the reader accepts the generic
//! shape users produce: an optional header line, `,` `;` or tab as the delimiter (sniffed from
//! the first line, in that order of preference after tab), and names that may contain spaces.
//! Only when a file has none of those delimiters is it read as a whitespace table, where names
//! cannot contain spaces. Extra columns after Z (σx σy σz, reflectivity) are ignored.
//!
//! Names identify points across scan positions, so a repeated name is an error (naming both
//! lines) rather than a silent overwrite.

use std::collections::BTreeMap;
use std::path::Path;

use regolith_format::limits::Limits;

use super::riscan_ascii::{fields, is_blank, lines, number, parse_f64, read_file, show, Delim};
use super::types::NamedPoint;
use crate::error::{IngestError, Result};

/// One data row of a `Name, v1, v2, …` table.
pub(crate) struct NamedRow<'a> {
    /// 1-based line number.
    pub line_no: u64,
    /// The table's delimiter.
    pub delim: Delim,
    /// The whole line.
    pub line: &'a [u8],
    /// Field 1, quotes and surrounding spaces trimmed.
    pub name: String,
    /// The fields after the name, at most the `max_values` asked for.
    pub values: Vec<&'a [u8]>,
}

/// The data rows of a named-point table (tie points, control points): blank and `#` lines
/// skipped, the delimiter sniffed from the first row (tab, `;`, `,`, else whitespace), a first
/// row whose second field is not a number skipped as a header. `bytes` without a UTF-8 BOM.
pub(crate) fn named_rows(bytes: &[u8], max_values: usize) -> impl Iterator<Item = NamedRow<'_>> {
    let mut delim = None;
    let mut first_row = true;
    lines(bytes).filter_map(move |(line_no, _, line)| {
        if is_blank(line) || line.first() == Some(&b'#') {
            return None;
        }
        let d = *delim
            .get_or_insert_with(|| Delim::sniff_among(line, b"\t;,").unwrap_or(Delim::Whitespace));
        let mut f = fields(line, d);
        let name = show(f.next().unwrap_or_default())
            .trim_matches('"')
            .trim()
            .to_string();
        let values: Vec<&[u8]> = f.take(max_values).collect();
        let is_header = first_row && values.first().is_some_and(|c| parse_f64(c).is_none());
        first_row = false;
        (!is_header).then_some(NamedRow {
            line_no,
            delim: d,
            line,
            name,
            values,
        })
    })
}

/// Reads a tie-point table.
pub fn read_tiepoints(bytes: &[u8], limits: &Limits) -> Result<Vec<NamedPoint>> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut out = Vec::new();
    let mut seen: BTreeMap<String, u64> = BTreeMap::new();
    for row in named_rows(bytes, 3) {
        let NamedRow {
            line_no,
            delim: d,
            line,
            name,
            values: coords,
        } = row;
        let err_at = |e: IngestError| e.at_line(line_no);
        if coords.len() != 3 {
            let found = format!("{} fields: {}", coords.len() + 1, show(line));
            return Err(err_at(IngestError::syntax(
                format!("4 fields Name, X, Y, Z separated by {}", d.describe()),
                &found,
            )));
        }
        if name.is_empty() {
            return Err(err_at(IngestError::syntax(
                "a tie-point name in field 1",
                &show(line),
            )));
        }
        let mut xyz = [0.0; 3];
        for (slot, (field, axis)) in xyz.iter_mut().zip(coords.iter().zip(["X", "Y", "Z"])) {
            *slot = number(field, &format!("{axis} of tie point {name:?}")).map_err(err_at)?;
        }
        if let Some(first) = seen.insert(name.clone(), line_no) {
            return Err(err_at(IngestError::invalid(format!(
                "duplicate tie-point name {name:?} (first on line {first})"
            ))));
        }
        Limits::check_len("tie points", out.len() as u64 + 1, limits.max_points)?;
        out.push(NamedPoint { name, xyz });
    }
    if out.is_empty() {
        return Err(IngestError::invalid(format!(
            "{}: expected at least one tie-point row `Name,X,Y,Z` (a reflector centre in the \
             scanner's own coordinates, metres, named as its ground marker); fill it from the \
             scan position's tie-point list (RiSCAN PRO: TPL export), or register the scan \
             with `sop = \"<file>.DAT\"` instead",
            if bytes.is_empty() {
                "the file is empty"
            } else {
                "the file has no data rows"
            },
        ))
        .at_line(1));
    }
    Ok(out)
}

/// Reads a tie-point table from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Vec<NamedPoint>> {
    let bytes = read_file(path, limits)?;
    read_tiepoints(&bytes, limits).map_err(|e| e.in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_with_spaces_and_semicolons() {
        let t = b"Name;X;Y;Z\r\nGSE Flat 1;-16.0027;-7.79145;11.4307\r\ntp002;1;2;3\r\n";
        let pts = read_tiepoints(t, &Limits::default()).unwrap();
        assert_eq!(pts.len(), 2);
        assert_eq!(pts[0].name, "GSE Flat 1");
        assert_eq!(pts[0].xyz, [-16.0027, -7.79145, 11.4307]);
    }
}
