//! Errors of the reader (and writer): every variant names the object, entry or path concerned.

use std::path::PathBuf;

use regolith_format::{FormatError, ObjectId};
use thiserror::Error;

use crate::store::Location;

/// Errors reading or writing a database.
#[derive(Debug, Error)]
pub enum ReaderError {
    /// A file-system operation failed.
    #[error("{source} ({op} {})", path.display())]
    Io {
        /// What was being done (`reading`, `writing`, `renaming`...).
        op: &'static str,
        /// The path concerned.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// Another process is writing to the database (it holds `DB/lock`).
    #[error("the database is being written by another process (lock held on {}/lock); try again when it finishes", path.display())]
    Locked {
        /// The database folder.
        path: PathBuf,
    },
    /// The folder (or object-store prefix) is not a regolith database.
    #[error(
        "{location} is not a regolith database: {reason}; a database is the folder (or \
         object-store prefix) `regolith compile CAMPAIGN --db DB` creates (compile a campaign \
         into it first, or give the location of an existing database)"
    )]
    NotADatabase {
        /// The folder or URL.
        location: Location,
        /// What is there instead (no such folder, a file, no `regolith.db` marker...), with a
        /// hint when a database sits right below it.
        reason: String,
    },
    /// A new database was to be created in a folder that holds other files.
    #[error(
        "{location} is neither a regolith database nor empty (it holds {}): a new database \
         needs a folder (or prefix) of its own; give a new name (it is created) or an empty one",
        found_files(found)
    )]
    NotEmpty {
        /// The folder or URL.
        location: Location,
        /// What is in it, sorted.
        found: Vec<String>,
    },
    /// An object-store operation failed (network, server, configuration).
    #[error("{message} ({location})")]
    Store {
        /// The URL (with the key, when one is concerned).
        location: String,
        /// What went wrong.
        message: String,
    },
    /// The object store refused the credentials; nothing was written.
    #[error(
        "the object store refused the credentials for {location}: {message}; nothing was \
         written. Check {hint} (docs/object-storage.md)"
    )]
    Credentials {
        /// The URL (with the key, when one is concerned).
        location: String,
        /// The server's answer.
        message: String,
        /// The environment variables that hold the credentials for this kind of store.
        hint: &'static str,
    },
    /// No release matches the given name, version, id or ref.
    #[error("no release matches {spec:?}; {}", known_releases(known))]
    UnknownRelease {
        /// What the user asked for.
        spec: String,
        /// The releases (`name@version`) and other refs (`latest`, `published/...`) the
        /// database has, for the message.
        known: Vec<String>,
    },
    /// A release id prefix matches several releases.
    #[error("release id prefix {spec:?} is ambiguous")]
    AmbiguousRelease {
        /// The prefix.
        spec: String,
    },
    /// The release has no entry of that name.
    #[error(
        "release {release} has no entry {entry:?}; its entries are: {} (`regolith inspect DB \
         {release}` lists them with their kinds)",
        known.join(", ")
    )]
    NoSuchEntry {
        /// Release label.
        release: String,
        /// Entry name.
        entry: String,
        /// The entries the release has, sorted.
        known: Vec<String>,
    },
    /// The entry has no file with that role.
    #[error("entry {entry:?} has no file with role {role:?}")]
    NoSuchRole {
        /// Entry name.
        entry: String,
        /// Role.
        role: String,
    },
    /// The entry is of another kind than the call needs.
    #[error("entry {entry:?} is a {found}, expected a {expected}")]
    WrongKind {
        /// Entry name.
        entry: String,
        /// The kind needed.
        expected: &'static str,
        /// The kind found.
        found: String,
    },
    /// A referenced object is not in the store.
    #[error("object {object} is missing (entry {entry:?}, role {role:?})")]
    MissingObject {
        /// The object id.
        object: ObjectId,
        /// Entry name (or `<manifest>`).
        entry: String,
        /// Role.
        role: String,
    },
    /// An object's bytes do not hash to its name, or its size is wrong.
    #[error("object {object} is corrupt: {detail} (entry {entry:?}, role {role:?})")]
    CorruptObject {
        /// The object id.
        object: ObjectId,
        /// Entry name (or `<manifest>`).
        entry: String,
        /// Role.
        role: String,
        /// Expected vs found.
        detail: String,
    },
    /// An object's content could not be decoded.
    #[error("cannot decode {what} of entry {entry:?}: {message}")]
    Decode {
        /// Entry name.
        entry: String,
        /// What was being decoded.
        what: &'static str,
        /// The decoder's message.
        message: String,
    },
    /// A format-level rule was violated.
    #[error("{source} ({context})")]
    Format {
        /// Where.
        context: String,
        /// The rule.
        source: FormatError,
    },
    /// A write would change an immutable name.
    #[error("release {label} already exists with id {existing}; releases are immutable, choose a new version")]
    ReleaseExists {
        /// `name@version`.
        label: String,
        /// Its id.
        existing: ObjectId,
    },
    /// A write references an object that is not in the store.
    #[error(
        "release references object {object} (entry {entry:?}, role {role:?}) that was never stored"
    )]
    DanglingReference {
        /// The object id.
        object: ObjectId,
        /// Entry name.
        entry: String,
        /// Role.
        role: String,
    },
}

impl ReaderError {
    pub(crate) fn io(
        op: &'static str,
        path: impl Into<PathBuf>,
    ) -> impl FnOnce(std::io::Error) -> ReaderError {
        let path = path.into();
        move |source| ReaderError::Io { op, path, source }
    }
    pub(crate) fn format(context: impl Into<String>) -> impl FnOnce(FormatError) -> ReaderError {
        let context = context.into();
        move |source| ReaderError::Format { context, source }
    }
}

/// The tail of [`ReaderError::UnknownRelease`]: what the database does hold.
fn known_releases(known: &[String]) -> String {
    if known.is_empty() {
        return "the database holds no release yet: compile one with `regolith compile CAMPAIGN \
                --db DB`"
            .to_string();
    }
    format!(
        "the database has: {} (a release is named `name@version`, by a ref such as `latest`, or \
         by an id prefix of at least 6 hex digits; `regolith inspect DB` lists them)",
        known.join(", ")
    )
}

/// The first few names of a folder's listing, for [`ReaderError::NotEmpty`].
fn found_files(found: &[String]) -> String {
    let first: Vec<&str> = found.iter().take(4).map(String::as_str).collect();
    match found.len() {
        n if n > 4 => format!("{} and {} more", first.join(", "), n - 4),
        _ => first.join(", "),
    }
}

/// Result alias.
pub type Result<T, E = ReaderError> = std::result::Result<T, E>;
