//! A small reader for the YAML subset that OpenCV FileStorage, ROS `camera_info` and Kalibr
//! write, plus the text-input helpers the other calibration and Vicon readers share.
//!
//! Why not a YAML crate: `serde_yaml` is deprecated and rejects OpenCV files outright
//! (`%YAML:1.0` is not a valid directive, `!!opencv-matrix` is an unknown tag, `data:[` has no
//! space after the colon). Those files use a tiny, regular part of YAML, so a line-based reader
//! of ~400 lines is simpler than patching a general parser, and it keeps a line number on every
//! node so errors say where the problem is (formats.md §13–15).
//!
//! Accepted: a first `%YAML...` line and `---` / `...` markers (stripped); comments; nested
//! maps by indentation; block sequences (`- item`, including `- key: value` maps); flow
//! sequences and maps (`[ ... ]`, `{ ... }`) spanning lines; `key:value` with no space (OpenCV
//! reads it, so do we); tags (`!!opencv-matrix`, `!<tag:yaml.org,2002:opencv-matrix>`), kept
//! on the node; single- and double-quoted scalars. Not accepted: anchors/aliases, block
//! scalars (`|`, `>`), multi-document streams. Everything else about scalars (numbers such as
//! `e+002`, `0.`) is left to the accessors, which also split a flow item on whitespace to
//! tolerate the missing commas ROS files sometimes have.

use std::path::Path;

use regolith_format::limits::Limits;

use crate::error::{IngestError, Result};

/// Deepest nesting accepted (guards the recursive parser against hostile input).
const MAX_DEPTH: usize = 64;

/// A parsed YAML node with the 1-based line it started on.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// 1-based line of the node's first character.
    pub line: u64,
    /// Tag without the `!!` / `!<...>` decoration, e.g. `opencv-matrix`.
    pub tag: Option<String>,
    /// The value.
    pub value: Value,
}

/// The value of a [`Node`].
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Empty value (`key:` with nothing below it).
    Null,
    /// A scalar, unquoted and with surrounding spaces removed.
    Scalar(String),
    /// A sequence.
    Seq(Vec<Node>),
    /// A mapping in file order.
    Map(Vec<(String, Node)>),
}

/// A row-major numeric matrix (`!!opencv-matrix`, ROS `{rows, cols, data}` or nested list).
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// `rows * cols` values, row-major.
    pub data: Vec<f64>,
}

impl Node {
    /// The value under `key` (exact match) when this node is a map.
    pub fn get(&self, key: &str) -> Option<&Node> {
        self.entries()
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v)
    }

    /// The first value whose key matches one of `aliases`, ignoring ASCII case.
    pub fn get_any(&self, aliases: &[&str]) -> Option<(&str, &Node)> {
        self.entries()
            .iter()
            .find(|(k, _)| aliases.iter().any(|a| k.eq_ignore_ascii_case(a)))
            .map(|(k, v)| (k.as_str(), v))
    }

    /// The map entries (empty for non-maps).
    pub fn entries(&self) -> &[(String, Node)] {
        match &self.value {
            Value::Map(m) => m,
            _ => &[],
        }
    }

    /// The scalar text, if this is a scalar.
    pub fn as_str(&self) -> Option<&str> {
        match &self.value {
            Value::Scalar(s) => Some(s),
            _ => None,
        }
    }

    /// The error for this node: `line N: expected ..., found ...`.
    pub fn error(&self, expected: &str) -> IngestError {
        let found = match &self.value {
            Value::Null => "nothing".to_string(),
            Value::Scalar(s) => s.clone(),
            Value::Seq(v) => format!("a list of {}", v.len()),
            Value::Map(_) => "a map".to_string(),
        };
        IngestError::syntax(expected, &found).at_line(self.line)
    }

    /// A finite number.
    pub fn as_f64(&self) -> Result<f64> {
        self.as_str()
            .and_then(parse_number)
            .ok_or_else(|| self.error("a finite number"))
    }

    /// A non-negative integer.
    pub fn as_u64(&self) -> Result<u64> {
        let v = self.as_f64()?;
        if v < 0.0 || v.fract() != 0.0 || v > 1e15 {
            return Err(self.error("a non-negative integer"));
        }
        Ok(v as u64)
    }

    /// All numbers of a (possibly nested) sequence, row-major; a scalar item holding several
    /// whitespace-separated numbers (a missing comma) contributes each of them.
    pub fn as_f64_list(&self) -> Result<Vec<f64>> {
        let mut out = Vec::new();
        self.collect_numbers(&mut out, 0)?;
        Ok(out)
    }

    fn collect_numbers(&self, out: &mut Vec<f64>, depth: usize) -> Result<()> {
        match &self.value {
            Value::Seq(items) if depth < MAX_DEPTH => {
                for it in items {
                    it.collect_numbers(out, depth + 1)?;
                }
                Ok(())
            }
            Value::Scalar(s) => {
                for tok in s.split_whitespace() {
                    out.push(parse_number(tok).ok_or_else(|| self.error("a finite number"))?);
                }
                Ok(())
            }
            _ => Err(self.error("a list of numbers")),
        }
    }

    /// A matrix: a `{rows, cols, data}` map (OpenCV or ROS), or a nested list of equal rows.
    pub fn as_matrix(&self) -> Result<Matrix> {
        match &self.value {
            Value::Map(_) => {
                let field = |k: &str| self.get(k).ok_or_else(|| self.error(&format!("`{k}`")));
                let rows = field("rows")?.as_u64()?;
                let cols = field("cols")?.as_u64()?;
                let channels = match self.get("dt").and_then(Node::as_str) {
                    Some(dt) => dt.trim_end_matches(|c: char| c.is_ascii_alphabetic()),
                    None => "",
                };
                let channels: u64 = if channels.is_empty() {
                    1
                } else {
                    channels.parse().unwrap_or(0)
                };
                let data = field("data")?.as_f64_list()?;
                let want = rows.saturating_mul(cols).saturating_mul(channels);
                if channels != 1 || data.len() as u64 != want {
                    return Err(IngestError::invalid(format!(
                        "matrix is {rows}x{cols} with {channels} channel(s) but `data` has {} values",
                        data.len()
                    ))
                    .at_line(self.line));
                }
                Ok(Matrix {
                    rows: rows as usize,
                    cols: cols as usize,
                    data,
                })
            }
            Value::Seq(items) if items.iter().any(|i| matches!(i.value, Value::Seq(_))) => {
                let mut data = Vec::new();
                let mut cols = None;
                for row in items {
                    let r = row.as_f64_list()?;
                    if *cols.get_or_insert(r.len()) != r.len() {
                        return Err(row.error("rows of equal length"));
                    }
                    data.extend(r);
                }
                Ok(Matrix {
                    rows: items.len(),
                    cols: cols.unwrap_or(0),
                    data,
                })
            }
            Value::Seq(_) => {
                let data = self.as_f64_list()?;
                Ok(Matrix {
                    rows: 1,
                    cols: data.len(),
                    data,
                })
            }
            _ => Err(self.error("a matrix")),
        }
    }
}

/// Parses a finite `f64` (accepts `0.`, `.5`, `e+002`); `None` for anything else.
pub fn parse_number(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

/// Reads a whole input file after checking its size against `limits.max_object_bytes`.
pub fn read_file(path: &Path, limits: &Limits) -> Result<Vec<u8>> {
    let len = std::fs::metadata(path).map_err(IngestError::from)?.len();
    Limits::check_len("input file bytes", len, limits.max_object_bytes)?;
    Ok(std::fs::read(path)?)
}

/// Decodes UTF-8 text, dropping a leading BOM; an invalid byte is an error at its offset.
pub fn decode_text(bytes: &[u8]) -> Result<&str> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    std::str::from_utf8(bytes).map_err(|e| {
        IngestError::syntax("UTF-8 text", "invalid byte").at_offset(e.valid_up_to() as u64)
    })
}

/// Reads `path` and runs `parse` on its bytes, naming the file in any error.
pub fn read_with<T>(
    path: &Path,
    limits: &Limits,
    parse: impl FnOnce(&[u8]) -> Result<T>,
) -> Result<T> {
    read_file(path, limits)
        .and_then(|b| parse(&b))
        .map_err(|e| e.in_file(path))
}

/// Parses a document; the root is a map (or `Null` for an empty document).
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<Node> {
    Limits::check_len("YAML bytes", bytes.len() as u64, limits.max_object_bytes)?;
    let text = decode_text(bytes)?;
    let mut lines = Vec::new();
    // Open `[`/`{` of a flow collection spanning lines: its continuation lines are not block
    // indentation, and OpenCV's data blocks may be indented with tabs there.
    let mut flow_depth = 0i64;
    for (i, raw) in text.lines().enumerate() {
        let no = i as u64 + 1;
        let body = strip_comment(raw).trim_end();
        let trimmed = body.trim_start();
        if (i == 0 && trimmed.starts_with("%YAML")) || trimmed.is_empty() || trimmed == "---" {
            continue;
        }
        if trimmed == "..." {
            break;
        }
        let continuation = flow_depth > 0;
        flow_depth = (flow_depth + bracket_depth(trimmed)).max(0);
        if !continuation
            && body.contains('\t')
            && body.starts_with(|c: char| c.is_whitespace())
            && !body.starts_with(' ')
        {
            return Err(IngestError::syntax("spaces for indentation", "a tab").at_line(no));
        }
        if trimmed.starts_with('%') || trimmed.starts_with("--- ") {
            return Err(
                IngestError::Unsupported("YAML directives or multiple documents".into())
                    .at_line(no),
            );
        }
        lines.push(Line {
            indent: body.len() - trimmed.len(),
            text: trimmed.to_string(),
            no,
        });
    }
    let mut p = Parser { lines, pos: 0 };
    let Some(first) = p.lines.first() else {
        return Ok(Node {
            line: 1,
            tag: None,
            value: Value::Null,
        });
    };
    let indent = first.indent;
    let root = p.block(indent, 0)?;
    if let Some(l) = p.lines.get(p.pos) {
        return Err(
            IngestError::syntax("a key at the indentation of its parent", &l.text).at_line(l.no),
        );
    }
    Ok(root)
}

/// Removes a `#` comment that starts the line or follows whitespace, outside quotes.
fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    let mut prev_space = true;
    for (i, c) in line.char_indices() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), _) if c == q => quote = None,
            (None, '#') if prev_space => return line.get(..i).unwrap_or(line),
            _ => {}
        }
        prev_space = c.is_whitespace();
    }
    line
}

#[derive(Debug)]
struct Line {
    indent: usize,
    text: String,
    no: u64,
}

struct Parser {
    lines: Vec<Line>,
    pos: usize,
}

fn is_seq_item(text: &str) -> bool {
    text == "-" || text.starts_with("- ")
}

impl Parser {
    fn current(&self) -> Option<&Line> {
        self.lines.get(self.pos)
    }

    /// A block (map or sequence) whose lines sit at exactly `indent`.
    fn block(&mut self, indent: usize, depth: usize) -> Result<Node> {
        let Some(line) = self.current() else {
            return Ok(Node {
                line: 0,
                tag: None,
                value: Value::Null,
            });
        };
        let no = line.no;
        if depth > MAX_DEPTH {
            return Err(IngestError::invalid("nesting too deep").at_line(no));
        }
        let value = if is_seq_item(&line.text) {
            self.seq(indent, depth)?
        } else {
            self.map(indent, depth)?
        };
        Ok(Node {
            line: no,
            tag: None,
            value,
        })
    }

    fn seq(&mut self, indent: usize, depth: usize) -> Result<Value> {
        let mut items = Vec::new();
        while let Some(line) = self.lines.get_mut(self.pos) {
            if line.indent != indent || !is_seq_item(&line.text) {
                break;
            }
            let rest = line.text.get(1..).unwrap_or("");
            let content = rest.trim_start();
            let no = line.no;
            if content.is_empty() {
                self.pos += 1;
                items.push(self.child(indent, no, depth)?);
            } else if is_plain_item(content) {
                let content = content.to_string();
                self.pos += 1;
                items.push(self.inline_value(&content, indent, no, depth)?);
            } else {
                // `- key: value`: the rest of the line starts a map indented past the dash.
                let new_indent = indent + 1 + rest.len() - content.len();
                line.indent = new_indent;
                line.text = content.to_string();
                items.push(self.block(new_indent, depth + 1)?);
            }
        }
        Ok(Value::Seq(items))
    }

    fn map(&mut self, indent: usize, depth: usize) -> Result<Value> {
        let mut entries: Vec<(String, Node)> = Vec::new();
        while let Some(line) = self.current() {
            if line.indent < indent {
                break;
            }
            if line.indent > indent || is_seq_item(&line.text) {
                return Err(IngestError::syntax(
                    "a key at the indentation of its parent",
                    &line.text,
                )
                .at_line(line.no));
            }
            let no = line.no;
            let (key, rest) = split_key(&line.text)
                .ok_or_else(|| IngestError::syntax("`key: value`", &line.text).at_line(no))?;
            let (key, rest) = (unquote(key).to_string(), rest.to_string());
            if entries.iter().any(|(k, _)| *k == key) {
                return Err(IngestError::invalid(format!("duplicate key `{key}`")).at_line(no));
            }
            self.pos += 1;
            let node = self.inline_value(&rest, indent, no, depth)?;
            entries.push((key, node));
        }
        Ok(Value::Map(entries))
    }

    /// The value written after `key:` or `- ` on line `no` (possibly continuing below).
    fn inline_value(&mut self, rest: &str, indent: usize, no: u64, depth: usize) -> Result<Node> {
        let (tag, rest) = split_tag(rest.trim());
        let mut node = if rest.is_empty() {
            // Errors about a block value point at its key's line.
            Node {
                line: no,
                ..self.child(indent, no, depth)?
            }
        } else if rest.starts_with('[') || rest.starts_with('{') {
            let mut text = rest.to_string();
            while !balanced(&text) {
                let Some(next) = self.current() else {
                    return Err(IngestError::syntax("a closing bracket", "end of file").at_line(no));
                };
                text.push(' ');
                text.push_str(&next.text);
                self.pos += 1;
            }
            let mut f = Flow {
                chars: text.chars().collect(),
                pos: 0,
                line: no,
            };
            let v = f.value(depth)?;
            f.skip_ws();
            if let Some(c) = f.chars.get(f.pos) {
                return Err(
                    IngestError::syntax("end of the flow value", &c.to_string()).at_line(no)
                );
            }
            v
        } else if rest.starts_with('|')
            || rest.starts_with('>')
            || rest.starts_with('&')
            || rest.starts_with('*')
        {
            return Err(
                IngestError::Unsupported("block scalars, anchors and aliases".into()).at_line(no),
            );
        } else {
            Node {
                line: no,
                tag: None,
                value: Value::Scalar(unquote(rest).to_string()),
            }
        };
        node.tag = tag.or(node.tag);
        Ok(node)
    }

    /// The block below a line that ended with `key:` / `-`; a sequence may sit at the
    /// parent's own indentation (`key:\n- a`).
    fn child(&mut self, indent: usize, no: u64, depth: usize) -> Result<Node> {
        match self.current() {
            Some(l) if l.indent > indent => {
                let i = l.indent;
                self.block(i, depth + 1)
            }
            Some(l) if l.indent == indent && is_seq_item(&l.text) => {
                let v = self.seq(indent, depth + 1)?;
                Ok(Node {
                    line: no,
                    tag: None,
                    value: v,
                })
            }
            _ => Ok(Node {
                line: no,
                tag: None,
                value: Value::Null,
            }),
        }
    }
}

/// A sequence item that is not itself a `key: value` map.
fn is_plain_item(content: &str) -> bool {
    content.starts_with(['[', '{', '"', '\'', '!']) || split_key(content).is_none()
}

/// Splits `key: value`, `key:value` (OpenCV) or `key:`; quoted keys allowed.
fn split_key(text: &str) -> Option<(&str, &str)> {
    if text.starts_with(['[', '{', '-']) && !text.starts_with("-.") {
        return None;
    }
    let pos = text
        .find(": ")
        .or_else(|| text.strip_suffix(':').map(|t| t.len()))
        .or_else(|| {
            // OpenCV's `data:[` and `Viewer.PointSize:2`: a colon right after an identifier.
            text.find(':').filter(|&i| {
                text.get(..i).is_some_and(|k| {
                    !k.is_empty() && k.chars().all(|c| c.is_alphanumeric() || "._-".contains(c))
                })
            })
        })?;
    let key = text.get(..pos)?.trim();
    let value = text.get(pos + 1..)?.trim();
    (!key.is_empty()).then_some((key, value))
}

fn split_tag(text: &str) -> (Option<String>, &str) {
    if let Some(rest) = text.strip_prefix("!<") {
        if let Some(end) = rest.find('>') {
            let tag = rest.get(..end).unwrap_or("");
            let tag = tag.rsplit(':').next().unwrap_or(tag);
            return (
                Some(tag.to_string()),
                rest.get(end + 1..).unwrap_or("").trim(),
            );
        }
    }
    if text.starts_with('!') {
        let end = text.find(char::is_whitespace).unwrap_or(text.len());
        let tag = text.get(..end).unwrap_or("").trim_start_matches('!');
        let tag = tag.strip_prefix("tag:yaml.org,2002:").unwrap_or(tag);
        return (Some(tag.to_string()), text.get(end..).unwrap_or("").trim());
    }
    (None, text)
}

fn unquote(s: &str) -> &str {
    let s = s.trim();
    for q in ['"', '\''] {
        if let Some(inner) = s.strip_prefix(q).and_then(|r| r.strip_suffix(q)) {
            return inner;
        }
    }
    s
}

/// True when every `[`/`{` outside quotes is closed (or over-closed: the flow parser reports it).
fn balanced(text: &str) -> bool {
    bracket_depth(text) <= 0
}

/// Opened minus closed `[`/`{` outside quotes.
fn bracket_depth(text: &str) -> i64 {
    let mut depth = 0i64;
    let mut quote = None;
    for c in text.chars() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), _) if c == q => quote = None,
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            _ => {}
        }
    }
    depth
}

/// Recursive-descent parser of one flow value (which may span joined lines).
struct Flow {
    chars: Vec<char>,
    pos: usize,
    line: u64,
}

impl Flow {
    fn peek(&self) -> Option<char> {
        self.chars.get(self.pos).copied()
    }
    fn skip_ws(&mut self) {
        while self.peek().is_some_and(char::is_whitespace) {
            self.pos += 1;
        }
    }
    fn err(&self, expected: &str) -> IngestError {
        let found: String = self.chars.iter().skip(self.pos).take(20).collect();
        IngestError::syntax(
            expected,
            if found.is_empty() {
                "end of line"
            } else {
                &found
            },
        )
        .at_line(self.line)
    }

    fn value(&mut self, depth: usize) -> Result<Node> {
        if depth > MAX_DEPTH {
            return Err(IngestError::invalid("nesting too deep").at_line(self.line));
        }
        self.skip_ws();
        let line = self.line;
        let (open, close) = match self.peek() {
            Some('[') => ('[', ']'),
            Some('{') => ('{', '}'),
            _ => {
                return Ok(Node {
                    line,
                    tag: None,
                    value: Value::Scalar(self.scalar()),
                })
            }
        };
        self.pos += 1;
        let mut items = Vec::new();
        let mut entries = Vec::new();
        loop {
            self.skip_ws();
            if self.peek() == Some(close) {
                self.pos += 1;
                break;
            }
            if open == '[' {
                items.push(self.value(depth + 1)?);
            } else {
                let key = self.scalar_until(&[':', ',', '}']);
                if self.peek() != Some(':') {
                    return Err(self.err("`:` after a flow-map key"));
                }
                self.pos += 1;
                entries.push((unquote(&key).to_string(), self.value(depth + 1)?));
            }
            self.skip_ws();
            match self.peek() {
                Some(',') => self.pos += 1,
                Some(c) if c == close => {}
                _ => return Err(self.err(&format!("`,` or `{close}`"))),
            }
        }
        let value = if open == '[' {
            Value::Seq(items)
        } else {
            Value::Map(entries)
        };
        Ok(Node {
            line,
            tag: None,
            value,
        })
    }

    fn scalar(&mut self) -> String {
        self.skip_ws();
        if let Some(q @ ('"' | '\'')) = self.peek() {
            self.pos += 1;
            let start = self.pos;
            while self.peek().is_some_and(|c| c != q) {
                self.pos += 1;
            }
            let s: String = self
                .chars
                .get(start..self.pos)
                .unwrap_or(&[])
                .iter()
                .collect();
            self.pos += 1;
            return s;
        }
        self.scalar_until(&[',', ']', '}'])
    }

    fn scalar_until(&mut self, stops: &[char]) -> String {
        let start = self.pos;
        while self.peek().is_some_and(|c| !stops.contains(&c)) {
            self.pos += 1;
        }
        self.chars
            .get(start..self.pos)
            .unwrap_or(&[])
            .iter()
            .collect::<String>()
            .trim()
            .to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc(s: &str) -> Node {
        parse(s.as_bytes(), &Limits::default()).unwrap()
    }

    #[test]
    fn opencv_matrix_with_wrapped_data_and_old_exponents() {
        let d = doc("%YAML:1.0\n---\nK: !!opencv-matrix\n   rows: 1\n   cols: 3\n   dt: d\n   data: [ 6.5e+002, 0.,\n       3.1950000000000000e+002 ]\nn: 5 # comment\n");
        let k = d.get("K").unwrap();
        assert_eq!(k.tag.as_deref(), Some("opencv-matrix"));
        assert_eq!(
            k.as_matrix().unwrap(),
            Matrix {
                rows: 1,
                cols: 3,
                data: vec![650.0, 0.0, 319.5]
            }
        );
        assert_eq!(d.get("n").unwrap().as_u64().unwrap(), 5);
    }

    #[test]
    fn no_space_after_colon_and_expanded_tag() {
        let d = doc(
            "A: !<tag:yaml.org,2002:opencv-matrix>\n  rows: 1\n  cols: 2\n  data:[1, 2]\nB:3\n",
        );
        assert_eq!(d.get("A").unwrap().tag.as_deref(), Some("opencv-matrix"));
        assert_eq!(
            d.get("A").unwrap().as_matrix().unwrap().data,
            vec![1.0, 2.0]
        );
        assert_eq!(d.get("B").unwrap().as_f64().unwrap(), 3.0);
    }

    #[test]
    fn block_sequences_of_flow_rows_and_maps() {
        let d = doc("cam1:\n  T:\n  - [1, 0, 0, 0.5]\n  - [0, 1, 0, 0]\n  items:\n    - name: a\n      v: 1\n    - b\n");
        let t = d
            .get("cam1")
            .unwrap()
            .get("T")
            .unwrap()
            .as_matrix()
            .unwrap();
        assert_eq!((t.rows, t.cols), (2, 4));
        assert_eq!(t.data.get(3), Some(&0.5));
        let items = d.get("cam1").unwrap().get("items").unwrap();
        let Value::Seq(v) = &items.value else {
            panic!("{items:?}")
        };
        assert_eq!(v[0].get("v").unwrap().as_f64().unwrap(), 1.0);
        assert_eq!(v[1].as_str(), Some("b"));
    }

    #[test]
    fn missing_comma_is_tolerated_and_bad_number_names_line() {
        let d = doc("data: [0., 410.2 459.8,\n  1.]\nx: abc\n");
        assert_eq!(
            d.get("data").unwrap().as_f64_list().unwrap(),
            vec![0.0, 410.2, 459.8, 1.0]
        );
        let e = d.get("x").unwrap().as_f64().unwrap_err().to_string();
        assert_eq!(e, "line 3: expected a finite number, found \"abc\"");
    }

    #[test]
    fn errors_never_panic_on_unclosed_or_bad_indentation() {
        let l = Limits::default();
        assert!(parse(b"a: [1, 2", &l)
            .unwrap_err()
            .to_string()
            .contains("line 1"));
        assert!(parse(b"a: 1\n   b: 2\n", &l)
            .unwrap_err()
            .to_string()
            .contains("line 2"));
        assert!(parse(b"a: 1\na: 2\n", &l)
            .unwrap_err()
            .to_string()
            .contains("duplicate key"));
        assert_eq!(parse(b"", &l).unwrap().value, Value::Null);
    }
}
