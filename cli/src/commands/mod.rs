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
mod shell_support;
mod validate;
mod verify;

use crate::args::{Cli, Command};
use crate::paths::{absolute as abs, absolute_opt as abs_opt, db_location as loc};
use crate::Outcome;

pub use validate::Shard;

/// Runs the parsed command. Every path argument goes through [`crate::paths`] first, so each
/// command sees an absolute path whatever form the user typed, and every DB argument becomes a
/// [`regolith_reader::Location`] (a folder or an object-store URL).
pub fn run(cli: &Cli) -> anyhow::Result<Outcome> {
    match &cli.command {
        Command::Verify { db } => verify::run(&loc(db)?, cli.json),
        Command::Inspect { db, release, entry } => {
            inspect::run(&loc(db)?, release.as_deref(), entry.as_deref(), cli.json)
        }
        Command::Export {
            db,
            release,
            entry,
            to,
            profile,
        } => export::run(&loc(db)?, release, entry, &abs(to)?, *profile, cli.json),
        Command::Gc { db, grace_seconds } => gc::run(&loc(db)?, *grace_seconds, cli.json),
        Command::Control {
            db,
            release,
            entry,
            texture_blur_m,
        } => control::run(&loc(db)?, release, entry, *texture_blur_m, cli.json),
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
            &loc(db)?,
            release,
            entry,
            captures,
            cameras,
            *apply,
            *min_share,
            abs_opt(report.as_deref())?.as_deref(),
            cli.json,
        ),
        Command::Release {
            db,
            release,
            publish,
            allow_uncertified,
        } => release::run(&loc(db)?, release, *publish, *allow_uncertified, cli.json),
        Command::Validate {
            db,
            release,
            entry,
            detector,
            thresholds,
            report,
            shard,
            merge,
        } => validate::run(
            &validate::Request {
                db: &loc(db)?,
                release,
                entries: entry,
                detectors: detector,
                thresholds: abs_opt(thresholds.as_deref())?.as_deref(),
                report: abs_opt(report.as_deref())?.as_deref(),
                json: cli.json,
            },
            match (shard, merge) {
                (Some(s), _) => validate::Mode::Shard(*s),
                (None, true) => validate::Mode::Merge,
                (None, false) => validate::Mode::Whole,
            },
        ),
        Command::Compile {
            campaign,
            db,
            release,
            check,
        } => compile::run(
            &abs(campaign)?,
            *check,
            db.as_deref().map(loc).transpose()?.as_ref(),
            release.as_deref(),
            cli.json,
        ),
        Command::Corpus { action } => corpus::run(action, cli.json),
        Command::Features { action } => features::run(action, cli.json),
        Command::Completions { shell } => shell_support::completions(*shell),
        Command::Manpage { dir } => shell_support::manpage(abs_opt(dir.as_deref())?.as_deref()),
        Command::Demo { campaign, out } => demo::run(&abs(campaign)?, &abs(out)?, cli.json),
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
