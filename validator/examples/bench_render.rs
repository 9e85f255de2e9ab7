//! Renderer benchmark (no criterion): renders a 1280 x 1024 navcam view of a rough 8.7 m
//! terrain at the grid resolutions the compiler and corpus use, and prints ms per view and
//! triangles per second, and a shadowed view relit from its kept camera-ray hits against the
//! full render (`Scene::relight`, what the gap search over a light's direction does).
//! `--export DIR` also writes the 580 x 574 heightfield, the pose and the rendered depth for
//! the Open3D peer check (`tools/peers/render_open3d.py`).
//!
//! Run: `cargo run -p regolith-validator --release --example bench_render [-- --export DIR]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::time::Instant;

use regolith_format::camera_model::{CameraModel, Distortion};
use regolith_validator::render::{
    AlbedoGrid, Geometry, HeightGrid, Light, MeshTexture, RenderOptions, Rendered, Scene,
    TriMeshF32, View,
};

const EXTENT_M: f64 = 8.7;

/// Smooth dunes plus pseudo-random rocks: a deterministic stand-in for a lab terrain.
fn terrain(cell: f64) -> Geometry {
    let n = (EXTENT_M / cell).round() as usize;
    let (w, h) = (n, n - n / 100);
    let mut z = Vec::with_capacity(w * h);
    let mut albedo = Vec::with_capacity(w * h);
    for r in 0..h {
        for c in 0..w {
            let (x, y) = (c as f64 * cell, -(r as f64) * cell);
            let dunes = 0.12 * (x * 1.3).sin() * (y * 0.9).cos() + 0.05 * (x * 4.1 + y * 2.7).sin();
            let mut rocks = 0.0f64;
            for k in 0..12 {
                let (rx, ry) = ((k * 37 % 87) as f64 * 0.1, -((k * 53 % 87) as f64) * 0.1);
                let d2 = (x - rx).powi(2) + (y - ry).powi(2);
                rocks = rocks.max(0.15 - d2 * 2.0);
            }
            z.push((dunes + rocks.max(0.0)) as f32);
            albedo.push((0.35 + 0.15 * (x * 23.0).sin() * (y * 19.0).cos()) as f32);
        }
    }
    Geometry::Heightfield {
        grid: HeightGrid {
            origin_m: [0.0, 0.0],
            cell_m: cell,
            width: w,
            height: h,
            z,
        },
        albedo: AlbedoGrid {
            origin_m: [0.0, 0.0],
            cell_m: cell,
            width: w,
            height: h,
            value: albedo,
        },
    }
}

/// The heightfield as a triangle mesh with the renderer's NW–SE split.
fn as_mesh(g: &Geometry) -> Option<TriMeshF32> {
    let Geometry::Heightfield { grid, albedo } = g else {
        return None;
    };
    let (w, h) = (grid.width, grid.height);
    let mut positions = Vec::with_capacity(w * h);
    for r in 0..h {
        for c in 0..w {
            positions.push([
                (c as f64 * grid.cell_m) as f32,
                -((r as f64) * grid.cell_m) as f32,
                grid.z[r * w + c],
            ]);
        }
    }
    let mut triangles = Vec::new();
    for r in 0..h - 1 {
        for c in 0..w - 1 {
            let (nw, ne, sw, se) = (
                r * w + c,
                r * w + c + 1,
                (r + 1) * w + c,
                (r + 1) * w + c + 1,
            );
            triangles.push([nw as u32, ne as u32, se as u32]);
            triangles.push([nw as u32, se as u32, sw as u32]);
        }
    }
    Some(TriMeshF32 {
        origin_m: [grid.origin_m[0], grid.origin_m[1], 0.0],
        positions,
        triangles,
        albedo: albedo.value.clone(),
        texture: None,
    })
}

fn navcam() -> CameraModel {
    CameraModel {
        distortion: Distortion {
            k1: -0.21,
            k2: 0.09,
            p1: 4e-4,
            p2: -2e-4,
            k3: -0.01,
        },
        ..CameraModel::pinhole(1280, 1024, 832.0, 831.0, 639.5, 511.5)
    }
}

fn view() -> View {
    View::look_at(navcam(), [4.35, -9.2, 1.6], [4.35, -3.5, 0.0])
}

/// CPU time (user + system) of this process in ms, from `/proc/self/stat` (Linux; 0 elsewhere).
/// The machine may be shared, so the bench reports CPU time next to wall time.
fn cpu_ms() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = after
        .split_whitespace()
        .map(|x| x.parse().unwrap_or(0.0))
        .collect();
    // Fields 14 and 15 (utime, stime) are at 11, 12 after the ")"; clock ticks of 10 ms.
    (f.get(11).unwrap_or(&0.0) + f.get(12).unwrap_or(&0.0)) * 10.0
}

/// The campaign light of every benchmark render.
const LIGHT: Light = Light {
    azimuth_deg: 135.0,
    elevation_deg: 35.0,
    ambient: 0.2,
};

/// Median wall time per view, the first view's wall time (it builds the camera's ray table),
/// CPU time per view, and the last image.
fn time_views(scene: &Scene<'_>, opts: &RenderOptions, runs: usize) -> (f64, f64, f64, Rendered) {
    time_runs(runs, || scene.render(&LIGHT, &view(), opts))
}

/// [`time_views`] of any way of making the view.
fn time_runs(runs: usize, make: impl Fn() -> Rendered) -> (f64, f64, f64, Rendered) {
    let cpu0 = cpu_ms();
    let t = Instant::now();
    let mut last = make();
    let mut times = vec![t.elapsed().as_secs_f64() * 1e3];
    for _ in 1..runs {
        let t = Instant::now();
        last = make();
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let cpu = (cpu_ms() - cpu0) / times.len() as f64;
    let first = times[0];
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], first, cpu, last)
}

fn triangles(g: &Geometry) -> usize {
    match g {
        Geometry::Heightfield { grid, .. } => 2 * (grid.width - 1) * (grid.height - 1),
        Geometry::Mesh(m) => m.triangles.len(),
    }
}

fn report(label: &str, g: &Geometry, runs: usize) {
    let t = Instant::now();
    let scene = Scene::new(g);
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let threads = rayon::current_num_threads();
    let mut shadowed_ms = 0.0;
    for (name, opts) in [
        (
            "plain",
            RenderOptions {
                distort: true,
                shadows: false,
                supersample: 1,
                filter_textures: true,
                adaptive: false,
            },
        ),
        (
            "pinhole",
            RenderOptions {
                distort: false,
                shadows: false,
                supersample: 1,
                filter_textures: true,
                adaptive: false,
            },
        ),
        (
            "shadows",
            RenderOptions {
                distort: true,
                shadows: true,
                supersample: 1,
                filter_textures: true,
                adaptive: false,
            },
        ),
    ] {
        let (ms, first, cpu, r) = time_views(&scene, &opts, runs);
        if opts.shadows {
            shadowed_ms = ms;
        }
        let seen = r.mask.iter().filter(|&&m| m == 255).count() as f64 / r.mask.len() as f64;
        println!(
            "{label:<28} {name:<8} build {build_ms:7.1} ms  wall {ms:7.1} ms/view (first {first:6.1})  cpu {cpu:7.1} ms/view  \
             (= {:6.1} ms on {threads} idle cores)  {:6.1} Mtri/s  {:.0}% of pixels see terrain",
            cpu / threads as f64,
            triangles(g) as f64 / (cpu / threads as f64) / 1e3,
            seen * 100.0
        );
    }
    // A search over the light's direction: the camera rays traced once, then each light only
    // shades their hits and casts the shadow rays (the same bytes as the full render).
    let opts = RenderOptions {
        distort: true,
        shadows: true,
        supersample: 1,
        filter_textures: true,
        adaptive: false,
    };
    let hits = scene.primary_hits(&view(), &opts);
    let (ms, _, cpu, _) = time_runs(runs, || scene.relight(&hits, &LIGHT, true));
    println!(
        "{label:<28} relit    wall {ms:7.1} ms/view  cpu {cpu:7.1} ms/view  ({:.2} of the shadowed render: the camera rays traced once)",
        ms / shadowed_ms
    );
}

fn main() -> std::io::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let export = args
        .iter()
        .position(|a| a == "--export")
        .and_then(|i| args.get(i + 1))
        .cloned();
    println!("threads: {}", rayon::current_num_threads());
    let compiled = terrain(0.015);
    report("heightfield 0.015 m (580²)", &compiled, 5);
    if let Some(mesh) = as_mesh(&compiled).filter(|_| std::env::var_os("BENCH_QUICK").is_none()) {
        // The same mesh textured as the compiler writes it: UVs on texel centres.
        let (w, h) = match &compiled {
            Geometry::Heightfield { grid, .. } => (grid.width, grid.height),
            Geometry::Mesh(_) => (mesh.positions.len(), 1),
        };
        let textured = TriMeshF32 {
            albedo: Vec::new(),
            texture: Some(MeshTexture {
                uvs: (0..w * h)
                    .map(|i| {
                        [
                            ((i % w) as f32 + 0.5) / w as f32,
                            ((i / w) as f32 + 0.5) / h as f32,
                        ]
                    })
                    .collect(),
                width: w,
                height: h,
                value: mesh.albedo.clone(),
            }),
            ..mesh.clone()
        };
        report("mesh of the same (~670k tri)", &Geometry::Mesh(mesh), 3);
        report("textured mesh of the same", &Geometry::Mesh(textured), 3);
    }
    if std::env::var_os("BENCH_QUICK").is_none() {
        report("heightfield 0.005 m (1740²)", &terrain(0.005), 3);
        report("heightfield 0.0025 m (3480²)", &terrain(0.0025), 1);
    }
    if let Some(dir) = export {
        export_peer(std::path::Path::new(&dir), &compiled)?;
    }
    Ok(())
}

/// Writes `heightfield.json` + `heightfield.f32` + `albedo.f32`, `view.json` (with the light)
/// and `depth.f32` + `radiance.f32` (undistorted pinhole render, one ray per pixel centre, since
/// Open3D has no lens distortion).
fn export_peer(dir: &std::path::Path, g: &Geometry) -> std::io::Result<()> {
    let Geometry::Heightfield { grid, albedo } = g else {
        return Ok(());
    };
    std::fs::create_dir_all(dir)?;
    let v = view();
    let light = LIGHT;
    let r = Scene::new(g).render(
        &light,
        &v,
        &RenderOptions {
            distort: false,
            shadows: false,
            supersample: 1,
            filter_textures: true,
            adaptive: false,
        },
    );
    let bytes = |xs: &[f32]| xs.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    std::fs::write(dir.join("heightfield.f32"), bytes(&grid.z))?;
    std::fs::write(dir.join("depth.f32"), bytes(&r.depth))?;
    std::fs::write(dir.join("radiance.f32"), bytes(&r.radiance))?;
    std::fs::write(dir.join("albedo.f32"), bytes(&albedo.value))?;
    let meta = serde_json::json!({
        "origin_m": grid.origin_m, "cell_m": grid.cell_m, "width": grid.width, "height": grid.height,
        "split": "nw-se", "z": "heightfield.f32 (f32 LE, row-major, row 0 = north)",
        "albedo": {"file": "albedo.f32", "origin_m": albedo.origin_m, "cell_m": albedo.cell_m,
                   "width": albedo.width, "height": albedo.height},
    });
    std::fs::write(
        dir.join("heightfield.json"),
        serde_json::to_string_pretty(&meta)?,
    )?;
    let cam = v.camera.undistorted();
    let view_json = serde_json::json!({
        "width": cam.width, "height": cam.height, "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
        "ground_from_camera": v.ground_from_camera, "depth": "depth.f32 (f32 LE camera z, NaN = miss)",
        "radiance": "radiance.f32 (f32 LE, albedo x (ambient + (1 - ambient) max(0, n.l)), 0 = miss)",
        "light": light,
    });
    std::fs::write(
        dir.join("view.json"),
        serde_json::to_string_pretty(&view_json)?,
    )?;
    println!("exported peer inputs to {}", dir.display());
    Ok(())
}
