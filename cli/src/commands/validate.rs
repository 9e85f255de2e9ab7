//! `regolith validate DB`: certify terrain entries (heightfields and meshes, by default all of
//! them) against the real captures (see `regolith_validator::validate`); certificates go into
//! the database under `certificates/<release id>/<escaped entry>` (SPEC §2), each under the
//! database's write lock for the write alone. With `--report DIR` the same run also draws an
//! offline HTML report (`regolith_validator::report`).
//!
//! A validation is (entry × view) work, each unit independent of the others. `--shard I/N`
//! computes every N-th unit (from the I-th) and stores each result as an object named by a
//! `units/<key>` ref, the key being the hash of everything the result depends on; `--merge`
//! reads every unit back and writes the certificates a one-process run writes, byte for byte.
//! Shards can run in any number of processes or machines sharing the database; one killed
//! mid-way loses only the units it had not stored, and running it again skips the rest.

use std::path::Path;
use std::str::FromStr;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::Context;
use regolith_format::ObjectId;
use regolith_reader::database::unit_ref;
use regolith_reader::{Database, Location, ReleaseView, Writer};
use regolith_validator::features::Detector;
use regolith_validator::report::ValidationReport;
use regolith_validator::validate::{
    certified_entries, Certificate, Thresholds, ValidateOptions, Validator, ViewArtifacts,
    ViewResult, UNIT_SCHEMA,
};
use serde::{Deserialize, Serialize};

use super::print_json;
use crate::progress::Progress;
use crate::Outcome;

/// The arguments every mode shares.
pub struct Request<'a> {
    pub db: &'a Location,
    pub release: &'a str,
    pub entries: &'a [String],
    pub detectors: &'a [String],
    pub thresholds: Option<&'a Path>,
    pub report: Option<&'a Path>,
    pub json: bool,
}

/// What to do with the units.
pub enum Mode {
    /// Compute every unit and write the certificates.
    Whole,
    /// Compute and store one shard's units.
    Shard(Shard),
    /// Certify from stored units.
    Merge,
}

/// `--shard I/N`: the units whose number u (over entries in order, then views) has
/// `u mod N = I − 1`. Round robin spreads every entry's views over the shards, so shards of a
/// multi-entry validation take about equally long.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 1-based.
    pub index: usize,
    pub count: usize,
}

impl FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || format!("`{s}` is not a shard: expected I/N with 1 ≤ I ≤ N, e.g. 2/4");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// A unit's stored result: what it is the result of (checked on reading), and the result.
#[derive(Serialize, Deserialize)]
struct UnitRecord {
    schema: String,
    release_id: String,
    entry: String,
    capture: String,
    camera: String,
    result: ViewResult,
}

pub fn run(req: &Request<'_>, mode: Mode) -> anyhow::Result<Outcome> {
    let database = Database::open(req.db)?;
    let view = database.release(req.release)?;
    let mut opts = ValidateOptions::default();
    if !req.detectors.is_empty() {
        opts.detectors = req
            .detectors
            .iter()
            .map(|d| d.parse::<Detector>())
            .collect::<Result<_, _>>()?;
    }
    if let Some(path) = req.thresholds {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        opts.thresholds = serde_json::from_str::<Thresholds>(&text)
            .with_context(|| format!("thresholds file {}", path.display()))?;
    }
    let names: Vec<String> = if req.entries.is_empty() {
        certified_entries(&view)
    } else {
        req.entries.to_vec()
    };
    anyhow::ensure!(
        !names.is_empty(),
        "release {} has no heightfield or mesh entry to validate",
        view.label()
    );
    // Every entry named must exist before the first result is written.
    for name in &names {
        view.entry(name)?;
    }
    // One validator for every entry: the real frames' side is made once (see `Validator`).
    let validator = Validator::new(&view, opts)?;
    match mode {
        Mode::Whole => whole(req, &view, &validator, &names),
        Mode::Shard(shard) => run_shard(req, &database, &view, &validator, &names, shard),
        Mode::Merge => merge(req, &database, &view, &validator, &names),
    }
}

/// Computes every unit in this process and writes the certificates (and the report).
fn whole(
    req: &Request<'_>,
    view: &ReleaseView,
    validator: &Validator<'_>,
    names: &[String],
) -> anyhow::Result<Outcome> {
    let mut html = match req.report {
        Some(dir) => Some(
            ValidationReport::new(dir, &view.label(), &view.id.to_hex())
                .with_context(|| format!("report folder {}", dir.display()))?,
        ),
        None => None,
    };
    let mut certs = Certified::new(req, view);
    // Progress counts views: each entry is rendered and compared at every camera of every capture.
    let total = (names.len() * validator.views().len()).max(1) as f64;
    let done = AtomicUsize::new(0);
    for (k, name) in names.iter().enumerate() {
        let step = format!("validating {name} ({}/{})", k + 1, names.len());
        certs
            .progress
            .report(&step, done.load(Ordering::Relaxed) as f64 / total);
        let tick = |_: &ViewArtifacts<'_>| {
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            certs.progress.report(&step, d as f64 / total);
        };
        let cert = match html.as_mut() {
            Some(r) => r
                .validate_entry(validator, name, &tick)
                .map_err(anyhow::Error::from),
            None => validator
                .entry(name, Some(&tick))
                .map_err(anyhow::Error::from),
        }
        .with_context(|| format!("validating {name}"))?;
        certs.write(name, &cert)?;
    }
    let index = match html {
        Some(r) => Some(r.finish().context("writing the report")?),
        None => None,
    };
    certs.finish(index.as_deref())
}

/// Computes the units of `shard` that are not stored yet and stores them.
fn run_shard(
    req: &Request<'_>,
    database: &Database,
    view: &ReleaseView,
    validator: &Validator<'_>,
    names: &[String],
    shard: Shard,
) -> anyhow::Result<Outcome> {
    let n_views = validator.views().len();
    // Per entry, this shard's views that have no stored result yet.
    let mut todo: Vec<(&String, Vec<(usize, ObjectId)>)> = Vec::new();
    let (mut mine, mut reused) = (0usize, 0usize);
    for (e, name) in names.iter().enumerate() {
        let mut ks = Vec::new();
        for k in 0..n_views {
            if (e * n_views + k) % shard.count != shard.index - 1 {
                continue;
            }
            mine += 1;
            let key = validator.unit_key(name, k)?;
            if database.read_ref(&unit_ref(&key))?.is_some() {
                reused += 1;
            } else {
                ks.push((k, key));
            }
        }
        if !ks.is_empty() {
            todo.push((name, ks));
        }
    }
    let progress = Progress::new();
    let total = (mine - reused).max(1) as f64;
    let done = AtomicUsize::new(0);
    for (name, units) in &todo {
        let step = format!("validating {name}, shard {shard}");
        progress.report(&step, done.load(Ordering::Relaxed) as f64 / total);
        let tick = |_: &ViewArtifacts<'_>| {
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress.report(&step, d as f64 / total);
        };
        let ks: Vec<usize> = units.iter().map(|(k, _)| *k).collect();
        let results = validator
            .view_results(name, &ks, Some(&tick))
            .with_context(|| format!("validating {name}"))?;
        // Stored per entry: a shard killed later keeps these.
        progress.suspend(|| -> anyhow::Result<()> {
            let w = open_writer(req.db)?;
            for ((k, key), result) in units.iter().zip(results) {
                let (capture, camera) = &validator.views()[*k];
                let record = UnitRecord {
                    schema: UNIT_SCHEMA.into(),
                    release_id: view.id.to_hex(),
                    entry: (*name).clone(),
                    capture: capture.clone(),
                    camera: camera.clone(),
                    result,
                };
                let f = w.put_json(&record)?;
                w.set_ref(&unit_ref(key), &f.object)?;
            }
            Ok(())
        })?;
    }
    let computed = mine - reused;
    if req.json {
        print_json(
            &serde_json::json!({"release": view.label(), "release_id": view.id.to_hex(),
            "shard": shard.to_string(), "units": mine, "computed": computed, "reused": reused}),
        )?;
    } else {
        say!(
            "shard {shard} of {}: {mine} units ({computed} computed, {reused} already stored); run every shard, then `regolith validate --merge`",
            view.label()
        );
    }
    Ok(Outcome::Ok)
}

/// Writes the certificates from the stored units of every shard.
fn merge(
    req: &Request<'_>,
    database: &Database,
    view: &ReleaseView,
    validator: &Validator<'_>,
    names: &[String],
) -> anyhow::Result<Outcome> {
    let views = validator.views();
    // Read every unit before writing anything: a merge with a shard missing writes nothing.
    let mut per_entry = Vec::new();
    let mut missing = Vec::new();
    for name in names {
        let mut results = Vec::new();
        for (k, (capture, camera)) in views.iter().enumerate() {
            let key = validator.unit_key(name, k)?;
            let Some(id) = database.read_ref(&unit_ref(&key))? else {
                missing.push(format!("{name} at {capture} {camera}"));
                continue;
            };
            let bytes = regolith_reader::object::read_verified(
                database.store().as_ref(),
                &id,
                None,
                &regolith_reader::object::Site::new(name, "validation unit"),
            )?;
            let record: UnitRecord = serde_json::from_slice(&bytes).with_context(|| {
                format!(
                    "the stored unit {} ({name} at {capture} {camera}) is not a unit result",
                    id.short()
                )
            })?;
            anyhow::ensure!(
                record.schema == UNIT_SCHEMA
                    && record.release_id == view.id.to_hex()
                    && record.entry == *name
                    && (&record.capture, &record.camera) == (capture, camera),
                "the stored unit {} is not the result of {name} at {capture} {camera} of release {} (the database is damaged: run `regolith verify`)",
                id.short(),
                view.label()
            );
            results.push(record.result);
        }
        per_entry.push((name, results));
    }
    if !missing.is_empty() {
        let shown = missing
            .iter()
            .take(5)
            .cloned()
            .collect::<Vec<_>>()
            .join("; ");
        anyhow::bail!(
            "{} of {} units have no stored result ({shown}{}): run every shard first (`regolith validate --shard I/N` for I = 1..N, with the same release, entries, detectors and thresholds); nothing was written",
            missing.len(),
            names.len() * views.len(),
            if missing.len() > 5 { "; …" } else { "" }
        );
    }
    let mut certs = Certified::new(req, view);
    for (name, results) in per_entry {
        let cert = validator
            .certify(name, results)
            .with_context(|| format!("certifying {name}"))?;
        certs.write(name, &cert)?;
    }
    certs.finish(None)
}

/// Certificates written so far, their printout and the JSON summary.
struct Certified<'a> {
    req: &'a Request<'a>,
    view: &'a ReleaseView,
    progress: Progress,
    all_pass: bool,
    out: Vec<serde_json::Value>,
}

impl<'a> Certified<'a> {
    fn new(req: &'a Request<'a>, view: &'a ReleaseView) -> Certified<'a> {
        Certified {
            req,
            view,
            progress: Progress::new(),
            all_pass: true,
            out: Vec::new(),
        }
    }

    /// Stores `cert` and prints it. The database is locked for the write alone, not for the
    /// validation: several validations (of other entries, or shards) run side by side.
    fn write(&mut self, name: &str, cert: &Certificate) -> anyhow::Result<()> {
        let f = self
            .progress
            .suspend(|| open_writer(self.req.db)?.put_certificate(&self.view.id, name, cert))?;
        self.all_pass &= cert.passed;
        if !self.req.json {
            self.progress
                .suspend(|| print_certificate(name, cert, &f.object.short()));
        }
        self.out.push(serde_json::json!({"entry": name, "certificate": f.object.to_hex(), "passed": cert.passed,
            "failures": cert.failures, "summary": cert.summary}));
        Ok(())
    }

    fn finish(self, index: Option<&Path>) -> anyhow::Result<Outcome> {
        let view = self.view;
        if self.req.json {
            let mut v = serde_json::json!({"release": view.label(), "release_id": view.id.to_hex(), "entries": self.out, "passed": self.all_pass});
            if let Some(index) = index {
                v["report"] = index.display().to_string().into();
            }
            print_json(&v)?;
        } else if let Some(index) = index {
            say!("report: {}", index.display());
        }
        Ok(if self.all_pass {
            Outcome::Ok
        } else {
            Outcome::CheckFailed
        })
    }
}

/// The database's writer, waiting (and saying so) while another process writes.
fn open_writer(db: &Location) -> Result<Writer, regolith_reader::ReaderError> {
    Writer::open_waiting(db, &|| {
        eprintln!("waiting for another process writing to {db}");
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn shards_parse_as_one_based_i_of_n() {
        assert_eq!(
            "2/4".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 4 }
        );
        for bad in ["0/4", "5/4", "1", "a/b", "1/0", "-1/2"] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(e.contains("expected I/N"), "{bad}: {e}");
        }
    }
}
