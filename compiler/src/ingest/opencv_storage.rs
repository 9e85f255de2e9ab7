//! OpenCV FileStorage (`cv::FileStorage`): the one reader of its three forms — YAML
//! (`%YAML:1.0`, `!!opencv-matrix`), XML (`<opencv_storage>`, `type_id="opencv-matrix"`) and
//! JSON — into one [`Node`] tree (formats.md §13). Calibrations ([`super::calib_opencv`]) and
//! homographies ([`super::homography`]) both read through it, so a file OpenCV writes is read
//! the same way whatever it holds and whatever its form.
//!
//! The form is told from the content, not the file name: a leading `<` is XML, a leading `{`
//! JSON, anything else YAML. XML matrices become `{rows, cols, dt, data}` maps like the YAML
//! and JSON ones; the whitespace of an XML `<data>` block (OpenCV indents it with tabs) is a
//! separator.

use std::path::Path;

use regolith_format::limits::Limits;

use super::opencv_json;
use super::yaml_lite::{self, Matrix, Node, Value};
use crate::error::{IngestError, Result};

/// Reads a FileStorage file of any form; errors name the file.
pub fn read_path(path: &Path, limits: &Limits) -> Result<Node> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Parses YAML, XML (detected by a leading `<`) or JSON (a leading `{`).
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<Node> {
    if is_xml(bytes) {
        xml_tree(bytes, limits)
    } else if opencv_json::is_json(bytes) {
        opencv_json::parse(bytes, limits)
    } else {
        yaml_lite::parse(bytes, limits)
    }
}

/// Whether the text looks like XML (first non-blank character `<`).
pub fn is_xml(bytes: &[u8]) -> bool {
    let t = yaml_lite::decode_text(bytes).unwrap_or("");
    t.trim_start().starts_with('<')
}

/// Every top-level matrix of a FileStorage root, with its key, in file order. Entries that are
/// not matrices are skipped; a matrix whose `data` disagrees with its size is an error.
pub fn matrices(root: &Node) -> Result<Vec<(&str, Matrix)>> {
    let mut out = Vec::new();
    for (key, node) in root.entries() {
        let is_matrix = node
            .tag
            .as_deref()
            .is_some_and(|t| t.contains("opencv-matrix"))
            || matches!(&node.value, Value::Map(_)) && node.get("data").is_some();
        if is_matrix {
            out.push((key.as_str(), node.as_matrix()?));
        }
    }
    Ok(out)
}

/// Converts `<opencv_storage>` into a node tree: matrices become `{rows, cols, dt, data}`
/// maps, elements with children become maps, others scalars.
pub fn xml_tree(bytes: &[u8], limits: &Limits) -> Result<Node> {
    Limits::check_len("XML bytes", bytes.len() as u64, limits.max_object_bytes)?;
    let text = yaml_lite::decode_text(bytes)?;
    let doc = roxmltree::Document::parse(text).map_err(|e| {
        IngestError::syntax("well-formed XML", &e.to_string()).at_line(u64::from(e.pos().row))
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "opencv_storage" {
        return Err(IngestError::syntax("<opencv_storage>", root.tag_name().name()).at_line(1));
    }
    Ok(xml_node(&doc, root, 0))
}

fn xml_node(doc: &roxmltree::Document<'_>, el: roxmltree::Node<'_, '_>, depth: usize) -> Node {
    let line = u64::from(doc.text_pos_at(el.range().start).row);
    let children: Vec<_> = el.children().filter(roxmltree::Node::is_element).collect();
    let text = el.text().unwrap_or("").trim();
    let value = if el.tag_name().name() == "data"
        && el
            .parent_element()
            .is_some_and(|p| p.attribute("type_id").is_some())
    {
        let items = text.split_whitespace().map(|t| Node {
            line,
            tag: None,
            value: Value::Scalar(t.into()),
        });
        Value::Seq(items.collect())
    } else if children.is_empty() || depth > 32 {
        Value::Scalar(text.to_string())
    } else {
        let mut entries: Vec<(String, Node)> = Vec::new();
        for c in children {
            let name = c.tag_name().name().to_string();
            if !entries.iter().any(|(k, _)| *k == name) {
                entries.push((name, xml_node(doc, c, depth + 1)));
            }
        }
        Value::Map(entries)
    };
    let tag = el.attribute("type_id").map(str::to_string);
    Node { line, tag, value }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    const XML: &str = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<H type_id=\"opencv-matrix\">\n  <rows>2</rows>\n  <cols>2</cols>\n  <dt>d</dt>\n  <data>\n\t1.5e+00  -2.\n\t3 4 </data></H>\n</opencv_storage>\n";
    const YAML: &str = "%YAML:1.0\n---\nH: !!opencv-matrix\n   rows: 2\n   cols: 2\n   dt: d\n   data: [ 1.5, -2.,\n\t3, 4 ]\n";
    const JSON: &str = "{\n  \"H\": {\"type_id\": \"opencv-matrix\", \"rows\": 2, \"cols\": 2, \"dt\": \"d\",\n  \"data\": [1.5, -2.0, 3, 4]}\n}\n";

    #[test]
    fn the_three_forms_give_the_same_matrix() {
        for text in [XML, YAML, JSON] {
            let root = parse(text.as_bytes(), &Limits::default()).unwrap();
            let m = matrices(&root).unwrap();
            assert_eq!(m.len(), 1, "{text}");
            assert_eq!(m[0].0, "H");
            assert_eq!((m[0].1.rows, m[0].1.cols), (2, 2));
            assert_eq!(m[0].1.data, vec![1.5, -2.0, 3.0, 4.0], "{text}");
        }
    }

    #[test]
    fn a_tab_before_a_block_key_is_still_refused_with_its_line() {
        let err = parse(b"%YAML:1.0\nH:\n\trows: 2\n", &Limits::default()).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("line 3") && msg.contains("tab"), "{msg}");
    }

    #[test]
    fn a_matrix_with_too_few_values_is_an_error() {
        let bad = XML.replace("3 4 ", "3 ");
        let root = parse(bad.as_bytes(), &Limits::default()).unwrap();
        let msg = matrices(&root).unwrap_err().to_string();
        assert!(msg.contains("2x2") && msg.contains("3 values"), "{msg}");
    }
}
