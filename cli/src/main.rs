//! The `regolith` binary: parse arguments, run one command, map the outcome to an exit code
//! (0 ok, 1 check failed, 2 usage or input error). Panics are caught and reported as bugs so
//! a user never sees a raw backtrace.

mod args;
mod commands;

use std::process::ExitCode;

use clap::Parser;

/// What a command reports back to `main`.
pub enum Outcome {
    /// Success.
    Ok,
    /// The command ran but a check failed (exit 1).
    CheckFailed,
}

fn main() -> ExitCode {
    let cli = args::Cli::parse();
    let result = std::panic::catch_unwind(|| commands::run(&cli));
    match result {
        Ok(Ok(Outcome::Ok)) => ExitCode::SUCCESS,
        Ok(Ok(Outcome::CheckFailed)) => ExitCode::from(1),
        Ok(Err(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
        Err(_) => {
            eprintln!("error: internal error (this is a bug in regolith; please report it with the command line)");
            ExitCode::from(3)
        }
    }
}
