//! FAST-9 corners (Rosten & Drummond) with OpenCV's score and non-maximum suppression.
//!
//! FAST is defined on 8-bit levels, so the image is quantised to `round(255 v)` and the
//! threshold converted to levels (`20/255` → 20), exactly as OpenCV sees an 8-bit image. A pixel
//! is a corner when 9 contiguous pixels of the radius-3 Bresenham circle are all brighter than
//! `p + t` or all darker than `p − t`. The score is OpenCV's `cornerScore`: the largest
//! threshold at which the pixel is still a corner, minus one. With suppression on, a corner is
//! kept when its score is strictly above all 8 neighbours' (non-corners score 0). Circle tests
//! use bit masks: a run of 9 set bits in the doubled 16-bit mask.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::image::GreyF32;
use super::keypoint::Keypoint;

/// FAST parameters; defaults are OpenCV's `FastFeatureDetector::create(10, true, TYPE_9_16)`
/// except the threshold, which is the validator's 20/255.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FastParams {
    /// Intensity threshold in image units (`20/255`; converted to 8-bit levels, rounded).
    pub threshold: f32,
    /// Non-maximum suppression over the 3×3 neighbourhood (default on).
    pub nonmax: bool,
}

impl Default for FastParams {
    fn default() -> Self {
        FastParams {
            threshold: 20.0 / 255.0,
            nonmax: true,
        }
    }
}

/// The 16 circle offsets `(dx, dy)` in OpenCV's order.
const CIRCLE: [(isize, isize); 16] = [
    (0, 3),
    (1, 3),
    (2, 2),
    (3, 1),
    (3, 0),
    (3, -1),
    (2, -2),
    (1, -3),
    (0, -3),
    (-1, -3),
    (-2, -2),
    (-3, -1),
    (-3, 0),
    (-3, 1),
    (-2, 2),
    (-1, 3),
];

/// True when the circular 16-bit mask has a run of at least 9 set bits.
#[inline]
fn has_run9(bits: u32) -> bool {
    let m = bits | (bits << 16);
    let r2 = m & (m >> 1);
    let r4 = r2 & (r2 >> 2);
    let r8 = r4 & (r4 >> 4);
    (r8 & (m >> 8)) != 0
}

/// OpenCV's corner score from the differences `d[k] = centre − circle[k]`.
fn corner_score(d: &[i32; 16], threshold: i32) -> i32 {
    let mut best = threshold;
    for start in 0..16 {
        let arc = (0..9).map(|j| d.get((start + j) % 16).copied().unwrap_or(0));
        let lo = arc.clone().min().unwrap_or(0);
        let hi = arc.max().unwrap_or(0);
        best = best.max(lo).max(-hi);
    }
    best - 1
}

/// Score map: 0 for non-corners, `cornerScore + 1` (≥ 1) for corners.
fn score_map(levels: &[u8], w: usize, h: usize, t: i32) -> Vec<i32> {
    let mut scores = vec![0i32; w * h];
    scores
        .par_chunks_mut(w)
        .enumerate()
        .filter(|(y, _)| *y >= 3 && *y + 3 < h)
        .for_each(|(y, row)| {
            // Rows y-3 ..= y+3; circle pixel k of column x is rows[3 + dy][x + dx].
            let rows: Vec<&[u8]> = (0..7)
                .map(|i| levels.get((y + i - 3) * w..(y + i - 2) * w).unwrap_or(&[]))
                .collect();
            let at = |dx: isize, dy: isize, x: usize| -> i32 {
                rows.get((3 + dy) as usize)
                    .and_then(|r| r.get((x as isize + dx) as usize))
                    .map_or(0, |&v| i32::from(v))
            };
            // Any 9-arc holds two of the four compass pixels: a vectorisable pre-pass over the
            // row rejects most pixels before the full circle test.
            let sl = |r: usize, a: usize| {
                rows.get(r)
                    .and_then(|row| row.get(a..(a + w).saturating_sub(6)))
                    .unwrap_or(&[])
            };
            let candidates: Vec<bool> = sl(3, 3)
                .iter()
                .zip(sl(0, 3))
                .zip(sl(6, 3))
                .zip(sl(3, 0))
                .zip(sl(3, 6))
                .map(|((((&p, &u), &d), &l), &r)| {
                    let (p, c) = (i32::from(p), [u, d, l, r].map(i32::from));
                    let nb = c.iter().map(|&v| i32::from(v > p + t)).sum::<i32>();
                    let nd = c.iter().map(|&v| i32::from(v < p - t)).sum::<i32>();
                    nb >= 2 || nd >= 2
                })
                .collect();
            for (x, _) in candidates.iter().enumerate().filter(|(_, &c)| c) {
                let x = x + 3;
                let p = at(0, 0, x);
                let mut d = [0i32; 16];
                let (mut bright, mut dark) = (0u32, 0u32);
                for (k, (&(dx, dy), dk)) in CIRCLE.iter().zip(d.iter_mut()).enumerate() {
                    let v = at(dx, dy, x);
                    *dk = p - v;
                    bright |= u32::from(v > p + t) << k;
                    dark |= u32::from(v < p - t) << k;
                }
                if has_run9(bright) || has_run9(dark) {
                    if let Some(s) = row.get_mut(x) {
                        *s = corner_score(&d, t) + 1;
                    }
                }
            }
        });
    scores
}

/// FAST-9 corners (see the module docs); `response` is the score in 8-bit levels.
pub fn detect_fast(img: &GreyF32, p: &FastParams) -> Vec<Keypoint> {
    if img.is_degenerate() || img.width < 7 || img.height < 7 {
        return Vec::new();
    }
    let (w, h) = (img.width, img.height);
    let t = (p.threshold * 255.0).round().clamp(0.0, 255.0) as i32;
    let levels = img.to_u8();
    let s = score_map(&levels, w, h, t);
    let at = |x: usize, y: usize| s.get(y * w + x).copied().unwrap_or(0);
    (3..h - 3)
        .into_par_iter()
        .flat_map_iter(|y| {
            let row = s.get(y * w..(y + 1) * w).unwrap_or(&[]);
            row.iter()
                .enumerate()
                .filter(|&(_, &v)| v > 0)
                .filter(move |&(x, &v)| {
                    !p.nonmax
                        || (y - 1..=y + 1).all(|yy| {
                            (x - 1..=x + 1).all(|xx| (xx == x && yy == y) || at(xx, yy) < v)
                        })
                })
                .map(|(x, &v)| Keypoint::at(x as f32, y as f32, 7.0, (v - 1) as f32))
                .collect::<Vec<_>>()
        })
        .collect()
}
