//! `regolith demo`: compile the checked-in demo campaign into `<out>/db`, validate every
//! heightfield against the real captures (certificates into the database), verify, and print
//! where everything is. The demo campaign is a `mini` corpus campaign with ground truth.

use std::path::Path;

use anyhow::Context;
use regolith_compiler::compile;
use regolith_format::kinds;
use regolith_reader::{verify, Database, Writer};
use regolith_validator::validate::{validate_entry, ValidateOptions};

use super::print_json;
use crate::Outcome;

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
    let quiet = |_: &str, _: f64| {};
    let summary = compile::compile(
        &c,
        &writer,
        &compile::options(&c, Some("demo@1.0.0")),
        &quiet,
    )?;
    // Validate every laser heightfield against the real captures and store the certificates.
    let db = Database::open(&db_path)?;
    let view = db.release("latest")?;
    let mut certificates = Vec::new();
    for e in view
        .entries()
        .iter()
        .filter(|e| e.kind == kinds::HEIGHTFIELD)
    {
        let cert = validate_entry(&view, &e.name, &ValidateOptions::default())?;
        writer.put_certificate(&view.id, &e.name, &cert)?;
        certificates.push(cert);
    }
    drop(writer);
    let report = verify(&db)?;
    if json {
        print_json(
            &serde_json::json!({"db": db_path, "compile": summary, "verify_ok": report.ok()}),
        )?;
    } else {
        println!(
            "compiled {} ({} entries) into {}",
            summary.release,
            summary.entries.len(),
            db_path.display()
        );
        for d in &summary.dem {
            println!(
                "  DEM {:<14} {} triangles",
                d["entry"].as_str().unwrap_or(""),
                d["triangles"]
            );
        }
        for c in &certificates {
            let sift = c
                .summary
                .get("sift")
                .and_then(|s| s.ratio)
                .map_or(0.0, |r| r.mean);
            println!(
                "  certificate {:<14} {} (SIFT repeatability / real-vs-real ceiling {:.2}; {} failed criteria)",
                c.entry,
                if c.passed { "PASS" } else { "FAIL" },
                sift,
                c.failures.len()
            );
        }
        println!("verify: {}", if report.ok() { "intact" } else { "CORRUPT" });
        println!("next: regolith inspect {} latest", db_path.display());
        println!(
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
