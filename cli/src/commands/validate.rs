//! `regolith validate DB`: certify terrain entries (heightfields and meshes, by default all of
//! them) against the real captures (see `regolith_validator::validate`); certificates go into
//! the database under `certificates/<release id>/<escaped entry>` (SPEC §2), each under the
//! database's write lock for the write alone. With `--report DIR` the same run also draws an
//! offline HTML report (`regolith_validator::report`).

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::Context;
use regolith_reader::{Database, Writer};
use regolith_validator::features::Detector;
use regolith_validator::report::ValidationReport;
use regolith_validator::validate::{
    certified_entries, Certificate, Thresholds, ValidateOptions, Validator, ViewArtifacts,
};

use super::print_json;
use crate::progress::Progress;
use crate::Outcome;

pub fn run(
    db: &Path,
    release: &str,
    entries: &[String],
    detectors: &[String],
    thresholds: Option<&Path>,
    report: Option<&Path>,
    json: bool,
) -> anyhow::Result<Outcome> {
    let database = Database::open(db)?;
    let view = database.release(release)?;
    let mut opts = ValidateOptions::default();
    if !detectors.is_empty() {
        opts.detectors = detectors
            .iter()
            .map(|d| d.parse::<Detector>())
            .collect::<Result<_, _>>()?;
    }
    if let Some(path) = thresholds {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        opts.thresholds = serde_json::from_str::<Thresholds>(&text)
            .with_context(|| format!("thresholds file {}", path.display()))?;
    }
    let names: Vec<String> = if entries.is_empty() {
        certified_entries(&view)
    } else {
        entries.to_vec()
    };
    anyhow::ensure!(
        !names.is_empty(),
        "release {} has no heightfield or mesh entry to validate",
        view.label()
    );
    // Every entry named must exist before the first certificate is written.
    for name in &names {
        view.entry(name)?;
    }
    let mut html = match report {
        Some(dir) => Some(
            ValidationReport::new(dir, &view.label(), &view.id.to_hex())
                .with_context(|| format!("report folder {}", dir.display()))?,
        ),
        None => None,
    };
    let mut all_pass = true;
    let mut out = Vec::new();
    // One validator for every entry: the real frames' side is made once (see `Validator`).
    let validator = Validator::new(&view, opts)?;
    // Progress counts views: each entry is rendered and compared at every camera of every capture.
    let total = (names.len() * validator.views().len()).max(1) as f64;
    let progress = Progress::new();
    let done = AtomicUsize::new(0);
    for (k, name) in names.iter().enumerate() {
        let step = format!("validating {name} ({}/{})", k + 1, names.len());
        progress.report(&step, done.load(Ordering::Relaxed) as f64 / total);
        let tick = |_: &ViewArtifacts<'_>| {
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress.report(&step, d as f64 / total);
        };
        let cert = match html.as_mut() {
            Some(r) => r
                .validate_entry(&validator, name, &tick)
                .map_err(anyhow::Error::from),
            None => validator
                .entry(name, Some(&tick))
                .map_err(anyhow::Error::from),
        }
        .with_context(|| format!("validating {name}"))?;
        // The database is locked for the write alone, not for the validation: several
        // validations (of other entries, or other shards of work) run side by side.
        let f = progress.suspend(|| {
            Writer::open_waiting(db, &|| {
                eprintln!("waiting for another process writing to {}", db.display());
            })?
            .put_certificate(&view.id, name, &cert)
        })?;
        all_pass &= cert.passed;
        if !json {
            progress.suspend(|| print_certificate(name, &cert, &f.object.short()));
        }
        out.push(serde_json::json!({"entry": name, "certificate": f.object.to_hex(), "passed": cert.passed,
            "failures": cert.failures, "summary": cert.summary}));
    }
    let index = match html {
        Some(r) => Some(r.finish().context("writing the report")?),
        None => None,
    };
    if json {
        let mut v = serde_json::json!({"release": view.label(), "release_id": view.id.to_hex(), "entries": out, "passed": all_pass});
        if let Some(index) = &index {
            v["report"] = index.display().to_string().into();
        }
        print_json(&v)?;
    } else if let Some(index) = &index {
        say!("report: {}", index.display());
    }
    Ok(if all_pass {
        Outcome::Ok
    } else {
        Outcome::CheckFailed
    })
}

/// The certificate of `name` as lines of text: verdict, object, then per detector the
/// repeatability figures, then the failed criteria.
fn print_certificate(name: &str, cert: &Certificate, object: &str) {
    say!(
        "{name}: {} (certificate {})",
        if cert.passed { "PASS" } else { "FAIL" },
        object
    );
    for (d, s) in &cert.summary {
        let ceiling = s
            .ceiling
            .map_or("   -  ".to_string(), |c| format!("{:.3}", c.mean));
        let ratio = s.ratio.map_or("   -  ".to_string(), |r| {
            format!("{:.3} [{:.3}, {:.3}]", r.mean, r.low, r.high)
        });
        say!(
            "  {d:<7} re-detected over chance {:.3}  ceiling {ceiling}  ratio {ratio}  one-directional {:.3} (chance {:.3})  ÷min(n) {:.3}",
            s.sim.mean, s.one_directional.mean, s.chance.mean, s.score.mean
        );
    }
    for f in &cert.failures {
        say!("  failed: {f}");
    }
}
