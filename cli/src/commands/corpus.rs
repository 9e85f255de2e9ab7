//! `regolith corpus generate`: a synthetic campaign with ground truth, with a progress bar.

use std::path::Path;

use anyhow::Context;
use regolith_corpus::{effects, generate, GenerateOptions, Preset};

use super::print_json;
use crate::args::{CorpusAction, PresetArg};
use crate::progress::Progress;
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
    let out = &crate::paths::absolute(out)?;
    let bad_inputs = &crate::paths::absolute_opt(bad_inputs.as_deref())?;
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
    let progress = Progress::new();
    let summary = generate(&opts, out, &|stage, f| progress.report(stage, f))
        .with_context(|| format!("generating into {}", out.display()))?;
    progress.finish();
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
