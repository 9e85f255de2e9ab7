//! Ground-control-point files for aligning an SfM reconstruction (`[[reconstruction]] align =
//! "<file>"`, campaign.md §3 "Ground control points").
//!
//! The shape photogrammetry tools write when they export markers (Agisoft Metashape's marker
//! export, a hand-made list): a text table, `#` comment lines, an optional header line, one row
//! per marker `label, x, y, z` — the marker's position in the reconstruction's own frame, as
//! measured (clicked) in the SfM model, in the model's units — optionally followed by
//! `ground_x, ground_y, ground_z`, the marker's position in the ground frame in metres.
//!
//! * Delimiter: `,` `;` or tab, sniffed from the first row (header or data) in the order tab,
//!   `;`, `,` (labels may then contain spaces, `point 1`); a file with none of them is a
//!   whitespace table, whose labels cannot contain spaces. The helpers are the tie-point
//!   reader's (`riscan_ascii`), so both tables split and report alike.
//! * A row has exactly 4 fields or exactly 7: a 5th column is never guessed at (Metashape can
//!   append accuracies and errors; such columns must be removed, not silently mis-read as
//!   ground coordinates). Rows of both kinds may be mixed (a hand-made list giving ground
//!   coordinates for the few points that are not Vicon markers); a 7-field row whose three
//!   ground cells are all empty (a spreadsheet with some ground coordinates missing) has none.
//! * A row without ground coordinates is matched by name to the campaign's ground markers
//!   (the Vicon ball centres) by [`match_markers`]: exact name first, else the part after the
//!   last `:` (the `Subject:Marker` convention of Vicon names). A label that matches none is an
//!   error naming it and the known markers. Given ground coordinates win over a marker of the
//!   same name.
//! * Labels identify markers, so a repeated label is an error naming both lines.

use std::collections::BTreeMap;
use std::path::Path;

use regolith_format::limits::Limits;

use super::riscan_ascii::{number, read_file, show};
use super::tiepoints::{named_rows, NamedRow};
use super::types::NamedPoint;
use crate::error::{IngestError, Result};

/// One row of a ground-control-point file.
#[derive(Debug, Clone, PartialEq)]
pub struct GcpMarker {
    /// Label as written (quotes and surrounding spaces removed).
    pub name: String,
    /// 1-based line of the row, for messages.
    pub line: u64,
    /// Position in the reconstruction's frame (SfM units).
    pub sfm: [f64; 3],
    /// Position in the ground frame (metres), when the file gives it.
    pub ground: Option<[f64; 3]>,
}

/// Where a control point's ground position came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GroundFrom {
    /// The GCP file's ground columns.
    File,
    /// The campaign's ground marker of the same name (Vicon mean).
    Marker,
}

impl GroundFrom {
    /// `file` or `markers`, as reports write it.
    pub fn as_str(self) -> &'static str {
        match self {
            GroundFrom::File => "file",
            GroundFrom::Marker => "markers",
        }
    }
}

/// A marker known in both frames.
#[derive(Debug, Clone, PartialEq)]
pub struct MatchedGcp {
    /// Label.
    pub name: String,
    /// Position in the reconstruction's frame.
    pub sfm: [f64; 3],
    /// Position in the ground frame, metres.
    pub ground: [f64; 3],
    /// Where `ground` came from.
    pub ground_from: GroundFrom,
}

const AXES: [&str; 6] = ["x", "y", "z", "ground_x", "ground_y", "ground_z"];

/// Reads a ground-control-point table.
pub fn read_gcp(bytes: &[u8], limits: &Limits) -> Result<Vec<GcpMarker>> {
    Limits::check_len(
        "GCP file bytes",
        bytes.len() as u64,
        limits.max_object_bytes,
    )?;
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut out: Vec<GcpMarker> = Vec::new();
    let mut seen: BTreeMap<String, u64> = BTreeMap::new();
    // The label and at most 7 more fields: an 8th says "more than 7" well enough.
    for row in named_rows(bytes, 7) {
        let NamedRow {
            line_no,
            delim: d,
            line,
            name,
            values,
        } = row;
        let err_at = |e: IngestError| e.at_line(line_no);
        let n = values.len() + 1;
        if n != 4 && n != 7 {
            let expected = format!(
                "4 fields `label, x, y, z` or 7 `label, x, y, z, ground_x, ground_y, ground_z` separated by {}",
                d.describe()
            );
            let found = if n > 7 {
                format!("more than 7 fields: {}", show(line))
            } else {
                format!("{n} fields: {}", show(line))
            };
            return Err(err_at(IngestError::syntax(expected, &found)));
        }
        if name.is_empty() {
            return Err(err_at(IngestError::syntax(
                "a marker label in field 1",
                &show(line),
            )));
        }
        let no_ground = n == 7
            && values
                .get(3..)
                .is_some_and(|g| g.iter().all(|c| c.is_empty()));
        let used = if no_ground { 3 } else { values.len() };
        let mut xyz = [0.0; 6];
        for ((slot, field), axis) in xyz.iter_mut().zip(values.iter().take(used)).zip(AXES) {
            *slot = number(field, &format!("{axis} of marker {name:?}")).map_err(err_at)?;
        }
        if let Some(first) = seen.insert(name.clone(), line_no) {
            return Err(err_at(IngestError::invalid(format!(
                "duplicate marker label {name:?} (first on line {first})"
            ))));
        }
        Limits::check_len("control points", out.len() as u64 + 1, limits.max_points)?;
        let [x, y, z, gx, gy, gz] = xyz;
        out.push(GcpMarker {
            name,
            line: line_no,
            sfm: [x, y, z],
            ground: (used == 6).then_some([gx, gy, gz]),
        });
    }
    if out.is_empty() {
        return Err(IngestError::syntax(
            "at least one marker row `label, x, y, z` (line 1)",
            if bytes.is_empty() {
                "an empty file"
            } else {
                "no data rows"
            },
        )
        .at_line(1));
    }
    Ok(out)
}

/// Reads a ground-control-point file from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Vec<GcpMarker>> {
    let bytes = read_file(path, limits)?;
    read_gcp(&bytes, limits).map_err(|e| e.in_file(path))
}

/// Gives every marker its ground position: the file's, else the ground marker of the same
/// name (exact, else the part of the label after its last `:`). A label without either is an
/// error at its line naming it and the known markers. Order is the file's.
pub fn match_markers(gcps: &[GcpMarker], markers: &[NamedPoint]) -> Result<Vec<MatchedGcp>> {
    let by_name: BTreeMap<&str, &NamedPoint> =
        markers.iter().map(|m| (m.name.as_str(), m)).collect();
    gcps.iter()
        .map(|g| {
            let (ground, ground_from) = match g.ground {
                Some(p) => (p, GroundFrom::File),
                None => {
                    let short = g.name.rsplit(':').next().unwrap_or(&g.name);
                    let m = by_name
                        .get(g.name.as_str())
                        .or_else(|| by_name.get(short))
                        .ok_or_else(|| {
                            let known: Vec<&str> = by_name.keys().copied().collect();
                            IngestError::invalid(format!(
                                "marker {:?} has no ground coordinates and no ground marker of that name; known markers: {}",
                                g.name,
                                if known.is_empty() {
                                    "none".to_string()
                                } else {
                                    known.join(", ")
                                }
                            ))
                            .at_line(g.line)
                        })?;
                    (m.xyz, GroundFrom::Marker)
                }
            };
            Ok(MatchedGcp {
                name: g.name.clone(),
                sfm: g.sfm,
                ground,
                ground_from,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn read(t: &str) -> Result<Vec<GcpMarker>> {
        read_gcp(t.as_bytes(), &Limits::default())
    }

    fn err(t: &str) -> String {
        read(t).unwrap_err().to_string()
    }

    fn markers() -> Vec<NamedPoint> {
        [
            ("Marker1", [0.45, 0.5, 0.09]),
            ("Marker2", [1.55, 0.35, 0.08]),
            ("Marker3", [1.0, 1.05, 0.11]),
        ]
        .into_iter()
        .map(|(n, xyz)| NamedPoint {
            name: n.into(),
            xyz,
        })
        .collect()
    }

    #[test]
    fn metashape_style_export_with_comments_and_header() {
        let t = "# Agisoft Metashape marker export\r\n\
                 # Markers (3), local coordinates of chunk 1\r\n\
                 Label,X,Y,Z\r\n\
                 point 1,-4.120331,3.271207,-3.664502\r\n\
                 \r\n\
                 point 2,-5.348215,3.457032,-2.929840\r\n\
                 \"point 3\",-5.061288,4.128004,-3.844129\r\n";
        let g = read(t).unwrap();
        assert_eq!(g.len(), 3);
        assert_eq!(g[0].name, "point 1");
        assert_eq!(g[0].sfm, [-4.120331, 3.271207, -3.664502]);
        assert_eq!(g[0].line, 4);
        assert_eq!(g[2].name, "point 3");
        assert!(g.iter().all(|p| p.ground.is_none()));
    }

    #[test]
    fn plain_four_columns_whitespace_and_bom() {
        let t = "\u{FEFF}Marker1   0.1 0.2 0.3\nMarker2\t1e-3 -2 3.5\n";
        let g = read(t).unwrap();
        assert_eq!(g[1].name, "Marker2");
        // The tab makes the file tab-separated only when the first row has one; here it does
        // not, so both rows are whitespace tables.
        assert_eq!(g[1].sfm, [1e-3, -2.0, 3.5]);
    }

    #[test]
    fn seven_columns_give_ground_coordinates() {
        let t = "label;x;y;z;ground_x;ground_y;ground_z\n\
                 gcp A;1;2;3;10.5;20.25;0.125\n\
                 gcp B;4;5;6;;;\n";
        let g = read(t).unwrap();
        assert_eq!(g[0].ground, Some([10.5, 20.25, 0.125]));
        assert_eq!(g[1].ground, None, "three empty ground cells = no ground");
        let m = match_markers(
            &g,
            &[NamedPoint {
                name: "gcp B".into(),
                xyz: [7.0, 8.0, 9.0],
            }],
        )
        .unwrap();
        assert_eq!(m[0].ground_from, GroundFrom::File);
        assert_eq!(
            (m[1].ground, m[1].ground_from),
            ([7.0, 8.0, 9.0], GroundFrom::Marker)
        );
    }

    #[test]
    fn matched_by_name_and_by_marker_part() {
        let t = "Marker1,1,2,3\nTestbed:Marker2,4,5,6\nMarker3,7,8,9,0.5,0.5,0.5\n";
        let m = match_markers(&read(t).unwrap(), &markers()).unwrap();
        assert_eq!(m[0].ground, [0.45, 0.5, 0.09]);
        assert_eq!(m[1].name, "Testbed:Marker2");
        assert_eq!(m[1].ground, [1.55, 0.35, 0.08]);
        assert_eq!(
            (m[2].ground, m[2].ground_from),
            ([0.5; 3], GroundFrom::File),
            "the file's ground coordinates win"
        );
    }

    #[test]
    fn bad_inputs_name_line_and_what_was_expected() {
        let e = err("a,1,2,3\nb,1,2x,3\n");
        assert!(
            e.starts_with("line 2:") && e.contains("a number for y of marker \"b\""),
            "{e}"
        );
        assert!(e.contains("\"2x\""), "{e}");
        let e = err("a,1,2,3\nb,1,2\n");
        assert!(e.starts_with("line 2:") && e.contains("3 fields"), "{e}");
        assert!(e.contains("4 fields `label, x, y, z` or 7"), "{e}");
        let e = err("a,1,2,3,4,5\n");
        assert!(e.contains("6 fields"), "{e}");
        let e = err("a,1,2,3,4,5,6,7,8\n");
        assert!(e.contains("more than 7 fields"), "{e}");
        let mixed = read("a,1,2,3\nb,1,2,3,4,5,6\n").unwrap();
        assert_eq!(
            (mixed[0].ground, mixed[1].ground),
            (None, Some([4.0, 5.0, 6.0]))
        );
        let e = err("a,1,2,3\n\n\"a\",4,5,6\n");
        assert!(
            e.starts_with("line 3:")
                && e.contains("duplicate marker label \"a\" (first on line 1)"),
            "{e}"
        );
        let e = err(",1,2,3\n");
        assert!(e.contains("a marker label"), "{e}");
        let e = err("a,1,inf,3\n");
        assert!(e.contains("a finite number for y"), "{e}");
        let e = err("a,1,2,3,4,,6\n");
        assert!(e.contains("ground_y"), "{e}");
        assert!(err("").contains("an empty file"));
        assert!(err("# only comments\nLabel,X,Y,Z\n").contains("no data rows"));
        let e = read_path(Path::new("/nonexistent/gcp.csv"), &Limits::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/gcp.csv"), "{e}");
    }

    #[test]
    fn unknown_label_names_it_and_the_known_markers() {
        let g = read("Marker1,1,2,3\n# hand-made\nMarker9,4,5,6\n").unwrap();
        let e = match_markers(&g, &markers()).unwrap_err().to_string();
        assert!(e.starts_with("line 3:"), "{e}");
        assert!(e.contains("\"Marker9\""), "{e}");
        assert!(
            e.contains("known markers: Marker1, Marker2, Marker3"),
            "{e}"
        );
        let e = match_markers(&g, &[]).unwrap_err().to_string();
        assert!(e.contains("known markers: none"), "{e}");
    }

    #[test]
    fn limits_are_respected() {
        let limits = Limits {
            max_points: 2,
            ..Limits::default()
        };
        let t = b"a,1,2,3\nb,1,2,3\nc,1,2,3\n";
        assert!(read_gcp(t, &limits).is_err());
        assert_eq!(read_gcp(&t[..16], &limits).unwrap().len(), 2);
        let small = Limits {
            max_object_bytes: 8,
            ..Limits::default()
        };
        assert!(read_gcp(t, &small).is_err());
    }

    proptest! {
        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            if let Ok(g) = read_gcp(&bytes, &Limits::default()) {
                let _ = match_markers(&g, &markers());
            }
        }

        #[test]
        fn random_tables_never_panic(rows in proptest::collection::vec(
            proptest::collection::vec("[ a-z0-9.,;:\"#eE+-]{0,8}", 0..9), 0..8)) {
            let text: String = rows.iter().map(|r| r.join(",") + "\n").collect();
            if let Ok(g) = read_gcp(text.as_bytes(), &Limits::default()) {
                let _ = match_markers(&g, &markers());
            }
        }
    }
}
