//! Separable Gaussian filtering, shared by the image blur (PSF, in pixels) and the texture
//! low-pass (in albedo cells).
//!
//! The kernel is the sampled Gaussian truncated at `ceil(3 sigma)` and normalised to sum 1;
//! borders replicate the edge value so a constant image stays constant. Each pass sums a line's
//! values tap by tap, all in the same fixed order (lines in parallel), so the result does not
//! depend on the thread count; summing a whole line per tap rather than one value at a time
//! lets the loop vectorise (the band-passes of `gap`'s geometric stage are built from these).

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
    let radius = kernel.len() / 2;
    let mut horizontal = vec![0.0f32; width * height];
    horizontal
        .par_chunks_mut(width)
        .zip(data.par_chunks(width))
        .for_each(|(out, row)| {
            // The row with its edge values replicated `radius` times either side: tap `k` of
            // output `c` is `padded[c + k]`.
            let padded: Vec<f64> = (0..width + 2 * radius)
                .map(|j| f64::from(row[j.saturating_sub(radius).min(width - 1)]))
                .collect();
            accumulate(kernel, out, |k| &padded[k..k + width], f64::clone);
        });
    let mut out = vec![0.0f32; width * height];
    out.par_chunks_mut(width).enumerate().for_each(|(r, out)| {
        accumulate(
            kernel,
            out,
            |k| {
                let i = (r + k).saturating_sub(radius).min(height - 1);
                &horizontal[i * width..(i + 1) * width]
            },
            |x| f64::from(*x),
        );
    });
    out
}

/// One line of output: `out[c] = Σ_k kernel[k] · tap(k)[c]`, summed tap by tap in `k`'s order
/// (the same order for every value, and the line's values side by side, which vectorises).
fn accumulate<'a, T: 'a>(
    kernel: &[f64],
    out: &mut [f32],
    tap: impl Fn(usize) -> &'a [T],
    value: impl Fn(&T) -> f64,
) {
    let mut acc = vec![0.0f64; out.len()];
    for (k, w) in kernel.iter().enumerate() {
        for (a, x) in acc.iter_mut().zip(tap(k)) {
            *a += w * value(x);
        }
    }
    for (o, a) in out.iter_mut().zip(&acc) {
        *o = *a as f32;
    }
}

/// The kernel's radius for `sigma` on a raster whose longer side is `max_len`: `ceil(3 sigma)`,
/// at least 1 and at most `max_len`.
pub fn kernel_radius(sigma: f64, max_len: usize) -> usize {
    ((3.0 * sigma).ceil() as usize).clamp(1, max_len.max(1))
}

/// Normalised weights for offsets `-radius..=radius` ([`kernel_radius`]).
fn kernel(sigma: f64, max_len: usize) -> Vec<f64> {
    let radius = kernel_radius(sigma, max_len);
    let raw: Vec<f64> = (0..=2 * radius)
        .map(|i| {
            let x = i as f64 - radius as f64;
            (-x * x / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.into_iter().map(|w| w / sum).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Each value on its own, as the definition reads: the reference the line-wise passes
    /// must reproduce bit for bit.
    fn one_by_one(data: &[f32], width: usize, height: usize, sigma: f64) -> Vec<f32> {
        let kernel = kernel(sigma, width.max(height));
        let radius = kernel.len() / 2;
        let line = |at: usize, len: usize, get: &dyn Fn(usize) -> f32| {
            let mut acc = 0.0f64;
            for (k, w) in kernel.iter().enumerate() {
                acc += w * f64::from(get((at + k).saturating_sub(radius).min(len - 1)));
            }
            acc as f32
        };
        let horizontal: Vec<f32> = (0..width * height)
            .map(|i| line(i % width, width, &|x| data[(i / width) * width + x]))
            .collect();
        (0..width * height)
            .map(|i| line(i / width, height, &|y| horizontal[y * width + i % width]))
            .collect()
    }

    proptest! {
        #[test]
        fn the_line_wise_passes_equal_the_definition(
            width in 1usize..40,
            height in 1usize..30,
            sigma in 0.3f64..15.0,
            seed in any::<u64>(),
        ) {
            let data: Vec<f32> = (0..width * height)
                .map(|i| {
                    let x = (i as u64 ^ seed).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                    (x >> 40) as f32 / 1000.0
                })
                .collect();
            let got = gaussian_blur(&data, width, height, sigma);
            let want = one_by_one(&data, width, height, sigma);
            prop_assert_eq!(
                got.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                want.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
    }

    #[test]
    fn a_constant_image_stays_constant_and_an_impulse_spreads_as_the_kernel() {
        let flat = gaussian_blur(&[5.0; 64 * 48], 64, 48, 3.0);
        assert!(flat.iter().all(|v| (v - 5.0).abs() < 1e-5));
        let mut dot = vec![0.0f32; 41 * 41];
        dot[20 * 41 + 20] = 1.0;
        let spread = gaussian_blur(&dot, 41, 41, 2.0);
        let sum: f32 = spread.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "{sum}");
        // Separable: the centre row's profile is the kernel times its centre value.
        let k = kernel(2.0, 41);
        let centre = f64::from(spread[20 * 41 + 20]);
        assert!((centre - k[6] * k[6]).abs() < 1e-7, "{centre}");
        assert!((f64::from(spread[20 * 41 + 22]) - k[6] * k[8]).abs() < 1e-7);
    }
}
