//! Vicon Nexus CSV / TXT export → marker [`Trajectories`] (metres), segment poses
//! ([`Segments`]) and [`ModelOutputs`], formats.md §5.
//!
//! A Nexus export is a sequence of sections (`Devices`, `Joints`, `Model Outputs`,
//! `Segments`, `Trajectories`), each `name / rate / object names / column roles / units /
//! data rows`, separated by blank lines. Each section is found **by name**, never by line
//! number or position, so any order and any subset of sections reads the same; sections we do
//! not read (`Devices`, `Joints`) are skipped. One small state machine serves all three (no
//! CSV crate needed: Nexus never quotes cells):
//! * a UTF-8 BOM, leading blank lines and CRLF are accepted; the delimiter is `,`, `;` or tab,
//!   whichever the first lines use most (with `;` or tab, a decimal comma is accepted in
//!   numbers);
//! * `Subject:Name` names sit above the first of their columns; an object's columns run to the
//!   next name. Trajectories take the columns labelled `X`, `Y`, `Z` (ignoring derivative
//!   columns `X'`, `X''` and any `Count`); segments take `RX RY RZ TX TY TZ`; a model output
//!   keeps every labelled column, however many (angles 3, a step width 1, ...);
//! * the units row is required (a section without it is an error naming the line). Lengths in
//!   `mm`, `cm` or `m` become metres for trajectories (a marker coordinate beyond
//!   [`MAX_COORDINATE_M`] under `m` is an error: millimetres under the wrong unit) and segment
//!   translations; segment rotations in `deg` (or `rad`, converted) stay degrees; model
//!   outputs keep values and unit strings as written;
//! * an empty cell is a gap → `None`; frame numbers may start above 1 and must increase
//!   (missing frame numbers become gaps, bounded by [`Limits::max_points`]).

use std::ops::Range;
use std::path::Path;

use regolith_format::limits::Limits;

use super::types::{
    MarkerTrack, ModelColumn, ModelOutput, ModelOutputs, SegmentSample, SegmentTrack, Segments,
    Trajectories,
};
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

/// Every section regolith reads from one export; at least one is present.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NexusExport {
    /// The `Trajectories` section (marker positions, metres).
    pub trajectories: Option<Trajectories>,
    /// The `Segments` section.
    pub segments: Option<Segments>,
    /// The `Model Outputs` section.
    pub model_outputs: Option<ModelOutputs>,
}

/// Reads every section of an export regolith understands.
pub fn read_export_path(path: &Path, limits: &Limits) -> Result<NexusExport> {
    yaml_lite::read_with(path, limits, |b| parse_export(b, limits))
}

/// Parses the `Trajectories`, `Segments` and `Model Outputs` sections that are present; a file
/// with none of them is an error.
pub fn parse_export(bytes: &[u8], limits: &Limits) -> Result<NexusExport> {
    let text = decode(bytes, limits)?;
    let delim = detect_delimiter(&text);
    let out = NexusExport {
        trajectories: open(&text, delim, "Trajectories")?
            .map(|s| trajectories(s, delim, limits))
            .transpose()?,
        segments: open(&text, delim, "Segments")?
            .map(|s| segments(s, delim, limits))
            .transpose()?,
        model_outputs: open(&text, delim, "Model Outputs")?
            .map(|s| model_outputs(s, delim, limits))
            .transpose()?,
    };
    if out.trajectories.is_none() && out.segments.is_none() && out.model_outputs.is_none() {
        return Err(IngestError::syntax(
            "a `Trajectories`, `Segments` or `Model Outputs` section",
            "none",
        )
        .at_line(1));
    }
    Ok(out)
}

/// Parses the `Segments` section.
pub fn parse_segments(bytes: &[u8], limits: &Limits) -> Result<Segments> {
    let text = decode(bytes, limits)?;
    let delim = detect_delimiter(&text);
    let section = required(&text, delim, "Segments")?;
    segments(section, delim, limits)
}

/// Parses the `Model Outputs` section.
pub fn parse_model_outputs(bytes: &[u8], limits: &Limits) -> Result<ModelOutputs> {
    let text = decode(bytes, limits)?;
    let delim = detect_delimiter(&text);
    let section = required(&text, delim, "Model Outputs")?;
    model_outputs(section, delim, limits)
}

/// Parses the section called `name` (case-insensitive) as marker trajectories.
pub fn parse_section(bytes: &[u8], name: &str, limits: &Limits) -> Result<Trajectories> {
    let text = decode(bytes, limits)?;
    let delim = detect_delimiter(&text);
    let section = required(&text, delim, name)?;
    trajectories(section, delim, limits)
}

fn decode(bytes: &[u8], limits: &Limits) -> Result<String> {
    Limits::check_len(
        "Vicon CSV bytes",
        bytes.len() as u64,
        limits.max_object_bytes,
    )?;
    // Marker names may be Latin-1 (`Daphnée`): decode lossily rather than reject the file.
    let text = String::from_utf8_lossy(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes));
    Ok(text.into_owned())
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

type Rows<'a> = Box<dyn Iterator<Item = Row<'a>> + 'a>;

/// A section's header rows and an iterator over the rest of the file after them.
struct Section<'a> {
    rate: f64,
    names: Row<'a>,
    header: Row<'a>,
    units: Row<'a>,
    rows: Rows<'a>,
}

fn required<'a>(text: &'a str, delim: char, name: &str) -> Result<Section<'a>> {
    open(text, delim, name)?
        .ok_or_else(|| IngestError::syntax(format!("a `{name}` section"), "none").at_line(1))
}

/// Finds the section titled `name` and reads its rate, name, role and units rows.
fn open<'a>(text: &'a str, delim: char, name: &str) -> Result<Option<Section<'a>>> {
    let mut rows: Rows<'a> = Box::new(text.lines().enumerate().map(move |(i, l)| Row {
        no: i as u64 + 1,
        cells: l.split(delim).map(str::trim).collect(),
    }));
    let is_title = |r: &Row<'_>| {
        r.cell(0).eq_ignore_ascii_case(name) && r.cells.iter().skip(1).all(|c| c.is_empty())
    };
    let Some(title) = rows.find(is_title) else {
        return Ok(None);
    };
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
    let names = next("the object-name row")?;
    let header = next("the `Frame,Sub Frame,...` column-role row")?;
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
    Ok(Some(Section {
        rate,
        names,
        header,
        units,
        rows,
    }))
}

/// The named column groups of a section: `(label, columns)`, an object's columns running to
/// the next name (or the end of the role row).
fn groups(s: &Section<'_>, what: &str) -> Result<Vec<(String, Range<usize>)>> {
    let starts: Vec<usize> = (0..s.names.cells.len())
        .filter(|&i| !s.names.cell(i).is_empty())
        .collect();
    if starts.is_empty() {
        return Err(IngestError::syntax(
            format!("at least one `Subject:{what}` name"),
            "an empty row",
        )
        .at_line(s.names.no));
    }
    Ok(starts
        .iter()
        .enumerate()
        .map(|(k, &start)| {
            let end = starts
                .get(k + 1)
                .copied()
                .unwrap_or(s.header.cells.len().max(start + 1));
            (s.names.cell(start).to_string(), start..end)
        })
        .collect())
}

/// `Subject:Name` → (subject, name).
fn split_label(label: &str) -> (Option<String>, String) {
    match label.split_once(':') {
        Some((s, n)) => (Some(s.to_string()), n.to_string()),
        None => (None, label.to_string()),
    }
}

/// The columns labelled `roles` (case-insensitive) inside `cols`; `what` names the object.
fn role_columns<const N: usize>(
    s: &Section<'_>,
    what: &str,
    cols: &Range<usize>,
    roles: [&str; N],
) -> Result<[usize; N]> {
    let mut out = [0; N];
    for (slot, role) in out.iter_mut().zip(roles) {
        *slot = cols
            .clone()
            .find(|&c| s.header.cell(c).eq_ignore_ascii_case(role))
            .ok_or_else(|| {
                IngestError::syntax(
                    format!("{} columns under {what}", roles.join(", ")),
                    s.header.cell(cols.start),
                )
                .at_line(s.header.no)
            })?;
    }
    Ok(out)
}

/// The factor from the unit of column `c` to metres, or to degrees when `angle`; `what` names
/// the object (``marker `s:m` ``).
fn unit_scale(s: &Section<'_>, c: usize, what: &str, angle: bool) -> Result<f64> {
    let unit = s.units.cell(c);
    let scale = if angle {
        match unit {
            "deg" => Some(1.0),
            "rad" => Some(180.0 / std::f64::consts::PI),
            _ => None,
        }
    } else {
        match unit {
            "mm" => Some(1e-3),
            "cm" => Some(1e-2),
            "m" => Some(1.0),
            _ => None,
        }
    };
    let expected = if angle {
        "an angle unit (deg, rad)"
    } else {
        "a length unit (mm, cm, m)"
    };
    scale.ok_or_else(|| {
        let fix = if angle {
            "write `deg` or `rad` in the units row"
        } else {
            "write `mm`, `cm` or `m` in the units row (converting the values if they are in \
             another unit); Nexus exports write `mm`"
        };
        IngestError::invalid(format!(
            "expected {expected} for {what}, found {unit:?} in the units row; {fix}"
        ))
        .at_line(s.units.no)
    })
}

/// Maps the frame number of each data row to an index from the first frame.
struct FrameCounter {
    first: Option<i64>,
    frames: usize,
    budget: u64,
}

impl FrameCounter {
    fn new(limits: &Limits, columns: usize) -> FrameCounter {
        FrameCounter {
            first: None,
            frames: 0,
            budget: limits.max_points / columns.max(1) as u64,
        }
    }

    /// The row's frame index (frames must increase; skipped numbers become gaps).
    fn index(&mut self, row: &Row<'_>, delim: char) -> Result<usize> {
        let frame = number(row.cell(0), delim)
            .filter(|f| f.fract() == 0.0 && f.abs() < 1e15)
            .ok_or_else(|| IngestError::syntax("a frame number", row.cell(0)).at_line(row.no))?
            as i64;
        let first = *self.first.get_or_insert(frame);
        let index = frame
            .checked_sub(first)
            .filter(|i| *i >= self.frames as i64)
            .ok_or_else(|| {
                IngestError::invalid(format!("frame {frame} does not increase")).at_line(row.no)
            })?;
        let index = Limits::check_len("Vicon frames x columns", index as u64 + 1, self.budget)? - 1;
        self.frames = index + 1;
        Ok(index)
    }
}

/// A cell as a number scaled by `scale`; empty → `None`.
fn sample(
    cell: &str,
    delim: char,
    scale: f64,
    what: impl Fn() -> String,
    line: u64,
) -> Result<Option<f64>> {
    if cell.is_empty() {
        return Ok(None);
    }
    number(cell, delim)
        .map(|v| Some(v * scale))
        .ok_or_else(|| IngestError::syntax(what(), cell).at_line(line))
}

/// No motion-capture volume reaches this far from its origin (the largest Vicon rooms span tens
/// of metres): a marker coordinate beyond it in a file whose units row says `m` is a millimetre
/// value under the wrong unit.
pub const MAX_COORDINATE_M: f64 = 100.0;

fn trajectories(s: Section<'_>, delim: char, limits: &Limits) -> Result<Trajectories> {
    let units_line = s.units.no;
    let mut layout = Vec::new();
    for (label, cols) in groups(&s, "Marker")? {
        let xyz = role_columns(&s, &format!("marker `{label}`"), &cols, ["X", "Y", "Z"])?;
        let mut scale = [0.0; 3];
        for (out, c) in scale.iter_mut().zip(xyz) {
            *out = unit_scale(&s, c, &format!("marker `{label}`"), false)?;
        }
        let (subject, name) = split_label(&label);
        layout.push((
            label,
            xyz,
            scale,
            MarkerTrack {
                name,
                subject,
                frames: Vec::new(),
            },
        ));
    }
    let mut counter = FrameCounter::new(limits, layout.len());
    for row in s.rows {
        if row.is_blank() {
            break;
        }
        let index = counter.index(&row, delim)?;
        for (label, xyz, scale, track) in &mut layout {
            track.frames.resize(index, None);
            let mut p = [0.0; 3];
            let mut seen = true;
            for ((out, c), k) in p.iter_mut().zip(*xyz).zip(*scale) {
                let what = || format!("a coordinate of marker `{label}`");
                match sample(row.cell(c), delim, k, what, row.no)? {
                    Some(v) if k == 1.0 && v.abs() > MAX_COORDINATE_M => {
                        return Err(IngestError::invalid(format!(
                            "marker `{label}` has a coordinate of {} m, farther than any \
                             motion-capture volume reaches ({MAX_COORDINATE_M} m): the units \
                             row (line {units_line}) says `m` but the values look like \
                             millimetres; change the units row to `mm` (or convert the values \
                             to metres)",
                            row.cell(c)
                        ))
                        .at_line(row.no));
                    }
                    Some(v) => *out = v,
                    None => seen = false,
                }
            }
            track.frames.push(seen.then_some(p));
        }
    }
    Ok(Trajectories {
        rate_hz: s.rate,
        first_frame: counter.first.unwrap_or(1),
        markers: layout.into_iter().map(|l| l.3).collect(),
    })
}

const SEGMENT_ROLES: [&str; 6] = ["RX", "RY", "RZ", "TX", "TY", "TZ"];

fn segments(s: Section<'_>, delim: char, limits: &Limits) -> Result<Segments> {
    let mut layout = Vec::new();
    for (label, cols) in groups(&s, "Segment")? {
        let what = format!("segment `{label}`");
        let c = role_columns(&s, &what, &cols, SEGMENT_ROLES)?;
        let mut scale = [0.0; 6];
        for (k, (out, col)) in scale.iter_mut().zip(c).enumerate() {
            *out = unit_scale(&s, col, &what, k < 3)?;
        }
        let (subject, name) = split_label(&label);
        layout.push((
            label,
            c,
            scale,
            SegmentTrack {
                name,
                subject,
                frames: Vec::new(),
            },
        ));
    }
    let mut counter = FrameCounter::new(limits, 2 * layout.len());
    for row in s.rows {
        if row.is_blank() {
            break;
        }
        let index = counter.index(&row, delim)?;
        for (label, cols, scale, track) in &mut layout {
            track.frames.resize(index, None);
            let mut v = [0.0; 6];
            let mut seen = true;
            for ((out, c), k) in v.iter_mut().zip(*cols).zip(*scale) {
                let what = || format!("a value of segment `{label}`");
                match sample(row.cell(c), delim, k, what, row.no)? {
                    Some(x) => *out = x,
                    None => seen = false,
                }
            }
            let [rx, ry, rz, tx, ty, tz] = v;
            track.frames.push(seen.then_some(SegmentSample {
                rotation_deg: [rx, ry, rz],
                translation_m: [tx, ty, tz],
            }));
        }
    }
    Ok(Segments {
        rate_hz: s.rate,
        first_frame: counter.first.unwrap_or(1),
        segments: layout.into_iter().map(|l| l.3).collect(),
    })
}

fn model_outputs(s: Section<'_>, delim: char, limits: &Limits) -> Result<ModelOutputs> {
    let mut layout = Vec::new();
    let mut total = 0;
    for (label, cols) in groups(&s, "Output")? {
        let labelled: Vec<usize> = cols.filter(|&c| !s.header.cell(c).is_empty()).collect();
        if labelled.is_empty() {
            return Err(IngestError::syntax(
                format!("at least one labelled column under model output `{label}`"),
                "none",
            )
            .at_line(s.header.no));
        }
        total += labelled.len();
        let (subject, name) = split_label(&label);
        let columns = labelled
            .iter()
            .map(|&c| ModelColumn {
                label: s.header.cell(c).to_string(),
                unit: s.units.cell(c).to_string(),
                values: Vec::new(),
            })
            .collect();
        layout.push((
            label,
            labelled,
            ModelOutput {
                name,
                subject,
                columns,
            },
        ));
    }
    let mut counter = FrameCounter::new(limits, total);
    for row in s.rows {
        if row.is_blank() {
            break;
        }
        let index = counter.index(&row, delim)?;
        for (label, cols, output) in &mut layout {
            for (&c, column) in cols.iter().zip(output.columns.iter_mut()) {
                column.values.resize(index, None);
                let what = || format!("a value of model output `{label}`");
                column
                    .values
                    .push(sample(row.cell(c), delim, 1.0, what, row.no)?);
            }
        }
    }
    Ok(ModelOutputs {
        rate_hz: s.rate,
        first_frame: counter.first.unwrap_or(1),
        outputs: layout.into_iter().map(|l| l.2).collect(),
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

    #[test]
    fn millimetre_values_under_metres_name_the_line_and_the_fix() {
        let l = Limits::default();
        let f = "Trajectories\n100\n,,s:m,,\nFrame,Sub Frame,X,Y,Z\n,,m,m,m\n1,0,1.2,2.5,0.1\n2,0,1549.4,350.2,79.6\n";
        let msg = parse(f.as_bytes(), &l).unwrap_err().to_string();
        assert!(msg.starts_with("line 7: marker `s:m`"), "{msg}");
        assert!(
            msg.contains("units row (line 5) says `m`") && msg.contains("to `mm`"),
            "{msg}"
        );
        // Metre values under `m` (a large lab, far from the origin) are fine.
        let f = "Trajectories\n100\n,,s:m,,\nFrame,Sub Frame,X,Y,Z\n,,m,m,m\n1,0,42.5,-61.0,0.1\n";
        assert!(parse(f.as_bytes(), &l).is_ok());
    }
}
