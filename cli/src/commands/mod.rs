//! One module per subcommand; each returns an [`Outcome`] or an error (exit 2).

mod compile;
mod control;
mod corpus;
mod demo;
mod export;
mod features;
mod gap;
mod gc;
mod inspect;
mod release;
mod validate;
mod verify;

use crate::args::{Cli, Command};
use crate::Outcome;

/// Runs the parsed command.
pub fn run(cli: &Cli) -> anyhow::Result<Outcome> {
    match &cli.command {
        Command::Verify { db } => verify::run(db, cli.json),
        Command::Inspect { db, release, entry } => {
            inspect::run(db, release.as_deref(), entry.as_deref(), cli.json)
        }
        Command::Export {
            db,
            release,
            entry,
            to,
            profile,
        } => export::run(db, release, entry, to, *profile, cli.json),
        Command::Gc { db } => gc::run(db, cli.json),
        Command::Control {
            db,
            release,
            entry,
            texture_blur_m,
        } => control::run(db, release, entry, *texture_blur_m, cli.json),
        Command::Gap {
            db,
            release,
            entry,
            captures,
            cameras,
            apply,
            min_share,
            report,
        } => gap::run(
            db,
            release,
            entry,
            captures,
            cameras,
            *apply,
            *min_share,
            report.as_deref(),
            cli.json,
        ),
        Command::Release {
            db,
            release,
            publish,
            allow_uncertified,
        } => release::run(db, release, *publish, *allow_uncertified, cli.json),
        Command::Validate {
            db,
            release,
            entry,
            detector,
            thresholds,
            report,
        } => validate::run(
            db,
            release,
            entry,
            detector,
            thresholds.as_deref(),
            report.as_deref(),
            cli.json,
        ),
        Command::Compile {
            campaign,
            db,
            release,
            check,
        } => compile::run(
            campaign,
            *check,
            db.as_deref(),
            release.as_deref(),
            cli.json,
        ),
        Command::Corpus { action } => corpus::run(action, cli.json),
        Command::Features { action } => features::run(action, cli.json),
        Command::Demo { campaign, out } => demo::run(campaign, out, cli.json),
    }
}

/// Prints a value as pretty JSON on stdout.
pub fn print_json(v: &impl serde::Serialize) -> anyhow::Result<()> {
    say!("{}", serde_json::to_string_pretty(v)?);
    Ok(())
}

/// Human-readable byte count.
pub fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} B")
    } else {
        format!("{v:.1} {}", UNITS.get(u).copied().unwrap_or("B"))
    }
}
