//! Reading objects with their hash verified while the bytes stream.
//!
//! Every read of an object goes through [`read_verified`] or [`VerifyingReader`], so a bit flip,
//! a truncation or a swapped file is reported as corruption naming the object, the entry and the
//! role, instead of surfacing as a confusing decode error later.

use std::io::{self, Read};

use regolith_format::hash::Hasher;
use regolith_format::{FileRef, ObjectId};

use crate::error::{ReaderError, Result};
use crate::store::Store;

/// Where an object was referenced from, for error messages.
#[derive(Debug, Clone)]
pub struct Site {
    /// Entry name (`<manifest>` for a release manifest).
    pub entry: String,
    /// Role path.
    pub role: String,
}

impl Site {
    /// A site.
    pub fn new(entry: &str, role: &str) -> Site {
        Site {
            entry: entry.to_string(),
            role: role.to_string(),
        }
    }
}

/// The key of an object (`objects/sha256/<2>/<62>`).
pub fn object_key(id: &ObjectId) -> String {
    id.object_path()
}

/// Reads an object whole, checking its size (if given) and its hash.
pub fn read_verified(
    store: &dyn Store,
    id: &ObjectId,
    size: Option<u64>,
    site: &Site,
) -> Result<Vec<u8>> {
    let mut r = VerifyingReader::open(store, id, size, site.clone())?;
    let mut buf = Vec::new();
    r.read_to_end(&mut buf)
        .map_err(|e| unwrap_verify_error(e, store, id))?;
    Ok(buf)
}

/// Reads the object a [`FileRef`] points to.
pub fn read_ref(store: &dyn Store, f: &FileRef, site: &Site) -> Result<Vec<u8>> {
    read_verified(store, &f.object, Some(f.size), site)
}

/// Streams an object's bytes; at end of stream checks the size and hash and fails the last
/// read with the corruption error if they differ.
pub struct VerifyingReader {
    file: Box<dyn Read + Send>,
    hasher: Option<Hasher>,
    read: u64,
    id: ObjectId,
    size: Option<u64>,
    site: Site,
}

impl VerifyingReader {
    /// Opens an object for verified streaming.
    pub fn open(
        store: &dyn Store,
        id: &ObjectId,
        size: Option<u64>,
        site: Site,
    ) -> Result<VerifyingReader> {
        let file = store
            .open_read(&object_key(id))?
            .ok_or_else(|| ReaderError::MissingObject {
                object: *id,
                entry: site.entry.clone(),
                role: site.role.clone(),
            })?;
        Ok(VerifyingReader {
            file,
            hasher: Some(Hasher::new()),
            read: 0,
            id: *id,
            size,
            site,
        })
    }

    fn check(&mut self) -> Option<ReaderError> {
        let hasher = self.hasher.take()?;
        let found = hasher.finish();
        let detail = if self.size.is_some_and(|s| s != self.read) {
            Some(format!(
                "expected {} bytes, found {}",
                self.size.unwrap_or(0),
                self.read
            ))
        } else if found != self.id {
            Some(format!("content hashes to {found}"))
        } else {
            None
        };
        detail.map(|detail| ReaderError::CorruptObject {
            object: self.id,
            entry: self.site.entry.clone(),
            role: self.site.role.clone(),
            detail,
        })
    }
}

impl Read for VerifyingReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.file.read(buf)?;
        if let Some(h) = self.hasher.as_mut() {
            if let Some(chunk) = buf.get(..n) {
                h.update(chunk);
            }
        }
        self.read += n as u64;
        if n == 0 || buf.is_empty() {
            if let Some(err) = self.check() {
                return Err(io::Error::other(err));
            }
        }
        Ok(n)
    }
}

/// Turns an io::Error produced by [`VerifyingReader`] back into the corruption error.
pub fn unwrap_verify_error(e: io::Error, store: &dyn Store, id: &ObjectId) -> ReaderError {
    if e.get_ref().is_some_and(|inner| inner.is::<ReaderError>()) {
        if let Some(inner) = e.into_inner() {
            if let Ok(re) = inner.downcast::<ReaderError>() {
                return *re;
            }
        }
        return ReaderError::Io {
            op: "reading",
            path: store.describe(&object_key(id)).into(),
            source: io::Error::other("corrupt"),
        };
    }
    ReaderError::Io {
        op: "reading",
        path: store.describe(&object_key(id)).into(),
        source: e,
    }
}
