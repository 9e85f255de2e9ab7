//! LAS and LAZ point clouds via the `las` crate (feature `laz`), formats.md §4.
//!
//! Design decisions:
//! - Coordinates come back already scaled and offset, as `f64` (they reach 10^6 m).
//! - Points are read in batches of `BATCH` rather than with `read_all`, so a header that
//!   claims billions of points cannot make us allocate before the data proves it exists; the
//!   header count is also checked against [`Limits`] first.
//! - Intensity is kept as stored (`u16` → `f32`): producers scale it differently. Colour is
//!   `u16` per channel, but many writers store 8-bit values there, so when no channel exceeds
//!   255 the values are taken as they are, otherwise they are reduced to 8 bits (`>> 8`).

use std::io::{BufReader, Cursor, Read, Seek};
use std::path::Path;

use regolith_format::limits::Limits;

use super::types::PointCloud;
use crate::error::{IngestError, Result};

/// Points decoded per batch.
const BATCH: u64 = 1 << 16;

fn las_err(e: las::Error) -> IngestError {
    IngestError::invalid(format!("LAS: {e}"))
}

/// Reads all points from a LAS/LAZ source.
pub fn read_las_from<R: Read + Seek + Send + Sync + 'static>(
    source: R,
    limits: &Limits,
) -> Result<PointCloud> {
    let mut reader = las::Reader::new(source).map_err(las_err)?;
    let header = reader.header();
    let n = header.number_of_points();
    Limits::check_len("points", n, limits.max_points)?;
    let has_rgb = header.point_format().has_color;
    let room = n.min(1 << 24);
    let mut points = limits.vec_with_capacity::<[f64; 3]>("points", room)?;
    let mut intensity = limits.vec_with_capacity::<f32>("intensities", room)?;
    let mut rgb16: Vec<[u16; 3]> = Vec::new();
    loop {
        let batch = reader.read_points(BATCH).map_err(las_err)?;
        if batch.is_empty() {
            break;
        }
        for p in batch.points() {
            let p = p.map_err(las_err)?;
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                let msg = format!("point {} has a non-finite coordinate", points.len() + 1);
                return Err(IngestError::invalid(msg));
            }
            points.push([p.x, p.y, p.z]);
            intensity.push(f32::from(p.intensity));
            if has_rgb {
                let c = p.color.unwrap_or_default();
                rgb16.push([c.red, c.green, c.blue]);
            }
        }
    }
    if points.len() as u64 != n {
        let msg = format!("the header says {n} points, the data has {}", points.len());
        return Err(IngestError::invalid(msg));
    }
    let shift = if rgb16.iter().flatten().any(|&c| c > 255) {
        8
    } else {
        0
    };
    let rgb = has_rgb.then(|| {
        rgb16
            .iter()
            .map(|c| c.map(|v| (v >> shift) as u8))
            .collect()
    });
    Ok(PointCloud {
        points,
        intensity: Some(intensity),
        rgb,
        ..Default::default()
    })
}

/// Reads LAS/LAZ bytes (used by tests and the fuzz target).
pub fn read_las(bytes: &[u8], limits: &Limits) -> Result<PointCloud> {
    read_las_from(Cursor::new(bytes.to_vec()), limits)
}

/// Reads a LAS/LAZ file, streaming it from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<PointCloud> {
    let file = std::fs::File::open(path).map_err(|e| IngestError::from(e).in_file(path))?;
    read_las_from(BufReader::new(file), limits).map_err(|e| e.in_file(path))
}
