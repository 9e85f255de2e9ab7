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

mod common;

use std::path::PathBuf;
use std::time::Instant;

use common::{cloud, gauss, Scene, NOISE_M};
use rayon::prelude::*;
use regolith_compiler::compile::DEM_REGRESSION_SPACINGS;
use regolith_compiler::stages::dem_raster::{Raster, RasterStats};
use regolith_compiler::stages::dem_regress::regress;
use regolith_compiler::stages::dem_tin::{build_tin, Tin};
use regolith_compiler::stages::geometry::median;
use sha2::{Digest, Sha256};

/// Median horizontal edge of a Delaunay TIN of the vertices in a 1 m² patch.
fn median_edge(tin_vertices: &[[f64; 3]]) -> f64 {
    let patch: Vec<[f64; 3]> = tin_vertices
        .iter()
        .filter(|p| (4.0..5.0).contains(&p[0]) && (4.0..5.0).contains(&p[1]))
        .copied()
        .collect();
    let tin = build_tin(&patch, None, f64::INFINITY).expect("patch TIN");
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
    let value = |flag: &str| common::flag_value(&args, flag);
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
        max_edge_m: None,
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
