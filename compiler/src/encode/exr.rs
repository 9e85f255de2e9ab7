//! Single-channel float32 OpenEXR (channel `Y`), written without threads for reproducible bytes.

use ::exr::prelude::*;

use super::EncodeError;

/// Encodes a float grid (row-major, row 0 at the top). NaN is kept as NaN (nodata).
pub fn grey_f32(
    width: usize,
    height: usize,
    values: &[f32],
) -> std::result::Result<Vec<u8>, EncodeError> {
    if values.len() != width * height {
        return Err(EncodeError::new(
            "EXR",
            format!("{} values for {width}x{height}", values.len()),
        ));
    }
    let channel = AnyChannel::new("Y", FlatSamples::F32(values.to_vec()));
    let layer = Layer::new(
        (width, height),
        LayerAttributes::named("height"),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(vec![channel].into()),
    );
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| EncodeError::new("EXR", e))?;
    Ok(out.into_inner())
}

/// Decodes the first float channel of an EXR (for tests and export round trips).
pub fn read_grey_f32(bytes: &[u8]) -> std::result::Result<(usize, usize, Vec<f32>), EncodeError> {
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| EncodeError::new("EXR", e))?;
    let layer = image.layer_data;
    let size = layer.size;
    let ch = layer
        .channel_data
        .list
        .first()
        .ok_or_else(|| EncodeError::new("EXR", "no channel"))?;
    let values = match &ch.sample_data {
        FlatSamples::F32(v) => v.clone(),
        FlatSamples::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
        FlatSamples::U32(v) => v.iter().map(|&u| u as f32).collect(),
    };
    Ok((size.width(), size.height(), values))
}
