//! Plane-to-plane homographies (3 × 3, mapping image A's pixels to image B's), as the feature
//! benchmarks ship them: OpenCV's samples as a FileStorage matrix (`samples/data/H1to3p.xml`,
//! in any of FileStorage's three forms, read by [`super::opencv_storage`]) and the Oxford
//! affine-covariant dataset as plain text (`H1to3p`: three rows of three numbers).
//!
//! A FileStorage file must hold exactly one 3 × 3 matrix (two would leave the choice to a
//! guess); plain text must hold exactly nine numbers. The matrix is returned row-major and
//! normalised by nothing: a homography is defined up to scale, and the caller divides by `w`.

use std::path::Path;

use regolith_format::limits::Limits;

use super::{opencv_json, opencv_storage, yaml_lite};
use crate::error::{IngestError, Result};

/// What a homography file may hold, for error messages.
pub const ACCEPTED: &str = "nine numbers as plain text (the Oxford dataset's `H1to3p` form: \
three rows of three) or an OpenCV FileStorage file (XML, YAML or JSON) holding one 3x3 \
`opencv-matrix` (as OpenCV's `samples/data/H1to3p.xml`)";

/// Reads a homography file; errors name the file and what it should hold.
pub fn read_path(path: &Path, limits: &Limits) -> Result<[f64; 9]> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Parses a homography from plain text or FileStorage bytes.
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<[f64; 9]> {
    let text = yaml_lite::decode_text(bytes)?;
    if let Some(h) = plain(text) {
        return Ok(h);
    }
    let looks_like_storage = opencv_storage::is_xml(bytes)
        || opencv_json::is_json(bytes)
        || text.trim_start().starts_with("%YAML")
        || text.contains(':');
    if !looks_like_storage {
        let n = text.split_whitespace().count();
        return Err(IngestError::invalid(format!(
            "found {n} whitespace-separated items, not a homography; expected {ACCEPTED}"
        )));
    }
    let root = opencv_storage::parse(bytes, limits)?;
    let all = opencv_storage::matrices(&root)?;
    let square: Vec<_> = all
        .iter()
        .filter(|(_, m)| m.rows == 3 && m.cols == 3)
        .collect();
    match square.as_slice() {
        [(_, m)] => m.data.as_slice().try_into().map_err(|_| {
            IngestError::invalid(format!("a 3x3 matrix with {} values", m.data.len()))
        }),
        [] => {
            let found: Vec<String> = all
                .iter()
                .map(|(k, m)| format!("`{k}` {}x{}", m.rows, m.cols))
                .collect();
            Err(IngestError::invalid(format!(
                "no 3x3 matrix in this FileStorage file (found: {}); expected {ACCEPTED}",
                if found.is_empty() {
                    "no matrix".to_string()
                } else {
                    found.join(", ")
                }
            )))
        }
        several => {
            let keys: Vec<&str> = several.iter().map(|(k, _)| *k).collect();
            Err(IngestError::invalid(format!(
                "{} 3x3 matrices ({}); keep the one mapping image A to image B in its own file",
                keys.len(),
                keys.join(", ")
            )))
        }
    }
}

/// Exactly nine numbers separated by whitespace, commas or semicolons.
fn plain(text: &str) -> Option<[f64; 9]> {
    let mut h = [0.0; 9];
    let mut n = 0;
    for token in text
        .split(|c: char| c.is_whitespace() || c == ',' || c == ';')
        .filter(|t| !t.is_empty())
    {
        let v: f64 = token.parse().ok()?;
        *h.get_mut(n)? = v;
        n += 1;
    }
    (n == 9 && h.iter().all(|v| v.is_finite())).then_some(h)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    const OXFORD: &str = "7.6285898e-01 -2.9922929e-01 2.2567123e+02\n\
                          3.3443473e-01 1.0143901e+00 -7.6999973e+01\n\
                          3.4663091e-04 -1.4364524e-05 1.0000000e+00\n";

    #[test]
    fn plain_text_and_filestorage_forms_agree() {
        let want = parse(OXFORD.as_bytes(), &Limits::default()).unwrap();
        assert!((want[2] - 225.67123).abs() < 1e-9);
        let rows = "[ 7.6285898e-01, -2.9922929e-01, 2.2567123e+02,\n\t3.3443473e-01, 1.0143901e+00, -7.6999973e+01,\n\t3.4663091e-04, -1.4364524e-05, 1.0000000e+00 ]";
        let yaml = format!(
            "%YAML:1.0\n---\nH13: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: {rows}\n"
        );
        let json = format!(
            "{{\"H13\": {{\"type_id\": \"opencv-matrix\", \"rows\": 3, \"cols\": 3, \"dt\": \"d\", \"data\": {}}}}}",
            rows.replace('\t', " ")
        );
        for text in [yaml, json] {
            assert_eq!(parse(text.as_bytes(), &Limits::default()).unwrap(), want);
        }
    }

    #[test]
    fn wrong_contents_name_what_is_accepted() {
        for (text, words) in [
            ("1 2 3 4 5 6 7 8", "found 8"),
            (
                "%YAML:1.0\nK: !!opencv-matrix\n   rows: 2\n   cols: 2\n   dt: d\n   data: [1, 2, 3, 4]\n",
                "`K` 2x2",
            ),
            (
                "%YAML:1.0\nA: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [1,0,0,0,1,0,0,0,1]\nB: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [1,0,0,0,1,0,0,0,1]\n",
                "A, B",
            ),
        ] {
            let msg = parse(text.as_bytes(), &Limits::default())
                .unwrap_err()
                .to_string();
            assert!(msg.contains(words), "{msg}");
        }
    }
}
