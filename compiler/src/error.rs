//! Errors of the compiler crate.
//!
//! Ingest errors are built from a small core (`Syntax`, `Invalid`, `Io`, ...) wrapped in
//! location context (`AtLine`, `AtOffset`, `WithPath`), so every message names the file, the
//! place in it and what was expected, e.g.
//! `line 12, column 3: expected a number, found "abc" (in scans/pos1.asc)`.

use std::path::PathBuf;

use thiserror::Error;

/// An error while reading raw campaign input.
#[derive(Debug, Error)]
pub enum IngestError {
    /// The error happened in this file (the path is relative to the campaign when possible).
    #[error("{err} (in {})", path.display())]
    WithPath {
        /// File path.
        path: PathBuf,
        /// The underlying error.
        err: Box<IngestError>,
    },
    /// The error happened at this 1-based line.
    #[error("line {line}: {err}")]
    AtLine {
        /// 1-based line number.
        line: u64,
        /// The underlying error.
        err: Box<IngestError>,
    },
    /// The error happened at this byte offset.
    #[error("byte offset {offset}: {err}")]
    AtOffset {
        /// Byte offset from the start of the file.
        offset: u64,
        /// The underlying error.
        err: Box<IngestError>,
    },
    /// The error is about the place in the file where `needle` appears (a key or a value of
    /// `campaign.toml`, found by [`IngestError::near`]'s caller, which knows the text, and
    /// turned into [`IngestError::AtLine`]); shown as the underlying error until then.
    #[error("{err}")]
    Near {
        /// The text to look for (e.g. `"scans/pos1_tiepoints.csv"`, quotes included).
        needle: String,
        /// The underlying error.
        err: Box<IngestError>,
    },
    /// The error concerns this part of the campaign (`[[scan]] "pos1" tiepoints`).
    #[error("{context}: {err}")]
    Context {
        /// What the file is to the campaign.
        context: String,
        /// The underlying error.
        err: Box<IngestError>,
    },
    /// Input did not match the grammar.
    #[error("expected {expected}, found {found}")]
    Syntax {
        /// What the parser expected.
        expected: String,
        /// What it found (quoted, truncated).
        found: String,
    },
    /// Input parsed but is not valid (NaN coordinate, index out of range, ...).
    #[error("{0}")]
    Invalid(String),
    /// A feature of the format that regolith does not read.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// A size read from the file exceeds the configured limits.
    #[error(transparent)]
    Limit(#[from] regolith_format::FormatError),
    /// Reading failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

impl IngestError {
    /// Wraps the error with a file path.
    pub fn in_file(self, path: impl Into<PathBuf>) -> IngestError {
        IngestError::WithPath {
            path: path.into(),
            err: Box::new(self),
        }
    }
    /// Wraps the error with a 1-based line number.
    pub fn at_line(self, line: u64) -> IngestError {
        IngestError::AtLine {
            line,
            err: Box::new(self),
        }
    }
    /// Wraps the error with a byte offset.
    pub fn at_offset(self, offset: u64) -> IngestError {
        IngestError::AtOffset {
            offset,
            err: Box::new(self),
        }
    }
    /// Prefixes the error with what the file is to the campaign (`[[scan]] "pos1" tiepoints`).
    pub fn context(self, context: impl Into<String>) -> IngestError {
        IngestError::Context {
            context: context.into(),
            err: Box::new(self),
        }
    }
    /// Marks the error as being about the place where `needle` appears in the file; see
    /// [`IngestError::locate`].
    pub fn near(self, needle: impl Into<String>) -> IngestError {
        IngestError::Near {
            needle: needle.into(),
            err: Box::new(self),
        }
    }
    /// Turns a [`IngestError::Near`] into the line of `text` holding its needle (the first
    /// occurrence; no line when the needle does not occur). Other errors are returned as they
    /// are.
    pub fn locate(self, text: &str) -> IngestError {
        match self {
            IngestError::Near { needle, err } => match text.find(&needle) {
                Some(at) => {
                    let line = text.get(..at).unwrap_or("").matches('\n').count() as u64 + 1;
                    (*err).at_line(line)
                }
                None => *err,
            },
            other => other,
        }
    }
    /// A syntax error; `found` is quoted and truncated to 40 characters.
    pub fn syntax(expected: impl Into<String>, found: &str) -> IngestError {
        let mut f: String = found.chars().take(40).collect();
        if found.chars().count() > 40 {
            f.push('…');
        }
        IngestError::Syntax {
            expected: expected.into(),
            found: format!("{f:?}"),
        }
    }
    /// An invalid-value error.
    pub fn invalid(msg: impl Into<String>) -> IngestError {
        IngestError::Invalid(msg.into())
    }
}

/// Result alias for ingest.
pub type Result<T, E = IngestError> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_names_line_and_file_last() {
        let e = IngestError::syntax("a number", "abc")
            .at_line(12)
            .in_file("scans/pos1.asc");
        assert_eq!(
            e.to_string(),
            "line 12: expected a number, found \"abc\" (in scans/pos1.asc)"
        );
    }
}
