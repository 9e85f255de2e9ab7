//! RiSCAN PRO "Multi SOP export" `.DAT` files (one 4x4 matrix as 4 lines of 4 numbers), and
//! [`detect_convention`], the one place that decides how a 4x4 matrix from a file is oriented.
//!
//! RIEGL writes matrices for column vectors (`p' = M·[x y z 1]ᵀ`, translation in the 4th
//! column), PTX writes them for row vectors (`p' = [x y z 1]·M`, translation in the 4th row)
//! (formats.md §0 trap 1). Transposing by mistake silently drops the translation, so instead of
//! trusting the file type we look at which side carries `0 0 0 1`, and refuse to guess when
//! both do and the 3x3 part is not symmetric (a pure rotation without translation cannot tell
//! us its orientation). `riscan_rsp` and `ptx` use the same function.
//!
//! The `.DAT` grammar is deliberately loose where real writers vary (any run of whitespace,
//! CRLF, `E-005` exponents, blank lines) and strict where mistakes hide (exactly 4x4 finite
//! numbers, nothing after them).

use std::path::Path;

use regolith_format::limits::Limits;

use super::riscan_ascii::{fields, lines, number, read_file, show, Delim};
use super::types::Matrix4;
use crate::error::{IngestError, Result};

/// Tolerance for recognising the `0 0 0 1` row or column.
const EPS: f64 = 1e-9;

fn is_unit_tail(v: [f64; 4]) -> bool {
    v[0].abs() <= EPS && v[1].abs() <= EPS && v[2].abs() <= EPS && (v[3] - 1.0).abs() <= EPS
}

/// Returns the transpose of `m`.
pub fn transpose(m: &Matrix4) -> Matrix4 {
    let mut t = [[0.0; 4]; 4];
    for (i, row) in m.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            if let Some(cell) = t.get_mut(j).and_then(|r| r.get_mut(i)) {
                *cell = *v;
            }
        }
    }
    t
}

/// Accepts a 4x4 matrix in column-vector form (last row `0 0 0 1`, RIEGL) or row-vector form
/// (last column `0 0 0 1`, PTX) and returns it in column-vector form ([`Matrix4`]).
///
/// Errors when no side is `0 0 0 1`, when an entry is not finite, and when both sides are
/// (zero translation) but the 3x3 part is not symmetric, so the orientation cannot be told.
pub fn detect_convention(m: [[f64; 4]; 4]) -> Result<Matrix4> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(IngestError::invalid("expected a matrix of finite numbers"));
    }
    let last_row = m[3];
    let last_col = [m[0][3], m[1][3], m[2][3], m[3][3]];
    match (is_unit_tail(last_row), is_unit_tail(last_col)) {
        (true, false) => Ok(m),
        (false, true) => Ok(transpose(&m)),
        (true, true) => {
            let symmetric = (m[0][1] - m[1][0]).abs() <= EPS
                && (m[0][2] - m[2][0]).abs() <= EPS
                && (m[1][2] - m[2][1]).abs() <= EPS;
            if symmetric {
                Ok(m)
            } else {
                Err(IngestError::invalid(
                    "ambiguous 4x4 matrix: both the last row and the last column are 0 0 0 1 \
                     (no translation) and the 3x3 part is not symmetric, so it cannot be told \
                     whether it is written for column or row vectors",
                ))
            }
        }
        (false, false) => Err(IngestError::syntax(
            "a 4x4 transform with a last row or last column of 0 0 0 1",
            &format!("last row {last_row:?}, last column {last_col:?}"),
        )),
    }
}

/// Arranges 16 numbers, row-major, into a raw 4x4 matrix.
pub(crate) fn matrix_from_numbers(values: &[f64]) -> Result<[[f64; 4]; 4]> {
    if values.len() != 16 {
        return Err(IngestError::syntax(
            "16 numbers (a 4x4 matrix)",
            &format!("{} numbers", values.len()),
        ));
    }
    let mut m = [[0.0; 4]; 4];
    for (k, v) in values.iter().enumerate() {
        if let Some(cell) = m.get_mut(k / 4).and_then(|r| r.get_mut(k % 4)) {
            *cell = *v;
        }
    }
    Ok(m)
}

/// Reads a `.DAT` matrix file and returns the matrix in column-vector form.
pub fn read_sop_dat(bytes: &[u8]) -> Result<Matrix4> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut values = Vec::new();
    let mut last_line = 0;
    for (line_no, _, line) in lines(bytes) {
        last_line = line_no;
        let mut row = Vec::new();
        for field in fields(line, Delim::Whitespace) {
            if row.len() == 4 || values.len() == 16 {
                return Err(
                    IngestError::syntax("4 numbers per line, 4 lines", &show(line))
                        .at_line(line_no),
                );
            }
            let what = format!(
                "matrix row {}, column {}",
                values.len() / 4 + 1,
                row.len() + 1
            );
            row.push(number(field, &what).map_err(|e| e.at_line(line_no))?);
        }
        match row.len() {
            0 => continue,
            4 => values.extend(row),
            n => {
                return Err(IngestError::syntax(
                    "4 numbers per line",
                    &format!("{n} numbers: {}", show(line)),
                )
                .at_line(line_no))
            }
        }
    }
    if values.len() != 16 {
        let found = format!("end of file after {} rows", values.len() / 4);
        return Err(IngestError::syntax("4 lines of 4 numbers", &found).at_line(last_line.max(1)));
    }
    detect_convention(matrix_from_numbers(&values)?)
}

/// Reads a `.DAT` matrix file from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Matrix4> {
    let bytes = read_file(path, limits)?;
    read_sop_dat(&bytes).map_err(|e| e.in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_vector_form_is_transposed() {
        // PDAL complex-transform.ptx matrix (formats.md §2.2): translation in the 4th row.
        let ptx = [
            [0.999979, -0.003604, -0.005365, 0.0],
            [0.003613, 0.999992, 0.001630, 0.0],
            [0.005359, -0.001650, 0.999984, 0.0],
            [-3.028748, -3.819741, -1.384333, 1.0],
        ];
        let m = detect_convention(ptx).unwrap();
        assert_eq!(
            [m[0][3], m[1][3], m[2][3]],
            [-3.028748, -3.819741, -1.384333]
        );
        assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(m[0][1], 0.003613);
    }

    #[test]
    fn symmetric_without_translation_is_accepted_and_rotation_is_not() {
        let mut m = crate::ingest::types::IDENTITY4;
        m[2][2] = 2.0;
        assert_eq!(detect_convention(m).unwrap(), m);
        let rot = [
            [0.0, -1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        assert!(detect_convention(rot)
            .unwrap_err()
            .to_string()
            .contains("ambiguous"));
    }
}
