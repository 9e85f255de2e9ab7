//! Albedo of the true surface, by material.
//!
//! The Mars-yard is grey: sandy soil (albedo ≈ 0.33, with decimetre-scale patches of lighter
//! dust and darker gravel and a millimetre grain), white gypsum boulders (≈ 0.78), dark pebbles
//! (≈ 0.18) and the white retro-reflective marker balls (0.98). Values are drawn from noise
//! keyed by the seed and the cell centre, so they do not depend on evaluation order. The grid
//! has the geometry of the height grid, so one bilinear lookup serves both.

use regolith_format::grid::AlbedoGrid;

use super::synth::material;
use super::GridShape;
use crate::seeding::{fractal, lattice, stage_hash};

/// Albedo of a survey marker ball (white).
pub const MARKER_ALBEDO: f64 = 0.98;

/// Builds the albedo grid from the per-cell materials.
pub fn albedo(shape: &GridShape, materials: &[u8], seed: u64) -> AlbedoGrid {
    let patches = stage_hash(seed, "albedo.patches", 0);
    let grain = stage_hash(seed, "albedo.grain", 0);
    let ids: Vec<f32> = materials.iter().map(|&m| f32::from(m)).collect();
    let value = shape.map(|x, y| {
        // Nearest cell's material (the map evaluates exactly at cell centres).
        let m = shape.bilinear(&ids, x, y).round() as u8;
        let [u, v] = shape.to_grid(x, y);
        let g = lattice(grain, u.round() as i64, v.round() as i64) - 0.5;
        let a = match m {
            material::GYPSUM => 0.78 + 0.08 * g,
            material::PEBBLE => 0.18 + 0.08 * g,
            material::MARKER => MARKER_ALBEDO,
            _ => 0.33 + 0.07 * fractal(patches, x, y, 0.8, 0.05, 0.7) + 0.08 * g,
        };
        a.clamp(0.02, 1.0) as f32
    });
    AlbedoGrid {
        origin_m: shape.origin_m,
        cell_m: shape.cell_m,
        width: shape.width,
        height: shape.height,
        value,
    }
}
