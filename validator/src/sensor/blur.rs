//! Separable Gaussian filtering, shared by the image blur (PSF, in pixels) and the texture
//! low-pass (in albedo cells).
//!
//! The kernel is the sampled Gaussian truncated at `ceil(3 sigma)` and normalised to sum 1;
//! borders replicate the edge value so a constant image stays constant. Each output value is
//! computed independently (rows in parallel, fixed summation order), so the result does not
//! depend on the thread count.

use rayon::prelude::*;

/// Gaussian-filters a row-major `width x height` raster. `sigma <= 0` (or non-finite) returns
/// the input unchanged; a raster shorter than `width * height` is returned unchanged too.
pub fn gaussian_blur(data: &[f32], width: usize, height: usize, sigma: f64) -> Vec<f32> {
    if !(sigma > 0.0 && sigma.is_finite())
        || width == 0
        || data.len() < width.saturating_mul(height)
    {
        return data.to_vec();
    }
    let kernel = &kernel(sigma, width.max(height));
    let horizontal: Vec<f32> = data
        .par_chunks(width)
        .take(height)
        .flat_map_iter(|row| {
            (0..width).map(|c| convolve(kernel, c, width, |i| row.get(i).copied()))
        })
        .collect();
    (0..height)
        .into_par_iter()
        .flat_map_iter(|r| {
            let src = &horizontal;
            (0..width)
                .map(move |c| convolve(kernel, r, height, |i| src.get(i * width + c).copied()))
        })
        .collect()
}

/// Normalised weights for offsets `-radius..=radius`; the radius never exceeds `max_len`.
fn kernel(sigma: f64, max_len: usize) -> Vec<f64> {
    let radius = ((3.0 * sigma).ceil() as usize).clamp(1, max_len.max(1));
    let raw: Vec<f64> = (0..=2 * radius)
        .map(|i| {
            let x = i as f64 - radius as f64;
            (-x * x / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.into_iter().map(|w| w / sum).collect()
}

/// One output value at position `at` of a line of `len` values read through `get`.
fn convolve(kernel: &[f64], at: usize, len: usize, get: impl Fn(usize) -> Option<f32>) -> f32 {
    let radius = kernel.len() / 2;
    let mut acc = 0.0f64;
    for (k, w) in kernel.iter().enumerate() {
        let i = (at + k).saturating_sub(radius).min(len.saturating_sub(1));
        acc += w * f64::from(get(i).unwrap_or(0.0));
    }
    acc as f32
}
