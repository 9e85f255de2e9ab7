//! The grey image type and the filters every detector shares.
//!
//! [`GreyF32`] holds row-major `f32` samples; detector inputs are in `[0, 1]` (8-bit images
//! are `level / 255`), while detectors reuse the type for intermediate planes in other units
//! (SIFT's scale space works in 0..255 so its thresholds are OpenCV's). Filters follow
//! OpenCV's conventions so that keypoints can be compared with it pixel for pixel: Gaussian
//! kernels sized `round(8σ + 1) | 1` (OpenCV's size for float images), normalised, and
//! `BORDER_REFLECT_101` borders everywhere (`dcb|abcd|cba`).
//!
//! Rows are filtered in parallel with indexed rayon iterators; each output row is a pure
//! function of the input, so results are bit-identical on any thread count.

use rayon::prelude::*;

/// A grey image, row-major, `data.len() == width * height`.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyF32 {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Samples, row-major.
    pub data: Vec<f32>,
}

impl GreyF32 {
    /// An image from samples; `None` if `data.len() != width * height`.
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Option<GreyF32> {
        (width.checked_mul(height) == Some(data.len())).then_some(GreyF32 {
            width,
            height,
            data,
        })
    }

    /// An image of zeros.
    pub fn zeros(width: usize, height: usize) -> GreyF32 {
        GreyF32 {
            width,
            height,
            data: vec![0.0; width * height],
        }
    }

    /// An image from 8-bit levels (`level / 255`); `None` on a size mismatch.
    pub fn from_u8(width: usize, height: usize, levels: &[u8]) -> Option<GreyF32> {
        let data = levels.iter().map(|&v| f32::from(v) / 255.0).collect();
        GreyF32::new(width, height, data)
    }

    /// True when the image has no pixels or its buffer does not match its size (a truncated
    /// image); detectors return nothing for such an image.
    pub fn is_degenerate(&self) -> bool {
        self.width == 0
            || self.height == 0
            || self.width.checked_mul(self.height) != Some(self.data.len())
    }

    /// 8-bit levels: `round(255 v)` clamped to 0..=255 (`NaN` → 0), see [`to_levels`].
    pub fn to_u8(&self) -> Vec<u8> {
        let mut out = vec![0u8; self.data.len()];
        to_levels(&self.data, &mut out);
        out
    }

    /// Sample at `(x, y)`, `0` outside (callers keep inside; this never panics).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data.get(y * self.width + x).copied().unwrap_or(0.0)
    }

    /// Row `y` (empty outside).
    #[inline]
    pub fn row(&self, y: usize) -> &[f32] {
        self.data
            .get(y * self.width..(y + 1) * self.width)
            .unwrap_or(&[])
    }

    /// Every sample multiplied by `k`.
    pub fn scaled(&self, k: f32) -> GreyF32 {
        GreyF32 {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(|v| v * k).collect(),
        }
    }
}

/// `round(255 v)` clamped to 0..=255 (`NaN` → 0).
#[inline]
pub fn to_level(v: f32) -> u8 {
    // `as` saturates and maps NaN to 0; adding 0.5 then truncating rounds half up.
    (v * 255.0 + 0.5) as u8
}

/// `round(255 v)` clamped to 0..=255, `NaN` → 0, exactly as [`to_level`] but written so
/// that it vectorises (the saturating `as` casts do not): the conversion every detector starts
/// with, about 1 ms per megapixel as `to_level` per value.
pub fn to_levels(src: &[f32], dst: &mut [u8]) {
    const MAGIC: f32 = 8_388_608.0; // 2^23: adding it rounds [0, 2^23) to an integer.
    for (d, &v) in dst.iter_mut().zip(src) {
        let x = v * 255.0 + 0.5;
        let x = if x > 0.0 { x } else { 0.0 }; // NaN → 0
        let x = if x < 255.0 { x } else { 255.0 };
        // The low mantissa bits of `y` hold x rounded to nearest; truncation is one less when
        // that rounded up.
        let y = x + MAGIC;
        *d = (y.to_bits() - u32::from(y - MAGIC > x)) as u8;
    }
}

/// OpenCV's `BORDER_REFLECT_101` index into `0..n` (`n > 0`).
#[inline]
pub fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n <= 1 {
        return 0;
    }
    let mut i = i;
    loop {
        if i < 0 {
            i = -i;
        } else if i >= n {
            i = 2 * n - 2 - i;
        } else {
            return i as usize;
        }
    }
}

/// Normalised Gaussian kernel of OpenCV's size for float images, `round(8σ + 1) | 1` taps.
pub fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    let n = ((sigma.max(1e-3) * 8.0 + 1.0).round() as usize) | 1;
    gaussian_kernel_n(n, sigma)
}

/// Normalised Gaussian kernel with exactly `n` taps (OpenCV `getGaussianKernel(n, σ)`).
pub fn gaussian_kernel_n(n: usize, sigma: f64) -> Vec<f32> {
    let sigma = sigma.max(1e-3);
    let r = (n as f64 - 1.0) / 2.0;
    let w: Vec<f64> = (0..n)
        .map(|i| (-(i as f64 - r).powi(2) / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = w.iter().sum();
    w.iter().map(|v| (v / s) as f32).collect()
}

/// True when `k[i] == k[n − 1 − i]` for every tap (Gaussians, boxes, Sobel's smoothing).
fn is_symmetric(k: &[f32]) -> bool {
    k.iter().zip(k.iter().rev()).all(|(a, b)| a == b)
}

/// One row filtered horizontally with reflect-101 borders, `out[x] = Σ_k kx[k]·src[x + k − r]`.
/// A symmetric kernel adds mirrored samples before multiplying (`k_c·s_0 + Σ_i k_i·(s_−i +
/// s_i)`, OpenCV's order, half the multiplies); any other kernel accumulates tap by tap from
/// zero. `padded` is scratch reused between rows.
pub fn filter_row(src: &[f32], kx: &[f32], padded: &mut Vec<f32>, out: &mut [f32]) {
    let w = src.len();
    let rx = kx.len() / 2;
    padded.clear();
    let at = |i: usize| {
        src.get(reflect101(i as isize - rx as isize, w))
            .copied()
            .unwrap_or(0.0)
    };
    if rx < w {
        // The interior is the row itself; only the borders are reflected.
        padded.extend((0..rx).map(at));
        padded.extend_from_slice(src);
        padded.extend((w + rx..w + 2 * rx).map(at));
    } else {
        padded.extend((0..w + 2 * rx).map(at));
    }
    let rows: Vec<&[f32]> = (0..kx.len())
        .map(|k| padded.get(k..k + w).unwrap_or(&[]))
        .collect();
    combine_rows(&rows, kx, out);
}

/// `out[x] = Σ_j ky[j]·rows[j][x]` in [`filter_row`]'s order (the vertical half of a separable
/// filter; `rows` are the source rows under the taps, already reflected).
pub fn combine_rows(rows: &[&[f32]], ky: &[f32], out: &mut [f32]) {
    let r = ky.len() / 2;
    if ky.len() % 2 == 1 && is_symmetric(ky) {
        let (Some(&kc), Some(centre)) = (ky.get(r), rows.get(r)) else {
            return;
        };
        for (o, s) in out.iter_mut().zip(*centre) {
            *o = kc * s;
        }
        for i in 1..=r {
            let (Some(&k), Some(lo), Some(hi)) = (ky.get(r + i), rows.get(r - i), rows.get(r + i))
            else {
                continue;
            };
            for ((o, a), b) in out.iter_mut().zip(*lo).zip(*hi) {
                *o += k * (a + b);
            }
        }
        return;
    }
    out.fill(0.0);
    for (&k, src) in ky.iter().zip(rows) {
        for (o, s) in out.iter_mut().zip(*src) {
            *o += k * s;
        }
    }
}

/// Smallest and largest row index reached from rows `y0..y1` by the taps `-r..=r` with
/// reflect-101 borders in an image of `h` rows.
pub fn reach(y0: usize, y1: usize, r: usize, h: usize) -> (usize, usize) {
    let rows = (y0 as isize - r as isize..y1 as isize + r as isize).map(|y| reflect101(y, h));
    rows.fold((usize::MAX, 0), |(lo, hi), y| (lo.min(y), hi.max(y)))
}

/// Separable filtering with odd-length kernels per axis, reflect-101 borders.
///
/// Works in bands of output rows: a band filters the source rows it reaches horizontally into
/// its own scratch (reused from band to band, about 1 MB), then combines them vertically, so
/// no full-size intermediate plane is allocated and the rows stay in cache. Each output row is
/// the same arithmetic whatever the banding, so results are bit-identical on any thread count.
pub fn separable_filter(img: &GreyF32, kx: &[f32], ky: &[f32]) -> GreyF32 {
    let (w, h) = (img.width, img.height);
    if img.is_degenerate() {
        return img.clone();
    }
    let ry = ky.len() / 2;
    // Rows recomputed at band edges (2·ry per band) stay below a quarter of the work.
    let band = (8 * ry).max(64);
    let mut data = vec![0.0f32; w * h];
    data.par_chunks_mut(band * w).enumerate().for_each_init(
        || (Vec::new(), Vec::new()),
        |(padded, tmp), (b, out)| {
            let (y0, y1) = (b * band, b * band + out.len() / w);
            let (lo, hi) = reach(y0, y1, ry, h);
            tmp.clear();
            tmp.resize((hi + 1 - lo) * w, 0.0);
            for (i, row) in tmp.chunks_mut(w).enumerate() {
                filter_row(img.row(lo + i), kx, padded, row);
            }
            let tmp: &[f32] = tmp;
            for (y, o) in (y0..y1).zip(out.chunks_mut(w)) {
                let rows: Vec<&[f32]> = (0..ky.len())
                    .map(|j| {
                        let sy = reflect101(y as isize + j as isize - ry as isize, h) - lo;
                        tmp.get(sy * w..(sy + 1) * w).unwrap_or(&[])
                    })
                    .collect();
                combine_rows(&rows, ky, o);
            }
        },
    );
    GreyF32 {
        width: w,
        height: h,
        data,
    }
}

/// Gaussian blur with standard deviation `sigma` px (OpenCV `GaussianBlur(src, Size(), σ)`
/// on a float image).
pub fn gaussian_blur(img: &GreyF32, sigma: f64) -> GreyF32 {
    let k = gaussian_kernel(sigma);
    separable_filter(img, &k, &k)
}

/// Every second pixel in both directions: `dst(x, y) = src(2x, 2y)` (OpenCV `resize` with
/// `INTER_NEAREST` to half size, as SIFT uses between octaves).
pub fn decimate2(img: &GreyF32) -> GreyF32 {
    let (w, h) = (img.width / 2, img.height / 2);
    let data = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| img.at(2 * x, 2 * y))
        .collect();
    GreyF32 {
        width: w,
        height: h,
        data,
    }
}

/// Bilinear doubling (OpenCV `resize(.., INTER_LINEAR)` to twice the size): destination
/// pixel `u` samples the source at `(u + 0.5) / 2 - 0.5`, clamped at the borders.
pub fn upsample2(img: &GreyF32) -> GreyF32 {
    let (w, h) = (img.width * 2, img.height * 2);
    let taps = |u: usize, n: usize| -> (usize, usize, f32) {
        let s = ((u as f32 + 0.5) * 0.5 - 0.5).max(0.0);
        let i0 = (s.floor() as usize).min(n - 1);
        let i1 = (i0 + 1).min(n - 1);
        (i0, i1, s - i0 as f32)
    };
    let columns: Vec<(usize, usize, f32)> = (0..w).map(|x| taps(x, img.width)).collect();
    let mut data = vec![0.0f32; w * h];
    data.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let (y0, y1, fy) = taps(y, img.height);
        let (r0, r1) = (img.row(y0), img.row(y1));
        for (o, &(x0, x1, fx)) in out.iter_mut().zip(&columns) {
            let g = |r: &[f32], i: usize| r.get(i).copied().unwrap_or(0.0);
            let top = g(r0, x0) * (1.0 - fx) + g(r0, x1) * fx;
            let bottom = g(r1, x0) * (1.0 - fx) + g(r1, x1) * fx;
            *o = top * (1.0 - fy) + bottom * fy;
        }
    });
    GreyF32 {
        width: w,
        height: h,
        data,
    }
}

/// Integral image of 8-bit levels, `(width + 1) × (height + 1)`, `sum[y][x]` = sum of the
/// pixels above and left of `(x, y)` (OpenCV `integral`).
#[derive(Debug, Clone)]
pub struct Integral {
    /// Columns of the sum table (`image width + 1`).
    pub stride: usize,
    /// Rows of the sum table (`image height + 1`).
    pub rows: usize,
    /// The sums.
    pub sum: Vec<i64>,
}

impl Integral {
    /// Integral of the image's 8-bit levels (see [`GreyF32::to_u8`]).
    pub fn of_levels(img: &GreyF32) -> Integral {
        let (w, h) = (img.width, img.height);
        let stride = w + 1;
        let mut sum = vec![0i64; stride * (h + 1)];
        let levels = img.to_u8();
        for y in 0..h {
            let mut acc = 0i64;
            for x in 0..w {
                acc += i64::from(levels.get(y * w + x).copied().unwrap_or(0));
                let above = sum.get(y * stride + x + 1).copied().unwrap_or(0);
                if let Some(s) = sum.get_mut((y + 1) * stride + x + 1) {
                    *s = above + acc;
                }
            }
        }
        Integral {
            stride,
            rows: h + 1,
            sum,
        }
    }

    /// Sum of the pixels in columns `x0..x1`, rows `y0..y1` (0 if out of range).
    #[inline]
    pub fn rect(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> i64 {
        let g = |x: usize, y: usize| self.sum.get(y * self.stride + x).copied().unwrap_or(0);
        g(x1, y1) - g(x0, y1) - g(x1, y0) + g(x0, y0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_match_to_level() {
        let mut v: Vec<f32> = (0..=255).map(|l| l as f32 / 255.0).collect();
        // Every half-level tie and its float neighbours, plus values outside [0, 1].
        for k in 0..=512 {
            let x = (k as f32 - 0.5) / 255.0;
            v.extend([x, x.next_down(), x.next_up()]);
        }
        v.extend([
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            -1e-30,
            1e30,
            2.0,
        ]);
        let mut got = vec![0u8; v.len()];
        to_levels(&v, &mut got);
        for (x, g) in v.iter().zip(&got) {
            assert_eq!(*g, to_level(*x), "{x:e}");
        }
    }
}
