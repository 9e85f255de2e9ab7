//! `regolith compile CAMPAIGN --check`: load and resolve the campaign, parse every file it
//! references and print the inventory; nothing is written.

use std::path::Path;

use regolith_compiler::ingest::campaign;
use regolith_compiler::inventory;
use regolith_format::limits::Limits;

use super::{human_bytes, print_json};
use crate::Outcome;

pub fn run(path: &Path, check: bool, json: bool) -> anyhow::Result<Outcome> {
    let c = campaign::load(path)?;
    if !check {
        anyhow::bail!("only `regolith compile --check` is available in this version");
    }
    let inv = inventory::inventory(&c, &Limits::default())?;
    if json {
        print_json(&inv)?;
        return Ok(Outcome::Ok);
    }
    println!("campaign {} — {}", inv.campaign, inv.counts);
    for f in &inv.files {
        println!(
            "  {:<44} {:<15} {:<16} {:>10}  {}",
            f.path,
            f.role,
            f.format,
            human_bytes(f.bytes),
            f.summary
        );
    }
    println!("all {} files parsed; nothing written", inv.files.len());
    Ok(Outcome::Ok)
}
