//! Renderer tests: geometry against analytic ray/plane distances, shading against the formula,
//! shadows, a marker projected with `CameraModel::project`, distorted vs. remapped
//! undistorted renders, heightfield vs. mesh, and thread-count determinism. The distorted
//! camera is the real OpenCV sample calibration from `../shared/realdata`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_format::camera_model::{CameraModel, Distortion};
use regolith_validator::render::{
    render, AlbedoGrid, Geometry, HeightGrid, HeightfieldTracer, Light, MeshTexture, RenderOptions,
    Rendered, Scene, Sphere, TriMeshF32, View,
};

const PLAIN: RenderOptions = RenderOptions {
    distort: false,
    shadows: false,
    supersample: 1,
    filter_textures: true,
    adaptive: false,
};

fn grid(w: usize, h: usize, cell: f64, f: impl Fn(f64, f64) -> f64) -> HeightGrid {
    let mut z = Vec::new();
    for r in 0..h {
        for c in 0..w {
            z.push(f(c as f64 * cell, -(r as f64) * cell) as f32);
        }
    }
    HeightGrid {
        origin_m: [0.0, 0.0],
        cell_m: cell,
        width: w,
        height: h,
        z,
    }
}

fn albedo(w: usize, h: usize, cell: f64, f: impl Fn(f64, f64) -> f64) -> AlbedoGrid {
    let g = grid(w, h, cell, f);
    AlbedoGrid {
        origin_m: g.origin_m,
        cell_m: cell,
        width: w,
        height: h,
        value: g.z,
    }
}

fn heightfield(g: HeightGrid, a: f64) -> Geometry {
    let alb = albedo(2, 2, 100.0, |_, _| a);
    Geometry::Heightfield {
        grid: g,
        albedo: alb,
    }
}

fn light(az: f64, el: f64, ambient: f64) -> Light {
    Light {
        azimuth_deg: az,
        elevation_deg: el,
        ambient,
    }
}

/// Numbers of `key: !!opencv-matrix ... data: [ ... ]` in an OpenCV YAML file.
fn opencv_matrix(text: &str, key: &str) -> Vec<f64> {
    let start = text.find(key).expect("key present");
    let data = start + text[start..].find("data:").expect("data") + 5;
    let open = data + text[data..].find('[').expect("[") + 1;
    let close = open + text[open..].find(']').expect("]");
    text[open..close]
        .split(',')
        .map(|v| v.trim().parse().expect("number"))
        .collect()
}

/// The real 640 x 480 calibration of `realdata/calibration/left_intrinsics.yml`.
fn real_camera() -> CameraModel {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/realdata/calibration/left_intrinsics.yml"
    );
    let text = std::fs::read_to_string(path).expect("realdata sample present");
    let k = opencv_matrix(&text, "camera_matrix");
    let d = opencv_matrix(&text, "distortion_coefficients");
    // PROVENANCE.md facts: fx = fy ~ 535.92, cx ~ 342.28, cy ~ 235.57, k1 ~ -0.266.
    assert!((k[0] - 535.92).abs() < 0.01 && (k[4] - 535.92).abs() < 0.01);
    assert!(
        (k[2] - 342.28).abs() < 0.01
            && (k[5] - 235.57).abs() < 0.01
            && (d[0] + 0.266).abs() < 0.001
    );
    CameraModel {
        distortion: Distortion {
            k1: d[0],
            k2: d[1],
            p1: d[2],
            p2: d[3],
            k3: d[4],
        },
        ..CameraModel::pinhole(640, 480, k[0], k[4], k[2], k[5])
    }
}

fn at<T: Copy>(r: &Rendered, v: &[T], px: [f64; 2]) -> T {
    v[px[1].round() as usize * r.width + px[0].round() as usize]
}

/// Camera z of the plane `z = a x + b y + c` along the ray of pixel `(u, v)` (undistorted).
fn plane_depth(view: &View, (a, b, c): (f64, f64, f64), u: f64, v: f64) -> f64 {
    let cam = &view.camera;
    let d = view
        .ground_from_camera
        .rotate([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0]);
    let e = view.ground_from_camera.translation_m;
    // n = (a, b, -1): a x + b y - z + c = 0.
    (-(a * e[0] + b * e[1] - e[2] + c)) / (a * d[0] + b * d[1] - d[2])
}

#[test]
fn flat_and_tilted_plane_depths_match_analytic() {
    let cam = CameraModel::pinhole(101, 81, 80.0, 80.0, 50.0, 40.0);
    let flat = heightfield(grid(101, 101, 0.05, |_, _| 0.5), 0.5);
    let down = View::look_at(cam.clone(), [2.5, -2.5, 3.0], [2.5, -2.5, 0.5]);
    let r = render(&flat, &light(0.0, 60.0, 0.2), &down, &PLAIN);
    assert!((at(&r, &r.depth, [50.0, 40.0]) - 2.5).abs() < 1e-3);
    assert!(r.mask.iter().all(|&m| m == 255), "the plane fills the view");

    let plane = (0.1, -0.05, 0.2);
    let tilted = heightfield(
        grid(101, 101, 0.05, |x, y| plane.0 * x + plane.1 * y + plane.2),
        0.5,
    );
    let target = [2.5, -2.0, 0.1 * 2.5 + 0.05 * 2.0 + 0.2];
    let eye = [0.5, -4.5, 2.0];
    let oblique = View::look_at(cam, eye, target);
    let r = render(&tilted, &light(0.0, 60.0, 0.2), &oblique, &PLAIN);
    let dist = ((0..3).map(|k| (target[k] - eye[k]).powi(2)).sum::<f64>()).sqrt();
    assert!((f64::from(at(&r, &r.depth, [50.0, 40.0])) - dist).abs() < 1e-3);
    let mut checked = 0;
    for v in 0..r.height {
        for u in 0..r.width {
            if r.mask[v * r.width + u] == 255 {
                let want = plane_depth(&oblique, plane, u as f64, v as f64);
                assert!(
                    (f64::from(r.depth[v * r.width + u]) - want).abs() < 1e-3,
                    "pixel {u},{v}"
                );
                checked += 1;
            }
        }
    }
    assert!(
        checked > r.width * r.height / 2,
        "most of the view sees the plane: {checked}"
    );
}

#[test]
fn shading_matches_formula_on_a_tilted_plane() {
    let (a, b) = (0.3, -0.2);
    let g = heightfield(grid(81, 81, 0.05, |x, y| a * x + b * y), 0.6);
    let view = View::look_at(
        CameraModel::pinhole(64, 48, 80.0, 80.0, 31.5, 23.5),
        [2.0, -2.0, 4.0],
        [2.0, -2.0, 0.2],
    );
    let l = light(30.0, 40.0, 0.2);
    let (az, el) = (30f64.to_radians(), 40f64.to_radians());
    let to_light = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
    let n = [-a, -b, 1.0];
    let n_dot_l = (0..3).map(|k| n[k] * to_light[k]).sum::<f64>() / (a * a + b * b + 1.0).sqrt();
    let want = 0.6 * (0.2 + 0.8 * n_dot_l.max(0.0));
    for shadows in [false, true] {
        let r = render(&g, &l, &view, &RenderOptions { shadows, ..PLAIN });
        assert!(r.mask.iter().all(|&m| m == 255));
        for px in &r.radiance {
            assert!((f64::from(*px) - want).abs() < 1e-5, "{px} vs {want}");
        }
    }
}

/// Flat ground at z = 0 with a 0.4 m square box of height 0.3 m centred at (2, -2).
fn box_grid() -> HeightGrid {
    grid(201, 201, 0.02, |x, y| {
        if (x - 2.0).abs() <= 0.2 + 1e-9 && (y + 2.0).abs() <= 0.2 + 1e-9 {
            0.3
        } else {
            0.0
        }
    })
}

/// The bits of a render's radiance and depth, to compare renders byte for byte.
fn bits(r: &Rendered) -> Vec<u32> {
    r.radiance
        .iter()
        .chain(&r.depth)
        .map(|v| v.to_bits())
        .collect()
}

fn project(view: &View, p: [f64; 3]) -> [f64; 2] {
    let pc = view.ground_from_camera.inverse().transform_point(p);
    view.camera.project(pc).expect("in front")
}

#[test]
fn box_depths_shadow_and_marker() {
    let view = View::look_at(
        CameraModel::pinhole(200, 200, 150.0, 150.0, 99.5, 99.5),
        [2.0, -2.0, 5.0],
        [2.0, -2.0, 0.0],
    );
    let g = heightfield(box_grid(), 0.5);
    let l = light(0.0, 45.0, 0.25);
    let r = render(
        &g,
        &l,
        &view,
        &RenderOptions {
            shadows: true,
            ..PLAIN
        },
    );
    // The box top is 0.3 m closer than the ground.
    assert!((f64::from(at(&r, &r.depth, project(&view, [2.0, -2.0, 0.3]))) - 4.7).abs() < 1e-3);
    assert!((f64::from(at(&r, &r.depth, project(&view, [1.0, -1.0, 0.0]))) - 5.0).abs() < 1e-3);
    // Light from +x at 45°: the shadow covers 0.3 m of ground on the -x side only.
    let lit = 0.5 * (0.25 + 0.75 * 45f64.to_radians().sin());
    let shadowed = 0.5 * 0.25;
    for (x, want) in [
        (1.65, shadowed),
        (1.55, shadowed),
        (1.35, lit),
        (2.4, lit),
        (2.0 + 0.3, lit),
    ] {
        let got = f64::from(at(&r, &r.radiance, project(&view, [x, -2.0, 0.0])));
        assert!(
            (got - want).abs() < 1e-5,
            "ground at x = {x}: {got} vs {want}"
        );
    }
    // Without shadows the same ground is lit.
    let r = render(&g, &l, &view, &PLAIN);
    assert!((f64::from(at(&r, &r.radiance, project(&view, [1.65, -2.0, 0.0]))) - lit).abs() < 1e-5);
}

#[test]
fn marker_lands_where_camera_model_projects_it_with_real_distortion() {
    // Dark ground (z = 0.05 x) with a bright 6 cm square where pixel (90, 400) of the real,
    // strongly distorted camera looks, far from the principal point.
    let cam = real_camera();
    let view = View::look_at(cam.clone(), [0.5, -3.5, 1.8], [2.0, -1.8, 0.1]);
    let (x, y) = cam.unproject(90.0, 400.0);
    let d = view.ground_from_camera.rotate([x, y, 1.0]);
    let e = view.ground_from_camera.translation_m;
    let t = (0.05 * e[0] - e[2]) / (d[2] - 0.05 * d[0]);
    let centre = [e[0] + t * d[0], e[1] + t * d[1]];
    let alb = albedo(401, 401, 0.01, |x, y| {
        if (x - centre[0]).abs() < 0.03 && (y - centre[1]).abs() < 0.03 {
            0.9
        } else {
            0.1
        }
    });
    let g = Geometry::Heightfield {
        grid: grid(201, 201, 0.02, |x, _| 0.05 * x),
        albedo: alb,
    };
    let opts = RenderOptions {
        distort: true,
        shadows: false,
        supersample: 3,
        filter_textures: true,
        adaptive: false,
    };
    let r = render(&g, &light(0.0, 90.0, 1.0), &view, &opts);
    let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
    for v in 0..r.height {
        for u in 0..r.width {
            let w = (f64::from(r.radiance[v * r.width + u]) - 0.1).max(0.0);
            sw += w;
            su += w * u as f64;
            sv += w * v as f64;
        }
    }
    let want = project(&view, [centre[0], centre[1], 0.05 * centre[0]]);
    let got = [su / sw, sv / sw];
    // The marker is far from the principal point, so distortion moves it by many pixels.
    let pinhole = view
        .camera
        .undistorted()
        .project(view.ground_from_camera.inverse().transform_point([
            centre[0],
            centre[1],
            0.05 * centre[0],
        ]))
        .unwrap();
    assert!(
        (pinhole[0] - want[0]).hypot(pinhole[1] - want[1]) > 5.0,
        "{pinhole:?} vs {want:?}"
    );
    assert!(
        (got[0] - want[0]).hypot(got[1] - want[1]) < 0.5,
        "centroid {got:?} vs projected {want:?}"
    );
}

/// Bilinear sample of a row-major image; `None` outside or next to a NaN.
fn bilinear(img: &[f32], w: usize, h: usize, x: f64, y: f64) -> Option<f64> {
    if x < 0.0 || y < 0.0 || x > (w - 1) as f64 || y > (h - 1) as f64 {
        return None;
    }
    let (c0, r0) = (x.floor() as usize, y.floor() as usize);
    let (c1, r1) = ((c0 + 1).min(w - 1), (r0 + 1).min(h - 1));
    let (fx, fy) = (x - c0 as f64, y - r0 as f64);
    let p = |c: usize, r: usize| f64::from(img[r * w + c]);
    let v = (p(c0, r0) * (1.0 - fx) + p(c1, r0) * fx) * (1.0 - fy)
        + (p(c0, r1) * (1.0 - fx) + p(c1, r1) * fx) * fy;
    v.is_finite().then_some(v)
}

#[test]
fn distorted_render_equals_undistorted_render_remapped() {
    let g = Geometry::Heightfield {
        grid: grid(301, 301, 0.02, |x, y| {
            0.1 * (x * 1.7).sin() * (y * 1.3).cos()
        }),
        albedo: albedo(301, 301, 0.02, |x, y| {
            0.5 + 0.3 * (x * 3.0).sin() * (y * 2.0).cos()
        }),
    };
    let cam = real_camera();
    let view = View::look_at(cam.clone(), [3.0, -6.5, 2.0], [3.0, -3.0, 0.0]);
    let scene = Scene::new(&g);
    let l = light(120.0, 50.0, 0.3);
    let raw = scene.render(
        &l,
        &view,
        &RenderOptions {
            distort: true,
            ..PLAIN
        },
    );
    let und = scene.render(&l, &view, &PLAIN);
    let (mut n, mut err_rad, mut err_depth) = (0usize, 0.0, 0.0f64);
    for v in 0..raw.height {
        for u in 0..raw.width {
            let i = v * raw.width + u;
            if raw.mask[i] != 255 {
                continue;
            }
            let (x, y) = cam.unproject(u as f64, v as f64);
            let (qx, qy) = (cam.fx * x + cam.cx, cam.fy * y + cam.cy);
            let (Some(rad), Some(depth)) = (
                bilinear(&und.radiance, und.width, und.height, qx, qy),
                bilinear(&und.depth, und.width, und.height, qx, qy),
            ) else {
                continue;
            };
            n += 1;
            err_rad += (f64::from(raw.radiance[i]) - rad).abs();
            err_depth = err_depth.max((f64::from(raw.depth[i]) - depth).abs() / depth);
        }
    }
    assert!(n > 100_000, "compared {n} pixels");
    let mean = err_rad / n as f64;
    assert!(mean < 0.005, "mean radiance difference {mean}");
    assert!(
        err_depth < 0.01,
        "max relative depth difference {err_depth}"
    );
}

/// The grid as a mesh with the renderer's NW–SE split.
fn as_mesh(g: &HeightGrid, a: f32) -> TriMeshF32 {
    let (w, h) = (g.width, g.height);
    let positions = (0..w * h)
        .map(|i| {
            [
                ((i % w) as f64 * g.cell_m) as f32,
                (-((i / w) as f64) * g.cell_m) as f32,
                g.z[i],
            ]
        })
        .collect();
    let mut triangles = Vec::new();
    for r in 0..h - 1 {
        for c in 0..w - 1 {
            let (nw, ne, sw, se) = (
                (r * w + c) as u32,
                (r * w + c + 1) as u32,
                ((r + 1) * w + c) as u32,
                ((r + 1) * w + c + 1) as u32,
            );
            triangles.push([nw, ne, se]);
            triangles.push([nw, sw, se]); // opposite winding: normals are per face, turned to the ray
        }
    }
    TriMeshF32 {
        origin_m: [0.0; 3],
        positions,
        triangles,
        albedo: vec![a; w * h],
        texture: None,
    }
}

#[test]
fn mesh_and_heightfield_renders_agree() {
    let hf = heightfield(box_grid(), 0.4);
    let mesh = Geometry::Mesh(as_mesh(&box_grid(), 0.4));
    let view = View::look_at(
        CameraModel::pinhole(160, 120, 120.0, 120.0, 79.5, 59.5),
        [0.3, -3.8, 1.5],
        [2.0, -2.0, 0.1],
    );
    let l = light(200.0, 35.0, 0.2);
    let opts = RenderOptions {
        shadows: true,
        ..PLAIN
    };
    let a = render(&hf, &l, &view, &opts);
    let b = render(&mesh, &l, &view, &opts);
    let mut differ = 0;
    for i in 0..a.mask.len() {
        if a.mask[i] != b.mask[i] {
            differ += 1;
        } else if a.mask[i] == 255 {
            assert!((a.depth[i] - b.depth[i]).abs() < 1e-4, "depth at {i}");
            if (a.radiance[i] - b.radiance[i]).abs() > 1e-4 {
                differ += 1;
            }
        }
    }
    assert!(a.mask.iter().filter(|&&m| m == 255).count() > 10_000);
    assert!(differ <= a.mask.len() / 500, "{differ} pixels differ");
}

#[test]
fn output_is_identical_for_one_and_two_threads() {
    let g = Geometry::Heightfield {
        grid: grid(151, 151, 0.03, |x, y| {
            0.2 * (x * 2.1).sin() * (y * 1.7).cos() + 0.05 * (x * 9.0 + y * 7.0).sin()
        }),
        albedo: albedo(301, 301, 0.015, |x, y| {
            0.4 + 0.2 * (x * 13.0).sin() * (y * 11.0).cos()
        }),
    };
    let view = View::look_at(real_camera(), [2.2, -5.5, 1.2], [2.2, -2.0, 0.0]);
    let opts = RenderOptions {
        distort: true,
        shadows: true,
        supersample: 2,
        filter_textures: true,
        adaptive: false,
    };
    let run = |threads| {
        on_threads(threads, || {
            render(&g, &light(60.0, 25.0, 0.2), &view, &opts)
        })
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(bits(&one), bits(&two));
    assert_eq!(one.mask, two.mask);
    assert!(
        one.mask.contains(&255) && one.mask.contains(&0),
        "sky and terrain both in view"
    );
}

/// A scene keeps the camera-ray table of each camera it rendered: a view rendered again after
/// other cameras and sampling rates (cache hits, a miss in between, an eviction) has the bytes
/// of the same view in a fresh scene, and a second camera never reuses the first one's rays.
#[test]
fn cached_camera_rays_give_the_bytes_of_a_fresh_scene() {
    let g = Geometry::Heightfield {
        grid: grid(121, 121, 0.03, |x, y| {
            0.15 * (x * 2.3).sin() * (y * 1.9).cos()
        }),
        albedo: albedo(121, 121, 0.03, |x, y| {
            0.4 + 0.2 * (x * 9.0).sin() * (y * 7.0).cos()
        }),
    };
    let l = light(60.0, 40.0, 0.3);
    let a = real_camera();
    let mut b = a.clone();
    b.distortion.k1 *= 0.5;
    let view = |cam: &CameraModel| View::look_at(cam.clone(), [1.8, -4.0, 1.0], [1.8, -1.8, 0.0]);
    let opts = |n: u32| RenderOptions {
        distort: true,
        shadows: false,
        supersample: n,
        filter_textures: true,
        adaptive: false,
    };
    let fresh = |cam: &CameraModel, n: u32| bits(&Scene::new(&g).render(&l, &view(cam), &opts(n)));
    let scene = Scene::new(&g);
    let first = bits(&scene.render(&l, &view(&a), &opts(1)));
    assert_eq!(first, fresh(&a, 1));
    let other = bits(&scene.render(&l, &view(&b), &opts(1)));
    assert_ne!(other, first, "the second camera's distortion must show");
    assert_eq!(other, fresh(&b, 1));
    for n in 2..=4 {
        assert_eq!(bits(&scene.render(&l, &view(&a), &opts(n))), fresh(&a, n));
    }
    // Five tables were asked for; the oldest (camera a, n = 1) was evicted and is rebuilt.
    assert_eq!(bits(&scene.render(&l, &view(&a), &opts(1))), first);
    assert_eq!(bits(&scene.render(&l, &view(&b), &opts(1))), other);
}

#[test]
fn supersampling_box_filters_an_albedo_edge() {
    // Albedo 0 for x < 2, 1 for x >= 2 on 5 mm cells, seen from above with 0.02 m pixels;
    // pixel column 50 is centred on the edge. Its 4 x 4 samples lie at x = 2 ± 2.5 mm and
    // 2 ± 7.5 mm, where the bilinear albedo is 0, 0.5, 1 and 1: the box filter gives 0.625.
    let alb = albedo(
        801,
        11,
        0.005,
        |x, _| if x < 2.0 - 1e-9 { 0.0 } else { 1.0 },
    );
    let alb = AlbedoGrid {
        origin_m: [0.0, 0.0],
        ..alb
    };
    let g = Geometry::Heightfield {
        grid: grid(201, 201, 0.02, |_, _| 0.0),
        albedo: alb,
    };
    let view = View::look_at(
        CameraModel::pinhole(101, 9, 100.0, 100.0, 50.0, 4.0),
        [2.0, -0.025, 2.0],
        [2.0, -0.025, 0.0],
    );
    let l = light(0.0, 90.0, 1.0);
    let one = render(&g, &l, &view, &PLAIN);
    let four = render(
        &g,
        &l,
        &view,
        &RenderOptions {
            supersample: 4,
            ..PLAIN
        },
    );
    let row = 4 * 101;
    assert!(four.radiance[row + 30] < 1e-6 && (four.radiance[row + 70] - 1.0).abs() < 1e-6);
    assert!(
        (four.radiance[row + 50] - 0.625).abs() < 1e-4,
        "edge pixel {}",
        four.radiance[row + 50]
    );
    // One sample per 0.02 m pixel spans 4 texels: it reads the mip level that averages them,
    // the same 0.625 as the 4 x 4 box filter (without mip-mapping it read 0 or 1).
    assert!(
        (one.radiance[row + 50] - 0.625).abs() < 1e-4,
        "one-sample edge pixel {}",
        one.radiance[row + 50]
    );
    let bits = |v: &[f32]| v.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert_eq!(
        bits(&one.depth),
        bits(&four.depth),
        "depth comes from the pixel centre"
    );
    assert!(one.depth[row + 50] == 2.0, "seen from 2 m");
}

#[test]
fn tracer_hits_planes_from_above_and_below_and_respects_holes() {
    let (a, b, c) = (0.2, 0.1, 0.5);
    let mut g = grid(51, 41, 0.1, |x, y| a * x + b * y + c);
    let tracer = HeightfieldTracer::new(&g);
    let z = |x: f64, y: f64| a * x + b * y + c;
    let down = tracer
        .trace([1.23, -2.34, 10.0], [0.0, 0.0, -1.0], 100.0)
        .expect("hit from above");
    assert!(
        (down.point[2] - z(1.23, -2.34)).abs() < 1e-6
            && (down.t - (10.0 - z(1.23, -2.34))).abs() < 1e-6
    );
    let n = [-a, -b, 1.0].map(|v| v / (a * a + b * b + 1.0f64).sqrt());
    assert!(
        (0..3).all(|k| (down.normal[k] - n[k]).abs() < 1e-6),
        "{:?}",
        down.normal
    );
    let up = tracer
        .trace([3.01, -1.5, -5.0], [0.1, 0.05, 1.0], 100.0)
        .expect("hit from below");
    assert!((up.point[2] - z(up.point[0], up.point[1])).abs() < 1e-6);
    assert!(
        tracer
            .trace([1.23, -2.34, 10.0], [0.0, 0.0, -1.0], 5.0)
            .is_none(),
        "t_max is respected"
    );
    assert!(
        tracer
            .trace([9.0, -2.0, 10.0], [0.0, 0.0, -1.0], 100.0)
            .is_none(),
        "outside the grid"
    );
    // A hole at cell (12, 23) removes the six triangles around it and nothing else.
    g.z[23 * 51 + 12] = f32::NAN;
    let holed = HeightfieldTracer::new(&g);
    assert!(holed
        .trace([1.2, -2.3, 10.0], [0.0, 0.0, -1.0], 100.0)
        .is_none());
    assert!(holed
        .trace([1.5, -2.3, 10.0], [0.0, 0.0, -1.0], 100.0)
        .is_some());
    fn is_sync<T: Sync + Send>(_: &T) {}
    is_sync(&holed);
}

/// The nearest hit of a ray with every triangle of `g` (quads split NW–SE, holes removed),
/// by testing them all (Möller–Trumbore): what the march through the quadtree must find.
fn brute_force_t(g: &HeightGrid, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<f64> {
    let p = |c: usize, r: usize| -> [f64; 3] {
        [
            g.origin_m[0] + c as f64 * g.cell_m,
            g.origin_m[1] - r as f64 * g.cell_m,
            f64::from(g.z[r * g.width + c]),
        ]
    };
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut best: Option<f64> = None;
    for r in 0..g.height - 1 {
        for c in 0..g.width - 1 {
            let (nw, ne, sw, se) = (p(c, r), p(c + 1, r), p(c, r + 1), p(c + 1, r + 1));
            for tri in [[nw, ne, se], [nw, se, sw]] {
                if tri.iter().any(|v| !v[2].is_finite()) {
                    continue;
                }
                let (e1, e2) = (sub(tri[1], tri[0]), sub(tri[2], tri[0]));
                let q = cross(d, e2);
                let det = dot(e1, q);
                if det.abs() < 1e-15 {
                    continue;
                }
                let s = sub(o, tri[0]);
                let u = dot(s, q) / det;
                let rr = cross(s, e1);
                let v = dot(d, rr) / det;
                let t = dot(e2, rr) / det;
                if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= 0.0 && t <= t_max {
                    best = Some(best.map_or(t, |b: f64| b.min(t)));
                }
            }
        }
    }
    best
}

#[test]
fn tracer_finds_the_nearest_triangle_of_a_rough_terrain_with_holes() {
    // Rough relief with overhang-free spikes and pits, and a few holes: rays from a camera
    // above (steep and grazing), from below and nearly horizontal, each checked against every
    // triangle. A march that skips a node it should enter misses or finds a farther hit.
    let mut g = grid(37, 29, 0.05, |x, y| {
        0.3 * (x * 7.0).sin() * (y * 5.0).cos() + 0.15 * ((x + 2.0 * y) * 23.0).sin()
    });
    for k in [40usize, 333, 334, 600, 901] {
        g.z[k] = f32::NAN;
    }
    let tracer = HeightfieldTracer::new(&g);
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut hits, mut rays) = (0, 0);
    for _ in 0..3000 {
        let o = [
            -0.5 + 2.8 * uniform(),
            0.5 - 2.4 * uniform(),
            -1.0 + 3.0 * uniform(),
        ];
        let target = [1.8 * uniform(), -1.4 * uniform(), -0.4 + 0.8 * uniform()];
        let d = [target[0] - o[0], target[1] - o[1], target[2] - o[2]];
        let t_max = 0.5 + 1.5 * uniform();
        let want = brute_force_t(&g, o, d, t_max);
        let got = tracer.trace(o, d, t_max).map(|h| h.t);
        rays += 1;
        match (want, got) {
            (Some(a), Some(b)) => {
                hits += 1;
                assert!(
                    (a - b).abs() < 1e-9,
                    "ray {o:?} {d:?}: nearest t {a}, march {b}"
                );
            }
            (None, None) => {}
            _ => panic!("ray {o:?} {d:?}: brute force {want:?}, march {got:?}"),
        }
    }
    assert!(hits > rays / 4 && hits < rays, "{hits} of {rays} rays hit");
}

/// Mean and standard deviation of the radiance over the pixels that see terrain.
fn mean_std(r: &Rendered) -> (f64, f64) {
    let v: Vec<f64> = r
        .radiance
        .iter()
        .zip(&r.mask)
        .filter(|(_, m)| **m == 255)
        .map(|(x, _)| f64::from(*x))
        .collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    (
        mean,
        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt(),
    )
}

#[test]
fn a_distant_fine_texture_is_filtered_not_aliased() {
    // A 1-texel checkerboard (albedo 0 / 1 on 5 mm texels) seen from 4 m with 4 cm pixels and
    // one sample per pixel: each sample spans 8 texels. Point sampling would give every pixel 0
    // or 1 (standard deviation ~0.5); the mip levels give the local mean, 0.5.
    let n = 800;
    let checker = |x: f64, y: f64| {
        let (c, r) = ((x / 0.005).round() as i64, (-y / 0.005).round() as i64);
        if (c + r) % 2 == 0 {
            0.0
        } else {
            1.0
        }
    };
    let g = Geometry::Heightfield {
        grid: grid(201, 201, 0.02, |_, _| 0.0),
        albedo: albedo(n, n, 0.005, checker),
    };
    let view = View::look_at(
        CameraModel::pinhole(61, 61, 100.0, 100.0, 30.0, 30.0),
        [2.0, -2.0, 4.0],
        [2.0, -2.0, 0.0],
    );
    let l = light(0.0, 90.0, 1.0);
    let (mean, std) = mean_std(&render(&g, &l, &view, &PLAIN));
    assert!(
        (mean - 0.5).abs() < 0.02 && std < 0.02,
        "heightfield: mean {mean} std {std}"
    );

    // The same texture on a textured mesh (two triangles, uv 0..1 over the 4 m square).
    let side = (n - 1) as f32 * 0.005;
    let h = -(side);
    let tex = MeshTexture {
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
        width: n,
        height: n,
        value: (0..n * n)
            .map(|i| checker((i % n) as f64 * 0.005, -((i / n) as f64) * 0.005) as f32)
            .collect(),
    };
    let mesh = Geometry::Mesh(TriMeshF32 {
        origin_m: [0.0; 3],
        positions: vec![
            [0.0, 0.0, 0.0],
            [side, 0.0, 0.0],
            [0.0, h, 0.0],
            [side, h, 0.0],
        ],
        triangles: vec![[0, 1, 3], [0, 2, 3]],
        albedo: vec![0.0; 4],
        texture: Some(tex),
    });
    let (mean, std) = mean_std(&render(&mesh, &l, &view, &PLAIN));
    assert!(
        (mean - 0.5).abs() < 0.02 && std < 0.02,
        "mesh: mean {mean} std {std}"
    );
}

/// The textured box terrain as a heightfield and as a mesh, and an oblique view of it: the
/// scene of the relighting tests.
fn relight_scene() -> (Geometry, Geometry, View) {
    let hf = Geometry::Heightfield {
        grid: box_grid(),
        albedo: albedo(201, 201, 0.02, |x, y| {
            0.4 + 0.2 * (x * 9.0).sin() * (y * 7.0).cos()
        }),
    };
    let mesh = Geometry::Mesh(as_mesh(&box_grid(), 0.4));
    let view = View::look_at(real_camera(), [0.3, -3.8, 1.5], [2.0, -2.0, 0.1]);
    (hf, mesh, view)
}

/// A view's camera rays traced once and shaded under other lights give the bytes of full
/// renders under those lights — heightfield and mesh, with and without cast shadows, at one and
/// two samples per axis (two adds the centre ray) — while the lights' shadows do differ. A
/// light's kept cast shadow shades them to the same bytes, and one kept for another light's
/// direction is not used.
#[test]
fn relit_hits_give_the_bytes_of_a_render() {
    let (hf, mesh, view) = relight_scene();
    for g in [&hf, &mesh] {
        let scene = Scene::new(g);
        for n in [1, 2] {
            let opts = |shadows| RenderOptions {
                distort: true,
                shadows,
                supersample: n,
                filter_textures: true,
                adaptive: false,
            };
            let hits = scene.primary_hits(&view, &opts(false));
            let mut seen = Vec::new();
            for (l, shadows) in [
                (light(200.0, 35.0, 0.2), true),
                (light(120.0, 20.0, 0.2), true),
                (light(120.0, 20.0, 0.2), false),
            ] {
                let relit = scene.relight(&hits, &l, shadows);
                let full = scene.render(&l, &view, &opts(shadows));
                assert_eq!(bits(&relit), bits(&full), "n = {n}, shadows {shadows}");
                assert_eq!(relit.mask, full.mask);
                if shadows {
                    let cast = scene.cast_shadow(&hits, &l);
                    let kept = scene.relight_cast(&hits, &l, &cast);
                    assert_eq!(bits(&kept), bits(&full), "n = {n}, kept cast shadow");
                    assert_eq!(kept.mask, full.mask);
                    let other = scene.cast_shadow(&hits, &light(l.azimuth_deg + 90.0, 60.0, 0.2));
                    let stale = scene.relight_cast(&hits, &l, &other);
                    assert_eq!(bits(&stale), bits(&full), "n = {n}, another light's shadow");
                }
                seen.push(bits(&relit));
            }
            assert!(
                seen[0] != seen[1] && seen[1] != seen[2],
                "the lights must show"
            );
        }
    }
}

/// A render given the view's first hits at one sample a pixel gives the bytes of the render
/// it stands for — adaptive at two and three samples a side (the centres kept, the edge
/// pixels traced), at one (a relight) and plain at two (traced) — heightfield and mesh, with
/// and without cast shadows. The centres do come from the hits: another view's make another
/// image.
#[test]
fn a_render_from_kept_hits_gives_the_bytes_of_a_render() {
    let (hf, mesh, view) = relight_scene();
    let elsewhere = View::look_at(real_camera(), [4.0, -0.5, 1.2], [2.0, -2.0, 0.1]);
    let l = light(200.0, 35.0, 0.2);
    for g in [&hf, &mesh] {
        let scene = Scene::new(g);
        let opts = |n, adaptive, shadows| RenderOptions {
            distort: true,
            shadows,
            supersample: n,
            filter_textures: true,
            adaptive,
        };
        let hits = scene.primary_hits(&view, &opts(1, false, false));
        let stale = scene.primary_hits(&elsewhere, &opts(1, false, false));
        for (n, adaptive) in [(2, true), (3, true), (1, true), (2, false)] {
            for shadows in [false, true] {
                let o = opts(n, adaptive, shadows);
                let full = scene.render(&l, &view, &o);
                let kept = scene.render_from_hits(&hits, &l, &view, &o);
                let what = format!("n = {n}, adaptive {adaptive}, shadows {shadows}");
                assert_eq!(bits(&kept), bits(&full), "{what}");
                assert_eq!(kept.mask, full.mask, "{what}");
                assert_eq!(kept.depth.len(), full.depth.len());
                assert!(
                    kept.depth
                        .iter()
                        .zip(&full.depth)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{what}: depth"
                );
                if n == 2 && adaptive {
                    let wrong = scene.render_from_hits(&stale, &l, &view, &o);
                    assert_ne!(bits(&wrong), bits(&full), "another view's hits must show");
                }
            }
        }
    }
}

/// Flat ground 4 m square (albedo 0.5) with a ball of radius 0.2 m (albedo 0.9) standing at its
/// centre, (2, −2).
fn ball_on_ground() -> (Geometry, Sphere) {
    let g = heightfield(grid(41, 41, 0.1, |_, _| 0.0), 0.5);
    let ball = Sphere {
        centre: [2.0, -2.0, 0.2],
        radius: 0.2,
        albedo: 0.9,
    };
    (g, ball)
}

/// `f` run in a rayon pool of `threads` threads.
fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn a_sphere_is_seen_shaded_and_casts_its_shadow_exactly() {
    // A ball of radius 0.2 m on flat ground, seen from 5 m straight above, lit from +x at 45°.
    let view = View::look_at(
        CameraModel::pinhole(201, 201, 150.0, 150.0, 100.0, 100.0),
        [2.0, -2.0, 5.0],
        [2.0, -2.0, 0.0],
    );
    let (g, ball) = ball_on_ground();
    let scene = Scene::new(&g).with_spheres(vec![ball]);
    let l = light(0.0, 45.0, 0.25);
    let opts = RenderOptions {
        shadows: true,
        ..PLAIN
    };
    let r = scene.render(&l, &view, &opts);
    // The top of the ball is 0.4 m above the ground: depth 4.6 m.
    let top = project(&view, [2.0, -2.0, 0.4]);
    assert!((f64::from(at(&r, &r.depth, top)) - 4.6).abs() < 1e-4);
    // Its top faces straight up: n·l = sin 45°.
    let want = 0.9 * (0.25 + 0.75 * 45f64.to_radians().sin());
    assert!((f64::from(at(&r, &r.radiance, top)) - want).abs() < 1e-5);
    // The ball's silhouette: the exact ray–sphere hit inside, ground beyond.
    let h = |t: f64| f64::from(at(&r, &r.depth, [100.0 + t, 100.0]));
    let edge = 150.0 * 0.2 / (4.8f64.powi(2) - 0.04).sqrt();
    assert!(h(edge - 0.6) < 4.81 && (h(edge + 0.6) - 5.0).abs() < 1e-4);
    // Its shadow falls on the -x side: at 45° the ball's centre casts onto x = 1.8, and the
    // shadow spans ±0.2 √2 about it along x.
    let shadowed = 0.5 * 0.25;
    let ground = |x: f64| f64::from(at(&r, &r.radiance, project(&view, [x, -2.0, 0.0])));
    assert!((ground(2.0 - 0.35) - shadowed).abs() < 1e-5);
    let lit = 0.5 * (0.25 + 0.75 * 45f64.to_radians().sin());
    assert!((ground(2.0 + 0.35) - lit).abs() < 1e-5);
    assert!((ground(1.8 - 0.2 * 2f64.sqrt() - 0.05) - lit).abs() < 1e-5);
    // The geometry alone (no sphere) has no ball.
    let bare = Scene::new(&g).render(&l, &view, &opts);
    assert!((f64::from(at(&bare, &bare.depth, top)) - 5.0).abs() < 1e-4);
    // A ray from inside the sphere meets its far side; rays that miss it meet nothing.
    let o = [2.0, -2.0, 0.2];
    let hit = ball
        .hit(o, [0.0, 0.0, 2.0], 0.0, f64::INFINITY)
        .expect("far side");
    assert!((hit.t - 0.1).abs() < 1e-12 && (hit.normal[2] - 1.0).abs() < 1e-12);
    assert!(ball
        .hit([2.5, -2.0, 5.0], [0.0, 0.0, -1.0], 0.0, f64::INFINITY)
        .is_none());
    assert!(ball
        .hit([2.0, -2.0, 5.0], [0.0, 0.0, -1.0], 0.0, 4.0)
        .is_none());
    // A degenerate ball is never hit (no NaN normal).
    for radius in [0.0, -0.2, f64::NAN] {
        let bad = Sphere { radius, ..ball };
        assert!(bad.hit(o, [0.0, 0.0, 1.0], 0.0, f64::INFINITY).is_none());
    }
}

/// Supersampling at edge pixels only (`RenderOptions::adaptive`): the ball's outline, its cast
/// shadow's edge and the terrain's outline against the sky get every sample, so over flat,
/// uniformly coloured ground the image is the fully supersampled one bit for bit; on the ball
/// (a curved surface, shaded once per pixel) it stays within a small share of the radiance.
/// Depth and mask are the centre ray's either way, and the bytes do not depend on the thread
/// count.
#[test]
fn supersampling_at_edges_only_matches_full_supersampling_where_it_shows() {
    let view = View::look_at(
        CameraModel::pinhole(201, 161, 150.0, 150.0, 100.0, 80.0),
        [2.0, -4.2, 1.6],
        [2.0, -2.0, 0.0],
    );
    let (g, ball) = ball_on_ground();
    let scene = Scene::new(&g).with_spheres(vec![ball]);
    let l = light(0.0, 35.0, 0.25);
    let full = RenderOptions {
        shadows: true,
        supersample: 2,
        ..PLAIN
    };
    let edges = RenderOptions {
        adaptive: true,
        ..full
    };
    let a = scene.render(&l, &view, &full);
    let run = |threads| on_threads(threads, || scene.render(&l, &view, &edges));
    let (b, b2) = (run(1), run(2));
    assert_eq!(bits(&b), bits(&b2));
    assert_eq!(b.mask, a.mask);
    assert_eq!(
        a.depth.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        b.depth.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    // The view holds sky, ground in and out of the shadow, and the ball.
    let lit = 0.5 * (0.25 + 0.75 * 35f64.to_radians().sin());
    let shadowed = 0.5 * 0.25;
    let count = |v: f64| {
        a.radiance
            .iter()
            .filter(|r| (f64::from(**r) - v).abs() < 1e-6)
            .count()
    };
    assert!(a.mask.contains(&0) && count(lit) > 1000 && count(shadowed) > 100);
    let on_ball = |i: usize| {
        let (c, r) = ((i % 201) as f64, (i / 201) as f64);
        // Within 1.5 px of the ball's image (its hits are nearer than the ground's).
        (-2i32..=2).any(|dc| {
            (-2i32..=2).any(|dr| {
                let (cc, rr) = (c + f64::from(dc), r + f64::from(dr));
                (0.0..201.0).contains(&cc) && (0.0..161.0).contains(&rr) && {
                    let j = rr as usize * 201 + cc as usize;
                    let gd = plane_depth(&view, (0.0, 0.0, 0.0), cc, rr);
                    f64::from(a.depth[j]) < gd - 1e-3
                }
            })
        })
    };
    let (mut off_ball, mut ball_err, mut ball_px) = (0usize, 0.0f64, 0usize);
    for i in 0..a.radiance.len() {
        let d = (f64::from(a.radiance[i]) - f64::from(b.radiance[i])).abs();
        if on_ball(i) {
            ball_err += d;
            ball_px += 1;
        } else if d > 0.0 {
            off_ball += 1;
        }
    }
    assert_eq!(
        off_ball, 0,
        "ground and sky pixels differing from the full render"
    );
    assert!(
        ball_px > 100 && ball_err / (ball_px as f64) < 0.01,
        "{ball_err} over {ball_px}"
    );
}
