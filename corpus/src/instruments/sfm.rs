//! The multi-view-stereo reconstruction: the surface as CMP SfM would give it.
//!
//! A regular mesh (vertex spacing 2 cm, quads split NW–SE like the renderer's) whose heights
//! are the true surface low-passed by a Gaussian of σ 1.2 cm (detail below ~3 cm is gone),
//! plus vertical Gaussian noise of σ 1.2 cm that grows to 2.6 cm within 0.6 m of the walls
//! (the bed edges, where the thesis says fewer photos were taken). Vertex colours are the
//! albedo blurred by σ 1 cm — and additionally by the hidden `texture-lowpass` when it is set
//! (the caller passes the low-passed albedo) — as 8-bit grey. The mesh is then put into an
//! arbitrary similarity frame `p_sfm = s · R · p_ground + t` with `s = 1/0.68` by default, a
//! seeded rotation and a seeded translation; `truth/sfm.json` records (s, R, t) and the
//! direction. Written as VRML 2.0 (CMPMVS style, `colorPerVertex`) and binary PLY.
//!
//! The ground markers are also written as a ground-control-point file (`sfm/mesh_gcp.csv`, a
//! Metashape-style marker export): each ball centre in the SfM frame with 1.5 mm-per-axis
//! picking noise; `truth/gcp.json` holds the true and noisy positions.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use regolith_format::frames::{quat_from_axis_angle, Pose};
use regolith_format::grid::AlbedoGrid;
use serde::Serialize;

use crate::presets::PresetConfig;
use crate::seeding::item_rng;
use crate::sink::push_fixed;
use crate::terrain::{gaussian_blur, GridShape, Terrain};

/// The similarity from the ground frame to the SfM frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Similarity {
    /// Which way it maps.
    pub maps: &'static str,
    /// Scale `s`.
    pub scale: f64,
    /// Rotation `R`, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation `t`, SfM units.
    pub translation: [f64; 3],
}

impl Similarity {
    /// Applies `s R p + t`.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        let q = |i: usize| {
            self.scale * (r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2]) + self.translation[i]
        };
        [q(0), q(1), q(2)]
    }
}

/// The reconstructed mesh in the SfM frame.
pub struct SfmMesh {
    /// Vertex positions (SfM frame).
    pub positions: Vec<[f64; 3]>,
    /// Grey vertex colours.
    pub colors: Vec<[u8; 3]>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// ground → SfM.
    pub similarity: Similarity,
}

/// Builds the reconstruction; `albedo` is the texture source (true or hidden-low-passed).
pub fn reconstruct(
    cfg: &PresetConfig,
    terrain: &Terrain,
    albedo: &AlbedoGrid,
    world: &crate::lab::World,
    seed: u64,
    rng: &mut ChaCha8Rng,
) -> SfmMesh {
    let g = &terrain.height;
    let shape = GridShape::of(g.origin_m, g.cell_m, g.width, g.height);
    let smooth = gaussian_blur(&g.z, g.width, g.height, 0.012 / g.cell_m);
    let ashape = GridShape::of(albedo.origin_m, albedo.cell_m, albedo.width, albedo.height);
    let colour = gaussian_blur(
        &albedo.value,
        albedo.width,
        albedo.height,
        0.01 / albedo.cell_m,
    );
    let mesh = GridShape::covering(cfg.extent_m, cfg.sfm_cell_m);
    let axis = [
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    ];
    let rot = Pose {
        translation_m: [0.0; 3],
        rotation_xyzw: quat_from_axis_angle(axis, rng.gen_range(0.4..2.8)),
    };
    let similarity = Similarity {
        maps: "ground -> sfm: p_sfm = scale * rotation * p_ground + translation",
        scale: 1.0 / 0.68,
        rotation: rot.rotation_matrix(),
        translation: [
            rng.gen_range(-5.0..5.0),
            rng.gen_range(-5.0..5.0),
            rng.gen_range(-5.0..5.0),
        ],
    };
    let rows: Vec<Vec<([f64; 3], [u8; 3])>> = (0..mesh.height)
        .into_par_iter()
        .map(|r| {
            let mut rng = item_rng(seed, "sfm.noise", r as u64);
            (0..mesh.width)
                .map(|c| {
                    let [x, y] = mesh.centre(c, r);
                    let edge = x.min(y).min(cfg.extent_m[0] - x).min(cfg.extent_m[1] - y);
                    let sigma = 0.012 * (1.0 + 1.2 * (1.0 - edge / 0.6).max(0.0));
                    let n = Normal::new(0.0, sigma).map_or(0.0, |d| d.sample(&mut rng));
                    let z = shape.bilinear(&smooth, x, y) + n;
                    let a = ashape.bilinear(&colour, x, y);
                    let grey = world.photo_dn(a);
                    (similarity.apply([x, y, z]), [grey; 3])
                })
                .collect()
        })
        .collect();
    let (positions, colors) = rows.into_iter().flatten().unzip();
    SfmMesh {
        positions,
        colors,
        triangles: grid_triangles(mesh.width, mesh.height),
        similarity,
    }
}

/// Two triangles per quad, split along the NW–SE diagonal, counter-clockwise seen from above.
pub fn grid_triangles(width: usize, height: usize) -> Vec<[u32; 3]> {
    let mut t = Vec::with_capacity(2 * width.saturating_sub(1) * height.saturating_sub(1));
    for r in 0..height.saturating_sub(1) {
        for c in 0..width.saturating_sub(1) {
            let nw = (r * width + c) as u32;
            let (ne, sw, se) = (nw + 1, nw + width as u32, nw + width as u32 + 1);
            // Row index grows southwards, so NW -> SE -> NE is counter-clockwise from above.
            t.push([nw, se, ne]);
            t.push([nw, sw, se]);
        }
    }
    t
}

/// VRML 2.0 text of the mesh (one Shape, an IndexedFaceSet with per-vertex colours).
pub fn vrml(mesh: &SfmMesh) -> Vec<u8> {
    let mut out = String::from(
        "#VRML V2.0 utf8\n# multi-view stereo reconstruction (simulated by regolith-corpus)\n\
         Shape {\n  appearance Appearance {\n    material Material { diffuseColor 0.8 0.8 0.8 }\n  }\n\
         \x20 geometry IndexedFaceSet {\n    solid FALSE\n    colorPerVertex TRUE\n    coord Coordinate { point [\n",
    );
    let lines = |n: usize, f: &(dyn Fn(usize, &mut String) + Sync)| -> String {
        let parts: Vec<String> = (0..n.div_ceil(8192))
            .into_par_iter()
            .map(|chunk| {
                let mut s = String::new();
                for i in chunk * 8192..((chunk + 1) * 8192).min(n) {
                    s.push_str("      ");
                    f(i, &mut s);
                    s.push_str(",\n");
                }
                s
            })
            .collect();
        parts.concat()
    };
    out.push_str(&lines(mesh.positions.len(), &|i, s| {
        if let Some(p) = mesh.positions.get(i) {
            push_fixed(s, p[0], 6);
            s.push(' ');
            push_fixed(s, p[1], 6);
            s.push(' ');
            push_fixed(s, p[2], 6);
        }
    }));
    out.push_str("    ] }\n    color Color { color [\n");
    out.push_str(&lines(mesh.colors.len(), &|i, s| {
        if let Some(c) = mesh.colors.get(i) {
            let v: Vec<String> = c
                .iter()
                .map(|&x| format!("{:.4}", f64::from(x) / 255.0))
                .collect();
            s.push_str(&v.join(" "));
        }
    }));
    out.push_str("    ] }\n    coordIndex [\n");
    out.push_str(&lines(mesh.triangles.len(), &|i, s| {
        if let Some(t) = mesh.triangles.get(i) {
            s.push_str(&format!("{} {} {} -1", t[0], t[1], t[2]));
        }
    }));
    out.push_str("    ]\n  }\n}\n");
    out.into_bytes()
}

/// Picking noise of a ground control point, metres per axis in the ground frame (σ of a
/// Gaussian): 1.5 mm per axis, 2.6 mm RMS in 3D, what clicking a 26 mm ball's centre in a
/// 2 cm-vertex SfM model gives.
pub const GCP_PICKING_SIGMA_M: f64 = 0.0015;

/// One ground control point as the GCP file holds it, with its truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GcpTruth {
    /// Marker name (as in `vicon/markers.csv`).
    pub name: String,
    /// True ball centre, ground frame, metres.
    pub ground_m: [f64; 3],
    /// Picking noise added before mapping, ground frame, metres.
    pub noise_m: [f64; 3],
    /// The true centre mapped into the SfM frame (no noise).
    pub sfm_true: [f64; 3],
    /// The position written to the file: `similarity(ground_m + noise_m)`, SfM units.
    pub sfm: [f64; 3],
}

/// The ground markers as a photogrammetrist would mark them in the reconstruction: each ball
/// centre mapped into the SfM frame by the true similarity, after Gaussian picking noise of
/// [`GCP_PICKING_SIGMA_M`] per axis (ground units).
pub fn ground_control_points(
    markers: &[(String, [f64; 3])],
    similarity: &Similarity,
    rng: &mut ChaCha8Rng,
) -> Vec<GcpTruth> {
    let pick = Normal::new(0.0, GCP_PICKING_SIGMA_M).ok();
    markers
        .iter()
        .map(|(name, g)| {
            let mut n = || pick.map_or(0.0, |d| d.sample(rng));
            let noise_m = [n(), n(), n()];
            GcpTruth {
                name: name.clone(),
                ground_m: *g,
                noise_m,
                sfm_true: similarity.apply(*g),
                sfm: similarity.apply([g[0] + noise_m[0], g[1] + noise_m[1], g[2] + noise_m[2]]),
            }
        })
        .collect()
}

/// The GCP file: a marker export (`#` comments, a `Label,X,Y,Z` header, one row per marker in
/// the reconstruction's frame, 6 decimals), labels = the Vicon marker names, no ground
/// columns (the compiler takes the ground positions from the Vicon markers).
pub fn gcp_csv(points: &[GcpTruth]) -> Vec<u8> {
    let mut s = String::from(
        "# Markers placed on the multi-view stereo reconstruction (simulated by regolith-corpus)\n\
         # Coordinates: the reconstruction's own frame (sfm/mesh.wrl, sfm/mesh.ply); labels = Vicon marker names\n\
         Label,X,Y,Z\n",
    );
    for p in points {
        s.push_str(&p.name);
        for v in p.sfm {
            s.push(',');
            push_fixed(&mut s, v, 6);
        }
        s.push('\n');
    }
    s.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn gcp_file_maps_markers_with_millimetre_noise() {
        let sim = Similarity {
            maps: "",
            scale: 1.0 / 0.68,
            rotation: [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [1.0, 2.0, 3.0],
        };
        let markers: Vec<(String, [f64; 3])> = (0..200)
            .map(|i| (format!("M{i}"), [i as f64 * 0.01, 1.0, 0.1]))
            .collect();
        let a = ground_control_points(&markers, &sim, &mut ChaCha8Rng::seed_from_u64(3));
        let b = ground_control_points(&markers, &sim, &mut ChaCha8Rng::seed_from_u64(3));
        assert_eq!(a, b);
        let ms: f64 = a
            .iter()
            .map(|p| p.noise_m.iter().map(|v| v * v).sum::<f64>())
            .sum::<f64>()
            / a.len() as f64;
        // 3D RMS ≈ √3 · 1.5 mm = 2.6 mm.
        assert!((ms.sqrt() - 0.0026).abs() < 0.0004, "{}", ms.sqrt());
        for p in &a {
            let d: f64 = (0..3).map(|k| (p.sfm[k] - p.sfm_true[k]).powi(2)).sum();
            let n: f64 = p.noise_m.iter().map(|v| v * v).sum();
            assert!((d.sqrt() - sim.scale * n.sqrt()).abs() < 1e-12);
        }
        let text = String::from_utf8(gcp_csv(&a[..2])).unwrap();
        let rows: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(rows[0], "Label,X,Y,Z");
        assert!(rows[1].starts_with("M0,"), "{}", rows[1]);
        assert_eq!(rows.len(), 3);
    }

    #[test]
    fn triangles_cover_the_grid_counter_clockwise() {
        let t = grid_triangles(3, 2);
        assert_eq!(t.len(), 4);
        // Vertex (c, r) at x = c, y = -r: signed area must be positive (CCW from above).
        for tri in &t {
            let p = |i: u32| [(i % 3) as f64, -((i / 3) as f64)];
            let (a, b, c) = (p(tri[0]), p(tri[1]), p(tri[2]));
            let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(area > 0.0, "{tri:?}");
        }
    }

    #[test]
    fn similarity_scales_distances() {
        let s = Similarity {
            maps: "",
            scale: 2.0,
            rotation: [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [1.0, 2.0, 3.0],
        };
        assert_eq!(s.apply([1.0, 0.0, 0.0]), [1.0, 4.0, 3.0]);
    }
}
