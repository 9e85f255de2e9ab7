//! Writing a database: atomic object writes, release commits, atomic ref updates, gc.
//!
//! The writer lives in this small crate (not in the compiler) because three tools write:
//! the compiler (releases), the validator (certificates) and the gap workflow (sensor-model
//! releases). All of them must obey the same crash-safety rules, so there is one implementation:
//!
//! 1. every object is written to `tmp/`, fsynced, renamed into `objects/`, and the directory
//!    fsynced; an existing object is never rewritten (content addressing makes it identical);
//! 2. the manifest object is written only after every object it references exists;
//! 3. refs are updated last, each by writing a temp file, fsync, rename.
//!
//! A writer killed at any point therefore leaves every earlier release readable and `verify`
//! clean; at worst it leaves unreachable objects, which `gc` removes. In a local folder a writer
//! holds an exclusive lock on `DB/lock` for its lifetime, so `gc` never runs beside a writer.
//!
//! On an object store ([`crate::store`], SPEC.md §2.1 "Databases on object stores") there is no
//! lock: a PUT is atomic (rule 1), objects and `releases/…` refs are written create-only, and
//! mutable refs (`latest`, certificates) by compare-and-swap on the version read, retried on a
//! conflict. Two writers racing therefore never lose a release: both `releases/…` refs exist
//! and `latest` ends on one of them. `gc` keeps unreachable objects younger than a grace
//! period, since they may belong to a release another writer is committing.
//!
//! For crash tests, the environment variable `REGOLITH_FAILPOINT` names a step at which the
//! process aborts (`object-renamed`, `objects-stored`, `manifest-stored`, `ref-temp-written`;
//! on an object store the last fires just before the ref's conditional PUT).

use std::collections::BTreeSet;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use regolith_format::manifest::{check_name, MANIFEST_MEDIA_TYPE};
use regolith_format::{canonical_json, FileRef, ObjectId, Release, SCHEMA};
use serde::Serialize;

use crate::database::{
    certificate_ref, is_object_ref, parse_ref, Database, LATEST, MARKER, RELEASES_PREFIX,
};
use crate::error::{ReaderError, Result};
use crate::object::object_key;
use crate::store::{Location, Store, WriteLock};

/// Prefix of the object keys.
const OBJECTS_PREFIX: &str = "objects/sha256/";
/// How often a compare-and-swap of a mutable ref is retried when other writers keep winning.
const CAS_ATTEMPTS: usize = 32;

/// Aborts the process if `REGOLITH_FAILPOINT` names this step (crash-safety tests only).
fn failpoint(step: &str) {
    if std::env::var("REGOLITH_FAILPOINT").is_ok_and(|v| v == step) {
        eprintln!("regolith: failpoint {step} reached, aborting");
        std::process::abort();
    }
}

/// A handle that writes into a database; holds the database's write lock.
#[derive(Debug)]
pub struct Writer {
    db: Database,
    _lock: WriteLock,
    /// Keys of the objects this writer created, in order (see [`Writer::roll_back`]).
    created: Mutex<Vec<String>>,
}

/// What `gc` removed.
#[derive(Debug, Clone, Default, Serialize)]
pub struct GcReport {
    /// Objects kept (reachable from a ref).
    pub kept: u64,
    /// Objects removed.
    pub removed: u64,
    /// Bytes freed.
    pub bytes_freed: u64,
    /// Unreachable objects kept because they are younger than the grace period (they may
    /// belong to a release another writer is committing).
    pub kept_young: u64,
}

impl Writer {
    /// Opens a database for writing, creating it if the folder (or object-store prefix) is
    /// empty or absent. A folder holding other files is refused ([`ReaderError::NotEmpty`]): a
    /// database among a campaign's or a project's files would be mixed up with them. Accepts
    /// what [`Database::open`] accepts.
    pub fn create_or_open(location: impl Into<Location>) -> Result<Writer> {
        Writer::open_with(location.into().open_store()?, None)
    }

    /// Opens an existing database for writing, waiting for another writer to finish instead
    /// of refusing: for a short write at the end of long work (a certificate after a
    /// validation, a fitted model after `gap`), so that the work itself holds no lock and
    /// several such commands can run on one database. `on_wait` is called once if the lock is
    /// held by another process, before waiting (never on object stores, which have no lock).
    pub fn open_waiting(location: impl Into<Location>, on_wait: &dyn Fn()) -> Result<Writer> {
        let db = Database::open(location)?;
        Writer::open_with(db.store().clone(), Some(on_wait))
    }

    /// [`Writer::create_or_open`], or with `wait`, [`Writer::open_waiting`].
    fn open_with(store: Arc<dyn Store>, wait: Option<&dyn Fn()>) -> Result<Writer> {
        let has_marker = store.head(MARKER)?.is_some();
        store.prepare_create(has_marker)?;
        let lock = store.lock(wait)?;
        if !has_marker {
            let body = format!("{{\"schema\":\"{SCHEMA}\"}}\n");
            // Create-only: of two writers creating one database, one marker wins (same bytes).
            store.put_object(MARKER, body.as_bytes())?;
        }
        let db = Database::open_store(store)?;
        Ok(Writer {
            db,
            _lock: lock,
            created: Mutex::new(Vec::new()),
        })
    }

    /// Takes back what a failed operation stored: removes every object this writer created
    /// that no ref reaches (and the fan-out folders it created for them, when empty again), so
    /// the object store is as it was before. Objects that were there already and everything a
    /// ref reaches (a committed release, a certificate) are kept, so this is safe to call after
    /// any failure. Returns how many objects were removed.
    pub fn roll_back(&self) -> Result<usize> {
        let created = std::mem::take(
            &mut *self
                .created
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        );
        if created.is_empty() {
            return Ok(0);
        }
        let reachable: BTreeSet<String> = reachable_objects(&self.db)?
            .iter()
            .map(object_key)
            .collect();
        let store = self.db.store();
        let mut removed = 0;
        for key in created.iter().rev() {
            if !reachable.contains(key) {
                store.delete(key)?;
                store.remove_empty_parent(key);
                removed += 1;
            }
        }
        Ok(removed)
    }

    /// The database being written (for reads during a write session).
    pub fn database(&self) -> &Database {
        &self.db
    }

    /// Stores bytes as an object (deduplicated) and returns its reference.
    pub fn put(&self, bytes: &[u8], media_type: &str) -> Result<FileRef> {
        let id = ObjectId::of_bytes(bytes);
        let key = object_key(&id);
        let store = self.db.store();
        if store.head(&key)?.is_none() && store.put_object(&key, bytes)? {
            self.created
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push(key);
            failpoint("object-renamed");
        }
        Ok(FileRef {
            object: id,
            size: bytes.len() as u64,
            media_type: media_type.to_string(),
        })
    }

    /// Stores a value as canonical JSON.
    pub fn put_json<T: Serialize>(&self, value: &T) -> Result<FileRef> {
        let bytes = canonical_json::to_vec(value).map_err(ReaderError::format("JSON object"))?;
        self.put(&bytes, regolith_format::kinds::media::JSON)
    }

    /// Commits a release: checks it, makes sure every referenced object is stored, writes
    /// the manifest object, creates the immutable `releases/<name>@<version>` ref and, when
    /// `update_latest`, moves `latest`. Returns the release id.
    pub fn commit(&self, mut release: Release, update_latest: bool) -> Result<ObjectId> {
        release
            .normalise()
            .map_err(ReaderError::format(format!("release {}", release.label())))?;
        for (entry, role, f) in release.file_refs() {
            if self.db.store().head(&object_key(&f.object))?.is_none() {
                return Err(ReaderError::DanglingReference {
                    object: f.object,
                    entry: entry.to_string(),
                    role,
                });
            }
        }
        failpoint("objects-stored");
        let label = release.label();
        let bytes = release
            .to_canonical_bytes()
            .map_err(ReaderError::format(format!("release {label}")))?;
        let manifest = self.put(&bytes, MANIFEST_MEDIA_TYPE)?;
        let id = manifest.object;
        failpoint("manifest-stored");
        let tag = format!("{RELEASES_PREFIX}{label}");
        match self.create_ref(&tag, &id)? {
            Some(existing) if existing != id => {
                return Err(ReaderError::ReleaseExists { label, existing });
            }
            _ => {}
        }
        if update_latest {
            self.set_ref(LATEST, &id)?;
        }
        Ok(id)
    }

    /// Points a ref at a release atomically and appends the change to the ref log. On an
    /// object store the write is a compare-and-swap against the value read, retried when
    /// another writer moved the ref meanwhile (the last writer wins, none is lost half-way).
    pub fn set_ref(&self, name: &str, id: &ObjectId) -> Result<()> {
        check_name("ref name", name).map_err(ReaderError::format("ref"))?;
        let key = format!("refs/{name}");
        let store = self.db.store();
        let body = format!("{id}\n");
        for _ in 0..CAS_ATTEMPTS {
            let current = store.get_versioned(&key)?;
            let old = match &current {
                Some((bytes, _)) => Some(parse_ref(bytes, &**store, &key)?),
                None => None,
            };
            let expected = current.as_ref().map(|(_, v)| v);
            if store.put_ref(&key, body.as_bytes(), expected, &|| {
                failpoint("ref-temp-written")
            })? {
                return self.log_ref_change(name, old, id);
            }
        }
        Err(ReaderError::Store {
            location: store.describe(&key),
            message: format!(
                "other writers kept moving ref `{name}`; {CAS_ATTEMPTS} compare-and-swap \
                 attempts failed"
            ),
        })
    }

    /// Creates an immutable ref (create-only); returns the id it already held if it existed,
    /// leaving it unchanged.
    fn create_ref(&self, name: &str, id: &ObjectId) -> Result<Option<ObjectId>> {
        check_name("ref name", name).map_err(ReaderError::format("ref"))?;
        let key = format!("refs/{name}");
        let store = self.db.store();
        let body = format!("{id}\n");
        if let Some(existing) = self.db.read_ref(name)? {
            return Ok(Some(existing));
        }
        if store.put_ref(&key, body.as_bytes(), None, &|| {
            failpoint("ref-temp-written")
        })? {
            self.log_ref_change(name, None, id)?;
            return Ok(None);
        }
        // Another writer created it between the read and the write.
        self.db.read_ref(name)
    }

    /// Appends one change to the ref log (the only place wall-clock time is kept).
    fn log_ref_change(&self, name: &str, old: Option<ObjectId>, new: &ObjectId) -> Result<()> {
        let time = SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        let line = serde_json::json!({
            "time_unix_s": time,
            "ref": name,
            "old": old.map(|o| o.to_hex()),
            "new": new.to_hex(),
        });
        self.db.store().log_ref_change(&line)
    }

    /// Stores a certificate (canonical JSON) for an entry of a release and points
    /// `certificates/<release id>/<entry>` at it; a newer validation replaces the ref.
    pub fn put_certificate<T: Serialize>(
        &self,
        release: &ObjectId,
        entry: &str,
        body: &T,
    ) -> Result<FileRef> {
        let f = self.put_json(body)?;
        self.set_ref(&certificate_ref(release, entry), &f.object)?;
        Ok(f)
    }

    /// Removes every object not reachable from a ref (following release parents) and
    /// leftover temp files, with the store's default grace period (none in a local folder,
    /// where the write lock keeps writers out; an hour on object stores).
    pub fn gc(&self) -> Result<GcReport> {
        self.gc_with_grace(self.db.store().default_gc_grace())
    }

    /// [`Writer::gc`], keeping unreachable objects younger than `grace`: on an object store a
    /// concurrent writer's objects are unreachable until its release's ref is written.
    pub fn gc_with_grace(&self, grace: Duration) -> Result<GcReport> {
        let store = self.db.store();
        // Listed before the reachable set is computed: an object stored after the listing
        // is not considered at all, one stored before is either reachable or old enough.
        let listed = store.list(OBJECTS_PREFIX)?;
        let reachable = reachable_objects(&self.db)?;
        let cutoff = SystemTime::now().checked_sub(grace);
        let mut report = GcReport::default();
        for meta in listed {
            if object_id_of_key(&meta.key).is_some_and(|id| reachable.contains(&id)) {
                report.kept += 1;
                continue;
            }
            let young = !grace.is_zero()
                && match (meta.modified, cutoff) {
                    (Some(m), Some(c)) => m > c,
                    _ => true, // age unknown: keep
                };
            if young {
                report.kept_young += 1;
                continue;
            }
            store.delete(&meta.key)?;
            report.removed += 1;
            report.bytes_freed += meta.size;
        }
        store.clean_scratch();
        Ok(report)
    }
}

/// The id an object key names (`None` for a stray key).
fn object_id_of_key(key: &str) -> Option<ObjectId> {
    let rest = key.strip_prefix(OBJECTS_PREFIX)?;
    let (a, b) = rest.split_once('/')?;
    format!("{a}{b}").parse().ok()
}

/// Every object id reachable from the refs: manifests, their parents (when present) and
/// every file they reference.
pub fn reachable_objects(db: &Database) -> Result<BTreeSet<ObjectId>> {
    let mut seen = BTreeSet::new();
    let mut stack = Vec::new();
    for (name, id) in db.refs()? {
        if is_object_ref(&name) {
            seen.insert(id);
        } else {
            stack.push(id);
        }
    }
    while let Some(id) = stack.pop() {
        if !seen.insert(id) {
            continue;
        }
        let Ok(view) = db.release_by_id(&id) else {
            continue; // a missing parent is allowed; verify reports broken refs
        };
        for (_, _, f) in view.manifest.file_refs() {
            seen.insert(f.object);
        }
        if let Some(p) = view.manifest.parent {
            if db.store().head(&object_key(&p))?.is_some() {
                stack.push(p);
            }
        }
    }
    Ok(seen)
}
