//! RiSCAN PRO `project.rsp` project XML (formats.md §1.2): the project's POP matrix, and per
//! scan position its SOP matrix and its `<tp_socs>` tie points.
//!
//! Design decisions:
//! - `roxmltree` with `allow_dtd` (real files carry `<!DOCTYPE project SYSTEM "./project.dtd">`)
//!   and no entity resolver, so the external DTD is never fetched or read; roxmltree's own
//!   entity-loop checks and a node limit derived from [`Limits`] bound hostile input.
//! - Elements are found by tag name, not by fixed paths: RiSCAN versions nest scan positions
//!   under different folders (`SCANPOSITIONS`, `scanpositions`), but the tags are stable.
//! - Matrices go through [`super::sop_dat::detect_convention`]; RiSCAN writes them for column
//!   vectors (translation in elements 3, 7, 11), which the check confirms.
//! - A missing POP or SOP is `None`, not identity: an unregistered position must not look
//!   registered. Duplicate tie-point names within a position are an error.
//! - Errors carry the XML line of the offending element.

use std::collections::BTreeSet;
use std::path::Path;

use regolith_format::limits::Limits;
use roxmltree::{Document, Node, ParsingOptions};

use super::riscan_ascii::{fields, number, read_file, Delim};
use super::sop_dat::{detect_convention, matrix_from_numbers};
use super::types::{Matrix4, NamedPoint};
use crate::error::{IngestError, Result};

/// One scan position of a RiSCAN project.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanPosition {
    /// Scan-position name (`SP01`, `ScanPos057`).
    pub name: String,
    /// SOP (SOCS → PRCS), column-vector form; `None` when the file has none.
    pub sop: Option<Matrix4>,
    /// Tie points measured in this position's scanner frame (SOCS), metres.
    pub tie_points: Vec<NamedPoint>,
}

/// What regolith takes from a `project.rsp`.
#[derive(Debug, Clone, PartialEq)]
pub struct RspProject {
    /// Project name attribute.
    pub name: String,
    /// POP (PRCS → GLCS), column-vector form; `None` when the file has none.
    pub pop: Option<Matrix4>,
    /// Scan positions in file order.
    pub scan_positions: Vec<ScanPosition>,
}

fn line_of(node: &Node<'_, '_>) -> u64 {
    u64::from(node.document().text_pos_at(node.range().start).row)
}

fn child<'a, 'i>(node: &Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|n| n.has_tag_name(tag))
}

/// The 16 numbers of `<matrix rows="4" cols="4">` inside `owner`, in column-vector form.
fn matrix_in(owner: &Node<'_, '_>, what: &str) -> Result<Matrix4> {
    let Some(node) = child(owner, "matrix") else {
        return Err(
            IngestError::syntax(format!("a <matrix> in {what}"), "none").at_line(line_of(owner))
        );
    };
    let at = |e: IngestError| e.at_line(line_of(&node));
    for attr in ["rows", "cols"] {
        if let Some(v) = node.attribute(attr).filter(|v| v.trim() != "4") {
            return Err(at(IngestError::syntax(
                format!("{attr}=\"4\" on the {what} matrix"),
                v,
            )));
        }
    }
    let text = node.text().unwrap_or_default();
    let values = fields(text.as_bytes(), Delim::Whitespace)
        .map(|f| number(f, &format!("an element of the {what} matrix")))
        .collect::<Result<Vec<_>>>()
        .map_err(at)?;
    matrix_from_numbers(&values)
        .and_then(detect_convention)
        .map_err(at)
}

fn vector_in(owner: &Node<'_, '_>, what: &str) -> Result<[f64; 3]> {
    let node = child(owner, "vector");
    let at = |e: IngestError| e.at_line(line_of(&node.unwrap_or(*owner)));
    let text = node.and_then(|n| n.text()).unwrap_or_default();
    let values = fields(text.as_bytes(), Delim::Whitespace)
        .map(|f| number(f, &format!("a coordinate of {what}")))
        .collect::<Result<Vec<_>>>()
        .map_err(at)?;
    match values.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(at(IngestError::syntax(
            format!("<vector> with 3 numbers in {what}"),
            text.trim(),
        ))),
    }
}

fn tie_points(position: &Node<'_, '_>, pos_name: &str, limits: &Limits) -> Result<Vec<NamedPoint>> {
    let mut out = Vec::new();
    let mut names = BTreeSet::new();
    for tp in position.descendants().filter(|n| n.has_tag_name("tp_socs")) {
        let name = child(&tp, "name")
            .and_then(|n| n.text())
            .or_else(|| tp.attribute("name"));
        let Some(name) = name.map(str::trim).filter(|n| !n.is_empty()) else {
            return Err(IngestError::syntax("a <name> in <tp_socs>", "none").at_line(line_of(&tp)));
        };
        let xyz = vector_in(&tp, &format!("tie point {name:?} of {pos_name}"))?;
        if !names.insert(name.to_string()) {
            let msg = format!("duplicate tie-point name {name:?} in scan position {pos_name:?}");
            return Err(IngestError::invalid(msg).at_line(line_of(&tp)));
        }
        Limits::check_len("tie points", out.len() as u64 + 1, limits.max_points)?;
        out.push(NamedPoint {
            name: name.to_string(),
            xyz,
        });
    }
    Ok(out)
}

/// Parses `project.rsp` text.
pub fn read_rsp(bytes: &[u8], limits: &Limits) -> Result<RspProject> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        IngestError::syntax("UTF-8 XML text", "invalid UTF-8").at_offset(e.valid_up_to() as u64)
    })?;
    let nodes_limit = u32::try_from(limits.max_points.min(u64::from(u32::MAX))).unwrap_or(u32::MAX);
    let opts = ParsingOptions {
        allow_dtd: true,
        nodes_limit,
        entity_resolver: None,
    };
    let doc = Document::parse_with_options(text, opts).map_err(|e| {
        let pos = e.pos();
        IngestError::syntax("well-formed XML", &e.to_string()).at_line(u64::from(pos.row))
    })?;
    let root = doc.root_element();
    if !root.has_tag_name("project") {
        return Err(
            IngestError::syntax("a <project> root element", root.tag_name().name())
                .at_line(line_of(&root)),
        );
    }
    let pop = match root.descendants().find(|n| n.has_tag_name("pop")) {
        Some(node) => Some(matrix_in(&node, "POP")?),
        None => None,
    };
    let mut scan_positions = Vec::new();
    for sp in root
        .descendants()
        .filter(|n| n.has_tag_name("scanposition"))
    {
        let name = sp.attribute("name").unwrap_or_default().to_string();
        let sop = match child(&sp, "sop") {
            Some(node) => Some(matrix_in(&node, &format!("SOP of {name}"))?),
            None => None,
        };
        let tie_points = tie_points(&sp, &name, limits)?;
        scan_positions.push(ScanPosition {
            name,
            sop,
            tie_points,
        });
    }
    Ok(RspProject {
        name: root.attribute("name").unwrap_or_default().to_string(),
        pop,
        scan_positions,
    })
}

/// Reads `project.rsp` from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<RspProject> {
    let bytes = read_file(path, limits)?;
    read_rsp(&bytes, limits).map_err(|e| e.in_file(path))
}
