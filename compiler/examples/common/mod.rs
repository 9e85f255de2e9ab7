//! The synthetic laser terrain shared by the DEM benchmarks (`bench_dem`, `bench_gridding`): a
//! rough surface over 8.7 × 8.6 m (undulations, a ridge, steep-edged boulders) with a known true
//! height `Scene::z`, and points jittered around a square grid with 8 mm of range noise and a
//! per-point albedo with dark pebbles. Deterministic: the same `n` gives the same points.
// Each example compiles its own copy of this module and uses only part of it.
#![allow(dead_code)]

use rayon::prelude::*;

pub const EXTENT: [f64; 2] = [8.7, 8.6];
pub const NOISE_M: f64 = 0.008;

/// A deterministic hash of `(seed, i)` to [0, 1).
pub fn unit(seed: u64, i: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(i.wrapping_mul(0xBF58_476D_1CE4_E5B9));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Approximately normal noise of standard deviation `sigma` (sum of four uniforms).
pub fn gauss(seed: u64, i: u64, sigma: f64) -> f64 {
    let s: f64 = (0..4).map(|k| unit(seed + k, i)).sum();
    (s - 2.0) * 3f64.sqrt() * sigma
}

/// Boulders `(x, y, radius, height)` and dark pebbles `(x, y, radius)`.
pub struct Scene {
    boulders: Vec<[f64; 4]>,
    pebbles: Vec<[f64; 3]>,
    /// Pebble indices per 10 cm grid cell.
    pebble_grid: Vec<Vec<u32>>,
    pebble_cols: usize,
}

impl Scene {
    pub fn new() -> Scene {
        let boulders = (0..60u64)
            .map(|k| {
                [
                    unit(11, k) * EXTENT[0],
                    unit(12, k) * EXTENT[1],
                    0.05 + 0.25 * unit(13, k),
                    0.03 + 0.3 * unit(14, k),
                ]
            })
            .collect();
        let pebbles: Vec<[f64; 3]> = (0..20_000u64)
            .map(|k| {
                [
                    unit(21, k) * EXTENT[0],
                    unit(22, k) * EXTENT[1],
                    0.005 + 0.005 * unit(23, k),
                ]
            })
            .collect();
        let pebble_cols = (EXTENT[0] / 0.1).ceil() as usize + 1;
        let rows = (EXTENT[1] / 0.1).ceil() as usize + 1;
        let mut pebble_grid = vec![Vec::new(); pebble_cols * rows];
        for (k, p) in (0u32..).zip(&pebbles) {
            let (c0, c1) = (((p[0] - p[2]) / 0.1).floor(), ((p[0] + p[2]) / 0.1).floor());
            let (r0, r1) = (((p[1] - p[2]) / 0.1).floor(), ((p[1] + p[2]) / 0.1).floor());
            for r in r0.max(0.0) as usize..=(r1.max(0.0) as usize).min(rows - 1) {
                for c in c0.max(0.0) as usize..=(c1.max(0.0) as usize).min(pebble_cols - 1) {
                    pebble_grid[r * pebble_cols + c].push(k);
                }
            }
        }
        Scene {
            boulders,
            pebbles,
            pebble_grid,
            pebble_cols,
        }
    }

    /// The true surface height.
    pub fn z(&self, x: f64, y: f64) -> f64 {
        let mut z = 0.04 * (1.3 * x).sin() * (0.9 * y).cos()
            + 0.015 * (7.0 * x + 3.0 * y).sin()
            + 0.02 * x
            + 0.1 * (-((x - 4.0) * 0.8 - (y - 3.0) * 0.6).powi(2) / 0.5).exp();
        for b in &self.boulders {
            let d2 = (x - b[0]).powi(2) + (y - b[1]).powi(2);
            if d2 < b[2] * b[2] {
                // Steep-sided: a flattened dome that rises within 2 cm of its edge.
                let t = 1.0 - d2 / (b[2] * b[2]);
                z += b[3] * t.powf(0.25);
            }
        }
        z
    }

    /// The true albedo.
    pub fn albedo(&self, x: f64, y: f64) -> f64 {
        let base = 0.25 + 0.05 * (2.1 * x).sin() * (1.7 * y).sin();
        let (c, r) = ((x / 0.1).floor(), (y / 0.1).floor());
        let cell = (r.max(0.0) as usize) * self.pebble_cols + c.max(0.0) as usize;
        let dark = self.pebble_grid.get(cell).is_some_and(|list| {
            list.iter().any(|&k| {
                let p = self.pebbles[k as usize];
                (x - p[0]).powi(2) + (y - p[1]).powi(2) < p[2] * p[2]
            })
        });
        if dark {
            0.08
        } else {
            base
        }
    }
}

/// Points jittered around a square grid of about `n` nodes over `EXTENT`, x-sorted (then y), with
/// their albedo.
pub fn cloud(scene: &Scene, n: usize) -> (Vec<[f64; 3]>, Vec<f32>) {
    let step = (EXTENT[0] * EXTENT[1] / n as f64).sqrt();
    let (nx, ny) = (
        (EXTENT[0] / step).round() as usize,
        (EXTENT[1] / step).round() as usize,
    );
    let mut pts: Vec<([f64; 3], f32)> = (0..nx * ny)
        .into_par_iter()
        .map(|k| {
            let (i, j) = (k % nx, k / nx);
            let kk = k as u64;
            let x = (i as f64 + 0.5 + 0.9 * (unit(1, kk) - 0.5)) * step;
            let y = (j as f64 + 0.5 + 0.9 * (unit(2, kk) - 0.5)) * step;
            let z = scene.z(x, y) + gauss(3, kk, NOISE_M);
            let a = (scene.albedo(x, y) * (1.0 + gauss(8, kk, 0.1))).max(0.0);
            ([x, y, z], a as f32)
        })
        .collect();
    pts.par_sort_unstable_by(|a, b| a.0[0].total_cmp(&b.0[0]).then(a.0[1].total_cmp(&b.0[1])));
    let albedo = pts.iter().map(|p| p.1).collect();
    let vertices = pts.into_iter().map(|p| p.0).collect();
    (vertices, albedo)
}

/// The argument after `flag` in `args`, if `flag` is given (a flag without a value aborts the
/// benchmark with a message).
pub fn flag_value<'a>(args: &'a [String], flag: &str) -> Option<&'a String> {
    args.iter().position(|a| a == flag).map(|i| {
        args.get(i + 1)
            .unwrap_or_else(|| panic!("{flag} needs a value"))
    })
}
