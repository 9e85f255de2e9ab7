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

use super::image::{separable_filter, sobel, GreyF32};
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

/// Harris response map (same size as the image).
pub fn harris_response(img: &GreyF32, p: &HarrisParams) -> GreyF32 {
    let (gx, gy) = sobel(img);
    let n = gx.data.len();
    let (mut xx, mut xy, mut yy) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
    for (((&a, &b), (pxx, pxy)), pyy) in gx
        .data
        .iter()
        .zip(&gy.data)
        .zip(xx.iter_mut().zip(xy.iter_mut()))
        .zip(yy.iter_mut())
    {
        *pxx = a * a;
        *pxy = a * b;
        *pyy = b * b;
    }
    let window = vec![1.0f32; p.block_size.max(1) | 1];
    let sum = |m: Vec<f32>| {
        let plane = GreyF32 {
            width: img.width,
            height: img.height,
            data: m,
        };
        separable_filter(&plane, &window, &window)
    };
    let (a, b, c) = (sum(xx), sum(xy), sum(yy));
    let data = a
        .data
        .par_iter()
        .zip(&b.data)
        .zip(&c.data)
        .map(|((&a, &b), &c)| a * c - b * b - p.k * (a + c) * (a + c))
        .collect();
    GreyF32 {
        width: img.width,
        height: img.height,
        data,
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
