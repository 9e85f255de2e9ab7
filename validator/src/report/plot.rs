//! Generic PNG figures for reports: line plots of several series, grouped bar charts, grey and
//! colour-mapped rasters, image strips and keypoint overlays.
//!
//! Nothing here knows about certificates: callers pass series of `(x, y)`, category names and
//! raw `f32` images, so the validation report and the gap report (residual maps, radial
//! profiles, spectra) draw with the same code.
//!
//! Charts are drawn by `plotters` into an in-memory RGB buffer (its bitmap backend) and encoded
//! here with the `png` crate at pinned settings (zlib default level, Paeth filter, no adaptive
//! filtering), like the compiler's encoders: the same input gives the same bytes. Text uses
//! DejaVu Sans compiled into the binary (the `dejavu` crate, rasterised by `ab_glyph`), so
//! plots render on a headless machine with no system fonts and do not change with the fonts a
//! machine happens to have.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

/// A figure could not be made or written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Encoding or drawing failed.
    #[error("{path}: {message}")]
    Draw {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The bundled font could not be loaded.
    #[error("the bundled report font could not be loaded")]
    Font,
}

fn draw_err(path: &Path, e: impl std::fmt::Display) -> PlotError {
    PlotError::Draw {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// An 8-bit RGB colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// Black.
    pub const BLACK: Rgb = Rgb(0, 0, 0);
    /// Mid grey.
    pub const GREY: Rgb = Rgb(128, 128, 128);
    /// Keypoints of real images.
    pub const GREEN: Rgb = Rgb(0, 200, 60);
    /// Keypoints of renders.
    pub const RED: Rgb = Rgb(230, 30, 30);
    /// Repeated keypoints.
    pub const YELLOW: Rgb = Rgb(255, 220, 0);

    fn plotters(self) -> RGBColor {
        RGBColor(self.0, self.1, self.2)
    }
}

/// A fixed categorical palette (colour-blind-safe Okabe–Ito order), indexed cyclically.
pub fn palette(i: usize) -> Rgb {
    const P: [Rgb; 8] = [
        Rgb(0, 114, 178),
        Rgb(213, 94, 0),
        Rgb(0, 158, 115),
        Rgb(204, 121, 167),
        Rgb(230, 159, 0),
        Rgb(86, 180, 233),
        Rgb(0, 0, 0),
        Rgb(240, 228, 66),
    ];
    P[i % P.len()]
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesStyle {
    /// Solid line with a marker at every point.
    LineMarkers,
    /// Solid line.
    Line,
    /// Dashed line (reference levels, ceilings).
    Dashed,
    /// Markers only.
    Markers,
}

/// One series of a line plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// The points, drawn in this order.
    pub points: Vec<(f64, f64)>,
    /// Colour.
    pub colour: Rgb,
    /// Style.
    pub style: SeriesStyle,
}

impl Series {
    /// A line with markers in `colour`.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, colour: Rgb) -> Series {
        Series {
            label: label.into(),
            points,
            colour,
            style: SeriesStyle::LineMarkers,
        }
    }

    /// The same series in another style.
    pub fn styled(mut self, style: SeriesStyle) -> Series {
        self.style = style;
        self
    }
}

/// The size of the charts this module draws by default.
pub const CHART_SIZE: (u32, u32) = (560, 360);

/// Title, axis labels, ranges and size of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Axes {
    /// Caption above the chart.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// x range; `None` = the data's.
    pub x_range: Option<(f64, f64)>,
    /// y range; `None` = the data's, padded by 5 %.
    pub y_range: Option<(f64, f64)>,
    /// Image size in pixels.
    pub size: (u32, u32),
}

impl Axes {
    /// Size [`CHART_SIZE`], ranges from the data.
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Axes {
        Axes {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            x_range: None,
            y_range: None,
            size: CHART_SIZE,
        }
    }

    /// With a fixed y range.
    pub fn y_range(mut self, lo: f64, hi: f64) -> Axes {
        self.y_range = Some((lo, hi));
        self
    }

    /// With a fixed x range.
    pub fn x_range(mut self, lo: f64, hi: f64) -> Axes {
        self.x_range = Some((lo, hi));
        self
    }
}

/// Registers the bundled font once (plotters looks fonts up by family name).
fn fonts() -> Result<(), PlotError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        let regular = dejavu::sans::regular();
        ["sans-serif", "serif", "monospace"]
            .iter()
            .all(|family| register_font(family, FontStyle::Normal, regular).is_ok())
    });
    ok.then_some(()).ok_or(PlotError::Font)
}

/// An RGB raster, row-major from the top-left.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Raster {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// `width × height` pixels.
    pub pixels: Vec<Rgb>,
}

fn to_u8(v: f32) -> u8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// Colour of non-finite samples in colour-mapped rasters (outside a mask, no data).
pub const NO_DATA: Rgb = Rgb(96, 112, 128);

impl Raster {
    /// A filled raster.
    pub fn filled(width: u32, height: u32, colour: Rgb) -> Raster {
        Raster {
            width,
            height,
            pixels: vec![colour; width as usize * height as usize],
        }
    }

    fn from_values(w: u32, h: u32, values: &[f32], map: impl Fn(f32) -> Rgb) -> Raster {
        let n = w as usize * h as usize;
        let mut pixels: Vec<Rgb> = values.iter().take(n).map(|&v| map(v)).collect();
        pixels.resize(n, NO_DATA);
        Raster {
            width: w,
            height: h,
            pixels,
        }
    }

    /// Grey levels in `[0, 1]` (clamped; NaN is black).
    pub fn grey(w: u32, h: u32, values: &[f32]) -> Raster {
        Raster::from_values(w, h, values, |v| {
            let g = to_u8(v);
            Rgb(g, g, g)
        })
    }

    /// A diverging map for signed values: `lo` blue, the midpoint white, `hi` red (clamped);
    /// non-finite values are [`NO_DATA`].
    pub fn diverging(w: u32, h: u32, values: &[f32], lo: f32, hi: f32) -> Raster {
        let span = if hi > lo { hi - lo } else { 1.0 };
        Raster::from_values(w, h, values, |v| {
            if !v.is_finite() {
                return NO_DATA;
            }
            let t = ((v - lo) / span).clamp(0.0, 1.0);
            // Blue (33, 102, 172) → white → red (178, 24, 43), linear in each half.
            let (a, b, s) = if t < 0.5 {
                ([33.0, 102.0, 172.0], [247.0, 247.0, 247.0], t * 2.0)
            } else {
                ([247.0, 247.0, 247.0], [178.0, 24.0, 43.0], t * 2.0 - 1.0)
            };
            let c = |k: usize| (a[k] + (b[k] - a[k]) * s).round() as u8;
            Rgb(c(0), c(1), c(2))
        })
    }

    /// A sequential map for magnitudes: 0 black → red → yellow → `hi` white (clamped);
    /// non-finite values are [`NO_DATA`].
    pub fn magnitude(w: u32, h: u32, values: &[f32], hi: f32) -> Raster {
        let hi = if hi > 0.0 { hi } else { 1.0 };
        Raster::from_values(w, h, values, |v| {
            if !v.is_finite() {
                return NO_DATA;
            }
            let t = (v / hi).clamp(0.0, 1.0) * 3.0;
            let c = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
            Rgb(c(t), c(t - 1.0), c(t - 2.0))
        })
    }

    /// Nearest-neighbour enlargement by an integer factor (≥ 1).
    pub fn upscale(&self, factor: u32) -> Raster {
        let f = factor.max(1);
        let (w, h) = (self.width * f, self.height * f);
        let mut pixels = Vec::with_capacity(w as usize * h as usize);
        for y in 0..h {
            let row = (y / f) as usize * self.width as usize;
            for x in 0..w {
                pixels.push(self.pixels[row + (x / f) as usize]);
            }
        }
        Raster {
            width: w,
            height: h,
            pixels,
        }
    }

    fn bytes(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| [p.0, p.1, p.2]).collect()
    }

    fn from_bytes(width: u32, height: u32, bytes: &[u8]) -> Raster {
        Raster {
            width,
            height,
            pixels: bytes
                .chunks_exact(3)
                .map(|c| Rgb(c[0], c[1], c[2]))
                .collect(),
        }
    }

    /// Writes the raster as an 8-bit PNG (greyscale when every pixel is grey, else RGB).
    pub fn write_png(&self, path: &Path) -> Result<(), PlotError> {
        let grey = self.pixels.iter().all(|p| p.0 == p.1 && p.1 == p.2);
        let png = if grey {
            let g: Vec<u8> = self.pixels.iter().map(|p| p.0).collect();
            encode_png(self.width, self.height, ::png::ColorType::Grayscale, &g)
        } else {
            encode_png(
                self.width,
                self.height,
                ::png::ColorType::Rgb,
                &self.bytes(),
            )
        }
        .map_err(|e| draw_err(path, e))?;
        std::fs::write(path, png).map_err(|source| PlotError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// PNG with pinned settings, so the same pixels give the same bytes.
pub(crate) fn encode_png(
    width: u32,
    height: u32,
    colour: ::png::ColorType,
    data: &[u8],
) -> Result<Vec<u8>, ::png::EncodingError> {
    let mut out = Vec::new();
    {
        let mut enc = ::png::Encoder::new(&mut out, width, height);
        enc.set_color(colour);
        enc.set_depth(::png::BitDepth::Eight);
        enc.set_compression(::png::Compression::Default);
        enc.set_filter(::png::FilterType::Paeth);
        enc.set_adaptive_filter(::png::AdaptiveFilterType::NonAdaptive);
        let mut w = enc.write_header()?;
        w.write_image_data(data)?;
        w.finish()?;
    }
    Ok(out)
}

/// Writes grey levels in `[0, 1]` (row-major, `w × h`) as an 8-bit grey PNG.
pub fn grey_png(path: &Path, w: u32, h: u32, values: &[f32]) -> Result<(), PlotError> {
    Raster::grey(w, h, values).write_png(path)
}

/// Writes signed values with a diverging colour map (`lo` blue, midpoint white, `hi` red;
/// non-finite = [`NO_DATA`]): residual maps.
pub fn heatmap_png(
    path: &Path,
    w: u32,
    h: u32,
    values: &[f32],
    lo: f32,
    hi: f32,
) -> Result<(), PlotError> {
    Raster::diverging(w, h, values, lo, hi).write_png(path)
}

/// Writes magnitudes `0..=hi` with a black–red–yellow–white map (non-finite = [`NO_DATA`]):
/// absolute differences.
pub fn magnitude_png(
    path: &Path,
    w: u32,
    h: u32,
    values: &[f32],
    hi: f32,
) -> Result<(), PlotError> {
    Raster::magnitude(w, h, values, hi).write_png(path)
}

/// Writes panels side by side (tops aligned) with `gap` white pixels between them.
pub fn image_strip(path: &Path, panels: &[Raster], gap: u32) -> Result<(), PlotError> {
    let w: u32 =
        panels.iter().map(|p| p.width).sum::<u32>() + gap * (panels.len().saturating_sub(1) as u32);
    let h = panels.iter().map(|p| p.height).max().unwrap_or(0);
    let mut out = Raster::filled(w.max(1), h.max(1), Rgb(255, 255, 255));
    let mut x0 = 0u32;
    for p in panels {
        for y in 0..p.height {
            for x in 0..p.width {
                out.pixels[(y * out.width + x0 + x) as usize] =
                    p.pixels[(y * p.width + x) as usize];
            }
        }
        x0 += p.width + gap;
    }
    out.write_png(path)
}

/// The shape of a keypoint marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Circle outline.
    Circle,
    /// Diagonal cross.
    Cross,
    /// Square outline.
    Square,
}

/// A marker on an overlay, in the coordinates of the background image (`(0, 0)` = centre of
/// the top-left pixel, as keypoints are given).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    /// Column.
    pub x: f64,
    /// Row.
    pub y: f64,
    /// Shape.
    pub shape: Shape,
    /// Colour.
    pub colour: Rgb,
    /// Radius in output pixels.
    pub radius: u32,
    /// Line width in output pixels.
    pub stroke: u32,
}

/// A line segment between two background-image points (links a repeated pair).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link {
    /// From `(x, y)`.
    pub from: (f64, f64),
    /// To `(x, y)`.
    pub to: (f64, f64),
    /// Colour.
    pub colour: Rgb,
}

/// Draws markers and links over a background raster enlarged by `scale` (nearest neighbour)
/// and writes it: `(width × scale, height × scale)` pixels. Links are drawn first, then the
/// markers in the order given (later ones on top).
pub fn keypoint_overlay(
    path: &Path,
    background: &Raster,
    scale: u32,
    markers: &[Marker],
    links: &[Link],
) -> Result<(), PlotError> {
    let s = f64::from(scale.max(1));
    let big = background.upscale(scale);
    let (w, h) = (big.width, big.height);
    let mut buf = big.bytes();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let px = |x: f64, y: f64| {
            (
                ((x + 0.5) * s).round() as i32,
                ((y + 0.5) * s).round() as i32,
            )
        };
        for l in links {
            root.draw(&PathElement::new(
                vec![px(l.from.0, l.from.1), px(l.to.0, l.to.1)],
                l.colour.plotters().stroke_width(1),
            ))
            .map_err(|e| draw_err(path, e))?;
        }
        for m in markers {
            let c = px(m.x, m.y);
            let style = m.colour.plotters().stroke_width(m.stroke.max(1));
            let r = m.radius.max(1) as i32;
            match m.shape {
                Shape::Circle => root.draw(&Circle::new(c, r, style)),
                Shape::Cross => root.draw(&Cross::new(c, r, style)),
                Shape::Square => root.draw(&Rectangle::new(
                    [(c.0 - r, c.1 - r), (c.0 + r, c.1 + r)],
                    style,
                )),
            }
            .map_err(|e| draw_err(path, e))?;
        }
        root.present().map_err(|e| draw_err(path, e))?;
    }
    Raster::from_bytes(w, h, &buf).write_png(path)
}

/// Draws into a fresh white RGB buffer of `size` and writes the PNG.
fn chart_png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), String>,
) -> Result<(), PlotError> {
    fonts()?;
    let (w, h) = size;
    let mut buf = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw(&root).map_err(|m| draw_err(path, m))?;
        root.present().map_err(|e| draw_err(path, e))?;
    }
    Raster::from_bytes(w, h, &buf).write_png(path)
}

fn span(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

fn padded((lo, hi): (f64, f64)) -> (f64, f64) {
    if hi - lo < 1e-12 {
        let d = if lo.abs() > 1e-12 {
            lo.abs() * 0.1
        } else {
            1.0
        };
        (lo - d, hi + d)
    } else {
        let d = (hi - lo) * 0.05;
        (lo - d, hi + d)
    }
}

/// Tick labels with as few decimals as they need (`3500`, `0.25`, not `3500.0`).
fn tick(v: &f64) -> String {
    let t = format!("{v:.4}");
    let t = t.trim_end_matches('0').trim_end_matches('.');
    if t == "-0" {
        "0".into()
    } else {
        t.into()
    }
}

/// The legend box of every chart: upper right, small font, translucent white.
fn draw_legend<'a, 'b: 'a>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 12))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .draw()
        .map_err(e)
}

fn e<T: std::fmt::Display>(x: T) -> String {
    x.to_string()
}

/// A line plot of several series with a legend (series with an empty label have none).
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), PlotError> {
    line_plot_axes(path, &Axes::new(title, x_label, y_label), series)
}

/// [`line_plot`] with explicit ranges and size.
pub fn line_plot_axes(path: &Path, axes: &Axes, series: &[Series]) -> Result<(), PlotError> {
    let pts = || series.iter().flat_map(|s| s.points.iter());
    let xr = axes
        .x_range
        .or_else(|| span(pts().map(|p| p.0)).map(padded))
        .unwrap_or((0.0, 1.0));
    let yr = axes
        .y_range
        .or_else(|| span(pts().map(|p| p.1)).map(padded))
        .unwrap_or((0.0, 1.0));
    chart_png(path, axes.size, |root| {
        root.fill(&WHITE).map_err(e)?;
        let mut chart = ChartBuilder::on(root)
            .caption(&axes.title, ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(58)
            .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(axes.x_label.as_str())
            .y_desc(axes.y_label.as_str())
            .x_label_formatter(&tick)
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 13))
            .light_line_style(TRANSPARENT)
            .bold_line_style(RGBColor(225, 225, 225))
            .y_label_formatter(&tick)
            .draw()
            .map_err(e)?;
        let mut legend = false;
        for s in series {
            let c = s.colour.plotters();
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .collect();
            let anno = match s.style {
                SeriesStyle::Line | SeriesStyle::LineMarkers => chart
                    .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                    .map_err(e)?,
                SeriesStyle::Dashed => chart
                    .draw_series(DashedLineSeries::new(pts.clone(), 8, 5, c.stroke_width(2)))
                    .map_err(e)?,
                SeriesStyle::Markers => chart
                    .draw_series(pts.iter().map(|p| Circle::new(*p, 4, c.filled())))
                    .map_err(e)?,
            };
            if !s.label.is_empty() {
                legend = true;
                anno.label(s.label.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                });
            }
            if s.style == SeriesStyle::LineMarkers {
                chart
                    .draw_series(pts.iter().map(|p| Circle::new(*p, 3, c.filled())))
                    .map_err(e)?;
            }
        }
        if legend {
            draw_legend(&mut chart)?;
        }
        Ok(())
    })
}

/// One group of bars (one colour): a value per category, optionally with an interval drawn as
/// an error bar.
#[derive(Debug, Clone, PartialEq)]
pub struct BarGroup {
    /// Legend text.
    pub label: String,
    /// A value per category (NaN = no bar).
    pub values: Vec<f64>,
    /// Optional `(low, high)` per category.
    pub intervals: Vec<Option<(f64, f64)>>,
    /// Colour.
    pub colour: Rgb,
}

impl BarGroup {
    /// A group without intervals.
    pub fn new(label: impl Into<String>, values: Vec<f64>, colour: Rgb) -> BarGroup {
        BarGroup {
            label: label.into(),
            values,
            intervals: Vec::new(),
            colour,
        }
    }

    /// With an interval per category.
    pub fn with_intervals(mut self, intervals: Vec<Option<(f64, f64)>>) -> BarGroup {
        self.intervals = intervals;
        self
    }
}

/// A grouped bar chart: one cluster per category, one bar per group in it (bars start at 0,
/// so negative values hang down). `reference` draws dashed horizontal lines (label, y).
pub fn bar_chart(
    path: &Path,
    axes: &Axes,
    categories: &[String],
    groups: &[BarGroup],
    reference: &[(String, f64)],
) -> Result<(), PlotError> {
    let n = categories.len().max(1);
    let values = groups
        .iter()
        .flat_map(|g| {
            g.values
                .iter()
                .copied()
                .chain(g.intervals.iter().flatten().flat_map(|&(lo, hi)| [lo, hi]))
        })
        .chain(reference.iter().map(|r| r.1))
        .chain([0.0]);
    let yr = axes.y_range.unwrap_or_else(|| {
        let (lo, hi) = span(values).unwrap_or((0.0, 1.0));
        let (plo, phi) = padded((lo, hi));
        (if lo >= 0.0 { 0.0 } else { plo }, phi)
    });
    chart_png(path, axes.size, |root| {
        root.fill(&WHITE).map_err(e)?;
        let mut chart = ChartBuilder::on(root)
            .caption(&axes.title, ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(58)
            .build_cartesian_2d(0.0..n as f64, yr.0..yr.1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .x_desc(axes.x_label.as_str())
            .y_desc(axes.y_label.as_str())
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 13))
            .light_line_style(TRANSPARENT)
            .bold_line_style(RGBColor(225, 225, 225))
            .y_label_formatter(&tick)
            .draw()
            .map_err(e)?;
        let k = groups.len().max(1) as f64;
        let width = 0.8 / k;
        for (gi, g) in groups.iter().enumerate() {
            let c = g.colour.plotters();
            let x0 = |ci: usize| ci as f64 + 0.1 + gi as f64 * width;
            let bars = g
                .values
                .iter()
                .enumerate()
                .filter(|(_, v)| v.is_finite())
                .map(|(ci, &v)| {
                    Rectangle::new([(x0(ci), 0.0), (x0(ci) + width * 0.92, v)], c.filled())
                });
            let anno = chart.draw_series(bars).map_err(e)?;
            if !g.label.is_empty() {
                anno.label(g.label.as_str()).legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 12, y + 5)], c.filled())
                });
            }
            let whisk = g.intervals.iter().enumerate().filter_map(|(ci, iv)| {
                let (lo, hi) = (*iv)?;
                let xm = x0(ci) + width * 0.46;
                Some(PathElement::new(
                    vec![(xm, lo), (xm, hi)],
                    BLACK.stroke_width(2),
                ))
            });
            chart.draw_series(whisk).map_err(e)?;
        }
        for (ri, (label, y)) in reference.iter().enumerate() {
            let c = RGBColor(90, 90, 90);
            let anno = chart
                .draw_series(DashedLineSeries::new(
                    vec![(0.0, *y), (n as f64, *y)],
                    6,
                    4,
                    c.stroke_width(1 + (ri as u32 % 2)),
                ))
                .map_err(e)?;
            if !label.is_empty() {
                anno.label(label.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
            }
        }
        // Category names under each cluster (the x axis is 0..n; labels are placed by hand).
        let style = TextStyle::from(("sans-serif", 13).into_font()).pos(
            plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Center,
                plotters::style::text_anchor::VPos::Top,
            ),
        );
        for (ci, name) in categories.iter().enumerate() {
            let (px, py) = chart.backend_coord(&(ci as f64 + 0.5, yr.0));
            root.draw(&Text::new(name.clone(), (px, py + 6), style.clone()))
                .map_err(e)?;
        }
        if groups.iter().any(|g| !g.label.is_empty()) || reference.iter().any(|r| !r.0.is_empty()) {
            draw_legend(&mut chart)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(path: &Path) -> (u32, u32, Vec<u8>) {
        let dec = ::png::Decoder::new(std::fs::File::open(path).unwrap());
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        let info = r.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    #[test]
    fn plots_are_deterministic_and_have_their_size() {
        let dir = tempfile::tempdir().unwrap();
        let series = vec![
            Series::new("a", vec![(1.0, 0.2), (2.0, 0.5), (5.0, 0.9)], palette(0)),
            Series::new("b", vec![(1.0, 0.1), (5.0, 0.3)], palette(1)).styled(SeriesStyle::Dashed),
        ];
        let p1 = dir.path().join("l1.png");
        let p2 = dir.path().join("l2.png");
        line_plot(&p1, "Title ε", "ε (px)", "repeatability", &series).unwrap();
        line_plot(&p2, "Title ε", "ε (px)", "repeatability", &series).unwrap();
        assert_eq!(std::fs::read(&p1).unwrap(), std::fs::read(&p2).unwrap());
        let (w, h, px) = read(&p1);
        assert_eq!((w, h), CHART_SIZE);
        // Text and lines were drawn: not a blank page.
        assert!(px.iter().filter(|&&v| v < 128).count() > 500);
        let b = dir.path().join("b.png");
        bar_chart(
            &b,
            &Axes::new("counts", "detector", "keypoints"),
            &["harris".into(), "fast".into()],
            &[
                BarGroup::new("real", vec![10.0, 20.0], palette(2))
                    .with_intervals(vec![Some((8.0, 12.0)), None]),
                BarGroup::new("render", vec![5.0, -3.0], palette(1)),
            ],
            &[("threshold".into(), 7.0)],
        )
        .unwrap();
        assert_eq!((read(&b).0, read(&b).1), CHART_SIZE);
    }

    #[test]
    fn rasters_overlays_and_strips() {
        let dir = tempfile::tempdir().unwrap();
        let v: Vec<f32> = (0..12).map(|i| i as f32 / 11.0).collect();
        let g = dir.path().join("g.png");
        grey_png(&g, 4, 3, &v).unwrap();
        let (w, h, px) = read(&g);
        assert_eq!((w, h, px.len()), (4, 3, 12), "8-bit grey");
        assert_eq!((px[0], px[11]), (0, 255));
        let hm = dir.path().join("h.png");
        let signed = [-1.0, 0.0, 1.0, f32::NAN];
        heatmap_png(&hm, 2, 2, &signed, -1.0, 1.0).unwrap();
        let (_, _, px) = read(&hm);
        assert_eq!(&px[0..3], &[33, 102, 172]);
        assert_eq!(&px[3..6], &[247, 247, 247]);
        assert_eq!(&px[6..9], &[178, 24, 43]);
        assert_eq!(&px[9..12], &[NO_DATA.0, NO_DATA.1, NO_DATA.2]);
        let o = dir.path().join("o.png");
        let bg = Raster::grey(4, 3, &v);
        keypoint_overlay(
            &o,
            &bg,
            20,
            &[Marker {
                x: 1.0,
                y: 1.0,
                shape: Shape::Circle,
                colour: Rgb::GREEN,
                radius: 6,
                stroke: 2,
            }],
            &[Link {
                from: (1.0, 1.0),
                to: (2.0, 2.0),
                colour: Rgb::YELLOW,
            }],
        )
        .unwrap();
        let (w, h, px) = read(&o);
        assert_eq!((w, h), (80, 60));
        assert!(
            px.chunks_exact(3).any(|c| c == [0, 200, 60]),
            "marker drawn"
        );
        let s = dir.path().join("s.png");
        image_strip(&s, &[bg.clone(), bg.upscale(2)], 5).unwrap();
        assert_eq!((read(&s).0, read(&s).1), (4 + 5 + 8, 6));
    }
}
