//! The crate graph follows ARCHITECTURE.md: format ← reader ← {compiler, validator} ← cli;
//! corpus → format only (it makes the validator's test data, so it must not share its code);
//! model-captures → format + validator + corpus; tests → all. The reader never pulls compiler
//! dependencies.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

#[test]
fn crate_layering_is_respected() {
    let out = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .current_dir(regolith_tests::workspace_root())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let members: BTreeSet<String> = meta["workspace_members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap().to_string())
        .collect();
    let mut deps: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for p in meta["packages"].as_array().unwrap() {
        if !members.contains(p["id"].as_str().unwrap()) {
            continue;
        }
        let name = p["name"].as_str().unwrap().to_string();
        let d = p["dependencies"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|d| d["kind"].is_null())
            .map(|d| d["name"].as_str().unwrap().to_string())
            .collect();
        deps.insert(name, d);
    }
    assert!(
        deps.len() >= 7,
        "expected every workspace crate, found {:?}",
        deps.keys()
    );
    let allowed: BTreeMap<&str, &[&str]> = [
        ("regolith-format", &[][..]),
        ("regolith-reader", &["regolith-format"][..]),
        (
            "regolith-compiler",
            &["regolith-format", "regolith-reader"][..],
        ),
        (
            "regolith-validator",
            &["regolith-format", "regolith-reader"][..],
        ),
        ("regolith-corpus", &["regolith-format"][..]),
        (
            "regolith-model-captures",
            &["regolith-format", "regolith-validator", "regolith-corpus"][..],
        ),
        (
            "regolith-cli",
            &[
                "regolith-format",
                "regolith-reader",
                "regolith-compiler",
                "regolith-validator",
                "regolith-corpus",
                "regolith-model-captures",
            ][..],
        ),
        (
            "regolith-tests",
            &[
                "regolith-format",
                "regolith-reader",
                "regolith-compiler",
                "regolith-validator",
                "regolith-corpus",
                "regolith-model-captures",
            ][..],
        ),
    ]
    .into();
    for (krate, d) in &deps {
        let ok = allowed
            .get(krate.as_str())
            .unwrap_or_else(|| panic!("unknown crate {krate}"));
        for dep in d.iter().filter(|d| d.starts_with("regolith-")) {
            assert!(
                ok.contains(&dep.as_str()),
                "forbidden edge {krate} -> {dep}"
            );
        }
    }
    let forbidden_in_reader = [
        "image", "spade", "kiddo", "rayon", "exr", "gltf", "nalgebra", "e57", "las",
    ];
    for dep in &deps["regolith-reader"] {
        assert!(
            !forbidden_in_reader.contains(&dep.as_str()),
            "the reader must stay small: it depends on {dep}"
        );
    }
}

/// The corpus makes the data that test the validator: no edge of any kind (normal, dev or
/// build) may lead from it to the validator, directly or through another crate.
#[test]
fn the_corpus_shares_no_code_with_the_validator() {
    let out = Command::new(env!("CARGO"))
        .args([
            "tree",
            "-p",
            "regolith-corpus",
            "-e",
            "normal,dev,build",
            "--prefix",
            "none",
            "--offline",
        ])
        .current_dir(regolith_tests::workspace_root())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tree = String::from_utf8_lossy(&out.stdout);
    assert!(
        tree.lines().any(|l| l.starts_with("regolith-format ")),
        "cargo tree lists the corpus's dependencies:\n{tree}"
    );
    for crate_name in ["regolith-validator", "regolith-model-captures"] {
        assert!(
            !tree
                .lines()
                .any(|l| l.starts_with(&format!("{crate_name} "))),
            "regolith-corpus depends on {crate_name}:\n{tree}"
        );
    }
}
