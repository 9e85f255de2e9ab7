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
