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
use regolith_reader::{Database, ReleaseView, Writer};
use regolith_tests::albedo_truth;
use serde_json::Value;

/// RMS difference between an entry's texture and the true albedo over its measured cells.
fn texture_vs_truth(view: &ReleaseView, entry: &str, camp: &Path) -> f64 {
    let t = albedo_truth::texture_vs_truth(view, entry, camp).unwrap();
    assert!(t.cells > 1000, "{entry}: {} cells", t.cells);
    t.rms
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
            captures: None,
            hidden: vec![],
            auto_exposure: 0.0,
        },
        &camp,
        &regolith_model_captures::ModelCaptures,
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
