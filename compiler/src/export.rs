//! Engine-specific heightfield variants derived on export (SPEC.md §5.1): Gazebo wants a square
//! `2^n+1` grid, Unreal a landscape size with value 32768 = z 0. Both are bilinear resamplings
//! of the hole-filled heights at the new cell centres, with the edge value padding the square.

use regolith_reader::Heightfield;
use serde_json::{json, Value};

use crate::encode::{png, EncodeError};

/// A resampled 16-bit heightmap and the sidecar that says how to place it.
#[derive(Debug, Clone)]
pub struct EngineVariant {
    /// Side of the square grid, samples.
    pub size: usize,
    /// 16-bit greyscale PNG.
    pub png: Vec<u8>,
    /// Placement metadata for the engine.
    pub sidecar: Value,
}

/// Bilinear height at ground (x, y) from the hole-filled grid, clamped to the edge.
fn sample(hf: &Heightfield, x: f64, y: f64) -> f64 {
    let m = &hf.meta;
    let (w, h) = (m.width as usize, m.height as usize);
    let fc = ((x - m.origin_m[0]) / m.cell_m).clamp(0.0, (w - 1) as f64);
    let fr = ((m.origin_m[1] - y) / m.cell_m).clamp(0.0, (h - 1) as f64);
    let (c0, r0) = (fc.floor() as usize, fr.floor() as usize);
    let (c1, r1) = ((c0 + 1).min(w - 1), (r0 + 1).min(h - 1));
    let (tx, ty) = (fc - c0 as f64, fr - r0 as f64);
    let z = |c: usize, r: usize| f64::from(hf.heights.get(r * w + c).copied().unwrap_or(0.0));
    let top = z(c0, r0) * (1.0 - tx) + z(c1, r0) * tx;
    let bottom = z(c0, r1) * (1.0 - tx) + z(c1, r1) * tx;
    top * (1.0 - ty) + bottom * ty
}

/// Resamples onto an `n x n` grid spanning the larger extent; returns heights and spacing.
fn resample(hf: &Heightfield, n: usize) -> (Vec<f64>, f64) {
    let m = &hf.meta;
    let extent = (f64::from(m.width.max(m.height)) - 1.0).max(1.0) * m.cell_m;
    let s = extent / (n - 1) as f64;
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            out.push(sample(
                hf,
                m.origin_m[0] + i as f64 * s,
                m.origin_m[1] - j as f64 * s,
            ));
        }
    }
    (out, s)
}

fn range(z: &[f64]) -> (f64, f64) {
    z.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        })
}

/// Gazebo (classic and gz): the smallest `2^n+1 ≥` the larger side, at most 4097.
pub fn gazebo(hf: &Heightfield) -> Result<EngineVariant, EncodeError> {
    let side = hf.meta.width.max(hf.meta.height) as usize;
    let n = (1..=12)
        .map(|k| (1usize << k) + 1)
        .find(|&n| n >= side)
        .unwrap_or(4097);
    let (z, s) = resample(hf, n);
    let (lo, hi) = range(&z);
    let zs = if hi > lo { hi - lo } else { 1e-3 };
    let values: Vec<u16> = z
        .iter()
        .map(|v| (((v - lo) / zs) * 65535.0).round().clamp(0.0, 65535.0) as u16)
        .collect();
    let extent = s * (n - 1) as f64;
    let m = &hf.meta;
    let sidecar = json!({
        "profile": "gazebo",
        "image": "height_gazebo.png",
        "size_px": n,
        "heightmap_size_m": [extent, extent, zs],
        "heightmap_pos_m": [m.origin_m[0] + extent / 2.0, m.origin_m[1] - extent / 2.0, lo],
        "spacing_m": s,
        "resampling": "bilinear from the hole-filled heights at the new cell centres; south/east padded with the edge value",
        "note": "Gazebo centres the heightmap on pos; heights = value / 65535 * size.z + pos.z. Check the row orientation with an asymmetric terrain in your Gazebo version.",
    });
    Ok(EngineVariant {
        size: n,
        png: png::grey16(n as u32, n as u32, &values)?,
        sidecar,
    })
}

/// Unreal Engine landscape: the smallest recommended size ≥ the larger side.
pub fn unreal(hf: &Heightfield) -> Result<EngineVariant, EncodeError> {
    const SIZES: [usize; 7] = [127, 253, 505, 1009, 2017, 4033, 8129];
    let side = hf.meta.width.max(hf.meta.height) as usize;
    let n = SIZES.iter().copied().find(|&n| n >= side).unwrap_or(8129);
    let (z, s) = resample(hf, n);
    let (lo, hi) = range(&z);
    let range_cm = ((hi - lo) * 100.0).max(0.1);
    // height_cm = (v - 32768) / 128 * ZScale; [lo, hi] → [32768, 65535].
    let z_scale = range_cm * 128.0 / 32767.0;
    let values: Vec<u16> = z
        .iter()
        .map(|v| {
            (32768.0 + (v - lo) * 100.0 * 128.0 / z_scale)
                .round()
                .clamp(0.0, 65535.0) as u16
        })
        .collect();
    let m = &hf.meta;
    let sidecar = json!({
        "profile": "unreal",
        "image": "height_unreal.png",
        "size_px": n,
        "scale_cm": [s * 100.0, s * 100.0, z_scale],
        "location_cm": [m.origin_m[0] * 100.0, -m.origin_m[1] * 100.0, lo * 100.0],
        "resampling": "bilinear from the hole-filled heights at the new cell centres; south/east padded with the edge value",
        "note": "value 32768 = z 0 relative to the actor; Unreal is left-handed (y flipped), centimetres",
    });
    Ok(EngineVariant {
        size: n,
        png: png::grey16(n as u32, n as u32, &values)?,
        sidecar,
    })
}
