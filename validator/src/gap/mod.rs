//! `regolith gap`: find where the simulation and the measurement disagree, name the missing
//! effect, fit it, and show the gap shrink.
//!
//! The workflow, per terrain entry, over every (capture, camera) view of the release:
//! 1. **Measure** ([`measure`]) with the entry's current sensor model: the photometric residual
//!    of the real frames' mean against the expected render (overall, by image radius, by
//!    intensity, by the terrain's illumination, and in cast shadow of the campaign light), the
//!    radial power-spectrum log-ratio, the noise variance by intensity (from the repeat frames,
//!    next to the model's), and the residual of the dense geometric alignment; per view as
//!    well. Every geometric and photometric effect named is also fitted on each capture
//!    location alone ([`Named::per_capture`]): an effect of the camera is the same in each.
//!    [`measure_model`] takes the same figures for any model: on a synthetic campaign, the
//!    model with the true hidden effects gives the floor a fit can reach.
//! 2. **Attribute**, in the order that keeps effects from masquerading as each other: geometry
//!    first ([`geometry`]: `distortion`, `pose-bias` jointly, by dense alignment), then `blur`
//!    from the width of the skyline edges, the PSF that widens the render's as much ([`blur`]:
//!    a pixel fit would mistake the render's own noise for it), then photometry jointly with that PSF ([`photometry`]: `exposure`,
//!    `vignetting`, `gamma`; the response curve and the black level first from the repeat
//!    frames' noise over the dark background, a photon-transfer analysis the entry does not
//!    enter ([`response`]): when it decides the curve, `gamma` is held at the curve it shows
//!    (or linear) and an exposure's offset at the black level, and the render's samples choose
//!    and fit the rest; a vignetting's strength also from where the stereo head's two
//!    views see the same terrain at different radii, [`overlap`], which the entry's own
//!    radiance errors do not bias, and which can witness a falloff too weak for the render's
//!    samples to name alone), then cast `shadows` of the campaign light where they would fall
//!    ([`shadows`]: too small and sharp for the low-passed photometric fit; the light's
//!    direction, recorded as the lab surveyed it, is searched first), then `texture-lowpass` ([`texture`]: the texture's effective blur against the
//!    real albedo gathered on the ground in the texture's cells, beyond what a faithful texture
//!    of its cell size shows; heightfield entries),
//!    then `noise` (from the repeat frames: on the linear signal by the photon-transfer fit
//!    of [`response`] where the views show a dark background, else by [`noise`]). Within a stage every subset of candidates is fitted and
//!    scored on held-out captures, and the subset is chosen jointly ([`select`]); an effect is
//!    named only if it explains at least a set share of the stage's held-out error (geometry:
//!    0.3 of that share and at least 0.04 band-pass units, because most of its error is texture
//!    no alignment can remove; a distortion must also bring each capture's two real images
//!    closer through the terrain's geometry, which the entry's texture does not enter
//!    ([`geometry::stereo_pairs`], which then join its fit); and the chosen set, rendered,
//!    must lower the photometric RMS and the alignment residual, as a real geometric
//!    correction does).
//! 3. **Add**: the named effects join the entry's sensor model (see [`apply`] for writing it into
//!    a child release), and the measurement is repeated with the new model (before/after); the
//!    headline is the figure the named effects shrink ([`Figure::headline`]).
//!
//! Each stage's orchestration lives in `stages` (one file per stage, on the shared run
//! context of `context`); the models and fits it uses live in the modules named for them
//! ([`geometry`], [`photometry`], ...). What the workflow recovers on the corpus' campaigns and
//! where it stops — measured, with the causes found and the remedies tried — is in
//! `docs/gap-findings.md`.

pub mod apply;
pub mod blur;
pub mod blur_spectrum;
pub mod capture_exposure;
pub mod consistency;
mod context;
pub mod geometry;
pub mod lsq;
pub mod markers;
pub mod measure;
pub mod noise;
mod one_sample;
pub mod overlap;
pub mod photometry;
pub mod response;
pub mod select;
pub mod shadows;
mod stages;
pub mod texture;
pub mod views;

use std::collections::BTreeMap;

use regolith_reader::{ReaderError, ReleaseView};
use serde::Serialize;

use crate::render::Geometry;
use crate::sensor::{stored_model, Effect, SensorModel};
use crate::validate::entry_geometry;

use context::Ctx;
pub use measure::{Figure, Metrics};
use stages::blur::blur_stage;
use stages::geometry::geometry_stage;
use stages::noise::noise_stage;
use stages::photometry::{photometry_stage, NoiseWitness};
use stages::shadows::shadows_stage;
use stages::texture::texture_stage;
use views::Prediction;

/// Options of a gap run.
#[derive(Debug, Clone, PartialEq)]
pub struct GapOptions {
    /// Only these captures (all when empty).
    pub captures: Vec<String>,
    /// Only these cameras (all when empty); one camera of a stereo head runs the workflow as
    /// for a lone camera (no stereo pairs).
    pub cameras: Vec<String>,
    /// Render supersampling per axis, at the pixels where it changes the render
    /// ([`crate::render::Sampling::Edges`]).
    pub supersample: u32,
    /// Minimum held-out share of the stage error an effect must explain to be named.
    pub min_share: f64,
    /// Keep each view's real mean and predictions in [`GapResult::images`] (for the report).
    pub keep_images: bool,
}

impl Default for GapOptions {
    fn default() -> Self {
        GapOptions {
            captures: Vec::new(),
            cameras: Vec::new(),
            supersample: 2,
            min_share: 0.10,
            keep_images: false,
        }
    }
}

/// A named effect.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Named {
    /// Catalogue name.
    pub effect: String,
    /// Fitted parameters.
    pub params: BTreeMap<String, f64>,
    /// Standard error of each parameter: the larger of the least-squares estimate and the
    /// jackknife over captures (the spread of the fits that each leave one capture out); for
    /// `blur`, `texture-lowpass` and the `shadows` direction, which are measured or searched
    /// rather than fitted, the jackknife and the measurement's calibration over mini's
    /// campaigns in quadrature, and for `distortion` the larger one and its calibration
    /// ([`geometry::CALIBRATION_DK`]) in quadrature. The
    /// least-squares one treats every pixel as an independent observation, while neighbouring
    /// residuals are correlated, so alone it is far too small (a fitted dk1 off by 0.003 came
    /// with 0.0001); with two captures the jackknife is itself rough, but of the right size
    /// where the error varies from capture to capture. Where it is shared by every capture (the
    /// laser entry's texture and heights) it is too small: over mini seeds 101–107 twice the
    /// reported error covered the fitted − true error for gamma 14 of 14 times, vignetting 19
    /// of 21, `dk1` 5 of 7 (7 of 7 with its calibration), and per pose-bias axis 6–12 of 14
    /// (`gap_matrix`). A block-robust
    /// (sandwich) error over 48 px image blocks came out 5–7 times the least-squares one and
    /// still under the jackknife: the entry's errors are not a random field over the image.
    /// A pose bias's errors therefore also hold, in quadrature, how far the stereo pairs moved
    /// the render's own fit (see the geometric stage; per axis 12–14 of 14 then).
    pub std_err: BTreeMap<String, f64>,
    /// Share of the stage's held-out error the effect explains.
    pub explained_fraction: f64,
    /// `geometry`, `blur`, `photometry`, `shadows`, `texture` or `noise`.
    pub stage: String,
    /// What showed it.
    pub evidence: String,
    /// The fitted effect in forms that need no catalogue definition, to compare with a lab's
    /// own calibration (`Effect::plain_figures`, with the first view's camera).
    pub plain: BTreeMap<String, f64>,
    /// The effect fitted on each capture location's views alone (geometry and photometry, two
    /// captures or more): an effect fixed to the camera comes out the same in every capture,
    /// within the entry's own error there; a pose or lighting error of one capture does not.
    pub per_capture: Vec<CaptureParams>,
}

/// An effect's parameters fitted on one capture location's views alone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaptureParams {
    /// The capture (the camera, when the views hold one capture).
    pub capture: String,
    /// Fitted parameters.
    pub params: BTreeMap<String, f64>,
}

impl CaptureParams {
    /// `e`'s parameters, fitted on the views of `capture`.
    fn new(capture: &str, e: &Effect) -> CaptureParams {
        CaptureParams {
            capture: capture.to_string(),
            params: param_map(e),
        }
    }
}

/// `e`'s parameters by name.
fn param_map(e: &Effect) -> BTreeMap<String, f64> {
    e.params()
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

/// The entry's texture transfer ([`crate::sensor::TextureTransfer`]) the photometric stage
/// measured: the level at which the camera sees the texture. A texture from another instrument
/// (laser reflectance, an SfM model's colours) has no known level in the camera's terms, and
/// over one entry a constant exposure's gain is the same number, so that gain is the entry's,
/// not the camera's: `exposure` is named only for an offset the transfer cannot take.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TransferFit {
    /// Camera albedo per texture albedo (times a stored transfer's gain).
    pub gain: f64,
    /// Its standard error (as a named effect's, [`Named::std_err`]).
    pub std_err: f64,
    /// What showed it.
    pub evidence: String,
    /// The gain fitted on each capture location's views alone: an entry property comes out the
    /// same at every capture, within the entry's own error there.
    pub per_capture: Vec<CaptureParams>,
}

/// An effect the workflow could not measure or would not name on this data, and why (the
/// evidence it lacked or that spoke against it).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Withheld {
    /// Catalogue name.
    pub effect: String,
    /// `geometry`, `blur`, `photometry`, `shadows`, `texture` or `noise`.
    pub stage: String,
    /// Why.
    pub reason: String,
}

/// One scored candidate subset of a stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoredCandidate {
    /// The effects.
    pub effects: Vec<String>,
    /// Free parameters.
    pub k: usize,
    /// Held-out error (geometry: normalised band-pass residual²; photometry: DN²).
    pub cv_error: f64,
}

/// The result of a gap run.
#[derive(Debug, Clone, Serialize)]
pub struct GapResult {
    /// The release examined.
    pub release_id: String,
    /// The entry.
    pub entry: String,
    /// The named effects, geometry first.
    pub named: Vec<Named>,
    /// Effects not measured or not named for want of evidence, and why.
    pub withheld: Vec<Withheld>,
    /// The headline figure: the one the named effects are read on ([`Figure::headline`]).
    pub gap_metric: Figure,
    /// Headline gap with the model before.
    pub gap_before: f64,
    /// Headline gap with the model after.
    pub gap_after: f64,
    /// All metrics before.
    pub metrics_before: Metrics,
    /// All metrics after.
    pub metrics_after: Metrics,
    /// The model before (the entry's stored one, or plain).
    pub model_before: SensorModel,
    /// The model after (before + named effects).
    pub model_after: SensorModel,
    /// Every candidate of every stage with its held-out error.
    pub candidates: BTreeMap<String, Vec<ScoredCandidate>>,
    /// The texture's effective blur against the real images (heightfield entries).
    pub texture: Option<TextureFigures>,
    /// The texture's transfer, when the photometric stage chose a level change (it is then in
    /// `model_after`).
    pub texture_transfer: Option<TransferFit>,
    /// The response curve, black level and noise the repeat frames show over the dark
    /// background ([`response`]); `None` without two frames per pose or a dark background that
    /// shows its noise.
    pub response: Option<response::ResponseFit>,
    /// Per view, the images behind the figures (only with [`GapOptions::keep_images`]).
    #[serde(skip)]
    pub images: Vec<GapViewImages>,
}

/// The texture's effective blur ([`texture`]), metres.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TextureFigures {
    /// Ground blur of the real albedo that best matches the entry's texture.
    pub effective_blur_m: f64,
    /// What a faithful texture of the entry's cell size shows ([`texture::own_blur_m`]).
    pub own_blur_m: f64,
    /// The low-pass on top of the texture's own.
    pub excess_m: f64,
    /// Band-passed correlation real/texture at the effective blur.
    pub correlation: f64,
    /// The entry's texture cell, metres.
    pub cell_m: f64,
}

/// The images of one view, before and after the named effects, in DN.
#[derive(Debug, Clone)]
pub struct GapViewImages {
    /// Capture name.
    pub capture: String,
    /// Camera name.
    pub camera: String,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Mean of the real frames.
    pub real: Vec<f32>,
    /// Prediction with the model before; `NaN` where the render sees no terrain.
    pub before: Vec<f32>,
    /// Prediction with the model after; `NaN` where the render sees no terrain.
    pub after: Vec<f32>,
}

/// The texture figures ([`texture`]) of `entry` under its stored model, without the other
/// stages: how the own-blur constants are measured on campaigns with nothing hidden (the
/// `texture_blur` example). `None` for a mesh entry or without terrain in view.
pub fn texture_figures(
    view: &ReleaseView,
    entry: &str,
    captures: &[String],
) -> Result<Option<TextureFigures>, ReaderError> {
    let geometry_data = entry_geometry(view, entry)?;
    let opts = GapOptions {
        captures: captures.to_vec(),
        supersample: 1,
        ..GapOptions::default()
    };
    let ctx = Ctx::load(view, &geometry_data, &opts)?;
    let mut model = stored_model(view, entry)?;
    Ok(texture_stage(&ctx, &mut model, &mut Vec::new()))
}

/// Measures the disagreement of `entry`'s renders made with `model` against the real captures,
/// as [`run`] does before and after. With a model holding the true hidden effects of a
/// synthetic campaign this is the floor the workflow can reach: the gap left when nothing is
/// missing but what no sensor model can add (texture, laser noise). The shadow figures are
/// taken on the pixels where the campaign light casts shadows seen through `reference` (the
/// run's [`GapResult::model_before`], to compare with its figures).
pub fn measure_model(
    view: &ReleaseView,
    entry: &str,
    model: &SensorModel,
    reference: &SensorModel,
    opts: &GapOptions,
) -> Result<Metrics, ReaderError> {
    measure_model_on(view, &entry_geometry(view, entry)?, model, reference, opts)
}

/// [`measure_model`] with the terrain given as `geometry` rather than read from an entry.
pub fn measure_model_on(
    view: &ReleaseView,
    geometry: &Geometry,
    model: &SensorModel,
    reference: &SensorModel,
    opts: &GapOptions,
) -> Result<Metrics, ReaderError> {
    let ctx = Ctx::load(view, geometry, opts)?;
    let shadow = ctx.shadow_pixels(reference);
    Ok(ctx.measure(&ctx.predict_all(model), model, &shadow, None))
}

/// The workflow's steps in the order they run, each with its share of a run's time, for
/// [`run_observed`]'s progress: as measured on the estec preset (nothing hidden,
/// `laser/0.015`, two cores, median of three runs 74.6 s: 23.4, 37.5, 0.7, 6.8, 2.0, 3.8, 0.1
/// and 0.2 s); the shares move with what a campaign hides (a stage that names nothing stops
/// early; a hidden blur or cast shadows lengthen their own stage, the shadows stage to
/// minutes; with an effect named the gap after is measured again, some 7 s).
pub const STEPS: [(&str, f64); 8] = [
    ("loading and measuring the gap", 0.314),
    ("geometry: distortion, pose bias", 0.503),
    ("blur", 0.009),
    ("photometry: response, exposure, vignetting", 0.091),
    ("shadows", 0.027),
    ("texture", 0.051),
    ("noise", 0.001),
    ("measuring the gap after", 0.003),
];

/// Reports the start of each of [`STEPS`] with the share of the run done before it.
struct Progress<'a> {
    report: &'a dyn Fn(&str, f64),
    next: usize,
}

impl<'a> Progress<'a> {
    /// Announces the first step to `report`.
    fn start(report: &'a dyn Fn(&str, f64)) -> Self {
        let mut p = Progress { report, next: 0 };
        p.step();
        p
    }

    /// Announces the next step.
    fn step(&mut self) {
        let total: f64 = STEPS.iter().map(|s| s.1).sum();
        let done: f64 = STEPS[..self.next].iter().map(|s| s.1).sum();
        if let Some((label, _)) = STEPS.get(self.next) {
            (self.report)(label, done / total);
        }
        self.next += 1;
    }
}

/// Runs the gap workflow on `entry` (see the module docs).
pub fn run(view: &ReleaseView, entry: &str, opts: &GapOptions) -> Result<GapResult, ReaderError> {
    run_observed(view, entry, opts, &|_, _| {})
}

/// [`run`], calling `progress(step, fraction done)` as each of [`STEPS`] begins. The result
/// does not depend on it.
pub fn run_observed(
    view: &ReleaseView,
    entry: &str,
    opts: &GapOptions,
    progress: &dyn Fn(&str, f64),
) -> Result<GapResult, ReaderError> {
    let mut steps = Progress::start(progress);
    let geometry = entry_geometry(view, entry)?;
    run_steps(view, &geometry, entry, opts, &mut steps)
}

/// Runs the gap workflow with the terrain given as `geometry` instead of `entry`'s own, `entry`
/// still naming the stored sensor model to start from and the result. With a synthetic
/// campaign's true terrain (the corpus' heights and albedo) this separates what the workflow
/// recovers from what the entry costs: on mini the geometric stage then recovers a pose bias
/// within 0.03° and 0.3 mm per axis and a distortion's `dk1` within 3 %, where the laser entry
/// leaves up to 0.5° along the pitch/height valley and 16 % (see `docs/gap-findings.md`).
pub fn run_on(
    view: &ReleaseView,
    geometry: &Geometry,
    entry: &str,
    opts: &GapOptions,
) -> Result<GapResult, ReaderError> {
    run_steps(
        view,
        geometry,
        entry,
        opts,
        &mut Progress::start(&|_, _| {}),
    )
}

/// The workflow on `geometry`, announcing each step to `steps` (the first already announced).
fn run_steps(
    view: &ReleaseView,
    geometry: &Geometry,
    entry: &str,
    opts: &GapOptions,
    steps: &mut Progress<'_>,
) -> Result<GapResult, ReaderError> {
    let ctx = Ctx::load(view, geometry, opts)?;
    let model_before = stored_model(view, entry)?;
    // Where the campaign light casts shadows, seen through the stored geometry: the same
    // pixels before and after, so the two shadow figures compare like with like.
    let flat = match geometry {
        Geometry::Heightfield { albedo, .. } => Some(stages::texture::flat_albedo(albedo)),
        _ => None,
    };
    let (preds_before, shadow, flat) = ctx.predict_with_shadows_and_flat(&model_before, flat);
    let metrics_before = ctx.measure(&preds_before, &model_before, &shadow, flat);
    let witness = NoiseWitness::new(&ctx, &preds_before);
    let mut model = model_before.clone();
    let mut found = Vec::new();
    let mut candidates = BTreeMap::new();
    steps.step();
    candidates.insert(
        "geometry".to_string(),
        geometry_stage(&ctx, &mut model, &preds_before, opts.min_share, &mut found),
    );
    steps.step();
    let mut withheld = Vec::new();
    let mut texture_transfer = None;
    withheld.extend(blur_stage(&ctx, &mut model, opts.min_share, &mut found));
    steps.step();
    candidates.insert(
        "photometry".to_string(),
        photometry_stage(
            &ctx,
            &mut model,
            opts.min_share,
            &witness,
            &mut found,
            &mut withheld,
            &mut texture_transfer,
        ),
    );
    steps.step();
    shadows_stage(&ctx, &mut model, &mut found);
    steps.step();
    let texture = texture_stage(&ctx, &mut model, &mut found);
    steps.step();
    noise_stage(&ctx, &preds_before, &mut model, &witness, &mut found);
    steps.step();
    let preds_after = ctx.predict_all(&model);
    // A measurement depends on nothing but the model (and the views): with nothing named the
    // gap after is the gap before.
    let metrics_after = if model == model_before {
        metrics_before.clone()
    } else {
        ctx.measure(&preds_after, &model, &shadow, None)
    };
    let masked = |p: &Prediction| -> Vec<f32> {
        p.dn.iter()
            .zip(&p.mask)
            .map(|(v, m)| if *m { *v } else { f32::NAN })
            .collect()
    };
    let images = if opts.keep_images {
        ctx.views
            .iter()
            .zip(preds_before.iter().zip(&preds_after))
            .map(|(v, (pb, pa))| GapViewImages {
                capture: v.capture.clone(),
                camera: v.camera.clone(),
                width: v.width,
                height: v.height,
                real: v.mean(),
                before: masked(pb),
                after: masked(pa),
            })
            .collect()
    } else {
        Vec::new()
    };
    let camera = ctx.views.first().map(|v| &v.camera_model);
    for n in &mut found {
        if let Some(e) = model.effects.iter().find(|e| e.name() == n.effect) {
            n.plain = e
                .plain_figures(camera)
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect();
        }
        // An auto-exposing camera's gains as the brightest capture's over the darkest's.
        let gains = model.capture_exposure.values();
        let (lo, hi) = gains.fold((f64::INFINITY, 0.0f64), |(lo, hi), g| {
            (lo.min(*g), hi.max(*g))
        });
        if n.effect == "exposure" && lo > 0.0 && lo.is_finite() {
            n.plain.insert("capture_gain_ratio".into(), hi / lo);
        }
    }
    let headline = Figure::headline(&found.iter().map(|n| n.effect.as_str()).collect::<Vec<_>>());
    Ok(GapResult {
        images,
        release_id: view.id.to_hex(),
        entry: entry.to_string(),
        gap_metric: headline,
        gap_before: headline.of(&metrics_before),
        gap_after: headline.of(&metrics_after),
        named: found,
        withheld,
        metrics_before,
        metrics_after,
        model_before,
        model_after: model,
        candidates,
        texture,
        texture_transfer,
        response: witness.fit,
    })
}
