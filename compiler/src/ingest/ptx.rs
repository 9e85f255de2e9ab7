//! PTX (Leica Cyclone, Faro Scene, Trimble RealWorks): one or more structured scans
//! concatenated in one text file (formats.md §2).
//!
//! Each scan is a 10-line header (columns, rows, scanner position, three axis lines, a 4x4
//! matrix for row vectors with the translation in the 4th row) followed by exactly
//! `columns*rows` point lines `x y z intensity [r g b]`; that count is the only way to find the
//! next scan, so it is enforced. Design decisions:
//! - The matrix goes through [`super::sop_dat::detect_convention`] like every other matrix, and
//!   is returned in column-vector form as the scan's `pose`; points stay in the scanner frame.
//!   A matrix without translation whose rotation is not symmetric is ambiguous in general;
//!   PTX resolves it because its rotation rows must equal the axis lines, so only then do we
//!   take the row-vector reading. A matrix that fits neither form is an error, never identity.
//! - Missing returns (`0 0 0 0.5`, `0 0 0 0`, with or without colour) keep the grid complete in
//!   the file; here they are dropped, since a return at exactly the scanner origin is impossible.
//! - The field count (4 or 7) is decided per scan by its first point line (it may differ
//!   between scans), and blank lines anywhere are skipped, as PDAL does.

use std::path::Path;

use regolith_format::limits::Limits;

use super::riscan_ascii::{
    color_byte, fields, is_blank, lines, number, read_file, show, Delim, Lines,
};
use super::sop_dat::{detect_convention, matrix_from_numbers, transpose};
use super::types::{Matrix4, PointCloud};
use crate::error::{IngestError, Result};

struct Cursor<'a> {
    it: Lines<'a>,
    last_line: u64,
    len: usize,
}

impl<'a> Cursor<'a> {
    /// Next non-blank line, or an error saying what was expected at end of file.
    fn next(&mut self, expected: &str) -> Result<(u64, usize, &'a [u8])> {
        match self.it.by_ref().find(|l| !is_blank(l.2)) {
            Some(l) => {
                self.last_line = l.0;
                Ok(l)
            }
            None => {
                Err(IngestError::syntax(expected, "end of file").at_line(self.last_line.max(1)))
            }
        }
    }

    /// True when only blank lines remain.
    fn at_end(&self) -> bool {
        self.it.clone().all(|l| is_blank(l.2))
    }

    /// A line of exactly `n` numbers.
    fn numbers(&mut self, n: usize, what: &str) -> Result<(u64, Vec<f64>)> {
        let (line_no, _, line) = self.next(what)?;
        let values = fields(line, Delim::Whitespace)
            .map(|f| number(f, what))
            .collect::<Result<Vec<f64>>>()
            .map_err(|e| e.at_line(line_no))?;
        if values.len() != n {
            let found = format!("{} fields: {}", values.len(), show(line));
            return Err(
                IngestError::syntax(format!("{n} numbers ({what})"), &found).at_line(line_no)
            );
        }
        Ok((line_no, values))
    }

    /// A line holding one non-negative integer.
    fn count(&mut self, what: &str) -> Result<u64> {
        let (line_no, _, line) = self.next(what)?;
        let mut f = fields(line, Delim::Whitespace);
        match (f.next().and_then(|t| show(t).parse::<u64>().ok()), f.next()) {
            (Some(n), None) => Ok(n),
            _ => Err(
                IngestError::syntax(format!("an integer ({what})"), &show(line)).at_line(line_no),
            ),
        }
    }
}

/// Reads every scan of a PTX file.
pub fn read_ptx(bytes: &[u8], limits: &Limits) -> Result<Vec<PointCloud>> {
    let mut cur = Cursor {
        it: lines(bytes),
        last_line: 0,
        len: bytes.len(),
    };
    let mut scans = Vec::new();
    let mut total = 0u64;
    while !cur.at_end() {
        let scan = scans.len() + 1;
        let cols = cur.count(&format!("number of columns of scan {scan}"))?;
        let rows = cur.count(&format!("number of rows of scan {scan}"))?;
        let n = cols.saturating_mul(rows);
        Limits::check_len("PTX points (columns x rows)", n, limits.max_points)
            .map_err(|e| IngestError::from(e).at_line(cur.last_line))?;
        let _position = cur.numbers(3, "scanner position x y z")?;
        let mut axes = Vec::new();
        for axis in ["X", "Y", "Z"] {
            axes.extend(cur.numbers(3, &format!("scanner {axis} axis"))?.1);
        }
        let mut values = Vec::new();
        let mut first_matrix_line = 0;
        for r in 1..=4 {
            let (l, row) = cur.numbers(4, &format!("row {r} of the 4x4 transform"))?;
            first_matrix_line = if r == 1 { l } else { first_matrix_line };
            values.extend(row);
        }
        let pose = pose_from(&values, &axes).map_err(|e| e.at_line(first_matrix_line))?;
        let cloud = read_points(&mut cur, n, scan, limits)?;
        total += cloud.points.len() as u64;
        Limits::check_len("points", total, limits.max_points)?;
        scans.push(PointCloud {
            pose: Some(pose),
            ..cloud
        });
    }
    if scans.is_empty() {
        return Err(IngestError::syntax(
            "a PTX scan header (number of columns)",
            "end of file",
        ));
    }
    Ok(scans)
}

/// The scan pose in column-vector form (see the module doc for the ambiguous case).
fn pose_from(values: &[f64], axes: &[f64]) -> Result<Matrix4> {
    let m = matrix_from_numbers(values)?;
    detect_convention(m).or_else(|e| {
        let rows_are_axes = values
            .chunks(4)
            .take(3)
            .flat_map(|r| r.iter().take(3))
            .zip(axes)
            .all(|(a, b)| (a - b).abs() <= 1e-6);
        if rows_are_axes && m[3] == [0.0, 0.0, 0.0, 1.0] {
            Ok(transpose(&m))
        } else {
            Err(e)
        }
    })
}

fn read_points(cur: &mut Cursor<'_>, n: u64, scan: usize, limits: &Limits) -> Result<PointCloud> {
    let room = n.min(cur.len as u64 / 8);
    let mut points = limits.vec_with_capacity::<[f64; 3]>("points", room)?;
    let mut intensity = limits.vec_with_capacity::<f32>("intensities", room)?;
    let mut rgb = Vec::new();
    let mut width = None;
    for k in 0..n {
        let expected = format!(
            "point line {} of {n} (columns x rows) of scan {scan}",
            k + 1
        );
        let (line_no, _, line) = cur.next(&expected)?;
        let mut v = [0.0f64; 7];
        let mut count = 0;
        for (slot, field) in v.iter_mut().zip(fields(line, Delim::Whitespace)) {
            *slot = number(field, &format!("field {} of a point", count + 1))
                .map_err(|e| e.at_line(line_no))?;
            count += 1;
        }
        let count = fields(line, Delim::Whitespace).count().max(count);
        let w = *width.get_or_insert(count);
        if count != w || !(w == 4 || w == 7) {
            let expected = if w == count {
                "4 or 7 fields (x y z intensity [r g b])".to_string()
            } else {
                format!("{w} fields like the first point of scan {scan}")
            };
            return Err(IngestError::syntax(expected, &show(line)).at_line(line_no));
        }
        if v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0 {
            continue;
        }
        points.push([v[0], v[1], v[2]]);
        intensity.push(v[3] as f32);
        if w == 7 {
            let c = |x: f64, name: &str| {
                color_byte(x, false, || format!("{name} of a point"))
                    .map_err(|e| e.at_line(line_no))
            };
            rgb.push([c(v[4], "red")?, c(v[5], "green")?, c(v[6], "blue")?]);
        }
    }
    Ok(PointCloud {
        points,
        intensity: Some(intensity),
        rgb: (width == Some(7)).then_some(rgb),
        ..Default::default()
    })
}

/// Reads a PTX file from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Vec<PointCloud>> {
    let bytes = read_file(path, limits)?;
    read_ptx(&bytes, limits).map_err(|e| e.in_file(path))
}
