//! `dem.raster` local-regression benchmark (`stages::dem_regress::regress`) on a synthetic laser
//! terrain: ~19 M points (`--points N`) jittered around a square grid over 8.7 × 8.6 m (2 mm at the
//! default count), a rough surface (undulations, a ridge, steep-edged boulders) with 8 mm of range
//! noise and a per-point albedo with dark pebbles. The vertices are x-sorted as `dem.tin` leaves
//! them; the support is `max(cell, DEM_REGRESSION_SPACINGS × median TIN edge)` as `regolith
//! compile` sets it, the median edge measured on a Delaunay TIN of a 1 m² patch. Each raster is
//! built directly (every cell valid; its TIN value the true surface plus 8 mm of noise) at the five
//! cell sizes of the compile, `regress` is timed alone, and the seconds, the fallback cells and a
//! SHA-256 of the output heights and albedo are printed so two builds can be compared byte for
//! byte. `--dump DIR` writes the raw outputs, `--compare DIR` prints the largest height and
//! albedo difference from such a dump (e.g. one written by the previous code). Timing lives here,
//! never in tests.
//!
//! `cargo run --release -p regolith-compiler --example bench_dem -- [--points N] [--cells
//! 0.03,0.02] [--dump DIR | --compare DIR]` (memory: ~1.3 GB at 19 M points).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;
use regolith_compiler::compile::DEM_REGRESSION_SPACINGS;
use regolith_compiler::stages::dem_raster::{Raster, RasterStats};
use regolith_compiler::stages::dem_regress::regress;
use regolith_compiler::stages::dem_tin::{build_tin, Tin};
use regolith_compiler::stages::geometry::median;
use sha2::{Digest, Sha256};

const EXTENT: [f64; 2] = [8.7, 8.6];
const NOISE_M: f64 = 0.008;

/// A deterministic hash of `(seed, i)` to [0, 1).
fn unit(seed: u64, i: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(i.wrapping_mul(0xBF58_476D_1CE4_E5B9));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Approximately normal noise of standard deviation `sigma` (sum of four uniforms).
fn gauss(seed: u64, i: u64, sigma: f64) -> f64 {
    let s: f64 = (0..4).map(|k| unit(seed + k, i)).sum();
    (s - 2.0) * 3f64.sqrt() * sigma
}

/// Boulders `(x, y, radius, height)` and dark pebbles `(x, y, radius)`.
struct Scene {
    boulders: Vec<[f64; 4]>,
    pebbles: Vec<[f64; 3]>,
    /// Pebble indices per 10 cm grid cell.
    pebble_grid: Vec<Vec<u32>>,
    pebble_cols: usize,
}

impl Scene {
    fn new() -> Scene {
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
    fn z(&self, x: f64, y: f64) -> f64 {
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
    fn albedo(&self, x: f64, y: f64) -> f64 {
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
fn cloud(scene: &Scene, n: usize) -> (Vec<[f64; 3]>, Vec<f32>) {
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

/// Median horizontal edge of a Delaunay TIN of the vertices in a 1 m² patch.
fn median_edge(tin_vertices: &[[f64; 3]]) -> f64 {
    let patch: Vec<[f64; 3]> = tin_vertices
        .iter()
        .filter(|p| (4.0..5.0).contains(&p[0]) && (4.0..5.0).contains(&p[1]))
        .copied()
        .collect();
    let tin = build_tin(&patch, None).expect("patch TIN");
    let d = |a: u32, b: u32| {
        let (p, q) = (tin.vertices[a as usize], tin.vertices[b as usize]);
        (p[0] - q[0]).hypot(p[1] - q[1])
    };
    let mut lens: Vec<f64> = tin
        .triangles
        .iter()
        .flat_map(|t| [d(t[0], t[1]), d(t[1], t[2]), d(t[2], t[0])])
        .collect();
    median(&mut lens).expect("edges")
}

/// A raster over the cloud's extent with every cell valid (TIN value = truth + noise).
fn raster(scene: &Scene, bounds: [f64; 4], cell: f64) -> Raster {
    let count = |span: f64| ((span / cell) - 1e-9).ceil().max(1.0) as usize;
    let (cols, rows) = (count(bounds[2] - bounds[0]), count(bounds[3] - bounds[1]));
    let origin = [bounds[0] + 0.5 * cell, bounds[3] - 0.5 * cell];
    let heights: Vec<f32> = (0..rows * cols)
        .into_par_iter()
        .map(|k| {
            let (r, c) = (k / cols, k % cols);
            let (x, y) = (origin[0] + c as f64 * cell, origin[1] - r as f64 * cell);
            (scene.z(x, y) + gauss(5, k as u64, NOISE_M)) as f32
        })
        .collect();
    Raster {
        cell_m: cell,
        rows,
        cols,
        origin,
        bounds,
        heights,
        albedo: Some(vec![0.0; rows * cols]),
        stats: RasterStats::default(),
    }
}

/// CPU seconds (user + system) of this process so far, from `/proc/self/stat` (NaN elsewhere):
/// less sensitive than wall time to other jobs on the machine.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which ends with the last ')'): state is field 3, utime 14.
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or(vec![], |(_, rest)| rest.split_whitespace().collect());
    let ticks = |k: usize| fields.get(k).and_then(|v| v.parse::<f64>().ok());
    match (ticks(11), ticks(12)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => f64::NAN,
    }
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn read_f32(path: &PathBuf) -> Vec<f32> {
    std::fs::read(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// Largest |a − b| over cells finite in both, and the cells finite in only one.
fn max_diff(a: &[f32], b: &[f32]) -> (f64, usize) {
    assert_eq!(a.len(), b.len(), "grid sizes differ");
    a.iter().zip(b).fold((0.0, 0), |(m, odd), (&x, &y)| {
        match (x.is_finite(), y.is_finite()) {
            (true, true) => (m.max((f64::from(x) - f64::from(y)).abs()), odd),
            (false, false) => (m, odd),
            _ => (m, odd + 1),
        }
    })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter().position(|a| a == flag).map(|i| {
            args.get(i + 1)
                .unwrap_or_else(|| panic!("{flag} needs a value"))
        })
    };
    let points: usize = value("--points").map_or(19_000_000, |v| v.parse().expect("--points N"));
    let cells: Vec<f64> = value("--cells").map_or(vec![0.03, 0.02, 0.015, 0.01, 0.005], |v| {
        v.split(',').map(|c| c.parse().expect("--cells")).collect()
    });
    let dump = value("--dump").map(PathBuf::from);
    let compare = value("--compare").map(PathBuf::from);

    let t = Instant::now();
    let scene = Scene::new();
    let (vertices, albedo) = cloud(&scene, points);
    let edge = median_edge(&vertices);
    let b = vertices.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        },
    );
    let tin = Tin {
        vertices,
        albedo: Some(albedo),
        triangles: vec![],
        duplicates_merged: 0,
    };
    println!(
        "{} points over {:.3} x {:.3} m, median TIN edge {:.2} mm, {} threads, input {:.1} s",
        tin.vertices.len(),
        b[2] - b[0],
        b[3] - b[1],
        edge * 1e3,
        rayon::current_num_threads(),
        t.elapsed().as_secs_f64()
    );
    if let Some(d) = &dump {
        std::fs::create_dir_all(d).expect("dump dir");
    }
    println!("cell_m  support_mm  cells       fallback  seconds  cpu_s    sha256(heights, albedo)");
    let (mut total, mut total_cpu) = (0.0, 0.0);
    let mut all = Sha256::new();
    for &cell in &cells {
        let mut r = raster(&scene, b, cell);
        let support = cell.max(DEM_REGRESSION_SPACINGS * edge);
        let (t, c) = (Instant::now(), cpu_seconds());
        let kept = regress(&tin, &mut r, support, cell);
        let (secs, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        total += secs;
        total_cpu += cpu;
        let (h, a) = (
            f32_bytes(&r.heights),
            f32_bytes(r.albedo.as_deref().unwrap_or(&[])),
        );
        let mut sha = Sha256::new();
        sha.update(&h);
        sha.update(&a);
        let digest = sha.finalize();
        all.update(digest);
        println!(
            "{cell:<7} {:<11.2} {:<11} {kept:<9} {secs:<8.3} {cpu:<8.2} {}",
            support * 1e3,
            r.rows * r.cols,
            digest
                .iter()
                .take(8)
                .map(|x| format!("{x:02x}"))
                .collect::<String>()
        );
        if let Some(d) = &dump {
            std::fs::write(d.join(format!("h_{cell}.f32")), &h).expect("write");
            std::fs::write(d.join(format!("a_{cell}.f32")), &a).expect("write");
        }
        if let Some(d) = &compare {
            let (dh, oh) = max_diff(&r.heights, &read_f32(&d.join(format!("h_{cell}.f32"))));
            let (da, oa) = max_diff(
                r.albedo.as_deref().unwrap_or(&[]),
                &read_f32(&d.join(format!("a_{cell}.f32"))),
            );
            println!(
                "        vs {}: max |dh| {dh:.3e} m, max |dalbedo| {da:.3e}, \
                 cells finite in one only: {oh} / {oa}",
                d.display()
            );
        }
    }
    let digest = all.finalize();
    println!(
        "total {total:.3} s, cpu {total_cpu:.2} s, sha256 {}",
        digest
            .iter()
            .map(|x| format!("{x:02x}"))
            .collect::<String>()
    );
}
