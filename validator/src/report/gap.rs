//! The gap workflow's report: what was named and why, and the gap before and after, as an
//! offline page (`index.html` + PNG charts) with the same chart helpers as the validation report.
//!
//! Charts: the residual ratio real/render by normalised image radius (vignetting shows as a
//! falling curve that the model flattens), the same by the terrain's illumination (a shading
//! error of the entry tilts it), real against rendered intensity (exposure and the response
//! curve bend it away from the diagonal), the spectrum log-ratio per band (blur and noise tilt
//! it), the frames' noise variance by intensity against the model's, and the held-out error of
//! every candidate set per stage (why a set won).

use std::path::{Path, PathBuf};

use super::html::{Cell, Figure, Page};
use super::plot::{bar_chart, image_strip, line_plot, palette, Axes, BarGroup, Raster, Series};
use super::{io_err, ReportError};
use crate::gap::{Figure as GapFigure, GapResult, GapViewImages, Metrics};

fn before_after(
    before: &Metrics,
    after: &Metrics,
    pick: impl Fn(&Metrics) -> Vec<(f64, f64)>,
) -> Vec<Series> {
    vec![
        Series::new("before", pick(before), palette(0)),
        Series::new("after", pick(after), palette(1)),
    ]
}

/// Half-range of the residual colour map, DN.
const RESIDUAL_DN: f32 = 48.0;

/// Real | before | real − before | after | real − after of one view.
fn residual_strip(path: &Path, v: &GapViewImages) -> Result<(), ReportError> {
    let (w, h) = (v.width as u32, v.height as u32);
    let unit = |x: &[f32]| x.iter().map(|d| d / 255.0).collect::<Vec<f32>>();
    let residual = |p: &[f32]| {
        v.real
            .iter()
            .zip(p)
            .map(|(r, p)| r - p)
            .collect::<Vec<f32>>()
    };
    let panels = [
        Raster::grey(w, h, &unit(&v.real)),
        Raster::grey(w, h, &unit(&v.before)),
        Raster::diverging(w, h, &residual(&v.before), -RESIDUAL_DN, RESIDUAL_DN),
        Raster::grey(w, h, &unit(&v.after)),
        Raster::diverging(w, h, &residual(&v.after), -RESIDUAL_DN, RESIDUAL_DN),
    ];
    Ok(image_strip(path, &panels, 8)?)
}

/// Writes the report of `r` into `dir` (created if needed); returns the path of `index.html`.
pub fn write_gap_report(dir: &Path, r: &GapResult) -> Result<PathBuf, ReportError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let (b, a) = (&r.metrics_before, &r.metrics_after);
    let bins = |v: &[f64]| -> Vec<(f64, f64)> {
        let n = v.len().max(1) as f64;
        v.iter()
            .enumerate()
            .filter(|(_, y)| y.is_finite())
            .map(|(i, y)| ((i as f64 + 0.5) / n, *y))
            .collect()
    };
    line_plot(
        &dir.join("radius.png"),
        "Real / render by image radius",
        "radius / corner distance",
        "mean ratio",
        &before_after(b, a, |m| bins(&m.residual_by_radius)),
    )?;
    let by_light = !b.residual_by_illumination.is_empty();
    if by_light {
        line_plot(
            &dir.join("illumination.png"),
            "Real / render by the terrain's illumination",
            "illumination / its 99th percentile",
            "mean ratio",
            &before_after(b, a, |m| m.residual_by_illumination.clone()),
        )?;
    }
    let has_noise = !b.noise_by_intensity.is_empty();
    if has_noise {
        let curve = |m: &Metrics, real: bool| -> Vec<(f64, f64)> {
            m.noise_by_intensity
                .iter()
                .map(|&(dn, r, model)| (dn, if real { r } else { model }))
                .collect()
        };
        let mut series = vec![
            Series::new("real frames", curve(b, true), palette(2)),
            Series::new("model before", curve(b, false), palette(0)),
            Series::new("model after", curve(a, false), palette(1)),
        ];
        // The photon-transfer fit (response curve, shot and read noise) over its levels.
        if let Some(w) = &r.response {
            series.push(Series::new(
                format!("photon transfer, γ {:.3}", w.gamma),
                w.levels
                    .iter()
                    .map(|&(c, _, _)| (c, w.sigma_at(c).powi(2)))
                    .collect(),
                palette(3),
            ));
        }
        line_plot(
            &dir.join("noise.png"),
            "Noise variance by intensity",
            "DN",
            "variance, DN²",
            &series,
        )?;
    }
    let mut intensity = before_after(b, a, |m| m.real_by_intensity.clone());
    intensity.push(Series::new(
        "identity",
        vec![(0.0, 0.0), (255.0, 255.0)],
        palette(7),
    ));
    line_plot(
        &dir.join("intensity.png"),
        "Real against rendered intensity",
        "rendered DN",
        "real DN",
        &intensity,
    )?;
    line_plot(
        &dir.join("spectrum.png"),
        "Spectrum log10 ratio render/real",
        "band (fraction of 0.5 cycles/px)",
        "log10 power ratio",
        &before_after(b, a, |m| bins(&m.spectrum_log_ratio)),
    )?;
    let mut page = Page::new(&format!("regolith gap: {}", r.entry));
    page.heading(1, &format!("Gap of {}", r.entry), None);
    page.paragraph(&format!("Release {}", r.release_id));
    page.heading(2, "Named effects", None);
    if r.named.is_empty() {
        page.paragraph("No effect explains a significant share of the gap.");
    } else {
        let rows: Vec<Vec<Cell>> = r
            .named
            .iter()
            .map(|n| {
                let params: Vec<String> = n
                    .params
                    .iter()
                    .map(|(k, v)| match n.std_err.get(k) {
                        Some(e) if *e > 0.0 => format!("{k} = {v:.4} ± {e:.4}"),
                        _ => format!("{k} = {v:.4}"),
                    })
                    .collect();
                let per_capture: Vec<String> = n
                    .per_capture
                    .iter()
                    .map(|c| {
                        let p: Vec<String> = c
                            .params
                            .iter()
                            .map(|(k, v)| format!("{k} {v:.4}"))
                            .collect();
                        format!("{}: {}", c.capture, p.join(", "))
                    })
                    .collect();
                vec![
                    Cell::new(n.effect.clone()),
                    Cell::new(params.join(", ")),
                    Cell::new(format!("{:.0} %", 100.0 * n.explained_fraction)),
                    Cell::new(n.stage.clone()),
                    Cell::new(n.evidence.clone()),
                    Cell::new(per_capture.join("; ")),
                ]
            })
            .collect();
        page.table(
            &[
                "effect",
                "parameters",
                "explains",
                "stage",
                "evidence",
                "fitted per capture",
            ],
            &rows,
        );
    }
    if !r.withheld.is_empty() {
        page.heading(2, "Not named, and why", None);
        let rows: Vec<Vec<Cell>> = r
            .withheld
            .iter()
            .map(|w| {
                vec![
                    Cell::new(w.effect.clone()),
                    Cell::new(w.stage.clone()),
                    Cell::new(w.reason.clone()),
                ]
            })
            .collect();
        page.table(&["effect", "stage", "reason"], &rows);
    }
    if let Some(t) = &r.texture_transfer {
        page.heading(2, "Texture transfer", None);
        let per_capture: Vec<String> = t
            .per_capture
            .iter()
            .map(|c| {
                format!(
                    "{} {:.3}",
                    c.capture,
                    c.params.get("gain").copied().unwrap_or(f64::NAN)
                )
            })
            .collect();
        page.paragraph(&format!(
            "The camera sees the entry's texture at {:.3} ± {:.3} times its values (per capture: {}). The texture was measured by another instrument, whose level in the camera's terms is unknown, so this gain is a property of the entry, not an exposure of the camera; the model after holds it and validation renders use it. Evidence: {}",
            t.gain,
            t.std_err,
            per_capture.join(", "),
            t.evidence
        ));
    }
    if let Some(t) = &r.texture {
        page.heading(2, "Texture detail", None);
        page.paragraph(&format!(
            "The entry's texture ({:.3} m cells) matches the real albedo blurred by {:.1} mm on the ground (band-passed correlation {:.2}); a faithful texture of these cells shows about {:.1} mm, so the texture lacks a low-pass of {:.1} mm. The real pattern cannot be recovered from the texture (the remedy is a sharper texture source); with the effect in the model, sample renders carry procedural detail of the missing spectrum.",
            t.cell_m,
            t.effective_blur_m * 1e3,
            t.correlation,
            t.own_blur_m * 1e3,
            t.excess_m * 1e3
        ));
    }
    if let Some(w) = &r.response {
        page.heading(2, "The camera's response, from its noise", None);
        page.paragraph(&format!(
            "Two frames of each pose differ only by sensor noise, which arises before the response curve and is reshaped by it. Over {} levels of the frames and {} values of the dark background the noise fits a response curve γ {:.3} ± {:.3}, shot noise {:.4} DN²/DN and read noise {:.2} DN on the linear signal, and a black level of {:.1} ± {:.1} DN (residuals {:.2} standard errors² each). The entry does not enter this figure: it witnesses the camera's curve and black level for the photometric fit.",
            w.levels.len(),
            w.background_px,
            w.gamma,
            w.gamma_se,
            w.shot_gain,
            w.read_sigma,
            w.black_dn,
            w.black_se,
            w.reduced_chi2
        ));
    }
    page.heading(2, "Gap before and after", None);
    let row = |name: &str, f: &dyn Fn(&Metrics) -> f64| {
        vec![
            Cell::new(name),
            Cell::new(format!("{:.3}", f(b))),
            Cell::new(format!("{:.3}", f(a))),
        ]
    };
    let mut rows: Vec<Vec<Cell>> = GapFigure::ALL
        .iter()
        .filter(|f| **f != GapFigure::TextureBandDeficit || b.texture_band_log_ratio.is_some())
        .map(|f| {
            let mut name = f.label().to_string();
            if *f == GapFigure::ShadowRmsDn {
                name = format!("{name} ({} px)", b.shadow_pixels);
            }
            if *f == r.gap_metric {
                name.push_str(" (headline)");
            }
            row(&name, &|m| f.of(m))
        })
        .collect();
    rows.push(row("noise variance of the real frames, DN²", &|m| {
        m.noise_variance_dn2
    }));
    page.table(&["metric", "before", "after"], &rows);
    let view_rows: Vec<Vec<Cell>> = b
        .views
        .iter()
        .zip(&a.views)
        .map(|(vb, va)| {
            vec![
                Cell::new(format!("{} {}", vb.capture, vb.camera)),
                Cell::new(format!("{:.2}", vb.photometric_rms_dn)),
                Cell::new(format!("{:.2}", va.photometric_rms_dn)),
            ]
        })
        .collect();
    page.table(&["view", "RMS before, DN", "RMS after, DN"], &view_rows);
    let mut figs = vec![
        Figure::new("radius.png", "Residual ratio by image radius", 480),
        Figure::new("intensity.png", "Real vs rendered intensity", 480),
        Figure::new("spectrum.png", "Spectrum log-ratio per band", 480),
    ];
    if by_light {
        figs.insert(
            1,
            Figure::new("illumination.png", "Residual ratio by illumination", 480),
        );
    }
    if has_noise {
        figs.push(Figure::new("noise.png", "Noise variance by intensity", 480));
    }
    for (stage, cands) in &r.candidates {
        if cands.is_empty() {
            continue;
        }
        let file = format!("candidates_{stage}.png");
        let cats: Vec<String> = cands
            .iter()
            .map(|c| {
                if c.effects.is_empty() {
                    "(none)".to_string()
                } else {
                    c.effects.join("+")
                }
            })
            .collect();
        bar_chart(
            &dir.join(&file),
            &Axes::new(
                &format!("Held-out error per candidate set: {stage}"),
                "candidate set",
                "held-out error",
            ),
            &cats,
            &[BarGroup::new(
                "",
                cands.iter().map(|c| c.cv_error).collect(),
                palette(2),
            )],
            &[],
        )?;
        figs.push(Figure::new(
            file,
            format!("Candidates of the {stage} stage"),
            640,
        ));
    }
    page.heading(2, "Where the disagreement is", None);
    page.figures(&figs);
    if !r.images.is_empty() {
        page.heading(2, "Residual maps per view", None);
        page.paragraph(&format!(
            "Real (mean of the frames) | prediction before | real − before | prediction after | real − after; residuals in DN, blue −{RESIDUAL_DN} … red +{RESIDUAL_DN}; pixels where the render sees no terrain are black in the predictions and marked as no data in the residuals."
        ));
        let mut maps = Vec::new();
        for v in &r.images {
            let file = format!("residual_{}_{}.png", v.capture, v.camera);
            residual_strip(&dir.join(&file), v)?;
            maps.push(Figure::new(
                file,
                format!("{} {}", v.capture, v.camera),
                1200,
            ));
        }
        page.figures(&maps);
    }
    let index = dir.join("index.html");
    page.write(&index).map_err(io_err(&index))?;
    Ok(index)
}
