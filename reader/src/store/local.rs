//! The local-folder backend: today's on-disk layout, byte for byte (SPEC.md §2).
//!
//! Crash safety comes from the file system: every write goes to `tmp/`, is fsynced, renamed
//! into place and its folder fsynced, so a key is either absent or whole. One writer at a time
//! holds an OS lock on `DB/lock`, which is what makes "check, then write" sequences (create-only
//! objects and refs, compare-and-swap of `latest`) safe here without server support.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::{KeyMeta, Location, Store, Version, WriteLock};
use crate::database::MARKER;
use crate::error::{ReaderError, Result};

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A database in a local folder.
#[derive(Debug)]
pub struct LocalStore {
    root: PathBuf,
    location: Location,
}

impl LocalStore {
    /// The store of the folder `root` (nothing is checked or created).
    pub fn new(root: PathBuf) -> LocalStore {
        LocalStore {
            location: Location::Local(root.clone()),
            root,
        }
    }

    /// The folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    fn path(&self, key: &str) -> PathBuf {
        self.root.join(key)
    }
}

/// Reads a file, `None` when it (or a folder in its place) is not a file.
fn read_file(path: &Path) -> Result<Option<Vec<u8>>> {
    match fs::read(path) {
        Ok(b) => Ok(Some(b)),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
        Err(_) if path.is_dir() => Ok(None),
        Err(e) => Err(ReaderError::Io {
            op: "reading",
            path: path.to_path_buf(),
            source: e,
        }),
    }
}

impl Store for LocalStore {
    fn location(&self) -> &Location {
        &self.location
    }

    fn describe(&self, key: &str) -> String {
        self.path(key).display().to_string()
    }

    fn get(&self, key: &str) -> Result<Option<Vec<u8>>> {
        read_file(&self.path(key))
    }

    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>> {
        let path = self.path(key);
        let mut f = File::open(&path).map_err(ReaderError::io("opening", &path))?;
        f.seek(SeekFrom::Start(range.start))
            .map_err(ReaderError::io("seeking in", &path))?;
        let mut buf = Vec::new();
        f.take(range.end.saturating_sub(range.start))
            .read_to_end(&mut buf)
            .map_err(ReaderError::io("reading", &path))?;
        Ok(buf)
    }

    fn open_read(&self, key: &str) -> Result<Option<Box<dyn Read + Send>>> {
        let path = self.path(key);
        match File::open(&path) {
            Ok(f) => Ok(Some(Box::new(f))),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(ReaderError::Io {
                op: "opening",
                path,
                source: e,
            }),
        }
    }

    fn head(&self, key: &str) -> Result<Option<KeyMeta>> {
        match fs::metadata(self.path(key)) {
            Ok(m) if m.is_file() => Ok(Some(KeyMeta {
                key: key.to_string(),
                size: m.len(),
                modified: m.modified().ok(),
            })),
            _ => Ok(None),
        }
    }

    fn put_object(&self, key: &str, bytes: &[u8]) -> Result<bool> {
        let path = self.path(key);
        if path.exists() {
            return Ok(false);
        }
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(ReaderError::io("creating", parent))?;
        }
        write_atomic(&self.root, &path, bytes, &|| {})?;
        Ok(true)
    }

    fn get_versioned(&self, key: &str) -> Result<Option<(Vec<u8>, Version)>> {
        Ok(self.get(key)?.map(|b| {
            let v = Version {
                e_tag: Some(String::from_utf8_lossy(&b).into_owned()),
                version: None,
            };
            (b, v)
        }))
    }

    fn put_ref(
        &self,
        key: &str,
        bytes: &[u8],
        expected: Option<&Version>,
        before_commit: &dyn Fn(),
    ) -> Result<bool> {
        // The caller holds the write lock, so the comparison and the write are one step.
        let current = self.get_versioned(key)?.map(|(_, v)| v);
        if current.as_ref() != expected {
            return Ok(false);
        }
        let path = self.path(key);
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(ReaderError::io("creating", parent))?;
        }
        write_atomic(&self.root, &path, bytes, before_commit)?;
        Ok(true)
    }

    fn list(&self, prefix: &str) -> Result<Vec<KeyMeta>> {
        let mut out = Vec::new();
        let dir = self.path(prefix);
        if dir.is_dir() {
            walk(&dir, prefix, &mut out)?;
        }
        Ok(out)
    }

    fn delete(&self, key: &str) -> Result<()> {
        let path = self.path(key);
        match fs::remove_file(&path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(ReaderError::Io {
                op: "removing",
                path,
                source: e,
            }),
        }
    }

    fn log_ref_change(&self, record: &serde_json::Value) -> Result<()> {
        let log = self.root.join("logs/refs.jsonl");
        let mut f = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .map_err(ReaderError::io("opening", &log))?;
        writeln!(f, "{record}").map_err(ReaderError::io("appending to", &log))?;
        f.sync_all().map_err(ReaderError::io("syncing", &log))?;
        Ok(())
    }

    fn lock(&self, wait: Option<&dyn Fn()>) -> Result<WriteLock> {
        let lock_path = self.root.join("lock");
        let lock = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .map_err(ReaderError::io("opening", &lock_path))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(fs::TryLockError::WouldBlock) => match wait {
                Some(on_wait) => {
                    on_wait();
                    lock.lock()
                        .map_err(ReaderError::io("locking", &lock_path))?;
                }
                None => {
                    return Err(ReaderError::Locked {
                        path: self.root.clone(),
                    })
                }
            },
            Err(fs::TryLockError::Error(e)) => {
                return Err(ReaderError::Io {
                    op: "locking",
                    path: lock_path,
                    source: e,
                });
            }
        }
        Ok(WriteLock(Some(lock)))
    }

    fn prepare_create(&self, has_marker: bool) -> Result<()> {
        if !has_marker {
            // Only what this function creates may be there already (an interrupted creation).
            const SKELETON: [&str; 5] = ["objects", "refs", "logs", "tmp", "lock"];
            let mut others: Vec<String> = fs::read_dir(&self.root)
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| !SKELETON.contains(&n.as_str()))
                .collect();
            if !others.is_empty() {
                others.sort();
                return Err(ReaderError::NotEmpty {
                    location: self.location.clone(),
                    found: others,
                });
            }
        }
        for d in ["objects/sha256", "refs/releases", "logs", "tmp"] {
            let p = self.root.join(d);
            fs::create_dir_all(&p).map_err(ReaderError::io("creating", &p))?;
        }
        Ok(())
    }

    fn why_not_a_database(&self) -> String {
        why_not_a_database(&self.root)
    }

    fn clean_scratch(&self) {
        let tmp = self.root.join("tmp");
        if let Ok(rd) = fs::read_dir(&tmp) {
            for e in rd.flatten() {
                let _ = fs::remove_file(e.path());
            }
        }
    }

    fn remove_empty_parent(&self, key: &str) {
        if let Some(parent) = self.path(key).parent() {
            // Only removed when empty: a fan-out folder still holding objects stays.
            let _ = fs::remove_dir(parent);
        }
    }
}

/// Every file below `dir` as a key `prefix…`, sorted; names starting with `.` (temp files of
/// an interrupted ref update) are skipped.
fn walk(dir: &Path, prefix: &str, out: &mut Vec<KeyMeta>) -> Result<()> {
    let rd = fs::read_dir(dir).map_err(ReaderError::io("listing", dir))?;
    let mut entries: Vec<_> = rd.filter_map(|e| e.ok()).map(|e| e.path()).collect();
    entries.sort();
    for path in entries {
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        if name.starts_with('.') {
            continue;
        }
        let key = format!("{prefix}{name}");
        let meta = fs::metadata(&path).map_err(ReaderError::io("reading", &path))?;
        if meta.is_dir() {
            walk(&path, &format!("{key}/"), out)?;
        } else {
            out.push(KeyMeta {
                key,
                size: meta.len(),
                modified: meta.modified().ok(),
            });
        }
    }
    Ok(())
}

/// Writes `bytes` to `dest` atomically: temp file in `root/tmp`, fsync, `before_rename`,
/// rename, fsync of the folder.
pub fn write_atomic(
    root: &Path,
    dest: &Path,
    bytes: &[u8],
    before_rename: &dyn Fn(),
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

/// Why `root` is not a database: what is there instead, and the database right below it when
/// there is one (`out/demo` for `out/demo/db`).
fn why_not_a_database(root: &Path) -> String {
    match fs::metadata(root) {
        Err(_) => return "no such folder".to_string(),
        Ok(m) if !m.is_dir() => return "it is a file, not a folder".to_string(),
        Ok(_) => {}
    }
    let Ok(rd) = fs::read_dir(root) else {
        return "the folder cannot be read".to_string();
    };
    let mut children: Vec<PathBuf> = rd.flatten().map(|e| e.path()).collect();
    if children.is_empty() {
        return "the folder is empty".to_string();
    }
    children.sort();
    let below: Vec<String> = children
        .iter()
        .filter(|c| c.join(MARKER).is_file())
        .map(|c| c.display().to_string())
        .collect();
    if !below.is_empty() {
        return match below.as_slice() {
            [one] => {
                format!("it has no `{MARKER}` marker, but the folder below it is one: give {one}")
            }
            _ => format!(
                "it has no `{MARKER}` marker, but folders below it are: give one of {}",
                below.join(", ")
            ),
        };
    }
    if root.join("campaign.toml").is_file() {
        return "it is a campaign folder (it holds campaign.toml): compile it into a database \
                with `regolith compile CAMPAIGN --db DB` and give DB"
            .to_string();
    }
    format!("the folder has no `{MARKER}` marker file")
}
