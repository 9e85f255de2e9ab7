//! The `blur` effect, measured on the skyline: the width of the terrain/sky edge in the real
//! frames against the same edge in the render.
//!
//! Blur cannot be fitted reliably by matching pixels: a terrain entry's render carries noise
//! of its own (laser range noise in the DEM's normals, reflectance speckle in its texture) that
//! the real image does not have, and blurring the render removes that noise too, so a pixel fit
//! finds "blur" on every entry. An occluding edge against the sky is different: in the render it
//! is a step softened only by anti-aliasing, in the real image by the lens PSF as well, and its
//! width does not depend on where exactly the edge lies (each profile is measured on its own,
//! so a small misalignment does not matter).
//!
//! For every column where the render's terrain mask starts below sky and the skyline is nearly
//! horizontal (it moves at most 1 px over 4 columns), the vertical profile ±[`HALF`] px around
//! it is differentiated; the second moment of that derivative is the edge's variance. The
//! per-column difference real − render (paired, so terrain texture and slope cancel) has its
//! median taken over all columns of all views: `σ² = median(var_real − var_render)`. The
//! anti-aliasing of both images is the same box and cancels.

/// Half-height of an edge profile, px.
pub const HALF: usize = 6;
/// Minimum step across an edge, DN (sky to terrain), for the profile to count.
const MIN_STEP: f64 = 20.0;
/// Minimum number of profiles for a measurement.
const MIN_PROFILES: usize = 30;

/// The skyline edge measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeBlur {
    /// Gaussian PSF σ the real edges have in excess of the render's, px (0 when sharper).
    pub sigma_px: f64,
    /// Median edge variance of the render, px² (anti-aliasing and geometry).
    pub render_var: f64,
    /// Median edge variance of the real frames, px².
    pub real_var: f64,
    /// Profiles used.
    pub profiles: usize,
}

/// Skyline rows `(x, y0)`: `y0` is the first terrain row of column `x` with sky above.
fn skyline(mask: &[bool], w: usize, h: usize) -> Vec<(usize, usize)> {
    let top: Vec<Option<usize>> = (0..w)
        .map(|x| {
            let y0 = (0..h).find(|&y| mask[y * w + x])?;
            let clean =
                y0 > HALF && y0 + HALF + 1 < h && (y0..=y0 + HALF + 1).all(|y| mask[y * w + x]);
            clean.then_some(y0)
        })
        .collect();
    (2..w.saturating_sub(2))
        .filter_map(|x| {
            let y0 = top[x]?;
            let (a, b) = (top[x - 2]?, top[x + 2]?);
            (a.abs_diff(b) <= 1 && a.abs_diff(y0) <= 1).then_some((x, y0))
        })
        .collect()
}

/// Variance of the edge at `(x, y0)` in `img`, `None` when the step is too weak.
fn edge_variance(img: &[f32], w: usize, x: usize, y0: usize) -> Option<f64> {
    let (mut s, mut sy, mut syy) = (0.0f64, 0.0f64, 0.0f64);
    for y in y0 - HALF..y0 + HALF {
        let d = f64::from(img[(y + 1) * w + x] - img[y * w + x]);
        let t = y as f64 + 0.5;
        s += d;
        sy += d * t;
        syy += d * t * t;
    }
    if s < MIN_STEP {
        return None;
    }
    let c = sy / s;
    Some(syy / s - c * c)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => 0.0,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// One view for [`measure`]: real and rendered DN and the render's terrain mask, `w x h`.
#[derive(Debug, Clone, Copy)]
pub struct EdgeView<'a> {
    /// Real DN (the frame mean).
    pub real: &'a [f32],
    /// Rendered DN.
    pub render: &'a [f32],
    /// The render sees terrain.
    pub mask: &'a [bool],
    /// Width.
    pub w: usize,
    /// Height.
    pub h: usize,
}

/// Measures the excess edge blur of the real images over the renders along the skyline of the
/// render masks, over several views; `None` with fewer than 30 usable profiles.
pub fn measure(views: &[EdgeView<'_>]) -> Option<EdgeBlur> {
    let mut diff = Vec::new();
    let mut rv = Vec::new();
    let mut qv = Vec::new();
    for v in views {
        let (real, render, w) = (v.real, v.render, v.w);
        for (x, y0) in skyline(v.mask, w, v.h) {
            if let (Some(q), Some(r)) = (
                edge_variance(real, w, x, y0),
                edge_variance(render, w, x, y0),
            ) {
                diff.push(q - r);
                qv.push(q);
                rv.push(r);
            }
        }
    }
    if diff.len() < MIN_PROFILES {
        return None;
    }
    let profiles = diff.len();
    Some(EdgeBlur {
        sigma_px: median(diff).max(0.0).sqrt(),
        render_var: median(rv),
        real_var: median(qv),
        profiles,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::gaussian_blur;

    /// A bright terrain below a wavy skyline, black sky above, box anti-aliased.
    fn scene(w: usize, h: usize) -> (Vec<f32>, Vec<bool>) {
        let sky = |x: f64| 40.0 + 3.0 * (x / 37.0).sin();
        let mut img = vec![0.0f32; w * h];
        let mut mask = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let cover = ((y as f64 + 0.5) - sky(x as f64)).clamp(0.0, 1.0);
                img[y * w + x] =
                    (120.0 + 10.0 * ((x * 7 + y * 3) % 5) as f64 / 5.0) as f32 * cover as f32;
                mask[y * w + x] = y as f64 >= sky(x as f64);
            }
        }
        (img, mask)
    }

    #[test]
    fn recovers_the_psf_of_a_blurred_copy() {
        let (w, h) = (256, 96);
        let (render, mask) = scene(w, h);
        for sigma in [0.6, 1.0, 1.5] {
            let real = gaussian_blur(&render, w, h, sigma);
            let m = measure(&[EdgeView {
                real: &real,
                render: &render,
                mask: &mask,
                w,
                h,
            }])
            .unwrap();
            assert!((m.sigma_px - sigma).abs() < 0.1, "{sigma}: {m:?}");
        }
        let m = measure(&[EdgeView {
            real: &render,
            render: &render,
            mask: &mask,
            w,
            h,
        }])
        .unwrap();
        assert!(m.sigma_px < 0.05, "{m:?}");
    }
}
