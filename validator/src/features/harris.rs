//! Harris corners, selected as OpenCV's `goodFeaturesToTrack(useHarrisDetector = true)`.
//!
//! Response `R = det(M) − k·tr(M)²` with `M` the structure tensor of 3×3 Sobel gradients summed
//! over a `block_size`² window. OpenCV's `cornerHarris` uses an (unnormalised) box window, not a
//! Gaussian; we keep the box so that our corners and OpenCV's coincide pixel for pixel. A pixel is
//! a corner when `R ≥ quality · max R` and `R` equals the 3×3 maximum; corners are then taken by
//! decreasing response, dropping any closer than `min_distance` to one already taken, up to
//! `max_corners` (0 = no cap). Positions are integer pixels, like OpenCV's.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::image::separable_filter;
use super::image::{combine_rows, filter_row, reach, reflect101, GreyF32};
use super::keypoint::{sort_keypoints, Keypoint};

/// Harris parameters; the defaults are OpenCV's `GFTTDetector::create(1000, 0.01, 1, 3, false,
/// 0.04)` with the Harris switch on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HarrisParams {
    /// Side of the summation window, pixels (OpenCV `blockSize`, default 3).
    pub block_size: usize,
    /// Harris free parameter `k` (default 0.04).
    pub k: f32,
    /// Keep responses `≥ quality × max response` (OpenCV `qualityLevel`, default 0.01).
    pub quality: f32,
    /// Minimum distance between corners, pixels (OpenCV `minDistance`, default 1).
    pub min_distance: f32,
    /// Keep at most this many strongest corners; 0 = all (OpenCV `maxCorners`, default 1000).
    pub max_corners: usize,
}

impl Default for HarrisParams {
    fn default() -> Self {
        HarrisParams {
            block_size: 3,
            k: 0.04,
            quality: 0.01,
            min_distance: 1.0,
            max_corners: 1000,
        }
    }
}

/// Output rows per band of [`harris_response`]: a band's working rows (about 8 planes of
/// `BAND + 4` rows) stay in cache, and the rows recomputed at band edges cost ~25 %.
const BAND: usize = 16;

/// Harris response map (same size as the image).
///
/// Computed band by band of output rows, each band from its own few source rows: 3×3 Sobel
/// gradients, their products, the `block_size` box sums and the response, without a
/// full-size intermediate plane. The arithmetic per pixel is that of chaining
/// [`separable_filter`] passes (Sobel, then the box), so the map is the same bit for bit.
pub fn harris_response(img: &GreyF32, p: &HarrisParams) -> GreyF32 {
    let (w, h) = (img.width, img.height);
    if img.is_degenerate() {
        return GreyF32::zeros(w, h);
    }
    let block = p.block_size.max(1) | 1;
    let window = vec![1.0f32; block];
    let mut data = vec![0.0f32; w * h];
    data.par_chunks_mut(BAND * w)
        .enumerate()
        .for_each(|(band, out)| response_band(img, &window, p.k, band * BAND, out));
    GreyF32 {
        width: w,
        height: h,
        data,
    }
}

/// Rows `lo..=hi` of some per-row quantity, stored contiguously.
struct Rows {
    lo: usize,
    w: usize,
    data: Vec<f32>,
}

impl Rows {
    fn new(lo: usize, hi: usize, w: usize) -> Rows {
        Rows {
            lo,
            w,
            data: vec![0.0; (hi + 1 - lo) * w],
        }
    }
    fn row(&self, y: usize) -> &[f32] {
        let i = y.wrapping_sub(self.lo) * self.w;
        self.data.get(i..i + self.w).unwrap_or(&[])
    }
    fn rows_mut(&mut self) -> impl Iterator<Item = (usize, &mut [f32])> {
        let lo = self.lo;
        self.data
            .chunks_mut(self.w)
            .enumerate()
            .map(move |(i, r)| (lo + i, r))
    }
}

/// The rows of `plane` under the taps `-r..=r` centred on row `y` (reflect-101 in `h` rows).
fn rows(plane: &Rows, y: usize, r: usize, h: usize) -> Vec<&[f32]> {
    (0..2 * r + 1)
        .map(|j| plane.row(reflect101(y as isize + j as isize - r as isize, h)))
        .collect()
}

/// Response rows `y0..y0 + out.len() / w` into `out`.
fn response_band(img: &GreyF32, window: &[f32], k: f32, y0: usize, out: &mut [f32]) {
    const D: [f32; 3] = [-1.0, 0.0, 1.0];
    const S: [f32; 3] = [1.0, 2.0, 1.0];
    let (w, h) = (img.width, img.height);
    let y1 = y0 + out.len() / w;
    let r = window.len() / 2;
    // Rows of the gradient products the box sums reach, and the image rows their Sobel reaches.
    let (plo, phi) = reach(y0, y1, r, h);
    let (ilo, ihi) = reach(plo, phi + 1, 1, h);
    let mut padded = Vec::new();
    let (mut hd, mut hs) = (Rows::new(ilo, ihi, w), Rows::new(ilo, ihi, w));
    for ((y, d), (_, s)) in hd.rows_mut().zip(hs.rows_mut()) {
        filter_row(img.row(y), &D, &mut padded, d);
        filter_row(img.row(y), &S, &mut padded, s);
    }
    let mut boxed = [(); 3].map(|_| Rows::new(plo, phi, w));
    let (mut gx, mut gy) = (vec![0.0f32; w], vec![0.0f32; w]);
    let mut prod = [(); 3].map(|_| vec![0.0f32; w]);
    for y in plo..=phi {
        combine_rows(&rows(&hd, y, 1, h), &S, &mut gx);
        combine_rows(&rows(&hs, y, 1, h), &D, &mut gy);
        let [xx, xy, yy] = &mut prod;
        for (((&a, &b), (pxx, pxy)), pyy) in gx
            .iter()
            .zip(&gy)
            .zip(xx.iter_mut().zip(xy.iter_mut()))
            .zip(yy.iter_mut())
        {
            *pxx = a * a;
            *pxy = a * b;
            *pyy = b * b;
        }
        for (plane, src) in boxed.iter_mut().zip(&prod) {
            let i = (y - plo) * w;
            if let Some(dst) = plane.data.get_mut(i..i + w) {
                filter_row(src, window, &mut padded, dst);
            }
        }
    }
    let mut sums = [(); 3].map(|_| vec![0.0f32; w]);
    for (y, row) in (y0..y1).zip(out.chunks_mut(w)) {
        for (sum, plane) in sums.iter_mut().zip(&boxed) {
            combine_rows(&rows(plane, y, r, h), window, sum);
        }
        let [a, b, c] = &sums;
        for (((o, &a), &b), &c) in row.iter_mut().zip(a).zip(b).zip(c) {
            *o = a * c - b * b - k * (a + c) * (a + c);
        }
    }
}

/// Harris corners (see the module docs).
pub fn detect_harris(img: &GreyF32, p: &HarrisParams) -> Vec<Keypoint> {
    if img.is_degenerate() || img.width < 3 || img.height < 3 {
        return Vec::new();
    }
    let r = harris_response(img, p);
    let max = r.data.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    if max.is_nan() || max <= 0.0 {
        return Vec::new();
    }
    let thr = max * p.quality;
    let w = img.width;
    let val = |x: usize, y: usize| {
        let v = r.at(x, y);
        if v >= thr {
            v
        } else {
            0.0
        }
    };
    let mut cands: Vec<Keypoint> = (1..img.height - 1)
        .into_par_iter()
        .flat_map_iter(|y| {
            (1..w - 1).filter_map(move |x| {
                let v = val(x, y);
                let is_max =
                    v > 0.0 && (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| val(xx, yy) <= v));
                is_max.then(|| Keypoint::at(x as f32, y as f32, p.block_size as f32, v))
            })
        })
        .collect();
    sort_keypoints(&mut cands);
    select_spaced(cands, p.min_distance, p.max_corners, w, img.height)
}

/// Greedy selection in the given order: drop points closer than `min_distance` to one already
/// kept (squared distance `<` min², as OpenCV), stop after `max` points (0 = no cap).
pub fn select_spaced(
    cands: Vec<Keypoint>,
    min_distance: f32,
    max: usize,
    width: usize,
    height: usize,
) -> Vec<Keypoint> {
    let cap = if max == 0 { usize::MAX } else { max };
    if min_distance < 1.0 {
        return cands.into_iter().take(cap).collect();
    }
    let cell = min_distance.max(1.0);
    let gw = (width as f32 / cell) as usize + 1;
    let gh = (height as f32 / cell) as usize + 1;
    let mut grid: Vec<Vec<(f32, f32)>> = vec![Vec::new(); gw * gh];
    let md2 = min_distance * min_distance;
    let mut out = Vec::new();
    for kp in cands {
        if out.len() >= cap {
            break;
        }
        let cx = (kp.x / cell) as usize;
        let cy = (kp.y / cell) as usize;
        let near = (cy.saturating_sub(1)..=(cy + 1).min(gh - 1)).any(|gy| {
            (cx.saturating_sub(1)..=(cx + 1).min(gw - 1)).any(|gx| {
                grid.get(gy * gw + gx).is_some_and(|c| {
                    c.iter()
                        .any(|&(x, y)| (x - kp.x).powi(2) + (y - kp.y).powi(2) < md2)
                })
            })
        });
        if !near {
            if let Some(c) = grid.get_mut(cy * gw + cx) {
                c.push((kp.x, kp.y));
            }
            out.push(kp);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::image::separable_filter;

    /// The response as the plain chain of full-image filters: Sobel, products, box, formula.
    fn chained(img: &GreyF32, p: &HarrisParams) -> Vec<f32> {
        const D: [f32; 3] = [-1.0, 0.0, 1.0];
        const S: [f32; 3] = [1.0, 2.0, 1.0];
        let (gx, gy) = (separable_filter(img, &D, &S), separable_filter(img, &S, &D));
        let plane = |f: &dyn Fn(f32, f32) -> f32| {
            let data = gx.data.iter().zip(&gy.data).map(|(&a, &b)| f(a, b));
            let window = vec![1.0f32; p.block_size | 1];
            let m =
                GreyF32::new(img.width, img.height, data.collect()).unwrap_or_else(|| img.clone());
            separable_filter(&m, &window, &window).data
        };
        let (a, b, c) = (
            plane(&|a, _| a * a),
            plane(&|a, b| a * b),
            plane(&|_, b| b * b),
        );
        (0..a.len())
            .map(|i| a[i] * c[i] - b[i] * b[i] - p.k * (a[i] + c[i]) * (a[i] + c[i]))
            .collect()
    }

    #[test]
    fn banded_response_is_the_filter_chain_bit_for_bit() {
        let mut s = 12345u32;
        for (w, h) in [(37, 53), (5, 3), (64, 16), (20, 33)] {
            let data = (0..w * h)
                .map(|_| {
                    s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (s >> 8) as f32 / 16_777_216.0
                })
                .collect();
            let img = GreyF32::new(w, h, data).unwrap_or_else(|| GreyF32::zeros(w, h));
            for block_size in [1, 3, 5, 7] {
                let p = HarrisParams {
                    block_size,
                    ..HarrisParams::default()
                };
                let got: Vec<u32> = harris_response(&img, &p)
                    .data
                    .iter()
                    .map(|v| v.to_bits())
                    .collect();
                let want: Vec<u32> = chained(&img, &p).iter().map(|v| v.to_bits()).collect();
                assert_eq!(got, want, "{w}x{h} block {block_size}");
            }
        }
    }
}
