//! Where a database's bytes live: a local folder or an object store (S3 and compatibles, GCS,
//! Azure Blob Storage).
//!
//! Why an abstraction: the database (SPEC.md §2) only needs a handful of operations on keys
//! (`regolith.db`, `objects/sha256/<2>/<62>`, `refs/<name>`, the ref log), and the guarantees
//! the writer's crash-safety rests on can be had on both kinds of storage, by different means:
//!
//! | need                          | local folder ([`local`])            | object store (`object`, feature)  |
//! |-------------------------------|-------------------------------------|--------------------------------|
//! | an object appears whole       | temp file, fsync, rename            | a PUT is atomic                |
//! | an object is never rewritten  | checked under the write lock        | create-only PUT (`If-None-Match`) |
//! | an immutable ref is never moved | checked under the write lock      | create-only PUT                |
//! | a mutable ref is not lost     | the write lock (one writer)         | compare-and-swap on the ETag   |
//! | `gc` does not race a writer   | the write lock                      | a grace period on object age   |
//! | the ref log                   | `logs/refs.jsonl`, appended         | one object per change, `logs/refs/` |
//!
//! [`Database`](crate::Database) and [`Writer`](crate::Writer) hold an `Arc<dyn Store>` and
//! speak only in keys; nothing above this module knows which backend it has. The object-store
//! backend is behind the `object-store` cargo feature so that a simulator reading local folders
//! keeps a small dependency tree.

use std::fmt;
use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use crate::error::Result;

pub mod local;
#[cfg(feature = "object-store")]
pub mod object;

/// Where a database is: a folder, or the URL of a prefix in an object store.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A folder on a local file system.
    Local(PathBuf),
    /// An object-store URL (`s3://bucket/prefix`, `gs://…`, `az://…`), without a trailing `/`.
    Url(String),
}

impl Location {
    /// Reads a location as a user types it: `scheme://…` is a URL (`file://` a local path),
    /// anything else a local path.
    pub fn parse(s: &str) -> Location {
        match url_scheme(s) {
            Some("file") => Location::Local(PathBuf::from(&s["file://".len()..])),
            Some(_) => Location::Url(s.trim_end_matches('/').to_string()),
            None => Location::Local(PathBuf::from(s)),
        }
    }

    /// Whether `s` is written as a URL (`scheme://…`).
    pub fn is_url(s: &str) -> bool {
        url_scheme(s).is_some()
    }

    /// The folder, for a local location.
    pub fn as_local(&self) -> Option<&Path> {
        match self {
            Location::Local(p) => Some(p),
            Location::Url(_) => None,
        }
    }

    /// Something to format (mirrors `Path::display`, so call sites read the same).
    pub fn display(&self) -> &Self {
        self
    }

    /// Opens the storage at this location (no check that it holds a database).
    pub fn open_store(&self) -> Result<Arc<dyn Store>> {
        match self {
            Location::Local(p) => Ok(Arc::new(local::LocalStore::new(p.clone()))),
            #[cfg(feature = "object-store")]
            Location::Url(url) => Ok(Arc::new(object::ObjectStoreBackend::open(url)?)),
            #[cfg(not(feature = "object-store"))]
            Location::Url(url) => Err(crate::error::ReaderError::Store {
                location: url.clone(),
                message: "this build of regolith-reader reads local folders only; enable its \
                          `object-store` cargo feature for s3://, gs:// and az:// locations"
                    .to_string(),
            }),
        }
    }
}

/// The scheme of `scheme://…` (RFC 3986 scheme characters, at least two so that a Windows
/// drive letter is never one).
fn url_scheme(s: &str) -> Option<&str> {
    let (scheme, _) = s.split_once("://")?;
    let mut chars = scheme.chars();
    let first = chars.next()?;
    (scheme.len() >= 2
        && first.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')))
    .then_some(scheme)
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Local(p) => write!(f, "{}", p.display()),
            Location::Url(u) => f.write_str(u),
        }
    }
}

impl From<&Path> for Location {
    fn from(p: &Path) -> Location {
        Location::Local(p.to_path_buf())
    }
}
impl From<PathBuf> for Location {
    fn from(p: PathBuf) -> Location {
        Location::Local(p)
    }
}
impl From<&PathBuf> for Location {
    fn from(p: &PathBuf) -> Location {
        Location::Local(p.clone())
    }
}
impl From<&str> for Location {
    fn from(s: &str) -> Location {
        Location::parse(s)
    }
}
impl From<&String> for Location {
    fn from(s: &String) -> Location {
        Location::parse(s)
    }
}
impl From<String> for Location {
    fn from(s: String) -> Location {
        Location::parse(&s)
    }
}
impl From<&Location> for Location {
    fn from(l: &Location) -> Location {
        l.clone()
    }
}

/// Size and age of a stored key.
#[derive(Debug, Clone)]
pub struct KeyMeta {
    /// The key, relative to the database (`objects/sha256/ab/…`).
    pub key: String,
    /// Bytes.
    pub size: u64,
    /// When it was last written, if the storage says.
    pub modified: Option<SystemTime>,
}

/// What a compare-and-swap write of a mutable key compares against: the version read with
/// [`Store::get_versioned`] (an ETag and/or version id on object stores; the content locally).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Version {
    /// Entity tag (object stores) or the content read (local).
    pub e_tag: Option<String>,
    /// Version id, where the object store keeps versions.
    pub version: Option<String>,
}

/// The write lock a local writer holds for its lifetime (none on object stores, whose writers
/// rely on create-only and compare-and-swap writes instead).
#[derive(Debug)]
pub struct WriteLock(#[allow(dead_code)] pub(crate) Option<std::fs::File>);

/// The operations a database needs from its storage. Keys are `/`-separated and relative to
/// the database root.
pub trait Store: fmt::Debug + Send + Sync {
    /// Where this store is.
    fn location(&self) -> &Location;
    /// A key's full name for messages (a path, or `url/key`).
    fn describe(&self, key: &str) -> String;
    /// The whole value of a key, `None` if absent.
    fn get(&self, key: &str) -> Result<Option<Vec<u8>>>;
    /// A byte range of a key (must exist).
    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>>;
    /// A stream over a key's bytes, `None` if absent (large objects are not held in memory).
    fn open_read(&self, key: &str) -> Result<Option<Box<dyn Read + Send>>>;
    /// Size and age of a key, `None` if absent.
    fn head(&self, key: &str) -> Result<Option<KeyMeta>>;
    /// Stores an immutable key (an object, the marker) if absent; an existing key is not
    /// rewritten. Returns whether this call created it.
    fn put_object(&self, key: &str, bytes: &[u8]) -> Result<bool>;
    /// The value of a mutable key with the version to compare-and-swap against.
    fn get_versioned(&self, key: &str) -> Result<Option<(Vec<u8>, Version)>>;
    /// Writes a ref: with `expected` `None` only if the key is absent (create-only), else only
    /// if it still has that version (compare-and-swap). `before_commit` runs when the write is
    /// prepared but not yet visible (crash tests). Returns `false` on a lost race, writing
    /// nothing.
    fn put_ref(
        &self,
        key: &str,
        bytes: &[u8],
        expected: Option<&Version>,
        before_commit: &dyn Fn(),
    ) -> Result<bool>;
    /// Every key under `prefix` (which ends in `/`), sorted.
    fn list(&self, prefix: &str) -> Result<Vec<KeyMeta>>;
    /// Removes a key (absent is not an error).
    fn delete(&self, key: &str) -> Result<()>;
    /// Records one ref change (a JSON line) in the ref log.
    fn log_ref_change(&self, record: &serde_json::Value) -> Result<()>;
    /// Takes the write lock (`wait` called once before waiting for another writer; `None`:
    /// fail with [`crate::ReaderError::Locked`]).
    fn lock(&self, wait: Option<&dyn Fn()>) -> Result<WriteLock>;
    /// Before a database is created here: refuses a place holding other things
    /// ([`crate::ReaderError::NotEmpty`]) and lays out what the backend needs.
    fn prepare_create(&self, has_marker: bool) -> Result<()>;
    /// Why this is not a database (no such folder, empty, a campaign...), for
    /// [`crate::ReaderError::NotADatabase`].
    fn why_not_a_database(&self) -> String;
    /// Removes scratch left by killed writers (local temp files); called by `gc`.
    fn clean_scratch(&self) {}
    /// After [`Store::delete`] during a roll-back: removes the key's now empty parent folder.
    fn remove_empty_parent(&self, _key: &str) {}
    /// The default age below which `gc` keeps unreachable objects: zero where the write lock
    /// keeps writers out, an hour on object stores.
    fn default_gc_grace(&self) -> Duration {
        Duration::ZERO
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn locations_are_urls_only_with_a_scheme() {
        assert_eq!(
            Location::parse("s3://bucket/a/b/"),
            Location::Url("s3://bucket/a/b".into())
        );
        assert_eq!(
            Location::parse("file:///srv/db"),
            Location::Local(PathBuf::from("/srv/db"))
        );
        for local in ["db", "./s3/x", "c://x", "/abs/path", "a:b"] {
            assert_eq!(
                Location::parse(local),
                Location::Local(PathBuf::from(local))
            );
        }
    }

    #[test]
    fn local_refs_are_create_only_or_compare_and_swap() {
        let dir = tempfile::tempdir().unwrap();
        let store = local::LocalStore::new(dir.path().to_path_buf());
        let key = "refs/latest";
        assert!(store.put_ref(key, b"a\n", None, &|| {}).unwrap());
        assert!(!store.put_ref(key, b"b\n", None, &|| {}).unwrap());
        let (_, v) = store.get_versioned(key).unwrap().unwrap();
        assert!(store.put_ref(key, b"c\n", Some(&v), &|| {}).unwrap());
        // `v` is stale now: the swap is refused and the value kept.
        assert!(!store.put_ref(key, b"d\n", Some(&v), &|| {}).unwrap());
        assert_eq!(store.get(key).unwrap().unwrap(), b"c\n");
        assert!(store.put_object("objects/x", b"1").unwrap());
        assert!(!store.put_object("objects/x", b"2").unwrap());
        assert_eq!(store.get("objects/x").unwrap().unwrap(), b"1");
        let keys: Vec<String> = store
            .list("refs/")
            .unwrap()
            .into_iter()
            .map(|m| m.key)
            .collect();
        assert_eq!(keys, ["refs/latest"]);
    }
}
