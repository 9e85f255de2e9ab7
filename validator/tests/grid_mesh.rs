//! A mesh whose triangles are a height grid's is traced as that grid (`render::grid_mesh`):
//! the grid it gives back is the mesh's surface, its render the mesh's, and any mesh that is
//! not exactly a grid stays a mesh.

use regolith_format::camera_model::CameraModel;
use regolith_validator::render::grid_mesh::as_height_grid;
use regolith_validator::render::{
    render, Geometry, Light, MeshTexture, RenderOptions, TriMeshF32, View,
};

const W: usize = 40;
const H: usize = 30;
const CELL: f64 = 0.05;
/// Ground position of the mesh's local origin (the GLB's root translation), as the compiler
/// writes it: cell (0, 0)'s centre and the lowest height.
const ORIGIN: [f64; 3] = [312.25, -48.5, 1.125];
/// The one hole: the compiler drops the six triangles that touch a `NaN` height.
const HOLE: (usize, usize) = (17, 11);

fn height(c: usize, r: usize) -> f64 {
    let (x, y) = (c as f64 * CELL, r as f64 * CELL);
    0.08 * (3.1 * x).sin() * (2.3 * y).cos()
        + 0.3 * (-((x - 1.0).powi(2) + (y - 0.7).powi(2)) / 0.05).exp()
}

fn texel(c: usize, r: usize) -> f32 {
    (0.2 + 0.6 * (((c * 7 + r * 13) % 11) as f64 / 10.0)) as f32
}

/// The `lod0` mesh the compiler writes for a `W × H` grid (SPEC §5.3): vertices row-major at
/// the cell centres as `f32` offsets from the origin, texel centres as texture coordinates,
/// each quad split along its NW–SE diagonal, counter-clockwise from above.
fn grid_mesh() -> TriMeshF32 {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for r in 0..H {
        for c in 0..W {
            positions.push([
                (c as f64 * CELL) as f32,
                -(r as f64 * CELL) as f32,
                height(c, r) as f32,
            ]);
            uvs.push([(c as f32 + 0.5) / W as f32, (r as f32 + 0.5) / H as f32]);
        }
    }
    let ok = |c: usize, r: usize| (c, r) != HOLE;
    let mut triangles = Vec::new();
    for r in 0..H - 1 {
        for c in 0..W - 1 {
            let nw = (r * W + c) as u32;
            let (ne, sw, se) = (nw + 1, nw + W as u32, nw + W as u32 + 1);
            if ok(c, r) && ok(c, r + 1) && ok(c + 1, r + 1) {
                triangles.push([nw, sw, se]);
            }
            if ok(c, r) && ok(c + 1, r + 1) && ok(c + 1, r) {
                triangles.push([nw, se, ne]);
            }
        }
    }
    let value = (0..W * H).map(|i| texel(i % W, i / W)).collect();
    TriMeshF32 {
        origin_m: ORIGIN,
        albedo: vec![0.5; W * H],
        positions,
        triangles,
        texture: Some(MeshTexture {
            uvs,
            width: W,
            height: H,
            value,
        }),
    }
}

#[test]
fn a_grid_mesh_is_its_grid() {
    let m = grid_mesh();
    let (grid, albedo) = as_height_grid(&m).expect("the compiler's grid mesh is a grid");
    assert_eq!((grid.width, grid.height), (W, H));
    // Estimated from the f32 positions of the first row's ends.
    assert!((grid.cell_m - CELL).abs() < 1e-8, "{}", grid.cell_m);
    assert!((grid.origin_m[0] - ORIGIN[0]).abs() < 1e-9);
    assert!((grid.origin_m[1] - ORIGIN[1]).abs() < 1e-9);
    for r in 0..H {
        for c in 0..W {
            let z = grid.z[r * W + c];
            if (c, r) == HOLE {
                assert!(z.is_nan(), "the vertex no triangle uses is a hole");
            } else {
                let want = ORIGIN[2] + height(c, r);
                assert!(
                    (f64::from(z) - want).abs() < 1e-6,
                    "({c}, {r}): {z} vs {want}"
                );
            }
            assert_eq!(albedo.value[r * W + c], texel(c, r));
        }
    }
    assert_eq!(albedo.origin_m, grid.origin_m);
    assert_eq!((albedo.width, albedo.height), (W, H));
}

#[test]
fn the_grid_renders_as_the_mesh() {
    let m = grid_mesh();
    let (grid, albedo) = as_height_grid(&m).unwrap();
    let view = View::look_at(
        CameraModel::pinhole(160, 120, 110.0, 110.0, 79.5, 59.5),
        [ORIGIN[0] + 1.0, ORIGIN[1] - 1.75, ORIGIN[2] + 0.8],
        [ORIGIN[0] + 1.0, ORIGIN[1] - 0.75, ORIGIN[2]],
    );
    let light = Light {
        azimuth_deg: 130.0,
        elevation_deg: 40.0,
        ambient: 0.3,
    };
    let opts = RenderOptions {
        shadows: true,
        ..RenderOptions::default()
    };
    let a = render(&Geometry::Mesh(m), &light, &view, &opts);
    let b = render(
        &Geometry::Heightfield { grid, albedo },
        &light,
        &view,
        &opts,
    );
    let seen = a.mask.iter().filter(|&&v| v == 255).count();
    assert!(seen > a.mask.len() / 2, "the view sees the terrain: {seen}");
    let through_hole = a.mask.iter().zip(&b.mask).filter(|(x, y)| x != y).count();
    assert_eq!(through_hole, 0, "the same pixels see the surface");
    let (mut sum, mut over_dn) = (0.0f64, 0usize);
    for k in 0..a.mask.len() {
        if a.mask[k] == 255 {
            let d = (a.radiance[k] - b.radiance[k]).abs();
            sum += f64::from(d);
            over_dn += usize::from(d > 1.0 / 255.0);
            assert!((a.depth[k] - b.depth[k]).abs() < 1e-5, "depth at {k}");
        }
    }
    // The same triangles' normals and the same texels: what differs is rounding (a ray through
    // a crease or a shadow's edge may land on the other side) and the texture filter's
    // footprint (the sloped triangle's against the horizontal cell's). Measured: mean |Δ|
    // 2.5e-6 (0.0006 DN), 2 of 13 469 pixels more than a DN apart; a flipped axis, a lost
    // origin or a texel shift moves both by orders of magnitude.
    let mean = sum / seen as f64;
    assert!(mean < 2e-5, "mean |Δ radiance| {mean}");
    assert!(
        over_dn * 1000 <= seen,
        "{over_dn} pixels differ by more than a DN"
    );
}

#[test]
fn a_mesh_that_is_not_exactly_a_grid_stays_a_mesh() {
    type Change = fn(&mut TriMeshF32);
    let cases: [(&str, Change); 8] = [
        ("a vertex moved by 0.1 mm", |m| {
            m.positions[5 * W + 3][0] += 1e-4
        }),
        ("the other diagonal in one quad", |m| {
            let i = m
                .triangles
                .iter()
                .position(|t| *t == [0, W as u32, W as u32 + 1])
                .unwrap();
            m.triangles[i] = [0, W as u32, 1];
            m.triangles[i + 1] = [1, W as u32, W as u32 + 1];
        }),
        ("a triangle missing between used vertices", |m| {
            m.triangles.remove(100);
        }),
        ("a triangle twice", |m| {
            let t = m.triangles[7];
            m.triangles.push(t);
        }),
        ("a texture coordinate off its texel", |m| {
            m.texture.as_mut().unwrap().uvs[W + 1][1] += 1e-3;
        }),
        ("a texture finer than the grid", |m| {
            let t = m.texture.as_mut().unwrap();
            t.width = 2 * W;
            t.value = vec![0.5; 2 * W * H];
        }),
        ("no texture", |m| m.texture = None),
        ("a triangle across two quads", |m| {
            m.triangles[0] = [0, 2, 2 * W as u32]
        }),
    ];
    for (what, change) in cases {
        let mut m = grid_mesh();
        assert!(as_height_grid(&m).is_some());
        change(&mut m);
        assert!(as_height_grid(&m).is_none(), "{what}: taken for a grid");
    }
}

#[test]
fn either_winding_is_the_same_grid() {
    let mut m = grid_mesh();
    let bits = |m: &TriMeshF32| {
        let (g, a) = as_height_grid(m).unwrap();
        let z: Vec<u32> = g.z.iter().map(|v| v.to_bits()).collect();
        (z, g.origin_m, g.cell_m, a)
    };
    let want = bits(&m);
    for t in &mut m.triangles {
        t.swap(1, 2);
    }
    assert!(bits(&m) == want);
}
