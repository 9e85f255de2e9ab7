//! Heightfield objects (SPEC.md §5.1): quantisation to 16 bits, validity mask, float EXR.
//!
//! The scale is chosen from the data so the whole 16-bit range is used and the stated
//! quantisation error (`z_scale / 2`) is as small as the range allows.

use regolith_format::kinds::HeightfieldMeta;

use super::{exr, png, EncodeError};

/// A height grid to encode; row 0 is north, NaN marks nodata.
#[derive(Debug, Clone)]
pub struct GridInput<'a> {
    /// Ground x, y of the centre of cell (0, 0).
    pub origin_m: [f64; 2],
    /// Cell size, metres.
    pub cell_m: f64,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Measured heights (NaN = nodata).
    pub heights: &'a [f32],
    /// Survey = ground + this.
    pub site_origin_m: [f64; 3],
    /// Terrain source name.
    pub source: &'a str,
}

/// The three objects of a heightfield entry and its metadata.
#[derive(Debug, Clone)]
pub struct EncodedHeightfield {
    /// Entry metadata.
    pub meta: HeightfieldMeta,
    /// 16-bit PNG of the hole-filled heights.
    pub height_png: Vec<u8>,
    /// 8-bit validity mask PNG.
    pub mask_png: Vec<u8>,
    /// Float EXR of the measured heights (NaN kept).
    pub height_exr: Vec<u8>,
}

/// Fills NaN cells from their measured neighbours, wave by wave (each wave fills the holes
/// touching the known surface with the mean of their known 4-neighbours), so the result is
/// continuous and independent of any thread count. A grid with no value at all becomes 0.
pub fn fill_holes(heights: &[f32], width: usize, height: usize) -> Vec<f32> {
    let mut z = heights.to_vec();
    if z.iter().all(|v| v.is_nan()) {
        return vec![0.0; z.len()];
    }
    loop {
        let mut updates = Vec::new();
        for r in 0..height {
            for c in 0..width {
                let i = r * width + c;
                if !z.get(i).is_some_and(|v| v.is_nan()) {
                    continue;
                }
                let mut sum = 0.0f64;
                let mut n = 0u32;
                let neighbours = [
                    (c > 0).then(|| i - 1),
                    (c + 1 < width).then(|| i + 1),
                    (r > 0).then(|| i - width),
                    (r + 1 < height).then(|| i + width),
                ];
                for j in neighbours.into_iter().flatten() {
                    if let Some(v) = z.get(j).filter(|v| !v.is_nan()) {
                        sum += f64::from(*v);
                        n += 1;
                    }
                }
                if n > 0 {
                    updates.push((i, (sum / f64::from(n)) as f32));
                }
            }
        }
        if updates.is_empty() {
            return z;
        }
        for (i, v) in updates {
            if let Some(slot) = z.get_mut(i) {
                *slot = v;
            }
        }
    }
}

/// Encodes a grid into its PNG, mask and EXR objects.
pub fn encode(g: &GridInput<'_>) -> Result<EncodedHeightfield, EncodeError> {
    encode_filled(
        g,
        &fill_holes(g.heights, g.width as usize, g.height as usize),
    )
}

/// [`encode`] with the grid's [`fill_holes`] already computed (callers that also mesh it).
pub fn encode_filled(g: &GridInput<'_>, filled: &[f32]) -> Result<EncodedHeightfield, EncodeError> {
    let (w, h) = (g.width as usize, g.height as usize);
    if g.heights.len() != w * h || filled.len() != w * h || w == 0 || h == 0 {
        return Err(EncodeError::new(
            "heightfield",
            format!("{} values for {w}x{h}", g.heights.len()),
        ));
    }
    let valid: Vec<bool> = g.heights.iter().map(|v| v.is_finite()).collect();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in filled {
        lo = lo.min(f64::from(*v));
        hi = hi.max(f64::from(*v));
    }
    let (mut vlo, mut vhi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (v, ok) in g.heights.iter().zip(&valid) {
        if *ok {
            vlo = vlo.min(f64::from(*v));
            vhi = vhi.max(f64::from(*v));
        }
    }
    let valid_cells = valid.iter().filter(|v| **v).count() as u64;
    if valid_cells == 0 {
        (vlo, vhi) = (0.0, 0.0);
    }
    let z_scale = if hi > lo { (hi - lo) / 65535.0 } else { 1e-6 };
    let meta = HeightfieldMeta {
        frame: "ground".to_string(),
        origin_m: g.origin_m,
        cell_m: g.cell_m,
        width: g.width,
        height: g.height,
        row_order: "north-up".to_string(),
        z_offset_m: lo,
        z_scale_m: z_scale,
        quantisation_error_m: z_scale / 2.0,
        z_range_m: [vlo, vhi],
        valid_cells,
        holes_filled: valid_cells < (w * h) as u64,
        site_origin_m: g.site_origin_m,
        source: g.source.to_string(),
    };
    let values: Vec<u16> = filled
        .iter()
        .map(|&z| meta.value_of(f64::from(z)))
        .collect();
    let mask: Vec<u8> = valid.iter().map(|&v| if v { 255 } else { 0 }).collect();
    Ok(EncodedHeightfield {
        height_png: png::grey16(g.width, g.height, &values)?,
        mask_png: png::grey8(g.width, g.height, &mask)?,
        height_exr: exr::grey_f32(w, h, g.heights)?,
        meta,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_error_is_within_half_a_step() {
        let heights: Vec<f32> = (0..12)
            .map(|i| {
                if i == 5 {
                    f32::NAN
                } else {
                    i as f32 * 0.0731 - 0.02
                }
            })
            .collect();
        let g = GridInput {
            origin_m: [0.0, 1.0],
            cell_m: 0.1,
            width: 4,
            height: 3,
            heights: &heights,
            site_origin_m: [0.0; 3],
            source: "test",
        };
        let e = encode(&g).unwrap();
        assert_eq!(e.meta.valid_cells, 11);
        assert!(e.meta.holes_filled);
        for &z in heights.iter().filter(|z| z.is_finite()) {
            let back = e.meta.height_of(e.meta.value_of(f64::from(z)));
            assert!((back - f64::from(z)).abs() <= e.meta.quantisation_error_m * 1.000001 + 1e-9);
        }
        let (w, h, v) = exr::read_grey_f32(&e.height_exr).unwrap();
        assert_eq!((w, h), (4, 3));
        assert!(v[5].is_nan() && v[4] == heights[4]);
        let again = encode(&g).unwrap();
        assert_eq!(again.height_png, e.height_png);
        assert_eq!(again.height_exr, e.height_exr);
    }

    #[test]
    fn fill_is_continuous() {
        let nan = f32::NAN;
        let z = fill_holes(&[1.0, nan, 3.0, nan, nan, nan], 3, 2);
        assert_eq!(z[1], 2.0);
        assert!(z.iter().all(|v| v.is_finite()));
    }
}
