//! Vicon Nexus CSV / TXT export → marker [`Trajectories`] (metres), formats.md §5.
//!
//! A Nexus export is a sequence of sections (`Devices`, `Joints`, `Model Outputs`,
//! `Segments`, `Trajectories`), each `name / rate / object names / column roles / units /
//! data rows`, separated by blank lines. We find the `Trajectories` section **by name**, never
//! by line number, and read it with a small state machine (no CSV crate needed: Nexus never
//! quotes cells):
//! * a UTF-8 BOM, leading blank lines and CRLF are accepted; the delimiter is `,`, `;` or tab,
//!   whichever the section-name line and the header use most (with `;` or tab, a decimal
//!   comma is accepted in numbers);
//! * `Subject:Marker` names sit above the first of their columns; a marker's columns run to the
//!   next name, and within them we take the ones labelled `X`, `Y`, `Z`, ignoring derivative
//!   columns (`X'`, `X''`) and any `Count` column;
//! * the units row is required (a file without it is an error naming the line): `mm`, `cm`
//!   or `m`, converted to metres;
//! * an empty cell is a gap → `None`; frame numbers may start above 1 and must increase
//!   (missing frame numbers become gaps, bounded by [`Limits::max_points`]).

use std::path::Path;

use regolith_format::limits::Limits;

use super::types::{MarkerTrack, Trajectories};
use super::yaml_lite;
use crate::error::{IngestError, Result};

/// Reads the `Trajectories` section of a Nexus CSV/TXT export.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Trajectories> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Parses the `Trajectories` section from the bytes of an export.
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<Trajectories> {
    parse_section(bytes, "Trajectories", limits)
}

/// One text line split into trimmed cells.
struct Row<'a> {
    no: u64,
    cells: Vec<&'a str>,
}

impl Row<'_> {
    fn cell(&self, i: usize) -> &str {
        self.cells.get(i).copied().unwrap_or("")
    }
    fn is_blank(&self) -> bool {
        self.cells.iter().all(|c| c.is_empty())
    }
}

/// Parses the section called `name` (case-insensitive) as marker trajectories.
pub fn parse_section(bytes: &[u8], name: &str, limits: &Limits) -> Result<Trajectories> {
    Limits::check_len(
        "Vicon CSV bytes",
        bytes.len() as u64,
        limits.max_object_bytes,
    )?;
    // Marker names may be Latin-1 (`Daphnée`): decode lossily rather than reject the file.
    let text = String::from_utf8_lossy(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes));
    let delim = detect_delimiter(&text);
    let mut rows = text.lines().enumerate().map(|(i, l)| Row {
        no: i as u64 + 1,
        cells: l.split(delim).map(str::trim).collect(),
    });
    let is_title = |r: &Row<'_>| {
        r.cell(0).eq_ignore_ascii_case(name) && r.cells.iter().skip(1).all(|c| c.is_empty())
    };
    let title = rows
        .find(is_title)
        .ok_or_else(|| IngestError::syntax(format!("a `{name}` section"), "none").at_line(1))?;
    let mut next = |what: &str| {
        rows.next()
            .ok_or_else(|| IngestError::syntax(what, "end of file").at_line(title.no))
    };
    let rate_row = next("the frame rate line")?;
    let rate = number(rate_row.cell(0), delim)
        .filter(|r| *r > 0.0)
        .ok_or_else(|| {
            IngestError::syntax("a frame rate in Hz", rate_row.cell(0)).at_line(rate_row.no)
        })?;
    let names = next("the marker-name row")?;
    let header = next("the `Frame,Sub Frame,X,Y,Z` row")?;
    if !header.cell(0).eq_ignore_ascii_case("Frame") {
        return Err(
            IngestError::syntax("`Frame` heading the column-role row", header.cell(0))
                .at_line(header.no),
        );
    }
    let units = next("the units row")?;
    if !units.cell(0).is_empty() || number(units.cell(0), delim).is_some() {
        return Err(IngestError::syntax(
            "a units row (`,,mm,mm,mm,...`) after the column roles",
            units.cell(0),
        )
        .at_line(units.no));
    }
    let layout = columns(&names, &header, &units)?;
    let mut markers: Vec<MarkerTrack> = layout.iter().map(|c| c.track.clone()).collect();
    let mut first_frame = None;
    let mut frames = 0usize;
    for row in rows {
        if row.is_blank() {
            break;
        }
        let frame = number(row.cell(0), delim)
            .filter(|f| f.fract() == 0.0 && f.abs() < 1e15)
            .ok_or_else(|| IngestError::syntax("a frame number", row.cell(0)).at_line(row.no))?
            as i64;
        let first = *first_frame.get_or_insert(frame);
        let index = frame
            .checked_sub(first)
            .filter(|i| *i >= frames as i64)
            .ok_or_else(|| {
                IngestError::invalid(format!("frame {frame} does not increase")).at_line(row.no)
            })?;
        let budget = limits.max_points / layout.len().max(1) as u64;
        let index = Limits::check_len("Vicon frames x markers", index as u64 + 1, budget)? - 1;
        for (m, col) in markers.iter_mut().zip(&layout) {
            m.frames.resize(index, None);
            let xyz = col.xyz.map(|c| row.cell(c));
            let sample = if xyz.iter().any(|c| c.is_empty()) {
                None
            } else {
                let mut p = [0.0; 3];
                for ((out, cell), scale) in p.iter_mut().zip(xyz).zip(col.scale) {
                    let v = number(cell, delim).ok_or_else(|| {
                        IngestError::syntax(format!("a coordinate of marker `{}`", col.label), cell)
                            .at_line(row.no)
                    })?;
                    *out = v * scale;
                }
                Some(p)
            };
            m.frames.push(sample);
        }
        frames = index + 1;
    }
    Ok(Trajectories {
        rate_hz: rate,
        first_frame: first_frame.unwrap_or(1),
        markers,
    })
}

/// The delimiter used most on the first non-blank lines.
fn detect_delimiter(text: &str) -> char {
    let head: String = text
        .lines()
        .filter(|l| !l.trim().is_empty())
        .take(5)
        .collect();
    let count = |c: char| head.matches(c).count();
    [',', ';', '\t']
        .into_iter()
        .max_by_key(|c| count(*c))
        .unwrap_or(',')
}

/// A finite number; with `;`/tab delimiters a decimal comma is accepted.
fn number(cell: &str, delim: char) -> Option<f64> {
    match yaml_lite::parse_number(cell) {
        Some(v) => Some(v),
        None if delim != ',' && cell.contains(',') => {
            yaml_lite::parse_number(&cell.replace(',', "."))
        }
        None => None,
    }
}

/// Where one marker's X, Y, Z live and how to scale them to metres.
struct MarkerColumns {
    label: String,
    track: MarkerTrack,
    xyz: [usize; 3],
    scale: [f64; 3],
}

fn columns(names: &Row<'_>, header: &Row<'_>, units: &Row<'_>) -> Result<Vec<MarkerColumns>> {
    let starts: Vec<usize> = (0..names.cells.len())
        .filter(|&i| !names.cell(i).is_empty())
        .collect();
    let mut out = Vec::new();
    for (k, &start) in starts.iter().enumerate() {
        let end = starts
            .get(k + 1)
            .copied()
            .unwrap_or(header.cells.len().max(start + 1));
        let label = names.cell(start).to_string();
        let find = |axis: &str| (start..end).find(|&c| header.cell(c).eq_ignore_ascii_case(axis));
        let (Some(x), Some(y), Some(z)) = (find("X"), find("Y"), find("Z")) else {
            return Err(IngestError::syntax(
                format!("X, Y, Z columns under marker `{label}`"),
                header.cell(start),
            )
            .at_line(header.no));
        };
        let mut scale = [0.0; 3];
        for (s, c) in scale.iter_mut().zip([x, y, z]) {
            *s = match units.cell(c) {
                "mm" => 1e-3,
                "cm" => 1e-2,
                "m" => 1.0,
                other => {
                    return Err(IngestError::syntax(
                        format!("a length unit (mm, cm, m) for marker `{label}`"),
                        other,
                    )
                    .at_line(units.no))
                }
            };
        }
        let (subject, name) = match label.split_once(':') {
            Some((s, n)) => (Some(s.to_string()), n.to_string()),
            None => (None, label.clone()),
        };
        out.push(MarkerColumns {
            track: MarkerTrack {
                name,
                subject,
                frames: Vec::new(),
            },
            label,
            xyz: [x, y, z],
            scale,
        });
    }
    if out.is_empty() {
        return Err(
            IngestError::syntax("at least one `Subject:Marker` name", "an empty row")
                .at_line(names.no),
        );
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_first_semicolon_derivatives_gaps_and_offset_frames() {
        let f = "\u{feff}\r\n\r\nDevices\r\n1000\r\n,,Plate,,\r\nFrame,Sub Frame,Fx,Fy,Fz\r\n,,N,N,N\r\n1,0,1,2,3\r\n\r\n\
                 Trajectories\r\n100\r\n,,S 1:a,,,,,,b\r\nFrame,Sub Frame,X,Y,Z,X',Y',Z',X,Y,Z\r\n,,mm,mm,mm,mm/s,mm/s,mm/s,m,m,m\r\n\
                 101,0,1,2,3,9,9,9,,,\r\n103,0,4,5,6,9,9,9,1,2,3\r\n";
        let t = parse(f.as_bytes(), &Limits::default()).unwrap();
        assert_eq!((t.rate_hz, t.first_frame, t.markers.len()), (100.0, 101, 2));
        assert_eq!(t.markers[0].subject.as_deref(), Some("S 1"));
        assert_eq!(
            t.markers[0].frames,
            vec![
                Some([0.001, 0.002, 0.003]),
                None,
                Some([0.004, 0.005, 0.006])
            ]
        );
        assert_eq!(t.markers[1].frames, vec![None, None, Some([1.0, 2.0, 3.0])]);
        let semi =
            "Trajectories;;;;\n100;;;;\n;;s:m;;\nFrame;Sub Frame;X;Y;Z\n;;mm;mm;mm\n1;0;1,5;2;3\n";
        let t = parse(semi.as_bytes(), &Limits::default()).unwrap();
        assert_eq!(t.markers[0].frames, vec![Some([0.0015, 0.002, 0.003])]);
    }

    #[test]
    fn decreasing_frames_and_unknown_units_name_the_line() {
        let l = Limits::default();
        let f =
            "Trajectories\n100\n,,s:m,,\nFrame,Sub Frame,X,Y,Z\n,,mm,mm,mm\n2,0,1,2,3\n2,0,1,2,3\n";
        assert_eq!(
            parse(f.as_bytes(), &l).unwrap_err().to_string(),
            "line 7: frame 2 does not increase"
        );
        let f = "Trajectories\n100\n,,s:m,,\nFrame,Sub Frame,X,Y,Z\n,,in,in,in\n";
        assert!(parse(f.as_bytes(), &l)
            .unwrap_err()
            .to_string()
            .starts_with("line 5: expected a length unit"));
    }
}
