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
//! clean; at worst it leaves unreachable objects, which `gc` removes. A writer holds an
//! exclusive lock on `DB/lock` for its lifetime, so `gc` never runs beside a writer.
//!
//! For crash tests, the environment variable `REGOLITH_FAILPOINT` names a step at which the
//! process aborts (`object-renamed`, `objects-stored`, `manifest-stored`, `ref-temp-written`).

use std::collections::BTreeSet;
use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use regolith_format::manifest::{check_name, MANIFEST_MEDIA_TYPE};
use regolith_format::{canonical_json, FileRef, ObjectId, Release, SCHEMA};
use serde::Serialize;

use crate::database::{certificate_ref, is_object_ref, Database, LATEST, MARKER, RELEASES_PREFIX};
use crate::error::{ReaderError, Result};
use crate::object::object_path;

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

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
    _lock: File,
    /// Object files and fan-out folders this writer created, in order (see [`Writer::roll_back`]).
    created: Mutex<Vec<PathBuf>>,
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
}

impl Writer {
    /// Opens a database for writing, creating it if the folder is empty or absent.
    /// A folder holding other files is refused ([`ReaderError::NotEmpty`]): a database among a
    /// campaign's or a project's files would be mixed up with them.
    pub fn create_or_open(path: impl AsRef<Path>) -> Result<Writer> {
        Writer::open_with(path.as_ref(), None)
    }

    /// Opens an existing database for writing, waiting for another writer to finish instead
    /// of refusing: for a short write at the end of long work (a certificate after a
    /// validation, a fitted model after `gap`), so that the work itself holds no lock and
    /// several such commands can run on one database. `on_wait` is called once if the lock is
    /// held by another process, before waiting.
    pub fn open_waiting(path: impl AsRef<Path>, on_wait: &dyn Fn()) -> Result<Writer> {
        let root = path.as_ref();
        Database::open(root)?;
        Writer::open_with(root, Some(on_wait))
    }

    /// [`Writer::create_or_open`], or with `wait`, [`Writer::open_waiting`].
    fn open_with(root: &Path, wait: Option<&dyn Fn()>) -> Result<Writer> {
        let root = root.to_path_buf();
        if !root.join(MARKER).exists() {
            // Only what this function creates may be there already (an interrupted creation).
            const SKELETON: [&str; 5] = ["objects", "refs", "logs", "tmp", "lock"];
            let mut others: Vec<String> = fs::read_dir(&root)
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| !SKELETON.contains(&n.as_str()))
                .collect();
            if !others.is_empty() {
                others.sort();
                return Err(ReaderError::NotEmpty {
                    path: root,
                    found: others,
                });
            }
        }
        for d in ["objects/sha256", "refs/releases", "logs", "tmp"] {
            let p = root.join(d);
            fs::create_dir_all(&p).map_err(ReaderError::io("creating", &p))?;
        }
        let lock_path = root.join("lock");
        let lock = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .map_err(ReaderError::io("opening", &lock_path))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => match wait {
                Some(on_wait) => {
                    on_wait();
                    lock.lock()
                        .map_err(ReaderError::io("locking", &lock_path))?;
                }
                None => return Err(ReaderError::Locked { path: root.clone() }),
            },
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(ReaderError::Io {
                    op: "locking",
                    path: lock_path,
                    source: e,
                });
            }
        }
        let marker = root.join(MARKER);
        if !marker.exists() {
            let body = format!("{{\"schema\":\"{SCHEMA}\"}}\n");
            write_atomic(&root, &marker, body.as_bytes())?;
        }
        let db = Database::open(&root)?;
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
        let reachable: BTreeSet<PathBuf> = reachable_objects(&self.db)?
            .iter()
            .map(|id| object_path(self.db.root(), id))
            .collect();
        let mut removed = 0;
        for path in created.iter().rev() {
            if path.is_dir() {
                // Only removed when empty: a fan-out folder still holding objects stays.
                let _ = fs::remove_dir(path);
            } else if !reachable.contains(path) {
                fs::remove_file(path).map_err(ReaderError::io("removing", path))?;
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
        let path = object_path(self.db.root(), &id);
        if !path.exists() {
            let mut created = Vec::new();
            if let Some(parent) = path.parent() {
                if !parent.is_dir() {
                    created.push(parent.to_path_buf());
                }
                fs::create_dir_all(parent).map_err(ReaderError::io("creating", parent))?;
            }
            write_atomic(self.db.root(), &path, bytes)?;
            created.push(path.clone());
            self.created
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .extend(created);
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
            if !object_path(self.db.root(), &f.object).is_file() {
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
        match self.db.read_ref(&tag)? {
            Some(existing) if existing != id => {
                return Err(ReaderError::ReleaseExists { label, existing });
            }
            Some(_) => {}
            None => self.set_ref(&tag, &id)?,
        }
        if update_latest {
            self.set_ref(LATEST, &id)?;
        }
        Ok(id)
    }

    /// Points a ref at a release atomically and appends the change to the ref log.
    pub fn set_ref(&self, name: &str, id: &ObjectId) -> Result<()> {
        check_name("ref name", name).map_err(ReaderError::format("ref"))?;
        let old = self.db.read_ref(name)?;
        let path = self.db.root().join("refs").join(name);
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(ReaderError::io("creating", parent))?;
        }
        write_atomic_with(self.db.root(), &path, format!("{id}\n").as_bytes(), || {
            failpoint("ref-temp-written")
        })?;
        let time = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        let line = serde_json::json!({
            "time_unix_s": time,
            "ref": name,
            "old": old.map(|o| o.to_hex()),
            "new": id.to_hex(),
        });
        let log = self.db.root().join("logs/refs.jsonl");
        let mut f = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .map_err(ReaderError::io("opening", &log))?;
        writeln!(f, "{line}").map_err(ReaderError::io("appending to", &log))?;
        f.sync_all().map_err(ReaderError::io("syncing", &log))?;
        Ok(())
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
    /// leftover temp files. Holds the write lock, so no writer runs meanwhile.
    pub fn gc(&self) -> Result<GcReport> {
        let reachable = reachable_objects(&self.db)?;
        let mut report = GcReport::default();
        let objects = self.db.root().join("objects/sha256");
        for (path, id) in list_objects(&objects)? {
            if id.is_some_and(|id| reachable.contains(&id)) {
                report.kept += 1;
                continue;
            }
            let len = fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
            fs::remove_file(&path).map_err(ReaderError::io("removing", &path))?;
            report.removed += 1;
            report.bytes_freed += len;
        }
        let tmp = self.db.root().join("tmp");
        if let Ok(rd) = fs::read_dir(&tmp) {
            for e in rd.flatten() {
                let _ = fs::remove_file(e.path());
            }
        }
        Ok(report)
    }
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
            if object_path(db.root(), &p).is_file() {
                stack.push(p);
            }
        }
    }
    Ok(seen)
}

/// Lists object files with the id their path names (`None` for a stray file).
pub fn list_objects(objects: &Path) -> Result<Vec<(PathBuf, Option<ObjectId>)>> {
    let mut out = Vec::new();
    let Ok(rd) = fs::read_dir(objects) else {
        return Ok(out);
    };
    let mut dirs: Vec<PathBuf> = rd.flatten().map(|e| e.path()).collect();
    dirs.sort();
    for d in dirs {
        let prefix = d
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default()
            .to_string();
        let rd = fs::read_dir(&d).map_err(ReaderError::io("listing", &d))?;
        let mut files: Vec<PathBuf> = rd.flatten().map(|e| e.path()).collect();
        files.sort();
        for f in files {
            let rest = f.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            let id = format!("{prefix}{rest}").parse::<ObjectId>().ok();
            out.push((f, id));
        }
    }
    Ok(out)
}

/// Writes `bytes` to `dest` atomically: temp file in `root/tmp`, fsync, rename, fsync dir.
pub fn write_atomic(root: &Path, dest: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(root, dest, bytes, || {})
}

fn write_atomic_with(
    root: &Path,
    dest: &Path,
    bytes: &[u8],
    before_rename: impl FnOnce(),
) -> Result<()> {
    let tmp_dir = root.join("tmp");
    fs::create_dir_all(&tmp_dir).map_err(ReaderError::io("creating", &tmp_dir))?;
    let n = TMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp = tmp_dir.join(format!("{}-{n}.tmp", std::process::id()));
    {
        let mut f = File::create(&tmp).map_err(ReaderError::io("creating", &tmp))?;
        f.write_all(bytes)
            .map_err(ReaderError::io("writing", &tmp))?;
        f.sync_all().map_err(ReaderError::io("syncing", &tmp))?;
    }
    before_rename();
    fs::rename(&tmp, dest).map_err(ReaderError::io("renaming into", dest))?;
    if let Some(parent) = dest.parent() {
        if let Ok(d) = File::open(parent) {
            let _ = d.sync_all();
        }
    }
    Ok(())
}
