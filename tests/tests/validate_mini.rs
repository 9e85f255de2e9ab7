//! `validate` on a compiled corpus campaign: a certificate per entry bound to the release and
//! entry hash, stored in the database, verified by `verify` and kept by `gc`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_compiler::compile::{compile, options};
use regolith_compiler::ingest::campaign;
use regolith_corpus::{generate, GenerateOptions, Preset};
use regolith_reader::{verify, Database, Writer};
use regolith_validator::features::Detector;
use regolith_validator::validate::{validate_entry, ValidateOptions, Validator};

#[test]
fn certificates_are_bound_stored_and_verified() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("campaign");
    generate(
        &GenerateOptions {
            preset: Preset::Mini,
            seed: 21,
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
    let c = campaign::load(&camp).unwrap();
    let db_path = tmp.path().join("db");
    let w = Writer::create_or_open(&db_path).unwrap();
    compile(&c, &w, &options(&c, Some("mini@1.0.0")), &|_, _| {}).unwrap();
    let db = Database::open(&db_path).unwrap();
    let view = db.release("latest").unwrap();
    let opts = ValidateOptions {
        detectors: vec![Detector::Harris, Detector::Fast],
        ..ValidateOptions::default()
    };
    let cert = validate_entry(&view, "laser/0.01", &opts).unwrap();
    assert_eq!(
        cert.entry_hash,
        view.entry("laser/0.01").unwrap().hash().unwrap().to_hex()
    );
    assert_eq!(cert.release_id, view.id.to_hex());
    assert_eq!(
        cert.views.len(),
        2 * 2 * 2,
        "2 captures x 2 cameras x 2 detectors"
    );
    for (d, s) in &cert.summary {
        // Two real frames per pose: the ceiling exists and noise keeps it below 1.
        let ceiling = s.ceiling.unwrap_or_else(|| panic!("{d}: no ceiling"));
        assert!(
            ceiling.mean > 0.3 && ceiling.mean <= 1.0,
            "{d}: ceiling {}",
            ceiling.mean
        );
        assert!(
            s.sim.mean > 0.0 && s.sim.mean < ceiling.mean,
            "{d}: sim {} ceiling {}",
            s.sim.mean,
            ceiling.mean
        );
    }
    assert_eq!(cert.passed, cert.failures.is_empty());
    // One validator for several entries keeps the real frames' detections (keypoints,
    // descriptors, regions) for the next entry: its certificates are those made afresh.
    let kept = ValidateOptions {
        detectors: vec![Detector::Sift, Detector::Mser, Detector::Fast],
        ..opts.clone()
    };
    let validator = Validator::new(&view, kept.clone()).unwrap();
    let coarse = validator.entry("laser/0.02", None).unwrap();
    let fine = validator.entry("laser/0.01", None).unwrap();
    fn json(c: &impl serde::Serialize) -> serde_json::Value {
        serde_json::to_value(c).unwrap()
    }
    assert_eq!(
        json(&fine),
        json(&validate_entry(&view, "laser/0.01", &kept).unwrap())
    );
    assert_ne!(json(&coarse.views), json(&fine.views), "the entries differ");
    // A detector's figures do not depend on which others run with it.
    let fast = |c: &regolith_validator::validate::Certificate| {
        let v: Vec<_> = c
            .views
            .iter()
            .filter(|v| v.detector == Detector::Fast)
            .collect();
        json(&v)
    };
    assert_eq!(fast(&fine), fast(&cert));
    w.put_certificate(&view.id, "laser/0.01", &cert).unwrap();
    let stored = db.certificate(&view.id, "laser/0.01").unwrap().unwrap();
    assert_eq!(stored["entry_hash"], cert.entry_hash);
    assert!(verify(&db).unwrap().ok());
    w.gc().unwrap();
    assert!(
        db.certificate(&view.id, "laser/0.01").unwrap().is_some(),
        "gc must keep certificates"
    );
    assert_eq!(
        db.releases().unwrap().len(),
        1,
        "certificate refs are not releases"
    );
}
