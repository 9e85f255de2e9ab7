//! `regolith export DB RELEASE ENTRY --to DIR`: plain files under fixed names for simulators
//! that want a file path. Everything is written into a temp folder beside DIR and renamed into
//! place at the end, so DIR is complete or absent — never half written.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use regolith_format::kinds::{self, roles};
use regolith_reader::{Database, Location};
use serde_json::json;

use super::print_json;
use crate::args::Profile;
use crate::Outcome;

fn extension(media_type: &str) -> &'static str {
    match media_type {
        kinds::media::PNG => "png",
        kinds::media::EXR => "exr",
        kinds::media::GLB => "glb",
        kinds::media::MCAP => "mcap",
        kinds::media::JSON => "json",
        _ => "bin",
    }
}

fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> anyhow::Result<()> {
    let path = dir.join(name);
    let mut f = fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    f.write_all(bytes)
        .with_context(|| format!("writing {}", path.display()))?;
    f.sync_all()?;
    Ok(())
}

pub fn run(
    db: &Location,
    release: &str,
    entry: &str,
    to: &Path,
    profile: Option<Profile>,
    json_out: bool,
) -> anyhow::Result<Outcome> {
    let database = Database::open(db)?;
    let view = database.release(release)?;
    let e = view.entry(entry)?.clone();
    if to.exists()
        && fs::read_dir(to)
            .map(|mut d| d.next().is_some())
            .unwrap_or(true)
    {
        bail!(
            "output folder {} exists and is not empty: give a new folder (export creates it, \
             whole or not at all) or empty this one",
            to.display()
        );
    }
    let parent = to
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    fs::create_dir_all(parent)?;
    let tmp: PathBuf = parent.join(format!(
        ".{}.tmp-{}",
        to.file_name().and_then(|n| n.to_str()).unwrap_or("export"),
        std::process::id()
    ));
    let _ = fs::remove_dir_all(&tmp);
    fs::create_dir_all(&tmp)?;
    let written = match write_all(&view, &e, &tmp, profile) {
        Ok(w) => w,
        Err(err) => {
            let _ = fs::remove_dir_all(&tmp);
            return Err(err);
        }
    };
    if to.exists() {
        fs::remove_dir(to).with_context(|| format!("replacing empty folder {}", to.display()))?;
    }
    fs::rename(&tmp, to).with_context(|| format!("moving export into {}", to.display()))?;
    if json_out {
        print_json(&json!({"release": view.label(), "entry": entry, "to": to, "files": written}))?;
    } else {
        say!(
            "exported {entry} of {} to {}: {}",
            view.label(),
            to.display(),
            written.join(", ")
        );
    }
    Ok(Outcome::Ok)
}

fn write_all(
    view: &regolith_reader::ReleaseView,
    e: &regolith_format::Entry,
    dir: &Path,
    profile: Option<Profile>,
) -> anyhow::Result<Vec<String>> {
    let mut written = Vec::new();
    let provenance = json!({"release": view.label(), "release_id": view.id.to_hex(), "entry": e.name,
        "entry_hash": e.hash()?.to_hex()});
    if e.kind == kinds::HEIGHTFIELD {
        let hf = view.heightfield(&e.name)?;
        for (role, name) in [
            (roles::HEIGHT, "height.png"),
            (roles::HEIGHT_F32, "height.exr"),
            (roles::MASK, "mask.png"),
        ] {
            write_file(dir, name, &view.read_file(&e.name, role)?)?;
            written.push(name.to_string());
        }
        let m = &hf.meta;
        let sidecar = json!({
            "frame": m.frame, "origin_m": m.origin_m, "origin_is": "centre of cell (0,0), the north-west cell",
            "cell_m": m.cell_m, "width": m.width, "height": m.height, "row_order": m.row_order,
            "z_offset_m": m.z_offset_m, "z_scale_m": m.z_scale_m, "formula": "z = z_offset_m + value * z_scale_m",
            "quantisation_error_m": m.quantisation_error_m, "z_range_m": m.z_range_m,
            "mask": "mask.png: 255 measured, 0 filled/nodata", "holes_filled": m.holes_filled,
            "site_origin_m": m.site_origin_m, "provenance": provenance,
        });
        write_file(
            dir,
            "height.json",
            serde_json::to_string_pretty(&sidecar)?.as_bytes(),
        )?;
        written.push("height.json".into());
        if let Some(p) = profile {
            let (v, stem) = match p {
                Profile::Gazebo => (regolith_compiler::export::gazebo(&hf)?, "height_gazebo"),
                Profile::Unreal => (regolith_compiler::export::unreal(&hf)?, "height_unreal"),
            };
            write_file(dir, &format!("{stem}.png"), &v.png)?;
            write_file(
                dir,
                &format!("{stem}.json"),
                serde_json::to_string_pretty(&v.sidecar)?.as_bytes(),
            )?;
            written.push(format!("{stem}.png"));
            written.push(format!("{stem}.json"));
        }
        return Ok(written);
    }
    if profile.is_some() {
        bail!(
            "--profile applies to heightfield entries; {:?} is a {}",
            e.name,
            e.kind
        );
    }
    let mut files: Vec<(String, &regolith_format::FileRef)> =
        e.files.iter().map(|(r, f)| (r.clone(), f)).collect();
    if let Some(t) = e.root_tile() {
        files.extend(t.files.iter().map(|(r, f)| (r.clone(), f)));
    }
    for (role, f) in files {
        let name = format!("{role}.{}", extension(&f.media_type));
        write_file(dir, &name, &view.read_file(&e.name, &role)?)?;
        written.push(name);
    }
    let meta = json!({"kind": e.kind, "meta": e.meta, "provenance": provenance});
    write_file(
        dir,
        "entry.json",
        serde_json::to_string_pretty(&meta)?.as_bytes(),
    )?;
    written.push("entry.json".into());
    Ok(written)
}
