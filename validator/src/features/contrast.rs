//! Contrast normalisation applied before detection, as the thesis did by hand.
//!
//! The thesis (§6) "contrasted" real and simulated images before running detectors; these are
//! the three standard choices, on 8-bit levels so they match the tools people compare with:
//! - [`stretch`]: MATLAB `imadjust(I, stretchlim(I))`, a linear map of the 1 % and 99 %
//!   quantiles of the 256-bin histogram to 0 and 1, saturating the tails;
//! - [`equalize`]: OpenCV `equalizeHist`;
//! - [`clahe`]: OpenCV `createCLAHE(clipLimit, tileGridSize)` (contrast-limited adaptive
//!   equalisation: clipped per-tile histograms, bilinear blend of the four nearest tile maps).

use super::image::{reflect101, to_level, GreyF32};

/// 256-bin histogram of 8-bit levels.
fn histogram<'a>(levels: impl Iterator<Item = &'a u8>) -> [u32; 256] {
    let mut h = [0u32; 256];
    for &v in levels {
        if let Some(b) = h.get_mut(usize::from(v)) {
            *b += 1;
        }
    }
    h
}

/// Maps every pixel through a 256-entry table of 8-bit levels.
fn apply_lut(img: &GreyF32, lut: &[u8; 256]) -> GreyF32 {
    let data = img
        .data
        .iter()
        .map(|&v| f32::from(lut.get(usize::from(to_level(v))).copied().unwrap_or(0)) / 255.0)
        .collect();
    GreyF32 {
        width: img.width,
        height: img.height,
        data,
    }
}

/// MATLAB `stretchlim(I, [low, high])`: the levels (in `[0, 1]`) at the `low` and `high`
/// fractions of the histogram; `(0, 1)` when they coincide (a flat image).
pub fn stretch_limits(img: &GreyF32, low: f64, high: f64) -> (f32, f32) {
    let levels = img.to_u8();
    let hist = histogram(levels.iter());
    let n = levels.len().max(1) as f64;
    let mut cum = 0.0;
    let (mut lo, mut hi) = (None, None);
    for (i, &c) in hist.iter().enumerate() {
        cum += f64::from(c);
        if lo.is_none() && cum / n > low {
            lo = Some(i);
        }
        if hi.is_none() && cum / n >= high {
            hi = Some(i);
        }
    }
    match (lo, hi) {
        (Some(l), Some(h)) if l < h => (l as f32 / 255.0, h as f32 / 255.0),
        _ => (0.0, 1.0),
    }
}

/// Linear stretch with 1 %/99 % saturation (MATLAB `imadjust(I)` on a grey image); output in
/// `[0, 1]`, not quantised.
pub fn stretch(img: &GreyF32) -> GreyF32 {
    let (lo, hi) = stretch_limits(img, 0.01, 0.99);
    let k = 1.0 / (hi - lo);
    GreyF32 {
        width: img.width,
        height: img.height,
        data: img
            .data
            .iter()
            .map(|&v| ((v - lo) * k).clamp(0.0, 1.0))
            .collect(),
    }
}

/// Histogram equalisation (OpenCV `equalizeHist`): level `i` maps to
/// `round(255 (cdf(i) − h(i₀)) / (N − h(i₀)))`, `i₀` the first non-empty level.
pub fn equalize(img: &GreyF32) -> GreyF32 {
    let levels = img.to_u8();
    let hist = histogram(levels.iter());
    let total = levels.len() as u64;
    let Some(i0) = hist.iter().position(|&c| c > 0) else {
        return img.clone();
    };
    let first = u64::from(hist.get(i0).copied().unwrap_or(0));
    let mut lut = [0u8; 256];
    if total == first {
        lut.iter_mut().enumerate().for_each(|(i, l)| *l = i as u8);
        return apply_lut(img, &lut);
    }
    let scale = 255.0 / (total - first) as f32;
    let mut sum = 0u64;
    for (i, l) in lut.iter_mut().enumerate().skip(i0 + 1) {
        sum += u64::from(hist.get(i).copied().unwrap_or(0));
        *l = (sum as f32 * scale).round().clamp(0.0, 255.0) as u8;
    }
    apply_lut(img, &lut)
}

/// Contrast-limited adaptive histogram equalisation (OpenCV `CLAHE`, defaults
/// `clip_limit = 40`, `tiles = (8, 8)`). Images not divisible into tiles are padded with
/// reflect-101 borders for the histograms, as OpenCV does.
pub fn clahe(img: &GreyF32, clip_limit: f64, tiles: (usize, usize)) -> GreyF32 {
    let (tx, ty) = (tiles.0.max(1), tiles.1.max(1));
    if img.is_degenerate() {
        return img.clone();
    }
    let (w, h) = (img.width, img.height);
    let levels = img.to_u8();
    let (tw, th) = (w.div_ceil(tx), h.div_ceil(ty));
    let area = tw * th;
    let clip = if clip_limit > 0.0 {
        ((clip_limit * area as f64 / 256.0) as u32).max(1)
    } else {
        u32::MAX
    };
    let lut_scale = 255.0 / area as f32;
    let level_at = |x: usize, y: usize| {
        let (xr, yr) = (reflect101(x as isize, w), reflect101(y as isize, h));
        levels.get(yr * w + xr).copied().unwrap_or(0)
    };
    let luts: Vec<[u8; 256]> = (0..ty * tx)
        .map(|t| {
            let (cx, cy) = (t % tx, t / tx);
            let mut hist = [0u32; 256];
            for y in cy * th..(cy + 1) * th {
                for x in cx * tw..(cx + 1) * tw {
                    if let Some(b) = hist.get_mut(usize::from(level_at(x, y))) {
                        *b += 1;
                    }
                }
            }
            let mut clipped = 0u32;
            for b in hist.iter_mut() {
                if *b > clip {
                    clipped += *b - clip;
                    *b = clip;
                }
            }
            let batch = clipped / 256;
            let mut residual = clipped - batch * 256;
            hist.iter_mut().for_each(|b| *b += batch);
            if residual > 0 {
                let step = (256 / residual as usize).max(1);
                let mut i = 0;
                while i < 256 && residual > 0 {
                    if let Some(b) = hist.get_mut(i) {
                        *b += 1;
                    }
                    residual -= 1;
                    i += step;
                }
            }
            let mut lut = [0u8; 256];
            let mut sum = 0u32;
            for (l, &c) in lut.iter_mut().zip(&hist) {
                sum += c;
                *l = (sum as f32 * lut_scale).round().clamp(0.0, 255.0) as u8;
            }
            lut
        })
        .collect();
    let lut = |cx: usize, cy: usize, v: u8| -> f32 {
        luts.get(cy * tx + cx)
            .and_then(|l| l.get(usize::from(v)))
            .copied()
            .map_or(0.0, f32::from)
    };
    let axis = |p: usize, t: usize, n: usize| {
        let f = p as f32 / t as f32 - 0.5;
        let i1 = f.floor();
        let a = f - i1;
        let lo = (i1.max(0.0) as usize).min(n - 1);
        let hi = ((i1 + 1.0).max(0.0) as usize).min(n - 1);
        (lo, hi, a)
    };
    let data = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let v = levels.get(y * w + x).copied().unwrap_or(0);
            let (x1, x2, xa) = axis(x, tw, tx);
            let (y1, y2, ya) = axis(y, th, ty);
            let top = lut(x1, y1, v) * (1.0 - xa) + lut(x2, y1, v) * xa;
            let bottom = lut(x1, y2, v) * (1.0 - xa) + lut(x2, y2, v) * xa;
            (top * (1.0 - ya) + bottom * ya).round().clamp(0.0, 255.0) / 255.0
        })
        .collect();
    GreyF32 {
        width: w,
        height: h,
        data,
    }
}
