//! OpenCV FileStorage JSON (OpenCV ≥ 3.2 writes it for a `.json` file name; formats.md §13) →
//! the same [`yaml_lite::Node`] tree the YAML and XML forms produce, so
//! [`super::calib_opencv`] interprets all three with one set of key aliases.
//!
//! `cv::FileStorage` writes `{"camera_matrix": {"type_id": "opencv-matrix", "rows": 3,
//! "cols": 3, "dt": "d", "data": [ ... ]}, "image_width": 640, ...}`. Design decisions:
//! - `serde_json` parses, but not into `serde_json::Value`: that map is sorted (cameras must
//!   stay in file order) and carries no position, while every error here names a line. Each
//!   level is read as ordered `(key, &RawValue)` pairs; a raw value borrows the input, so its
//!   byte offset, hence its line, is known. A nested value is parsed again from its raw text,
//!   at most [`MAX_DEPTH`] levels deep (serde_json itself stops at 128).
//! - `type_id` becomes the node's tag (as the XML reader does with the attribute), numbers keep
//!   their text (`yaml_lite` accessors parse it), strings are unescaped, `null` is
//!   [`Value::Null`]; a repeated key keeps its first value.

use std::fmt;

use regolith_format::limits::Limits;
use serde::de::{Deserialize, Deserializer, MapAccess, Visitor};
use serde_json::value::RawValue;

use super::yaml_lite::{self, Node, Value};
use crate::error::{IngestError, Result};

/// Deepest nesting accepted.
pub const MAX_DEPTH: usize = 64;

/// Whether the text looks like JSON (first non-blank character `{`).
pub fn is_json(bytes: &[u8]) -> bool {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    bytes
        .iter()
        .find(|b| !b.is_ascii_whitespace())
        .is_some_and(|b| *b == b'{')
}

/// Parses a FileStorage JSON document; the root must be an object.
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<Node> {
    Limits::check_len("JSON bytes", bytes.len() as u64, limits.max_object_bytes)?;
    let text = yaml_lite::decode_text(bytes)?;
    let doc = Doc {
        text,
        newlines: text
            .bytes()
            .enumerate()
            .filter(|(_, b)| *b == b'\n')
            .map(|(i, _)| i)
            .collect(),
    };
    let root: &RawValue = serde_json::from_str(text).map_err(|e| json_err(&e, 1))?;
    if !root.get().starts_with('{') {
        return Err(
            IngestError::syntax("a JSON object `{...}` at the top level", root.get())
                .at_line(doc.line(root)),
        );
    }
    doc.node(root, 0)
}

/// The input text with the offsets of its newlines (for lines by binary search).
struct Doc<'a> {
    text: &'a str,
    newlines: Vec<usize>,
}

impl<'a> Doc<'a> {
    /// 1-based line of a raw value borrowed from `text`.
    fn line(&self, raw: &RawValue) -> u64 {
        let offset = (raw.get().as_ptr() as usize).wrapping_sub(self.text.as_ptr() as usize);
        let offset = offset.min(self.text.len());
        self.newlines.partition_point(|&n| n < offset) as u64 + 1
    }

    fn node(&self, raw: &'a RawValue, depth: usize) -> Result<Node> {
        let line = self.line(raw);
        if depth > MAX_DEPTH {
            return Err(IngestError::invalid(format!(
                "JSON nested deeper than {MAX_DEPTH} levels"
            ))
            .at_line(line));
        }
        let text = raw.get();
        let mut tag = None;
        let value = match text.as_bytes().first() {
            Some(b'{') => {
                let entries: Entries<'a> =
                    serde_json::from_str(text).map_err(|e| json_err(&e, line))?;
                let mut map: Vec<(String, Node)> = Vec::new();
                for (k, v) in entries.0 {
                    if k == "type_id" {
                        let t: Option<String> = serde_json::from_str(v.get()).ok();
                        tag = tag.or(t);
                    } else if !map.iter().any(|(old, _)| *old == k) {
                        map.push((k, self.node(v, depth + 1)?));
                    }
                }
                Value::Map(map)
            }
            Some(b'[') => {
                let items: Vec<&'a RawValue> =
                    serde_json::from_str(text).map_err(|e| json_err(&e, line))?;
                let nodes = items.into_iter().map(|v| self.node(v, depth + 1));
                Value::Seq(nodes.collect::<Result<_>>()?)
            }
            Some(b'"') => {
                Value::Scalar(serde_json::from_str(text).map_err(|e| json_err(&e, line))?)
            }
            _ if text == "null" => Value::Null,
            _ => Value::Scalar(text.to_string()),
        };
        Ok(Node { line, tag, value })
    }
}

/// A serde_json error at its line (`base` = line where the parsed text starts).
fn json_err(e: &serde_json::Error, base: u64) -> IngestError {
    let msg = e.to_string();
    let what = msg.split(" at line ").next().unwrap_or(&msg);
    IngestError::syntax("well-formed JSON", what).at_line(base + (e.line() as u64).max(1) - 1)
}

/// The entries of a JSON object in file order, values left raw.
struct Entries<'a>(Vec<(String, &'a RawValue)>);

impl<'de> Deserialize<'de> for Entries<'de> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Entries<'de>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                mut m: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let mut out = Vec::new();
                while let Some(entry) = m.next_entry::<String, &'de RawValue>()? {
                    out.push(entry);
                }
                Ok(Entries(out))
            }
        }
        d.deserialize_map(V)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_lines_tags_and_errors() {
        let l = Limits::default();
        let j = "{\n  \"b\": 1,\n  \"a\": {\"type_id\": \"opencv-matrix\", \"rows\": 1,\n \"cols\": 2, \"dt\": \"d\", \"data\": [ 1.5, -2e+02 ]},\n  \"s\": \"x\\\"y\", \"n\": null, \"b\": 7\n}";
        let n = parse(j.as_bytes(), &l).unwrap();
        let keys: Vec<_> = n.entries().iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(keys, ["b", "a", "s", "n"]);
        let a = n.get("a").unwrap();
        assert_eq!((a.line, a.tag.as_deref()), (3, Some("opencv-matrix")));
        assert_eq!(a.as_matrix().unwrap().data, vec![1.5, -200.0]);
        assert_eq!(a.get("data").unwrap().line, 4);
        assert_eq!(n.get("s").unwrap().as_str(), Some("x\"y"));
        assert_eq!(n.get("b").unwrap().as_f64().unwrap(), 1.0);
        let e = parse(b"{\n \"a\": [1, 2,\n }", &l).unwrap_err().to_string();
        assert!(e.starts_with("line 3: expected well-formed JSON"), "{e}");
        let deep = format!("{{\"a\":{}1{}}}", "[".repeat(100), "]".repeat(100));
        let e = parse(deep.as_bytes(), &l).unwrap_err().to_string();
        assert!(e.contains("deeper than 64"), "{e}");
        assert!(parse(b"[1]", &l).is_err() && !is_json(b" [1]") && is_json(b"\n {"));
    }
}
