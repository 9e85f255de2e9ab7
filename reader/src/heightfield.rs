//! Loading a heightfield entry as a float grid with its metadata and validity mask.

use regolith_format::kinds::{self, roles, HeightfieldMeta};

use crate::database::ReleaseView;
use crate::error::{ReaderError, Result};

/// A decoded heightfield: heights in metres (ground frame) on the grid of `meta`.
#[derive(Debug, Clone)]
pub struct Heightfield {
    /// Grid geometry and quantisation.
    pub meta: HeightfieldMeta,
    /// Heights, row-major, row 0 = north edge; `z = z_offset + value * z_scale`.
    /// Where `holes_filled` is true, nodata cells hold the filled surface (see `valid`).
    pub heights: Vec<f32>,
    /// 255 for measured cells, 0 for filled or nodata cells.
    pub valid: Vec<u8>,
}

impl Heightfield {
    /// Height at (col, row), `None` outside the grid.
    pub fn at(&self, col: u32, row: u32) -> Option<f32> {
        if col >= self.meta.width || row >= self.meta.height {
            return None;
        }
        self.heights
            .get(row as usize * self.meta.width as usize + col as usize)
            .copied()
    }
}

/// A decoded PNG image: width, height, bit depth, samples (one channel).
pub struct GreyPng {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples, widened to u16 (8-bit images keep 0..255).
    pub samples: Vec<u16>,
    /// 8 or 16.
    pub bit_depth: u8,
}

/// Decodes a single-channel 8- or 16-bit PNG (no palette, no alpha).
pub fn decode_grey_png(bytes: &[u8], max_side: u32) -> std::result::Result<GreyPng, String> {
    let mut decoder = png::Decoder::new_with_limits(
        std::io::Cursor::new(bytes),
        png::Limits {
            bytes: (max_side as usize)
                .saturating_mul(max_side as usize)
                .saturating_mul(2),
        },
    );
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let (ct, depth) = reader.output_color_type();
    if ct != png::ColorType::Grayscale {
        return Err(format!("expected a greyscale PNG, found {ct:?}"));
    }
    let mut buf = vec![0u8; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    if info.width > max_side || info.height > max_side {
        return Err(format!(
            "image side {}x{} exceeds {max_side}",
            info.width, info.height
        ));
    }
    let n = info.width as usize * info.height as usize;
    let (samples, bit_depth) = match depth {
        png::BitDepth::Sixteen => {
            let mut s = Vec::with_capacity(n);
            for row in buf.chunks(info.line_size).take(info.height as usize) {
                s.extend(
                    row.chunks_exact(2)
                        .take(info.width as usize)
                        .map(|b| u16::from_be_bytes([b[0], b[1]])),
                );
            }
            (s, 16)
        }
        png::BitDepth::Eight => {
            let mut s = Vec::with_capacity(n);
            for row in buf.chunks(info.line_size).take(info.height as usize) {
                s.extend(row.iter().take(info.width as usize).map(|&b| u16::from(b)));
            }
            (s, 8)
        }
        d => return Err(format!("expected 8- or 16-bit samples, found {d:?}")),
    };
    if samples.len() != n {
        return Err("image data shorter than its header says".into());
    }
    Ok(GreyPng {
        width: info.width,
        height: info.height,
        samples,
        bit_depth,
    })
}

impl ReleaseView {
    /// Loads a heightfield entry: metadata, heights (from the 16-bit PNG) and mask, all
    /// verified against their hashes.
    ///
    /// ```no_run
    /// let db = regolith_reader::Database::open("terrain.db")?;
    /// let release = db.release("latest")?;
    /// let hf = release.heightfield("laser/0.015")?;
    /// println!("{} x {} cells of {} m", hf.meta.width, hf.meta.height, hf.meta.cell_m);
    /// # Ok::<(), regolith_reader::ReaderError>(())
    /// ```
    pub fn heightfield(&self, entry: &str) -> Result<Heightfield> {
        let e = self.entry_of_kind(entry, kinds::HEIGHTFIELD)?;
        let decode = |what: &'static str, message: String| ReaderError::Decode {
            entry: entry.to_string(),
            what,
            message,
        };
        let meta: HeightfieldMeta = serde_json::from_value(e.meta.clone())
            .map_err(|m| decode("heightfield metadata", m.to_string()))?;
        let max_side = meta.width.max(meta.height).max(1);
        let png = decode_grey_png(&self.read_file(entry, roles::HEIGHT)?, max_side)
            .map_err(|m| decode("height PNG", m))?;
        let mask = decode_grey_png(&self.read_file(entry, roles::MASK)?, max_side)
            .map_err(|m| decode("mask PNG", m))?;
        for (what, img, depth) in [("height PNG", &png, 16), ("mask PNG", &mask, 8)] {
            if img.width != meta.width || img.height != meta.height || img.bit_depth != depth {
                return Err(decode(
                    what,
                    format!(
                        "expected {}x{} {depth}-bit, found {}x{} {}-bit",
                        meta.width, meta.height, img.width, img.height, img.bit_depth
                    ),
                ));
            }
        }
        let heights = png
            .samples
            .iter()
            .map(|&v| meta.height_of(v) as f32)
            .collect();
        let valid = mask
            .samples
            .iter()
            .map(|&v| if v >= 128 { 255 } else { 0 })
            .collect();
        Ok(Heightfield {
            meta,
            heights,
            valid,
        })
    }
}
