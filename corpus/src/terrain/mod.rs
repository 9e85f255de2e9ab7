//! The true terrain: a fine height grid, its albedo, and the marker balls sitting on it.
//!
//! The truth is a [`HeightGrid`] (the format's grid type; the laser simulation traces exactly
//! the surface written to `truth/height.exr`, [`raycast`]) on a 2.5–5 mm grid,
//! plus an [`AlbedoGrid`] of the same geometry. Marker balls are part of both: the ball caps are
//! stamped into the heights and painted white, so the scanner sees them; the captures render
//! them again as exact white spheres over the caps, which lie inside them,
//! since a cap faceted to the grid puts a ball's image 0.1–0.3 px off its centre's projection. [`synth`] builds the relief, [`materials`] the albedo; the small grid
//! helpers below (bilinear sampling, box downsampling, Gaussian blur) are shared by the SfM
//! mesh and the texture low-pass.

pub mod materials;
pub mod raycast;
pub mod synth;

use rayon::prelude::*;
use regolith_format::grid::{AlbedoGrid, HeightGrid};

use crate::presets::{PresetConfig, MARKER_RADIUS_M};

/// A marker ball as it truly is.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TrueMarker {
    /// Marker name (`Marker1`...).
    pub name: String,
    /// Ball centre in the ground frame, metres.
    pub centre_m: [f64; 3],
    /// Ball radius, metres.
    pub radius_m: f64,
}

/// The generated terrain.
#[derive(Debug, Clone)]
pub struct Terrain {
    /// True heights.
    pub height: HeightGrid,
    /// True albedo (same geometry as `height`).
    pub albedo: AlbedoGrid,
    /// Material id per cell (`synth::material`), same geometry.
    pub material: Vec<u8>,
    /// Marker balls.
    pub markers: Vec<TrueMarker>,
}

impl Terrain {
    /// Builds the terrain of a preset at grid cell `cell_m`.
    pub fn build(cfg: &PresetConfig, cell_m: f64, seed: u64) -> Terrain {
        let shape = GridShape::covering(cfg.extent_m, cell_m);
        let built = synth::relief(cfg, &shape, seed);
        let albedo = materials::albedo(&shape, &built.material, seed);
        let material = built.material;
        let height = HeightGrid {
            origin_m: shape.origin_m,
            cell_m,
            width: shape.width,
            height: shape.height,
            z: built.z,
        };
        Terrain {
            height,
            albedo,
            material,
            markers: built.markers,
        }
    }

    /// Bilinear height at ground `(x, y)` (clamped to the grid).
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let g = &self.height;
        GridShape::of(g.origin_m, g.cell_m, g.width, g.height).bilinear(&g.z, x, y)
    }
}

/// Geometry of a grid in the [`HeightGrid`] convention (row 0 = north).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridShape {
    /// Centre of cell (0, 0).
    pub origin_m: [f64; 2],
    /// Cell size, metres.
    pub cell_m: f64,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl GridShape {
    /// A grid whose cell centres cover `[0, extent_x] x [0, extent_y]`, corners included.
    pub fn covering(extent_m: [f64; 2], cell_m: f64) -> GridShape {
        let width = (extent_m[0] / cell_m).round() as usize + 1;
        let height = (extent_m[1] / cell_m).round() as usize + 1;
        GridShape {
            origin_m: [0.0, (height - 1) as f64 * cell_m],
            cell_m,
            width,
            height,
        }
    }

    /// The shape of an existing grid.
    pub fn of(origin_m: [f64; 2], cell_m: f64, width: usize, height: usize) -> GridShape {
        GridShape {
            origin_m,
            cell_m,
            width,
            height,
        }
    }

    /// Ground x, y of the centre of cell `(c, r)`.
    pub fn centre(&self, c: usize, r: usize) -> [f64; 2] {
        [
            self.origin_m[0] + c as f64 * self.cell_m,
            self.origin_m[1] - r as f64 * self.cell_m,
        ]
    }

    /// Fractional (column, row) of ground `(x, y)`.
    pub fn to_grid(&self, x: f64, y: f64) -> [f64; 2] {
        [
            (x - self.origin_m[0]) / self.cell_m,
            (self.origin_m[1] - y) / self.cell_m,
        ]
    }

    /// Cell index range (inclusive-exclusive) covering a ground box around `(x, y)`.
    pub fn window(&self, x: f64, y: f64, radius_m: f64) -> ([usize; 2], [usize; 2]) {
        let [u, v] = self.to_grid(x, y);
        let rad = radius_m / self.cell_m;
        let lo = |a: f64| (a - rad).floor().max(0.0) as usize;
        let hi = |a: f64, n: usize| ((a + rad).ceil() + 1.0).clamp(0.0, n as f64) as usize;
        ([lo(u), hi(u, self.width)], [lo(v), hi(v, self.height)])
    }

    /// Bilinear sample of `values` at ground `(x, y)`, clamped to the grid.
    pub fn bilinear(&self, values: &[f32], x: f64, y: f64) -> f64 {
        let [u, v] = self.to_grid(x, y);
        let u = u.clamp(0.0, (self.width.max(1) - 1) as f64);
        let v = v.clamp(0.0, (self.height.max(1) - 1) as f64);
        let (c0, r0) = (u.floor() as usize, v.floor() as usize);
        let (c1, r1) = ((c0 + 1).min(self.width - 1), (r0 + 1).min(self.height - 1));
        let (fu, fv) = (u - c0 as f64, v - r0 as f64);
        let at = |c: usize, r: usize| {
            values
                .get(r * self.width + c)
                .map_or(0.0, |&z| f64::from(z))
        };
        let top = at(c0, r0) * (1.0 - fu) + at(c1, r0) * fu;
        let bottom = at(c0, r1) * (1.0 - fu) + at(c1, r1) * fu;
        top * (1.0 - fv) + bottom * fv
    }

    /// Evaluates `f(x, y)` at every cell centre, rows in parallel (order-independent).
    pub fn map<F: Fn(f64, f64) -> f32 + Sync>(&self, f: F) -> Vec<f32> {
        let rows: Vec<Vec<f32>> = (0..self.height)
            .into_par_iter()
            .map(|r| {
                (0..self.width)
                    .map(|c| self.centre(c, r))
                    .map(|[x, y]| f(x, y))
                    .collect()
            })
            .collect();
        rows.concat()
    }
}

/// Separable Gaussian blur of a row-major grid (edges clamped), rows/columns in parallel.
pub fn gaussian_blur(values: &[f32], width: usize, height: usize, sigma_cells: f64) -> Vec<f32> {
    if sigma_cells < 0.05 || width == 0 || height == 0 {
        return values.to_vec();
    }
    let radius = (3.0 * sigma_cells).ceil() as isize;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma_cells * sigma_cells)).exp())
        .collect();
    let norm: f64 = kernel.iter().sum();
    let pass = |src: &[f32], n: usize, stride: usize, lines: usize, step: usize| -> Vec<Vec<f32>> {
        (0..lines)
            .into_par_iter()
            .map(|l| {
                (0..n)
                    .map(|i| {
                        let mut acc = 0.0;
                        for (k, w) in kernel.iter().enumerate() {
                            let j = (i as isize + k as isize - radius).clamp(0, n as isize - 1);
                            let idx = l * step + j as usize * stride;
                            acc += w * src.get(idx).map_or(0.0, |&v| f64::from(v));
                        }
                        (acc / norm) as f32
                    })
                    .collect()
            })
            .collect()
    };
    let horizontal = pass(values, width, 1, height, width).concat();
    let columns = pass(&horizontal, height, width, width, 1);
    let mut out = vec![0.0f32; width * height];
    for (c, col) in columns.iter().enumerate() {
        for (r, v) in col.iter().enumerate() {
            if let Some(o) = out.get_mut(r * width + c) {
                *o = *v;
            }
        }
    }
    out
}

/// Marker radius used everywhere (re-exported for instruments).
pub const BALL_RADIUS_M: f64 = MARKER_RADIUS_M;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_shape_covers_extent_and_samples_planes_exactly() {
        let g = GridShape::covering([2.0, 1.0], 0.25);
        assert_eq!((g.width, g.height), (9, 5));
        assert_eq!(g.centre(0, 0), [0.0, 1.0]);
        assert_eq!(g.centre(8, 4), [2.0, 0.0]);
        let plane = g.map(|x, y| (0.5 * x - 0.25 * y) as f32);
        let z = g.bilinear(&plane, 1.13, 0.37);
        assert!((z - (0.5 * 1.13 - 0.25 * 0.37)).abs() < 1e-6);
    }

    #[test]
    fn blur_preserves_constants_and_mass() {
        let v = vec![2.0f32; 30 * 20];
        assert!(gaussian_blur(&v, 30, 20, 2.0)
            .iter()
            .all(|&x| (x - 2.0).abs() < 1e-5));
        let mut spike = vec![0.0f32; 41 * 41];
        spike[20 * 41 + 20] = 1.0;
        let b = gaussian_blur(&spike, 41, 41, 2.0);
        let sum: f32 = b.iter().sum();
        assert!((sum - 1.0).abs() < 1e-4);
        // Variance along x of the blurred spike equals sigma^2.
        let var: f32 = (0..41)
            .map(|c| (0..41).map(|r| b[r * 41 + c]).sum::<f32>() * ((c as f32 - 20.0).powi(2)))
            .sum();
        assert!((var - 4.0).abs() < 0.05, "{var}");
    }
}
