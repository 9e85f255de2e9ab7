//! Camera images (PNG, TIFF, JPEG; 8 or 16 bit; grey, RGB or RGBA) as grey `f32` images.
//!
//! Every stage that looks at pixels (undistortion, feature detection, texturing checks) works on
//! one grey type, [`GreyImage`]: row-major, row 0 at the top, values in `[0, 1]`. Design decisions:
//!
//! - **Grey, not colour.** Colour is converted with the Rec. 601 luma weights
//!   `Y = 0.299 R + 0.587 G + 0.114 B` (what OpenCV's `cvtColor(RGB2GRAY)` and most feature
//!   detectors use), so our grey values match the peers. Alpha is ignored.
//! - **Bit depth is kept**: values are divided by 255 or 65535 and [`GreyImage::bit_depth`]
//!   remembers which, so a 16-bit frame is not silently quantised to 8 bits. Float TIFFs get
//!   `bit_depth = 32` and are clamped to `[0, 1]`.
//! - **Limits before decoding**: the header is read first and the side length is checked against
//!   [`Limits::max_image_side`], and the `f32` buffer against `max_alloc_bytes`, before the
//!   decoder allocates anything; the decoder also receives the same limits.
//! - Decoding uses the `image` crate (pure Rust codecs). A truncated or corrupt file is an
//!   [`IngestError::Invalid`] naming the format and the decoder's reason; [`read_path`] adds the
//!   file name.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageEncoder, ImageReader};
use regolith_format::limits::Limits;

use crate::error::{IngestError, Result};

/// A grey image with values in `[0, 1]`, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Bits per sample of the source (8, 16, or 32 for float).
    pub bit_depth: u8,
    /// `width * height` values in `[0, 1]`.
    pub data: Vec<f32>,
}

impl GreyImage {
    /// A black image of the given size; fails when it would exceed `limits`.
    pub fn new(width: u32, height: u32, bit_depth: u8, limits: &Limits) -> Result<GreyImage> {
        check_side(width, height, limits)?;
        let n = u64::from(width) * u64::from(height);
        let mut data = limits.vec_with_capacity::<f32>("grey image pixels", n)?;
        data.resize(n as usize, 0.0);
        Ok(GreyImage {
            width,
            height,
            bit_depth,
            data,
        })
    }

    /// The value at column `x`, row `y`, or `None` outside the image.
    pub fn get(&self, x: u32, y: u32) -> Option<f32> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.data
            .get(y as usize * self.width as usize + x as usize)
            .copied()
    }

    /// Encodes the image as an 8-bit grey PNG (values rounded to the nearest of 0..=255).
    pub fn to_u8(&self) -> Result<Vec<u8>> {
        let px: Vec<u8> = self
            .data
            .iter()
            .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect();
        self.encode_png(&px, image::ExtendedColorType::L8)
    }

    /// Encodes the image as a 16-bit grey PNG (values rounded to the nearest of 0..=65535).
    pub fn to_u16(&self) -> Result<Vec<u8>> {
        // The encoder takes 16-bit samples in native byte order.
        let px: Vec<u8> = self
            .data
            .iter()
            .flat_map(|v| ((v.clamp(0.0, 1.0) * 65535.0).round() as u16).to_ne_bytes())
            .collect();
        self.encode_png(&px, image::ExtendedColorType::L16)
    }

    fn encode_png(&self, px: &[u8], color: image::ExtendedColorType) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(px, self.width, self.height, color)
            .map_err(|e| IngestError::invalid(format!("cannot encode PNG: {e}")))?;
        Ok(out)
    }
}

/// Reads an image file into a [`GreyImage`]; errors name the file.
pub fn read_path(path: &Path, limits: &Limits) -> Result<GreyImage> {
    let bytes = read_file(path, limits)?;
    decode(&bytes, limits).map_err(|e| e.in_file(path))
}

/// The `(width, height)` of an image file from its header alone (nothing is decoded), for
/// checks that must be cheap; errors name the file.
pub fn dimensions_path(path: &Path) -> Result<(u32, u32)> {
    let wrap = |e: IngestError| e.in_file(path);
    let reader = ImageReader::open(path)
        .and_then(ImageReader::with_guessed_format)
        .map_err(|e| wrap(e.into()))?;
    if reader.format().is_none() {
        return Err(wrap(IngestError::syntax(
            "a PNG, TIFF or JPEG signature",
            "another file kind",
        )));
    }
    reader.into_dimensions().map_err(|e| {
        wrap(IngestError::invalid(format!(
            "cannot read the image header: {e}"
        )))
    })
}

/// Decodes PNG, TIFF or JPEG bytes into a [`GreyImage`].
pub fn decode(bytes: &[u8], limits: &Limits) -> Result<GreyImage> {
    let img = decode_dynamic(bytes, limits)?;
    let (width, height) = (img.width(), img.height());
    let n = u64::from(width) * u64::from(height);
    let mut data = limits.vec_with_capacity::<f32>("grey image pixels", n)?;
    let bit_depth = match &img {
        DynamicImage::ImageLuma8(b) => push_grey(&mut data, b.as_raw(), 1, 255.0, 8),
        DynamicImage::ImageLumaA8(b) => push_grey(&mut data, b.as_raw(), 2, 255.0, 8),
        DynamicImage::ImageRgb8(b) => push_grey(&mut data, b.as_raw(), 3, 255.0, 8),
        DynamicImage::ImageRgba8(b) => push_grey(&mut data, b.as_raw(), 4, 255.0, 8),
        DynamicImage::ImageLuma16(b) => push_grey(&mut data, b.as_raw(), 1, 65535.0, 16),
        DynamicImage::ImageLumaA16(b) => push_grey(&mut data, b.as_raw(), 2, 65535.0, 16),
        DynamicImage::ImageRgb16(b) => push_grey(&mut data, b.as_raw(), 3, 65535.0, 16),
        DynamicImage::ImageRgba16(b) => push_grey(&mut data, b.as_raw(), 4, 65535.0, 16),
        other => push_grey(&mut data, other.to_rgb32f().as_raw(), 3, 1.0, 32),
    };
    Ok(GreyImage {
        width,
        height,
        bit_depth,
        data,
    })
}

/// Decodes an image after checking its header dimensions against `limits` (shared with the
/// CMPMVS DEM reader, which needs the raw 16-bit samples).
pub(crate) fn decode_dynamic(bytes: &[u8], limits: &Limits) -> Result<DynamicImage> {
    let reader = || -> Result<ImageReader<Cursor<&[u8]>>> {
        let r = ImageReader::new(Cursor::new(bytes)).with_guessed_format()?;
        if r.format().is_none() {
            let head: String = bytes.iter().take(8).map(|b| format!("{b:02x}")).collect();
            return Err(IngestError::syntax("a PNG, TIFF or JPEG signature", &head));
        }
        Ok(r)
    };
    let format = reader()?
        .format()
        .map(|f| format!("{f:?}"))
        .unwrap_or_default();
    let fail = |e: image::ImageError| IngestError::invalid(format!("cannot decode {format}: {e}"));
    let (width, height) = reader()?.into_dimensions().map_err(fail)?;
    check_side(width, height, limits)?;
    // 4 channels x 4 bytes is the largest buffer the decoder may produce.
    let decoded_bytes = u64::from(width) * u64::from(height) * 16;
    Limits::check_len("decoded image bytes", decoded_bytes, limits.max_alloc_bytes)?;
    let mut lim = image::Limits::default();
    lim.max_image_width = Some(limits.max_image_side);
    lim.max_image_height = Some(limits.max_image_side);
    lim.max_alloc = Some(limits.max_alloc_bytes);
    let mut r = reader()?;
    r.limits(lim);
    r.decode().map_err(fail)
}

/// Reads a whole file after checking its size against `limits.max_object_bytes`; errors name
/// the file. Shared by the readers of this family (VRML, COLMAP, CMPMVS, images).
pub(crate) fn read_file(path: &Path, limits: &Limits) -> Result<Vec<u8>> {
    let wrap = |e: IngestError| e.in_file(path);
    let len = std::fs::metadata(path).map_err(|e| wrap(e.into()))?.len();
    Limits::check_len("file bytes", len, limits.max_object_bytes).map_err(|e| wrap(e.into()))?;
    std::fs::read(path).map_err(|e| wrap(e.into()))
}

fn check_side(width: u32, height: u32, limits: &Limits) -> Result<()> {
    let side = width.max(height);
    Limits::check_len(
        "image side",
        u64::from(side),
        u64::from(limits.max_image_side),
    )?;
    if width == 0 || height == 0 {
        return Err(IngestError::invalid(format!(
            "image is {width}x{height}: expected pixels"
        )));
    }
    Ok(())
}

/// Appends the grey value of every pixel of interleaved `samples` (1–4 channels) and returns
/// `bit_depth`.
fn push_grey<T: Copy + Into<f64>>(
    out: &mut Vec<f32>,
    samples: &[T],
    channels: usize,
    scale: f64,
    bit_depth: u8,
) -> u8 {
    for px in samples.chunks_exact(channels) {
        let c = |i: usize| px.get(i).map_or(0.0, |&v| v.into()) / scale;
        let v = if channels >= 3 {
            0.299 * c(0) + 0.587 * c(1) + 0.114 * c(2)
        } else {
            c(0)
        };
        out.push(v.clamp(0.0, 1.0) as f32);
    }
    bit_depth
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip_keeps_16_bit_values() {
        let mut img = GreyImage::new(3, 2, 16, &Limits::default()).unwrap();
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = (i as f32 * 12345.0) / 65535.0;
        }
        let back = decode(&img.to_u16().unwrap(), &Limits::default()).unwrap();
        assert_eq!(back.bit_depth, 16);
        assert_eq!((back.width, back.height), (3, 2));
        for (a, b) in img.data.iter().zip(&back.data) {
            assert_eq!((a * 65535.0).round(), (b * 65535.0).round());
        }
    }

    #[test]
    fn side_limit_is_checked_before_decoding() {
        let img = GreyImage::new(40, 4, 8, &Limits::default()).unwrap();
        let small = Limits {
            max_image_side: 39,
            ..Limits::default()
        };
        let err = decode(&img.to_u8().unwrap(), &small)
            .unwrap_err()
            .to_string();
        assert!(err.contains("image side"), "{err}");
    }
}
