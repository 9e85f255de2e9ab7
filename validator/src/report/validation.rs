//! The validation report: per entry a summary (verdict, per-detector figures with confidence
//! intervals, photometric figures, failure messages, entry-level charts) and per (capture,
//! camera) view the images, keypoint overlays and charts.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::html::{Cell, Figure, Mark, Page};
use super::io_err;
use super::plot::{
    self, bar_chart, keypoint_overlay, line_plot_axes, magnitude_png, palette, Axes, BarGroup,
    Link, Marker, PlotError, Raster, Rgb, Series, SeriesStyle, Shape,
};
use super::{slug, ReportError};
use crate::features::Detector;
use crate::metrics::stats::Interval;
use crate::validate::{Certificate, Validator, ViewArtifacts, ViewMetrics};

/// |real − render| at this value and above is drawn white in the difference image.
const DIFF_FULL_SCALE: f32 = 0.5;
/// The ε axis ends past the curve (ε ≤ 5 px) to leave room for the legend.
const EPS_AXIS_MAX: f64 = 6.6;
/// Overlays are enlarged (integer factor) until at least this wide.
const OVERLAY_MIN_WIDTH: u32 = 480;

/// The integer enlargement of a keypoint overlay for an image `width` pixels wide.
pub fn overlay_scale(width: u32) -> u32 {
    OVERLAY_MIN_WIDTH.div_ceil(width.max(1)).clamp(1, 32)
}

/// What the report keeps of one view (the images themselves are already on disk).
#[derive(Debug, Clone)]
struct ViewRecord {
    capture: String,
    camera: String,
    prefix: String,
    width: u32,
    height: u32,
    /// Detector, keypoints in real a, in the render, repeated pairs at the certified ε.
    detectors: Vec<(Detector, usize, usize, usize)>,
}

#[derive(Debug)]
struct EntrySection {
    slug: String,
    cert: Certificate,
    views: Vec<ViewRecord>,
}

/// Writes `regolith validate --report DIR`: validate entries through
/// [`ValidationReport::validate_entry`] (which draws each view's figures as it is measured),
/// then [`ValidationReport::finish`] writes `DIR/index.html`.
#[derive(Debug)]
pub struct ValidationReport {
    dir: PathBuf,
    release_label: String,
    release_id: String,
    entries: Vec<EntrySection>,
    slugs: BTreeSet<String>,
}

fn fmt_interval(i: &Interval) -> String {
    if i.n > 1 {
        format!("{:.3} [{:.3}, {:.3}]", i.mean, i.low, i.high)
    } else {
        format!("{:.3}", i.mean)
    }
}

fn at_eps(v: &ViewMetrics, eps: f64) -> Option<&crate::metrics::repeatability::Repeatability> {
    v.sim.iter().find(|r| (r.epsilon_px - eps).abs() < 1e-9)
}

impl ValidationReport {
    /// A report into `dir` (created if missing; files of an earlier report with the same
    /// names are replaced) about the release `label` / `id`.
    pub fn new(dir: &Path, release_label: &str, release_id: &str) -> Result<Self, ReportError> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        Ok(ValidationReport {
            dir: dir.to_path_buf(),
            release_label: release_label.to_string(),
            release_id: release_id.to_string(),
            entries: Vec::new(),
            slugs: BTreeSet::new(),
        })
    }

    /// Validates `entry` through `validator` (exactly as [`Validator::entry`]) and draws its
    /// figures into `DIR/<entry slug>/`, handing each view to `also` as well (progress);
    /// returns the certificate.
    pub fn validate_entry(
        &mut self,
        validator: &Validator<'_>,
        entry: &str,
        also: &(dyn Fn(&ViewArtifacts<'_>) + Sync),
    ) -> Result<Certificate, ReportError> {
        let mut s = slug(entry);
        let base = s.clone();
        let mut k = 2;
        while self.slugs.contains(&s) {
            s = format!("{base}-{k}");
            k += 1;
        }
        let dir = self.dir.join(&s);
        std::fs::create_dir_all(&dir).map_err(io_err(&dir))?;
        let records: Mutex<Vec<ViewRecord>> = Mutex::new(Vec::new());
        let failed: Mutex<Option<PlotError>> = Mutex::new(None);
        let observe = |a: &ViewArtifacts<'_>| {
            match write_view_images(&dir, a) {
                Ok(r) => lock(&records).push(r),
                Err(e) => {
                    lock(&failed).get_or_insert(e);
                }
            }
            also(a);
        };
        let cert = validator.entry(entry, Some(&observe))?;
        if let Some(e) = into_inner(failed) {
            return Err(e.into());
        }
        let mut views = into_inner(records);
        views.sort_by(|a, b| (&a.capture, &a.camera).cmp(&(&b.capture, &b.camera)));
        for v in &views {
            write_view_charts(&dir, v, &cert)?;
        }
        write_entry_charts(&dir, &cert)?;
        self.slugs.insert(s.clone());
        self.entries.push(EntrySection {
            slug: s,
            cert: cert.clone(),
            views,
        });
        Ok(cert)
    }

    /// Writes `DIR/index.html` and returns its path.
    pub fn finish(self) -> Result<PathBuf, ReportError> {
        let mut page = Page::new(&format!(
            "regolith validation report — {}",
            self.release_label
        ));
        page.paragraph_parts(&[
            ("Release ", false),
            (&self.release_label, true),
            (", id ", false),
            (&self.release_id, true),
            (
                ". Every terrain entry was re-rendered at each real capture pose through the \
                 calibrated (distorted) camera and compared with the real frames; the figures \
                 below are drawn from the same run as the certificates.",
                false,
            ),
        ]);
        let overview: Vec<Vec<Cell>> = self
            .entries
            .iter()
            .map(|e| {
                vec![
                    Cell::new(e.cert.entry.clone()),
                    verdict(e.cert.passed),
                    Cell::new(e.cert.failures.len().to_string()),
                    Cell::new(e.views.len().to_string()),
                    Cell::new(e.cert.entry_hash.get(..12).unwrap_or_default()),
                ]
            })
            .collect();
        page.table(
            &["entry", "verdict", "failed criteria", "views", "entry hash"],
            &overview,
        );
        for e in &self.entries {
            entry_section(&mut page, e);
        }
        let path = self.dir.join("index.html");
        page.write(&path).map_err(io_err(&path))?;
        Ok(path)
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn into_inner<T>(m: Mutex<T>) -> T {
    m.into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn verdict(passed: bool) -> Cell {
    if passed {
        Cell::marked("PASS", Mark::Pass)
    } else {
        Cell::marked("FAIL", Mark::Fail)
    }
}

/// The images and keypoint overlays of one view, and its spectra chart (the spectra are not
/// in the certificate).
fn write_view_images(dir: &Path, a: &ViewArtifacts<'_>) -> Result<ViewRecord, PlotError> {
    let prefix = format!("{}_{}", slug(a.capture), slug(a.camera));
    let (w, h) = (a.real_a.width as u32, a.real_a.height as u32);
    let file = |name: &str| dir.join(format!("{prefix}_{name}.png"));
    plot::grey_png(&file("real"), w, h, &a.real_a.data)?;
    plot::grey_png(&file("render"), w, h, &a.render.data)?;
    let diff: Vec<f32> = a
        .real_a
        .data
        .iter()
        .zip(&a.render.data)
        .zip(a.mask)
        .map(|((r, s), &m)| if m == 255 { (r - s).abs() } else { f32::NAN })
        .collect();
    magnitude_png(&file("diff"), w, h, &diff, DIFF_FULL_SCALE)?;
    // Keypoints over the real frame, dimmed so the markers stand out.
    let dim: Vec<f32> = a.real_a.data.iter().map(|v| 0.15 + 0.6 * v).collect();
    let background = Raster::grey(w, h, &dim);
    let scale = overlay_scale(w);
    let r = (4 * scale.min(2)).max(3);
    let mut detectors = Vec::new();
    for k in &a.keypoints {
        let rep_real: BTreeSet<usize> = k.repeated.iter().map(|p| p.0).collect();
        let rep_render: BTreeSet<usize> = k.repeated.iter().map(|p| p.1).collect();
        let mut markers = Vec::new();
        let mark = |x: f32, y: f32, shape, colour, radius| Marker {
            x: f64::from(x),
            y: f64::from(y),
            shape,
            colour,
            radius,
            stroke: 1,
        };
        for (i, p) in k.real.iter().enumerate() {
            if !rep_real.contains(&i) {
                markers.push(mark(p.x, p.y, Shape::Circle, Rgb::GREEN, r));
            }
        }
        for (j, p) in k.render.iter().enumerate() {
            if !rep_render.contains(&j) {
                markers.push(mark(p.x, p.y, Shape::Cross, Rgb::RED, r - 1));
            }
        }
        let mut links = Vec::new();
        for &(i, j) in &k.repeated {
            let (p, q) = (k.real[i], k.render[j]);
            links.push(Link {
                from: (f64::from(p.x), f64::from(p.y)),
                to: (f64::from(q.x), f64::from(q.y)),
                colour: Rgb::YELLOW,
            });
            markers.push(mark(p.x, p.y, Shape::Square, Rgb::YELLOW, r + 1));
        }
        keypoint_overlay(
            &file(&format!("kp_{}", k.detector.name())),
            &background,
            scale,
            &markers,
            &links,
        )?;
        detectors.push((k.detector, k.real.len(), k.render.len(), k.repeated.len()));
    }
    let [real, render] = a.spectra;
    let pts = |s: &crate::metrics::spectrum::RadialSpectrum| -> Vec<(f64, f64)> {
        let step = s.band_upper.first().copied().unwrap_or(0.0);
        s.band_upper
            .iter()
            .zip(&s.power)
            .filter(|(_, p)| **p > 0.0)
            .map(|(u, p)| (u - step / 2.0, p.log10()))
            .collect()
    };
    line_plot_axes(
        &file("spectrum"),
        &Axes::new(
            &format!("Radial power spectrum, {} {}", a.capture, a.camera),
            "spatial frequency (cycles/pixel, band centre)",
            "log10 mean power",
        )
        .x_range(0.0, 0.5),
        &[
            Series::new("real", pts(real), Rgb::GREEN),
            Series::new("render", pts(render), Rgb::RED),
        ],
    )?;
    Ok(ViewRecord {
        capture: a.capture.to_string(),
        camera: a.camera.to_string(),
        prefix,
        width: w,
        height: h,
        detectors,
    })
}

fn detector_names(cert: &Certificate) -> Vec<Detector> {
    let mut ds: Vec<Detector> = Vec::new();
    for v in &cert.views {
        if !ds.contains(&v.detector) {
            ds.push(v.detector);
        }
    }
    ds
}

/// The per-detector floors as text, e.g. `fast 0.125, harris 0.085`.
fn floors_text(th: &crate::validate::Thresholds) -> String {
    th.min_ratio_to_ceiling
        .iter()
        .map(|(d, v)| format!("{d} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Repeatability-vs-ε curves and keypoint counts of one view, from the certificate.
fn write_view_charts(dir: &Path, v: &ViewRecord, cert: &Certificate) -> Result<(), PlotError> {
    let eps = cert.thresholds.epsilon_px;
    let metrics: Vec<&ViewMetrics> = cert
        .views
        .iter()
        .filter(|m| m.capture == v.capture && m.camera == v.camera)
        .collect();
    let mut series = Vec::new();
    for (i, m) in metrics.iter().enumerate() {
        let c = palette(i);
        series.push(Series::new(
            m.detector.name(),
            m.sim.iter().map(|r| (r.epsilon_px, r.excess)).collect(),
            c,
        ));
        if let Some(ceiling) = m.certified(eps).and_then(|f| f.ceiling) {
            series.push(Series::new("", vec![(eps, ceiling)], c).styled(SeriesStyle::Markers));
        }
    }
    line_plot_axes(
        &dir.join(format!("{}_repeat.png", v.prefix)),
        &Axes::new(
            &format!(
                "Repeatability over chance real→render, {} {}",
                v.capture, v.camera
            ),
            "ε (pixels)",
            "re-detected over chance",
        )
        .x_range(0.5, EPS_AXIS_MAX)
        .y_range(0.0, 1.0),
        &series,
    )?;
    let cats: Vec<String> = metrics.iter().map(|m| m.detector.name().into()).collect();
    let repeated: Vec<f64> = metrics
        .iter()
        .map(|m| at_eps(m, eps).map_or(f64::NAN, |r| r.repeated as f64))
        .collect();
    bar_chart(
        &dir.join(format!("{}_counts.png", v.prefix)),
        &Axes::new(
            &format!("Keypoints, {} {}", v.capture, v.camera),
            "detector",
            "keypoints (whole image)",
        ),
        &cats,
        &[
            BarGroup::new(
                "real",
                metrics.iter().map(|m| m.counts[0] as f64).collect(),
                Rgb::GREEN,
            ),
            BarGroup::new(
                "rendered",
                metrics.iter().map(|m| m.counts[1] as f64).collect(),
                Rgb::RED,
            ),
            BarGroup::new(
                format!("repeated at ε = {eps} px"),
                repeated,
                Rgb(200, 170, 0),
            ),
        ],
        &[],
    )
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// The entry-level charts: mean curves, ratio to the ceiling with CIs, mean counts and the
/// spectrum log-ratio per band.
fn write_entry_charts(dir: &Path, cert: &Certificate) -> Result<(), PlotError> {
    let eps = cert.thresholds.epsilon_px;
    let ds = detector_names(cert);
    let of = |d: Detector| cert.views.iter().filter(move |v| v.detector == d);
    let mut series = Vec::new();
    for (i, &d) in ds.iter().enumerate() {
        let c = palette(i);
        let mut curve: Vec<f64> = of(d)
            .flat_map(|v| v.sim.iter().map(|r| r.epsilon_px))
            .collect();
        curve.sort_by(f64::total_cmp);
        curve.dedup();
        let pts = curve
            .iter()
            .map(|&e| {
                (
                    e,
                    mean(of(d).filter_map(|v| at_eps(v, e)).map(|r| r.excess)),
                )
            })
            .collect();
        series.push(Series::new(d.name(), pts, c));
        if let Some(ceiling) = cert.summary.get(d.name()).and_then(|s| s.ceiling) {
            series.push(Series::new("", vec![(eps, ceiling.mean)], c).styled(SeriesStyle::Markers));
        }
    }
    line_plot_axes(
        &dir.join("summary_repeat.png"),
        &Axes::new(
            "Repeatability over chance real→render, mean over views",
            "ε (pixels)",
            "re-detected over chance",
        )
        .x_range(0.5, EPS_AXIS_MAX)
        .y_range(0.0, 1.0),
        &series,
    )?;
    let cats: Vec<String> = ds.iter().map(|d| d.name().to_string()).collect();
    let summary = |d: &Detector| cert.summary.get(d.name());
    let with_ratio = ds
        .iter()
        .any(|d| summary(d).is_some_and(|s| s.ratio.is_some()));
    let ivs: Vec<Option<Interval>> = ds
        .iter()
        .map(|d| {
            let s = summary(d)?;
            if with_ratio {
                s.ratio
            } else {
                Some(s.sim)
            }
        })
        .collect();
    let measured = BarGroup::new(
        "mean",
        ivs.iter().map(|i| i.map_or(f64::NAN, |i| i.mean)).collect(),
        palette(0),
    )
    .with_intervals(ivs.iter().map(|i| i.map(|i| (i.low, i.high))).collect());
    let th = &cert.thresholds;
    if with_ratio {
        // Each detector has its own floor: drawn as a grey bar beside the measured one.
        let floors = ds
            .iter()
            .map(|&d| th.detector_floor(d).unwrap_or(f64::NAN))
            .collect();
        bar_chart(
            &dir.join("summary_ratio.png"),
            &Axes::new(
                "Ratio to the real-vs-real ceiling (95 % CI over views)",
                "detector",
                "over-chance repeatability, sim ÷ ceiling",
            ),
            &cats,
            &[measured, BarGroup::new("pass floor", floors, Rgb::GREY)],
            &[],
        )?;
    } else {
        bar_chart(
            &dir.join("summary_ratio.png"),
            &Axes::new(
                "Repeatability over chance (no repeat frames; 95 % CI over views)",
                "detector",
                "repeatability over chance at the certified ε",
            ),
            &cats,
            &[measured],
            &[("pass threshold".to_string(), th.min_repeatability)],
        )?;
    }
    bar_chart(
        &dir.join("summary_counts.png"),
        &Axes::new(
            "Keypoints per view, real vs rendered (mean over views)",
            "detector",
            "keypoints (whole image)",
        ),
        &cats,
        &[
            BarGroup::new(
                "real",
                ds.iter()
                    .map(|&d| mean(of(d).map(|v| v.counts[0] as f64)))
                    .collect(),
                Rgb::GREEN,
            ),
            BarGroup::new(
                "rendered",
                ds.iter()
                    .map(|&d| mean(of(d).map(|v| v.counts[1] as f64)))
                    .collect(),
                Rgb::RED,
            ),
        ],
        &[],
    )?;
    let n = cert.spectrum_log_ratio.len().max(1);
    let bands: Vec<String> = (1..=cert.spectrum_log_ratio.len())
        .map(|k| format!("{:.3}", 0.5 * k as f64 / n as f64))
        .collect();
    bar_chart(
        &dir.join("summary_spectrum.png"),
        &Axes::new(
            "Spectrum log-ratio render/real per band (mean over views)",
            "band upper edge (cycles/pixel)",
            "log10(P_render / P_real)",
        ),
        &bands,
        &[BarGroup::new(
            "",
            cert.spectrum_log_ratio.clone(),
            palette(4),
        )],
        &[(String::new(), 0.0)],
    )
}

fn entry_section(page: &mut Page, e: &EntrySection) {
    let c = &e.cert;
    let th = &c.thresholds;
    page.heading(
        2,
        &format!("{} — {}", c.entry, if c.passed { "PASS" } else { "FAIL" }),
        Some(&e.slug),
    );
    page.paragraph_parts(&[
        ("Entry hash ", false),
        (&c.entry_hash, true),
        (", validator ", false),
        (&c.validator_version, true),
        (
            &format!(
                ", certified ε = {} px; repeatability = real keypoints re-detected in the render over chance; thresholds: ratio to ceiling ≥ {} per detector and ≥ {} in the mean over detectors, absolute repeatability ≥ {} (when there are no repeat frames), photometric RMS ≤ {} grey levels, high-band (0.25–0.5 cycles/px) log10 power ratio ≥ {}. Measured: mean ratio {}, high-band log ratio {:.2}.",
                th.epsilon_px, floors_text(th), th.min_mean_ratio_to_ceiling, th.min_repeatability, th.max_photometric_rms,
                th.min_high_band_log_ratio,
                c.mean_ratio_to_ceiling.map_or("—".to_string(), |i| fmt_interval(&i)),
                c.high_band_log_ratio
            ),
            false,
        ),
    ]);
    let rows: Vec<Vec<Cell>> = c
        .summary
        .iter()
        .map(|(d, s)| {
            let failed = c.failures.iter().any(|f| f.starts_with(&format!("{d}:")));
            let floor = d
                .parse::<Detector>()
                .ok()
                .and_then(|d| th.detector_floor(d));
            let criterion = if s.ratio.is_some() {
                floor.map_or("—".to_string(), |f| format!("ratio ≥ {f}"))
            } else {
                format!("repeatability ≥ {} (no ceiling)", th.min_repeatability)
            };
            let opt = |i: Option<Interval>| {
                i.map_or(Cell::marked("—", Mark::Muted), |i| {
                    Cell::new(fmt_interval(&i))
                })
            };
            vec![
                Cell::new(d.clone()),
                Cell::new(fmt_interval(&s.sim)),
                opt(s.ceiling),
                opt(s.ratio),
                Cell::new(format!(
                    "{:.3} ({:.3})",
                    s.one_directional.mean, s.chance.mean
                )),
                Cell::new(format!("{:.3}", s.score.mean)),
                Cell::new(criterion),
                verdict(!failed),
            ]
        })
        .collect();
    page.table(
        &[
            "detector",
            "re-detected over chance, real→render",
            "ceiling, real a→real b",
            "ratio (95 % CI)",
            "one-directional (chance)",
            "÷ min(n)",
            "criterion",
            "result",
        ],
        &rows,
    );
    // SIFT matching per view (thesis Table 6.1 analogue): reported, not gated.
    let sift: Vec<Vec<Cell>> = c
        .views
        .iter()
        .filter_map(|v| Some((v, v.matching.as_ref()?)))
        .map(|(v, m)| {
            let r = &m.sim.ransac;
            let ceiling = m.ceiling.map_or(Cell::marked("—", Mark::Muted), |c| {
                Cell::new(format!(
                    "{:.3} / {:.3}",
                    c.score.score, c.ransac.inlier_ratio
                ))
            });
            vec![
                Cell::new(format!("{} {}", v.capture, v.camera)),
                Cell::new(format!("{} / {}", r.keypoints_a, r.keypoints_b)),
                Cell::new(r.matches.to_string()),
                Cell::new(r.inliers.to_string()),
                Cell::new(format!("{:.3}", r.inlier_ratio)),
                Cell::new(r.iterations.to_string()),
                Cell::new(format!("{:.3}", m.sim.score.score)),
                ceiling,
            ]
        })
        .collect();
    if !sift.is_empty() {
        page.table(
            &[
                "view (SIFT + RANSAC homography)",
                "keypoints real / render",
                "matches (ratio 0.8)",
                "inliers",
                "inlier ratio",
                "iterations",
                "matching score",
                "real a→b: score / inlier ratio",
            ],
            &sift,
        );
    }
    let photo: Vec<Vec<Cell>> = c
        .photometric
        .iter()
        .map(|(cap, cam, p)| {
            vec![
                Cell::new(cap.clone()),
                Cell::new(cam.clone()),
                Cell::new(format!("{:.1}", p.rms)),
                Cell::new(format!("{:.1}", p.mean_diff)),
                Cell::new(format!("{:.3}", p.ssim)),
                Cell::new(p.pixels.to_string()),
                verdict(!c.failures.iter().any(|f| {
                    f.starts_with("photometric") && f.ends_with(&format!(" at {cap} {cam}"))
                })),
            ]
        })
        .collect();
    page.table(
        &[
            "capture",
            "camera",
            "photometric RMS",
            "mean difference",
            "SSIM",
            "pixels compared",
            "result",
        ],
        &photo,
    );
    if c.failures.is_empty() {
        page.list(&[Cell::marked("every criterion passed", Mark::Pass)]);
    } else {
        let items: Vec<Cell> = c
            .failures
            .iter()
            .map(|f| Cell::marked(format!("failed: {f}"), Mark::Fail))
            .collect();
        page.list(&items);
    }
    let s = &e.slug;
    page.figures(&[
        Figure::new(
            format!("{s}/summary_repeat.png"),
            "Mean repeatability vs ε per detector; dots: real-vs-real ceiling at the certified ε.",
            460,
        ),
        Figure::new(
            format!("{s}/summary_ratio.png"),
            "The certified figure per detector with its 95 % CI; dashed: pass threshold.",
            460,
        ),
        Figure::new(
            format!("{s}/summary_counts.png"),
            "Keypoints per view, real vs rendered (as the thesis's Fig. 6.9).",
            460,
        ),
        Figure::new(
            format!("{s}/summary_spectrum.png"),
            "Radial power log-ratio render/real per frequency band; below 0: the render lacks that band.",
            460,
        ),
    ]);
    for (i, v) in e.views.iter().enumerate() {
        page.details(
            &format!("{} {} — {}×{} px", v.capture, v.camera, v.width, v.height),
            i == 0,
            |page| view_section(page, s, v),
        );
    }
}

fn view_section(page: &mut Page, slug: &str, v: &ViewRecord) {
    let f = |name: &str| format!("{slug}/{}_{name}.png", v.prefix);
    let small = v.width < 320;
    let img = |name: &str, caption: &str| {
        let fig = Figure::new(f(name), caption, 320);
        if small {
            fig.pixelated()
        } else {
            fig
        }
    };
    page.figures(&[
        img("real", "Real frame a (contrast-normalised)"),
        img("render", "Render at the same pose (contrast-normalised)"),
        img(
            "diff",
            "|real − render| where the render sees terrain (black 0, white ≥ 0.5; blue-grey: no terrain)",
        ),
    ]);
    page.legend(&[
        ("#00c83c", "real keypoint (circle)"),
        ("#e61e1e", "rendered keypoint (cross)"),
        (
            "#ffdc00",
            "repeated pair (square on the real point, line to the render's)",
        ),
    ]);
    let overlays: Vec<Figure> = v
        .detectors
        .iter()
        .map(|(d, n_real, n_render, n_rep)| {
            Figure::new(
                f(&format!("kp_{}", d.name())),
                format!(
                    "{}: {n_real} real, {n_render} rendered, {n_rep} repeated",
                    d.name()
                ),
                480,
            )
        })
        .collect();
    page.figures(&overlays);
    page.figures(&[
        Figure::new(
            f("repeat"),
            "Repeatability real→render vs ε; dots: ceiling (real a vs real b) at the certified ε.",
            460,
        ),
        Figure::new(
            f("counts"),
            "Keypoints real vs rendered, and repeated.",
            460,
        ),
        Figure::new(
            f("spectrum"),
            "Radial power spectra of the real frame and the render.",
            460,
        ),
    ]);
}
