//! Certificate refs (SPEC §2): nested entry names (`laser/0.01` and its mesh
//! `laser/0.01/mesh`) each keep their own certificate, names with `@` and `/` never share a ref,
//! and a database written with the 1.1–1.2 layout (`certificates/<id>/<entry>`) is still read.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_format::ObjectId;
use regolith_reader::database::certificate_ref;
use regolith_reader::{Database, Writer};
use serde_json::json;

fn release_id(n: u8) -> ObjectId {
    ObjectId::of_bytes(&[n])
}

#[test]
fn nested_entries_keep_separate_certificates() {
    let dir = tempfile::tempdir().unwrap();
    let w = Writer::create_or_open(dir.path().join("db")).unwrap();
    let id = release_id(1);
    let names = [
        "laser/0.01",
        "laser/0.01/mesh",
        "laser@s0.01",
        "laser/0.01@mesh",
    ];
    for (i, e) in names.iter().enumerate() {
        w.put_certificate(&id, e, &json!({"entry": e, "n": i}))
            .unwrap();
    }
    let db = Database::open(dir.path().join("db")).unwrap();
    for (i, e) in names.iter().enumerate() {
        let c = db.certificate(&id, e).unwrap().expect("stored");
        assert_eq!(c, json!({"entry": e, "n": i}));
    }
    assert!(db.certificate(&id, "laser").unwrap().is_none());
    assert!(db
        .certificate(&release_id(2), "laser/0.01")
        .unwrap()
        .is_none());
    let refs: Vec<String> = names.iter().map(|e| certificate_ref(&id, e)).collect();
    let mut unique = refs.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), refs.len(), "{refs:?}");
    // Re-validating replaces the certificate.
    w.put_certificate(&id, "laser/0.01", &json!({"again": true}))
        .unwrap();
    assert_eq!(
        db.certificate(&id, "laser/0.01").unwrap(),
        Some(json!({"again": true}))
    );
}

#[test]
fn certificates_of_the_previous_layout_are_still_read() {
    let dir = tempfile::tempdir().unwrap();
    let w = Writer::create_or_open(dir.path().join("db")).unwrap();
    let id = release_id(3);
    let body = w.put_json(&json!({"legacy": true})).unwrap();
    w.set_ref(&format!("certificates/{id}/laser/0.05"), &body.object)
        .unwrap();
    let db = Database::open(dir.path().join("db")).unwrap();
    assert_eq!(
        db.certificate(&id, "laser/0.05").unwrap(),
        Some(json!({"legacy": true}))
    );
    // `laser` is a directory of that layout, not a certificate.
    assert!(db.certificate(&id, "laser").unwrap().is_none());
    // A certificate in the current layout takes precedence.
    w.put_certificate(&id, "laser/0.05", &json!({"legacy": false}))
        .unwrap();
    assert_eq!(
        db.certificate(&id, "laser/0.05").unwrap(),
        Some(json!({"legacy": false}))
    );
}
