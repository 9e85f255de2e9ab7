//! `regolith inspect DB [RELEASE [ENTRY]]`: what a database, a release or an entry holds.

use regolith_format::kinds;
use regolith_format::Entry;
use regolith_reader::database::{RELEASES_PREFIX, UNITS_PREFIX};
use regolith_reader::{Database, Location, ReleaseView};
use serde_json::{json, Value};

use super::{human_bytes, print_json};
use crate::Outcome;

pub fn run(
    db: &Location,
    release: Option<&str>,
    entry: Option<&str>,
    json_out: bool,
) -> anyhow::Result<Outcome> {
    let database = Database::open(db)?;
    match (release, entry) {
        (None, _) => database_summary(&database, json_out)?,
        (Some(r), None) => release_summary(&database.release(r)?, json_out)?,
        (Some(r), Some(e)) => entry_summary(&database.release(r)?, e, json_out)?,
    }
    Ok(Outcome::Ok)
}

fn database_summary(db: &Database, json_out: bool) -> anyhow::Result<()> {
    let refs = db.refs()?;
    let mut releases = Vec::new();
    for (label, id) in db.releases()? {
        let view = db.release_by_id(&id)?;
        let size: u64 = view
            .manifest
            .file_refs()
            .iter()
            .map(|(_, _, f)| f.size)
            .sum();
        releases.push(json!({"release": label, "id": id.to_hex(), "entries": view.entries().len(), "bytes": size,
            "parent": view.manifest.parent.map(|p| p.to_hex())}));
    }
    if json_out {
        let refs: serde_json::Map<String, Value> = refs
            .iter()
            .map(|(k, v)| (k.clone(), json!(v.to_hex())))
            .collect();
        return print_json(&json!({"releases": releases, "refs": refs}));
    }
    say!("{} release(s) in {}", releases.len(), db.location());
    for r in &releases {
        say!(
            "  {:<32} {}  {:>3} entries  {}",
            r["release"].as_str().unwrap_or_default(),
            &r["id"]
                .as_str()
                .unwrap_or_default()
                .get(..12)
                .unwrap_or_default(),
            r["entries"],
            human_bytes(r["bytes"].as_u64().unwrap_or(0))
        );
    }
    // Unit results of sharded validations can be thousands: counted, not listed (`--json`
    // lists every ref).
    let units = refs.keys().filter(|k| k.starts_with(UNITS_PREFIX)).count();
    for (name, id) in refs
        .iter()
        .filter(|(k, _)| !k.starts_with(RELEASES_PREFIX) && !k.starts_with(UNITS_PREFIX))
    {
        say!("  ref {name} -> {}", id.short());
    }
    if units > 0 {
        say!("  {units} unit result(s) of sharded validations ({UNITS_PREFIX}…)");
    }
    Ok(())
}

fn entry_size(e: &Entry) -> u64 {
    e.files
        .values()
        .chain(e.tiles.iter().flat_map(|t| t.files.values()))
        .map(|f| f.size)
        .sum()
}

/// One line describing an entry's content from its metadata.
fn describe(e: &Entry) -> String {
    let m = &e.meta;
    match e.kind.as_str() {
        kinds::HEIGHTFIELD => format!(
            "{}x{} cells of {} m, z {} m, {} valid",
            m["width"], m["height"], m["cell_m"], m["z_range_m"], m["valid_cells"]
        ),
        kinds::MESH => format!(
            "{} LOD(s), lod0 {} triangles",
            m["lods"].as_array().map_or(0, Vec::len),
            m["lods"][0]["triangles"]
        ),
        kinds::CAMERA => format!(
            "{}x{} fx {} fy {}",
            m["model"]["width"], m["model"]["height"], m["model"]["fx"], m["model"]["fy"]
        ),
        kinds::REPORT => format!("report {}", m["report"].as_str().unwrap_or("?")),
        _ => String::new(),
    }
}

fn release_summary(view: &ReleaseView, json_out: bool) -> anyhow::Result<()> {
    if json_out {
        return print_json(&json!({"id": view.id.to_hex(), "manifest": view.manifest}));
    }
    let m = &view.manifest;
    say!("release {}  id {}", view.label(), view.id);
    if let Some(p) = m.parent {
        say!("parent  {p}");
    }
    say!("producer {} {}", m.producer.name, m.producer.version);
    say!(
        "campaign {} ({} input files)",
        m.campaign.name,
        m.campaign.inputs.len()
    );
    if m.allow_uncertified == Some(true) {
        say!("published WITHOUT passing certificates (--allow-uncertified)");
    }
    say!("{} entries:", m.entries.len());
    for e in &m.entries {
        say!(
            "  {:<28} {:<12} {:>10}  {}",
            e.name,
            e.kind,
            human_bytes(entry_size(e)),
            describe(e)
        );
    }
    Ok(())
}

fn entry_summary(view: &ReleaseView, name: &str, json_out: bool) -> anyhow::Result<()> {
    let e = view.entry(name)?;
    let body = if e.kind == kinds::REPORT || e.kind == kinds::SENSOR_MODEL {
        let role = if e.kind == kinds::REPORT {
            kinds::roles::REPORT
        } else {
            kinds::roles::MODEL
        };
        Some(view.read_json::<Value>(name, role, "JSON body")?)
    } else {
        None
    };
    if json_out {
        return print_json(
            &json!({"release": view.label(), "entry": e, "entry_hash": e.hash()?.to_hex(), "body": body}),
        );
    }
    say!("{} in {} ({})", e.name, view.label(), e.kind);
    say!("entry hash {}", e.hash()?);
    say!("{}", describe(e));
    for (role, f) in &e.files {
        say!(
            "  {role:<16} {}  {:>10}  {}",
            f.object.short(),
            human_bytes(f.size),
            f.media_type
        );
    }
    for t in &e.tiles {
        for (role, f) in &t.files {
            say!(
                "  tile {}/{}/{} {role:<10} {}  {:>10}  {}",
                t.level,
                t.x,
                t.y,
                f.object.short(),
                human_bytes(f.size),
                f.media_type
            );
        }
    }
    say!("meta:\n{}", serde_json::to_string_pretty(&e.meta)?);
    if let Some(b) = body {
        say!("{}:\n{}", e.kind, serde_json::to_string_pretty(&b)?);
    }
    Ok(())
}
