//! VRML tokens: braces, brackets, words (numbers, names, keywords) and strings; commas and
//! `#` comments are whitespace. Errors carry the byte offset ([`PResult`]).

use crate::error::IngestError;

#[derive(Debug, Clone, PartialEq)]
pub(super) enum Tok<'a> {
    Open,
    Close,
    LBracket,
    RBracket,
    Word(&'a str),
    Str(String),
}

pub(super) type Token<'a> = (usize, Tok<'a>);
/// Parser errors carry the byte offset; `vrml::locate` turns it into line + offset.
pub(super) type PResult<T> = std::result::Result<T, (usize, IngestError)>;

pub(super) struct Lexer<'a> {
    pub(super) src: &'a [u8],
    pub(super) pos: usize,
}

impl<'a> Lexer<'a> {
    fn byte(&self, i: usize) -> Option<u8> {
        self.src.get(i).copied()
    }

    pub(super) fn next_token(&mut self) -> PResult<Option<Token<'a>>> {
        loop {
            match self.byte(self.pos) {
                None => return Ok(None),
                Some(b' ' | b'\t' | b'\r' | b'\n' | b',') => self.pos += 1,
                Some(b'#') => {
                    let rest = self.src.get(self.pos..).unwrap_or_default();
                    self.pos += memchr::memchr(b'\n', rest).unwrap_or(rest.len());
                }
                Some(_) => break,
            }
        }
        let start = self.pos;
        let tok = match self.byte(start) {
            Some(b'{') => Tok::Open,
            Some(b'}') => Tok::Close,
            Some(b'[') => Tok::LBracket,
            Some(b']') => Tok::RBracket,
            Some(b'"') => return self.string(start),
            _ => return self.word(start),
        };
        self.pos += 1;
        Ok(Some((start, tok)))
    }

    fn word(&mut self, start: usize) -> PResult<Option<Token<'a>>> {
        while let Some(b) = self.byte(self.pos) {
            if matches!(
                b,
                b' ' | b'\t' | b'\r' | b'\n' | b',' | b'{' | b'}' | b'[' | b']' | b'#' | b'"'
            ) {
                break;
            }
            self.pos += 1;
        }
        let word = self.src.get(start..self.pos).unwrap_or_default();
        let word = std::str::from_utf8(word).map_err(|_| {
            (
                start,
                IngestError::syntax("a UTF-8 word", &String::from_utf8_lossy(word)),
            )
        })?;
        Ok(Some((start, Tok::Word(word))))
    }

    fn string(&mut self, start: usize) -> PResult<Option<Token<'a>>> {
        let mut out = Vec::new();
        self.pos = start + 1;
        loop {
            match self.byte(self.pos) {
                None => return Err((start, IngestError::syntax("a closing '\"'", "end of file"))),
                Some(b'"') => break,
                Some(b'\\') => {
                    out.extend(self.byte(self.pos + 1));
                    self.pos += 2;
                }
                Some(b) => {
                    out.push(b);
                    self.pos += 1;
                }
            }
        }
        self.pos += 1;
        Ok(Some((
            start,
            Tok::Str(String::from_utf8_lossy(&out).into_owned()),
        )))
    }
}
