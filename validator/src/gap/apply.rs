//! Step 3 of the gap workflow: the fitted model into a new release.
//!
//! `--apply` never edits a release (releases are immutable): it writes a child release whose
//! `parent` is the examined one, with the same entries plus (or replacing) the `sensor-model`
//! entry `<entry>/sensor-model` (role `model`, canonical JSON, `meta.entry` naming the terrain
//! entry, `meta.fitted_by` the gap run's summary), and version `<version>+gap.<n>` with `n` the
//! first free number; a child of the same release with the same model is reused
//! (`child.rs`). `validate` and simulators then use the model
//! ([`crate::sensor::stored_model`]).

use regolith_format::kinds;
use regolith_format::manifest::Entry;
use regolith_format::ObjectId;
use regolith_reader::{ReaderError, ReleaseView, Writer};
use serde_json::json;

use crate::child::commit_child;
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
    let name = model_entry_name(entry);
    m.entries.retain(|e| e.name != name);
    m.entries.push(Entry {
        name: name.clone(),
        kind: kinds::SENSOR_MODEL.to_string(),
        meta: json!({"entry": entry, "fitted_by": summary}),
        files: [(kinds::roles::MODEL.to_string(), file)]
            .into_iter()
            .collect(),
        tiles: Vec::new(),
    });
    m.entries.sort_by(|a, b| a.name.cmp(&b.name));
    commit_child(writer, view, m, "gap", true, |e| {
        e.name == name && e.files.get(kinds::roles::MODEL).map(|f| f.object) == Some(object)
    })
}
