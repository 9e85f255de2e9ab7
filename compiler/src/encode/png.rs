//! PNG encoders with pinned settings (zlib level, adaptive filter), so bytes are reproducible.

use super::EncodeError;

/// Pixel layouts the encoders write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// 8-bit greyscale.
    Grey8,
    /// 16-bit greyscale (samples big-endian in the file, as PNG requires).
    Grey16,
    /// 8-bit RGB.
    Rgb8,
}

fn encode(width: u32, height: u32, layout: Layout, data: &[u8]) -> Result<Vec<u8>, EncodeError> {
    let mut out = Vec::new();
    {
        let mut enc = ::png::Encoder::new(&mut out, width, height);
        let (ct, depth) = match layout {
            Layout::Grey8 => (::png::ColorType::Grayscale, ::png::BitDepth::Eight),
            Layout::Grey16 => (::png::ColorType::Grayscale, ::png::BitDepth::Sixteen),
            Layout::Rgb8 => (::png::ColorType::Rgb, ::png::BitDepth::Eight),
        };
        enc.set_color(ct);
        enc.set_depth(depth);
        enc.set_compression(::png::Compression::Default);
        enc.set_filter(::png::FilterType::Paeth);
        enc.set_adaptive_filter(::png::AdaptiveFilterType::NonAdaptive);
        let mut w = enc.write_header().map_err(|e| EncodeError::new("PNG", e))?;
        w.write_image_data(data)
            .map_err(|e| EncodeError::new("PNG", e))?;
        w.finish().map_err(|e| EncodeError::new("PNG", e))?;
    }
    Ok(out)
}

/// Encodes 8-bit grey samples (row-major, row 0 at the top).
pub fn grey8(width: u32, height: u32, samples: &[u8]) -> Result<Vec<u8>, EncodeError> {
    encode(width, height, Layout::Grey8, samples)
}

/// Encodes 16-bit grey samples.
pub fn grey16(width: u32, height: u32, samples: &[u16]) -> Result<Vec<u8>, EncodeError> {
    let bytes: Vec<u8> = samples.iter().flat_map(|v| v.to_be_bytes()).collect();
    encode(width, height, Layout::Grey16, &bytes)
}

/// Encodes 8-bit RGB samples.
pub fn rgb8(width: u32, height: u32, samples: &[[u8; 3]]) -> Result<Vec<u8>, EncodeError> {
    let bytes: Vec<u8> = samples.iter().flatten().copied().collect();
    encode(width, height, Layout::Rgb8, &bytes)
}
