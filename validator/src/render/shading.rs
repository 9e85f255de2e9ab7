//! Lambertian shading with an ambient share, and bilinear albedo lookup.
//!
//! `radiance = albedo * (ambient + (1 - ambient) * max(0, n·l) * visible)` with `l` the unit
//! direction toward the light. The model is deliberately the simplest one the validator can
//! fit against real images: the gap workflow adds response, vignetting, blur and noise on top
//! (see `sensor`), not here. Albedo lookups are bilinear between cell centres and clamp to the
//! edge cells; supersampling in the renderer provides the antialiasing.

use super::{AlbedoGrid, Light};

/// Unit vector toward the light: azimuth from +x toward +y, elevation above the horizon.
pub fn light_direction(light: &Light) -> [f64; 3] {
    let (az, el) = (
        light.azimuth_deg.to_radians(),
        light.elevation_deg.to_radians(),
    );
    [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
}

/// The shading formula; `visible` is 1 when the light reaches the point, 0 in shadow.
pub fn shade(albedo: f64, ambient: f64, normal: [f64; 3], to_light: [f64; 3], visible: f64) -> f64 {
    let n_dot_l = normal[0] * to_light[0] + normal[1] * to_light[1] + normal[2] * to_light[2];
    albedo * (ambient + (1.0 - ambient) * n_dot_l.max(0.0) * visible)
}

/// Bilinear albedo at ground `(x, y)`; positions outside the grid take the nearest edge value,
/// an empty grid gives 0 and non-finite values count as 0.
pub fn sample_albedo(grid: &AlbedoGrid, x: f64, y: f64) -> f32 {
    if grid.cell_m <= 0.0 {
        return 0.0;
    }
    let u = (x - grid.origin_m[0]) / grid.cell_m;
    let v = (grid.origin_m[1] - y) / grid.cell_m;
    bilinear(grid.width, grid.height, &grid.value, u, v)
}

/// [`sample_albedo`] for a sample whose footprint is `footprint_m` metres wide, through the
/// grid's mip levels `mips` (see [`MipChain::sample`]; a footprint of at most one cell gives
/// exactly [`sample_albedo`]).
pub(crate) fn sample_albedo_filtered(
    grid: &AlbedoGrid,
    mips: &MipChain,
    x: f64,
    y: f64,
    footprint_m: f64,
) -> f32 {
    if grid.cell_m <= 0.0 {
        return 0.0;
    }
    let u = (x - grid.origin_m[0]) / grid.cell_m;
    let v = (grid.origin_m[1] - y) / grid.cell_m;
    mips.sample(
        grid.width,
        grid.height,
        &grid.value,
        u,
        v,
        footprint_m / grid.cell_m,
    )
}

/// Bilinear value of a row-major `width x height` raster at `(u, v)` in units of cells, cell
/// `(c, r)` centred at `(c, r)`; positions outside take the nearest edge value, an empty raster
/// or non-finite coordinates give 0 and non-finite values count as 0. The one lookup of the
/// renderer: heightfield albedo grids and mesh textures sample through it.
pub(crate) fn bilinear(width: usize, height: usize, value: &[f32], u: f64, v: f64) -> f32 {
    if width == 0 || height == 0 {
        return 0.0;
    }
    let u = u.clamp(0.0, (width - 1) as f64);
    let v = v.clamp(0.0, (height - 1) as f64);
    if !(u.is_finite() && v.is_finite()) {
        return 0.0;
    }
    let (c0, r0) = (u.floor() as usize, v.floor() as usize);
    let (c1, r1) = ((c0 + 1).min(width - 1), (r0 + 1).min(height - 1));
    let (fu, fv) = ((u - c0 as f64) as f32, (v - r0 as f64) as f32);
    let at = |c: usize, r: usize| {
        value
            .get(r * width + c)
            .copied()
            .filter(|a| a.is_finite())
            .unwrap_or(0.0)
    };
    let top = at(c0, r0) * (1.0 - fu) + at(c1, r0) * fu;
    let bottom = at(c0, r1) * (1.0 - fu) + at(c1, r1) * fu;
    top * (1.0 - fv) + bottom * fv
}

/// Box-filtered mip levels of a texture (level `k` averages `2^k × 2^k` texels of level 0; the
/// last level is 1 × 1), for sampling a texture whose texels are smaller than a ray sample's
/// footprint: a ray caster that point-samples such a texture aliases (a distant view of a fine
/// texture becomes noise with the texture's variance instead of its local mean). Level 0 is the
/// texture itself and is not copied; non-finite texels count as 0, as in [`bilinear`].
#[derive(Debug, Clone, Default)]
pub(crate) struct MipChain {
    /// Levels 1, 2, …: `(width, height, values)`.
    levels: Vec<(usize, usize, Vec<f32>)>,
}

impl MipChain {
    /// The levels above a `width × height` row-major level 0.
    pub(crate) fn new(width: usize, height: usize, level0: &[f32]) -> MipChain {
        let mut levels: Vec<(usize, usize, Vec<f32>)> = Vec::new();
        let (mut w, mut h) = (width, height);
        while w > 1 || h > 1 {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let prev: &[f32] = levels.last().map_or(level0, |l| &l.2);
            let at = |c: usize, r: usize| {
                prev.get(r.min(h - 1) * w + c.min(w - 1))
                    .copied()
                    .filter(|a| a.is_finite())
                    .unwrap_or(0.0)
            };
            let mut next = Vec::with_capacity(nw * nh);
            for r in 0..nh {
                for c in 0..nw {
                    let (c0, r0) = (2 * c, 2 * r);
                    next.push(
                        0.25 * (at(c0, r0) + at(c0 + 1, r0) + at(c0, r0 + 1) + at(c0 + 1, r0 + 1)),
                    );
                }
            }
            levels.push((nw, nh, next));
            (w, h) = (nw, nh);
        }
        MipChain { levels }
    }

    /// The value at `(u, v)` in level-0 texel units (texel centres at integers, as in
    /// [`bilinear`]) for a sample whose footprint spans `footprint` level-0 texels: bilinear on
    /// level 0 when the footprint is at most one texel (magnification: exactly [`bilinear`]),
    /// else trilinear between the two levels around `log2(footprint)`.
    pub(crate) fn sample(
        &self,
        width: usize,
        height: usize,
        level0: &[f32],
        u: f64,
        v: f64,
        footprint: f64,
    ) -> f32 {
        if footprint.is_nan() || footprint <= 1.0 || self.levels.is_empty() {
            return bilinear(width, height, level0, u, v);
        }
        let lambda = footprint.log2().min(self.levels.len() as f64);
        let k = lambda.floor() as usize;
        let f = (lambda - k as f64) as f32;
        let at_level = |k: usize| -> f32 {
            let scale = f64::from(1u32 << k.min(31));
            // Level-k texel j covers level-0 texels j·2^k … (j+1)·2^k − 1.
            let (uk, vk) = (
                (u - 0.5 * (scale - 1.0)) / scale,
                (v - 0.5 * (scale - 1.0)) / scale,
            );
            match k.checked_sub(1) {
                None => bilinear(width, height, level0, uk, vk),
                Some(i) => {
                    let (w, h, vals) = &self.levels[i.min(self.levels.len() - 1)];
                    bilinear(*w, *h, vals, uk, vk)
                }
            }
        };
        let lo = at_level(k);
        if f <= 0.0 {
            return lo;
        }
        lo * (1.0 - f) + at_level(k + 1) * f
    }
}

/// The footprint on the surface, in metres, of a ray sample that hits at parameter `t` along
/// the unnormalised direction `d` (`point = origin + t·d`) a surface of unit normal `n`, when
/// neighbouring samples are `spread` apart in normalised image coordinates: the side of the
/// square with the area of the sample's footprint ellipse, `t·spread·cos φ / sqrt(|cos θ|)`
/// (φ the ray's angle off the optical axis, `|d| = 1 / cos φ`; θ its incidence on the surface).
pub(crate) fn footprint_m(t: f64, d: [f64; 3], n: [f64; 3], spread: f64) -> f64 {
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if len.is_nan() || len <= 0.0 {
        return 0.0;
    }
    let cos_i = ((d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) / len)
        .abs()
        .max(1e-3);
    t * spread / len / cos_i.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_levels_average_blocks_and_magnification_is_plain_bilinear() {
        // 4 x 3 level 0; level 1 is 2 x 2 (the last row pairs with itself), level 2 is 1 x 1.
        let v: Vec<f32> = (0..12).map(|i| i as f32).collect();
        let m = MipChain::new(4, 3, &v);
        assert_eq!(m.levels.len(), 2);
        assert_eq!(m.levels[0].2, vec![2.5, 4.5, 8.5, 10.5]);
        assert_eq!(m.levels[1].2, vec![6.5]);
        for (u, v_) in [(0.3, 0.7), (2.5, 1.25), (3.0, 2.0)] {
            for foot in [0.0, 0.5, 1.0, f64::NAN] {
                assert_eq!(m.sample(4, 3, &v, u, v_, foot), bilinear(4, 3, &v, u, v_));
            }
        }
        // A footprint of 2 texels reads level 1 at the level-0 position: u = 0.5 is the centre
        // of level-1 texel 0 (level-0 texels 0 and 1).
        assert_eq!(m.sample(4, 3, &v, 0.5, 0.5, 2.0), 2.5);
        // Half-way between levels 1 and 2 (footprint 2^1.5): the mean of both.
        let mid = m.sample(4, 3, &v, 0.5, 0.5, 2f64.powf(1.5));
        assert!((mid - 0.5 * (2.5 + 6.5)).abs() < 1e-5, "{mid}");
        // Beyond the last level: the last level.
        assert_eq!(m.sample(4, 3, &v, 0.5, 0.5, 1e9), 6.5);
        assert_eq!(m.sample(4, 3, &v, 0.5, 0.5, f64::INFINITY), 6.5);
    }

    #[test]
    fn footprint_grows_with_distance_and_obliquity() {
        let down = [0.0, 0.0, -1.0];
        let up = [0.0, 0.0, 1.0];
        assert!((footprint_m(4.0, down, up, 0.01) - 0.04).abs() < 1e-12);
        // A ray 60° off the optical axis (|d| = 2, so 2 m away at t = 1; the samples' angular
        // spacing shrinks by cos² 60°) meeting the ground at 60° incidence: 2 · 0.01 / 4 across
        // the ray, and the footprint's area doubles on the surface (its side × √2).
        let d = [0.0, 3f64.sqrt(), -1.0];
        let f = footprint_m(1.0, d, up, 0.01);
        assert!((f - 2.0 * 0.01 / 4.0 * 2f64.sqrt()).abs() < 1e-12, "{f}");
        assert_eq!(footprint_m(1.0, [0.0; 3], up, 0.01), 0.0);
    }
}
