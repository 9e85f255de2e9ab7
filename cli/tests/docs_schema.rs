//! The `--json` output of every command matches the JSON Schema its page in `docs/` gives, and
//! every option `--help` lists is on that page. The schemas are checked by the small validator
//! in `common` (a subset of JSON Schema); its own tests come first, so a validator that
//! accepts everything cannot pass here.
//!
//! The outputs are real: the binary runs on the checked-in demo campaign (`corpus/demo`) and a
//! `mini` corpus campaign. `validate --json`, `gap --json` and `demo --json` take minutes; the
//! tests that already run them (`gate.rs`, `gap.rs`) check their schemas.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::{Path, PathBuf};

use common::{assert_matches_doc_schema, regolith, schema_errors, schema_from_markdown};
use serde_json::{json, Value};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn demo() -> String {
    root().join("corpus/demo").to_string_lossy().into_owned()
}

/// Runs `regolith --json ARGS`, expects exit code `code` and returns the parsed stdout.
fn json_of(args: &[&str], code: i32) -> Value {
    let mut all = vec!["--json"];
    all.extend_from_slice(args);
    let out = regolith(&all);
    assert_eq!(
        out.status.code(),
        Some(code),
        "regolith {all:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("regolith {all:?}: stdout is not JSON: {e}"))
}

// ---- the validator itself -------------------------------------------------------------------

/// A schema using every checked keyword, with `required` keys.
fn small_schema(required: &[&str]) -> serde_json::Value {
    json!({
        "type": "object",
        "required": required,
        "additionalProperties": false,
        "properties": {
            "a": {"type": "integer"},
            "b": {"type": ["number", "null"]},
            "c": {"type": "array", "items": {"type": "string", "enum": ["x", "y"]}},
            "d": {"type": "object", "additionalProperties": {"type": "number"}}
        }
    })
}

#[test]
fn a_value_that_fits_has_no_mismatch() {
    let schema = small_schema(&["a", "b"]);
    let v = json!({"a": 3, "b": null, "c": ["x", "y", "x"], "d": {"k/1": 1.5, "k2": 2}});
    assert_eq!(schema_errors(&schema, &v), Vec::<String>::new());
    let v = json!({"a": 3, "b": 0.25});
    assert_eq!(schema_errors(&schema, &v), Vec::<String>::new());
}

#[test]
fn every_mismatch_is_reported_with_its_path() {
    let schema = small_schema(&["a", "b", "gone"]);
    let v = json!({
        "a": 1.5,
        "b": "no",
        "c": ["x", "z", 3],
        "d": {"ok": 1, "not ok": "s"},
        "extra": true
    });
    let errors = schema_errors(&schema, &v);
    let expect = [
        "$.gone: required but missing",
        "$.a: expected integer, found number",
        "$.b: expected number or null, found string",
        "$.c[1]: \"z\" is not one of",
        "$.c[2]: expected string, found integer",
        "$.d[\"not ok\"]: expected number, found string",
        "$.extra: not in the schema's \"properties\"",
    ];
    for e in expect {
        assert!(
            errors.iter().any(|x| x.starts_with(e)),
            "{e:?} not in {errors:#?}"
        );
    }
    assert_eq!(errors.len(), expect.len(), "{errors:#?}");
}

#[test]
fn integers_are_numbers_but_fractions_are_not_integers() {
    let int = json!({"type": "integer"});
    let num = json!({"type": "number"});
    assert!(schema_errors(&int, &json!(7)).is_empty());
    assert!(schema_errors(&int, &json!(-7)).is_empty());
    assert!(
        schema_errors(&int, &json!(2.0)).is_empty(),
        "2.0 is an integer"
    );
    assert!(schema_errors(&num, &json!(7)).is_empty());
    assert_eq!(schema_errors(&int, &json!(2.5)).len(), 1);
    assert_eq!(schema_errors(&num, &json!("7")).len(), 1);
    assert_eq!(schema_errors(&num, &Value::Null).len(), 1);
}

#[test]
fn one_of_needs_exactly_one_alternative() {
    let schema = json!({"oneOf": [
        {"type": "object", "required": ["x"], "properties": {"x": {"type": "integer"}}},
        {"type": "object", "required": ["y"], "properties": {"y": {"type": "string"}}}
    ]});
    assert!(schema_errors(&schema, &json!({"x": 1})).is_empty());
    assert!(schema_errors(&schema, &json!({"y": "s"})).is_empty());
    let none = schema_errors(&schema, &json!({"x": "s"}));
    assert_eq!(none.len(), 1, "{none:?}");
    assert!(
        none[0].starts_with("$: matches none of the 2")
            && none[0].contains("$.x: expected integer"),
        "{none:?}"
    );
    let both = schema_errors(&schema, &json!({"x": 1, "y": "s"}));
    assert_eq!(both.len(), 1, "{both:?}");
    assert!(both[0].contains("matches 2 of"), "{both:?}");
}

#[test]
fn nested_paths_are_named() {
    let schema = json!({"type": "object", "properties": {"rows": {"type": "array", "items": {
        "type": "object", "required": ["name"], "properties": {"cells": {"type": "array", "items": {"type": "number"}}}
    }}}});
    let errors = schema_errors(
        &schema,
        &json!({"rows": [{"name": "a", "cells": [1, 2]}, {"cells": [1, null]}]}),
    );
    assert_eq!(
        errors,
        [
            "$.rows[1].name: required but missing",
            "$.rows[1].cells[1]: expected number, found null (null)"
        ]
    );
}

#[test]
fn unsupported_keywords_and_types_are_mismatches() {
    // A schema relying on a keyword the validator does not check would pass anything.
    let errors = schema_errors(&json!({"type": "string", "minLength": 3}), &json!("ab"));
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].contains("\"minLength\" is not supported"));
    let errors = schema_errors(&json!({"type": "float"}), &json!(1.0));
    assert!(errors[0].contains("unknown type"), "{errors:?}");
}

#[test]
fn the_schema_block_is_found_once() {
    let page = "# page\n\n```json\n{\"not\": \"this\"}\n```\n\n```json-schema\n{\"type\": \"object\"}\n```\n";
    assert_eq!(
        schema_from_markdown(page).unwrap(),
        json!({"type": "object"})
    );
    assert!(schema_from_markdown("# nothing\n").is_err());
    let two = format!("{page}\n```json-schema\n{{}}\n```\n");
    assert!(schema_from_markdown(&two).unwrap_err().contains("2 "));
    assert!(schema_from_markdown("```json-schema\n{\"type\": \n```\n").is_err());
    assert!(
        schema_from_markdown("```json-schema\n{}\n").is_err(),
        "unclosed"
    );
}

// ---- the pages ------------------------------------------------------------------------------

/// The command pages with `--json` output, and the command lines whose `--help` they document.
const PAGES: &[(&str, &[&[&str]])] = &[
    ("compile", &[&["compile"]]),
    ("validate", &[&["validate"]]),
    ("gap", &[&["gap"]]),
    ("control", &[&["control"]]),
    (
        "features",
        &[&["features", "detect"], &["features", "repeat"]],
    ),
    ("release", &[&["release"]]),
    ("verify", &[&["verify"]]),
    ("inspect", &[&["inspect"]]),
    ("export", &[&["export"]]),
    ("gc", &[&["gc"]]),
    ("corpus", &[&["corpus", "generate"]]),
    ("demo", &[&["demo"]]),
];

/// Keywords of `schema` and of every schema inside it that the validator does not check, and
/// type names it does not know, with their paths.
fn unchecked_keywords(schema: &Value, path: &str, out: &mut Vec<String>) {
    const KNOWN: [&str; 10] = [
        "type",
        "properties",
        "required",
        "additionalProperties",
        "items",
        "enum",
        "oneOf",
        "description",
        "$schema",
        "title",
    ];
    const TYPES: [&str; 7] = [
        "null", "boolean", "string", "number", "integer", "array", "object",
    ];
    let Some(s) = schema.as_object() else {
        if !schema.is_boolean() {
            out.push(format!("{path}: not a schema"));
        }
        return;
    };
    for key in s.keys().filter(|k| !KNOWN.contains(&k.as_str())) {
        out.push(format!("{path}: {key}"));
    }
    let types: Vec<&Value> = match s.get("type") {
        Some(Value::Array(ts)) => ts.iter().collect(),
        Some(t) => vec![t],
        None => Vec::new(),
    };
    for t in types {
        if !t.as_str().is_some_and(|t| TYPES.contains(&t)) {
            out.push(format!("{path}: type {t}"));
        }
    }
    if let Some(props) = s.get("properties").and_then(Value::as_object) {
        for (k, sub) in props {
            unchecked_keywords(sub, &format!("{path}.properties.{k}"), out);
        }
    }
    for key in ["items", "additionalProperties"] {
        if let Some(sub) = s.get(key) {
            unchecked_keywords(sub, &format!("{path}.{key}"), out);
        }
    }
    for (k, sub) in s
        .get("oneOf")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .enumerate()
    {
        unchecked_keywords(sub, &format!("{path}.oneOf[{k}]"), out);
    }
}

#[test]
fn every_command_page_has_one_schema_the_validator_fully_checks() {
    for (page, _) in PAGES {
        let schema = common::doc_schema(page);
        let mut unchecked = Vec::new();
        unchecked_keywords(&schema, "$", &mut unchecked);
        assert!(unchecked.is_empty(), "docs/{page}.md: {unchecked:?}");
    }
    let mut unchecked = Vec::new();
    unchecked_keywords(
        &json!({"type": ["integer", "float"], "minLength": 1, "properties": {"a": {"format": "x"}}}),
        "$",
        &mut unchecked,
    );
    assert_eq!(
        unchecked,
        [
            "$: minLength",
            "$: type \"float\"",
            "$.properties.a: format"
        ]
    );
    // completions and manpage print no JSON: their page has no schema.
    let text = std::fs::read_to_string(root().join("docs/completions.md")).unwrap();
    assert!(schema_from_markdown(&text).is_err());
}

/// The long options `regolith ARGS --help` lists.
fn long_options(args: &[&str]) -> Vec<String> {
    let mut all = args.to_vec();
    all.push("--help");
    let out = regolith(&all);
    assert!(out.status.success(), "{all:?}");
    let help = String::from_utf8_lossy(&out.stdout).into_owned();
    let mut opts: Vec<String> = help
        .lines()
        .map(str::trim_start)
        .filter_map(|l| {
            // `--json ...` or `-q, --quiet ...`
            let short = l.len() > 4 && l.starts_with('-') && l.get(2..6) == Some(", --");
            let name = if short {
                l.get(6..)?
            } else {
                l.strip_prefix("--")?
            };
            let name: String = name
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect();
            Some(format!("--{name}"))
        })
        .collect();
    opts.retain(|o| o != "--help" && o != "--version");
    opts.sort();
    opts.dedup();
    opts
}

#[test]
fn every_option_is_on_its_page() {
    let mut pages: Vec<(&str, &[&[&str]])> = PAGES.to_vec();
    pages.push(("completions", &[&["completions"], &["manpage"]]));
    for (page, commands) in pages {
        let text = std::fs::read_to_string(root().join(format!("docs/{page}.md"))).unwrap();
        for args in commands {
            let opts = long_options(args);
            // The help parser works: every command has the global options.
            assert!(
                opts.iter().any(|o| o == "--json") && opts.iter().any(|o| o == "--quiet"),
                "{args:?}: {opts:?}"
            );
            for opt in opts {
                assert!(
                    text.contains(&format!("`{opt}")),
                    "docs/{page}.md does not document {opt} of `regolith {}`",
                    args.join(" ")
                );
            }
        }
    }
}

// ---- real output ----------------------------------------------------------------------------

#[test]
fn compile_inspect_verify_export_control_release_gc_match_their_pages() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("db").to_string_lossy().into_owned();
    let demo = demo();

    let check = json_of(&["compile", "--check", &demo], 0);
    assert!(check["files"].as_array().unwrap().len() > 10);
    assert_matches_doc_schema("compile", &check);
    let compiled = json_of(
        &["compile", &demo, "--db", &db, "--release", "demo@1.0.0"],
        0,
    );
    assert_eq!(compiled["cached"], false);
    assert_matches_doc_schema("compile", &compiled);
    // The same inputs again: the cached summary has the same shape.
    let cached = json_of(
        &["compile", &demo, "--db", &db, "--release", "demo@1.0.0"],
        0,
    );
    assert_eq!(cached["cached"], true);
    assert_matches_doc_schema("compile", &cached);

    for args in [
        vec!["inspect", db.as_str()],
        vec!["inspect", db.as_str(), "demo@1.0.0"],
        vec!["inspect", db.as_str(), "demo@1.0.0", "laser/0.01"],
        vec!["inspect", db.as_str(), "latest", "cameras/navcam_left"],
        vec!["inspect", db.as_str(), "latest", "reports/summary"],
    ] {
        assert_matches_doc_schema("inspect", &json_of(&args, 0));
    }
    assert_matches_doc_schema("verify", &json_of(&["verify", &db], 0));

    let to = dir.path().join("export-hf").to_string_lossy().into_owned();
    let hf = json_of(
        &[
            "export",
            &db,
            "latest",
            "laser/0.01",
            "--to",
            &to,
            "--profile",
            "gazebo",
        ],
        0,
    );
    assert_matches_doc_schema("export", &hf);
    let to = dir
        .path()
        .join("export-mesh")
        .to_string_lossy()
        .into_owned();
    let mesh = json_of(
        &["export", &db, "latest", "laser/0.02/mesh", "--to", &to],
        0,
    );
    assert_matches_doc_schema("export", &mesh);

    let control = json_of(
        &[
            "control",
            &db,
            "--release",
            "demo@1.0.0",
            "--entry",
            "laser/0.01",
            "--texture-blur-m",
            "0.02",
        ],
        0,
    );
    assert_eq!(control["release"], "demo@1.0.0+control.1");
    assert_matches_doc_schema("control", &control);
    // The control's child release has a parent: the database summary shows it.
    assert_matches_doc_schema("inspect", &json_of(&["inspect", &db], 0));

    let refused = json_of(&["release", &db, "demo@1.0.0", "--publish"], 1);
    assert_eq!(refused["published"], false);
    assert_matches_doc_schema("release", &refused);
    let published = json_of(
        &[
            "release",
            &db,
            "demo@1.0.0",
            "--publish",
            "--allow-uncertified",
        ],
        0,
    );
    assert_eq!(published["allow_uncertified"], true);
    assert_matches_doc_schema("release", &published);

    assert_matches_doc_schema("gc", &json_of(&["gc", &db], 0));
}

#[test]
fn features_match_their_page() {
    let img = root().join("corpus/demo/captures/loc01_left_a.png");
    let other = root().join("corpus/demo/captures/loc01_left_b.png");
    let (img, other) = (img.to_str().unwrap(), other.to_str().unwrap());
    for detector in ["sift", "mser"] {
        let detect = json_of(&["features", "detect", img, "--detector", detector], 0);
        assert!(!detect["keypoints"].as_array().unwrap().is_empty());
        assert_matches_doc_schema("features", &detect);
    }
    let repeat = json_of(
        &[
            "features",
            "repeat",
            img,
            other,
            "--same-pose",
            "--detector",
            "fast",
        ],
        0,
    );
    assert_matches_doc_schema("features", &repeat);
}

#[test]
fn corpus_generate_matches_its_page() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mini").to_string_lossy().into_owned();
    let v = json_of(
        &[
            "corpus",
            "generate",
            "--renderer",
            "model",
            "--preset",
            "mini",
            "--seed",
            "1",
            "--out",
            &out,
        ],
        0,
    );
    assert_eq!(v["bad_inputs"], Value::Null);
    assert_matches_doc_schema("corpus", &v);
    let out = dir.path().join("mini-bad").to_string_lossy().into_owned();
    let bad = dir.path().join("bad").to_string_lossy().into_owned();
    let v = json_of(
        &[
            "corpus",
            "generate",
            "--renderer",
            "model",
            "--seed",
            "1",
            "--out",
            &out,
            "--bad-inputs",
            &bad,
        ],
        0,
    );
    assert!(v["bad_inputs"].is_array());
    assert_matches_doc_schema("corpus", &v);
}
