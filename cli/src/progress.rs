//! Progress of long work on stderr, shared by every command that runs for more than a moment:
//! an indicatif bar with the elapsed time and the current step on a terminal, one line per step
//! where stderr is a log (CI, `2> file`). `--json` changes stdout only: a user waiting minutes
//! for `validate --json > cert.json` still wants to know what it is doing, so progress stays on
//! stderr; `--quiet` silences it. It also times the steps, so a command can say where its time
//! went.

use std::io::IsTerminal;
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

/// `--quiet`: set once by `main` for the whole process, as the display is the process's.
static QUIET: OnceLock<bool> = OnceLock::new();

/// Silences every later [`Progress`] (`--quiet`).
pub fn set_quiet(quiet: bool) {
    // Set once, before any command runs; a second call keeps the first value.
    let _ = QUIET.set(quiet);
}

/// A command's progress display and step clock.
pub struct Progress {
    bar: ProgressBar,
    /// Print one line per step (stderr is not a terminal and not `--quiet`).
    lines: bool,
    /// Each step's label and when it began, in order.
    steps: Mutex<Vec<(String, Instant)>>,
}

impl Default for Progress {
    fn default() -> Progress {
        Progress::new()
    }
}

impl Progress {
    /// A display on stderr, silent after [`set_quiet`].
    pub fn new() -> Progress {
        let quiet = QUIET.get().copied().unwrap_or(false);
        let tty = std::io::stderr().is_terminal();
        let bar = if tty && !quiet {
            ProgressBar::new(1000)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template("{spinner} {elapsed:>4} [{bar:30}] {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        Progress {
            bar,
            lines: !tty && !quiet,
            steps: Mutex::new(Vec::new()),
        }
    }

    /// `step` is under way, `fraction` (0–1) of the whole done. A step is timed from the first
    /// report that names it to the first that names another.
    pub fn report(&self, step: &str, fraction: f64) {
        // `+ 0.0` turns a −0 (an empty float sum is −0) into 0, which prints without a sign.
        let fraction = fraction.clamp(0.0, 1.0) + 0.0;
        let mut steps = self.steps.lock().unwrap_or_else(|p| p.into_inner());
        if steps.last().is_none_or(|(last, _)| last != step) {
            steps.push((step.to_string(), Instant::now()));
            if self.lines {
                eprintln!("[{:>3.0}%] {step}", fraction * 100.0);
            }
        }
        self.bar.set_message(step.to_string());
        self.bar.set_position((fraction * 1000.0) as u64);
    }

    /// A reporter for one part of the work, which spans `lo..hi` of the whole: its steps are
    /// shown as `part: step`, its fractions mapped into that span.
    pub fn part<'a>(&'a self, part: &'a str, lo: f64, hi: f64) -> impl Fn(&str, f64) + Sync + 'a {
        move |step, f| self.report(&format!("{part}: {step}"), lo + (hi - lo) * f)
    }

    /// Runs `f` (which prints to stdout) with the bar out of the way.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bar.suspend(f)
    }

    /// Clears the bar; each step's label and duration in seconds, in order.
    pub fn finish(self) -> Vec<(String, f64)> {
        self.bar.finish_and_clear();
        let end = Instant::now();
        let steps = self.steps.into_inner().unwrap_or_else(|p| p.into_inner());
        let ends: Vec<Instant> = steps.iter().skip(1).map(|s| s.1).chain([end]).collect();
        steps
            .into_iter()
            .zip(ends)
            .map(|((label, start), end)| (label, (end - start).as_secs_f64()))
            .collect()
    }
}
