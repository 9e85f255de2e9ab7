//! The relief: hills, a crater, fractal roughness, gypsum boulders, pebbles, marker balls.
//!
//! Built in an order that keeps the surveyed facts exact:
//! 1. a smooth base (a main hill in the north-west as in thesis Fig. 5.4, secondary hills, a
//!    crater bowl with a rim) plus fBm roughness from 1 m down to two grid cells, then affinely
//!    rescaled so the base spans exactly the preset's [crater floor, hill top];
//! 2. where a marker's height is surveyed (Table 5.2), a local Gaussian correction (σ 0.25 m)
//!    moves the surface under the ball to `z - radius`, so the ball sits *on* the surface;
//! 3. boulders and pebbles are stamped as partly buried ellipsoid caps (kept off the markers);
//! 4. the marker balls' upper caps are stamped last.
//!
//! Each step also writes a material id per cell (soil, gypsum, pebble, marker) for the albedo.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::{GridShape, TrueMarker, BALL_RADIUS_M};
use crate::presets::PresetConfig;
use crate::seeding::{fractal, stage_hash, stage_rng};

/// Material ids per cell.
pub mod material {
    /// Sandy soil.
    pub const SOIL: u8 = 0;
    /// Gypsum boulder.
    pub const GYPSUM: u8 = 1;
    /// Dark pebble.
    pub const PEBBLE: u8 = 2;
    /// Retro-reflective marker ball.
    pub const MARKER: u8 = 3;
}

/// Output of [`relief`].
pub struct Built {
    /// Heights, row-major.
    pub z: Vec<f32>,
    /// Material id per cell.
    pub material: Vec<u8>,
    /// Marker balls.
    pub markers: Vec<TrueMarker>,
}

struct Hill {
    centre: [f64; 2],
    sigma: f64,
    amp: f64,
}

/// Builds the relief of a preset on `shape`.
pub fn relief(cfg: &PresetConfig, shape: &GridShape, seed: u64) -> Built {
    let mut rng = stage_rng(seed, "terrain");
    let r = &cfg.relief;
    let scale = cfg.extent_m[0].min(cfg.extent_m[1]) / 8.6;
    let mut hills = vec![Hill {
        centre: [r.main_hill[0], r.main_hill[1]],
        sigma: r.main_hill[2],
        amp: 1.0,
    }];
    for _ in 0..r.hills {
        hills.push(Hill {
            centre: [
                rng.gen_range(0.0..cfg.extent_m[0]),
                rng.gen_range(0.0..cfg.extent_m[1]),
            ],
            sigma: rng.gen_range(0.4..1.1) * scale,
            amp: rng.gen_range(0.12..0.4),
        });
    }
    let crater = r.crater;
    let key = stage_hash(seed, "terrain.roughness", 0);
    let smallest = 2.0 * shape.cell_m;
    let base = shape.map(|x, y| {
        let mut h: f64 = hills
            .iter()
            .map(|hl| {
                let d2 = (x - hl.centre[0]).powi(2) + (y - hl.centre[1]).powi(2);
                hl.amp * (-d2 / (2.0 * hl.sigma * hl.sigma)).exp()
            })
            .sum();
        let d = ((x - crater[0]).powi(2) + (y - crater[1]).powi(2)).sqrt() / crater[2];
        if d < 1.0 {
            h -= 0.45 * (1.0 - d * d);
        }
        h += 0.12 * (-((d - 1.0) / 0.25).powi(2)).exp();
        h += 0.05 * fractal(key, x, y, 1.0 * scale.max(0.3), smallest, 1.0);
        h as f32
    });
    let (lo, hi) = base
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let span = f64::from(hi - lo).max(1e-9);
    let mut z: Vec<f32> = base
        .iter()
        .map(|&v| (r.floor_m + f64::from(v - lo) / span * (r.top_m - r.floor_m)) as f32)
        .collect();
    let mut material = vec![material::SOIL; z.len()];
    seat_markers(cfg, shape, &mut z);
    let centres: Vec<[f64; 3]> = cfg
        .markers
        .iter()
        .map(|m| {
            let ground = shape.bilinear(&z, m.xy[0], m.xy[1]);
            [m.xy[0], m.xy[1], m.z.unwrap_or(ground + BALL_RADIUS_M)]
        })
        .collect();
    for _ in 0..r.boulders {
        let d = 0.05 + 0.35 * rng.gen::<f64>().powi(3);
        stamp_rock(
            shape,
            &mut z,
            &mut material,
            &centres,
            &mut rng,
            d,
            material::GYPSUM,
        );
    }
    for _ in 0..r.pebbles {
        let d = rng.gen_range(0.01..0.04);
        stamp_rock(
            shape,
            &mut z,
            &mut material,
            &centres,
            &mut rng,
            d,
            material::PEBBLE,
        );
    }
    let markers = cfg
        .markers
        .iter()
        .zip(&centres)
        .map(|(m, &c)| {
            stamp_ball(shape, &mut z, &mut material, c);
            TrueMarker {
                name: m.name.to_string(),
                centre_m: c,
                radius_m: BALL_RADIUS_M,
            }
        })
        .collect();
    Built {
        z,
        material,
        markers,
    }
}

/// Moves the surface under each surveyed marker to `z - radius` with a local Gaussian bump.
fn seat_markers(cfg: &PresetConfig, shape: &GridShape, z: &mut [f32]) {
    let sigma = 0.25 * (cfg.extent_m[0].min(cfg.extent_m[1]) / 8.6).max(0.3);
    for _ in 0..3 {
        for m in &cfg.markers {
            let Some(zm) = m.z else { continue };
            let delta = zm - BALL_RADIUS_M - shape.bilinear(z, m.xy[0], m.xy[1]);
            let ([c0, c1], [r0, r1]) = shape.window(m.xy[0], m.xy[1], 4.0 * sigma);
            for r in r0..r1 {
                for c in c0..c1 {
                    let [x, y] = shape.centre(c, r);
                    let d2 = (x - m.xy[0]).powi(2) + (y - m.xy[1]).powi(2);
                    if let Some(v) = z.get_mut(r * shape.width + c) {
                        *v += (delta * (-d2 / (2.0 * sigma * sigma)).exp()) as f32;
                    }
                }
            }
        }
    }
}

/// Stamps one partly buried ellipsoid cap of diameter `d` at a random place off the markers.
#[allow(clippy::too_many_arguments)]
fn stamp_rock(
    shape: &GridShape,
    z: &mut [f32],
    material: &mut [u8],
    markers: &[[f64; 3]],
    rng: &mut ChaCha8Rng,
    d: f64,
    id: u8,
) {
    let extent = [
        (shape.width - 1) as f64 * shape.cell_m,
        (shape.height - 1) as f64 * shape.cell_m,
    ];
    let cx = rng.gen_range(0.0..extent[0]);
    let cy = rng.gen_range(0.0..extent[1]);
    let (a, b) = (0.5 * d, 0.5 * d * rng.gen_range(0.6..1.0));
    let h = a * rng.gen_range(0.5..0.9);
    let angle: f64 = rng.gen_range(0.0..std::f64::consts::PI);
    if markers
        .iter()
        .any(|m| (m[0] - cx).hypot(m[1] - cy) < a + 0.08)
    {
        return;
    }
    let base = shape.bilinear(z, cx, cy) - 0.25 * h;
    let (s, c) = angle.sin_cos();
    let ([c0, c1], [r0, r1]) = shape.window(cx, cy, a);
    for r in r0..r1 {
        for col in c0..c1 {
            let [x, y] = shape.centre(col, r);
            let (dx, dy) = (x - cx, y - cy);
            let (u, v) = ((c * dx + s * dy) / a, (-s * dx + c * dy) / b);
            let q = u * u + v * v;
            if q >= 1.0 {
                continue;
            }
            let top = (base + h * (1.0 - q).sqrt()) as f32;
            let i = r * shape.width + col;
            if let (Some(zv), Some(mv)) = (z.get_mut(i), material.get_mut(i)) {
                if top > *zv {
                    *zv = top;
                    *mv = id;
                }
            }
        }
    }
}

/// Stamps the upper cap of a marker ball centred at `c`.
fn stamp_ball(shape: &GridShape, z: &mut [f32], material: &mut [u8], c: [f64; 3]) {
    let rad = BALL_RADIUS_M;
    let ([c0, c1], [r0, r1]) = shape.window(c[0], c[1], rad);
    for r in r0..r1 {
        for col in c0..c1 {
            let [x, y] = shape.centre(col, r);
            let d2 = (x - c[0]).powi(2) + (y - c[1]).powi(2);
            if d2 >= rad * rad {
                continue;
            }
            let top = (c[2] + (rad * rad - d2).sqrt()) as f32;
            let i = r * shape.width + col;
            if let (Some(zv), Some(mv)) = (z.get_mut(i), material.get_mut(i)) {
                *zv = zv.max(top);
                *mv = material::MARKER;
            }
        }
    }
}
