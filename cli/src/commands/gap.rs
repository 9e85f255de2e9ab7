//! `regolith gap DB --entry E`: the gap workflow of `regolith_validator::gap` — measure,
//! attribute, and with `--apply` write the fitted sensor model into a child release.

use std::path::Path;

use regolith_reader::{Database, Location, Writer};
use regolith_validator::gap::{self, apply, GapOptions};
use serde_json::json;

use super::print_json;
use crate::progress::Progress;
use crate::Outcome;

#[allow(clippy::too_many_arguments)]
pub fn run(
    db: &Location,
    release: &str,
    entry: &str,
    captures: &[String],
    cameras: &[String],
    apply_model: bool,
    min_share: f64,
    report: Option<&Path>,
    json: bool,
) -> anyhow::Result<Outcome> {
    anyhow::ensure!(
        (0.0..1.0).contains(&min_share),
        "--min-share must be in [0, 1), got {min_share}"
    );
    let database = Database::open(db)?;
    let view = database.release(release)?;
    let opts = GapOptions {
        captures: captures.to_vec(),
        cameras: cameras.to_vec(),
        min_share,
        keep_images: report.is_some(),
        ..GapOptions::default()
    };
    let progress = Progress::new();
    let result = gap::run_observed(&view, entry, &opts, &|step, f| progress.report(step, f))?;
    let seconds = progress.finish();
    let applied = if apply_model && result.model_after != result.model_before {
        // Locked for the write alone: the fit above ran without holding the database.
        let writer = Writer::open_waiting(db, &|| {
            eprintln!("waiting for another process writing to {}", db.display());
        })?;
        let summary = json!({
            "release": view.label(),
            "named": result.named.iter().map(|n| &n.effect).collect::<Vec<_>>(),
            "texture_transfer": result.texture_transfer.as_ref().map(|t| t.gain),
            "gap_metric": result.gap_metric,
            "gap_before": result.gap_before,
            "gap_after": result.gap_after,
        });
        Some(apply::write_model(
            &writer,
            &view,
            entry,
            &result.model_after,
            summary,
        )?)
    } else {
        None
    };
    let index = match report {
        Some(dir) => Some(regolith_validator::report::write_gap_report(dir, &result)?),
        None => None,
    };
    if json {
        let mut v = serde_json::to_value(&result)?;
        if let Some(i) = &index {
            v["report"] = json!(i);
        }
        v["step_seconds"] = json!(seconds);
        v["applied"] = match &applied {
            Some((label, id)) => json!({"release": label, "id": id.to_hex()}),
            None => serde_json::Value::Null,
        };
        print_json(&v)?;
    } else {
        say!("{} {entry}", view.label());
        if result.named.is_empty() {
            say!("  no effect explains a significant share of the gap");
        }
        for n in &result.named {
            let params: Vec<String> = n
                .params
                .iter()
                .map(|(k, v)| match n.std_err.get(k) {
                    Some(e) if *e > 0.0 => format!("{k}={v:.4}±{e:.4}"),
                    _ => format!("{k}={v:.4}"),
                })
                .collect();
            say!(
                "  {:<12} explains {:>5.1}%  {}",
                n.effect,
                100.0 * n.explained_fraction,
                params.join(" ")
            );
            if !n.plain.is_empty() {
                let plain: Vec<String> =
                    n.plain.iter().map(|(k, v)| format!("{k}={v:.4}")).collect();
                say!("  {:<12} i.e. {}", "", plain.join(" "));
            }
            say!("  {:<12} evidence: {}", "", n.evidence);
        }
        for w in &result.withheld {
            say!("  {:<12} withheld: {}", w.effect, w.reason);
        }
        let (b, a) = (&result.metrics_before, &result.metrics_after);
        say!(
            "  gap ({}): {:.3} -> {:.3}; geometric alignment residual {:.3} -> {:.3}; in cast shadow {:.2} -> {:.2} DN",
            result.gap_metric.label(),
            result.gap_before,
            result.gap_after,
            b.alignment_residual,
            a.alignment_residual,
            b.shadow_rms_dn,
            a.shadow_rms_dn
        );
        if let Some(t) = &result.texture {
            say!(
                "  texture: matches the real albedo blurred by {:.1} mm (a faithful {:.3} m texture: {:.1} mm)",
                t.effective_blur_m * 1e3,
                t.cell_m,
                t.own_blur_m * 1e3
            );
        }
        if let Some(t) = &result.texture_transfer {
            say!(
                "  texture transfer: the camera sees the texture at gain {:.3} ± {:.3} (the entry's, not an exposure)",
                t.gain,
                t.std_err
            );
            say!("  {:<12} evidence: {}", "", t.evidence);
        }
        if let (Some(tb), Some(ta)) = (b.texture_band_log_ratio, a.texture_band_log_ratio) {
            say!("  texture band power vs the real albedo (log10): {tb:.3} -> {ta:.3}");
        }
        let steps: Vec<String> = seconds
            .iter()
            .map(|(step, s)| format!("{step} {s:.1} s"))
            .collect();
        say!("  time: {}", steps.join(", "));
        if let Some(i) = &index {
            say!("  report: {}", i.display());
        }
        match &applied {
            Some((label, id)) => say!("  applied: release {label} ({})", id.short()),
            None if apply_model => say!("  nothing to apply"),
            None => {}
        }
    }
    Ok(Outcome::Ok)
}
