//! Vicon Tracker object CSV → per-object poses, formats.md §6.
//!
//! Tracker exports, per frame and object, `RX RY RZ TX TY TZ`: a helical rotation vector
//! (axis × angle, radians; Tracker's default representation) and a translation in mm in the
//! Tracker world frame (z up). The file does **not** state its frame rate, so the caller
//! supplies it, and its preamble lines are undocumented, so we skip everything before the row
//! that starts with `Frame` and read the object names from the non-empty row above it
//! (`Global Angle Subject:Segment` → `Subject:Segment`). The row after the header is a units
//! row when its first cell is empty. Occluded samples (empty cells or a short row) are `None`.
//! Each pose is `world_from_object`: `p_world = R(r) p_object + t`, t in metres.

use std::path::Path;

use regolith_format::frames::Pose;
use regolith_format::limits::Limits;

use super::markers;
use super::yaml_lite;
use crate::error::{IngestError, Result};

/// One tracked object.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedObject {
    /// `Subject:Segment` as in the file.
    pub name: String,
    /// `world_from_object` per frame; `None` when occluded.
    pub poses: Vec<Option<Pose>>,
}

/// All objects of a Tracker export.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerData {
    /// The frame rate the caller supplied, Hz.
    pub rate_hz: f64,
    /// Frame number of the first data row.
    pub first_frame: i64,
    /// Objects in file order.
    pub objects: Vec<TrackedObject>,
}

/// Reads a Tracker CSV; `rate_hz` must be given because the file does not hold it.
pub fn read_path(path: &Path, rate_hz: f64, limits: &Limits) -> Result<TrackerData> {
    yaml_lite::read_with(path, limits, |b| parse(b, rate_hz, limits))
}

fn cell<'a>(r: &[&'a str], i: usize) -> &'a str {
    r.get(i).copied().unwrap_or("")
}

/// Parses Tracker CSV bytes.
pub fn parse(bytes: &[u8], rate_hz: f64, limits: &Limits) -> Result<TrackerData> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(IngestError::invalid(format!(
            "frame rate {rate_hz} Hz must be positive"
        )));
    }
    Limits::check_len(
        "Tracker CSV bytes",
        bytes.len() as u64,
        limits.max_object_bytes,
    )?;
    let text = String::from_utf8_lossy(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes));
    let lines: Vec<(u64, Vec<&str>)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i as u64 + 1, l.split(',').map(str::trim).collect()))
        .collect();
    let header = lines
        .iter()
        .position(|(_, r)| cell(r, 0).eq_ignore_ascii_case("Frame"))
        .ok_or_else(|| {
            IngestError::syntax("a `Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ` row", "none").at_line(1)
        })?;
    let names_row = lines.get(..header).and_then(|h| {
        h.iter()
            .rev()
            .find(|(_, r)| r.iter().any(|c| !c.is_empty()))
    });
    let (hno, hrow) = lines
        .get(header)
        .map(|(n, r)| (*n, r.as_slice()))
        .unwrap_or((1, &[]));
    let mut objects = Vec::new();
    let mut starts = Vec::new();
    for (c, role) in hrow.iter().enumerate() {
        if role.eq_ignore_ascii_case("RX") {
            let roles: Vec<&str> = (c..c + 6).map(|i| cell(hrow, i)).collect();
            if roles
                .iter()
                .map(|r| r.to_ascii_uppercase())
                .ne(["RX", "RY", "RZ", "TX", "TY", "TZ"]
                    .iter()
                    .map(|s| s.to_string()))
            {
                return Err(IngestError::syntax("RX,RY,RZ,TX,TY,TZ", &roles.join(",")).at_line(hno));
            }
            let raw = names_row.map_or("", |(_, r)| cell(r, c));
            let name = raw.rsplit(' ').next().unwrap_or(raw);
            objects.push(TrackedObject {
                name: if name.is_empty() {
                    format!("object{}", starts.len() + 1)
                } else {
                    name.to_string()
                },
                poses: Vec::new(),
            });
            starts.push(c);
        }
    }
    if objects.is_empty() {
        return Err(IngestError::syntax("RX,RY,RZ,TX,TY,TZ columns", cell(hrow, 2)).at_line(hno));
    }
    let mut data = lines.iter().skip(header + 1).peekable();
    if data.peek().is_some_and(|(_, r)| cell(r, 0).is_empty()) {
        data.next();
    }
    let mut first_frame = None;
    for (no, row) in data {
        if row.iter().all(|c| c.is_empty()) {
            break;
        }
        let frame = yaml_lite::parse_number(cell(row, 0))
            .filter(|f| f.fract() == 0.0 && f.abs() < 1e15)
            .ok_or_else(|| IngestError::syntax("a frame number", cell(row, 0)).at_line(*no))?
            as i64;
        first_frame.get_or_insert(frame);
        for (obj, &c) in objects.iter_mut().zip(&starts) {
            Limits::check_len(
                "Tracker frames",
                obj.poses.len() as u64 + 1,
                limits.max_points,
            )?;
            let cells: Vec<&str> = (c..c + 6).map(|i| cell(row, i)).collect();
            if cells.iter().any(|s| s.is_empty()) {
                obj.poses.push(None);
                continue;
            }
            let mut v = [0.0; 6];
            for (out, s) in v.iter_mut().zip(&cells) {
                *out = yaml_lite::parse_number(s).ok_or_else(|| {
                    IngestError::syntax(format!("a number for object `{}`", obj.name), s)
                        .at_line(*no)
                })?;
            }
            let r = markers::rotation_from_vector([v[0], v[1], v[2]]).ok_or_else(|| {
                IngestError::invalid("rotation vector is not finite").at_line(*no)
            })?;
            obj.poses.push(Some(Pose::from_matrix(
                r,
                [v[3] / 1000.0, v[4] / 1000.0, v[5] / 1000.0],
            )));
        }
    }
    Ok(TrackerData {
        rate_hz,
        first_frame: first_frame.unwrap_or(1),
        objects,
    })
}
