//! `regolith gc DB`: remove unreachable objects under the write lock.

use std::path::Path;

use regolith_reader::Writer;

use super::{human_bytes, print_json};
use crate::Outcome;

pub fn run(db: &Path, json: bool) -> anyhow::Result<Outcome> {
    regolith_reader::Database::open(db)?;
    let writer = Writer::create_or_open(db)?;
    let report = writer.gc()?;
    if json {
        print_json(&report)?;
    } else {
        say!(
            "kept {} object(s), removed {} ({} freed)",
            report.kept,
            report.removed,
            human_bytes(report.bytes_freed)
        );
    }
    Ok(Outcome::Ok)
}
