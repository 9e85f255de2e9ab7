//! The object-store backend (`s3://`, `gs://`, `az://`), on Apache Arrow's `object_store`.
//!
//! The keys are the folder layout's, under the URL's prefix (SPEC.md §2 "Databases on object
//! stores"). There is no lock, so every guarantee comes from the server:
//!
//! - objects and the marker are written create-only (`PutMode::Create`, `If-None-Match: *`): an
//!   existing object is never rewritten, and two writers storing the same object both succeed;
//! - immutable refs (`releases/<name>@<version>`) are written create-only, so the first writer
//!   of a label wins and the second sees [`crate::ReaderError::ReleaseExists`] (or the same id);
//! - mutable refs (`latest`, certificates) are written by compare-and-swap against the ETag
//!   read (`PutMode::Update`, `If-Match`); a lost race re-reads and retries;
//! - the ref log cannot be appended to, so each change is one small object
//!   `logs/refs/<unix ms>-<sha256 of the record>.json`.
//!
//! The reader's API is synchronous (simulators call it from plain threads), so the backend
//! owns a small tokio runtime and blocks on each request. Large objects are streamed in ranged
//! GETs of [`CHUNK`] bytes, never held whole.

use std::io::{self, Read};
use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use futures::TryStreamExt;
use object_store::path::Path as KeyPath;
use object_store::{ObjectStore, ObjectStoreExt, PutMode, PutOptions, PutPayload, UpdateVersion};

use super::{KeyMeta, Location, Store, Version, WriteLock};
use crate::database::MARKER;
use crate::error::{ReaderError, Result};

/// Bytes per ranged GET when streaming an object.
pub const CHUNK: u64 = 8 << 20;
/// The default `gc` grace period on object stores.
pub const DEFAULT_GC_GRACE: Duration = Duration::from_secs(3600);

/// A database under a prefix of an object store.
pub struct ObjectStoreBackend {
    location: Location,
    url: String,
    /// The prefix, without leading or trailing `/` (empty: the bucket's root).
    prefix: String,
    store: Arc<dyn ObjectStore>,
    runtime: Arc<tokio::runtime::Runtime>,
    /// The environment variables holding credentials for this kind of store, for messages.
    credential_vars: &'static str,
}

impl std::fmt::Debug for ObjectStoreBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectStoreBackend")
            .field("url", &self.url)
            .finish_non_exhaustive()
    }
}

const AWS_VARS: &str = "AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY (and AWS_SESSION_TOKEN for \
                        temporary credentials), AWS_REGION and, for S3-compatible servers, \
                        AWS_ENDPOINT_URL";
const GCP_VARS: &str = "GOOGLE_SERVICE_ACCOUNT (or GOOGLE_APPLICATION_CREDENTIALS)";
const AZURE_VARS: &str = "AZURE_STORAGE_ACCOUNT_NAME and AZURE_STORAGE_ACCOUNT_KEY (or \
                          AZURE_STORAGE_SAS_TOKEN)";

impl ObjectStoreBackend {
    /// Connects to the store of `url` (`s3://bucket/prefix`, `s3a://`, `gs://`, `az://`,
    /// `abfs://`), configured from the environment (docs/object-storage.md). Nothing is
    /// requested yet.
    pub fn open(url: &str) -> Result<ObjectStoreBackend> {
        let url = url.trim_end_matches('/').to_string();
        let err = |message: String| ReaderError::Store {
            location: url.clone(),
            message,
        };
        let (scheme, rest) = url
            .split_once("://")
            .ok_or_else(|| err("not a URL".to_string()))?;
        let (container, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        if container.is_empty() {
            return Err(err(format!(
                "the URL names no bucket; write {scheme}://BUCKET/PREFIX"
            )));
        }
        let root = format!("{scheme}://{container}");
        let (store, credential_vars): (Arc<dyn ObjectStore>, &'static str) = match scheme {
            "s3" | "s3a" => (
                Arc::new(
                    object_store::aws::AmazonS3Builder::from_env()
                        .with_url(root)
                        .build()
                        .map_err(|e| err(format!("cannot configure S3: {e}")))?,
                ),
                AWS_VARS,
            ),
            "gs" => (
                Arc::new(
                    object_store::gcp::GoogleCloudStorageBuilder::from_env()
                        .with_url(root)
                        .build()
                        .map_err(|e| err(format!("cannot configure GCS: {e}")))?,
                ),
                GCP_VARS,
            ),
            "az" | "abfs" | "abfss" | "azure" => (
                Arc::new(
                    object_store::azure::MicrosoftAzureBuilder::from_env()
                        .with_url(root)
                        .build()
                        .map_err(|e| err(format!("cannot configure Azure: {e}")))?,
                ),
                AZURE_VARS,
            ),
            other => {
                return Err(err(format!(
                    "unsupported scheme `{other}://`; a database is a folder, file://PATH, \
                     s3://BUCKET/PREFIX, gs://BUCKET/PREFIX or az://CONTAINER/PREFIX"
                )))
            }
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("regolith-object-store")
            .enable_all()
            .build()
            .map_err(|e| err(format!("cannot start the I/O runtime: {e}")))?;
        Ok(ObjectStoreBackend {
            location: Location::Url(url.clone()),
            prefix: prefix.trim_matches('/').to_string(),
            url,
            store,
            runtime: Arc::new(runtime),
            credential_vars,
        })
    }

    fn path(&self, key: &str) -> KeyPath {
        if self.prefix.is_empty() {
            KeyPath::from(key)
        } else {
            KeyPath::from(format!("{}/{key}", self.prefix))
        }
    }

    /// The key of a listed path, relative to the database.
    fn key_of(&self, path: &KeyPath) -> Option<String> {
        let full = path.as_ref();
        if self.prefix.is_empty() {
            return Some(full.to_string());
        }
        full.strip_prefix(self.prefix.as_str())?
            .strip_prefix('/')
            .map(str::to_string)
    }

    fn block_on<F: std::future::Future>(&self, f: F) -> F::Output {
        self.runtime.block_on(f)
    }

    /// The reader error for a failed request on `key` (`""`: the database as a whole).
    fn error(&self, op: &str, key: &str, e: object_store::Error) -> ReaderError {
        let location = if key.is_empty() {
            self.url.clone()
        } else {
            format!("{}/{key}", self.url)
        };
        match e {
            object_store::Error::Unauthenticated { source, .. }
            | object_store::Error::PermissionDenied { source, .. } => ReaderError::Credentials {
                location,
                message: source.to_string(),
                hint: self.credential_vars,
            },
            other => {
                let text = other.to_string();
                let message = if text.contains("NoSuchBucket") {
                    "the bucket does not exist (create it first; regolith creates the prefix, \
                     not the bucket)"
                        .to_string()
                } else if text.contains("InvalidAccessKeyId")
                    || text.contains("SignatureDoesNotMatch")
                    || text.contains("AccessDenied")
                {
                    return ReaderError::Credentials {
                        location,
                        message: text,
                        hint: self.credential_vars,
                    };
                } else {
                    format!("{op} failed: {text}")
                };
                ReaderError::Store { location, message }
            }
        }
    }

    fn meta(&self, m: &object_store::ObjectMeta) -> Option<KeyMeta> {
        Some(KeyMeta {
            key: self.key_of(&m.location)?,
            size: m.size,
            modified: Some(SystemTime::from(m.last_modified)),
        })
    }
}

impl Store for ObjectStoreBackend {
    fn location(&self) -> &Location {
        &self.location
    }

    fn describe(&self, key: &str) -> String {
        format!("{}/{key}", self.url)
    }

    fn get(&self, key: &str) -> Result<Option<Vec<u8>>> {
        let path = self.path(key);
        let got = self.block_on(async {
            let r = self.store.get(&path).await?;
            r.bytes().await
        });
        match got {
            Ok(b) => Ok(Some(b.to_vec())),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(self.error("GET", key, e)),
        }
    }

    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>> {
        let path = self.path(key);
        self.block_on(self.store.get_range(&path, range))
            .map(|b| b.to_vec())
            .map_err(|e| self.error("ranged GET", key, e))
    }

    fn open_read(&self, key: &str) -> Result<Option<Box<dyn Read + Send>>> {
        let Some(meta) = self.head(key)? else {
            return Ok(None);
        };
        Ok(Some(Box::new(RangedReader {
            store: self.store.clone(),
            runtime: self.runtime.clone(),
            path: self.path(key),
            location: self.describe(key),
            size: meta.size,
            at: 0,
            buf: Vec::new(),
            buf_at: 0,
        })))
    }

    fn head(&self, key: &str) -> Result<Option<KeyMeta>> {
        match self.block_on(self.store.head(&self.path(key))) {
            Ok(m) => Ok(Some(KeyMeta {
                key: key.to_string(),
                size: m.size,
                modified: Some(SystemTime::from(m.last_modified)),
            })),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(self.error("HEAD", key, e)),
        }
    }

    fn put_object(&self, key: &str, bytes: &[u8]) -> Result<bool> {
        let opts = PutOptions {
            mode: PutMode::Create,
            ..Default::default()
        };
        let payload = PutPayload::from(bytes.to_vec());
        match self.block_on(self.store.put_opts(&self.path(key), payload, opts)) {
            Ok(_) => Ok(true),
            // Content addressing: what is there has the same bytes.
            Err(object_store::Error::AlreadyExists { .. })
            | Err(object_store::Error::Precondition { .. }) => Ok(false),
            Err(e) => Err(self.error("PUT", key, e)),
        }
    }

    fn get_versioned(&self, key: &str) -> Result<Option<(Vec<u8>, Version)>> {
        let path = self.path(key);
        let got = self.block_on(async {
            let r = self.store.get(&path).await?;
            let version = Version {
                e_tag: r.meta.e_tag.clone(),
                version: r.meta.version.clone(),
            };
            Ok::<_, object_store::Error>((r.bytes().await?, version))
        });
        match got {
            Ok((b, v)) => Ok(Some((b.to_vec(), v))),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(self.error("GET", key, e)),
        }
    }

    fn put_ref(
        &self,
        key: &str,
        bytes: &[u8],
        expected: Option<&Version>,
        before_commit: &dyn Fn(),
    ) -> Result<bool> {
        let mode = match expected {
            None => PutMode::Create,
            Some(v) => PutMode::Update(UpdateVersion {
                e_tag: v.e_tag.clone(),
                version: v.version.clone(),
            }),
        };
        let opts = PutOptions {
            mode,
            ..Default::default()
        };
        before_commit();
        let payload = PutPayload::from(bytes.to_vec());
        match self.block_on(self.store.put_opts(&self.path(key), payload, opts)) {
            Ok(_) => Ok(true),
            Err(object_store::Error::AlreadyExists { .. })
            | Err(object_store::Error::Precondition { .. })
            | Err(object_store::Error::NotFound { .. }) => Ok(false),
            Err(e) => Err(self.error("conditional PUT", key, e)),
        }
    }

    fn list(&self, prefix: &str) -> Result<Vec<KeyMeta>> {
        let path = self.path(prefix.trim_end_matches('/'));
        let root = path.as_ref().is_empty();
        let listed: Vec<object_store::ObjectMeta> = self
            .block_on(self.store.list((!root).then_some(&path)).try_collect())
            .map_err(|e| self.error("LIST", prefix, e))?;
        let mut out: Vec<KeyMeta> = listed.iter().filter_map(|m| self.meta(m)).collect();
        out.sort_by(|a, b| a.key.cmp(&b.key));
        Ok(out)
    }

    fn delete(&self, key: &str) -> Result<()> {
        match self.block_on(self.store.delete(&self.path(key))) {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(e) => Err(self.error("DELETE", key, e)),
        }
    }

    fn log_ref_change(&self, record: &serde_json::Value) -> Result<()> {
        let line = format!("{record}\n");
        let millis = SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_millis())
            .unwrap_or(0);
        let hash = regolith_format::ObjectId::of_bytes(line.as_bytes()).to_hex();
        let key = format!("logs/refs/{millis:016}-{}.json", &hash[..16]);
        self.put_object(&key, line.as_bytes()).map(|_| ())
    }

    fn lock(&self, _wait: Option<&dyn Fn()>) -> Result<WriteLock> {
        Ok(WriteLock(None))
    }

    fn prepare_create(&self, has_marker: bool) -> Result<()> {
        if has_marker {
            return Ok(());
        }
        // A database may only be created under a prefix that is empty, or holds only what an
        // interrupted creation or commit leaves (objects, refs, logs), or the marker a writer
        // creating the same database at the same moment has just put (between our `head` of
        // the marker and this listing); opening then checks that marker like any other.
        let listed = self.list("")?;
        let mut others: Vec<String> = listed
            .into_iter()
            .map(|m| m.key)
            .filter(|k| {
                k != crate::database::MARKER
                    && !["objects/", "refs/", "logs/"]
                        .iter()
                        .any(|p| k.starts_with(p))
            })
            .collect();
        if others.is_empty() {
            return Ok(());
        }
        others.sort();
        others.dedup();
        Err(ReaderError::NotEmpty {
            location: self.location.clone(),
            found: others,
        })
    }

    fn why_not_a_database(&self) -> String {
        match self.list("") {
            Ok(keys) if keys.is_empty() => "nothing is stored under that prefix".to_string(),
            Ok(keys) => {
                let first: Vec<&str> = keys.iter().take(3).map(|k| k.key.as_str()).collect();
                format!(
                    "there is no `{MARKER}` key under the prefix, which holds {} key(s) ({}…)",
                    keys.len(),
                    first.join(", ")
                )
            }
            Err(e) => format!("the prefix cannot be listed: {e}"),
        }
    }

    fn default_gc_grace(&self) -> Duration {
        DEFAULT_GC_GRACE
    }
}

/// Streams an object in ranged GETs of [`CHUNK`] bytes.
struct RangedReader {
    store: Arc<dyn ObjectStore>,
    runtime: Arc<tokio::runtime::Runtime>,
    path: KeyPath,
    location: String,
    size: u64,
    /// Offset of the next chunk to fetch.
    at: u64,
    buf: Vec<u8>,
    buf_at: usize,
}

impl Read for RangedReader {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        if self.buf_at >= self.buf.len() {
            if self.at >= self.size || out.is_empty() {
                return Ok(0);
            }
            let end = (self.at + CHUNK).min(self.size);
            let bytes = self
                .runtime
                .block_on(self.store.get_range(&self.path, self.at..end))
                .map_err(|e| {
                    io::Error::other(ReaderError::Store {
                        location: self.location.clone(),
                        message: format!("ranged GET failed: {e}"),
                    })
                })?;
            if bytes.is_empty() {
                return Ok(0); // shorter than its listed size: the hash check reports it
            }
            self.at += bytes.len() as u64;
            self.buf = bytes.to_vec();
            self.buf_at = 0;
        }
        let rest = self.buf.get(self.buf_at..).unwrap_or_default();
        let n = rest.len().min(out.len());
        if let (Some(dst), Some(src)) = (out.get_mut(..n), rest.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.buf_at += n;
        Ok(n)
    }
}
