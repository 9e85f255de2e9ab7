//! Opening a database, listing and resolving releases, and reading entries.
//!
//! Layout (SPEC.md §2): `regolith.db` marker, `objects/sha256/<2>/<62>` immutable objects
//! (payloads and release manifests), `refs/<name>` mutable names holding a release id,
//! `logs/refs.jsonl` the append-only ref log (the only place wall-clock time is kept).
//! The same keys live in a folder or under an object-store prefix ([`crate::store`]).

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::Arc;

use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;
use regolith_format::kinds::{self, RigMeta};
use regolith_format::manifest::{check_name, MANIFEST_MEDIA_TYPE};
use regolith_format::{Entry, ObjectId, Release};

use crate::error::{ReaderError, Result};
use crate::object::{object_key, read_ref, read_verified, Site};
use crate::store::{Location, Store};

/// File name of the marker that makes a folder a database.
pub const MARKER: &str = "regolith.db";
/// The ref naming the newest release.
pub const LATEST: &str = "latest";
/// Prefix of the immutable per-release refs (`releases/<name>@<version>`).
pub const RELEASES_PREFIX: &str = "releases/";
/// Prefix of certificate refs (`certificates/<release id>/<escaped entry>`), which name a
/// certificate object rather than a release (SPEC.md §2).
pub const CERTIFICATES_PREFIX: &str = "certificates/";

/// The ref of the certificate of `entry` in `release` (SPEC.md §2, format 1.3): the entry name
/// escaped into a single path segment, `@` → `@a` then `/` → `@s`.
///
/// Why: entry names nest (`laser/0.01` and its mesh `laser/0.01/mesh`), and a ref is a file, so
/// `certificates/<id>/laser/0.01` as a file would forbid the directory the mesh's ref needs.
/// The escape is reversible, so distinct entries never share a ref.
pub fn certificate_ref(release: &ObjectId, entry: &str) -> String {
    let escaped = entry.replace('@', "@a").replace('/', "@s");
    format!("{CERTIFICATES_PREFIX}{release}/{escaped}")
}

/// The certificate ref of formats 1.1–1.2 (`certificates/<release id>/<entry>`), still read.
fn legacy_certificate_ref(release: &ObjectId, entry: &str) -> String {
    format!("{CERTIFICATES_PREFIX}{release}/{entry}")
}

/// Prefix of validation-unit refs (`units/<unit key>`, format 1.10), which name the stored
/// result of one (entry, view) of a sharded validation (SPEC.md §2).
pub const UNITS_PREFIX: &str = "units/";

/// The ref of the validation unit whose content key is `key` (SPEC.md §2, format 1.10).
pub fn unit_ref(key: &ObjectId) -> String {
    format!("{UNITS_PREFIX}{key}")
}

/// Whether a ref names a plain object (a certificate or a validation unit's result) rather
/// than a release.
pub fn is_object_ref(name: &str) -> bool {
    name.starts_with(CERTIFICATES_PREFIX) || name.starts_with(UNITS_PREFIX)
}

/// An open database (read-only handle; see [`crate::write::Writer`] for writing).
#[derive(Debug, Clone)]
pub struct Database {
    store: Arc<dyn Store>,
}

/// A loaded release: its id and verified manifest.
#[derive(Debug, Clone)]
pub struct ReleaseView {
    store: Arc<dyn Store>,
    /// The release id (hash of the manifest bytes).
    pub id: ObjectId,
    /// The manifest.
    pub manifest: Release,
}

impl Database {
    /// Opens the database at `location`, checking its marker: a folder (`&Path`, `PathBuf`),
    /// or a string, where `s3://bucket/prefix`, `gs://…` and `az://…` name an object-store
    /// prefix (with the `object-store` feature) and `file://…` or anything else a folder.
    ///
    /// ```no_run
    /// let db = regolith_reader::Database::open("terrain.db")?;
    /// for (label, id) in db.releases()? {
    ///     println!("{label} {}", id.short());
    /// }
    /// # Ok::<(), regolith_reader::ReaderError>(())
    /// ```
    pub fn open(location: impl Into<Location>) -> Result<Database> {
        let location = location.into();
        let store = location.open_store()?;
        Database::open_store(store)
    }

    /// Opens the database held by `store`, checking its marker.
    pub fn open_store(store: Arc<dyn Store>) -> Result<Database> {
        let not_db = |store: &dyn Store| ReaderError::NotADatabase {
            location: store.location().clone(),
            reason: store.why_not_a_database(),
        };
        let bytes = match store.get(MARKER) {
            Ok(Some(b)) => b,
            Ok(None) => return Err(not_db(&*store)),
            Err(e @ (ReaderError::Store { .. } | ReaderError::Credentials { .. })) => {
                return Err(e)
            }
            Err(_) => return Err(not_db(&*store)),
        };
        let v: serde_json::Value =
            serde_json::from_slice(&bytes).map_err(|e| ReaderError::NotADatabase {
                location: store.location().clone(),
                reason: format!("its `{MARKER}` marker is not the JSON a database writes ({e})"),
            })?;
        let schema = v.get("schema").and_then(|s| s.as_str()).unwrap_or_default();
        regolith_format::manifest::check_schema(schema)
            .map_err(ReaderError::format(store.describe(MARKER)))?;
        Ok(Database { store })
    }

    /// Where the database is (a folder or a URL).
    pub fn location(&self) -> &Location {
        self.store.location()
    }

    /// The storage the database lives in.
    pub fn store(&self) -> &Arc<dyn Store> {
        &self.store
    }

    /// Every ref and the release id it holds, sorted by name.
    pub fn refs(&self) -> Result<BTreeMap<String, ObjectId>> {
        let mut out = BTreeMap::new();
        for meta in self.store.list("refs/")? {
            let Some(name) = meta.key.strip_prefix("refs/") else {
                continue;
            };
            let Some(bytes) = self.store.get(&meta.key)? else {
                continue; // removed since the listing
            };
            out.insert(
                name.to_string(),
                parse_ref(&bytes, &*self.store, &meta.key)?,
            );
        }
        Ok(out)
    }

    /// Reads one ref, `None` if it does not exist.
    pub fn read_ref(&self, name: &str) -> Result<Option<ObjectId>> {
        check_name("ref name", name).map_err(ReaderError::format("ref"))?;
        let key = format!("refs/{name}");
        self.store
            .get(&key)?
            .map(|b| parse_ref(&b, &*self.store, &key))
            .transpose()
    }

    /// Named releases (`name@version`, id), sorted by label.
    pub fn releases(&self) -> Result<Vec<(String, ObjectId)>> {
        Ok(self
            .refs()?
            .into_iter()
            .filter_map(|(k, v)| k.strip_prefix(RELEASES_PREFIX).map(|l| (l.to_string(), v)))
            .collect())
    }

    /// Resolves `name@version`, a ref name (`latest`), a full id or an id prefix of ≥ 6 digits.
    pub fn resolve(&self, spec: &str) -> Result<ObjectId> {
        if let Ok(id) = spec.parse::<ObjectId>() {
            return Ok(id);
        }
        if check_name("ref", spec).is_ok() {
            if let Some(id) = self.read_ref(&format!("{RELEASES_PREFIX}{spec}"))? {
                return Ok(id);
            }
            if let Some(id) = self.read_ref(spec)? {
                return Ok(id);
            }
        }
        if spec.len() >= 6 && spec.bytes().all(|b| b.is_ascii_hexdigit()) {
            let mut hits: Vec<ObjectId> = self
                .refs()?
                .into_iter()
                .filter(|(name, id)| !is_object_ref(name) && id.to_hex().starts_with(spec))
                .map(|(_, id)| id)
                .collect();
            hits.sort();
            hits.dedup();
            return match hits.as_slice() {
                [one] => Ok(*one),
                [] => Err(self.unknown_release(spec)),
                _ => Err(ReaderError::AmbiguousRelease {
                    spec: spec.to_string(),
                }),
            };
        }
        Err(self.unknown_release(spec))
    }

    /// The error for a release spec that names nothing, listing what the database has: every
    /// `name@version`, then the other refs that name releases (`latest`, `published/...`;
    /// not the compile cache's).
    fn unknown_release(&self, spec: &str) -> ReaderError {
        let refs = self.refs().unwrap_or_default();
        let labels = refs
            .keys()
            .filter_map(|k| k.strip_prefix(RELEASES_PREFIX))
            .map(str::to_string);
        let others = refs
            .keys()
            .filter(|k| {
                !k.starts_with(RELEASES_PREFIX) && !is_object_ref(k) && !k.starts_with("cache/")
            })
            .cloned();
        ReaderError::UnknownRelease {
            spec: spec.to_string(),
            known: labels.chain(others).collect(),
        }
    }

    /// Loads a release by any spec accepted by [`Database::resolve`].
    pub fn release(&self, spec: &str) -> Result<ReleaseView> {
        let id = self.resolve(spec)?;
        if self.store.head(&object_key(&id))?.is_none() && !self.refs()?.values().any(|r| *r == id)
        {
            // A full id that names no stored release (a typo of one character, an id of
            // another database): say so, rather than "object missing", which means corruption.
            return Err(self.unknown_release(spec));
        }
        self.release_by_id(&id)
    }

    /// The certificate stored for an entry of a release, verified, if any.
    pub fn certificate(
        &self,
        release: &ObjectId,
        entry: &str,
    ) -> Result<Option<serde_json::Value>> {
        // A folder at either name (which reads as no ref) holds refs of nested entries of the
        // 1.1–1.2 layout.
        let mut found = self.read_ref(&certificate_ref(release, entry))?;
        if found.is_none() {
            found = self.read_ref(&legacy_certificate_ref(release, entry))?;
        }
        let Some(id) = found else {
            return Ok(None);
        };
        let bytes = read_verified(&*self.store, &id, None, &Site::new(entry, "certificate"))?;
        serde_json::from_slice(&bytes)
            .map(Some)
            .map_err(|e| ReaderError::Decode {
                entry: entry.to_string(),
                what: "certificate",
                message: e.to_string(),
            })
    }

    /// Loads and verifies a release manifest by id.
    pub fn release_by_id(&self, id: &ObjectId) -> Result<ReleaseView> {
        let site = Site::new("<manifest>", MANIFEST_MEDIA_TYPE);
        let bytes = read_verified(&*self.store, id, None, &site)?;
        let manifest = Release::from_bytes(&bytes).map_err(ReaderError::format(format!(
            "release manifest {}",
            id.short()
        )))?;
        Ok(ReleaseView {
            store: self.store.clone(),
            id: *id,
            manifest,
        })
    }
}

/// Parses a ref's value (a release or object id and a newline).
pub(crate) fn parse_ref(bytes: &[u8], store: &dyn Store, key: &str) -> Result<ObjectId> {
    String::from_utf8_lossy(bytes)
        .trim()
        .parse()
        .map_err(ReaderError::format(format!(
            "ref file {}",
            store.describe(key)
        )))
}

impl ReleaseView {
    /// `name@version`.
    pub fn label(&self) -> String {
        self.manifest.label()
    }

    /// The entries, sorted by name.
    pub fn entries(&self) -> &[Entry] {
        &self.manifest.entries
    }

    /// An entry by name.
    pub fn entry(&self, name: &str) -> Result<&Entry> {
        self.manifest
            .entry(name)
            .ok_or_else(|| ReaderError::NoSuchEntry {
                release: self.label(),
                entry: name.to_string(),
                known: self.entries().iter().map(|e| e.name.clone()).collect(),
            })
    }

    /// An entry that must be of `kind`.
    pub fn entry_of_kind(&self, name: &str, kind: &'static str) -> Result<&Entry> {
        let e = self.entry(name)?;
        if e.kind != kind {
            return Err(ReaderError::WrongKind {
                entry: name.to_string(),
                expected: kind,
                found: e.kind.clone(),
            });
        }
        Ok(e)
    }

    /// The verified bytes of an entry's file with the given role (whole-entry or root tile).
    pub fn read_file(&self, entry: &str, role: &str) -> Result<Vec<u8>> {
        let e = self.entry(entry)?;
        let f = e.file(role).ok_or_else(|| ReaderError::NoSuchRole {
            entry: entry.to_string(),
            role: role.to_string(),
        })?;
        read_ref(&*self.store, f, &Site::new(entry, role))
    }

    /// A byte range of an entry's file, read without fetching the rest (a ranged GET on object
    /// stores). The range is checked against the manifest's size, but the bytes are not hashed
    /// — a hash covers the whole object: use [`ReleaseView::read_file`] (or `verify`) when the
    /// bytes must be proven intact.
    pub fn read_file_range(&self, entry: &str, role: &str, range: Range<u64>) -> Result<Vec<u8>> {
        let e = self.entry(entry)?;
        let f = e.file(role).ok_or_else(|| ReaderError::NoSuchRole {
            entry: entry.to_string(),
            role: role.to_string(),
        })?;
        if range.start > range.end || range.end > f.size {
            return Err(ReaderError::Decode {
                entry: entry.to_string(),
                what: "byte range",
                message: format!(
                    "{}..{} is outside the {} bytes of role {role:?}",
                    range.start, range.end, f.size
                ),
            });
        }
        if range.is_empty() {
            return Ok(Vec::new());
        }
        let key = object_key(&f.object);
        if self.store.head(&key)?.is_none() {
            return Err(ReaderError::MissingObject {
                object: f.object,
                entry: entry.to_string(),
                role: role.to_string(),
            });
        }
        self.store.get_range(&key, range)
    }

    /// Decodes a JSON file of an entry.
    pub fn read_json<T: serde::de::DeserializeOwned>(
        &self,
        entry: &str,
        role: &str,
        what: &'static str,
    ) -> Result<T> {
        let bytes = self.read_file(entry, role)?;
        serde_json::from_slice(&bytes).map_err(|e| ReaderError::Decode {
            entry: entry.to_string(),
            what,
            message: e.to_string(),
        })
    }

    /// A camera's intrinsics.
    pub fn camera(&self, entry: &str) -> Result<CameraModel> {
        self.entry_of_kind(entry, kinds::CAMERA)?;
        self.read_json(entry, kinds::roles::CALIBRATION, "camera calibration")
    }

    /// A stereo rig's extrinsics.
    pub fn rig(&self, entry: &str) -> Result<RigMeta> {
        self.entry_of_kind(entry, kinds::RIG)?;
        self.read_json(entry, kinds::roles::CALIBRATION, "rig calibration")
    }

    /// Where the camera entry `camera` sits on the release's stereo rig (the `rig` entries
    /// that name it; identity when none does): the frame a `pose-bias` is about.
    pub fn rig_from_camera(&self, camera: &str) -> Result<Pose> {
        for e in self.entries().iter().filter(|e| e.kind == kinds::RIG) {
            if let Some(p) = self.rig(&e.name)?.rig_from_camera(camera) {
                return Ok(p);
            }
        }
        Ok(Pose::IDENTITY)
    }

    /// A report's JSON body.
    pub fn report(&self, entry: &str) -> Result<serde_json::Value> {
        self.entry_of_kind(entry, kinds::REPORT)?;
        self.read_json(entry, kinds::roles::REPORT, "report")
    }
}
