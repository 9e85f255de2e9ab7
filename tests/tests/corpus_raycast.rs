//! The corpus' own ray caster (`regolith_corpus::terrain::raycast::TerrainCaster`) against the
//! validator's `HeightfieldTracer` on a rough random terrain with a hole: both intersect the
//! same surface (quads split along the NW–SE diagonal, holes removing the touching triangles),
//! so on ~200 k rays of every kind — camera-like rays from above, scanner-like rays from far
//! away at low elevation, rays leaving points just above the surface in any direction, rays
//! from outside the grid — they must agree on hit/miss (but for a tiny fraction of
//! edge-grazing rays), on `t` to 1e-9 relative and on the normal to 1e-9. Both casters' speed
//! is printed (informational).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::time::Instant;

use regolith_corpus::terrain::raycast::TerrainCaster;
use regolith_corpus::HeightGrid;
use regolith_validator::render::HeightfieldTracer;

/// Deterministic splitmix64 generator (the tests crate has no `rand`).
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// A uniformly random unit vector.
    fn sphere(&mut self) -> [f64; 3] {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let s = (1.0 - z * z).sqrt();
        [s * phi.cos(), s * phi.sin(), z]
    }
}

const W: usize = 300;
const H: usize = 250;
const CELL: f64 = 0.004;
const ORIGIN: [f64; 2] = [10.3, 20.7];

/// Rough terrain: a few sines (a few cm), 1 mm of per-cell noise, a round hole of NaN and a
/// few scattered NaN cells.
fn terrain(seed: u64) -> HeightGrid {
    let mut rng = Rng(seed);
    let waves: Vec<[f64; 4]> = (0..5)
        .map(|_| {
            [
                rng.range(0.002, 0.02), // amplitude, m
                rng.range(2.0, 40.0),   // wavenumber x, 1/m
                rng.range(2.0, 40.0),   // wavenumber y, 1/m
                rng.range(0.0, std::f64::consts::TAU),
            ]
        })
        .collect();
    let mut z = Vec::with_capacity(W * H);
    for r in 0..H {
        for c in 0..W {
            let x = c as f64 * CELL;
            let y = r as f64 * CELL;
            let mut h: f64 = waves
                .iter()
                .map(|[a, kx, ky, ph]| a * (kx * x + ky * y + ph).sin())
                .sum();
            h += rng.range(-0.001, 0.001);
            let hole = (c as f64 - 180.0).powi(2) + (r as f64 - 90.0).powi(2) < 12.0f64.powi(2);
            z.push(if hole { f32::NAN } else { (h + 0.3) as f32 });
        }
    }
    for _ in 0..40 {
        let k = (rng.next_u64() % (W * H) as u64) as usize;
        z[k] = f32::NAN;
    }
    HeightGrid {
        origin_m: ORIGIN,
        cell_m: CELL,
        width: W,
        height: H,
        z,
    }
}

/// Highest finite height among the four cells around ground `(x, y)` (clamped to the grid).
fn local_top(g: &HeightGrid, x: f64, y: f64) -> f64 {
    let u = ((x - g.origin_m[0]) / g.cell_m).clamp(0.0, (g.width - 2) as f64);
    let v = ((g.origin_m[1] - y) / g.cell_m).clamp(0.0, (g.height - 2) as f64);
    let (c, r) = (u.floor() as usize, v.floor() as usize);
    [(c, r), (c + 1, r), (c, r + 1), (c + 1, r + 1)]
        .iter()
        .map(|&(c, r)| f64::from(g.z[r * g.width + c]))
        .filter(|h| h.is_finite())
        .fold(0.3, f64::max)
}

struct Ray {
    o: [f64; 3],
    d: [f64; 3],
    t_max: f64,
}

/// ~200 k rays: four kinds, 50 k each.
fn rays(g: &HeightGrid, seed: u64) -> Vec<Ray> {
    let mut rng = Rng(seed);
    let (x0, x1) = (
        g.origin_m[0],
        g.origin_m[0] + (g.width - 1) as f64 * g.cell_m,
    );
    let (y1, y0) = (
        g.origin_m[1],
        g.origin_m[1] - (g.height - 1) as f64 * g.cell_m,
    );
    let centre = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
    let mut out = Vec::new();
    for k in 0..200_000 {
        let ray = match k % 4 {
            // Camera-like: from 5 cm to 2 m above, down at up to 60 degrees off nadir.
            0 => {
                let o = [
                    rng.range(x0 - 0.1, x1 + 0.1),
                    rng.range(y0 - 0.1, y1 + 0.1),
                    0.35 + rng.range(0.05, 2.0),
                ];
                let zen = rng.range(0.0, 60f64.to_radians());
                let az = rng.range(0.0, std::f64::consts::TAU);
                let d = [zen.sin() * az.cos(), zen.sin() * az.sin(), -zen.cos()];
                Ray { o, d, t_max: 10.0 }
            }
            // Scanner-like: 1.5-6 m from the centre, 0.2-1.5 m up, aimed at a random point of
            // the domain at surface level (elevations of a few degrees); non-unit direction.
            1 => {
                let az = rng.range(0.0, std::f64::consts::TAU);
                let dist = rng.range(1.5, 6.0);
                let o = [
                    centre[0] + dist * az.cos(),
                    centre[1] + dist * az.sin(),
                    0.3 + rng.range(0.2, 1.5),
                ];
                let target = [
                    rng.range(x0, x1),
                    rng.range(y0, y1),
                    0.3 + rng.range(-0.03, 0.03),
                ];
                let s = rng.range(0.5, 3.0);
                let d = [
                    (target[0] - o[0]) * s,
                    (target[1] - o[1]) * s,
                    (target[2] - o[2]) * s,
                ];
                Ray { o, d, t_max: 30.0 }
            }
            // Leaving a point just above the surface, any direction (shadow/secondary rays).
            2 => {
                let x = rng.range(x0, x1);
                let y = rng.range(y0, y1);
                let o = [x, y, local_top(g, x, y) + rng.range(1e-4, 5e-3)];
                Ray {
                    o,
                    d: rng.sphere(),
                    t_max: 5.0,
                }
            }
            // From anywhere around the grid (inside or outside the box), any direction below
            // the horizon.
            _ => {
                let o = [
                    rng.range(x0 - 0.5, x1 + 0.5),
                    rng.range(y0 - 0.5, y1 + 0.5),
                    rng.range(0.3, 0.6),
                ];
                let [dx, dy, dz] = rng.sphere();
                let d = [dx, dy, -dz.abs()];
                Ray { o, d, t_max: 5.0 }
            }
        };
        out.push(ray);
    }
    out
}

#[test]
fn corpus_caster_matches_the_validator_tracer() {
    let grid = terrain(0x5eed_2024);
    let rays = rays(&grid, 42);
    let ours = TerrainCaster::new(&grid);
    let theirs = HeightfieldTracer::new(&grid);

    // Speed (informational): single thread, per ray kind and overall; the two casters are
    // timed alternately, best of 3, to damp the noise of a shared machine.
    let rate = |sub: &[&Ray], f: &dyn Fn(&Ray) -> bool| {
        let start = Instant::now();
        let hits = sub.iter().filter(|r| f(r)).count();
        assert!(hits > 0);
        sub.len() as f64 / start.elapsed().as_secs_f64() / 1e6
    };
    let mut total = [0.0f64; 2];
    for (kind, name) in ["above", "scanner", "near-surface", "around"]
        .iter()
        .enumerate()
    {
        let sub: Vec<&Ray> = rays.iter().skip(kind).step_by(4).collect();
        let mut best = [0.0f64; 2];
        for _ in 0..3 {
            best[0] = best[0].max(rate(&sub, &|r| ours.trace(r.o, r.d, r.t_max).is_some()));
            best[1] = best[1].max(rate(&sub, &|r| theirs.trace(r.o, r.d, r.t_max).is_some()));
        }
        total[0] += 1.0 / best[0];
        total[1] += 1.0 / best[1];
        println!(
            "{name:>12}: corpus TerrainCaster {:.2} M rays/s, validator HeightfieldTracer \
             {:.2} M rays/s (1 thread)",
            best[0], best[1]
        );
    }
    println!(
        "{:>12}: corpus TerrainCaster {:.2} M rays/s, validator HeightfieldTracer {:.2} M rays/s, \
         ratio {:.2}",
        "all",
        4.0 / total[0],
        4.0 / total[1],
        total[1] / total[0]
    );

    let mut hits = [0usize; 4];
    let mut mismatches = Vec::new();
    let mut worst_t = 0.0f64;
    let mut worst_n = 0.0f64;
    for (k, r) in rays.iter().enumerate() {
        let a = ours.trace(r.o, r.d, r.t_max);
        let b = theirs.trace(r.o, r.d, r.t_max);
        assert_eq!(
            ours.occluded(r.o, r.d, r.t_max),
            a.is_some(),
            "occluded disagrees with trace on ray {k}"
        );
        match (a, b) {
            (Some(a), Some(b)) => {
                let dt = (a.t - b.t).abs() / b.t.abs().max(1e-300);
                let dn = (0..3)
                    .map(|i| (a.normal[i] - b.normal[i]).abs())
                    .fold(0.0, f64::max);
                if dt > 1e-9 || dn > 1e-9 {
                    mismatches.push(format!(
                        "ray {k} kind {}: t {} vs {}, n {:?} vs {:?}",
                        k % 4,
                        a.t,
                        b.t,
                        a.normal,
                        b.normal
                    ));
                } else {
                    worst_t = worst_t.max(dt);
                    worst_n = worst_n.max(dn);
                    hits[k % 4] += 1;
                }
                let dp = (0..3)
                    .map(|i| (a.point[i] - (r.o[i] + a.t * r.d[i])).abs())
                    .fold(0.0, f64::max);
                assert!(dp < 1e-12, "ray {k}: point off the ray by {dp}");
                assert!(a.normal[2] > 0.0, "ray {k}: normal {:?}", a.normal);
            }
            (None, None) => {}
            (a, b) => mismatches.push(format!(
                "ray {k} kind {}: corpus {:?} vs validator {:?}",
                k % 4,
                a.map(|h| h.t),
                b.map(|h| h.t)
            )),
        }
    }
    println!(
        "agreeing hits per kind (above, scanner, near-surface, around): {hits:?}; \
         worst relative dt {worst_t:.2e}, worst normal difference {worst_n:.2e}"
    );
    println!("mismatches: {} of {} rays", mismatches.len(), rays.len());
    for m in mismatches.iter().take(20) {
        println!("  {m}");
    }
    // Every kind is well exercised.
    assert!(hits.iter().all(|&h| h > 5_000), "{hits:?}");
    assert!(
        mismatches.len() as f64 <= 1e-4 * rays.len() as f64,
        "{} mismatches",
        mismatches.len()
    );
}
