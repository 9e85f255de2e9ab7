//! The one error type of the corpus generator.
//!
//! Generation only fails on I/O, on an encoder refusing its input, or on options that do not
//! make sense (an unknown hidden-effect name, a bad `--effect-param`). Every variant says what
//! was being written or parsed; paths come last in messages (house style, practice 7).

use std::path::PathBuf;

/// Errors of `regolith-corpus`.
#[derive(Debug, thiserror::Error)]
pub enum CorpusError {
    /// A file or folder could not be written.
    #[error("cannot write {what}: {source}: {}", path.display())]
    Io {
        /// What was being written.
        what: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
        /// The path.
        path: PathBuf,
    },
    /// An encoder (PNG, EXR, E57, LAS, JSON, TOML) failed.
    #[error("cannot encode {what}: {message}: {}", path.display())]
    Encode {
        /// What was being encoded.
        what: &'static str,
        /// The encoder's message.
        message: String,
        /// The output path.
        path: PathBuf,
    },
    /// An option is not valid.
    #[error("invalid option {option}: expected {expected}, found {found:?}")]
    Option {
        /// Which option.
        option: &'static str,
        /// What would be accepted.
        expected: String,
        /// What was given.
        found: String,
    },
}

impl CorpusError {
    /// Wraps an I/O error with what was written and where.
    pub fn io(what: &'static str, path: &std::path::Path) -> impl FnOnce(std::io::Error) -> Self {
        let path = path.to_path_buf();
        move |source| CorpusError::Io { what, source, path }
    }

    /// Wraps an encoder error with what was written and where.
    pub fn encode<E: std::fmt::Display>(
        what: &'static str,
        path: &std::path::Path,
    ) -> impl FnOnce(E) -> Self {
        let path = path.to_path_buf();
        move |e| CorpusError::Encode {
            what,
            message: e.to_string(),
            path,
        }
    }
}
