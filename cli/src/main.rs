//! The `regolith` binary: parse arguments, run one command, map the outcome to an exit code
//! (0 ok, 1 check failed, 2 usage or input error). Panics are caught and reported as bugs so
//! a user never sees a raw backtrace.

/// `println!` for command output: when stdout is closed early (`regolith … | head`) the process
/// ends quietly with success instead of panicking on the broken pipe.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::say_line(format_args!($($arg)*))
    };
}

mod args;
mod commands;
mod paths;
mod progress;

use std::process::ExitCode;

use clap::Parser;

/// What a command reports back to `main`.
pub enum Outcome {
    /// Success.
    Ok,
    /// The command ran but a check failed (exit 1).
    CheckFailed,
}

/// Writes one line to stdout (see `say!`). A closed pipe ends the process with status 0; any
/// other write error with status 2.
pub fn say_line(args: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.write_all(b"\n")) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: writing to stdout: {e}");
        std::process::exit(2);
    }
}

fn main() -> ExitCode {
    let cli = args::Cli::parse();
    progress::set_quiet(cli.quiet);
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
