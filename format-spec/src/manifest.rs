//! The release manifest: what a release contains and where every byte of it lives.
//!
//! A manifest is stored as an object like any payload; its canonical JSON bytes (RFC 8785)
//! hash to the release id. Because every file reference inside carries its object's SHA-256,
//! the release id is a Merkle root over entries and objects: changing any byte anywhere
//! changes the id. Nothing in a manifest depends on the machine, the clock or a path.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::{canonical_json, FormatError, ObjectId, SCHEMA};

/// Media type of a stored release manifest.
pub const MANIFEST_MEDIA_TYPE: &str = "application/vnd.regolith.release+json";

/// One release: an immutable, content-addressed set of entries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Release {
    /// Always `regolith.db/1` for this version.
    pub schema: String,
    /// Release name, e.g. `estec-arl-2012`.
    pub name: String,
    /// Release version, e.g. `1.0.0`; `name@version` is unique in a database.
    pub version: String,
    /// The release this one was derived from, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parent: Option<ObjectId>,
    /// The campaign the release was compiled from.
    pub campaign: CampaignRef,
    /// The tool that produced the release (name and version).
    pub producer: Producer,
    /// The executed plan: one record per stage, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub plan: Vec<PlanStep>,
    /// The entries, sorted by name, names unique.
    pub entries: Vec<Entry>,
    /// Set when a release was published without passing certificates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub allow_uncertified: Option<bool>,
}

/// The campaign a release was compiled from and the hashes of its input files.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CampaignRef {
    /// Campaign name from `campaign.toml`.
    pub name: String,
    /// Input files by path relative to the campaign folder (`/`-separated), sorted.
    #[serde(default)]
    pub inputs: Vec<InputFile>,
}

/// One input file of a campaign.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputFile {
    /// Path relative to the campaign folder, `/`-separated.
    pub path: String,
    /// SHA-256 of the file's bytes.
    pub sha256: ObjectId,
    /// Size in bytes.
    pub size: u64,
}

/// The producing tool.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Producer {
    /// Tool name, e.g. `regolith-compiler`.
    pub name: String,
    /// Tool version.
    pub version: String,
}

/// One executed compiler stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanStep {
    /// Stable dotted stage name, e.g. `dem.raster`.
    pub stage: String,
    /// Stage version (changes when the stage's output bytes change).
    pub version: u32,
    /// The stage's resolved parameters.
    #[serde(default)]
    pub params: Value,
}

/// A named item of a release (a heightfield, a mesh, a camera, the captures, a report...).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// Entry name, e.g. `laser/0.015`; unique within a release.
    pub name: String,
    /// Entry kind: an open set listed in `format-spec/registry.md`.
    pub kind: String,
    /// Kind-specific metadata (see [`crate::kinds`]).
    #[serde(default)]
    pub meta: Value,
    /// Whole-entry files by role.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub files: BTreeMap<String, FileRef>,
    /// Tiles of tiled kinds (heightfield, texture, mesh), sorted by (level, y, x).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tiles: Vec<Tile>,
}

/// A reference to an object.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileRef {
    /// SHA-256 of the object's bytes.
    pub object: ObjectId,
    /// Size in bytes.
    pub size: u64,
    /// IANA media type (`image/png`, `image/x-exr`, `model/gltf-binary`, ...).
    pub media_type: String,
}

/// One tile of a quadtree-tiled entry. v1 writers emit a single tile (level 0, x 0, y 0).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tile {
    /// Quadtree level; level 0 is one tile covering the entry.
    pub level: u32,
    /// Column index at this level, from the west edge.
    pub x: u32,
    /// Row index at this level, from the north edge.
    pub y: u32,
    /// Ground-frame bounds `[x_min, y_min, x_max, y_max]` in metres (cell edges).
    pub bounds_m: [f64; 4],
    /// The tile's files by role.
    pub files: BTreeMap<String, FileRef>,
}

impl Release {
    /// The canonical JSON bytes of this manifest.
    pub fn to_canonical_bytes(&self) -> Result<Vec<u8>, FormatError> {
        canonical_json::to_vec(self)
    }

    /// The release id: SHA-256 of the canonical bytes.
    pub fn id(&self) -> Result<ObjectId, FormatError> {
        Ok(ObjectId::of_bytes(&self.to_canonical_bytes()?))
    }

    /// Decodes manifest bytes, checking the schema's major version and the manifest rules.
    /// Unknown fields are ignored, as the spec requires of readers.
    pub fn from_bytes(bytes: &[u8]) -> Result<Release, FormatError> {
        let v: Value = serde_json::from_slice(bytes).map_err(|e| FormatError::InvalidJson {
            what: "release manifest",
            message: e.to_string(),
        })?;
        let schema = v.get("schema").and_then(Value::as_str).unwrap_or_default();
        check_schema(schema)?;
        let r: Release = serde_json::from_value(v).map_err(|e| FormatError::InvalidJson {
            what: "release manifest",
            message: e.to_string(),
        })?;
        r.validate()?;
        Ok(r)
    }

    /// `name@version`.
    pub fn label(&self) -> String {
        format!("{}@{}", self.name, self.version)
    }

    /// Finds an entry by name.
    pub fn entry(&self, name: &str) -> Option<&Entry> {
        self.entries
            .binary_search_by(|e| e.name.as_str().cmp(name))
            .ok()
            .and_then(|i| self.entries.get(i))
    }

    /// Every object reference of the release (not counting the manifest itself), with the
    /// entry name and a role path (`role` or `tile/L/X/Y/role`).
    pub fn file_refs(&self) -> Vec<(&str, String, &FileRef)> {
        let mut out = Vec::new();
        for e in &self.entries {
            for (role, f) in &e.files {
                out.push((e.name.as_str(), role.clone(), f));
            }
            for t in &e.tiles {
                for (role, f) in &t.files {
                    out.push((
                        e.name.as_str(),
                        format!("tile/{}/{}/{}/{role}", t.level, t.x, t.y),
                        f,
                    ));
                }
            }
        }
        out
    }

    /// Sorts entries and tiles into canonical order and checks the rules of the spec.
    pub fn normalise(&mut self) -> Result<(), FormatError> {
        self.entries.sort_by(|a, b| a.name.cmp(&b.name));
        for e in &mut self.entries {
            e.tiles.sort_by_key(|t| (t.level, t.y, t.x));
        }
        self.campaign.inputs.sort_by(|a, b| a.path.cmp(&b.path));
        self.validate()
    }

    /// Checks the manifest rules of SPEC.md §4.
    pub fn validate(&self) -> Result<(), FormatError> {
        check_schema(&self.schema)?;
        check_name("release name", &self.name)?;
        check_name("release version", &self.version)?;
        for pair in self.entries.windows(2) {
            if let [a, b] = pair {
                if a.name >= b.name {
                    return Err(FormatError::InvalidManifest(format!(
                        "entries must be sorted by name and unique: {:?} then {:?}",
                        a.name, b.name
                    )));
                }
            }
        }
        for e in &self.entries {
            check_name("entry name", &e.name)?;
            check_name("entry kind", &e.kind)?;
            if !(e.meta.is_object() || e.meta.is_null()) {
                return Err(FormatError::InvalidManifest(format!(
                    "entry {:?}: meta must be an object",
                    e.name
                )));
            }
            for role in e
                .files
                .keys()
                .chain(e.tiles.iter().flat_map(|t| t.files.keys()))
            {
                check_name("role", role)?;
            }
            if crate::kinds::is_tiled(&e.kind) && e.tiles.is_empty() {
                return Err(FormatError::InvalidManifest(format!(
                    "entry {:?} of kind {:?} must have at least one tile",
                    e.name, e.kind
                )));
            }
        }
        Ok(())
    }
}

impl Entry {
    /// The entry hash: SHA-256 of the entry's canonical JSON. Certificates bind to it.
    pub fn hash(&self) -> Result<ObjectId, FormatError> {
        Ok(ObjectId::of_bytes(&canonical_json::to_vec(self)?))
    }

    /// The level-0 tile, which covers the whole entry.
    pub fn root_tile(&self) -> Option<&Tile> {
        self.tiles
            .iter()
            .find(|t| t.level == 0 && t.x == 0 && t.y == 0)
    }

    /// Looks a role up in the whole-entry files, then in the root tile.
    pub fn file(&self, role: &str) -> Option<&FileRef> {
        self.files
            .get(role)
            .or_else(|| self.root_tile().and_then(|t| t.files.get(role)))
    }
}

/// Accepts `regolith.db/1` and any `regolith.db/1.<minor>`.
pub fn check_schema(schema: &str) -> Result<(), FormatError> {
    let ok = match schema.strip_prefix("regolith.db/") {
        Some(v) => v.split('.').next() == Some("1"),
        None => false,
    };
    if ok {
        Ok(())
    } else {
        Err(FormatError::UnsupportedSchema {
            found: schema.chars().take(80).collect(),
        })
    }
}

/// Names, versions, kinds and roles: 1-128 characters of `[A-Za-z0-9._@/+-]`, not starting with
/// `.` or `/`, and no `..` path segment, so they are safe as export file names.
pub fn check_name(what: &str, s: &str) -> Result<(), FormatError> {
    let ok = !s.is_empty()
        && s.len() <= 128
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"._@/+-".contains(&b))
        && !s.starts_with(['.', '/'])
        && !s.ends_with('/')
        && s.split('/').all(|seg| !seg.is_empty() && seg != "..");
    if ok {
        Ok(())
    } else {
        Err(FormatError::InvalidManifest(format!(
            "{what} {s:?} must be 1-128 characters of [A-Za-z0-9._@/+-], no leading '.' or '/'"
        )))
    }
}

/// A release label with a default schema, for writers.
pub fn new_release(name: &str, version: &str, producer: Producer) -> Release {
    Release {
        schema: SCHEMA.to_string(),
        name: name.to_string(),
        version: version.to_string(),
        parent: None,
        campaign: CampaignRef::default(),
        producer,
        plan: Vec::new(),
        entries: Vec::new(),
        allow_uncertified: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fref(b: &[u8]) -> FileRef {
        FileRef {
            object: ObjectId::of_bytes(b),
            size: b.len() as u64,
            media_type: "application/json".into(),
        }
    }

    fn sample() -> Release {
        let mut r = new_release(
            "t",
            "1.0.0",
            Producer {
                name: "x".into(),
                version: "0".into(),
            },
        );
        r.entries.push(Entry {
            name: "reports/b".into(),
            kind: "report".into(),
            meta: serde_json::json!({"report": "dem"}),
            files: [("report".to_string(), fref(b"b"))].into(),
            tiles: vec![],
        });
        r.entries.push(Entry {
            name: "reports/a".into(),
            kind: "report".into(),
            meta: serde_json::json!({}),
            files: [("report".to_string(), fref(b"a"))].into(),
            tiles: vec![],
        });
        r.normalise().unwrap();
        r
    }

    #[test]
    fn id_is_stable_and_sensitive() {
        let r = sample();
        let bytes = r.to_canonical_bytes().unwrap();
        let back = Release::from_bytes(&bytes).unwrap();
        assert_eq!(back, r);
        assert_eq!(back.id().unwrap(), r.id().unwrap());
        let mut r2 = r.clone();
        r2.entries[0].files.get_mut("report").unwrap().size += 1;
        assert_ne!(r2.id().unwrap(), r.id().unwrap());
        assert_eq!(r.entry("reports/b").unwrap().name, "reports/b");
        assert!(r.entry("nope").is_none());
    }

    #[test]
    fn readers_ignore_unknown_fields_but_not_unknown_major() {
        let r = sample();
        let mut v: Value = serde_json::from_slice(&r.to_canonical_bytes().unwrap()).unwrap();
        v["future_field"] = serde_json::json!({"x": 1});
        v["schema"] = serde_json::json!("regolith.db/1.3");
        assert!(Release::from_bytes(v.to_string().as_bytes()).is_ok());
        v["schema"] = serde_json::json!("regolith.db/2");
        assert!(matches!(
            Release::from_bytes(v.to_string().as_bytes()),
            Err(FormatError::UnsupportedSchema { .. })
        ));
    }

    #[test]
    fn rejects_bad_names_and_untiled_heightfields() {
        assert!(check_name("n", "../etc").is_err());
        assert!(check_name("n", "a/../b").is_err());
        assert!(check_name("n", "laser/0.015").is_ok());
        let mut r = sample();
        r.entries.push(Entry {
            name: "z".into(),
            kind: "heightfield".into(),
            meta: Value::Null,
            files: BTreeMap::new(),
            tiles: vec![],
        });
        assert!(r.validate().is_err());
    }
}
