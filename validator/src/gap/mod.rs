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
//!    from the width of the skyline edges ([`blur`]: a pixel fit would mistake the render's own
//!    noise for it), then photometry jointly with that PSF ([`photometry`]: `exposure`,
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
//! Known limits: `texture-lowpass` cannot bring back the real pattern (it is not in the entry;
//! see [`texture`]): once added, sample renders carry procedural detail of the missing spectrum
//! ([`crate::sensor::detail`]), which has zero mean, so the photometric RMS (against the
//! expected render) stays and the texture's band power against the real albedo's
//! ([`Metrics::texture_band_log_ratio`], the run's headline [`Figure`] then) is what shrinks — on mini seeds 101 and 102 from
//! −0.790 and −0.737 to −0.655 and −0.471, where the same campaigns with a faithful texture
//! read −0.691 and −0.618 (the detail's spectrum, extrapolated from where the low-passed
//! texture still shows its signal, overshoots on seed 102); and the smallest level or
//! contrast change the render names (an exposure; a response curve the noise cannot decide) is
//! about 5 DN RMS, because renders of laser DEMs are themselves a little darker and flatter
//! than the real images (a radial falloff cannot mimic that, so vignetting is named from
//! 3 DN²). Over a terrain's narrow intensity range a mild response curve and an exposure look
//! alike to the render: a curve of 1.18 is an offset of +0.06 within 2 DN, and exposures that
//! brighten with little offset (gains 1.11–1.14, mini seeds 106, 110, 112) had a lower
//! held-out error as curves of 1.10–1.24 from mini's two captures. The repeat frames' noise
//! over the dark background tells them apart whatever the entry ([`response`]): on mini seeds
//! 101–112 every hidden curve (1.18–2.39, and 1.10 and 1.06 set on seeds 101–103) is named
//! within 0.008 of the truth, every exposure whose black level the background shows reads a
//! linear response with its black level within 0.3 DN (its offset is then held there, and its
//! gain, fitted to the render, comes out within 0.8 %: seeds 103, 105, 106, 108, 110, 112), and nothing
//! hidden reads linear. The witness is silent without two frames per pose or a dark
//! background, and undecided when an exposure clips the background to 0 (offsets under about
//! −3 DN: seeds 101, 104, 107, 109, 111) or lifts it so far that the background's noise no
//! longer shows the curve (+10.5 DN, seed 102); then the render decides as before, the dark
//! background bounding an exposure's black level from above
//! ([`photometry::Samples::black_limit`]: an offset that lifts it is a response curve in
//! disguise), and the gains come out 3–8 % off.
//! Parameters are as good as the views are many and as wide as the scene they show. From
//! mini's two captures (four views) a vignetting strength comes out within 5 % alone and next
//! to a response curve or a pose bias (seeds 101–103: −0.4, −1.0, −4.3 %; next to a gamma,
//! held at the curve the noise shows, with a free gain, seeds 101–105: −0.5, −1.7, −3.8, +0.1,
//! −1.0 %, where the curve fitted to the render alone left +1.7 to +6.0 %; it was +8, −9, −23 %
//! and +20 % before the stereo overlap entered the fit), a
//! distortion's displacement at 0.7 of the radius comes out −5.1 and −1.6 % off on the test's seeds
//! (101, 102: dk1 −0.0447 for −0.0466, 0.0391 for 0.0385, −4.1 and +1.5 %, both radial terms fitted
//! to the render and the stereo pairs together); over seeds 101–105 dk1 −4.1, +1.6, +11.4, +15.8
//! and −1.1 % (seed 104: dk2 0.0017 for 0.0075 — the two terms still trade off). With the laser
//! texture's earlier principal-component incidence normal (`merge.clean` v3) seeds 101–107 read
//! −5.8, −1.5, +10.1, +9.0, 0.0, −1.0 and −10.3 % in the displacement (dk1 −5.1, +1.7, +10.5,
//! +15.4, −1.1, +12.3, −16.3 %). With one term it was −8.1, −2.3, +12.8, +10.2, +14.7, −2.2 and
//! +8.7 % (a hidden dk2 of 0.0075–0.0138 went into dk1; dk1 17 % off on average). From the render's
//! samples alone it was −11.8, −10.7, +34.0, +9.2, +2.1, +24.7 and +5.6 %: the laser entry's render
//! residual is lower at that fit than at the truth on every seed checked (101, 102, 103, 106), its
//! texture pulls; the stereo pairs ([`geometry::stereo_pairs`]) do not see the texture. Nor is the
//! entry's registration what is left: the laser block of these campaigns is tilted by 0.13–0.19°
//! against the ground frame (5 markers over 2 m), yet with that error removed by the truth (render
//! samples alone) the test's seeds still read −12 and −4 % in dk1, and the pose bias came out no
//! closer. And a pose bias's rotation and translation trade off (pitch against the vertical
//! translation: seed 102, 0.46° for 0.03° with 14 mm of y) while the displacement they make
//! together at 1.5 m is within 3.2 and 6.7 mm (seeds 101, 102), over seeds 101–107
//! (principal-component incidence normal) within 2.4–6.7 mm (mean 4.1), the roll within 0.03–0.15°
//! (mean 0.084°), the rotation within 0.09–0.73° (mean 0.33°). With the render's samples alone (the
//! pairs out of a pose bias's fit) the same seeds read 2.7–5.5 mm (mean 3.9), roll 0.02–0.30° (mean
//! 0.116°), rotation 0.03–1.27° (mean 0.42°): the pairs see the roll (it moves the right camera
//! vertically about the left) and not a motion common to both
//! cameras; the test `gap_hidden` asserts these measured tolerances. Six capture locations
//! (`corpus generate --captures 6`) bring the displacement within 1.9 and 2.0 mm and the roll
//! within 0.070° and 0.066° (seeds 101, 102; asserted too) and narrow the trade-off without
//! removing it (seed 101: within 0.091° and 1.1 mm on every axis; seed 102: pitch 0.22° off
//! with 6 mm of y): the terrain fills only the lower part of a mini view, where a pitch and a
//! vertical translation look alike at the terrain's distance. Where along that valley the fit
//! stops is set by the entry, not by the optimiser or the pairs' geometry. Given the
//! campaign's true terrain instead ([`run_on`]; `gap_hidden` asserts it) the same fit recovers
//! a pose bias within 0.03° and 0.3 mm on every axis from two locations (seeds 101–104) and a
//! distortion's `dk1` within 3 % (seeds 101–104: −2.7, −0.3, 0.0, +1.1 %; the laser entry
//! reads seeds 103, 104 +11 and +16 %). With nothing hidden (six locations, seed 103) the
//! forced pose-bias fit (render samples and pairs) reads 0.58° of pitch with 17 mm of y on the
//! laser entry, 0.17° and 5 mm with the laser heights under the true albedo, 0.17° and 5 mm
//! with the true heights under the laser texture, and 0.005° and 0.1 mm with both true. Of
//! the entry's heights it is their border that pulls, not their noise or resolution: 5 and
//! 10 cm cut off the laser heightfield's edges took the same fit to 0.41° and 0.23° (0.07°
//! under the true albedo), while the true heights with 2 mm of noise, blocked to 12 mm cells,
//! tilted by the laser block's 0.09° or raised 2 mm stayed within 0.04° (a raise comes out
//! as the translation it is). The stereo pairs alone, through the laser heights, go to 0.57°
//! with 20 mm of y, the same on `laser/0.02` and `sfm/0.02`; through the true heights to
//! 0.05°. A hidden bias on the laser entry comes out shifted the same way (seeds 101–104, six
//! locations: pitch −0.09, +0.22, +0.50, +0.06° off, y 0.7, 6.0, 15.3, 4.0 mm), and six locations
//! do not settle `dk1` against `dk2` there either (seeds 101–107: +0.2, −16.1, +4.9, −2.5, +1.7,
//! +7.1, −9.5 %). The largest single pull was the survey markers (each capture looks at one; see
//! [`markers`]): on seed 103 the 0.7 % of render samples within 4 cm of a marker and the 2.6 % of
//! pairs within 8 cm held all of the fit's preference for its solution over the truth. Kept out,
//! the same seeds read pitch −0.09, +0.14, +0.37, +0.01° off and y 1.7, 2.9, 9.6, 0.7 mm (mean
//! error over the six axes and four seeds 0.12° → 0.09° and 3.6 → 2.7 mm); a distortion from two
//! locations (seeds 101–107) `dk1` +3.9, −6.0, +8.4, +0.8, +8.5, +3.6, −22.9 % (fitted / true
//! − 1; with the markers: −4.1, +1.6, +11.4, +15.8, −1.1 % on 101–105). What still pulls on
//! seed 103 are the render's strongest band-pass features (1.8 % of the samples beyond 3
//! standard deviations) and the ground 5–20 cm inside the heightfield's border; squashing
//! the band-pass (`2·tanh(x/2)`), a Huber or Tukey weight from the fit's residuals, leaving
//! out samples next to the render's depth discontinuities, or leaving out the entry's small
//! bumps (cells 4 mm above the DEM smoothed at 2 cm, where most of the remaining pull on seed
//! 103 sat: dark pebbles) moved the seeds' errors by ±0.1° either way without shrinking them.
//! It is the texture, not the heights: under the true albedo the entry's own heights give a
//! hidden bias within 0.10° and
//! 2.9 mm on every axis from two locations (seeds 101–104; `gap_hidden` asserts 101, 102) and
//! from six. The texture's error against the true albedo (averaged over its 1 cm cells) sits on
//! the relief — RMS 0.14–0.20 on cells 2 mm or more off their 7 cm mean, 0.05 on the flat —
//! where the laser's reflectance keeps the shading of sub-cell facets toward each scanner
//! (the incidence normal is the 6 cm plane's). From six locations seed 103's pitch stays
//! 0.36–0.38° off with the scan's range noise off or its step 2.5 times finer (0.26° with
//! both); in place of the texture, the true albedo averaged over its cells reads 0.09°, and
//! times such shading, blurred 8 mm, 0.16°. Removing the relief from the masks instead loses
//! the alignment's information (pitch up to 0.58°); weighting the stereo pairs three times more
//! moves the error into the vertical translation (−4 to −7 mm). Nor is it the incidence
//! correction's scale: with its normal window at 12 cm instead of 6 seed 103's pitch reads
//! 0.39° off, with no correction at all 0.43° (and an exposure is named), and with a 3 cm
//! window on a scan 2.5 times finer 0.52°. Leaving out what the laser DEM interpolated (cells
//! under TIN triangles longer than 2.5 times the median, and filled holes, with two cells'
//! margin: 2–4 % of a view's terrain pixels, most at its far end) took seed 103's pitch from
//! six locations to 0.17° and 5.9 mm, and the mean error over seeds 101–104 from two
//! locations from 0.154° and 4.5 mm to 0.131° and 3.6 mm, but seed 101's `dk1` went from
//! 3.9 % to 15.2 % off and seed 106's pose bias was no longer named: the far terrain holds
//! the radial lever arm and much of a pose's signal (without the margin, or with four cells,
//! the same trade). Nor is the reconstruction's entry closer: `sfm/0.02` (2 cm heights fitted
//! to the SfM mesh, its vertex colours the albedo blurred by 1 cm, without the laser's
//! shading) gave from two locations on seeds 101–104 a pose bias within the targets on 2, 2,
//! 1 of four rotation axes and 3, 1, 3 translation axes, `dk1` within 5 % once (one
//! distortion not named), and `texture-lowpass` named next to a distortion, a pose bias and
//! nothing hidden (its colours are blurrier than the laser's 1 cm texture).
//! From estec's eight captures a
//! hidden vignetting of 0.4756 came out 0.4775 ± 0.0008 and a pose bias within 0.041° and
//! 0.4 mm per axis (seed 2; 0.049° and 0.8 mm with the survey markers kept out; 0.026° and
//! 1.1 mm from the render's samples alone, before the rig-frame bias and the pairs), a hidden distortion (dk1 −0.0417, dk2 0.0056) came out dk1
//! −0.0397 ± 0.0004, dk2 0.0034 ± 0.0004 (−5.0 % in dk1, displacement at 0.7 of the radius
//! −2.6 %; stereo residual 0.187 → 0.017; with one radial term −0.0370, −5.0 % in the
//! displacement), and nothing hidden named nothing. A hidden texture low-pass of 27.5 mm came
//! out 24.1 ± 4.1 mm, alone; before the rig-frame bias and the stereo pairs a false pose bias
//! (28 mm along the optical axis) was named next to it (the band-pass alignment, with the
//! texture low-passed, sees mostly relief shading). It is no longer chosen because its
//! held-out drop, 0.034, is under the geometric floor (0.04) — not because the pairs rejected it.
//! Through one camera alone (`gap --cameras navcam_left`, as for a rover with one NavCam: no
//! stereo pairs, the radial terms chosen on the held-out render residual, the camera its own
//! rig frame) seeds 101, 102 read a distortion's displacement −7.0 and −16.2 % off (dk1
//! −8.1 and −14.7 %, one term chosen), a pose bias's displacement 3.1 and 6.3 mm off, and
//! nothing hidden named nothing (asserted by `gap_hidden`). Over seeds 101–107 every case is
//! named right, but without the pairs the texture pulls the distortion again (displacement
//! −15.0 to +39.4 % off) and the roll is looser (up to 0.27° off; displacement 2.6–6.4 mm).

pub mod apply;
pub mod blur;
pub mod geometry;
pub mod lsq;
pub mod markers;
pub mod measure;
pub mod noise;
pub mod overlap;
pub mod photometry;
pub mod response;
pub mod select;
pub mod shadows;
pub mod texture;
pub mod views;

use std::collections::BTreeMap;

use regolith_format::frames::Pose;
use regolith_reader::{ReaderError, ReleaseView};
use serde::Serialize;

use crate::render::{AlbedoGrid, Geometry, HeightGrid, Light, Scene};
use crate::sensor::{stored_model, Effect, Placement, SensorModel};
use crate::validate::{campaign_light, entry_geometry};

pub use measure::{Figure, Metrics};
use select::{choose, choose_with, subsets, Candidate};
use views::{load_views, predict, GapView, ImagePair, Prediction};

/// Options of a gap run.
#[derive(Debug, Clone, PartialEq)]
pub struct GapOptions {
    /// Only these captures (all when empty).
    pub captures: Vec<String>,
    /// Only these cameras (all when empty); one camera of a stereo head runs the workflow as
    /// for a lone camera (no stereo pairs).
    pub cameras: Vec<String>,
    /// Render supersampling per axis.
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
    /// campaigns in quadrature. The
    /// least-squares one treats every pixel as an independent observation, while neighbouring
    /// residuals are correlated, so alone it is far too small (a fitted dk1 off by 0.003 came
    /// with 0.0001); with two captures the jackknife is itself rough, but of the right size
    /// where the error varies from capture to capture. Where it is shared by every capture (the
    /// laser entry's texture and heights) it is too small: over mini seeds 101–107 twice the
    /// reported error covered the fitted − true error for gamma 14 of 14 times, vignetting 19
    /// of 21, `dk1` 5 of 7, and per pose-bias axis 6–12 of 14 (`gap_matrix`). A block-robust
    /// (sandwich) error over 48 px image blocks came out 5–7 times the least-squares one and
    /// still under the jackknife: the entry's errors are not a random field over the image.
    /// A pose bias's errors therefore also hold, in quadrature, how far the stereo pairs moved
    /// the render's own fit (see the geometric stage).
    pub std_err: BTreeMap<String, f64>,
    /// Share of the stage's held-out error the effect explains.
    pub explained_fraction: f64,
    /// `geometry`, `blur`, `photometry`, `shadows`, `texture` or `noise`.
    pub stage: String,
    /// What showed it.
    pub evidence: String,
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

/// Fold of each view: the index of its capture (views of one capture are held out together).
fn folds(views: &[GapView]) -> Vec<usize> {
    let mut names: Vec<&str> = views.iter().map(|v| v.capture.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    if names.len() >= 2 {
        views
            .iter()
            .map(|v| names.iter().position(|n| *n == v.capture).unwrap_or(0))
            .collect()
    } else {
        // One capture: hold out cameras instead.
        let mut cams: Vec<&str> = views.iter().map(|v| v.camera.as_str()).collect();
        cams.sort_unstable();
        cams.dedup();
        views
            .iter()
            .map(|v| cams.iter().position(|n| *n == v.camera).unwrap_or(0))
            .collect()
    }
}

/// Held-out error of a fit: mean over folds of `test(train on the others, fold)`; with one
/// fold, the in-sample error.
fn cross_validate(n_folds: usize, fit_and_test: &(dyn Fn(Option<usize>) -> f64 + Sync)) -> f64 {
    if n_folds < 2 {
        return fit_and_test(None);
    }
    (0..n_folds).map(|f| fit_and_test(Some(f))).sum::<f64>() / n_folds as f64
}

/// Jackknife standard errors over folds: `fit(f)` gives the parameters fitted without fold `f`;
/// `sqrt((n − 1) / n · Σ (θ_f − θ̄)²)` per parameter. `None` with fewer than two folds.
fn jackknife(n_folds: usize, fit: &(dyn Fn(usize) -> Vec<f64> + Sync)) -> Option<Vec<f64>> {
    if n_folds < 2 {
        return None;
    }
    jackknife_spread(&(0..n_folds).map(fit).collect::<Vec<_>>())
}

/// The jackknife standard errors of leave-one-fold-out `fits` (see [`jackknife`]); `None` with
/// fewer than two.
fn jackknife_spread(fits: &[Vec<f64>]) -> Option<Vec<f64>> {
    if fits.len() < 2 {
        return None;
    }
    let n_folds = fits.len();
    let k = fits.first()?.len();
    let n = n_folds as f64;
    Some(
        (0..k)
            .map(|i| {
                let mean = fits.iter().map(|f| f[i]).sum::<f64>() / n;
                let ss = fits.iter().map(|f| (f[i] - mean).powi(2)).sum::<f64>();
                ((n - 1.0) / n * ss).sqrt()
            })
            .collect(),
    )
}

/// The larger of the least-squares and the jackknife standard error, per parameter.
fn honest_std_err<const K: usize>(formal: [f64; K], jack: Option<Vec<f64>>) -> [f64; K] {
    let mut out = formal;
    if let Some(j) = jack {
        for (o, j) in out.iter_mut().zip(j) {
            *o = o.max(j);
        }
    }
    out
}

struct Ctx<'a> {
    geometry: &'a Geometry,
    scene: Scene<'a>,
    light: Light,
    views: Vec<GapView>,
    folds: Vec<usize>,
    n_folds: usize,
    supersample: u32,
    /// Ground-frame survey markers, kept out of the geometric fit ([`markers`]).
    markers: Vec<[f64; 3]>,
}

impl<'a> Ctx<'a> {
    /// The views of `opts.captures` and `opts.cameras` (all when empty) of the release, with
    /// the entry's `geometry`, rendered at `opts.supersample`.
    fn load(
        view: &ReleaseView,
        geometry: &'a Geometry,
        opts: &GapOptions,
    ) -> Result<Ctx<'a>, ReaderError> {
        let views = load_views(view, &opts.captures, &opts.cameras)?;
        let folds = folds(&views);
        let n_folds = folds.iter().max().map_or(1, |m| m + 1);
        Ok(Ctx {
            geometry,
            scene: Scene::new(geometry),
            light: campaign_light(view)?,
            views,
            folds,
            n_folds,
            supersample: opts.supersample.max(1),
            markers: markers::survey_markers(view)?,
        })
    }

    /// Per view, the pixels in cast shadow of the campaign light (as [`shadows::shadow_pixels`])
    /// when the scene is seen through `model`'s geometry: where [`Metrics::shadow_rms_dn`] is
    /// measured.
    fn shadow_pixels(&self, model: &SensorModel) -> Vec<Vec<bool>> {
        let mut lit = model.clone();
        lit.effects.retain(|e| e.name() != "shadows");
        let mut shadowed = lit.clone();
        shadowed.effects.push(Effect::Shadows {
            azimuth_deg: self.light.azimuth_deg,
            elevation_deg: self.light.elevation_deg,
        });
        let (lit, shadowed) = (
            self.predict_sampled(&lit, 1),
            self.predict_sampled(&shadowed, 1),
        );
        self.views
            .iter()
            .zip(lit.iter().zip(&shadowed))
            .map(|(v, (l, s))| shadows::shadow_pixels(&l.dn, &s.dn, &l.mask, v.width, v.height))
            .collect()
    }

    /// Measures `preds` (made with `model`) against the real views; with a `texture-lowpass`
    /// in `model`, the spectrum is taken on renders with its texture detail.
    fn measure(&self, preds: &[Prediction], model: &SensorModel, shadow: &[Vec<bool>]) -> Metrics {
        let detailed_geometry = model.detailed(self.geometry);
        let detailed = detailed_geometry.as_ref().map(|g| {
            let scene = Scene::new(g);
            self.views
                .iter()
                .map(|v| predict(&scene, &self.light, v, model, self.supersample).radiance)
                .collect::<Vec<_>>()
        });
        let inputs = match self.geometry {
            Geometry::Heightfield { grid, albedo } => {
                Some(TextureInputs::new(self, grid, albedo, model))
            }
            _ => None,
        };
        let shading: Option<Vec<&[f32]>> = inputs
            .as_ref()
            .map(|t| t.flat.iter().map(|p| p.radiance.as_slice()).collect());
        let align_mask = geometric_masks(self, model, preds);
        let mut m = measure::measure(
            &self.views,
            preds,
            model,
            shadow,
            detailed.as_deref(),
            shading.as_deref(),
            &align_mask,
        );
        if let (Geometry::Heightfield { albedo, .. }, Some(inputs)) = (self.geometry, &inputs) {
            let texture = match &detailed_geometry {
                Some(Geometry::Heightfield { albedo, .. }) => albedo,
                _ => albedo,
            };
            m.texture_band_log_ratio = texture::band_power_log_ratio(&inputs.views(self), texture);
        }
        m
    }

    /// The name of each fold: its capture (its camera, when the views hold one capture).
    fn fold_names(&self) -> Vec<String> {
        (0..self.n_folds)
            .map(|k| {
                let v = self.views.iter().zip(&self.folds).find(|(_, f)| **f == k);
                v.map_or_else(String::new, |(v, _)| {
                    if self.n_folds >= 2 && self.views.iter().any(|w| w.capture != v.capture) {
                        v.capture.clone()
                    } else {
                        v.camera.clone()
                    }
                })
            })
            .collect()
    }

    fn predict_all(&self, model: &SensorModel) -> Vec<Prediction> {
        self.predict_sampled(model, self.supersample)
    }

    fn predict_sampled(&self, model: &SensorModel, supersample: u32) -> Vec<Prediction> {
        self.views
            .iter()
            .map(|v| predict(&self.scene, &self.light, v, model, supersample))
            .collect()
    }
}

fn has(model: &SensorModel, name: &str) -> bool {
    model.effects.iter().any(|e| e.name() == name)
}

/// Adds `e` to `model`: an effect already present is replaced by `e`.
fn upsert(model: &mut SensorModel, e: Effect) {
    match model.effects.iter_mut().find(|x| x.name() == e.name()) {
        Some(x) => *x = e,
        None => model.effects.push(e),
    }
}

fn named(
    e: &Effect,
    std_err: BTreeMap<String, f64>,
    share: f64,
    stage: &str,
    evidence: String,
) -> Named {
    Named {
        effect: e.name().to_string(),
        params: param_map(e),
        std_err,
        explained_fraction: share,
        stage: stage.to_string(),
        evidence,
        per_capture: Vec::new(),
    }
}

fn scored(cands: &[Candidate]) -> Vec<ScoredCandidate> {
    cands
        .iter()
        .map(|c| ScoredCandidate {
            effects: c.effects.iter().map(|s| s.to_string()).collect(),
            k: c.k,
            cv_error: c.cv_error,
        })
        .collect()
}

type Levels = Vec<(Vec<geometry::ViewImages>, Vec<geometry::Observation>)>;

/// The terrain mask of the render `p` of view `i` under `model`, without the survey markers'
/// discs ([`markers::keep_out`]): what the geometric stage band-passes and samples.
fn geometric_mask(ctx: &Ctx<'_>, model: &SensorModel, i: usize, p: &Prediction) -> Vec<bool> {
    let v = &ctx.views[i];
    let mut mask = p.mask.clone();
    markers::keep_out(
        &mut mask,
        v.width,
        v.height,
        &p.camera,
        &model.pose(&v.at),
        &ctx.markers,
    );
    mask
}

/// [`geometric_mask`] of every render of `preds`.
fn geometric_masks(ctx: &Ctx<'_>, model: &SensorModel, preds: &[Prediction]) -> Vec<Vec<bool>> {
    preds
        .iter()
        .enumerate()
        .map(|(i, p)| geometric_mask(ctx, model, i, p))
        .collect()
}

/// The band-pass levels of every view for the geometric fit, from the renders `preds` of
/// `model`.
fn geometry_levels(ctx: &Ctx<'_>, model: &SensorModel, preds: &[Prediction]) -> Levels {
    let masks = geometric_masks(ctx, model, preds);
    geometry::LEVELS
        .iter()
        .map(|band| {
            let mut imgs = Vec::new();
            let mut obs = Vec::new();
            for (i, (v, p)) in ctx.views.iter().zip(preds).enumerate() {
                let (img, o) = geometry::prepare(
                    i,
                    ctx.folds[i],
                    &p.dn,
                    &v.mean(),
                    &masks[i],
                    &p.depth,
                    &p.camera,
                    v.at.rig_from_camera,
                    v.width,
                    v.height,
                    *band,
                );
                imgs.push(img);
                obs.extend(o);
            }
            (imgs, obs)
        })
        .collect()
}

/// The stereo pairs ([`geometry::stereo_pairs`]) of every level of `levels`, which were made
/// from `preds`, the renders of `model`.
fn stereo_levels(
    ctx: &Ctx<'_>,
    model: &SensorModel,
    preds: &[Prediction],
    levels: &Levels,
) -> Levels {
    let poses: Vec<Pose> = ctx.views.iter().map(|v| model.pose(&v.at)).collect();
    let depth: Vec<&[f32]> = preds.iter().map(|p| p.depth.as_slice()).collect();
    let masks = geometric_masks(ctx, model, preds);
    let mask: Vec<&[bool]> = masks.iter().map(Vec::as_slice).collect();
    levels
        .iter()
        .map(|(imgs, obs)| {
            let pairs = geometry::stereo_pairs(obs, imgs, &poses, &depth, &mask);
            (imgs.clone(), pairs)
        })
        .collect()
}

/// The render samples of `levels` and the stereo pairs of `stereo`, the pairs weighted by
/// `weight`.
fn joined(levels: &Levels, stereo: &Levels, weight: f64) -> Levels {
    levels
        .iter()
        .zip(stereo)
        .map(|((imgs, obs), (_, pairs))| {
            let mut all = obs.clone();
            all.extend(pairs.iter().map(|o| geometry::Observation { weight, ..*o }));
            (imgs.clone(), all)
        })
        .collect()
}

/// A geometric fit joined by the stereo pairs.
struct Witness {
    /// The render samples and the weighted pairs.
    levels: Levels,
    /// Stereo residual at zero increment.
    before: f64,
    /// Stereo residual at the joint fit.
    after: f64,
    /// Weight of a pair.
    weight: f64,
    /// The render samples' own fit, before the pairs joined it.
    render_only: [f64; 8],
}

/// Fits `set` on `levels` (made from `preds`, the renders of `model`): the render's own fit,
/// then, where the views hold stereo pairs, the joint fit with them (which they must confirm),
/// each pair weighted by the ratio of the two residuals' standard deviations at the render's
/// own fit (inverse-variance weighting; 8–9 on mini). With the pairs a distortion gets both
/// radial terms: the pairs see the radial profile through the terrain's geometry, free of the
/// texture, and the second term took the hidden distortion's displacement at 0.7 of the radius
/// from 8.1, 2.3, 12.8, 10.2, 14.7, 2.2, 8.7 % off (one term) to 5.8, 1.5, 10.1, 9.0, 0.0, 1.0,
/// 10.3 % (mini seeds 101–107), dk1 from 17 % off on average to 8.9 %. The held-out residual,
/// render and pairs together, did not tell which seeds gain (it asked for the second term on
/// 103 and 107, and 107 lost), so it does not decide. Without pairs (a lone camera)
/// `lone_terms` decides. Returns the fit, the radial terms it used and the pairs' figures.
///
/// Each view carries its camera's place on the rig ([`crate::sensor::Placement`]), so a pose
/// bias moves both cameras of a capture as the rig moves them, and the pairs see a bias as it
/// is. (While the model applied a bias in each camera's own frame, the right camera swung about
/// its own centre — ≈ 0.9 mm for 0.5° over the 10 cm baseline, 0.24 px at 1.5 m — which the
/// pairs, whose floor is 0.015, did see: they pulled the fitted roll towards zero, mini seed
/// 102: −0.08° for −0.30°, where it now reads −0.27°.)
fn witnessed_fit(
    ctx: &Ctx<'_>,
    model: &SensorModel,
    preds: &[Prediction],
    levels: &Levels,
    set: &[&str],
    lone_terms: &dyn Fn() -> usize,
) -> (geometry::GeometryFit, usize, Option<Witness>) {
    let stereo = stereo_levels(ctx, model, preds, levels);
    if stereo.last().is_none_or(|(_, pairs)| pairs.is_empty()) {
        let terms = lone_terms();
        return (fit_levels(levels, set, terms, &|_, _| true), terms, None);
    }
    let f = fit_levels(levels, set, 1, &|_, _| true);
    let render_only = f.params;
    let stereo_mse = |p: &[f64; 8]| {
        stereo
            .last()
            .map_or(0.0, |(imgs, obs)| geometry::mse(obs, imgs, p))
    };
    let weight = (f.mse / stereo_mse(&f.params).max(1e-9)).sqrt();
    let both = joined(levels, &stereo, weight);
    let terms = if set.contains(&"distortion") { 2 } else { 1 };
    let f = fit_levels(&both, set, terms, &|_, _| true);
    let witness = Witness {
        before: stereo_mse(&[0.0; 8]),
        after: stereo_mse(&f.params),
        levels: both,
        weight,
        render_only,
    };
    (f, terms, Some(witness))
}

/// Coarse-to-fine fit of `set` on the observations passing `keep`, the distortion with
/// `radial_terms` terms.
///
/// The distortion's first term is fitted alone at every level and the second, if asked for,
/// is freed only at the end, from that solution: dk1 and dk2 trade off along a long valley
/// over the terrain's part of the image, and started from zero the two-term fit stopped in
/// another basin (mini seed 101: dk1 −0.059, dk2 +0.046 — outside dk2's plausible range —
/// for a hidden −0.047, +0.001, at a residual of 1.0865 where dk1 alone reaches 1.0808).
fn fit_levels(
    levels: &Levels,
    set: &[&str],
    radial_terms: usize,
    keep: &dyn Fn(&geometry::Observation, &[geometry::ViewImages]) -> bool,
) -> geometry::GeometryFit {
    let mut start = [0.0; 8];
    let mut last = None;
    for (level, (imgs, obs)) in levels.iter().enumerate() {
        let train: Vec<_> = obs.iter().filter(|o| keep(o, imgs)).copied().collect();
        let mut f = geometry::fit(&train, imgs, set, 1, &start);
        if radial_terms > 1 && set.contains(&"distortion") && level + 1 == levels.len() {
            f = geometry::fit(&train, imgs, set, radial_terms, &f.params);
        }
        start = f.params;
        last = Some(f);
    }
    last.unwrap_or(geometry::GeometryFit {
        params: [0.0; 8],
        std_err: [0.0; 8],
        mse: 0.0,
    })
}

/// The geometric stage's share rule is `min_share` times this. Its error, the band-pass residual
/// of unit-variance images, has a floor no geometry can remove: the fine texture the entry does
/// not reproduce (a laser-reflectance render correlates with the real band-pass at ρ ≈ 0.4, so
/// the error is ≈ 2 − 2ρ ≈ 1.1–1.2 with perfect alignment). A share of that floor understates
/// what an effect explains; a hidden distortion of dk1 −0.047 (36 px at the corners) removed
/// 9.7 % of it. Significance then rests on [`GEOMETRY_MIN_ABS`].
const GEOMETRY_SHARE_FACTOR: f64 = 0.3;

/// Smallest held-out reduction of the band-pass residual (unit-variance units) for which a
/// geometric effect is named. On mini campaigns with nothing geometric hidden, the best
/// geometric set reduced it by at most 0.009; a companion effect fitted next to a real one
/// (pose bias next to a hidden distortion, distortion next to a hidden pose bias) by up to 0.031;
/// a hidden distortion of dk1 −0.047 by 0.118, a hidden pose bias of 0.4°/15 mm by 0.67.
const GEOMETRY_MIN_ABS: f64 = 0.04;

/// Smallest drop of the alignment residual (band-pass units, all views, renders made with
/// the model) for which a chosen geometric set is named. Hidden effects on mini dropped it by
/// 0.056 and 0.069 (distortion, seeds 101, 102) and by 0.3–0.6 (pose bias).
const GEOMETRY_MIN_RERENDERED: f64 = 0.02;

/// The alignment residual at zero increment over all views at the finest level of `levels`
/// (what [`measure`] reports).
fn alignment_residual(levels: &Levels) -> f64 {
    levels
        .last()
        .map_or(0.0, |(imgs, obs)| geometry::mse(obs, imgs, &[0.0; 8]))
}

/// Stage 1: geometry. Returns the scored candidates and updates `model`.
fn geometry_stage(
    ctx: &Ctx<'_>,
    model: &mut SensorModel,
    min_share: f64,
    out: &mut Vec<Named>,
) -> Vec<ScoredCandidate> {
    let preds = ctx.predict_all(model);
    let levels = geometry_levels(ctx, model, &preds);
    let Some((_, fine_obs)) = levels.last() else {
        return Vec::new();
    };
    if fine_obs.len() < 100 {
        return Vec::new();
    }
    let names: Vec<&'static str> = ["distortion", "pose-bias"].to_vec();
    let cands: Vec<Candidate> = subsets(&names)
        .into_iter()
        .map(|set| {
            let cv = cross_validate(ctx.n_folds, &|hold| held_out_mse(&levels, &set, 1, hold));
            Candidate {
                k: geometry::free(&set, 1).len(),
                effects: set,
                cv_error: cv,
            }
        })
        .collect();
    let Some(choice) = choose(&cands, min_share * GEOMETRY_SHARE_FACTOR, GEOMETRY_MIN_ABS) else {
        return scored(&cands);
    };
    let set = cands[choice.index].effects.clone();
    if set.is_empty() {
        return scored(&cands);
    }
    let one_term_cv = cands[choice.index].cv_error;
    // Fit on everything and apply; a pose bias is then refined once from a render seen from
    // the corrected pose. A pose bias moves the camera: what the render occludes and where
    // its silhouette falls change, which the fixed render's samples cannot follow (mini seed
    // 101, 2 captures: the displacement at 1.5 m came out 15.8 mm off without the refinement,
    // 3.8 mm with it). A distortion only remaps the same rays, which the samples model
    // exactly; refitting it from the corrected render swung it back and forth (seed 101: dk1
    // −0.046, −0.024, −0.044 in three rounds).
    //
    // The render's own fit comes first; the stereo pairs then join it ([`witnessed_fit`]), so
    // they steer the parameters where the texture biases the render's samples. And the
    // correction must bring each capture's two real images closer through the terrain's
    // geometry. One fitted to the entry's texture does not: with a texture low-pass hidden (mini seed 102) a distortion
    // fitted to the render raised the stereo residual from 0.015 to 0.135, where hidden
    // distortions lowered it (0.133 → 0.013 and 0.063 → 0.018 on seeds 101, 102).
    let lone_terms = || radial_terms(ctx, &levels, &set, one_term_cv);
    let (f, terms, witness) = witnessed_fit(ctx, model, &preds, &levels, &set, &lone_terms);
    if let Some(w) = &witness {
        if w.after >= w.before {
            return scored(&cands);
        }
    }
    let mut current = with_geometry(model, &set, &f.params);
    let mut std_err_fit = f.std_err;
    if set.contains(&"pose-bias") {
        let seen = ctx.predict_all(&current);
        let seen_levels = geometry_levels(ctx, &current, &seen);
        let (refine, _, _) = witnessed_fit(ctx, &current, &seen, &seen_levels, &set, &|| terms);
        current = with_geometry(&current, &set, &refine.params);
        std_err_fit = refine.std_err;
    }

    let joint = witness.as_ref().map_or(&levels, |w| &w.levels);
    let jack = jackknife(ctx.n_folds, &|hold| {
        let p = fit_levels(joint, &set, terms, &|o, imgs| imgs[o.view].fold != hold).params;
        let mut v = p.to_vec();
        v.push(radial_shift(&p));
        v
    });
    // dk1 and dk2 trade off over the terrain's part of the image, so each alone can be within
    // its error of zero while the displacement they make together is well determined: a
    // distortion is named only if that displacement is (mini seed 102 with a 19 mm texture
    // low-pass hidden chose a distortion whose two captures disagreed on it).
    if set == ["distortion"] {
        if let Some(j) = &jack {
            if radial_shift(&f.params).abs() < SIGNIFICANCE * j[8] {
                return scored(&cands);
            }
        }
    }
    let mut std_err = honest_std_err(
        std_err_fit,
        jack.map(|mut j| {
            j.truncate(8);
            j
        }),
    );
    // What every capture shares — the entry's texture and heights — neither the least squares
    // nor the jackknife over captures see; the two witnesses do: the render's samples carry
    // the texture's pull, the pairs do not, and how far the pairs moved the render's own fit
    // is the scale of that pull. Added in quadrature to the pose bias's errors it raised the
    // share of axes whose fitted − true error was within twice the reported error from 51 to
    // 80 of 84 (mini seeds 101–107, a pose bias alone and next to a vignetting; pitch standard
    // errors 0.05–0.41° for errors up to 0.42°). Not to the distortion's: the render's own fit has one
    // radial term, the joint one two, so their difference is the terms' trade-off.
    if let Some(w) = &witness {
        for ((e, r), p) in std_err.iter_mut().zip(w.render_only).zip(f.params).skip(2) {
            *e = e.hypot(r - p);
        }
    }
    // A geometric correction that is real brings the images closer in plain intensity too; one
    // that only fits the band-passed texture better (a rotation traded against a translation
    // along an ill-conditioned valley) does not. On mini seed 103 with nothing hidden, pose-bias
    // (1.1°, 2.9 cm: outside the plausible range) lowered the held-out band-pass residual by
    // 0.046 and raised the photometric RMS in every view (15.34 → 15.60 DN overall); hidden
    // effects lowered it (distortion 16.04 → 15.95, pose-bias 15.43 → 13.92 and 19.51 → 16.31).
    // The RMS is taken after a gain and offset per view (see `photometric_rms_pair`).
    let corrected = ctx.predict_all(&current);
    let (rms_before, rms_after) = photometric_rms_pair(ctx, &preds, &corrected);
    if rms_after >= rms_before {
        return scored(&cands);
    }
    // The held-out residual is taken against the uncorrected render; rendered with the
    // correction, a real geometric effect brings the images closer too. One that only moved
    // the samples to where the real band-pass is weaker does not: with a texture low-pass
    // hidden (mini seed 102) a distortion of dk1 −0.064, the same in both captures, lowered the
    // held-out residual by 0.068 and the re-rendered one by 0.004.
    if alignment_residual(&levels) - alignment_residual(&geometry_levels(ctx, &current, &corrected))
        < GEOMETRY_MIN_RERENDERED
    {
        return scored(&cands);
    }
    // Per capture: the first pass (before a pose bias's refinement) on that capture's samples
    // and pairs alone.
    let names = ctx.fold_names();
    let per_fold: Vec<(String, SensorModel)> = if ctx.n_folds >= 2 {
        (0..ctx.n_folds)
            .map(|k| {
                let q = fit_levels(joint, &set, terms, &|o, imgs| imgs[o.view].fold == k).params;
                (names[k].clone(), with_geometry(model, &set, &q))
            })
            .collect()
    } else {
        Vec::new()
    };
    *model = current;
    let base_err = cands
        .iter()
        .find(|c| c.effects.is_empty())
        .map_or(0.0, |c| c.cv_error);
    for (name, share) in &choice.explained {
        let range = if *name == "distortion" { 0..2 } else { 2..8 };
        let errs = range
            .map(|i| (geometry::PARAMS[i].to_string(), std_err[i]))
            .collect();
        let Some(e) = model.effects.iter().find(|x| x.name() == *name).copied() else {
            continue;
        };
        let mut n = named(
            &e,
            errs,
            *share,
            "geometry",
            format!(
                "dense alignment: held-out band-pass residual {:.4} with no effect, {:.4} with the chosen set{}",
                base_err,
                cands[choice.index].cv_error,
                witness.as_ref().map_or(String::new(), |w| format!(
                    "; stereo residual {:.4} → {:.4} (pairs weighted {:.1})",
                    w.before, w.after, w.weight
                ))
            ),
        );
        n.per_capture = per_fold
            .iter()
            .filter_map(|(c, m)| {
                let e = m.effects.iter().find(|x| x.name() == *name)?;
                Some(CaptureParams::new(c, e))
            })
            .collect();
        out.push(n);
    }
    scored(&cands)
}

/// Held-out band-pass residual of `set` (the distortion with `radial_terms` terms) fitted on
/// every fold but `hold` (on everything, and measured on everything, for `None`).
fn held_out_mse(levels: &Levels, set: &[&str], radial_terms: usize, hold: Option<usize>) -> f64 {
    let Some((fine_imgs, fine_obs)) = levels.last() else {
        return 0.0;
    };
    let f = fit_levels(levels, set, radial_terms, &|o, imgs| {
        Some(imgs[o.view].fold) != hold
    });
    let test: Vec<_> = fine_obs
        .iter()
        .filter(|o| hold.is_none_or(|h| fine_imgs[o.view].fold == h))
        .copied()
        .collect();
    geometry::mse(&test, fine_imgs, &f.params)
}

/// How many radial terms the chosen `set`'s distortion gets when no stereo pairs join its fit:
/// the second (`dk2`) only when it lowers the held-out residual of the one-term fit
/// (`one_term_cv`) by [`SECOND_TERM_MIN`].
fn radial_terms(ctx: &Ctx<'_>, levels: &Levels, set: &[&str], one_term_cv: f64) -> usize {
    if !set.contains(&"distortion") {
        return 1;
    }
    let two = cross_validate(ctx.n_folds, &|hold| held_out_mse(levels, set, 2, hold));
    if two < one_term_cv - SECOND_TERM_MIN {
        2
    } else {
        1
    }
}

/// Smallest held-out reduction of the band-pass residual for which the distortion gets its
/// second radial term when no stereo pairs join the fit. On mini (seeds 101–103, render
/// samples alone) the second term raised the held-out residual by 0.004–0.008, also where a dk2
/// of −0.013 was hidden: over the terrain's part of a NavCam view the render's samples describe
/// the displacement with one term as well as with two, and the two-term fit wanders along
/// their trade-off.
const SECOND_TERM_MIN: f64 = 0.005;

/// Radial displacement (normalised image units) that the distortion increments of `p` make at
/// normalised radius 0.7 — the outer part of a NavCam image, where the terrain is.
fn radial_shift(p: &[f64; 8]) -> f64 {
    crate::sensor::distortion_shift(p[0], p[1])
}

/// Photometric RMS (DN) of the real frame means against the predictions `pa` and `pb`, over
/// the pixels both see terrain, each view's prediction first mapped by its least-squares gain
/// and offset (the photometric effects are fitted after the geometry: a hidden response curve
/// or exposure must not decide whether a geometric correction helps).
fn photometric_rms_pair(ctx: &Ctx<'_>, pa: &[Prediction], pb: &[Prediction]) -> (f64, f64) {
    let (mut sa, mut sb, mut n) = (0.0f64, 0.0f64, 0usize);
    for ((v, x), y) in ctx.views.iter().zip(pa).zip(pb) {
        let real = v.mean();
        let both: Vec<usize> = (0..real.len())
            .filter(|&i| x.mask[i] && y.mask[i])
            .collect();
        sa += affine_sse(&real, &x.dn, &both);
        sb += affine_sse(&real, &y.dn, &both);
        n += both.len();
    }
    let n = n.max(1) as f64;
    ((sa / n).sqrt(), (sb / n).sqrt())
}

/// Residual sum of squares of `real` against `pred` mapped by the least-squares `α·pred + β`,
/// over the pixels `at`.
fn affine_sse(real: &[f32], pred: &[f32], at: &[usize]) -> f64 {
    let n = at.len() as f64;
    if n < 2.0 {
        return 0.0;
    }
    let (mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &i in at {
        let (x, y) = (f64::from(pred[i]), f64::from(real[i]));
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    let vxx = sxx - sx * sx / n;
    let vxy = sxy - sx * sy / n;
    let vyy = syy - sy * sy / n;
    if vxx > 0.0 {
        (vyy - vxy * vxy / vxx).max(0.0)
    } else {
        vyy.max(0.0)
    }
}

/// `base` with the geometric increments `p` of the effects in `set` added.
fn with_geometry(base: &SensorModel, set: &[&str], p: &[f64; 8]) -> SensorModel {
    let mut m = base.clone();
    let (dist, bias) = geometry::effects_of(p);
    if set.contains(&"distortion") {
        let e = match m.effects.iter().find(|e| e.name() == "distortion") {
            Some(Effect::Distortion { dk1, dk2 }) => Effect::Distortion {
                dk1: dk1 + p[0],
                dk2: dk2 + p[1],
            },
            _ => dist,
        };
        upsert(&mut m, e);
    }
    if set.contains(&"pose-bias") {
        // Increments compose after the existing bias (the render already used it).
        m.effects.push(bias);
        let composed = m.pose(&Placement::lone(Pose::IDENTITY));
        m.effects.retain(|e| e.name() != "pose-bias");
        let r = composed.rotation_matrix();
        // R = Rz Ry Rx: recover the angles.
        let ry = (-r[2][0]).asin();
        let rx = r[2][1].atan2(r[2][2]);
        let rz = r[1][0].atan2(r[0][0]);
        m.effects.push(Effect::PoseBias {
            translation_m: composed.translation_m,
            rotation_deg: [rx.to_degrees(), ry.to_degrees(), rz.to_degrees()],
        });
    }
    m
}

/// Smallest held-out MSE reduction (DN², on the low-passed images of [`photometry`]) for which
/// a photometric effect is named: a 5 DN RMS change of the image. Renders of a laser DEM are
/// systematically a little darker and flatter than the real images (laser range noise roughens
/// the normals; the reflectance keeps a small range bias), which a response curve or exposure
/// reduces by up to 17 DN² on mini campaigns with nothing hidden (seeds 11, 12, 21).
const MIN_PHOTOMETRIC_DN2: f64 = 25.0;

/// The same floor for `vignetting`. The no-effect bias above is a level and contrast change,
/// which a radial falloff cannot mimic: with nothing hidden, vignetting alone or next to an
/// exposure change never lowered the held-out error (mini seeds 101/102), while a hidden
/// strength of 0.125–0.16 lowered it by 4–17 DN² — under the general floor. (On the estec
/// `laser/0.015` entry with nothing hidden it did lower it, by 5.4 DN², with a final strength
/// indistinguishable from zero: [`SIGNIFICANCE`] keeps such a choice from being named.)
const MIN_VIGNETTING_DN2: f64 = 3.0;

/// Held-out share of the stereo overlap pairs' squared log ratio ([`overlap`]) a vignetting
/// must remove for its render-side floor ([`MIN_VIGNETTING_DN2`]) to be waived (the share of
/// the error without it, `min_share`, still applies, as do [`SIGNIFICANCE`] and
/// [`VIGNETTING_MIN_STRENGTH`]). The pairs do not see the entry's radiance errors: on mini
/// seeds 101–107 with no vignetting hidden (nothing, gamma, exposure, blur) they read −0.00 to
/// 0.23; with one hidden (alone or next to a gamma) 0.35 to 0.97, the 0.35 and 0.45 from the
/// weakest strength drawn, 0.12 (seed 105), whose render-side drop next to a gamma of 2.23 was
/// 2.6 DN², under the floor.
const MIN_OVERLAP_WITNESS: f64 = 0.3;

/// Standard errors by which a photometric effect's fitted parameters must differ from their
/// neutral values for it to be named. With nothing hidden, the full-resolution estec
/// `laser/0.015` entry chose `vignetting` (5.4 DN² held out, over its 3 DN² floor) whose final
/// strength, next to the free gain, was 0.0007 ± 0.0083.
const SIGNIFICANCE: f64 = 2.0;

/// Smallest vignetting strength named: half the catalogue's lower bound (0.1, the falloff a
/// camera visibly has). A smaller fitted falloff is within a laser render's own radial level
/// error, however significant: estec seed 2 with a hidden distortion and no vignetting named
/// 0.031 ± 0.012 (7.8 DN² held out). The hidden strengths drawn on mini so far (0.17–0.23) came
/// out at 0.149 and above (six captures, seed 103: 0.149 for 0.173).
const VIGNETTING_MIN_STRENGTH: f64 = 0.05;

/// Smallest departure from a linear response the noise witness names, and the largest it
/// calls linear (γ within 1 ± this). Mini seeds 101–112: nothing hidden read 0.989–1.009,
/// exposures with their black level in the background 0.997–1.001, curves set to 1.06 read
/// 1.054–1.068.
const MIN_CURVE: f64 = 0.05;

/// The photon-transfer witness of a run: the fit over every view, and each view's dark
/// background (the render's no-terrain pixels, eroded) for the fits of one capture.
struct NoiseWitness {
    fit: Option<response::ResponseFit>,
    backgrounds: Vec<Vec<bool>>,
}

impl NoiseWitness {
    /// The witness of the views under the renders `preds`.
    fn new(ctx: &Ctx<'_>, preds: &[Prediction]) -> NoiseWitness {
        let backgrounds: Vec<Vec<bool>> = ctx
            .views
            .iter()
            .zip(preds)
            .map(|(v, p)| {
                let empty: Vec<bool> = p.mask.iter().map(|m| !m).collect();
                photometry::erode(&empty, v.width, v.height, photometry::ERODE)
            })
            .collect();
        NoiseWitness {
            fit: response_witness(ctx, &backgrounds, None),
            backgrounds,
        }
    }
}

/// The response curve the repeat frames' noise shows ([`response`]) over every view with two
/// frames and its dark `backgrounds`, or over those of fold `only`.
fn response_witness<B: AsRef<[bool]>>(
    ctx: &Ctx<'_>,
    backgrounds: &[B],
    only: Option<usize>,
) -> Option<response::ResponseFit> {
    let views: Vec<response::ResponseView<'_>> = ctx
        .views
        .iter()
        .zip(backgrounds)
        .zip(&ctx.folds)
        .filter(|(_, f)| only.is_none_or(|k| **f == k))
        .filter_map(|((v, b), &fold)| match v.frames.as_slice() {
            [x, y, ..] => Some(response::ResponseView {
                frames: [x.as_slice(), y.as_slice()],
                background: b.as_ref(),
                fold: if only.is_some() { 0 } else { fold },
            }),
            _ => None,
        })
        .collect();
    response::measure(&views, if only.is_some() { 1 } else { ctx.n_folds })
}

/// Frees the exposure gain in a final fit of `set` unless an exposure or a response curve is
/// in it. The gain is a nuisance of every final fit: the entry's albedo and shading are never
/// exactly at the camera's level, and an effect fitted without a free gain absorbs that level
/// (a darkening effect comes out too weak under a render that is too dark). Exposure is
/// written into the model only when it was chosen. Not with a response curve: over the narrow
/// intensity range of a terrain, gain and gamma trade off (a free gain moved a fitted gamma of
/// 2.0 to 2.3-2.4), while the level bias alone moves it by only ~0.05.
fn with_level_nuisance(set: &mut Vec<&str>) {
    if !set.contains(&"exposure") && !set.contains(&"gamma") {
        set.push("gain");
    }
}

/// The overlap pairs' witness for a vignetting: the held-out share (over capture folds) of
/// their squared log ratio that adding a vignetting removes, next to the other effects of the
/// best-scoring candidate with a vignetting and the `present` ones. `None` with fewer than two
/// folds, [`photometry::MIN_PAIRS`] pairs or no such candidate.
fn overlap_witness(
    n_folds: usize,
    cands: &[Candidate],
    present: &[&'static str],
    plain: &photometry::Samples,
    pairs: &[overlap::Pair],
) -> Option<f64> {
    if n_folds < 2 || pairs.len() < photometry::MIN_PAIRS {
        return None;
    }
    let best = cands
        .iter()
        .filter(|c| c.effects.contains(&"vignetting"))
        .min_by(|a, b| a.cv_error.total_cmp(&b.cv_error))?;
    let mut without: Vec<&str> = best.effects.to_vec();
    without.retain(|e| *e != "vignetting");
    without.extend(present);
    let mut with = without.clone();
    with.push("vignetting");
    with_level_nuisance(&mut without);
    let by_radiance = with.contains(&"exposure");
    let (mut err_with, mut err_without) = (0.0, 0.0);
    for hold in 0..n_folds {
        let train = |f: usize| f != hold;
        let test = |f: usize| f == hold;
        let a = photometry::refit_with_overlap(plain, pairs, &with, &train, by_radiance);
        let b = photometry::refit_with_overlap(plain, pairs, &without, &train, by_radiance);
        err_with += photometry::pair_mse(pairs, &a.params, &test);
        err_without += photometry::pair_mse(pairs, &b.params, &test);
    }
    (err_without > 0.0).then(|| 1.0 - err_with / err_without)
}

/// Stage 2: photometry (+ shadows). Updates `model`.
fn photometry_stage(
    ctx: &Ctx<'_>,
    model: &mut SensorModel,
    min_share: f64,
    transfer: &NoiseWitness,
    out: &mut Vec<Named>,
) -> Vec<ScoredCandidate> {
    let psf = model
        .effects
        .iter()
        .find_map(|e| match e {
            Effect::Blur { sigma_px } => Some(*sigma_px),
            _ => None,
        })
        .unwrap_or(0.0);
    let preds = ctx.predict_all(model);
    let analyses: Vec<photometry::Analysis> = ctx
        .views
        .iter()
        .zip(&preds)
        .map(|(v, p)| photometry::Analysis::new(v, p))
        .collect();
    let mut plain = photometry::Samples::default();
    for (((v, p), a), f) in ctx.views.iter().zip(&preds).zip(&analyses).zip(&ctx.folds) {
        plain.add(*f, v, p, a, psf);
    }
    let poses: Vec<_> = ctx.views.iter().map(|v| model.pose(&v.at)).collect();
    let pairs = overlap::pairs(&ctx.views, &preds, &analyses, &ctx.folds, &poses);
    // The response curve the noise shows ([`response`]) decides the curve when it can: then
    // `gamma` is no candidate of the render-side choice, which is made with the curve fixed.
    let noise_curve = transfer.fit.clone();
    let shows = noise_curve
        .as_ref()
        .and_then(|w| w.shows_curve(MIN_CURVE, SIGNIFICANCE));
    let linear = plain.clone();
    if shows == Some(true) {
        plain.curve = noise_curve.as_ref().map(|w| w.gamma);
    }
    // The black level it measured with the curve it decided (an undecided curve leaves the
    // linear level uncertain too).
    plain.black = noise_curve
        .as_ref()
        .filter(|_| shows.is_some())
        .map(|w| w.black_dn / 255.0);
    let decided = |n: &&str| *n != "gamma" || shows.is_none();
    let absent: Vec<&'static str> = ["exposure", "vignetting", "gamma"]
        .into_iter()
        .filter(|n| !has(model, n) && decided(n))
        .collect();
    let present: Vec<&'static str> = ["exposure", "vignetting", "gamma"]
        .into_iter()
        .filter(|n| has(model, n) && (*n != "gamma" || shows != Some(true)))
        .collect();
    let cv_of = |s: &photometry::Samples, set: &[&str]| {
        cross_validate(ctx.n_folds, &|hold| {
            let f = photometry::fit(s, set, &|fold| Some(fold) != hold);
            photometry::mse(s, &f.params, &|fold| hold.is_none_or(|h| fold == h))
        })
    };
    let cands: Vec<Candidate> = subsets(&absent)
        .into_iter()
        .map(|set| {
            let mut all = set.clone();
            all.extend(&present);
            Candidate {
                cv_error: cv_of(&plain, &all),
                k: plain.free(&set).len(),
                effects: set,
            }
        })
        .collect();
    let witness = overlap_witness(ctx.n_folds, &cands, &present, &plain, &pairs);
    let witnessed = witness.is_some_and(|w| w >= MIN_OVERLAP_WITNESS);
    let floor = |e: &str| match e {
        "vignetting" if witnessed => 0.0,
        "vignetting" => MIN_VIGNETTING_DN2,
        _ => MIN_PHOTOMETRIC_DN2,
    };
    // An exposure's gain and offset come from the radiance-side fit (see
    // `photometry::fit_radiance`: fitted on DN they are attenuated, 0.66/0.73/0.60 for
    // 0.76/0.93/0.76 on mini seeds 101-103, 0.73/0.92/0.69 on radiance; and the DN fit's
    // offset compensates the attenuation, lifting the black level 9-20 DN with nothing hidden).
    // Without an exposure the DN fit is kept: there the attenuation has no free gain to go to,
    // and on radiance a hidden vignetting of 0.2 under a gamma of 1.6 came out 0.12.
    // A vignetting's strength also rests on the overlap of the views (see `overlap`).
    let fit_final = |set: &[&str], use_fold: &(dyn Fn(usize) -> bool + Sync)| {
        let by_radiance = set.contains(&"exposure");
        photometry::refit_with_overlap(&plain, &pairs, set, use_fold, by_radiance)
    };
    let black_limit = plain.black_limit();
    // A chosen exposure whose fitted black level the background does not allow is a response
    // curve (or another effect) in disguise: the sets with an exposure are then out.
    let mut allowed = cands.clone();
    let mut rejected_black = None;
    // With the curve the noise shows, every candidate holds it: reported as such, next to the
    // linear camera with no effect.
    let linear_err = (shows == Some(true)).then(|| cv_of(&linear, &[]));
    let report = |cands: &[Candidate]| {
        let mut out = scored(cands);
        if let Some(err) = linear_err {
            for c in &mut out {
                c.effects.push("gamma".into());
            }
            out.insert(
                0,
                ScoredCandidate {
                    effects: Vec::new(),
                    k: 0,
                    cv_error: err,
                },
            );
        }
        out
    };
    // The curve the noise shows: named with the render's held-out error with and without it.
    if let (Some(true), Some(w), Some(without)) = (shows, &noise_curve, linear_err) {
        let e = Effect::Gamma { gamma: w.gamma };
        let was_absent = !has(model, "gamma");
        upsert(model, e);
        if was_absent {
            let with = cands
                .iter()
                .find(|c| c.effects.is_empty())
                .map_or(without, |c| c.cv_error);
            let mut n = named(
                &e,
                BTreeMap::from([("gamma".to_string(), w.gamma_se)]),
                (without - with) / without.max(1e-12),
                "photometry",
                format!(
                    "the repeat frames' noise: a response curve of {:.3} ± {:.3} (photon transfer over {} levels with the dark background's {} values; shot gain {:.4}, read noise {:.2} DN, black level {:.1} DN); held-out photometric MSE {:.1} DN² linear, {:.1} DN² with it",
                    w.gamma,
                    w.gamma_se,
                    w.levels.len(),
                    w.background_px,
                    w.shot_gain,
                    w.read_sigma,
                    w.black_dn,
                    without,
                    with
                ),
            );
            n.per_capture = ctx
                .fold_names()
                .iter()
                .enumerate()
                .filter(|_| ctx.n_folds >= 2)
                .filter_map(|(k, c)| {
                    let g = response_witness(ctx, &transfer.backgrounds, Some(k))?.gamma;
                    Some(CaptureParams::new(c, &Effect::Gamma { gamma: g }))
                })
                .collect();
            out.push(n);
        }
    }
    let (choice, chosen, fit_set, f) = loop {
        let Some(choice) = choose_with(&allowed, min_share, &floor) else {
            return report(&cands);
        };
        let chosen = allowed[choice.index].effects.clone();
        let mut fit_set: Vec<&str> = chosen.clone();
        fit_set.extend(&present);
        with_level_nuisance(&mut fit_set);
        let f = fit_final(&fit_set, &|_| true);
        let lifted = black_limit.is_some_and(|l| photometry::black_level(&f.params) > l);
        if chosen.contains(&"exposure") && lifted {
            rejected_black = Some(photometry::black_level(&f.params));
            allowed.retain(|c| !c.effects.contains(&"exposure"));
            continue;
        }
        break (choice, chosen, fit_set, f);
    };
    let p = f.params;
    let jack = jackknife(ctx.n_folds, &|hold| {
        fit_final(&fit_set, &|fold| fold != hold).params.to_vec()
    });
    let mut std_err = honest_std_err(f.std_err, jack);
    if let (Some(_), Some(w)) = (plain.black, &noise_curve) {
        std_err[1] = w.black_se / 255.0;
    }
    // The effect `name` at full parameters `q`, and the indices of its parameters.
    let effect_at = |name: &str, q: &[f64; 4]| -> Option<(Effect, &'static [usize])> {
        Some(match name {
            "exposure" => (
                Effect::Exposure {
                    gain: q[0],
                    offset: q[1],
                },
                &[0, 1],
            ),
            "vignetting" => (Effect::Vignetting { strength: q[2] }, &[2]),
            "gamma" => (Effect::Gamma { gamma: q[3] }, &[3]),
            _ => return None,
        })
    };
    let built = |name: &str| -> Option<(Effect, BTreeMap<String, f64>)> {
        let (e, idx) = effect_at(name, &p)?;
        let names = photometry::PARAMS;
        Some((
            e,
            idx.iter()
                .map(|&i| (names[i].to_string(), std_err[i]))
                .collect(),
        ))
    };
    let fold_names = ctx.fold_names();
    let per_fold: Vec<[f64; 4]> = if ctx.n_folds >= 2 {
        (0..ctx.n_folds)
            .map(|k| fit_final(&fit_set, &|fold| fold == k).params)
            .collect()
    } else {
        Vec::new()
    };
    // A chosen effect whose every parameter is within SIGNIFICANCE standard errors of its
    // neutral value is not named: its held-out gain came from a level difference the final
    // fit's free gain absorbs, not from the effect. Nor is a vignetting weaker than any a
    // camera visibly has (VIGNETTING_MIN_STRENGTH).
    let significant = |name: &str| -> bool {
        let idx: &[usize] = match name {
            "exposure" => &[0, 1],
            "vignetting" => &[2],
            "gamma" => &[3],
            _ => &[],
        };
        let plausible = name != "vignetting" || p[2].abs() >= VIGNETTING_MIN_STRENGTH;
        plausible
            && idx.iter().any(|&i| {
                (p[i] - photometry::NEUTRAL[i]).abs() > SIGNIFICANCE * std_err[i].max(f64::EPSILON)
            })
    };
    for name in chosen.iter().filter(|n| significant(n)).chain(&present) {
        if let Some((e, _)) = built(name) {
            upsert(model, e);
        }
    }
    let base_err = cands
        .iter()
        .find(|c| c.effects.is_empty())
        .map_or(0.0, |c| c.cv_error);
    for (name, share) in choice.explained.iter().filter(|(n, _)| significant(n)) {
        if let Some((e, errs)) = built(name) {
            let mut n = named(
                &e,
                errs,
                *share,
                "photometry",
                format!(
                    "held-out photometric MSE {:.1} DN² with no effect, {:.1} DN² with the chosen set{}",
                    base_err,
                    allowed[choice.index].cv_error,
                    match (witness, black_limit, rejected_black) {
                        (Some(w), _, _) if *name == "vignetting" => format!(
                            "; a vignetting removes {:.0} % of the stereo overlap's held-out log ratio",
                            100.0 * w
                        ),
                        (_, Some(l), _) if *name == "exposure" => format!(
                            "; black level {:.1} DN, the background allows {:.1}",
                            photometry::black_level(&p),
                            l
                        ),
                        (_, Some(l), Some(b)) if *name == "gamma" => format!(
                            "; an exposure fitted instead put the black level at {b:.1} DN, the background allows {l:.1}"
                        ),
                        _ => String::new(),
                    }
                ),
            );
            n.per_capture = fold_names
                .iter()
                .zip(&per_fold)
                .filter_map(|(c, q)| Some(CaptureParams::new(c, &effect_at(name, q)?.0)))
                .collect();
            out.push(n);
        }
    }
    report(&cands)
}

/// Smallest PSF σ named as `blur`, px (the catalogue's lower bound: below it the edge widths
/// of anti-aliasing and geometry dominate).
const BLUR_MIN_PX: f64 = 0.3;

/// Blur, measured on the skyline ([`blur`]). Updates `model`.
fn blur_stage(ctx: &Ctx<'_>, model: &mut SensorModel, min_share: f64, out: &mut Vec<Named>) {
    if has(model, "blur") {
        return;
    }
    let preds = ctx.predict_sampled(model, 1);
    let means: Vec<Vec<f32>> = ctx.views.iter().map(GapView::mean).collect();
    let views: Vec<ImagePair<'_>> = ctx
        .views
        .iter()
        .zip(&preds)
        .zip(&means)
        .map(|((v, p), m)| ImagePair {
            real: m,
            render: &p.dn,
            mask: &p.mask,
            w: v.width,
            h: v.height,
        })
        .collect();
    let Some(m) = blur::measure(&views) else {
        return;
    };
    let share = if m.real_var > 0.0 {
        (m.sigma_px.powi(2) / m.real_var).min(1.0)
    } else {
        0.0
    };
    if m.sigma_px < BLUR_MIN_PX || share < min_share {
        return;
    }
    // The captures' spread (each left out in turn) and the estimator's calibration in
    // quadrature.
    let jack = jackknife(ctx.n_folds, &|hold| {
        let kept: Vec<ImagePair<'_>> = views
            .iter()
            .zip(&ctx.folds)
            .filter(|(_, &f)| f != hold)
            .map(|(v, _)| *v)
            .collect();
        vec![blur::measure(&kept).map_or(m.sigma_px, |k| k.sigma_px)]
    });
    let spread = jack.map_or(0.0, |j| j[0]);
    let std_err = BTreeMap::from([("sigma_px".to_string(), spread.hypot(blur::CALIBRATION_PX))]);
    let e = Effect::Blur {
        sigma_px: m.sigma_px,
    };
    upsert(model, e);
    out.push(named(
        &e,
        std_err,
        share,
        "blur",
        format!(
            "skyline edges ({} profiles): variance {:.3} px² real vs {:.3} px² rendered",
            m.profiles, m.real_var, m.render_var
        ),
    ));
}

/// The views of a shadow test: the real frame means against `lit` and `shadowed` predictions.
fn shadow_views<'a>(
    ctx: &Ctx<'_>,
    means: &'a [Vec<f32>],
    lit: &'a [Prediction],
    shadowed: &'a [Prediction],
) -> Vec<shadows::ShadowView<'a>> {
    ctx.views
        .iter()
        .enumerate()
        .map(|(i, v)| shadows::ShadowView {
            real: &means[i],
            lit: &lit[i].dn,
            shadowed: &shadowed[i].dn,
            mask: &lit[i].mask,
            w: v.width,
            h: v.height,
            fold: ctx.folds[i],
        })
        .collect()
}

/// Cast shadows of the campaign light ([`shadows`]). Updates `model`.
fn shadows_stage(ctx: &Ctx<'_>, model: &mut SensorModel, out: &mut Vec<Named>) {
    if has(model, "shadows") {
        return;
    }
    let with = |d: (f64, f64)| {
        let mut m = model.clone();
        upsert(
            &mut m,
            Effect::Shadows {
                azimuth_deg: d.0,
                elevation_deg: d.1,
            },
        );
        m
    };
    // The model's render under a light from `d`, without cast shadows.
    let lit_at = |d: (f64, f64)| -> Vec<Prediction> {
        let light = Light {
            azimuth_deg: d.0,
            elevation_deg: d.1,
            ..ctx.light
        };
        ctx.views
            .iter()
            .map(|v| predict(&ctx.scene, &light, v, model, 1))
            .collect()
    };
    let means: Vec<Vec<f32>> = ctx.views.iter().map(GapView::mean).collect();
    let record = (ctx.light.azimuth_deg, ctx.light.elevation_deg);
    let lit = ctx.predict_sampled(model, 1);
    let shadowed = ctx.predict_sampled(&with(record), 1);
    // A light that casts no shadow the views would see has nothing to test or refine.
    if shadows::evidence(&shadow_views(ctx, &means, &lit, &shadowed)).pixels
        < shadows::MIN_SHADOW_PIXELS
    {
        return;
    }
    // The direction first: the campaign records its light as surveyed, a few degrees off, and
    // shadows tested where a wrong light casts them are half missed.
    let near = shadows::near_shadows(&shadow_views(ctx, &means, &lit, &shadowed));
    // The direction scored on the views `keep` selects, searched from the record.
    let search = |keep: &dyn Fn(usize) -> bool| {
        let idx: Vec<usize> = (0..ctx.views.len()).filter(|&i| keep(i)).collect();
        let near: Vec<&[bool]> = idx.iter().map(|&i| near[i].as_slice()).collect();
        shadows::refine_direction(record, |d| {
            let m = with(d);
            let preds: Vec<Prediction> = idx
                .iter()
                .map(|&i| predict(&ctx.scene, &ctx.light, &ctx.views[i], &m, 1))
                .collect();
            let v: Vec<shadows::ShadowView<'_>> = idx
                .iter()
                .zip(&preds)
                .map(|(&i, p)| shadows::ShadowView {
                    real: &means[i],
                    lit: &lit[i].dn,
                    shadowed: &p.dn,
                    mask: &lit[i].mask,
                    w: ctx.views[i].width,
                    h: ctx.views[i].height,
                    fold: ctx.folds[i],
                })
                .collect();
            shadows::direction_score(&v, &near)
        })
    };
    let (mut direction, _) = search(&|_| true);
    // A light fixed in the lab casts the same shadows in every capture: the refined direction
    // replaces the record only if it is better in each capture fold, not just overall (on mini
    // seed 103, 513 shadow pixels, the overall optimum was 3.5° off the true light).
    let fold_score = |preds: &[Prediction], fold: usize| {
        let (v, n): (Vec<_>, Vec<&[bool]>) = shadow_views(ctx, &means, &lit, preds)
            .into_iter()
            .zip(near.iter().map(Vec::as_slice))
            .filter(|(v, _)| v.fold == fold)
            .unzip();
        shadows::direction_score(&v, &n)
    };
    let mut refined = (direction != record).then(|| ctx.predict_sampled(&with(direction), 1));
    if let Some(r) = &refined {
        if !(0..ctx.n_folds).all(|f| fold_score(r, f) < fold_score(&shadowed, f)) {
            direction = record;
            refined = None;
        }
    }
    let moved = refined.map(|r| (lit_at(direction), r));
    let (lit_at_light, shadowed_at_light) =
        moved.as_ref().map_or((&lit, &shadowed), |m| (&m.0, &m.1));
    let ev = shadows::evidence(&shadow_views(ctx, &means, lit_at_light, shadowed_at_light));
    if !ev.convincing() {
        return;
    }
    // The direction's standard errors: the jackknife over captures (each searched alone when
    // the others are left out) and the search's calibration on the entry, in quadrature.
    let jack = jackknife(ctx.n_folds, &|hold| {
        let (d, _) = search(&|i| ctx.folds[i] != hold);
        vec![d.0, d.1]
    });
    let calibration = [
        shadows::CALIBRATION_AZIMUTH_DEG,
        shadows::CALIBRATION_ELEVATION_DEG,
    ];
    let std_err: BTreeMap<String, f64> = ["azimuth_deg", "elevation_deg"]
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let j = jack.as_ref().map_or(0.0, |j| j[k]);
            (name.to_string(), j.hypot(calibration[k]))
        })
        .collect();
    let e = Effect::Shadows {
        azimuth_deg: direction.0.rem_euclid(360.0),
        elevation_deg: direction.1,
    };
    upsert(model, e);
    out.push(named(
        &e,
        std_err,
        ev.explained,
        "shadows",
        format!(
            "{} shadow pixels of the campaign light ({:.1}°/{:.1}°, recorded {:.1}°/{:.1}°): MSE {:.0} DN² lit vs {:.0} DN² shadowed",
            ev.pixels,
            direction.0.rem_euclid(360.0),
            direction.1,
            record.0,
            record.1,
            ev.mse_lit,
            ev.mse_shadowed
        ),
    ));
}

/// What [`texture`] reads of every view under one model: the render with a uniform albedo
/// (the shading the real image is divided by) and the real frame mean, both on radiance.
struct TextureInputs {
    flat: Vec<Prediction>,
    real: Vec<Vec<f32>>,
    flat_radiance: Vec<Vec<f32>>,
    poses: Vec<Pose>,
}

impl TextureInputs {
    fn new(ctx: &Ctx<'_>, grid: &HeightGrid, albedo: &AlbedoGrid, model: &SensorModel) -> Self {
        let mean = albedo.value.iter().map(|&v| f64::from(v)).sum::<f64>()
            / albedo.value.len().max(1) as f64;
        let mut uniform = albedo.clone();
        uniform.value.fill(mean as f32);
        let flat_geometry = Geometry::Heightfield {
            grid: grid.clone(),
            albedo: uniform,
        };
        let flat_scene = Scene::new(&flat_geometry);
        let flat: Vec<Prediction> = ctx
            .views
            .iter()
            .map(|v| predict(&flat_scene, &ctx.light, v, model, 1))
            .collect();
        // Ratios are taken on radiance: the response curve and black level undone (a curve
        // left in bends the ratios and read mini seed 102's faithful texture 1.4 mm blurrier).
        let linear = |dn: &[f32]| crate::sensor::image::undo_response(&model.effects, dn);
        TextureInputs {
            real: ctx.views.iter().map(|v| linear(&v.mean())).collect(),
            flat_radiance: flat.iter().map(|p| linear(&p.dn)).collect(),
            poses: ctx.views.iter().map(|v| model.pose(&v.at)).collect(),
            flat,
        }
    }

    fn views(&self, ctx: &Ctx<'_>) -> Vec<texture::TextureView<'_>> {
        ctx.views
            .iter()
            .enumerate()
            .map(|(i, v)| texture::TextureView {
                real: &self.real[i],
                flat: &self.flat_radiance[i],
                mask: &self.flat[i].mask,
                depth: &self.flat[i].depth,
                camera: &self.flat[i].camera,
                ground_from_camera: &self.poses[i],
                w: v.width,
                h: v.height,
                fold: ctx.folds[i],
            })
            .collect()
    }
}

/// `texture-lowpass` from the texture's effective blur ([`texture`]); heightfield entries only.
/// Updates `model` and returns the figures.
fn texture_stage(
    ctx: &Ctx<'_>,
    model: &mut SensorModel,
    out: &mut Vec<Named>,
) -> Option<TextureFigures> {
    let Geometry::Heightfield { grid, albedo } = ctx.geometry else {
        return None;
    };
    let inputs = TextureInputs::new(ctx, grid, albedo, model);
    let views = inputs.views(ctx);
    let m = texture::TextureMeasure::new(&views, albedo)?;
    let (blur, correlation) = m.blur_m(&|_| true)?;
    let cell = albedo.cell_m;
    let excess = texture::excess_m(blur, cell);
    let figures = TextureFigures {
        effective_blur_m: blur,
        own_blur_m: texture::own_blur_m(cell),
        excess_m: excess,
        correlation,
        cell_m: cell,
    };
    // Per capture the blur is rough (one capture of a faithful texture read 9.0 mm, the other
    // 13.4 mm, on mini seed 101), so the pooled figure decides; the per-capture ones are shown.
    let per_fold: Vec<String> = m
        .folds()
        .iter()
        .filter_map(|&f| m.blur_m(&|g| g == f))
        .map(|(b, _)| format!("{:.1}", b * 1e3))
        .collect();
    if excess < texture::MIN_EXCESS_M || has(model, "texture-lowpass") {
        return Some(figures);
    }
    let folds = m.folds();
    let jack = jackknife(folds.len(), &|hold| {
        let f = folds[hold];
        vec![m
            .blur_m(&|g| g != f)
            .map_or(excess, |(b, _)| texture::excess_m(b, cell))]
    });
    let e = Effect::TextureLowpass { sigma_m: excess };
    upsert(model, e);
    // The captures' spread and the calibration's (texture::EXCESS_PER_SIGMA) in quadrature.
    let calibration = texture::EXCESS_SPREAD * excess;
    let spread = jack.map_or(0.0, |j| j[0]);
    let mut std_err = BTreeMap::new();
    std_err.insert("sigma_m".to_string(), spread.hypot(calibration));
    out.push(named(
        &e,
        std_err,
        1.0 - (figures.own_blur_m / blur).powi(2),
        "texture",
        format!(
            "the entry's texture matches the real albedo blurred by {:.1} mm (per capture {} mm; band-pass correlation {:.2}); a faithful texture of {:.3} m cells shows {:.1} mm",
            blur * 1e3,
            per_fold.join(", "),
            correlation,
            cell,
            figures.own_blur_m * 1e3
        ),
    ));
    Some(figures)
}

/// Stage 3: noise from the repeat frames. Updates `model`.
fn noise_stage(
    ctx: &Ctx<'_>,
    preds: &[Prediction],
    model: &mut SensorModel,
    witness: &NoiseWitness,
    out: &mut Vec<Named>,
) {
    if has(model, "noise") {
        return;
    }
    let pairs: Vec<(&[f32], &[f32], &[bool])> = ctx
        .views
        .iter()
        .zip(preds)
        .filter(|(v, _)| v.frames.len() >= 2)
        .map(|(v, p)| {
            (
                v.frames[0].as_slice(),
                v.frames[1].as_slice(),
                p.mask.as_slice(),
            )
        })
        .collect();
    let Some(fit) = noise::measure(&pairs) else {
        return;
    };
    // The sensor's noise is on the linear signal, before the response curve: the photon
    // transfer fit over the dark background ([`response`]) has it there; the level fit of
    // `noise::measure` only without a curve.
    let linear = &witness.fit;
    let sigma_at_128 = linear
        .as_ref()
        .map_or(fit.sigma_at_128, |w| w.sigma_at(128.0));
    if sigma_at_128 <= noise::NOISE_FLOOR_DN {
        return;
    }
    let e = linear.as_ref().map_or(
        Effect::Noise {
            gain: fit.gain,
            read_sigma: fit.read_sigma,
        },
        |w| Effect::Noise {
            gain: w.shot_gain,
            read_sigma: w.read_sigma,
        },
    );
    upsert(model, e);
    let share = 1.0 - (noise::NOISE_FLOOR_DN / sigma_at_128).powi(2);
    out.push(named(
        &e,
        BTreeMap::new(),
        share,
        "noise",
        format!(
            "repeat frames: noise σ {:.2} DN at DN 128 > nominal {:.1} DN{}",
            sigma_at_128,
            noise::NOISE_FLOOR_DN,
            if linear.is_some() {
                " (photon transfer with the dark background: shot and read noise of the linear signal)"
            } else {
                ""
            }
        ),
    ));
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
    Ok(ctx.measure(&ctx.predict_all(model), model, &shadow))
}

/// Runs the gap workflow on `entry` (see the module docs).
pub fn run(view: &ReleaseView, entry: &str, opts: &GapOptions) -> Result<GapResult, ReaderError> {
    run_on(view, &entry_geometry(view, entry)?, entry, opts)
}

/// Runs the gap workflow with the terrain given as `geometry` instead of `entry`'s own, `entry`
/// still naming the stored sensor model to start from and the result. With a synthetic
/// campaign's true terrain (the corpus' heights and albedo) this separates what the workflow
/// recovers from what the entry costs: on mini the geometric stage then recovers a pose bias
/// within 0.03° and 0.3 mm per axis and a distortion's `dk1` within 3 %, where the laser entry
/// leaves up to 0.5° along the pitch/height valley and 16 % (see the module docs).
pub fn run_on(
    view: &ReleaseView,
    geometry: &Geometry,
    entry: &str,
    opts: &GapOptions,
) -> Result<GapResult, ReaderError> {
    let ctx = Ctx::load(view, geometry, opts)?;
    let model_before = stored_model(view, entry)?;
    let preds_before = ctx.predict_all(&model_before);
    // Where the campaign light casts shadows, seen through the stored geometry: the same
    // pixels before and after, so the two shadow figures compare like with like.
    let shadow = ctx.shadow_pixels(&model_before);
    let metrics_before = ctx.measure(&preds_before, &model_before, &shadow);
    let witness = NoiseWitness::new(&ctx, &preds_before);
    let mut model = model_before.clone();
    let mut found = Vec::new();
    let mut candidates = BTreeMap::new();
    candidates.insert(
        "geometry".to_string(),
        geometry_stage(&ctx, &mut model, opts.min_share, &mut found),
    );
    blur_stage(&ctx, &mut model, opts.min_share, &mut found);
    candidates.insert(
        "photometry".to_string(),
        photometry_stage(&ctx, &mut model, opts.min_share, &witness, &mut found),
    );
    shadows_stage(&ctx, &mut model, &mut found);
    let texture = texture_stage(&ctx, &mut model, &mut found);
    noise_stage(&ctx, &preds_before, &mut model, &witness, &mut found);
    let preds_after = ctx.predict_all(&model);
    let metrics_after = ctx.measure(&preds_after, &model, &shadow);
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
    let headline = Figure::headline(&found.iter().map(|n| n.effect.as_str()).collect::<Vec<_>>());
    Ok(GapResult {
        images,
        release_id: view.id.to_hex(),
        entry: entry.to_string(),
        gap_metric: headline,
        gap_before: headline.of(&metrics_before),
        gap_after: headline.of(&metrics_after),
        named: found,
        metrics_before,
        metrics_after,
        model_before,
        model_after: model,
        candidates,
        texture,
        response: witness.fit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples and stereo overlap pairs of a camera with a falloff of `strength`, over two
    /// capture folds; the entry's radiance is ±20 % off (texture), which the pairs do not see.
    fn falloff_campaign(strength: f64) -> (photometry::Samples, Vec<overlap::Pair>) {
        let truth = [1.0, 0.0, strength, 1.0];
        let dn = |rad: f64, rho2: f64| photometry::predict_dn(rad, rho2, &truth);
        let mut s = photometry::Samples::default();
        let mut pairs = Vec::new();
        for k in 0..2000 {
            let (rho2, other) = ((k % 100) as f64 / 100.0, ((k * 7) % 100) as f64 / 100.0);
            let rad = 0.3 + 0.2 * ((k as f64 * 0.37).sin() + 1.0);
            // A little real-image noise so that nothing fits exactly.
            let noise = 0.01 * (k as f64 * 1.93).sin();
            s.fold.push(k % 2);
            s.real.push(dn(rad, rho2) * (1.0 + noise));
            s.radiance.push(rad * (1.0 + 0.2 * (k as f64 * 2.71).sin()));
            s.rho2.push(rho2);
            pairs.push(overlap::Pair {
                fold: k % 2,
                real: [dn(rad, rho2) * (1.0 + noise), dn(rad, other)],
                rho2: [rho2, other],
            });
        }
        (s, pairs)
    }

    #[test]
    fn the_overlap_witnesses_a_falloff_the_camera_has_and_not_one_it_lacks() {
        let cands = [
            Candidate {
                effects: vec![],
                k: 0,
                cv_error: 30.0,
            },
            Candidate {
                effects: vec!["vignetting"],
                k: 1,
                cv_error: 27.0,
            },
        ];
        let witness = |strength: f64| {
            let (s, pairs) = falloff_campaign(strength);
            overlap_witness(2, &cands, &[], &s, &pairs).unwrap()
        };
        let (with, without) = (witness(0.12), witness(0.0));
        assert!(with >= MIN_OVERLAP_WITNESS, "{with}");
        assert!(without < MIN_OVERLAP_WITNESS, "{without}");
        // Without a vignetting candidate, one fold or too few pairs there is no witness.
        let (s, pairs) = falloff_campaign(0.12);
        assert_eq!(overlap_witness(2, &cands[..1], &[], &s, &pairs), None);
        assert_eq!(overlap_witness(1, &cands, &[], &s, &pairs), None);
        let few = &pairs[..photometry::MIN_PAIRS - 1];
        assert_eq!(overlap_witness(2, &cands, &[], &s, few), None);
    }

    #[test]
    fn affine_sse_ignores_gain_and_offset_and_keeps_the_rest() {
        let pred = [10.0f32, 20.0, 30.0, 40.0, 50.0];
        let real: Vec<f32> = pred.iter().map(|p| 2.0 * p + 3.0).collect();
        let all: Vec<usize> = (0..5).collect();
        assert!(affine_sse(&real, &pred, &all) < 1e-6);
        // A residual orthogonal to (1, pred) stays whole: +1, −2, +2, −2, +1 → 14.
        let bumped: Vec<f32> = real
            .iter()
            .zip([1.0f32, -2.0, 2.0, -2.0, 1.0])
            .map(|(r, d)| r + d)
            .collect();
        assert!((affine_sse(&bumped, &pred, &all) - 14.0).abs() < 1e-3);
        assert_eq!(affine_sse(&real, &pred, &[2]), 0.0);
    }

    #[test]
    fn jackknife_spreads_fold_fits_and_never_lowers_the_formal_error() {
        // Two folds: θ = 1 and 2 → sqrt(1/2 · (0.25 + 0.25)) = 0.5; a constant parameter → 0.
        let j = jackknife(2, &|f| vec![1.0 + f as f64, 7.0]).unwrap_or_default();
        assert!((j[0] - 0.5).abs() < 1e-12 && j[1] == 0.0, "{j:?}");
        // Three folds 0, 0, 3: mean 1, Σ = 6, sqrt(2/3 · 6) = 2.
        let j = jackknife(3, &|f| vec![if f == 2 { 3.0 } else { 0.0 }]).unwrap_or_default();
        assert!((j[0] - 2.0).abs() < 1e-12, "{j:?}");
        assert!(jackknife(1, &|_| vec![1.0]).is_none());
        assert_eq!(honest_std_err([0.1, 0.7], Some(vec![0.5, 0.2])), [0.5, 0.7]);
        assert_eq!(honest_std_err([0.1], None), [0.1]);
    }
}
