//! `regolith compile CAMPAIGN --db DB [--release NAME@VERSION]`: compile a campaign into a new
//! release, with a progress bar on a terminal and a one-line summary per stage otherwise;
//! `--check` parses every referenced file and prints an inventory without writing anything.

use std::path::Path;

use regolith_compiler::compile;
use regolith_compiler::ingest::campaign;
use regolith_compiler::inventory;
use regolith_format::limits::Limits;
use regolith_reader::{Location, Writer};

use super::{human_bytes, print_json};
use crate::progress::Progress;
use crate::Outcome;

pub fn run(
    path: &Path,
    check: bool,
    db: Option<&Location>,
    release: Option<&str>,
    json: bool,
) -> anyhow::Result<Outcome> {
    let c = campaign::load(path)?;
    if check {
        let inv = inventory::inventory(&c, &Limits::default())?;
        if json {
            print_json(&inv)?;
            return Ok(Outcome::Ok);
        }
        say!("campaign {} — {}", inv.campaign, inv.counts);
        for f in &inv.files {
            say!(
                "  {:<44} {:<15} {:<16} {:>10}  {}",
                f.path,
                f.role,
                f.format,
                human_bytes(f.bytes),
                f.summary
            );
        }
        say!("all {} files parsed; nothing written", inv.files.len());
        return Ok(Outcome::Ok);
    }
    let Some(db) = db else {
        anyhow::bail!("`regolith compile` needs --db DB (or --check to only parse the campaign)");
    };
    // A compile that fails leaves the database as it was (the compiler takes back its objects);
    // a database folder this run created is removed whole (on an object store the roll-back
    // leaves at most the marker: there is no folder to remove).
    let created = db.as_local().is_some_and(|p| !p.exists());
    let writer = Writer::create_or_open(db)?;
    let progress = Progress::new();
    let opts = compile::options(&c, release);
    let summary = match compile::compile(&c, &writer, &opts, &|stage, f| progress.report(stage, f))
    {
        Ok(s) => s,
        Err(e) => {
            drop(writer);
            if let (true, Some(path)) = (created, db.as_local()) {
                // Best effort: the compile's own error is the one to report.
                let _ = std::fs::remove_dir_all(path);
            }
            return Err(e.into());
        }
    };
    progress.finish();
    if json {
        print_json(&summary)?;
        return Ok(Outcome::Ok);
    }
    say!(
        "release {} id {}{}",
        summary.release,
        summary.id,
        if summary.cached {
            " (unchanged inputs: cached)"
        } else {
            ""
        }
    );
    for (stage, s) in &summary.stage_seconds {
        say!("  {stage:<20} {s:>7.2} s");
    }
    for d in &summary.dem {
        say!(
            "  {:<24} area {:.3} m², volume {:.4} m³, {} points, {} triangles",
            d["entry"].as_str().unwrap_or(""),
            d["area_m2"].as_f64().unwrap_or(0.0),
            d["volume_m3"].as_f64().unwrap_or(0.0),
            d["points"],
            d["triangles"]
        );
    }
    for t in summary.registration.as_array().into_iter().flatten() {
        let r = &t["radiometry"];
        if let (Some(slope), Some(before), Some(after)) = (
            r["range_slope_db_per_m"].as_f64(),
            r["disagreement_before_db"].as_f64(),
            r["disagreement_after_db"].as_f64(),
        ) {
            let offset = r["scan_offsets_db"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|o| o["offset_db"].as_f64())
                .fold(0.0, |m: f64, v| m.max(v.abs()));
            let slope = if r["slope_fitted"] == true {
                format!("range slope {slope:+.3} dB/m")
            } else {
                "range slope not determined by the overlaps".to_string()
            };
            say!(
                "  {:<24} reflectance cross-calibration: {slope}, scan offsets ≤ {offset:.2} dB, scans agree {before:.2} → {after:.2} dB RMS{}",
                t["terrain"].as_str().unwrap_or(""),
                if r["applied"] == true { "" } else { " (implausible: not applied)" }
            );
        }
    }
    for (name, a) in summary.alignment.as_object().into_iter().flatten() {
        let mut line = format!(
            "  {name:<24} SfM alignment: scale {:.5}",
            a["scale"].as_f64().unwrap_or(f64::NAN)
        );
        if let Some(rms) = a["rms_m"].as_f64() {
            line.push_str(&format!(", laser ICP RMS {:.2} mm", rms * 1e3));
        }
        if let (Some(method), Some(rms)) = (a["method"].as_str(), a["gcp_rms_m"].as_f64()) {
            let residuals = a["gcp_residuals_m"].as_object();
            let worst = residuals
                .into_iter()
                .flatten()
                .filter_map(|(k, v)| Some((k, v.as_f64()?)))
                .max_by(|x, y| x.1.total_cmp(&y.1));
            line.push_str(&format!(
                ", method {method}, GCP RMS {:.2} mm over {} points",
                rms * 1e3,
                residuals.map_or(0, serde_json::Map::len)
            ));
            if let Some((k, v)) = worst {
                line.push_str(&format!(" (largest {:.2} mm at {k})", v * 1e3));
            }
        }
        say!("{line}");
    }
    for w in &summary.warnings {
        say!("  warning: {}", w["message"].as_str().unwrap_or(""));
    }
    say!(
        "{} entries; `regolith inspect {} {}` for details",
        summary.entries.len(),
        db.display(),
        summary.release
    );
    Ok(Outcome::Ok)
}
