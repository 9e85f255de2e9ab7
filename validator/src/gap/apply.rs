//! Step 3 of the gap workflow: the fitted model into a new release.
//!
//! `--apply` never edits a release (releases are immutable): it writes a child release whose
//! `parent` is the examined one, with the same entries plus (or replacing) the `sensor-model`
//! entry `<entry>/sensor-model` (role `model`, canonical JSON, `meta.entry` naming the terrain
//! entry, `meta.fitted_by` the gap run's summary), and version `<version>+gap.<n>` with `n` the
//! first free number; a child of the same release with the same model is reused. `validate` and simulators then use the model
//! ([`crate::sensor::stored_model`]).

use regolith_format::kinds;
use regolith_format::manifest::Entry;
use regolith_format::ObjectId;
use regolith_reader::{ReaderError, ReleaseView, Writer};
use serde_json::json;

use crate::sensor::{model_entry_name, SensorModel};

/// Writes the child release; returns its label and id. `latest` follows when it pointed at
/// the parent.
pub fn write_model(
    writer: &Writer,
    view: &ReleaseView,
    entry: &str,
    model: &SensorModel,
    summary: serde_json::Value,
) -> Result<(String, ObjectId), ReaderError> {
    let file = writer.put_json(model)?;
    let object = file.object;
    let mut m = view.manifest.clone();
    m.parent = Some(view.id);
    let name = model_entry_name(entry);
    m.entries.retain(|e| e.name != name);
    m.entries.push(Entry {
        name,
        kind: kinds::SENSOR_MODEL.to_string(),
        meta: json!({"entry": entry, "fitted_by": summary}),
        files: [(kinds::roles::MODEL.to_string(), file)]
            .into_iter()
            .collect(),
        tiles: Vec::new(),
    });
    m.entries.sort_by(|a, b| a.name.cmp(&b.name));
    let db = writer.database();
    let existing = db.releases()?;
    // The same model already written as a child of this release: reuse it.
    for (label, id) in &existing {
        let child = db.release_by_id(id)?;
        if child.manifest.parent == Some(view.id) {
            if let Some(e) = child
                .manifest
                .entries
                .iter()
                .find(|e| e.name == model_entry_name(entry))
            {
                if e.files.get(kinds::roles::MODEL).map(|f| f.object) == Some(object) {
                    return Ok((label.clone(), *id));
                }
            }
        }
    }
    let base = view.manifest.version.clone();
    let version = (1..)
        .map(|n| format!("{base}+gap.{n}"))
        .find(|v| {
            let label = format!("{}@{v}", m.name);
            !existing.iter().any(|(l, _)| *l == label)
        })
        .unwrap_or(base);
    m.version = version;
    let latest_was_parent = db.read_ref("latest")?.is_some_and(|id| id == view.id);
    let label = m.label();
    let id = writer.commit(m, latest_was_parent)?;
    Ok((label, id))
}
