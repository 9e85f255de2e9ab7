//! ASTM E57 files via the `e57` crate (formats.md §3): every `data3D` scan as a [`PointCloud`]
//! with its pose.
//!
//! Design decisions:
//! - Points stay in the scan's own frame and the `pose` (unit quaternion w,x,y,z plus
//!   translation, `p_file = R(q)·p + t`) is returned as a column-vector [`Matrix4`], the same
//!   shape PTX scans and RIEGL SOPs take; registration composes poses, so applying it here
//!   would hide it. A scan without a pose gets `pose: None` (the file frame).
//! - Spherical-only scans are converted to Cartesian by the crate (`x = r·cosE·cosA`, ...);
//!   ScaledInteger and Float coordinates come back as `f64` either way.
//! - Points whose coordinates are invalid or direction-only carry no position and are
//!   dropped. Intensity is kept as stored (E57 gives it no unit); colour is normalised with the
//!   file's `colorLimits` and stored as bytes. An invalid intensity or colour on a kept point
//!   becomes 0 so the per-point vectors stay aligned.
//! - `recordCount` is checked against [`Limits`] before anything is allocated for it.

use std::io::{BufReader, Cursor, Read, Seek};
use std::path::Path;

use e57::{CartesianCoordinate, E57Reader};
use regolith_format::limits::Limits;

use super::types::{Matrix4, PointCloud};
use crate::error::{IngestError, Result};

fn e57_err(what: &str) -> impl Fn(e57::Error) -> IngestError + '_ {
    move |e| IngestError::invalid(format!("E57 {what}: {e}"))
}

/// The pose of a scan as a column-vector matrix; the quaternion is normalised first.
pub fn pose_matrix(t: &e57::Transform) -> Result<Matrix4> {
    let q = &t.rotation;
    let norm = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
    if !norm.is_finite() || norm < 1e-9 {
        return Err(IngestError::invalid(format!(
            "E57 pose quaternion {q:?} is not a rotation"
        )));
    }
    let (w, x, y, z) = (q.w / norm, q.x / norm, q.y / norm, q.z / norm);
    let tr = &t.translation;
    Ok([
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            tr.x,
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
            tr.y,
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
            tr.z,
        ],
        [0.0, 0.0, 0.0, 1.0],
    ])
}

/// Reads every scan from an E57 source.
pub fn read_e57_from<R: Read + Seek>(source: R, limits: &Limits) -> Result<Vec<PointCloud>> {
    let mut reader = E57Reader::new(source).map_err(e57_err("header/XML"))?;
    let mut out = Vec::new();
    let mut total = 0u64;
    for (k, pc) in reader.pointclouds().into_iter().enumerate() {
        let what = format!(
            "scan {} ({})",
            k + 1,
            pc.name.as_deref().unwrap_or("unnamed")
        );
        Limits::check_len(
            "points",
            total.saturating_add(pc.records),
            limits.max_points,
        )?;
        let pose = pc.transform.as_ref().map(pose_matrix).transpose()?;
        let (has_int, has_rgb) = (pc.has_intensity(), pc.has_color());
        let room = pc.records.min(1 << 24);
        let mut cloud = PointCloud {
            points: limits.vec_with_capacity("points", room)?,
            intensity: has_int.then(Vec::new),
            rgb: has_rgb.then(Vec::new),
            pose,
            ..Default::default()
        };
        let mut iter = reader.pointcloud_simple(&pc).map_err(e57_err(&what))?;
        iter.apply_pose(false);
        iter.spherical_to_cartesian(true);
        iter.intensity_to_color(false);
        iter.normalize_intensity(false);
        iter.normalize_color(true);
        for p in iter {
            let p = p.map_err(e57_err(&what))?;
            let CartesianCoordinate::Valid { x, y, z } = p.cartesian else {
                continue;
            };
            if !(x.is_finite() && y.is_finite() && z.is_finite()) {
                let msg = format!(
                    "{what}: point {} has a non-finite coordinate",
                    cloud.points.len() + 1
                );
                return Err(IngestError::invalid(msg));
            }
            cloud.points.push([x, y, z]);
            if let Some(v) = cloud.intensity.as_mut() {
                v.push(p.intensity.filter(|i| i.is_finite()).unwrap_or(0.0));
            }
            if let Some(v) = cloud.rgb.as_mut() {
                let byte = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
                v.push(
                    p.color
                        .map_or([0; 3], |c| [byte(c.red), byte(c.green), byte(c.blue)]),
                );
            }
        }
        total += cloud.points.len() as u64;
        out.push(cloud);
    }
    Ok(out)
}

/// Reads every scan from E57 bytes (used by tests and the fuzz target).
pub fn read_e57(bytes: &[u8], limits: &Limits) -> Result<Vec<PointCloud>> {
    read_e57_from(Cursor::new(bytes), limits)
}

/// Reads an E57 file, streaming it from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Vec<PointCloud>> {
    let file = std::fs::File::open(path).map_err(|e| IngestError::from(e).in_file(path))?;
    read_e57_from(BufReader::new(file), limits).map_err(|e| e.in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_turn_about_z_matches_formats_md() {
        // formats.md §3.2: point (1,0,0), 90° about Z, t = (10,0,0) gives (10,1,0).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let t = e57::Transform {
            rotation: e57::Quaternion {
                w: h,
                x: 0.0,
                y: 0.0,
                z: h,
            },
            translation: e57::Translation {
                x: 10.0,
                y: 0.0,
                z: 0.0,
            },
        };
        let p = crate::ingest::types::transform(&pose_matrix(&t).unwrap(), [1.0, 0.0, 0.0]);
        assert!((p[0] - 10.0).abs() < 1e-12 && (p[1] - 1.0).abs() < 1e-12 && p[2].abs() < 1e-12);
    }
}
