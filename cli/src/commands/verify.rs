//! `regolith verify DB`: rehash everything reachable; exit 1 with the list of problems.

use anyhow::Context;
use regolith_reader::{Database, Location};

use super::{human_bytes, print_json};
use crate::Outcome;

pub fn run(db: &Location, json: bool) -> anyhow::Result<Outcome> {
    let database = Database::open(db)?;
    let report = regolith_reader::verify(&database)
        .with_context(|| format!("verifying {}", db.display()))?;
    if json {
        print_json(&serde_json::json!({
            "ok": report.ok(),
            "releases": report.releases,
            "objects_checked": report.objects_checked,
            "bytes_checked": report.bytes_checked,
            "problems": report.problems,
        }))?;
    } else {
        for p in &report.problems {
            say!(
                "{}  {}  entry {:?} role {:?} (release {})",
                p.object,
                p.message,
                p.entry,
                p.role,
                p.release
            );
        }
        say!(
            "{}: {} release(s), {} object(s), {} checked, {} problem(s)",
            if report.ok() { "intact" } else { "CORRUPT" },
            report.releases.len(),
            report.objects_checked,
            human_bytes(report.bytes_checked),
            report.problems.len()
        );
    }
    Ok(if report.ok() {
        Outcome::Ok
    } else {
        Outcome::CheckFailed
    })
}
