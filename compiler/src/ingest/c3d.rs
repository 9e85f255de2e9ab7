//! C3D motion-capture files → marker [`Trajectories`] (metres), via the `c3dio` crate.
//!
//! Design (formats.md §7): `c3dio` decodes the blocks, processor formats and scale; we turn
//! its grid into regolith's typed trajectories and fix the semantics it leaves to callers:
//! * a sample whose residual is negative (or whose coordinates are not finite) is a gap →
//!   `None`, **never** the origin that many files store for it;
//! * `POINT:UNITS` (`mm`, `cm`, `m`, space-padded) scales to metres; anything else is an error;
//! * labels are trimmed and split at the first `:` into subject and marker; points listed in
//!   `POINT:ANGLES / FORCES / MOMENTS / POWERS / SCALARS` are model outputs, not markers, and
//!   are left out;
//! * the first frame is the file's (often not 1).
//!
//! `c3dio` 0.8 misreads parameters that hold an empty array (a dimension of 0, e.g. Nexus's
//! `POINT:MOVIE_ID` `[32, 0]` or `EVENT:TIMES` `[2, 0]`): it drops the 0 and reads data that is
//! not there, failing with `InvalidParameterData` on real Nexus files such as the pyomeca
//! sample. `patch_empty_parameters` rewrites such records in a copy of the bytes into 1-byte
//! character arrays in the same bytes (records are linked by offsets; the layout is unchanged); none of them is
//! a parameter we use, and each is renamed
//! with a leading `_` so c3dio's typed readers (events, force plates) skip it.
//!
//! `c3dio` indexes its input directly and was not written for hostile files, so the call runs
//! under `catch_unwind`: a panic inside the crate becomes an ordinary error, keeping our
//! "bad input never panics" guarantee without forking the crate.

use std::path::Path;

use regolith_format::limits::Limits;

use super::types::{MarkerTrack, Trajectories};
use super::yaml_lite;
use crate::error::{IngestError, Result};

/// Reads a `.c3d` file.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Trajectories> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Parses the bytes of a C3D file.
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<Trajectories> {
    Limits::check_len("C3D bytes", bytes.len() as u64, limits.max_object_bytes)?;
    if bytes.len() < 512 {
        return Err(IngestError::syntax(
            "a 512-byte C3D header block",
            &format!("{} bytes", bytes.len()),
        )
        .at_offset(0));
    }
    let mut patched = bytes.to_vec();
    patch_empty_parameters(&mut patched);
    let c3d =
        std::panic::catch_unwind(|| c3dio::C3d::from_bytes(&patched).map_err(|e| e.to_string()))
            .map_err(|_| {
                IngestError::invalid("corrupt C3D file (inconsistent blocks or parameters)")
            })?
            .map_err(|e| IngestError::invalid(format!("C3D: {e}")))?;
    let points = &c3d.points;
    let unit: String = points.units.iter().collect();
    let scale = match unit.trim() {
        "mm" => 1e-3,
        "cm" => 1e-2,
        "m" => 1.0,
        other => return Err(IngestError::syntax("POINT:UNITS mm, cm or m", other)),
    };
    let model_outputs: Vec<String> = ["ANGLES", "FORCES", "MOMENTS", "POWERS", "SCALARS"]
        .iter()
        .filter_map(|g| c3d.parameters.get("POINT", g))
        .filter_map(|p| Vec::<String>::try_from(p).ok())
        .flatten()
        .map(|s| s.trim().to_string())
        .collect();
    let (frames, cols) = (points.rows(), points.cols());
    Limits::check_len(
        "C3D samples",
        (frames as u64).saturating_mul(cols as u64),
        limits.max_points,
    )?;
    let mut markers = Vec::new();
    for col in 0..cols {
        let label = points
            .labels
            .get(col)
            .map_or_else(|| format!("point{}", col + 1), |l| l.trim().to_string());
        if model_outputs.contains(&label) {
            continue;
        }
        let mut samples = limits.vec_with_capacity("C3D frames", frames as u64)?;
        for row in 0..frames {
            let sample = points.get(row, col).and_then(|m| {
                let p = m.point.map(|v| f64::from(v) * scale);
                (m.residual >= 0.0 && p.iter().all(|v| v.is_finite())).then_some(p)
            });
            samples.push(sample);
        }
        let (subject, name) = match label.split_once(':') {
            Some((s, n)) => (Some(s.to_string()), n.to_string()),
            None => (None, label),
        };
        markers.push(MarkerTrack {
            name,
            subject,
            frames: samples,
        });
    }
    let rate = f64::from(points.frame_rate);
    if !(rate.is_finite() && rate > 0.0) {
        return Err(IngestError::invalid(format!(
            "C3D frame rate {rate} is not positive"
        )));
    }
    Ok(Trajectories {
        rate_hz: rate,
        first_frame: i64::from(points.first_frame),
        markers,
    })
}

/// Turns every parameter record with a zero dimension (and so no data) into a one-character
/// array occupying the same bytes (see the module doc). Walks the records by their offsets; stops quietly at
/// anything malformed (c3dio then reports it).
fn patch_empty_parameters(b: &mut [u8]) {
    let Some(&first_block) = b.first() else {
        return;
    };
    let start = (usize::from(first_block).max(1) - 1) * 512;
    let big_endian = b.get(start + 3) == Some(&86);
    let mut i = start + 4;
    for _ in 0..100_000 {
        let (Some(&nc), Some(&id)) = (b.get(i), b.get(i + 1)) else {
            return;
        };
        let name_len = usize::from((nc as i8).unsigned_abs());
        let j = i + 2 + name_len;
        let (Some(&o0), Some(&o1)) = (b.get(j), b.get(j + 1)) else {
            return;
        };
        let offset = usize::from(if big_endian {
            u16::from_be_bytes([o0, o1])
        } else {
            u16::from_le_bytes([o0, o1])
        });
        if nc == 0 || id == 0 {
            return;
        }
        if (id as i8) > 0 {
            let nd = usize::from(b.get(j + 3).copied().unwrap_or(0));
            let has_zero = b.get(j + 4..j + 4 + nd).is_some_and(|d| d.contains(&0));
            if let (true, Some(rec)) = (has_zero, b.get_mut(j + 2..j + 4 + nd)) {
                // type -1 (char), one dimension fewer, all 1; the freed last dimension byte
                // becomes the single data byte, so the description stays where it was.
                let mut new = vec![0xFF, (nd - 1) as u8];
                new.resize(nd + 1, 1);
                new.push(b' ');
                rec.copy_from_slice(&new);
                // Rename it (`TIMES` → `_IMES`) so c3dio's typed groups do not look for it.
                if let Some(first) = b.get_mut(i + 2) {
                    *first = b'_';
                }
            }
        }
        if offset == 0 {
            return;
        }
        i = j + offset;
    }
}
