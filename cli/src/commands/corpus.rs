//! `regolith corpus generate`: a synthetic campaign with ground truth, with a progress bar.

use std::path::Path;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use regolith_corpus::{effects, generate, GenerateOptions, Preset};

use super::print_json;
use crate::args::{CorpusAction, PresetArg};
use crate::Outcome;

pub fn run(action: &CorpusAction, json: bool) -> anyhow::Result<Outcome> {
    let CorpusAction::Generate {
        preset,
        seed,
        full,
        captures,
        hidden_effect,
        effect_param,
        out,
        bad_inputs,
    } = action;
    let mut hidden = match hidden_effect {
        Some(list) => effects::parse_list(list)?,
        None => Vec::new(),
    };
    for p in effect_param {
        effects::apply_param(&mut hidden, p)?;
    }
    let opts = GenerateOptions {
        preset: match preset {
            PresetArg::Estec => Preset::Estec,
            PresetArg::Mini => Preset::Mini,
        },
        seed: *seed,
        full: *full,
        captures: captures.map(|n| n as usize),
        hidden,
    };
    let bar = if json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(1000)
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} {elapsed:>4} [{bar:30}] {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let progress = |stage: &str, f: f64| {
        bar.set_message(stage.to_string());
        bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
    };
    let summary = generate(&opts, out, &progress)
        .with_context(|| format!("generating into {}", out.display()))?;
    bar.finish_and_clear();
    let bad = match bad_inputs {
        Some(dir) => Some(regolith_corpus::write_bad_inputs(dir)?),
        None => None,
    };
    if json {
        print_json(&serde_json::json!({
            "out": out, "files": summary.files, "captures": summary.captures,
            "scan_points": summary.scan_points, "bad_inputs": bad,
        }))?;
    } else {
        let points: usize = summary.scan_points.iter().map(|s| s.1).sum();
        say!(
            "wrote {} files to {} ({} scans, {points} points, {} captures); truth in {}",
            summary.files.len(),
            out.display(),
            summary.scan_points.len(),
            summary.captures,
            Path::new(out).join("truth").display()
        );
        if let (Some(dir), Some(b)) = (bad_inputs, bad) {
            say!(
                "wrote {} malformed inputs to {} (see its README.md)",
                b.len(),
                dir.display()
            );
        }
    }
    Ok(Outcome::Ok)
}
