//! DEM gridding benchmark against a known true surface, and the export for the peer comparison
//! `tools/peers/gridding_scipy.py` (issue #4: compile speed next to a peer doing the same
//! gridding).
//!
//! Generates the synthetic laser terrain of `bench_dem` (`common/mod.rs`: ~4 M points by default,
//! `--points N`, jittered around a square grid over 8.7 × 8.6 m, 8 mm range noise, per-point
//! albedo) and runs the laser DEM exactly as `regolith compile` does (`compile::laser_terrain`):
//! `dem.tin` (`build_tin` of the points and their albedo), then `dem.raster` with the long-edge
//! limit `MaxEdge::Absolute(LASER_MAX_EDGE_M)`, base −0.1 m, at most 2^28 cells, no crop, and local regression
//! over `DEM_REGRESSION_SPACINGS` median TIN edges, at the compile's five cell sizes (`--cells`).
//! Each cell size is a separate `rasterize_all` call, timed alone; its time includes the per-call
//! setup (median edge, triangle preparation, TIN area) that the compile does once for all cells.
//! Then the compile's own single call over all the cell sizes is timed too, and its grids are
//! checked to be bit-identical to the per-cell ones (every raster depends only on the TIN and its
//! cell). `--heights-only` drops the albedo (the TIN and rasters then carry heights only, as the
//! peer's do); `--tin-only` skips the regression (plain TIN interpolation at the cell centres, as
//! the peer's linear gridding does: a diagnostic, not what the compile runs); `--threads N` sizes
//! rayon's pool (default: all cores).
//!
//! Prints per cell: seconds, valid cells, fallback cells of the regression, and the height RMS and
//! max |error| against the true surface over the valid cells. With `--export DIR` it also writes
//! `points.f64` (the points as little-endian f64 x, y, z, in the order given to `build_tin`),
//! `grid.json` (per raster: cell, rows, cols, origin = centre of the north-west cell, bounds, and
//! the file names), `truth_<cell>.f32` (the true surface at each cell centre, row-major, row 0 =
//! north), `ours_<cell>.f32` (our heights, NaN = nodata) and `ours.json` (our timings and errors).
//!
//! `cargo run --release -p regolith-compiler --example bench_gridding -- [--points N] [--threads
//! N] [--cells 0.03,0.02] [--heights-only] [--tin-only] [--export DIR]` (memory: ~1.2 GB at 4 M
//! points).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::{Path, PathBuf};
use std::time::Instant;

use common::{cloud, Scene, EXTENT, NOISE_M};
use rayon::prelude::*;
use regolith_compiler::compile::{DEM_REGRESSION_SPACINGS, LASER_MAX_EDGE_M};
use regolith_compiler::stages::dem_raster::{DemRaster, MaxEdge, Raster};
use regolith_compiler::stages::dem_tin::build_tin;
use serde_json::json;

/// The true surface at every cell centre of `r`, row-major.
fn truth(scene: &Scene, r: &Raster) -> Vec<f64> {
    (0..r.rows * r.cols)
        .into_par_iter()
        .map(|k| {
            let [x, y] = r.cell_centre(k / r.cols, k % r.cols);
            scene.z(x, y)
        })
        .collect()
}

/// Valid cells, RMS and max |height − truth| over them.
fn errors(heights: &[f32], truth: &[f64]) -> (usize, f64, f64) {
    let (n, ss, max) = heights
        .par_iter()
        .zip(truth)
        .filter(|(h, _)| h.is_finite())
        .map(|(&h, &t)| {
            let e = f64::from(h) - t;
            (1usize, e * e, e.abs())
        })
        .reduce(
            || (0, 0.0, 0.0),
            |a, b| (a.0 + b.0, a.1 + b.1, f64::max(a.2, b.2)),
        );
    let rms = if n > 0 {
        (ss / n as f64).sqrt()
    } else {
        f64::NAN
    };
    (n, rms, max)
}

fn write_f32(path: &Path, v: impl Iterator<Item = f32>) {
    let bytes: Vec<u8> = v.flat_map(f32::to_le_bytes).collect();
    std::fs::write(path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| common::flag_value(&args, flag);
    let points: usize = value("--points").map_or(4_000_000, |v| v.parse().expect("--points N"));
    let threads: usize = value("--threads").map_or(0, |v| v.parse().expect("--threads N"));
    let cells: Vec<f64> = value("--cells").map_or(vec![0.030, 0.020, 0.015, 0.010, 0.005], |v| {
        v.split(',').map(|c| c.parse().expect("--cells")).collect()
    });
    let heights_only = args.iter().any(|a| a == "--heights-only");
    let tin_only = args.iter().any(|a| a == "--tin-only");
    let export = value("--export").map(PathBuf::from);
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .expect("thread pool");
    if let Some(d) = &export {
        std::fs::create_dir_all(d).expect("export dir");
    }

    let t = Instant::now();
    let scene = Scene::new();
    let (vertices, albedo) = cloud(&scene, points);
    let albedo = (!heights_only).then_some(albedo);
    let input_s = t.elapsed().as_secs_f64();
    if let Some(d) = &export {
        let bytes: Vec<u8> = vertices
            .iter()
            .flat_map(|p| p.iter().flat_map(|v| v.to_le_bytes()))
            .collect();
        std::fs::write(d.join("points.f64"), bytes).expect("write points.f64");
    }
    let threads = rayon::current_num_threads();
    println!(
        "{} points over {} x {} m, {} mm noise, {}{}, {threads} threads, input {input_s:.1} s",
        vertices.len(),
        EXTENT[0],
        EXTENT[1],
        NOISE_M * 1e3,
        if heights_only {
            "heights only"
        } else {
            "heights + albedo"
        },
        if tin_only {
            ", TIN interpolation only (no regression)"
        } else {
            ""
        },
    );

    let t = Instant::now();
    let tin = build_tin(&vertices, albedo.as_deref(), LASER_MAX_EDGE_M).expect("dem.tin");
    let tin_s = t.elapsed().as_secs_f64();
    drop((vertices, albedo));
    println!(
        "dem.tin: {} vertices, {} triangles, {tin_s:.3} s",
        tin.vertices.len(),
        tin.triangles.len()
    );

    // `compile::laser_terrain`'s `dem.raster` (no crop) at the given cell sizes.
    let stage = |cells: Vec<f64>| {
        DemRaster::new(
            cells,
            None,
            MaxEdge::Absolute(LASER_MAX_EDGE_M),
            -0.1,
            1 << 28,
        )
        .expect("dem.raster parameters")
        .with_regression((!tin_only).then_some(DEM_REGRESSION_SPACINGS))
    };
    println!("cell_m  cells       valid       fallback  support_mm  seconds  rms_mm  max_mm");
    let (mut raster_s, mut rows_json, mut grid_json) = (0.0, Vec::new(), Vec::new());
    let mut grids: Vec<(Vec<f32>, Option<Vec<f32>>)> = Vec::new();
    for &cell in &cells {
        let t = Instant::now();
        let r = stage(vec![cell])
            .rasterize_all(&tin)
            .expect("dem.raster")
            .pop()
            .expect("one raster");
        let secs = t.elapsed().as_secs_f64();
        raster_s += secs;
        let truth = truth(&scene, &r);
        let (valid, rms, max) = errors(&r.heights, &truth);
        let fallback = r.stats.regression_fallback_cells;
        println!(
            "{cell:<7} {:<11} {valid:<11} {fallback:<9} {:<11.2} {secs:<8.3} {:<7.3} {:.3}",
            r.rows * r.cols,
            r.stats.regression_support_m * 1e3,
            rms * 1e3,
            max * 1e3
        );
        rows_json.push(json!({
            "cell_m": cell, "seconds": secs, "cells": r.rows * r.cols, "valid": valid,
            "regression_fallback_cells": fallback,
            "regression_support_m": r.stats.regression_support_m,
            "rms_m": rms, "max_m": max,
        }));
        let (truth_file, ours_file) = (format!("truth_{cell}.f32"), format!("ours_{cell}.f32"));
        grid_json.push(json!({
            "cell_m": cell, "rows": r.rows, "cols": r.cols, "origin": r.origin,
            "bounds": r.bounds, "truth": truth_file, "ours": ours_file,
        }));
        if let Some(d) = &export {
            write_f32(&d.join(&truth_file), truth.iter().map(|&z| z as f32));
            write_f32(&d.join(&ours_file), r.heights.iter().copied());
        }
        grids.push((r.heights, r.albedo));
    }
    // The compile's single call over all cell sizes: the same grids, its setup done once.
    let t = Instant::now();
    let all = stage(cells.clone())
        .rasterize_all(&tin)
        .expect("dem.raster");
    let one_call_s = t.elapsed().as_secs_f64();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
    for (r, (h, a)) in all.iter().zip(&grids) {
        assert!(
            bits(&r.heights) == bits(h) && r.albedo.as_deref().map(bits) == a.as_deref().map(bits),
            "the {} m raster of the all-cells call differs from its own call",
            r.cell_m
        );
    }
    drop((all, grids));
    println!(
        "total {:.3} s (dem.tin {tin_s:.3} s + dem.raster {raster_s:.3} s in one call per cell)",
        tin_s + raster_s
    );
    println!(
        "as regolith compile: {:.3} s (dem.tin {tin_s:.3} s + one dem.raster call over all cells \
         {one_call_s:.3} s; its grids are bit-identical to the per-cell calls)",
        tin_s + one_call_s
    );
    if let Some(d) = &export {
        let grid = json!({
            "points": tin.vertices.len() + tin.duplicates_merged,
            "points_file": "points.f64",
            "extent_m": EXTENT,
            "noise_m": NOISE_M,
            "rasters": grid_json,
        });
        let ours = json!({
            "threads": threads,
            "albedo": !heights_only,
            "regression": !tin_only,
            "points": tin.vertices.len() + tin.duplicates_merged,
            "tin_vertices": tin.vertices.len(),
            "tin_triangles": tin.triangles.len(),
            "input_s": input_s,
            "tin_s": tin_s,
            "raster_s": raster_s,
            "total_s": tin_s + raster_s,
            "one_call_raster_s": one_call_s,
            "one_call_total_s": tin_s + one_call_s,
            "rasters": rows_json,
        });
        for (name, v) in [("grid.json", grid), ("ours.json", ours)] {
            let text = serde_json::to_string_pretty(&v).expect("json");
            std::fs::write(d.join(name), text + "\n").expect("write json");
        }
        println!("exported to {}", d.display());
    }
}
