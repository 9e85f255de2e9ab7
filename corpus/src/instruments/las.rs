//! One scan as LAS 1.2 (point format 0) through the `las` crate.
//!
//! Coordinates are SOCS metres stored as i32 with a 0.1 mm scale and zero offset (SOCS ranges
//! are tens of metres, far inside i32 at that scale). Intensity is the reflectance mapped from
//! [-30, +5] dB to 0..65535, as RIEGL exports map reflectance into the u16 field (formats.md
//! §4). The header date is left empty and the generating software fixed, for reproducible bytes.

use std::path::Path;

use las::{point::Format, Builder, Point, Transform, Vector, Writer};

use super::e57::DB_RANGE;
use crate::CorpusError;

/// Writes `points` (SOCS) and reflectance to `path`.
pub fn write(path: &Path, points: &[[f64; 3]], reflectance_db: &[f32]) -> Result<(), CorpusError> {
    let enc = CorpusError::encode("LAS", path);
    let run = || -> Result<(), las::Error> {
        let mut b = Builder::from((1, 2));
        b.point_format = Format::new(0)?;
        b.date = None;
        b.generating_software = "regolith-corpus".into();
        b.system_identifier = "RIEGL SOCS (simulated)".into();
        let t = Transform {
            scale: 0.0001,
            offset: 0.0,
        };
        b.transforms = Vector { x: t, y: t, z: t };
        let mut w = Writer::from_path(path, b.into_header()?)?;
        for (p, r) in points.iter().zip(reflectance_db) {
            let i = ((f64::from(*r) - DB_RANGE[0]) / (DB_RANGE[1] - DB_RANGE[0])).clamp(0.0, 1.0);
            w.write_point(Point {
                x: p[0],
                y: p[1],
                z: p[2],
                intensity: (i * 65535.0).round() as u16,
                ..Default::default()
            })?;
        }
        w.close()
    };
    run().map_err(enc)
}
