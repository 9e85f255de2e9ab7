//! `regolith corpus generate`: a synthetic campaign with ground truth, with a progress bar.
//!
//! The NavCam frames come from Mitsuba through the corpus's own camera by default (a render
//! cache makes repeated campaigns cheap and lets CI regenerate the reference campaigns without
//! a renderer); `--renderer model` uses the validator's own forward model, for unit tests.

use std::path::{Path, PathBuf};

use anyhow::Context;
use regolith_corpus::captures::physical::{PhysicalCaptures, PhysicalOptions};
use regolith_corpus::captures::CaptureRenderer;
use regolith_corpus::{effects, generate, GenerateOptions, Preset};
use regolith_model_captures::ModelCaptures;

use super::print_json;
use crate::args::{CorpusAction, PresetArg, RendererArg};
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
        auto_exposure,
        out,
        renderer,
        renders,
        no_render,
        spp,
        bad_inputs,
    } = action;
    if !(auto_exposure.is_finite() && *auto_exposure >= 0.0) {
        anyhow::bail!(
            "--auto-exposure takes a spread of 0 or more (a log gain, e.g. 0.2), not {auto_exposure}"
        );
    }
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
        auto_exposure: *auto_exposure,
    };
    let renderer: Box<dyn CaptureRenderer> = match renderer {
        RendererArg::Model => Box::new(ModelCaptures),
        RendererArg::Mitsuba => {
            let cache = match renders {
                Some(dir) => crate::paths::absolute(dir)?,
                None => default_cache(),
            };
            let driver = if *no_render { None } else { mitsuba_driver() };
            let mut o = PhysicalOptions::new(cache, driver);
            o.spp = *spp;
            Box::new(PhysicalCaptures::new(o))
        }
    };
    let progress = Progress::new();
    let existed = out.exists();
    let summary = generate(&opts, out, renderer.as_ref(), &|stage, f| {
        progress.report(stage, f)
    });
    let summary = match summary {
        Ok(s) => s,
        Err(e) => {
            // The folder was absent or empty (the generator refuses others): leave it so.
            if !existed {
                let _ = std::fs::remove_dir_all(out);
            } else if let Ok(rd) = std::fs::read_dir(out) {
                for entry in rd.flatten() {
                    let p = entry.path();
                    let _ = if p.is_dir() {
                        std::fs::remove_dir_all(&p)
                    } else {
                        std::fs::remove_file(&p)
                    };
                }
            }
            return Err(e).with_context(|| format!("generating into {}", out.display()));
        }
    };
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

/// `$REGOLITH_RENDER_CACHE`, else `~/.cache/regolith/renders`, else `.regolith-renders`.
fn default_cache() -> PathBuf {
    if let Some(dir) = std::env::var_os("REGOLITH_RENDER_CACHE") {
        return PathBuf::from(dir);
    }
    match std::env::var_os("HOME") {
        Some(home) => Path::new(&home).join(".cache/regolith/renders"),
        None => PathBuf::from(".regolith-renders"),
    }
}

/// The Mitsuba driver: `$REGOLITH_MITSUBA_DRIVER`, else `tools/render/mitsuba_captures.py` of
/// the source tree this binary was built from, if it is still there.
fn mitsuba_driver() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("REGOLITH_MITSUBA_DRIVER") {
        return Some(PathBuf::from(p));
    }
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/render/mitsuba_captures.py");
    built.is_file().then_some(built)
}
