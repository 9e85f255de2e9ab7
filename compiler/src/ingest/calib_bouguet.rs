//! MATLAB Camera Calibration Toolbox (Bouguet) results → [`CameraModel`] and stereo pose.
//!
//! `Calib_Results.m` is a MATLAB script of assignments (formats.md §12.1). We parse
//! assignments, not lines: `name = [ a ; b ; ... ];` or `name = scalar;`, with `%` comments,
//! tabs, two spaces before `=`, `%5.15f` / `%e` numbers and `NaN` (inactive images). A value
//! may separate entries by `;`, `,` or spaces. Order is irrelevant; unknown names are kept and
//! ignored, so the per-image `omc_i`, `Tc_i` (which may be `NaN`) never cause errors.
//!
//! Conversion to regolith's camera model (pixel (0, 0) = centre of the top-left pixel):
//! * `fc = [fx; fy]` → `fx, fy`;
//! * `cc = [cx; cy]` → `cx, cy` **unchanged**: the toolbox defines pixel coordinates so that
//!   `[0; 0]` is the centre of the upper-left pixel (its default principal point is
//!   `[(nx-1)/2; (ny-1)/2]`, e.g. `[319.5; 239.5]` for 640x480), which is our convention; no
//!   ±0.5 or ±1 shift applies (the shift people expect comes from MATLAB's 1-based *array*
//!   indices, which the toolbox does not use for coordinates);
//! * `alpha_c` is the skew as a fraction of fx (`u = fx (x_d + alpha_c y_d) + cx`), so
//!   `skew = alpha_c * fx`;
//! * `kc = [k1; k2; p1; p2; k3]` (OpenCV order, k3 last) or only 4 entries (older
//!   `saving_calib.m`; k3 = 0);
//! * `nx`, `ny` → width, height (0 when absent: the campaign supplies `image_size`).
//!
//! Stereo (formats.md §12.2): the toolbox saves only `Calib_Results_stereo.mat`; a `.m` twin is
//! user-made, either in the same assignment form or as the text `go_calib_stereo` prints
//! (`om = [ a  b  c ] ± [ ... ]`). Both are read: everything after `±` (or its `?` / mojibake
//! forms) on a line is dropped. `X_right = R(om) X_left + T`, `T` in calibration-grid units,
//! taken to be millimetres and converted to metres. The `.mat` itself is read by
//! [`super::calib_bouguet_mat`], which turns its variables into the same [`Assignment`]s (placed
//! by byte offset instead of line) so both forms share the conversion below.

use std::path::Path;

use regolith_format::camera_model::{CameraModel, Distortion};
use regolith_format::frames::Pose;
use regolith_format::limits::Limits;

use super::calib_opencv::camera_from_k_with;
use super::markers;
use super::yaml_lite::{self, Matrix};
use crate::error::{IngestError, Result};

/// One assignment `name = values;` (or one `.mat` variable) with where it is in its file.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// Variable name.
    pub name: String,
    /// Values in file order (`NaN` allowed); a `.mat` matrix is given row by row, as MATLAB
    /// prints it.
    pub values: Vec<f64>,
    /// Where the variable is.
    pub at: Place,
}

/// Where an [`Assignment`] is: the line of its name in a script, or the byte offset of its
/// element in a `.mat` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// 1-based line of a `.m` script.
    Line(u64),
    /// Byte offset of a `.mat` data element.
    Offset(u64),
}

impl Place {
    /// Wraps `err` with this location.
    pub fn locate(self, err: IngestError) -> IngestError {
        match self {
            Place::Line(l) => err.at_line(l),
            Place::Offset(o) => err.at_offset(o),
        }
    }
}

/// Reads `Calib_Results.m`.
pub fn read_path(path: &Path, limits: &Limits) -> Result<CameraModel> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Reads a stereo `.m` (`om`, `T`) → `right_from_left`.
pub fn read_stereo_path(path: &Path, limits: &Limits) -> Result<Pose> {
    yaml_lite::read_with(path, limits, |b| parse_stereo(b, limits))
}

/// Parses `Calib_Results.m` (or the `_left` camera of a stereo file).
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<CameraModel> {
    let a = assignments(bytes, limits)?;
    camera(&a, stereo_suffix(&a), Form::Script)
}

/// Which file the variables come from (only the wording of a missing variable differs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Form {
    /// A `.m` script of assignments.
    Script,
    /// A `.mat` binary.
    Mat,
}

/// `"_left"` when the variables are a stereo result's (`fc_left`, no `fc`), else `""`.
pub(crate) fn stereo_suffix(a: &[Assignment]) -> &'static str {
    if find(a, "fc").is_none() && find(a, "fc_left").is_some() {
        "_left"
    } else {
        ""
    }
}

/// Parses a stereo result: `om` (Rodrigues, rad) and `T` (mm) → `right_from_left` in metres.
pub fn parse_stereo(bytes: &[u8], limits: &Limits) -> Result<Pose> {
    stereo(&assignments(bytes, limits)?, Form::Script)
}

/// `right_from_left` from the `om` and `T` variables (shared by the `.m` and `.mat` readers).
pub(crate) fn stereo(a: &[Assignment], form: Form) -> Result<Pose> {
    let om = vec3(a, "om", form)?;
    let t = vec3(a, "T", form)?;
    let r = markers::rotation_from_vector(om)
        .ok_or_else(|| IngestError::invalid("`om` is not finite"))?;
    Ok(Pose::from_matrix(r, t.map(|v| v / 1000.0)))
}

/// The camera of variables `fc{suffix}`, `cc{suffix}`, ... (suffix `""`, `"_left"`, `"_right"`).
pub(crate) fn camera(a: &[Assignment], suffix: &str, form: Form) -> Result<CameraModel> {
    let need = |n: &str, len: &[usize]| -> Result<&Assignment> {
        let name = format!("{n}{suffix}");
        let v = find(a, &name).ok_or_else(|| missing(&name, form))?;
        if !len.contains(&v.values.len()) || !v.values.iter().all(|x| x.is_finite()) {
            return Err(v.at.locate(IngestError::invalid(format!(
                "`{name}` must hold {len:?} finite values"
            ))));
        }
        Ok(v)
    };
    let fc = need("fc", &[2])?;
    let cc = need("cc", &[2])?;
    let kc = need("kc", &[4, 5])?;
    let alpha = match find(a, &format!("alpha_c{suffix}")) {
        Some(_) => need("alpha_c", &[1])?
            .values
            .first()
            .copied()
            .unwrap_or(0.0),
        None => 0.0,
    };
    let size = match (find(a, "nx"), find(a, "ny")) {
        // The image size has no `_left`/`_right` suffix: both cameras share it.
        (Some(nx), Some(ny)) => (dim(nx)?, dim(ny)?),
        _ => (0, 0),
    };
    let g = |v: &Assignment, i: usize| v.values.get(i).copied().unwrap_or(0.0);
    let (fx, fy) = (g(fc, 0), g(fc, 1));
    let k = Matrix {
        rows: 3,
        cols: 3,
        data: vec![fx, alpha * fx, g(cc, 0), 0.0, fy, g(cc, 1), 0.0, 0.0, 1.0],
    };
    let dist = Distortion {
        k1: g(kc, 0),
        k2: g(kc, 1),
        p1: g(kc, 2),
        p2: g(kc, 3),
        k3: g(kc, 4),
    };
    let key = format!("fc{suffix}, cc{suffix}");
    camera_from_k_with(&k, dist, size, &key, |e| fc.at.locate(e))
}

/// The error for a variable that is not there, worded for the form the others come from.
fn missing(name: &str, form: Form) -> IngestError {
    let expected = match form {
        Form::Mat => format!("a numeric variable `{name}`"),
        Form::Script => format!("an assignment `{name} = ...`"),
    };
    IngestError::syntax(expected, "none")
}

fn dim(v: &Assignment) -> Result<u32> {
    match v.values.as_slice() {
        [x] if *x >= 1.0 && *x < 1e6 && x.fract() == 0.0 => Ok(*x as u32),
        _ => Err(v.at.locate(IngestError::invalid(format!(
            "`{}` must be a positive pixel count",
            v.name
        )))),
    }
}

fn vec3(a: &[Assignment], name: &str, form: Form) -> Result<[f64; 3]> {
    let v = find(a, name).ok_or_else(|| missing(name, form))?;
    <[f64; 3]>::try_from(v.values.as_slice())
        .ok()
        .filter(|x| x.iter().all(|c| c.is_finite()))
        .ok_or_else(|| {
            v.at.locate(IngestError::invalid(format!(
                "`{name}` must hold 3 finite values"
            )))
        })
}

fn find<'a>(a: &'a [Assignment], name: &str) -> Option<&'a Assignment> {
    a.iter().find(|x| x.name == name)
}

/// All numeric assignments of a MATLAB results script, in file order.
pub fn assignments(bytes: &[u8], limits: &Limits) -> Result<Vec<Assignment>> {
    Limits::check_len(
        "MATLAB script bytes",
        bytes.len() as u64,
        limits.max_object_bytes,
    )?;
    // Latin-1 `±` is not UTF-8; decode lossily, the markers are ASCII anyway.
    let text = String::from_utf8_lossy(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes));
    let mut out: Vec<Assignment> = Vec::new();
    let mut pending: Option<(String, String, u64)> = None;
    for (i, raw) in text.lines().enumerate() {
        let no = i as u64 + 1;
        let line = cut_uncertainty(raw.split('%').next().unwrap_or(""));
        let mut rest = line.trim();
        if pending.is_none() {
            if rest.is_empty() {
                continue;
            }
            let Some((name, value)) = rest.split_once('=') else {
                return Err(IngestError::syntax("`name = value;`", rest).at_line(no));
            };
            let name = name.trim();
            if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                return Err(IngestError::syntax("a variable name", name).at_line(no));
            }
            pending = Some((name.to_string(), String::new(), no));
            rest = value;
        }
        if let Some((_, buf, _)) = pending.as_mut() {
            buf.push(' ');
            buf.push_str(rest);
        }
        let done = pending
            .as_ref()
            .is_some_and(|(_, b, _)| b.matches('[').count() <= b.matches(']').count());
        if done {
            if let Some((name, buf, line)) = pending.take() {
                out.push(Assignment {
                    values: numbers(&buf, line)?,
                    name,
                    at: Place::Line(line),
                });
            }
        }
    }
    if let Some((name, _, line)) = pending {
        return Err(
            IngestError::syntax(format!("`]` closing `{name}`"), "end of file").at_line(line),
        );
    }
    Ok(out)
}

/// Drops the printed uncertainty part `± [...]` (also seen as `?` or mojibake).
fn cut_uncertainty(line: &str) -> &str {
    match line.find(['±', '?', '\u{FFFD}']) {
        Some(i) => line.get(..i).unwrap_or(line),
        None => line,
    }
}

fn numbers(value: &str, line: u64) -> Result<Vec<f64>> {
    let inner = value.trim().trim_end_matches(';').trim();
    let inner = inner
        .strip_prefix('[')
        .and_then(|s| s.strip_suffix(']'))
        .unwrap_or(inner);
    inner
        .split(|c: char| c == ';' || c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| match t.parse::<f64>() {
            Ok(v) if v.is_finite() || t.eq_ignore_ascii_case("nan") => Ok(v),
            _ => Err(IngestError::syntax("a number or NaN", t).at_line(line)),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_kc_skew_nan_image_and_printed_stereo() {
        let l = Limits::default();
        let m = b"fc = [ 1000 ; 1010 ];\ncc = [ 319.5 ; 239.5 ];\nalpha_c = 0.01;\t% skew\nkc = [ -0.2 ; 0.1 ; 0.001 ; -0.002 ];\nnx = 640;\nny = 480;\nomc_5 = [ NaN ; NaN ; NaN ];\nTc_1  = [ 1 ;\n 2 ; 3 ];\n";
        let c = parse(m, &l).unwrap();
        assert_eq!(
            (
                c.fx,
                c.skew,
                c.cx,
                c.width,
                c.distortion.p2,
                c.distortion.k3
            ),
            (1000.0, 10.0, 319.5, 640, -0.002, 0.0)
        );
        let printed = "om = [ 0.0  0.0  1.5707963267948966 ] \u{b1} [ 0.001 0.001 0.001 ]\nT = [ -120.0  0.0  0.0 ] ? [ 0.1 0.1 0.1 ]\n";
        let p = parse_stereo(printed.as_bytes(), &l).unwrap();
        let x = p.transform_point([1.0, 0.0, 0.0]);
        assert!(
            (x[0] + 0.12).abs() < 1e-9 && (x[1] - 1.0).abs() < 1e-9,
            "{x:?}"
        );
        let e = parse(b"fc = [ 1000 ; abc ];\n", &l)
            .unwrap_err()
            .to_string();
        assert_eq!(e, "line 1: expected a number or NaN, found \"abc\"");
    }
}
