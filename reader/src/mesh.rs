//! Mesh entries: the GLB bytes of each level of detail and a structural summary parsed from
//! the glTF JSON chunk (no full glTF dependency: simulators load the GLB with their own
//! importer; the reader only checks what it hands over).

use regolith_format::kinds::{self, roles};
use serde_json::Value;

use crate::database::ReleaseView;
use crate::error::{ReaderError, Result};

/// Summary of one GLB file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GlbSummary {
    /// Number of meshes.
    pub meshes: usize,
    /// Number of primitives over all meshes.
    pub primitives: usize,
    /// Sum of POSITION accessor counts.
    pub vertices: u64,
    /// Sum of index counts / 3 (triangle lists).
    pub triangles: u64,
    /// Whether every primitive has NORMAL.
    pub normals: bool,
    /// Whether every primitive has TEXCOORD_0.
    pub uvs: bool,
    /// Number of images (embedded textures).
    pub images: usize,
}

/// One level of detail.
#[derive(Debug, Clone)]
pub struct Lod {
    /// The role (`lod0`, `lod1`, ...).
    pub role: String,
    /// The verified GLB bytes.
    pub glb: Vec<u8>,
    /// Its summary.
    pub summary: GlbSummary,
}

fn le_u32(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// The JSON and the BIN chunk (empty when there is none) of a GLB container (glTF 2.0 §4.4),
/// every offset bounds-checked; unknown chunk types are skipped.
pub fn glb_container(b: &[u8]) -> std::result::Result<(Value, &[u8]), String> {
    if b.get(0..4) != Some(b"glTF") {
        return Err("missing glTF magic at byte 0".into());
    }
    if le_u32(b, 4) != Some(2) {
        return Err("expected glTF container version 2 at byte 4".into());
    }
    let total = le_u32(b, 8).ok_or("truncated header")? as usize;
    if total != b.len() {
        return Err(format!("header says {total} bytes, file has {}", b.len()));
    }
    let mut at = 12usize;
    let mut json = None;
    let mut bin: Option<&[u8]> = None;
    while at < b.len() {
        let len = le_u32(b, at).ok_or(format!("truncated chunk header at byte {at}"))? as usize;
        let kind = le_u32(b, at + 4).ok_or(format!("truncated chunk header at byte {at}"))?;
        let data = at
            .checked_add(8)
            .and_then(|s| Some((s, s.checked_add(len)?)))
            .and_then(|(s, e)| b.get(s..e))
            .ok_or(format!(
                "chunk at byte {at} ({len} bytes) runs past the end"
            ))?;
        match (kind, json.is_some()) {
            (0x4E4F_534A, false) => {
                json = Some(
                    serde_json::from_slice::<Value>(data)
                        .map_err(|e| format!("JSON chunk: {e}"))?,
                );
            }
            (_, false) => return Err("first chunk at byte 12 must be JSON".into()),
            (0x004E_4942, true) if bin.is_none() => bin = Some(data),
            _ => {} // unknown chunk types are skipped (glTF 2.0 §4.4.3.3)
        }
        at = at + 8 + len;
    }
    Ok((json.ok_or("no JSON chunk")?, bin.unwrap_or(&[])))
}

/// Parses the GLB container and summarises its glTF JSON.
pub fn summarise_glb(b: &[u8]) -> std::result::Result<GlbSummary, String> {
    let (v, _) = glb_container(b)?;
    let accessors = v
        .get("accessors")
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    let count = |idx: Option<u64>| -> u64 {
        idx.and_then(|i| accessors.get(i as usize))
            .and_then(|a| a.get("count"))
            .and_then(Value::as_u64)
            .unwrap_or(0)
    };
    let meshes = v
        .get("meshes")
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    let mut s = GlbSummary {
        meshes: meshes.len(),
        primitives: 0,
        vertices: 0,
        triangles: 0,
        normals: true,
        uvs: true,
        images: v
            .get("images")
            .and_then(Value::as_array)
            .map_or(0, Vec::len),
    };
    for m in &meshes {
        for p in m
            .get("primitives")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            s.primitives += 1;
            let attrs = p.get("attributes");
            s.vertices += count(
                attrs
                    .and_then(|a| a.get("POSITION"))
                    .and_then(Value::as_u64),
            );
            s.triangles += count(p.get("indices").and_then(Value::as_u64)) / 3;
            s.normals &= attrs.and_then(|a| a.get("NORMAL")).is_some();
            s.uvs &= attrs.and_then(|a| a.get("TEXCOORD_0")).is_some();
        }
    }
    if s.primitives == 0 {
        s.normals = false;
        s.uvs = false;
    }
    Ok(s)
}

impl ReleaseView {
    /// Loads every level of detail of a mesh entry (lod0 first), verified.
    pub fn mesh(&self, entry: &str) -> Result<Vec<Lod>> {
        let e = self.entry_of_kind(entry, kinds::MESH)?;
        let mut lods = Vec::new();
        for n in 0.. {
            let role = roles::lod(n);
            if e.file(&role).is_none() {
                break;
            }
            let glb = self.read_file(entry, &role)?;
            let summary = summarise_glb(&glb).map_err(|message| ReaderError::Decode {
                entry: entry.to_string(),
                what: "GLB",
                message: format!("{role}: {message}"),
            })?;
            lods.push(Lod { role, glb, summary });
        }
        Ok(lods)
    }
}
