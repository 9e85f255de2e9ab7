//! The generic VRML node tree: a node is a type name plus `field -> value` pairs, a value a bag
//! of numbers, strings, words and nodes, so no field-type table is needed. Node types outside
//! [`KNOWN`] are skipped by balanced braces (their `DEF` names resolve to "skipped").

use std::collections::{HashMap, VecDeque};
use std::rc::Rc;

use super::lexer::{Lexer, PResult, Tok, Token};
use super::{KNOWN, MAX_DEPTH};
use crate::error::IngestError;

/// A parsed node: type name and fields in file order. Skipped (unknown) nodes have no fields.
#[derive(Debug, Default)]
pub(super) struct Node {
    pub(super) kind: String,
    pub(super) fields: Vec<(String, Value)>,
}

/// A field value: whatever the file put there.
#[derive(Debug, Default)]
pub(super) struct Value {
    pub(super) offset: usize,
    pub(super) nums: Vec<f64>,
    pub(super) strs: Vec<String>,
    pub(super) words: Vec<String>,
    pub(super) nodes: Vec<Rc<Node>>,
}

impl Node {
    pub(super) fn field(&self, name: &str) -> Option<&Value> {
        self.fields
            .iter()
            .rev()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v)
    }
    pub(super) fn node(&self, name: &str) -> Option<&Rc<Node>> {
        self.field(name).and_then(|v| v.nodes.first())
    }
    pub(super) fn nums(&self, name: &str) -> Option<&Value> {
        self.field(name).filter(|v| !v.nums.is_empty())
    }
    pub(super) fn vec<const N: usize>(&self, name: &str, default: [f64; N]) -> [f64; N] {
        let mut out = default;
        if let Some(v) = self.field(name) {
            for (o, n) in out.iter_mut().zip(&v.nums) {
                *o = *n;
            }
        }
        out
    }
    pub(super) fn flag(&self, name: &str, default: bool) -> bool {
        match self.field(name).and_then(|v| v.words.first()) {
            Some(w) => w == "TRUE",
            None => default,
        }
    }
}

pub(super) struct Parser<'a> {
    pub(super) lex: Lexer<'a>,
    pub(super) ahead: VecDeque<Token<'a>>,
    /// `DEF` names; `None` for nodes that were skipped.
    pub(super) defs: HashMap<String, Option<Rc<Node>>>,
}

impl<'a> Parser<'a> {
    fn peek(&mut self, k: usize) -> PResult<Option<&Token<'a>>> {
        while self.ahead.len() <= k {
            match self.lex.next_token()? {
                Some(t) => self.ahead.push_back(t),
                None => break,
            }
        }
        Ok(self.ahead.get(k))
    }

    fn next(&mut self) -> PResult<Token<'a>> {
        self.peek(0)?;
        let end = self.lex.pos;
        self.ahead
            .pop_front()
            .ok_or((end, IngestError::syntax("more input", "end of file")))
    }

    fn word(&mut self, what: &str) -> PResult<(usize, &'a str)> {
        match self.next()? {
            (off, Tok::Word(w)) => Ok((off, w)),
            (off, t) => Err((off, IngestError::syntax(what, &format!("{t:?}")))),
        }
    }

    fn expect(&mut self, tok: Tok<'a>) -> PResult<()> {
        let (off, t) = self.next()?;
        if t != tok {
            return Err((
                off,
                IngestError::syntax(format!("{tok:?}"), &format!("{t:?}")),
            ));
        }
        Ok(())
    }

    pub(super) fn parse_file(&mut self) -> PResult<Vec<Rc<Node>>> {
        let mut roots = Vec::new();
        while self.peek(0)?.is_some() {
            if !self.statement()? {
                roots.extend(self.node(0)?);
            }
        }
        Ok(roots)
    }

    /// Skips `ROUTE`, `PROTO` and `EXTERNPROTO`; returns whether one was consumed.
    fn statement(&mut self) -> PResult<bool> {
        let Some((_, Tok::Word(w))) = self.peek(0)?.cloned() else {
            return Ok(false);
        };
        match w {
            "ROUTE" => {
                for _ in 0..4 {
                    self.next()?;
                }
            }
            "PROTO" | "EXTERNPROTO" => {
                self.next()?;
                self.word("a PROTO name")?;
                self.skip_balanced()?;
                if w == "PROTO" {
                    self.skip_balanced()?;
                } else if let Some((_, Tok::Str(_))) = self.peek(0)? {
                    self.next()?;
                } else {
                    self.skip_balanced()?;
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// Skips one `{...}` or `[...]` group, recording `DEF` names inside as skipped.
    fn skip_balanced(&mut self) -> PResult<()> {
        let mut depth = 0usize;
        loop {
            let (off, t) = self.next()?;
            match t {
                Tok::Open | Tok::LBracket => depth += 1,
                _ if depth == 0 => {
                    return Err((off, IngestError::syntax("'{' or '['", &format!("{t:?}"))))
                }
                Tok::Close | Tok::RBracket => depth -= 1,
                Tok::Word("DEF") => {
                    let (_, name) = self.word("a DEF name")?;
                    self.defs.insert(name.to_string(), None);
                }
                _ => {}
            }
            if depth == 0 {
                return Ok(());
            }
        }
    }

    /// `DEF name Node`, `USE name`, `NULL` or `Type { ... }`; `None` for NULL and skipped nodes.
    fn node(&mut self, depth: usize) -> PResult<Option<Rc<Node>>> {
        let (off, w) = self.word("a node type, DEF, USE or NULL")?;
        if depth > MAX_DEPTH {
            return Err((
                off,
                IngestError::invalid(format!("nodes nested deeper than {MAX_DEPTH}")),
            ));
        }
        match w {
            "NULL" => Ok(None),
            "USE" => {
                let (off, name) = self.word("a USE name")?;
                match self.defs.get(name) {
                    Some(n) => Ok(n.clone()),
                    None => Err((
                        off,
                        IngestError::invalid(format!("USE {name}: no DEF {name} before it")),
                    )),
                }
            }
            "DEF" => {
                let (_, name) = self.word("a DEF name")?;
                let n = self.node(depth)?;
                self.defs.insert(name.to_string(), n.clone());
                Ok(n)
            }
            kind => {
                if !KNOWN.contains(&kind) {
                    self.skip_balanced()?;
                    return Ok(None);
                }
                self.expect(Tok::Open)?;
                let mut node = Node {
                    kind: kind.to_string(),
                    fields: Vec::new(),
                };
                loop {
                    if let Some((_, Tok::Close)) = self.peek(0)? {
                        self.next()?;
                        return Ok(Some(Rc::new(node)));
                    }
                    if self.statement()? {
                        continue;
                    }
                    let (_, field) = self.word("a field name or '}'")?;
                    let value = self.value(depth + 1)?;
                    node.fields.push((field.to_string(), value));
                }
            }
        }
    }

    fn starts_node(&mut self) -> PResult<bool> {
        let Some((_, Tok::Word(w))) = self.peek(0)?.cloned() else {
            return Ok(false);
        };
        Ok(matches!(w, "DEF" | "USE" | "NULL") || matches!(self.peek(1)?, Some((_, Tok::Open))))
    }

    fn value(&mut self, depth: usize) -> PResult<Value> {
        let end = self.lex.pos;
        let offset = self.peek(0)?.map_or(end, |t| t.0);
        let mut v = Value {
            offset,
            ..Value::default()
        };
        let list = matches!(self.peek(0)?, Some((_, Tok::LBracket)));
        if list {
            self.next()?;
        }
        loop {
            if self.starts_node()? {
                v.nodes.extend(self.node(depth)?);
            } else {
                match self.peek(0)?.cloned() {
                    Some((_, Tok::RBracket)) if list => {
                        self.next()?;
                        return Ok(v);
                    }
                    Some((_, Tok::Str(s))) => {
                        self.next()?;
                        v.strs.push(s);
                    }
                    Some((off, Tok::Word(w))) => {
                        let num = number(w);
                        if num.is_none()
                            && w.starts_with(|c: char| c.is_ascii_digit() || "+-.".contains(c))
                        {
                            return Err((off, IngestError::syntax("a number", w)));
                        }
                        if !list && num.is_none() && !v.nums.is_empty() {
                            return Ok(v); // the next field name ends a run of numbers
                        }
                        self.next()?;
                        match num {
                            Some(n) => v.nums.push(n),
                            None if list || v.words.is_empty() => v.words.push(w.to_string()),
                            None => return Err((off, IngestError::syntax("a value", w))),
                        }
                    }
                    Some((off, t)) => {
                        return Err((off, IngestError::syntax("a field value", &format!("{t:?}"))))
                    }
                    None => {
                        return Err((self.lex.pos, IngestError::syntax("a value", "end of file")))
                    }
                }
            }
            if !list && (!v.words.is_empty() || !v.strs.is_empty() || !v.nodes.is_empty()) {
                return Ok(v);
            }
            if !list && !matches!(self.peek(0)?, Some((_, Tok::Word(w))) if number(w).is_some()) {
                return Ok(v);
            }
        }
    }
}

/// A VRML number (decimal, exponent, `0x` hex; Rust also accepts `nan`/`inf`, which the
/// interpreter then rejects with a location).
fn number(w: &str) -> Option<f64> {
    let first = w.bytes().next()?;
    let numeric = first.is_ascii_digit() || matches!(first, b'-' | b'+' | b'.');
    if let Some(hex) = w.strip_prefix("0x").or_else(|| w.strip_prefix("0X")) {
        return i64::from_str_radix(hex, 16).ok().map(|v| v as f64);
    }
    if numeric || w.eq_ignore_ascii_case("nan") || w.eq_ignore_ascii_case("inf") {
        return w.parse().ok();
    }
    None
}
