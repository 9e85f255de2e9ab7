//! `sfm-on-laser`: a reconstruction terrain with `drape_on` puts its vertex colours on the laser
//! terrain's geometry. Checked against the corpus truth on `mini`: the draped entry has exactly
//! the laser raster's heights (the same objects), and its texture is the SfM albedo — as close
//! to the true albedo as the SfM raster's own texture, and closer than the laser reflectance
//! (the corpus' SfM colours are the true albedo blurred by 1 cm; the laser texture carries range
//! noise and incidence residuals).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;

use regolith_compiler::compile::{compile, options};
use regolith_compiler::ingest::campaign;
use regolith_corpus::{generate, GenerateOptions, Preset};
use regolith_reader::heightfield::decode_grey_png;
use regolith_reader::{Database, ReleaseView, Writer};
use serde_json::Value;

/// RMS difference between an entry's texture and the true albedo (nearest truth cell) over the
/// entry's measured cells.
fn texture_vs_truth(view: &ReleaseView, entry: &str, camp: &Path) -> f64 {
    let hf = view.heightfield(entry).unwrap();
    let tex = decode_grey_png(
        &view
            .read_file(&format!("{entry}/texture"), "image")
            .unwrap(),
        32_768,
    )
    .unwrap();
    let scale = if tex.bit_depth == 16 { 65535.0 } else { 255.0 };
    let meta: Value =
        serde_json::from_slice(&std::fs::read(camp.join("truth/height.json")).unwrap()).unwrap();
    let truth = decode_grey_png(
        &std::fs::read(camp.join("truth/albedo.png")).unwrap(),
        32_768,
    )
    .unwrap();
    let origin = [
        meta["origin_m"][0].as_f64().unwrap(),
        meta["origin_m"][1].as_f64().unwrap(),
    ];
    let cell = meta["cell_m"].as_f64().unwrap();
    let m = &hf.meta;
    let (mut sq, mut n) = (0.0, 0usize);
    for row in 0..m.height as usize {
        for col in 0..m.width as usize {
            let i = row * m.width as usize + col;
            if hf.valid[i] != 255 {
                continue;
            }
            let x = m.origin_m[0] + col as f64 * m.cell_m;
            let y = m.origin_m[1] - row as f64 * m.cell_m;
            let (tc, tr) = (
                ((x - origin[0]) / cell).round(),
                ((origin[1] - y) / cell).round(),
            );
            if tc < 0.0 || tr < 0.0 || tc >= f64::from(truth.width) || tr >= f64::from(truth.height)
            {
                continue;
            }
            let t = f64::from(truth.samples[tr as usize * truth.width as usize + tc as usize])
                / 65535.0;
            let e = f64::from(tex.samples[i]) / scale;
            sq += (e - t) * (e - t);
            n += 1;
        }
    }
    assert!(n > 1000, "{entry}: {n} cells");
    (sq / n as f64).sqrt()
}

#[test]
fn sfm_colours_drape_on_the_laser_geometry() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("campaign");
    generate(
        &GenerateOptions {
            preset: Preset::Mini,
            seed: 7,
            full: false,
            hidden: vec![],
        },
        &camp,
        &|_, _| {},
    )
    .unwrap();
    let toml = std::fs::read_to_string(camp.join("campaign.toml")).unwrap();
    let draped = toml.replacen(
        "texture = \"vertex-color\"",
        "texture = \"vertex-color\"\ndrape_on = \"laser\"",
        1,
    );
    assert_ne!(toml, draped, "the mini preset has no vertex-color terrain");
    std::fs::write(camp.join("campaign.toml"), draped).unwrap();
    let c = campaign::load(&camp).unwrap();
    let db_path = tmp.path().join("db");
    let w = Writer::create_or_open(&db_path).unwrap();
    compile(&c, &w, &options(&c, Some("drape@1")), &|_, _| {}).unwrap();
    let db = Database::open(&db_path).unwrap();
    let view = db.release("drape@1").unwrap();

    // The laser raster's geometry, stored once.
    let (laser, on) = (
        view.entry("laser/0.02").unwrap(),
        view.entry("sfm-on-laser/0.02").unwrap(),
    );
    assert_eq!(on.kind, "heightfield");
    let (mut a, mut b) = (on.meta.clone(), laser.meta.clone());
    assert_eq!(a["source"], "sfm-on-laser");
    a["source"] = Value::Null;
    b["source"] = Value::Null;
    assert_eq!(a, b, "the grid and quantisation are the laser raster's");
    for role in ["height", "height_f32"] {
        assert_eq!(
            on.file(role).map(|f| f.object),
            laser.file(role).map(|f| f.object),
            "{role}"
        );
    }
    let tex = view.entry("sfm-on-laser/0.02/texture").unwrap();
    assert_eq!(tex.meta["content"], "sfm-on-laser");
    assert_eq!(tex.meta["grid_of"], "sfm-on-laser/0.02");
    assert!(view.entry("sfm-on-laser/0.02/mesh").is_ok());

    // The SfM albedo, on the laser grid.
    let (rms_laser, rms_sfm, rms_on) = (
        texture_vs_truth(&view, "laser/0.02", &camp),
        texture_vs_truth(&view, "sfm/0.02", &camp),
        texture_vs_truth(&view, "sfm-on-laser/0.02", &camp),
    );
    assert!(
        rms_on < 0.8 * rms_laser,
        "draped {rms_on:.4} vs laser reflectance {rms_laser:.4}"
    );
    assert!(
        rms_on < 1.15 * rms_sfm,
        "draped {rms_on:.4} vs the SfM raster's own {rms_sfm:.4}"
    );
}
