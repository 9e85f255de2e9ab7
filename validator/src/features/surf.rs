//! SURF (Bay et al. 2008) fast-Hessian detector and 64-d descriptor, as in OpenCV's
//! `xfeatures2d::SURF` (the non-free contrib module, usually absent from pip wheels).
//!
//! Box filters on the integral image of the 8-bit levels approximate the Gaussian second
//! derivatives; `det = Dxx·Dyy − 0.81·Dxy²` (each box normalised by its area, so `det` is in
//! levels² and the threshold keeps OpenCV's units, default 100). Filter sizes are
//! `(9 + 6·layer) << octave` with sampling step `1 << octave`; maxima over 3×3×3 neighbours of
//! the middle layers are refined by one quadratic fit (rejected if the offset exceeds one
//! sample). Orientation: Haar responses of size `4s` (`s = 1.2·size/9`) on a radius-`6s`
//! disc, Gaussian-weighted (σ = 2.5 samples), summed in a sliding 60° window every 5°.
//! Descriptor: a `20s`-wide window rotated to the orientation, area-resampled to 21×21,
//! Gaussian-weighted (σ = 3.3) gradients summed over 4×4 cells as `(Σdx, Σdy, Σ|dx|, Σ|dy|)`,
//! normalised to unit length. The intermediate 8-bit roundings of OpenCV are kept.
//!
//! Layers are computed in parallel (one task per layer), maxima per middle layer; the output
//! is sorted canonically, so it does not depend on thread count.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::image::{gaussian_kernel_n, GreyF32, Integral};
use super::keypoint::{sort_keypoints, Keypoint};

/// SURF parameters; defaults are OpenCV's `SURF::create()` (hessianThreshold 100, 4 octaves,
/// 2 layers, 64-d, oriented). The thesis (Table 6.2) used thresholds 2500–5000 with 3 scale
/// levels on contrast-stretched images.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SurfParams {
    /// Minimum Hessian determinant, OpenCV units (levels²), default 100.
    pub hessian_threshold: f32,
    /// Octaves (default 4).
    pub octaves: usize,
    /// Middle layers per octave (default 2).
    pub octave_layers: usize,
}

impl Default for SurfParams {
    fn default() -> Self {
        SurfParams {
            hessian_threshold: 100.0,
            octaves: 4,
            octave_layers: 2,
        }
    }
}

/// One box of a Haar pattern: offsets `(x0, y0, x1, y1)` inside the pattern and a weight
/// already divided by the box area.
#[derive(Debug, Clone, Copy)]
struct HaarBox {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
    w: f64,
}

/// OpenCV's `resizeHaarPattern`: scales a pattern defined for `old` to `new` pixels.
fn haar(src: &[[i32; 5]], old: usize, new: usize) -> Vec<HaarBox> {
    let ratio = new as f32 / old as f32;
    let r = |v: i32| (ratio * v as f32).round().max(0.0) as usize;
    src.iter()
        .map(|b| {
            let (x0, y0, x1, y1) = (r(b[0]), r(b[1]), r(b[2]), r(b[3]));
            let area = ((x1.saturating_sub(x0)) * (y1.saturating_sub(y0))).max(1) as f64;
            HaarBox {
                x0,
                y0,
                x1,
                y1,
                w: f64::from(b[4]) / area,
            }
        })
        .collect()
}

const DX: [[i32; 5]; 3] = [[0, 2, 3, 7, 1], [3, 2, 6, 7, -2], [6, 2, 9, 7, 1]];
const DY: [[i32; 5]; 3] = [[2, 0, 7, 3, 1], [2, 3, 7, 6, -2], [2, 6, 7, 9, 1]];
const DXY: [[i32; 5]; 4] = [
    [1, 1, 4, 4, 1],
    [5, 1, 8, 4, -1],
    [1, 5, 4, 8, -1],
    [5, 5, 8, 8, 1],
];

/// One layer of the fast-Hessian pyramid.
struct Layer {
    size: usize,
    step: usize,
    rows: usize,
    cols: usize,
    det: Vec<f32>,
    trace_sign: Vec<i8>,
}

impl Layer {
    #[inline]
    fn det(&self, i: usize, j: usize) -> f32 {
        self.det.get(i * self.cols + j).copied().unwrap_or(0.0)
    }
}

/// A Haar box as offsets into the sum table from the pattern's top-left corner:
/// `sum[o + d11] − sum[o + d01] − sum[o + d10] + sum[o + d00]` is its pixel sum.
#[derive(Clone, Copy)]
struct BoxOffsets {
    d00: usize,
    d01: usize,
    d10: usize,
    d11: usize,
    w: f64,
}

fn offsets(pattern: &[HaarBox], stride: usize) -> Vec<BoxOffsets> {
    pattern
        .iter()
        .map(|b| BoxOffsets {
            d00: b.y0 * stride + b.x0,
            d01: b.y1 * stride + b.x0,
            d10: b.y0 * stride + b.x1,
            d11: b.y1 * stride + b.x1,
            w: b.w,
        })
        .collect()
}

/// Haar response of `pattern` with its top-left corner at offset `o` of the sum table.
#[inline]
fn haar_at(sum: &[i64], o: usize, pattern: &[BoxOffsets]) -> f32 {
    let g = |i: usize| sum.get(o + i).copied().unwrap_or(0);
    pattern
        .iter()
        .map(|b| (g(b.d11) - g(b.d01) - g(b.d10) + g(b.d00)) as f64 * b.w)
        .sum::<f64>() as f32
}

fn build_layer(sum: &Integral, size: usize, step: usize) -> Layer {
    let (h, w) = (sum.rows - 1, sum.stride - 1);
    let (rows, cols) = (h / step, w / step);
    let mut layer = Layer {
        size,
        step,
        rows,
        cols,
        det: vec![0.0; rows * cols],
        trace_sign: vec![0; rows * cols],
    };
    if size > h || size > w || cols == 0 {
        return layer;
    }
    let stride = sum.stride;
    let (dx, dy, dxy) = (
        offsets(&haar(&DX, 9, size), stride),
        offsets(&haar(&DY, 9, size), stride),
        offsets(&haar(&DXY, 9, size), stride),
    );
    let samples_i = 1 + (h - size) / step;
    let samples_j = 1 + (w - size) / step;
    let margin = (size / 2) / step;
    let table = &sum.sum[..];
    layer
        .det
        .par_chunks_mut(cols)
        .zip(layer.trace_sign.par_chunks_mut(cols))
        .enumerate()
        .skip(margin)
        .take(samples_i)
        .for_each(|(r, (det, sign))| {
            let y = (r - margin) * step;
            let cells = det.iter_mut().zip(sign.iter_mut()).skip(margin);
            for (j, (d, t)) in cells.take(samples_j).enumerate() {
                let o = y * stride + j * step;
                let (a, b, c) = (
                    haar_at(table, o, &dx),
                    haar_at(table, o, &dy),
                    haar_at(table, o, &dxy),
                );
                *d = a * b - 0.81 * c * c;
                *t = ((a + b) > 0.0) as i8 - ((a + b) < 0.0) as i8;
            }
        });
    layer
}

/// SURF keypoints with orientation (see the module docs); `response` is the determinant.
pub fn detect_surf(img: &GreyF32, p: &SurfParams) -> Vec<Keypoint> {
    if img.is_degenerate() {
        return Vec::new();
    }
    let sum = Integral::of_levels(img);
    let mut kps = find_maxima(&sum, p);
    let oriented: Vec<Option<f32>> = kps.par_iter().map(|kp| orientation(&sum, kp)).collect();
    kps = kps
        .into_iter()
        .zip(oriented)
        .filter_map(|(mut kp, a)| {
            kp.angle = a?;
            Some(kp)
        })
        .collect();
    sort_keypoints(&mut kps);
    kps
}

fn find_maxima(sum: &Integral, p: &SurfParams) -> Vec<Keypoint> {
    let nl = p.octave_layers.max(1);
    let specs: Vec<(usize, usize)> = (0..p.octaves)
        .flat_map(|o| (0..nl + 2).map(move |l| ((9 + 6 * l) << o, 1usize << o)))
        .collect();
    let layers: Vec<Layer> = specs
        .par_iter()
        .map(|&(size, step)| build_layer(sum, size, step))
        .collect();
    let middle: Vec<(usize, usize)> = (0..p.octaves)
        .flat_map(|o| (1..=nl).map(move |l| (o, o * (nl + 2) + l)))
        .collect();
    middle
        .into_par_iter()
        .flat_map_iter(|(o, li)| {
            let (Some(lo), Some(mid), Some(hi)) =
                (layers.get(li - 1), layers.get(li), layers.get(li + 1))
            else {
                return Vec::new();
            };
            maxima_in_layer(lo, mid, hi, o, p.hessian_threshold)
        })
        .collect()
}

fn maxima_in_layer(lo: &Layer, mid: &Layer, hi: &Layer, octave: usize, thr: f32) -> Vec<Keypoint> {
    let step = mid.step;
    let size = mid.size;
    let margin = (hi.size / 2) / step + 1;
    let mut out = Vec::new();
    for i in margin..mid.rows.saturating_sub(margin) {
        for j in margin..mid.cols.saturating_sub(margin) {
            let v = mid.det(i, j);
            if v <= thr {
                continue;
            }
            let mut n9 = [[0.0f32; 9]; 3];
            for (row, layer) in n9.iter_mut().zip([lo, mid, hi]) {
                for (k, v) in row.iter_mut().enumerate() {
                    *v = layer.det(i + k / 3 - 1, j + k % 3 - 1);
                }
            }
            let is_max = n9.iter().enumerate().all(|(l, row)| {
                row.iter()
                    .enumerate()
                    .all(|(k, &u)| (l == 1 && k == 4) || v > u)
            });
            if !is_max {
                continue;
            }
            let sum_i = step * (i - (size / 2) / step);
            let sum_j = step * (j - (size / 2) / step);
            let cx = sum_j as f32 + (size as f32 - 1.0) * 0.5;
            let cy = sum_i as f32 + (size as f32 - 1.0) * 0.5;
            let ds = (size - lo.size) as f32;
            if let Some((ox, oy, os)) = interpolate(&n9) {
                out.push(Keypoint {
                    x: cx + ox * step as f32,
                    y: cy + oy * step as f32,
                    size: (size as f32 + os * ds).round(),
                    angle: -1.0,
                    response: v,
                    octave: octave as i32,
                });
            }
        }
    }
    out
}

/// One Newton step on the 3×3×3 samples; `None` if the offset leaves the neighbourhood.
fn interpolate(n: &[[f32; 9]; 3]) -> Option<(f32, f32, f32)> {
    let b = [
        -(n[1][5] - n[1][3]) / 2.0,
        -(n[1][7] - n[1][1]) / 2.0,
        -(n[2][4] - n[0][4]) / 2.0,
    ];
    let dxy = (n[1][8] - n[1][6] - n[1][2] + n[1][0]) / 4.0;
    let dxs = (n[2][5] - n[2][3] - n[0][5] + n[0][3]) / 4.0;
    let dys = (n[2][7] - n[2][1] - n[0][7] + n[0][1]) / 4.0;
    let a = [
        [n[1][3] - 2.0 * n[1][4] + n[1][5], dxy, dxs],
        [dxy, n[1][1] - 2.0 * n[1][4] + n[1][7], dys],
        [dxs, dys, n[0][4] - 2.0 * n[1][4] + n[2][4]],
    ];
    let x = super::sift::solve3(a, b);
    let ok = x.iter().any(|&v| v != 0.0) && x.iter().all(|v| v.abs() <= 1.0);
    ok.then_some((x[0], x[1], x[2]))
}

/// Orientation radius (samples) and sliding-window width (degrees).
const ORI_RADIUS: i32 = 6;
const ORI_WIN: i32 = 60;
const ORI_SEARCH_INC: usize = 5;
/// Windows searched: one every [`ORI_SEARCH_INC`] degrees round the circle.
const ORI_WINDOWS: usize = 360 / ORI_SEARCH_INC;
const ORI_SIGMA: f64 = 2.5;
const DESC_SIGMA: f64 = 3.3;
const PATCH: usize = 20;

/// Dominant orientation in degrees, `None` when no gradient sample fits in the image.
fn orientation(sum: &Integral, kp: &Keypoint) -> Option<f32> {
    let s = kp.size * 1.2 / 9.0;
    let wav = 2 * (2.0 * s).round() as usize;
    if sum.rows < wav || sum.stride < wav || wav == 0 {
        return None;
    }
    let g = gaussian_kernel_n(2 * ORI_RADIUS as usize + 1, ORI_SIGMA);
    let hx = offsets(
        &haar(&[[0, 0, 2, 4, -1], [2, 0, 4, 4, 1]], 4, wav),
        sum.stride,
    );
    let hy = offsets(
        &haar(&[[0, 0, 4, 2, 1], [0, 2, 4, 4, -1]], 4, wav),
        sum.stride,
    );
    let mut samples: Vec<(f32, f32, i32)> = Vec::new();
    for i in -ORI_RADIUS..=ORI_RADIUS {
        for j in -ORI_RADIUS..=ORI_RADIUS {
            if i * i + j * j > ORI_RADIUS * ORI_RADIUS {
                continue;
            }
            let half = (wav as f32 - 1.0) / 2.0;
            let x = (kp.x + i as f32 * s - half).round() as i64;
            let y = (kp.y + j as f32 * s - half).round() as i64;
            if y < 0 || y >= (sum.rows - wav) as i64 || x < 0 || x >= (sum.stride - wav) as i64 {
                continue;
            }
            let wgt = g.get((i + ORI_RADIUS) as usize).copied().unwrap_or(0.0)
                * g.get((j + ORI_RADIUS) as usize).copied().unwrap_or(0.0);
            let o = y as usize * sum.stride + x as usize;
            let vx = haar_at(&sum.sum, o, &hx) * wgt;
            let vy = haar_at(&sum.sum, o, &hy) * wgt;
            let mut a = vy.atan2(vx).to_degrees();
            if a < 0.0 {
                a += 360.0;
            }
            samples.push((vx, vy, a.round() as i32));
        }
    }
    if samples.is_empty() {
        return None;
    }
    // Every window's sums at once, sample by sample: each window still adds its samples in
    // their order (the sums are those of one window at a time, bit for bit: a window a sample
    // is not in adds +0.0, and a sum that starts at +0.0 never becomes −0.0), but the loop over
    // the windows has no branch and no dependency from one window to the next.
    let mut sx = [0.0f32; ORI_WINDOWS];
    let mut sy = [0.0f32; ORI_WINDOWS];
    for &(vx, vy, a) in &samples {
        for (k, (x, y)) in sx.iter_mut().zip(sy.iter_mut()).enumerate() {
            let d = (a - (k * ORI_SEARCH_INC) as i32).abs();
            let inside = !(ORI_WIN / 2..=360 - ORI_WIN / 2).contains(&d);
            *x += if inside { vx } else { 0.0 };
            *y += if inside { vy } else { 0.0 };
        }
    }
    let (mut best, mut bx, mut by) = (0.0f32, 0.0f32, 0.0f32);
    for (&x, &y) in sx.iter().zip(&sy) {
        let m = x * x + y * y;
        if m > best {
            (best, bx, by) = (m, x, y);
        }
    }
    let mut dir = (-by).atan2(bx).to_degrees();
    if dir < 0.0 {
        dir += 360.0;
    }
    Some(dir)
}

/// `INTER_AREA` weights for shrinking `src` samples to `dst`: per destination index, a list of
/// `(source index, weight)` with weights summing to 1.
fn area_weights(src: usize, dst: usize) -> Vec<Vec<(usize, f32)>> {
    let scale = src as f64 / dst as f64;
    (0..dst)
        .map(|d| {
            let (a, b) = (d as f64 * scale, (d + 1) as f64 * scale);
            let mut v = Vec::new();
            let mut x = a.floor() as usize;
            while (x as f64) < b && x < src {
                let overlap = (b.min(x as f64 + 1.0) - a.max(x as f64)).max(0.0);
                if overlap > 1e-9 {
                    v.push((x, (overlap / scale) as f32));
                }
                x += 1;
            }
            v
        })
        .collect()
}

/// 64-d SURF descriptors of keypoints from [`detect_surf`] (orientation in `angle`).
pub fn describe_surf(img: &GreyF32, kps: &[Keypoint]) -> Vec<Vec<f32>> {
    let levels = img.to_u8();
    let g = gaussian_kernel_n(PATCH, DESC_SIGMA);
    kps.par_iter()
        .map(|kp| surf_descriptor(&levels, img.width, img.height, kp, &g))
        .collect()
}

fn surf_descriptor(levels: &[u8], w: usize, h: usize, kp: &Keypoint, g: &[f32]) -> Vec<f32> {
    let mut vec = vec![0.0f32; 64];
    if w < 2 || h < 2 {
        return vec;
    }
    let s = kp.size * 1.2 / 9.0;
    let win = ((PATCH + 1) as f32 * s) as usize;
    let dir = if kp.angle >= 0.0 { kp.angle } else { 270.0 }.to_radians();
    let (sin_dir, cos_dir) = (-dir.sin(), dir.cos());
    let off = -((win as f32) - 1.0) / 2.0;
    let start_x = kp.x + off * cos_dir + off * sin_dir;
    let start_y = kp.y - off * sin_dir + off * cos_dir;
    let px = |x: usize, y: usize| f32::from(levels.get(y * w + x).copied().unwrap_or(0));
    let mut window = vec![0.0f32; win * win];
    for i in 0..win {
        let (sx, sy) = (
            f64::from(start_x) + i as f64 * f64::from(sin_dir),
            f64::from(start_y) + i as f64 * f64::from(cos_dir),
        );
        for j in 0..win {
            let xx = sx + j as f64 * f64::from(cos_dir);
            let yy = sy - j as f64 * f64::from(sin_dir);
            let (ix, iy) = (xx.floor(), yy.floor());
            let v = if ix >= 0.0 && iy >= 0.0 && (ix as usize) < w - 1 && (iy as usize) < h - 1 {
                let (ix, iy) = (ix as usize, iy as usize);
                let (a, b) = ((xx - ix as f64) as f32, (yy - iy as f64) as f32);
                (px(ix, iy) * (1.0 - a) * (1.0 - b)
                    + px(ix + 1, iy) * a * (1.0 - b)
                    + px(ix, iy + 1) * (1.0 - a) * b
                    + px(ix + 1, iy + 1) * a * b)
                    .round()
            } else {
                let x = (xx.round().max(0.0) as usize).min(w - 1);
                let y = (yy.round().max(0.0) as usize).min(h - 1);
                px(x, y)
            };
            if let Some(o) = window.get_mut(i * win + j) {
                *o = v;
            }
        }
    }
    let wt = area_weights(win, PATCH + 1);
    let mut patch = [0.0f32; (PATCH + 1) * (PATCH + 1)];
    let pp = |p: &[f32], y: usize, x: usize| p.get(y * (PATCH + 1) + x).copied().unwrap_or(0.0);
    for (pi, row_w) in wt.iter().enumerate() {
        for (pj, col_w) in wt.iter().enumerate() {
            let v: f32 = row_w
                .iter()
                .flat_map(|&(r, wr)| col_w.iter().map(move |&(c, wc)| (r, c, wr * wc)))
                .map(|(r, c, ww)| window.get(r * win + c).copied().unwrap_or(0.0) * ww)
                .sum();
            if let Some(o) = patch.get_mut(pi * (PATCH + 1) + pj) {
                *o = v.round().clamp(0.0, 255.0);
            }
        }
    }
    let mut square = 0.0f64;
    for ci in 0..4 {
        for cj in 0..4 {
            let mut cell = [0.0f32; 4];
            for y in ci * 5..ci * 5 + 5 {
                for x in cj * 5..cj * 5 + 5 {
                    let dw = g.get(y).copied().unwrap_or(0.0) * g.get(x).copied().unwrap_or(0.0);
                    let (p00, p01) = (pp(&patch, y, x), pp(&patch, y, x + 1));
                    let (p10, p11) = (pp(&patch, y + 1, x), pp(&patch, y + 1, x + 1));
                    let tx = (p01 - p00 + p11 - p10) * dw;
                    let ty = (p10 - p00 + p11 - p01) * dw;
                    cell[0] += tx;
                    cell[1] += ty;
                    cell[2] += tx.abs();
                    cell[3] += ty.abs();
                }
            }
            for (k, c) in cell.iter().enumerate() {
                square += f64::from(c * c);
                if let Some(o) = vec.get_mut((ci * 4 + cj) * 4 + k) {
                    *o = *c;
                }
            }
        }
    }
    let scale = (1.0 / (square.sqrt() + f64::from(f32::EPSILON))) as f32;
    vec.iter_mut().for_each(|v| *v *= scale);
    vec
}
