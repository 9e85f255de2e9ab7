//! Shared by the CLI integration tests: run the `regolith` binary as a user would.
#![allow(clippy::unwrap_used, clippy::panic, dead_code)]

use std::process::{Command, Output};

/// Runs `regolith ARGS` and returns its output (status, stdout, stderr).
pub fn regolith(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_regolith"))
        .args(args)
        .output()
        .unwrap()
}

/// The certificate object a `validate --json` entry points at, read from the database folder.
pub fn certificate(db: &str, entry: &serde_json::Value) -> serde_json::Value {
    let h = entry["certificate"].as_str().unwrap();
    let path = std::path::Path::new(db).join(format!("objects/sha256/{}/{}", &h[..2], &h[2..]));
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Copies the directory tree `from` to `to`.
pub fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let dest = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &dest);
        } else {
            std::fs::copy(&p, &dest).unwrap();
        }
    }
}

/// Checks `value` (a command's `--json` output) against the JSON Schema of `docs/<page>.md`
/// (its one ```` ```json-schema ```` block) and fails naming the JSON path of every mismatch.
pub fn assert_matches_doc_schema(page: &str, value: &serde_json::Value) {
    let schema = doc_schema(page);
    let errors = schema_errors(&schema, value);
    assert!(
        errors.is_empty(),
        "docs/{page}.md: the --json output does not match its JSON Schema ({} mismatch(es)):\n  {}\n\
         output:\n{}",
        errors.len(),
        errors.join("\n  "),
        serde_json::to_string_pretty(value).unwrap()
    );
}

/// The JSON Schema of `docs/<page>.md` (the workspace's `docs/` folder).
pub fn doc_schema(page: &str) -> serde_json::Value {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../docs")
        .join(format!("{page}.md"));
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    schema_from_markdown(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The one fenced block with the info string `json-schema` in a Markdown text, parsed.
pub fn schema_from_markdown(text: &str) -> Result<serde_json::Value, String> {
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in text.lines() {
        match &mut current {
            None if line.trim_end() == "```json-schema" => current = Some(String::new()),
            None => {}
            Some(_) if line.trim_end() == "```" => blocks.extend(current.take()),
            Some(block) => {
                block.push_str(line);
                block.push('\n');
            }
        }
    }
    if current.is_some() {
        return Err("a ```json-schema block is not closed".into());
    }
    match blocks.as_slice() {
        [one] => serde_json::from_str(one).map_err(|e| format!("the ```json-schema block: {e}")),
        [] => Err("no ```json-schema block".into()),
        more => Err(format!(
            "{} ```json-schema blocks; expected one",
            more.len()
        )),
    }
}

/// Every mismatch between `value` and `schema`, each naming its JSON path (`$.a.b[2]`). The
/// schema is a subset of JSON Schema draft 2020-12: `type` (a name or a list of names, with
/// `integer`), `properties`, `required`, `additionalProperties` (`false` or a schema), `items`,
/// `enum`, `oneOf` and `description`; any other keyword is reported as a mismatch, so the
/// documentation cannot use one that is not checked.
pub fn schema_errors(schema: &serde_json::Value, value: &serde_json::Value) -> Vec<String> {
    let mut errors = Vec::new();
    check_schema(schema, value, "$", &mut errors);
    errors
}

fn json_type_matches(name: &str, v: &serde_json::Value) -> Option<bool> {
    use serde_json::Value;
    Some(match name {
        "null" => v.is_null(),
        "boolean" => v.is_boolean(),
        "string" => v.is_string(),
        "number" => v.is_number(),
        "integer" => match v {
            Value::Number(n) => {
                n.is_i64() || n.is_u64() || n.as_f64().is_some_and(|f| f.fract() == 0.0)
            }
            _ => false,
        },
        "array" => v.is_array(),
        "object" => v.is_object(),
        _ => return None,
    })
}

fn json_type_name(v: &serde_json::Value) -> &'static str {
    use serde_json::Value;
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(n) if n.is_i64() || n.is_u64() => "integer",
        Value::Number(_) => "number",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

fn child_path(path: &str, key: &str) -> String {
    if !key.is_empty() && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        format!("{path}.{key}")
    } else {
        format!("{path}[{key:?}]")
    }
}

fn check_schema(
    schema: &serde_json::Value,
    value: &serde_json::Value,
    path: &str,
    errors: &mut Vec<String>,
) {
    use serde_json::Value;
    let s = match schema {
        Value::Bool(true) => return,
        Value::Bool(false) => {
            errors.push(format!("{path}: no value is allowed here"));
            return;
        }
        Value::Object(s) => s,
        other => {
            errors.push(format!(
                "{path}: schema is not an object or a boolean: {other}"
            ));
            return;
        }
    };
    for key in s.keys() {
        if !matches!(
            key.as_str(),
            "type"
                | "properties"
                | "required"
                | "additionalProperties"
                | "items"
                | "enum"
                | "oneOf"
                | "description"
                | "$schema"
                | "title"
        ) {
            errors.push(format!("{path}: schema keyword {key:?} is not supported"));
        }
    }
    if let Some(t) = s.get("type") {
        let names: Vec<&str> = match t {
            Value::String(n) => vec![n.as_str()],
            Value::Array(ns) => ns.iter().filter_map(Value::as_str).collect(),
            _ => Vec::new(),
        };
        let known: Vec<Option<bool>> = names.iter().map(|n| json_type_matches(n, value)).collect();
        if names.is_empty() || known.iter().any(Option::is_none) {
            errors.push(format!("{path}: schema \"type\" {t} names an unknown type"));
        } else if !known.contains(&Some(true)) {
            errors.push(format!(
                "{path}: expected {}, found {} ({})",
                names.join(" or "),
                json_type_name(value),
                short(value)
            ));
            // The other keywords describe a value of the right type; they would only repeat
            // the mismatch.
            return;
        }
    }
    if let Some(e) = s.get("enum") {
        match e.as_array() {
            Some(options) if options.contains(value) => {}
            Some(options) => errors.push(format!(
                "{path}: {} is not one of {}",
                short(value),
                Value::Array(options.clone())
            )),
            None => errors.push(format!("{path}: schema \"enum\" is not an array")),
        }
    }
    if let Some(alternatives) = s.get("oneOf") {
        let Some(alternatives) = alternatives.as_array() else {
            errors.push(format!("{path}: schema \"oneOf\" is not an array"));
            return;
        };
        let results: Vec<Vec<String>> = alternatives
            .iter()
            .map(|alt| {
                let mut e = Vec::new();
                check_schema(alt, value, path, &mut e);
                e
            })
            .collect();
        let matching = results.iter().filter(|e| e.is_empty()).count();
        if matching == 0 {
            let detail: Vec<String> = results
                .iter()
                .enumerate()
                .map(|(k, e)| format!("alternative {k}: {}", e.join("; ")))
                .collect();
            errors.push(format!(
                "{path}: matches none of the {} \"oneOf\" alternatives ({})",
                alternatives.len(),
                detail.join(" | ")
            ));
        } else if matching > 1 {
            errors.push(format!(
                "{path}: matches {matching} of the \"oneOf\" alternatives; exactly one must match"
            ));
        }
    }
    if let Value::Object(obj) = value {
        let props = s.get("properties").and_then(Value::as_object);
        if let Some(required) = s.get("required").and_then(Value::as_array) {
            for key in required.iter().filter_map(Value::as_str) {
                if !obj.contains_key(key) {
                    errors.push(format!("{}: required but missing", child_path(path, key)));
                }
            }
        }
        for (key, v) in obj {
            let here = child_path(path, key);
            match (
                props.and_then(|p| p.get(key)),
                s.get("additionalProperties"),
            ) {
                (Some(sub), _) => check_schema(sub, v, &here, errors),
                (None, Some(Value::Bool(false))) => errors.push(format!(
                    "{here}: not in the schema's \"properties\" (additionalProperties is false)"
                )),
                (None, Some(extra)) => check_schema(extra, v, &here, errors),
                (None, None) => {}
            }
        }
    }
    if let (Value::Array(items), Some(item_schema)) = (value, s.get("items")) {
        for (k, v) in items.iter().enumerate() {
            check_schema(item_schema, v, &format!("{path}[{k}]"), errors);
        }
    }
}

/// A value for a message, cut to a readable length.
fn short(v: &serde_json::Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 60 {
        format!("{}…", s.chars().take(60).collect::<String>())
    } else {
        s
    }
}

/// Generates a `mini` corpus campaign of `seed` into `camp`, its frames made by the
/// validator's own model (fast; for tests of plumbing, not of the gap or the gate's figures).
pub fn generate_mini(camp: &std::path::Path, seed: u64) {
    let out = regolith(&[
        "corpus",
        "generate",
        "--renderer",
        "model",
        "--preset",
        "mini",
        "--seed",
        &seed.to_string(),
        "--out",
        camp.to_str().unwrap(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The (entry, certificate id) pairs of a `validate --json` output.
pub fn certificate_ids(v: &serde_json::Value) -> Vec<(String, String)> {
    v["entries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["entry"].as_str().unwrap().to_string(),
                e["certificate"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}
