//! One scan as E57 (ASTM E2807) through the `e57` crate's writer.
//!
//! Cartesian coordinates are written as doubles in SOCS with no pose (the file is "in the
//! scanner's own frame", like the ASCII export), and the reflectance as `intensity` mapped
//! linearly from [-30, +5] dB to 0..1 with `intensityLimits` set to that range, so a reader
//! that normalises intensity by the limits gets back the dB value exactly up to f32 rounding.
//! GUIDs are derived from the seed, not random, so the bytes are reproducible.

use std::path::Path;

use e57::{E57Writer, IntensityLimits, Record, RecordValue};

use crate::CorpusError;

/// Reflectance range mapped onto intensity 0..1, dB.
pub const DB_RANGE: [f64; 2] = [-30.0, 5.0];

/// Writes `points` (SOCS) and reflectance to `path`.
pub fn write(
    path: &Path,
    name: &str,
    points: &[[f64; 3]],
    reflectance_db: &[f32],
    seed: u64,
) -> Result<(), CorpusError> {
    let enc = CorpusError::encode("E57", path);
    let run = || -> Result<(), e57::Error> {
        let mut w = E57Writer::from_file(path, &format!("{{regolith-corpus-{seed:016x}}}"))?;
        let proto = vec![
            Record::CARTESIAN_X_F64,
            Record::CARTESIAN_Y_F64,
            Record::CARTESIAN_Z_F64,
            Record::INTENSITY_UNIT_F32,
        ];
        let mut pc = w.add_pointcloud(&format!("{{regolith-corpus-{seed:016x}-{name}}}"), proto)?;
        pc.set_name(Some(name.to_string()));
        pc.set_sensor_vendor(Some("RIEGL (simulated by regolith-corpus)".into()));
        pc.set_intensity_limits(Some(IntensityLimits {
            intensity_min: Some(RecordValue::Single(0.0)),
            intensity_max: Some(RecordValue::Single(1.0)),
        }));
        for (p, r) in points.iter().zip(reflectance_db) {
            let i = ((f64::from(*r) - DB_RANGE[0]) / (DB_RANGE[1] - DB_RANGE[0])).clamp(0.0, 1.0);
            pc.add_point(vec![
                RecordValue::Double(p[0]),
                RecordValue::Double(p[1]),
                RecordValue::Double(p[2]),
                RecordValue::Single(i as f32),
            ])?;
        }
        pc.finalize()?;
        w.finalize()
    };
    run().map_err(enc)
}
