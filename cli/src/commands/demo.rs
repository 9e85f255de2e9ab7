//! `regolith demo`: compile the checked-in demo campaign into `<out>/db`, validate every
//! heightfield against the real captures (certificates into the database), run one round of the
//! gap workflow on the finest laser entry (the hidden effect is named, written into a child
//! release, and the gap before/after printed next to the campaign's truth), verify, and print
//! where everything is. The demo campaign is a `mini` corpus campaign with ground truth.

use std::path::Path;

use anyhow::Context;
use regolith_compiler::compile;
use regolith_format::kinds;
use regolith_reader::{verify, Database, Writer};
use regolith_validator::gap::{self, apply, GapOptions};
use regolith_validator::validate::{validate_entry, Certificate, ValidateOptions, Validator};

use super::print_json;
use crate::progress::Progress;
use crate::Outcome;

/// One line per certificate: verdict, mean repeatability ratio to the real-vs-real ceiling, and
/// the first failed criterion.
fn print_certificate(c: &Certificate, prefix: &str) {
    say!(
        "  {prefix}certificate {:<14} {} (mean repeatability ratio to the real-vs-real ceiling {}){}",
        c.entry,
        if c.passed { "PASS" } else { "FAIL" },
        c.mean_ratio_to_ceiling
            .map_or("n/a".into(), |r| format!("{:.2}", r.mean)),
        c.failures
            .first()
            .map_or(String::new(), |f| format!(": {f}"))
    );
}

pub fn run(campaign: &Path, out: &Path, json: bool) -> anyhow::Result<Outcome> {
    if !campaign.join("campaign.toml").is_file() {
        anyhow::bail!(
            "demo campaign not found at {} (run from the repository root, or pass --campaign)",
            campaign.display()
        );
    }
    let c = regolith_compiler::ingest::campaign::load(campaign)?;
    let db_path = out.join("db");
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let writer = Writer::create_or_open(&db_path)?;
    // Rough shares of a demo run's time (two cores), for the progress display.
    let progress = Progress::new();
    let summary = compile::compile(
        &c,
        &writer,
        &compile::options(&c, Some("demo@1.0.0")),
        &progress.part("compiling", 0.0, 0.25),
    )?;
    // Validate every laser heightfield against the real captures and store the certificates.
    let db = Database::open(&db_path)?;
    let view = db.release("latest")?;
    let mut certificates = Vec::new();
    let heightfields: Vec<_> = view
        .entries()
        .iter()
        .filter(|e| e.kind == kinds::HEIGHTFIELD)
        .collect();
    let validator = Validator::new(&view, ValidateOptions::default())?;
    for (k, e) in heightfields.iter().enumerate() {
        let done = k as f64 / heightfields.len() as f64;
        progress.report(&format!("validating {}", e.name), 0.25 + 0.25 * done);
        let cert = validator.entry(&e.name, None)?;
        writer.put_certificate(&view.id, &e.name, &cert)?;
        certificates.push(cert);
    }
    // One round of the gap workflow on the finest laser entry: name the hidden effect, write it
    // into a child release, show the gap before and after.
    let finest = view
        .entries()
        .iter()
        .filter(|e| e.kind == kinds::HEIGHTFIELD && e.name.starts_with("laser/"))
        .min_by(|a, b| {
            let cell = |e: &regolith_format::manifest::Entry| {
                e.meta["cell_m"].as_f64().unwrap_or(f64::MAX)
            };
            cell(a).total_cmp(&cell(b))
        })
        .map(|e| e.name.clone());
    let gap_round = match &finest {
        Some(entry) => {
            let result = gap::run_observed(
                &view,
                entry,
                &GapOptions::default(),
                &progress.part(&format!("gap on {entry}"), 0.5, 0.9),
            )?;
            let applied = if result.model_after == result.model_before {
                None
            } else {
                Some(apply::write_model(
                    &writer,
                    &view,
                    entry,
                    &result.model_after,
                    serde_json::json!({"release": view.label(), "named": result.named.iter().map(|n| &n.effect).collect::<Vec<_>>()}),
                )?)
            };
            // The loop closes: the entry is validated again in the child release, through the
            // fitted sensor model.
            let revalidated = match &applied {
                Some((label, _)) => {
                    progress.report(&format!("validating {entry} in {label}"), 0.9);
                    let child = db.release(label)?;
                    let cert = validate_entry(&child, entry, &ValidateOptions::default())?;
                    writer.put_certificate(&child.id, entry, &cert)?;
                    Some(cert)
                }
                None => None,
            };
            Some((result, applied, revalidated))
        }
        None => None,
    };
    let hidden: serde_json::Value = std::fs::read(campaign.join("truth/hidden.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or_default();
    drop(writer);
    progress.report("verifying the database", 0.98);
    let report = verify(&db)?;
    progress.finish();
    if json {
        print_json(
            &serde_json::json!({"db": db_path, "compile": summary, "verify_ok": report.ok(),
            "certificates": certificates.iter().map(|c| serde_json::json!({"entry": c.entry, "passed": c.passed, "failures": c.failures})).collect::<Vec<_>>(),
            "gap": gap_round.as_ref().map(|(r, applied, revalidated)| serde_json::json!({
                "entry": r.entry, "named": r.named, "gap_metric": r.gap_metric,
                "gap_before": r.gap_before, "gap_after": r.gap_after,
                "applied": applied.as_ref().map(|(label, _)| label),
                "revalidated": revalidated.as_ref().map(|c| serde_json::json!({"passed": c.passed, "failures": c.failures})),
                "hidden_truth": hidden["effects"],
            }))}),
        )?;
    } else {
        say!(
            "compiled {} ({} entries) into {}",
            summary.release,
            summary.entries.len(),
            db_path.display()
        );
        for d in &summary.dem {
            say!(
                "  DEM {:<14} {} triangles",
                d["entry"].as_str().unwrap_or(""),
                d["triangles"]
            );
        }
        for c in &certificates {
            print_certificate(c, "");
        }
        if let Some((r, applied, revalidated)) = &gap_round {
            say!("  gap {}:", r.entry);
            if r.named.is_empty() {
                say!("    no effect explains a significant share of the gap");
            }
            for n in &r.named {
                let params: Vec<String> = n
                    .params
                    .iter()
                    .map(|(k, v)| format!("{k} {v:.3}"))
                    .collect();
                say!(
                    "    named {} ({}), explains {:.0} %",
                    n.effect,
                    params.join(", "),
                    100.0 * n.explained_fraction
                );
            }
            if let Some(truth) = hidden["effects"].as_array() {
                say!(
                    "    hidden in the demo campaign (truth/hidden.json): {}",
                    serde_json::Value::Array(truth.clone())
                );
            }
            say!(
                "    {} {:.2} -> {:.2}",
                r.gap_metric.label(),
                r.gap_before,
                r.gap_after
            );
            if let Some((label, _)) = applied {
                say!("    model written to release {label}");
            }
            if let Some(c) = revalidated {
                print_certificate(c, "  (with the fitted model) ");
            }
        }
        say!("verify: {}", if report.ok() { "intact" } else { "CORRUPT" });
        say!("next: regolith inspect {} latest", db_path.display());
        say!(
            "      regolith export {} latest laser/0.01 --to {}/laser-0.01 --profile gazebo",
            db_path.display(),
            out.display()
        );
    }
    Ok(if report.ok() {
        Outcome::Ok
    } else {
        Outcome::CheckFailed
    })
}
