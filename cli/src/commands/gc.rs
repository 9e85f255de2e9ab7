//! `regolith gc DB [--grace-seconds N]`: remove unreachable objects. In a folder this holds the
//! write lock, so no writer runs meanwhile; on an object store, which has no lock, objects
//! younger than the grace period (default an hour) are kept because they may belong to a
//! release another writer is still committing (SPEC.md §2.1 "Databases on object stores").

use std::time::Duration;

use regolith_reader::{Database, Location, Writer};

use super::{human_bytes, print_json};
use crate::Outcome;

pub fn run(db: &Location, grace_seconds: Option<u64>, json: bool) -> anyhow::Result<Outcome> {
    Database::open(db)?;
    let writer = Writer::create_or_open(db)?;
    let report = match grace_seconds {
        Some(s) => writer.gc_with_grace(Duration::from_secs(s))?,
        None => writer.gc()?,
    };
    if json {
        print_json(&report)?;
    } else {
        say!(
            "kept {} object(s), removed {} ({} freed){}",
            report.kept,
            report.removed,
            human_bytes(report.bytes_freed),
            if report.kept_young > 0 {
                format!(
                    "; kept {} unreachable object(s) younger than the grace period",
                    report.kept_young
                )
            } else {
                String::new()
            }
        );
    }
    Ok(Outcome::Ok)
}
