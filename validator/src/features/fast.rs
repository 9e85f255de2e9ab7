//! FAST-9 corners (Rosten & Drummond) with OpenCV's score and non-maximum suppression.
//!
//! FAST is defined on 8-bit levels, so the image is quantised to `round(255 v)` and the
//! threshold converted to levels (`20/255` → 20), exactly as OpenCV sees an 8-bit image. A pixel
//! is a corner when 9 contiguous pixels of the radius-3 Bresenham circle are all brighter than
//! `p + t` or all darker than `p − t`. The score is OpenCV's `cornerScore`: the largest
//! threshold at which the pixel is still a corner, minus one. With suppression on, a corner is
//! kept when its score is strictly above all 8 neighbours' (non-corners score 0).
//!
//! Shape: 16 columns at a time as `[u8; 16]` lanes, which the compiler turns into byte SIMD. A
//! quick rejection test on the 4 compass pixels skips most chunks; in the others the corner
//! test and the score are one computation (the best 9-arc minimum of the clamped differences
//! exceeds `t` exactly at corners and is then the score + 1), and suppression only visits
//! chunks holding a corner.

use rayon::prelude::*;

use serde::{Deserialize, Serialize};

use super::image::{to_levels, GreyF32};
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

/// Columns processed together (one SSE2 register of bytes).
const LANES: usize = 16;

/// One byte per column of a chunk.
type Lanes = [u8; LANES];

/// `LANES` bytes of `r` from `at`, if inside.
#[inline(always)]
fn load(r: &[u8], at: usize) -> Option<Lanes> {
    r.get(at..at + LANES).and_then(|s| Lanes::try_from(s).ok())
}

/// True when some lane is non-zero.
#[inline(always)]
fn any(a: Lanes) -> bool {
    u128::from_ne_bytes(a) != 0
}

#[inline(always)]
fn vmin(a: Lanes, b: Lanes) -> Lanes {
    let mut o = a;
    for (o, b) in o.iter_mut().zip(b) {
        *o = (*o).min(b);
    }
    o
}

#[inline(always)]
fn vmax(a: Lanes, b: Lanes) -> Lanes {
    let mut o = a;
    for (o, b) in o.iter_mut().zip(b) {
        *o = (*o).max(b);
    }
    o
}

/// `a − b` per lane, saturating at 0: non-zero exactly where `a > b`.
#[inline(always)]
fn vsubs(a: Lanes, b: Lanes) -> Lanes {
    let mut o = a;
    for (o, b) in o.iter_mut().zip(b) {
        *o = (*o).saturating_sub(b);
    }
    o
}

/// Chunk starts `(s, skip)` covering `0..n` (`n >= LANES`): steps of `LANES`, the last one
/// shifted left to end at `n`; its first `skip` lanes repeat the previous chunk's.
fn chunks(n: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..n.div_ceil(LANES)).map(move |c| {
        let start = c * LANES;
        let s = start.min(n - LANES);
        (s, start - s)
    })
}

/// `max over k of min(e[k], …, e[k + 8])` per lane (indices mod 16). As in OpenCV's
/// `cornerScore`, the arcs starting at `k` and `k + 1` (`k` even) share `e[k + 1 ..= k + 8]`,
/// whose minimum comes from doubling windows.
#[inline(always)]
fn best_arc(e: &[Lanes; 16]) -> Lanes {
    let mut m2 = [[0u8; LANES]; 8];
    for (j, m) in m2.iter_mut().enumerate() {
        *m = vmin(e[(2 * j + 1) & 15], e[(2 * j + 2) & 15]);
    }
    let mut m4 = [[0u8; LANES]; 8];
    for (j, m) in m4.iter_mut().enumerate() {
        *m = vmin(m2[j], m2[(j + 1) & 7]);
    }
    let mut best = [0u8; LANES];
    for j in 0..8 {
        let inner = vmin(m4[j], m4[(j + 2) & 7]);
        let ends = vmax(e[(2 * j) & 15], e[(2 * j + 9) & 15]);
        best = vmax(best, vmin(inner, ends));
    }
    best
}

/// Scores of one row: `srow[x] = score + 1` at corners, 0 elsewhere, for the columns
/// `3..3 + n`. `rows` are rows `y − 3 ..= y + 3`, each `n + 6` long (`n >= LANES`).
fn score_row(rows: &[&[u8]; 7], n: usize, t: u8, srow: &mut [u8]) {
    // ring[k][j] is circle pixel k of column 3 + j.
    let ring: [&[u8]; 16] = CIRCLE.map(|(dx, dy)| {
        let a = 3usize.wrapping_add_signed(dx);
        rows.get(3usize.wrapping_add_signed(dy))
            .and_then(|r| r.get(a..a + n))
            .unwrap_or(&[])
    });
    let centre = rows[3].get(3..3 + n).unwrap_or(&[]);
    for (s, _) in chunks(n) {
        let Some(p) = load(centre, s) else { return };
        let mut v = [[0u8; LANES]; 16];
        for (v, r) in v.iter_mut().zip(&ring) {
            match load(r, s) {
                Some(l) => *v = l,
                None => return,
            }
        }
        let mut hi = [0u8; LANES];
        let mut lo = [0u8; LANES];
        for ((h, l), &c) in hi.iter_mut().zip(lo.iter_mut()).zip(&p) {
            *h = c.saturating_add(t);
            *l = c.saturating_sub(t);
        }
        // Quick rejection: a 9-arc holds two neighbouring compass pixels (0-4, 4-8, 8-12 or
        // 12-0), both brighter or both darker. On the `vsubs` indicators max is "or" and min
        // is "and".
        let b = |k: usize| vsubs(v[k], hi);
        let d = |k: usize| vsubs(lo, v[k]);
        let cand = vmax(
            vmin(vmax(b(0), b(8)), vmax(b(4), b(12))),
            vmin(vmax(d(0), d(8)), vmax(d(4), d(12))),
        );
        if !any(cand) {
            continue;
        }
        // Darker and brighter differences clamped at 0. A corner's arc makes one side's best
        // 9-arc minimum exceed `t` (it is then the score + 1); the other side's is 0, since
        // every arc meets the corner's arc. A non-corner has both at most `t`.
        let mut dark = [[0u8; LANES]; 16];
        let mut bright = [[0u8; LANES]; 16];
        for ((d, b), &c) in dark.iter_mut().zip(bright.iter_mut()).zip(&v) {
            *d = vsubs(p, c);
            *b = vsubs(c, p);
        }
        let mut m = vmax(best_arc(&dark), best_arc(&bright));
        for m in &mut m {
            *m = if *m > t { *m } else { 0 };
        }
        if let Some(o) = srow.get_mut(3 + s..3 + s + LANES) {
            o.copy_from_slice(&m);
        }
    }
}

/// Keypoints of row `y` from the score rows `y − 1 ..= y + 1` (columns `3..3 + n`, each row
/// `n + 6` long, `n >= LANES`), in column order.
fn keep_row(rows: [&[u8]; 3], n: usize, y: usize, nonmax: bool, out: &mut Vec<Keypoint>) {
    let [up, mid, down] = rows;
    for (s, skip) in chunks(n) {
        let Some(c) = load(mid, 3 + s) else { return };
        if !any(c) {
            continue;
        }
        let mut keep = c;
        if nonmax {
            let mut nb = [0u8; LANES];
            for (r, dx) in [
                (up, 0),
                (up, 1),
                (up, 2),
                (mid, 0),
                (mid, 2),
                (down, 0),
                (down, 1),
                (down, 2),
            ] {
                nb = vmax(nb, load(r, 2 + s + dx).unwrap_or([u8::MAX; LANES]));
            }
            for (k, &m) in keep.iter_mut().zip(&nb) {
                *k = if *k > m { *k } else { 0 };
            }
        }
        // Bytes of kept lanes, lanes of the previous chunk cleared; lowest lane first.
        let mut bits =
            u128::from_le_bytes(keep) & u128::MAX.checked_shl(8 * skip as u32).unwrap_or(0);
        while bits != 0 {
            let i = bits.trailing_zeros() / 8;
            bits &= !(0xff << (8 * i));
            let k = keep.get(i as usize).copied().unwrap_or(1);
            let x = 3 + s + i as usize;
            out.push(Keypoint::at(x as f32, y as f32, 7.0, f32::from(k - 1)));
        }
    }
}

/// FAST-9 corners (see the module docs); `response` is the score in 8-bit levels.
pub fn detect_fast(img: &GreyF32, p: &FastParams) -> Vec<Keypoint> {
    if img.is_degenerate() || img.width < 7 || img.height < 7 {
        return Vec::new();
    }
    let (w, h) = (img.width, img.height);
    let t = (p.threshold * 255.0).round().clamp(0.0, 255.0) as u8;
    // Rows narrower than a chunk are padded with zeros on the right; a padding column is never
    // a circle pixel of a reported column, and its score is forced to 0.
    let stride = w.max(LANES + 6);
    let n = stride - 6;
    let mut levels = vec![0u8; stride * h];
    levels
        .par_chunks_mut(stride)
        .zip(img.data.par_chunks(w))
        .for_each(|(dst, src)| to_levels(src, dst));
    let mut scores = vec![0u8; stride * h];
    scores
        .par_chunks_mut(stride)
        .enumerate()
        .filter(|(y, _)| *y >= 3 && *y + 3 < h)
        .for_each(|(y, srow)| {
            let rows: [&[u8]; 7] = std::array::from_fn(|i| {
                levels
                    .get((y + i - 3) * stride..(y + i - 2) * stride)
                    .unwrap_or(&[])
            });
            score_row(&rows, n, t, srow);
            if let Some(pad) = srow.get_mut(w - 3..) {
                pad.fill(0);
            }
        });
    let row = |y: usize| scores.get(y * stride..(y + 1) * stride).unwrap_or(&[]);
    (3..h - 3)
        .into_par_iter()
        .flat_map_iter(|y| {
            let mut out = Vec::new();
            keep_row([row(y - 1), row(y), row(y + 1)], n, y, p.nonmax, &mut out);
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::image::to_level;

    /// The straightforward implementation this module replaced: full circle test and score at
    /// every pixel, suppression over a full score map.
    fn reference(img: &GreyF32, p: &FastParams) -> Vec<Keypoint> {
        let (w, h) = (img.width, img.height);
        if img.is_degenerate() || w < 7 || h < 7 {
            return Vec::new();
        }
        let t = (p.threshold * 255.0).round().clamp(0.0, 255.0) as i32;
        let lv: Vec<i32> = img.data.iter().map(|&v| i32::from(to_level(v))).collect();
        let mut s = vec![0i32; w * h];
        for y in 3..h - 3 {
            for x in 3..w - 3 {
                let c = lv[y * w + x];
                let d: Vec<i32> = CIRCLE
                    .iter()
                    .map(|&(dx, dy)| {
                        c - lv[(y as isize + dy) as usize * w + (x as isize + dx) as usize]
                    })
                    .collect();
                let arcs = (0..16).map(|k| (0..9).map(|j| d[(k + j) % 16]).collect::<Vec<_>>());
                let mut best = t;
                let mut corner = false;
                for a in arcs {
                    let (lo, hi) = (*a.iter().min().unwrap(), *a.iter().max().unwrap());
                    corner |= lo > t || hi < -t;
                    best = best.max(lo).max(-hi);
                }
                if corner {
                    s[y * w + x] = best;
                }
            }
        }
        let mut out = Vec::new();
        for y in 3..h - 3 {
            for x in 3..w - 3 {
                let v = s[y * w + x];
                let max_nb = (y - 1..=y + 1)
                    .flat_map(|yy| (x - 1..=x + 1).map(move |xx| (xx, yy)))
                    .filter(|&(xx, yy)| (xx, yy) != (x, y))
                    .map(|(xx, yy)| s[yy * w + xx])
                    .max()
                    .unwrap();
                if v > 0 && (!p.nonmax || max_nb < v) {
                    out.push(Keypoint::at(x as f32, y as f32, 7.0, (v - 1) as f32));
                }
            }
        }
        out
    }

    /// xorshift64 image: uniform levels, a few coarse levels (ties), out-of-range values, NaN.
    fn random_image(w: usize, h: usize, kind: u64, seed: &mut u64) -> GreyF32 {
        let data = (0..w * h)
            .map(|_| {
                *seed ^= *seed << 13;
                *seed ^= *seed >> 7;
                *seed ^= *seed << 17;
                let r = *seed;
                match kind {
                    0 => (r % 256) as f32 / 255.0,
                    1 => ((r % 6) * 50) as f32 / 255.0,
                    2 => (r % 1000) as f32 / 999.0 * 1.2 - 0.1,
                    _ if r.is_multiple_of(7) => f32::NAN,
                    _ => (r % 256) as f32 / 255.0,
                }
            })
            .collect();
        GreyF32::new(w, h, data).unwrap()
    }

    #[test]
    fn matches_reference_on_random_images() {
        let mut seed = 12345u64;
        let mut found = 0;
        for w in [1, 6, 7, 8, 21, 22, 23, 24, 37, 38, 39, 40, 71] {
            for h in [1, 6, 7, 9, 30] {
                for kind in 0..4 {
                    let img = random_image(w, h, kind, &mut seed);
                    for nonmax in [true, false] {
                        for t in [0.0, 10.0, 20.0, 40.0, 255.0] {
                            let p = FastParams {
                                threshold: t / 255.0,
                                nonmax,
                            };
                            let (ours, want) = (detect_fast(&img, &p), reference(&img, &p));
                            assert_eq!(ours, want, "{w}x{h} kind {kind} nonmax {nonmax} t {t}");
                            found += ours.len();
                        }
                    }
                }
            }
        }
        assert!(
            found > 10_000,
            "only {found} keypoints: the test exercises too little"
        );
    }
}
