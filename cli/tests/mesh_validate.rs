//! Mesh entries through `validate` end to end on a compiled mini corpus campaign: the compiler's
//! GLB of `laser/0.01/mesh` (lod0) renders at every real capture pose like the heightfield it
//! was built from (radiance and depth), `validate` stores its certificate next to the raster's,
//! with the same structure and figures, `release --publish` wants
//! certificates for mesh entries too, and the gap workflow runs on a mesh entry.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{certificate, regolith};
use regolith_reader::captures::ImageKind;
use regolith_reader::Database;
use regolith_validator::gap::{self, GapOptions};
use regolith_validator::mesh_entry::mesh_geometry;
use regolith_validator::render::{Geometry, RenderOptions, Scene, View};
use regolith_validator::validate::{campaign_light, certified_entries, entry_geometry};
use serde_json::Value;

fn ok(args: &[&str]) -> std::process::Output {
    let out = regolith(args);
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Keys of a JSON object, recursively, with array elements reduced to the first one's keys:
/// the shape of a certificate without its figures.
fn shape(v: &Value, path: &str, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = format!("{path}.{k}");
                out.push(p.clone());
                shape(x, &p, out);
            }
        }
        Value::Array(a) => {
            if let Some(x) = a.first() {
                shape(x, &format!("{path}[]"), out);
            }
        }
        _ => {}
    }
}

#[test]
fn mesh_entry_renders_like_its_heightfield_and_is_certified() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    let db = dir.path().join("db").to_string_lossy().into_owned();
    let camp_s = camp.to_str().unwrap();
    let out = ok(&[
        "corpus",
        "generate",
        "--renderer",
        "model",
        "--preset",
        "mini",
        "--seed",
        "7",
        "--out",
        camp_s,
    ]);
    assert_eq!(out.status.code(), Some(0));
    let out = ok(&["compile", camp_s, "--db", &db, "--release", "mesh@1.0.0"]);
    assert_eq!(out.status.code(), Some(0));

    let database = Database::open(&db).unwrap();
    let view = database.release("mesh@1.0.0").unwrap();
    // `validate` without --entry and the release gate cover both kinds.
    let names = certified_entries(&view);
    assert!(
        names.iter().any(|n| n == "laser/0.01") && names.iter().any(|n| n == "laser/0.01/mesh"),
        "{names:?}"
    );
    assert!(!names.iter().any(|n| n == "laser/0.01/texture"));

    // 1. Renders of the mesh (its GLB decoded and traced as triangles) and of the heightfield
    // at the real capture poses.
    let hf = entry_geometry(&view, "laser/0.01").unwrap();
    let mesh = mesh_geometry(&view, "laser/0.01/mesh").unwrap();
    let Geometry::Mesh(m) = &mesh else {
        panic!("a mesh entry must decode to a mesh")
    };
    // Validation traces it as the grid it is (`render::grid_mesh`); an SfM-shaped or
    // simplified mesh would stay a mesh.
    assert!(
        matches!(
            entry_geometry(&view, "laser/0.01/mesh").unwrap(),
            Geometry::Heightfield { .. }
        ),
        "the compiler's lod0 is a grid"
    );
    assert!(m.texture.is_some(), "the compiler embeds the texture");
    let (hf_scene, mesh_scene) = (Scene::new(&hf), Scene::new(&mesh));
    let light = campaign_light(&view).unwrap();
    let images = view.captures("captures").unwrap().images().unwrap();
    let opts = RenderOptions {
        distort: true,
        shadows: true,
        supersample: 1,
        filter_textures: true,
        adaptive: false,
    };
    let (mut both, mut only_hf, mut only_mesh) = (0usize, 0usize, 0usize);
    let (mut sum_abs, mut depth_err): (f64, Vec<f64>) = (0.0, Vec::new());
    let mut radiance_sum = 0.0;
    for img in images
        .iter()
        .filter(|i| i.kind == ImageKind::Raw && i.frame == 0)
    {
        let v = View {
            camera: view.camera(&format!("cameras/{}", img.camera)).unwrap(),
            ground_from_camera: img.ground_from_camera,
        };
        let a = hf_scene.render(&light, &v, &opts);
        let b = mesh_scene.render(&light, &v, &opts);
        for k in 0..a.mask.len() {
            match (a.mask[k] == 255, b.mask[k] == 255) {
                (true, true) => {
                    both += 1;
                    sum_abs += f64::from((a.radiance[k] - b.radiance[k]).abs());
                    radiance_sum += f64::from(a.radiance[k]);
                    depth_err.push(f64::from((a.depth[k] - b.depth[k]).abs()));
                }
                (true, false) => only_hf += 1,
                (false, true) => only_mesh += 1,
                _ => {}
            }
        }
    }
    depth_err.sort_by(f64::total_cmp);
    let q = |p: f64| depth_err[((depth_err.len() - 1) as f64 * p) as usize];
    let mean_abs = sum_abs / both as f64;
    eprintln!(
        "pixels both {both} only-heightfield {only_hf} only-mesh {only_mesh}; radiance mean {:.4}, mean |Δ| {mean_abs:.2e}; |Δdepth| median {:.2e} p99 {:.2e} p99.9 {:.2e} max {:.2e} m",
        radiance_sum / both as f64,
        q(0.5),
        q(0.99),
        q(0.999),
        q(1.0)
    );
    // Both surfaces are the same triangles (NW–SE split, vertices at cell centres, texel centres
    // at the vertices); they differ only by the heightfield's 16-bit height quantisation
    // (≈ 4 µm steps over this 0.28 m range) against the mesh's f32 heights and positions, and
    // by f32 texture coordinates. Measured (seed 7, 4 views, 725k pixels): mean |Δ radiance|
    // 1.3e-5 (0.003 DN at 8 bits), |Δ depth| median 0.8 µm, p99.9 6 µm, max 0.16 mm, no pixel
    // seen by one render only. The bounds leave ~15x margin and stay far below one 8-bit DN
    // (3.9e-3) and a millimetre: a UV flip, an axis swap or a lost origin translation moves
    // them by orders of magnitude.
    assert!(both > 100_000, "{both}");
    assert!(only_hf + only_mesh <= both / 1000, "silhouettes differ");
    assert!(mean_abs < 2e-4, "mean |Δ radiance| {mean_abs}");
    assert!(
        q(0.5) < 1e-5 && q(0.999) < 1e-4 && q(1.0) < 1e-3,
        "depth differs"
    );

    // 2. The gate wants certificates for mesh entries too: with none stored, publishing is
    // refused naming them.
    let out = ok(&["release", &db, "mesh@1.0.0", "--publish"]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    for name in ["laser/0.01", "laser/0.01/mesh", "sfm/0.02/mesh"] {
        assert!(text.contains(&format!("{name}: no certificate")), "{text}");
    }

    // 3. `validate` certifies the raster and its mesh in one run; both certificates are stored
    // side by side (SPEC §2 escapes nested entry names) and have the same structure.
    let out = ok(&[
        "--json",
        "validate",
        &db,
        "--entry",
        "laser/0.01",
        "--entry",
        "laser/0.01/mesh",
    ]);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let entries = v["entries"].as_array().unwrap();
    assert_eq!(entries.len(), 2);
    assert_eq!(entries[0]["entry"], "laser/0.01");
    assert_eq!(entries[1]["entry"], "laser/0.01/mesh");
    let (ch, cm) = (certificate(&db, &entries[0]), certificate(&db, &entries[1]));
    let database = Database::open(&db).unwrap();
    for (name, c) in [("laser/0.01", &ch), ("laser/0.01/mesh", &cm)] {
        assert_eq!(
            database.certificate(&view.id, name).unwrap().as_ref(),
            Some(c),
            "{name}: the stored certificate is the one reported"
        );
    }
    let (mut sh, mut sm) = (Vec::new(), Vec::new());
    shape(&ch, "", &mut sh);
    shape(&cm, "", &mut sm);
    assert_eq!(sh, sm, "certificate structure");
    assert_eq!(cm["entry"], "laser/0.01/mesh");
    assert_eq!(
        cm["entry_hash"].as_str(),
        Some(
            view.entry("laser/0.01/mesh")
                .unwrap()
                .hash()
                .unwrap()
                .to_hex()
                .as_str()
        )
    );
    assert_eq!(
        cm["views"].as_array().unwrap().len(),
        ch["views"].as_array().unwrap().len()
    );
    let band = |c: &Value| c["high_band_log_ratio"].as_f64().unwrap();
    let ratio = |c: &Value| c["mean_ratio_to_ceiling"]["mean"].as_f64().unwrap();
    let rms = |c: &Value| {
        c["photometric"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p[2]["rms"].as_f64().unwrap())
            .fold(0.0, f64::max)
    };
    eprintln!(
        "heightfield: passed {} high band {:.3} mean ratio {:.3} worst photometric RMS {:.2}; mesh: passed {} high band {:.3} mean ratio {:.3} worst photometric RMS {:.2}",
        ch["passed"],
        band(&ch),
        ratio(&ch),
        rms(&ch),
        cm["passed"],
        band(&cm),
        ratio(&cm),
        rms(&cm)
    );
    // The renders agree to a few thousandths of a DN, so the certificates' figures do too
    // (measured: identical to three decimals).
    assert!((band(&ch) - band(&cm)).abs() < 0.02);
    assert!((ratio(&ch) - ratio(&cm)).abs() < 0.02);
    assert!((rms(&ch) - rms(&cm)).abs() < 0.5);
    assert_eq!(ch["passed"], cm["passed"]);

    // 4. The gap workflow runs on a mesh entry too and measures the same gap.
    let opts = GapOptions {
        supersample: 1,
        ..GapOptions::default()
    };
    let (gh, gm) = (
        gap::run(&view, "laser/0.01", &opts).unwrap(),
        gap::run(&view, "laser/0.01/mesh", &opts).unwrap(),
    );
    eprintln!(
        "gap before: heightfield {:.3} DN, mesh {:.3} DN",
        gh.gap_before, gm.gap_before
    );
    assert!((gh.gap_before - gm.gap_before).abs() < 0.1);
}
