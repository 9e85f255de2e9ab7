//! `regolith validate`: re-render a terrain entry at every real capture pose and compare.
//!
//! Per (capture, camera) the entry is rendered from the capture's `ground_from_camera` through
//! the calibrated camera **to the raw (distorted) image**, so real frames are compared as the
//! camera recorded them, without resampling them (the certificate says so). Both images get the
//! same contrast normalisation (linear 1–99 % stretch). Each detector runs on real frame a,
//! real frame b and the render; repeatability real→render and real a→real b (the ceiling: noise
//! alone keeps repeatability below 1) are measured with identity mapping (same pose) in the
//! pixels where the render sees terrain. The certificate is on the ratio sim ÷ ceiling with a
//! 95 % confidence interval over captures, or on absolute repeatability when a campaign has no
//! repeat frames (and says so).
//!
//! The certified repeatability is the thesis's one-directional ratio (real keypoints re-detected
//! in the render ÷ real keypoints) **over chance** ([`Repeatability::excess`]), for the render
//! and for the ceiling alike. Why not the Mikolajczyk score (÷ min(n)): a coarse render has few
//! keypoints and min(n) rewards that (on the estec campaign it ranked a 0.015 m raster and the
//! SfM mesh above the 0.005 m raster); and why over chance: a render full of speckle corners
//! "re-detects" real corners it does not see, by coincidence within ε. The min(n) score and the
//! raw one-directional ratio are still reported.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use rayon::prelude::*;
use regolith_format::kinds::{self, HeightfieldMeta};
use regolith_format::{Entry, ObjectId};
use regolith_reader::captures::{CaptureImage, ImageKind};
use regolith_reader::heightfield::decode_grey_png;
use regolith_reader::{ReaderError, ReleaseView};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use crate::features::{self, contrast, Detector, DetectorParams, GreyF32};
use crate::metrics::compare::{
    compare, detect, Detected, MatchingFigures, RepeatFrame, ViewDetections,
};
use crate::metrics::photometric::{self, Photometric};
use crate::metrics::region_overlap::RegionRepeatability;
use crate::metrics::repeatability::{Repeatability, EPSILONS};
use crate::metrics::spectrum::{log_ratio, radial_spectrum, RadialSpectrum};
use crate::metrics::stats::{mean_ci, Interval};
use crate::render::{AlbedoGrid, Geometry, HeightGrid, Light, RayTables, Sampling, Scene};
use crate::sensor::{stored_model, Placement, SensorModel};

/// Version of the validator recorded in certificates and in sharded units' keys: its minor
/// number changes with the method (0.2: renders take their 2 x 2 samples at edge pixels only;
/// 0.3: SIFT and SURF keypoints are compared by region overlap), so a stored unit of another
/// method is never merged into a certificate of this one.
pub const VALIDATOR_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Pass/fail thresholds (documented defaults; `--thresholds FILE` overrides them).
///
/// The defaults were calibrated with `tools/calibrate/validate_thresholds.py` on the training
/// campaigns only — `mini` campaigns without hidden effects whose captures the validator's own
/// model made and that Mitsuba 3 rendered independently (the seeds are named in
/// docs/validate.md) — each
/// compiled with its laser rasters at 0.01 and 0.02 m, a deliberately coarse 0.05 m raster and
/// the SfM raster at 0.02 m, plus the negative control (laser/0.01 with its texture blurred by
/// σ = 2 cm, `regolith control`). Ratio of the repeatability over chance to the real-vs-real
/// ceiling, range over the eleven seeds (laser/0.01 | the degraded entries | the control):
/// FAST 0.164–0.370 | ≤ 0.212 | ≤ 0.109, Harris 0.094–0.185 | ≤ 0.086 | ≤ 0.062, MSER
/// 0.176–0.404 | ≤ 0.361 | ≤ 0.375, SIFT 0.568–0.925 | ≤ 0.443 | ≤ 0.197, SURF 0.713–0.980 |
/// ≤ 0.697 | ≤ 0.439, mean over detectors 0.389–0.530 | ≤ 0.310 | ≤ 0.186 (per seed and per
/// renderer in docs/validate.md). SIFT's floor and the mean's are the midpoints of the gap
/// between the best raster and every degraded entry; SURF's, where laser/0.02 reaches the best
/// raster on one seed, is the midpoint between the negative control and the best raster. FAST's
/// and Harris's floors, set on the model-made seeds before, lie between the control and the best
/// raster on all eleven. MSER's overlap criterion is lenient with a coarse render's large
/// blobs, so its floor only catches a render that is no better than chance. The held-out test
/// seeds are reported in docs/validate.md and never used here.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Thresholds {
    /// Repeatability tolerance, pixels.
    pub epsilon_px: f64,
    /// Minimum of the mean over detectors of sim ÷ ceiling (repeatability over chance), when
    /// repeat frames exist.
    pub min_mean_ratio_to_ceiling: f64,
    /// Per detector, the minimum of sim ÷ ceiling (mean over views), when repeat frames exist:
    /// a detector that finds too little of the real image in the render fails the entry. In a
    /// thresholds file either one number for every detector or an object naming some detectors
    /// (the others keep their defaults); a detector without a floor is not gated on its own.
    #[serde(deserialize_with = "detector_floors")]
    pub min_ratio_to_ceiling: BTreeMap<String, f64>,
    /// Minimum absolute repeatability over chance per detector when no repeat frames exist.
    pub min_repeatability: f64,
    /// Maximum photometric RMS (grey levels, after contrast normalisation).
    pub max_photometric_rms: f64,
    /// Minimum mean log10 power ratio render ÷ real over the upper half of the spectrum
    /// (0.25–0.5 cycles/px): −0.6 means the render keeps at least a quarter of the real image's
    /// fine-scale power.
    pub min_high_band_log_ratio: f64,
}

/// The default per-detector floors of [`Thresholds::min_ratio_to_ceiling`].
pub fn default_detector_floors() -> BTreeMap<String, f64> {
    [
        (Detector::Harris, 0.085),
        (Detector::Fast, 0.125),
        (Detector::Sift, 0.51),
        (Detector::Surf, 0.58),
        (Detector::Mser, 0.1),
    ]
    .into_iter()
    .map(|(d, v)| (d.name().to_string(), v))
    .collect()
}

/// `min_ratio_to_ceiling` from a thresholds file: a number for every detector, or an object
/// overriding some detectors' defaults (names checked).
fn detector_floors<'de, D: serde::Deserializer<'de>>(
    de: D,
) -> Result<BTreeMap<String, f64>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Floors {
        All(f64),
        Some(BTreeMap<String, f64>),
    }
    let mut floors = default_detector_floors();
    match Floors::deserialize(de)? {
        Floors::All(v) => floors.values_mut().for_each(|f| *f = v),
        Floors::Some(m) => {
            for (name, v) in m {
                name.parse::<Detector>().map_err(serde::de::Error::custom)?;
                floors.insert(name, v);
            }
        }
    }
    Ok(floors)
}

impl Thresholds {
    /// The floor of detector `d`, if it has one.
    pub fn detector_floor(&self, d: Detector) -> Option<f64> {
        self.min_ratio_to_ceiling.get(d.name()).copied()
    }
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            epsilon_px: 1.5,
            min_mean_ratio_to_ceiling: 0.35,
            min_ratio_to_ceiling: default_detector_floors(),
            min_repeatability: 0.1,
            max_photometric_rms: 60.0,
            min_high_band_log_ratio: -0.6,
        }
    }
}

/// What to validate.
#[derive(Debug, Clone)]
pub struct ValidateOptions {
    /// Detectors to run.
    pub detectors: Vec<Detector>,
    /// Thresholds.
    pub thresholds: Thresholds,
}

impl Default for ValidateOptions {
    fn default() -> Self {
        ValidateOptions {
            detectors: Detector::ALL.to_vec(),
            thresholds: Thresholds::default(),
        }
    }
}

/// Figures of one (capture, camera, detector).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewMetrics {
    /// Capture name.
    pub capture: String,
    /// Camera name.
    pub camera: String,
    /// Detector.
    pub detector: Detector,
    /// Keypoints in real frame a and in the render (whole image).
    pub counts: [usize; 2],
    /// Repeatability real→render over the ε curve.
    pub sim: Vec<crate::metrics::repeatability::Repeatability>,
    /// Repeatability real a→real b at the certified ε (the ceiling), if a second frame exists.
    pub ceiling: Option<Repeatability>,
    /// MSER, SIFT and SURF: region repeatability by ellipse overlap error (a SIFT or SURF
    /// keypoint's region is the circle of its size), which the certificate uses for them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub regions: Option<RegionMetrics>,
    /// SIFT: matching score and RANSAC inlier ratio (thesis Table 6.1 analogue).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matching: Option<MatchingMetrics>,
}

/// Region repeatability of one view of a scale-covariant detector (overlap error < 40 %, 30 px
/// normalisation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RegionMetrics {
    /// Real → render.
    pub sim: RegionRepeatability,
    /// Real a → real b (the ceiling).
    pub ceiling: Option<RegionRepeatability>,
}

/// SIFT matching of one view.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchingMetrics {
    /// Real → render.
    pub sim: MatchingFigures,
    /// Real a → real b (the ceiling).
    pub ceiling: Option<MatchingFigures>,
}

/// Everything measured at one view (capture, camera) for one entry: the unit of work of a
/// validation. A certificate is made from the results of every view, in [`Validator::views`]
/// order, whether they were computed in one process or in shards ([`Validator::view_results`],
/// [`Validator::certify`]); a stored result reads back to the same numbers (canonical JSON
/// keeps every f64 exactly), so a merged certificate is byte-identical to a one-process one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewResult {
    /// Per detector, in the options' order.
    pub metrics: Vec<ViewMetrics>,
    /// Photometric agreement of the render with real frame a.
    pub photometric: Photometric,
    /// Log10 power ratio render ÷ real per frequency band (8 bands up to 0.5 cycles/px).
    pub spectrum_log_ratio: Vec<f64>,
}

/// The figures of one view and detector that the certificate aggregates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CertifiedFigures {
    /// Repeatability real → render, ÷ min(n) (reported).
    pub score: f64,
    /// Real keypoints re-detected in the render ÷ real keypoints (reported).
    pub one_directional: f64,
    /// The chance part of `one_directional` (the render's keypoint density).
    pub chance: f64,
    /// `one_directional` over chance: the certified figure.
    pub excess: f64,
    /// The same over chance for real a → real b: the ceiling.
    pub ceiling: Option<f64>,
    /// Real a → real b ÷ min(n) (reported).
    pub ceiling_score: Option<f64>,
}

impl ViewMetrics {
    /// The certified figures of this view at `eps`: point repeatability, or region
    /// repeatability for the scale-covariant detectors (MSER, SIFT, SURF). Regions are not
    /// chance-corrected (chance 0): an overlap error
    /// below 40 % needs a region of similar position, size and shape, which unrelated regions
    /// rarely have.
    pub fn certified(&self, eps: f64) -> Option<CertifiedFigures> {
        if let Some(r) = &self.regions {
            return Some(CertifiedFigures {
                score: r.sim.score,
                one_directional: r.sim.one_directional,
                chance: 0.0,
                excess: r.sim.one_directional,
                ceiling: r.ceiling.map(|c| c.one_directional),
                ceiling_score: r.ceiling.map(|c| c.score),
            });
        }
        let s = self
            .sim
            .iter()
            .find(|r| (r.epsilon_px - eps).abs() < 1e-9)?;
        Some(CertifiedFigures {
            score: s.score,
            one_directional: s.one_directional,
            chance: s.chance,
            excess: s.excess,
            ceiling: self.ceiling.map(|c| c.excess),
            ceiling_score: self.ceiling.map(|c| c.score),
        })
    }
}

/// Everything measured for one entry, and the verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Certificate {
    /// `regolith.certificate/2` (2: the certified repeatability is one-directional over chance; 1 was ÷ min(n)).
    pub schema: String,
    /// The release validated.
    pub release_id: String,
    /// The entry.
    pub entry: String,
    /// Its entry hash.
    pub entry_hash: String,
    /// Object ids of the captures compared (MCAP).
    pub captures: Vec<String>,
    /// Validator version.
    pub validator_version: String,
    /// The comparison protocol.
    pub protocol: Value,
    /// Thresholds applied.
    pub thresholds: Thresholds,
    /// Per view and detector.
    pub views: Vec<ViewMetrics>,
    /// Photometric per view (capture, camera).
    pub photometric: Vec<(String, String, Photometric)>,
    /// Mean log10 power ratio render/real per frequency band (8 bands up to 0.5 cycles/px).
    pub spectrum_log_ratio: Vec<f64>,
    /// Per detector: sim, ceiling and ratio aggregated over views.
    pub summary: BTreeMap<String, DetectorSummary>,
    /// Mean over detectors of sim ÷ ceiling, aggregated over views (when repeat frames exist).
    pub mean_ratio_to_ceiling: Option<Interval>,
    /// Mean of `spectrum_log_ratio` over its upper half (0.25–0.5 cycles/px).
    pub high_band_log_ratio: f64,
    /// The verdict.
    pub passed: bool,
    /// Each failed criterion, with the figure and the threshold.
    pub failures: Vec<String>,
}

/// Aggregate of one detector.
#[derive(Debug, Clone, Serialize)]
pub struct DetectorSummary {
    /// Certified: real keypoints re-detected in the render over chance, at ε.
    pub sim: Interval,
    /// Certified: real a keypoints re-detected in real b over chance, at ε, when repeat frames
    /// exist.
    pub ceiling: Option<Interval>,
    /// sim ÷ ceiling per view, aggregated: the gated figure.
    pub ratio: Option<Interval>,
    /// The thesis's one-directional ratio (real keypoints re-detected in the render ÷ real),
    /// chance included.
    pub one_directional: Interval,
    /// The chance part of `one_directional`.
    pub chance: Interval,
    /// Mikolajczyk & Schmid repeatability real → render (÷ min(n)), reported.
    pub score: Interval,
    /// The same real a → real b, reported.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub score_ceiling: Option<Interval>,
    /// SIFT: matching score real → render at ε (reported, not gated).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matching_score: Option<Interval>,
    /// SIFT: matching score real a → real b.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matching_score_ceiling: Option<Interval>,
    /// SIFT: RANSAC homography inliers ÷ ratio-test matches, real → render (reported, not gated).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inlier_ratio: Option<Interval>,
    /// SIFT: the same, real a → real b.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inlier_ratio_ceiling: Option<Interval>,
}

/// Per view (capture, camera), the mean over detectors of sim ÷ ceiling at `eps`; aggregated over
/// views with a 95 % CI. `None` without repeat frames.
fn mean_ratio_over_detectors(views: &[ViewMetrics], eps: f64) -> Option<Interval> {
    let mut per_view: BTreeMap<(&str, &str), (f64, usize)> = BTreeMap::new();
    for v in views {
        let Some(f) = v.certified(eps) else {
            continue;
        };
        let Some(c) = f.ceiling.filter(|c| *c > 0.0) else {
            continue;
        };
        let e = per_view.entry((&v.capture, &v.camera)).or_default();
        e.0 += f.excess / c;
        e.1 += 1;
    }
    let means: Vec<f64> = per_view.values().map(|(s, n)| s / *n as f64).collect();
    (!means.is_empty()).then(|| mean_ci(&means))
}

/// Mean of the upper half of the band log-ratios (0.25–0.5 cycles/px with 8 bands).
pub fn high_band_log_ratio(bands: &[f64]) -> f64 {
    let upper = &bands[bands.len() / 2..];
    if upper.is_empty() {
        return 0.0;
    }
    upper.iter().sum::<f64>() / upper.len() as f64
}

fn decode_err(entry: &str, message: String) -> ReaderError {
    ReaderError::Decode {
        entry: entry.to_string(),
        what: "validation input",
        message,
    }
}

/// Decodes an 8- or 16-bit grey PNG to values in 0–1; errors name `entry`.
pub(crate) fn grey(png: &[u8], entry: &str) -> Result<GreyF32, ReaderError> {
    let g = decode_grey_png(png, 32_768).map_err(|m| decode_err(entry, m))?;
    let scale = if g.bit_depth == 16 { 65535.0 } else { 255.0 };
    GreyF32::new(
        g.width as usize,
        g.height as usize,
        g.samples.iter().map(|&v| f32::from(v) / scale).collect(),
    )
    .ok_or_else(|| decode_err(entry, "empty image".into()))
}

/// The entry kinds `validate` renders and certifies, and the release gate requires
/// certificates for: the terrain entries, heightfields and meshes.
pub const CERTIFIED_KINDS: [&str; 2] = [kinds::HEIGHTFIELD, kinds::MESH];

/// The names of the release's entries of a [`CERTIFIED_KINDS`] kind, in manifest order.
pub fn certified_entries(view: &ReleaseView) -> Vec<String> {
    view.entries()
        .iter()
        .filter(|e| CERTIFIED_KINDS.contains(&e.kind.as_str()))
        .map(|e| e.name.clone())
        .collect()
}

/// The render geometry of a terrain entry: a heightfield with its texture (or a uniform grey)
/// as albedo, or a mesh entry's `lod0` GLB with its embedded texture
/// ([`crate::mesh_entry::mesh_geometry`]) — as a height grid when its triangles are a grid's
/// ([`crate::render::grid_mesh`]: the same surface, traced faster); any other kind is
/// [`ReaderError::WrongKind`].
pub fn entry_geometry(view: &ReleaseView, entry: &str) -> Result<Geometry, ReaderError> {
    match view.entry(entry)?.kind.as_str() {
        kinds::HEIGHTFIELD => heightfield_geometry(view, entry),
        kinds::MESH => Ok(match crate::mesh_entry::mesh_geometry(view, entry)? {
            Geometry::Mesh(m) => match crate::render::grid_mesh::as_height_grid(&m) {
                Some((grid, albedo)) => Geometry::Heightfield { grid, albedo },
                None => Geometry::Mesh(m),
            },
            other => other,
        }),
        other => Err(ReaderError::WrongKind {
            entry: entry.to_string(),
            expected: "heightfield or mesh",
            found: other.to_string(),
        }),
    }
}

fn heightfield_geometry(view: &ReleaseView, entry: &str) -> Result<Geometry, ReaderError> {
    let hf = view.heightfield(entry)?;
    let m: &HeightfieldMeta = &hf.meta;
    let grid = HeightGrid {
        origin_m: m.origin_m,
        cell_m: m.cell_m,
        width: m.width as usize,
        height: m.height as usize,
        z: hf.heights.clone(),
    };
    let tex_name = format!("{entry}/texture");
    let albedo = match view.entry(&tex_name) {
        Ok(e) if e.kind == kinds::TEXTURE => {
            let g = grey(&view.read_file(&tex_name, kinds::roles::IMAGE)?, &tex_name)?;
            AlbedoGrid {
                origin_m: m.origin_m,
                cell_m: m.cell_m,
                width: g.width,
                height: g.height,
                // SPEC §5.2: the pixel value / (2^bit_depth − 1) is the linear albedo.
                value: g.data,
            }
        }
        _ => AlbedoGrid {
            origin_m: m.origin_m,
            cell_m: m.cell_m,
            width: 1,
            height: 1,
            value: vec![0.5],
        },
    };
    Ok(Geometry::Heightfield { grid, albedo })
}

/// The campaign light recorded with the release's captures (`meta.lighting`), or the
/// documented default (azimuth 210°, elevation 62°, ambient 0.35) when there is none.
pub fn campaign_light(view: &ReleaseView) -> Result<Light, ReaderError> {
    let caps = view.entry_of_kind("captures", kinds::CAPTURES)?;
    Ok(
        serde_json::from_value::<Light>(caps.meta["lighting"].clone()).unwrap_or(Light {
            azimuth_deg: 210.0,
            elevation_deg: 62.0,
            ambient: 0.35,
        }),
    )
}

/// Bands of the radial spectra compared per view.
const SPECTRUM_BANDS: usize = 8;

/// How a view's render samples its pixels: 2 x 2 samples at edge pixels (occlusion edges,
/// outlines, cast-shadow edges, creases), one shaded sample with a pixel-wide texture filter
/// elsewhere (see [`crate::render::RenderOptions::adaptive`]): 1.3–2.3 rays a pixel instead
/// of 5, with the verdicts and figures of 2 x 2 samples everywhere (measured on independent
/// captures in docs/validate.md).
const RENDER_SAMPLING: Sampling = Sampling::Edges(2);

/// An image's grey levels 0–255 (the contrast-normalised images are 0–1).
fn to255(g: &GreyF32) -> Vec<f32> {
    g.data.iter().map(|v| v * 255.0).collect()
}

/// The raw frame `k` of one view.
fn raw_frame<'i>(
    images: &'i [CaptureImage],
    capture: &str,
    camera: &str,
    k: u32,
) -> Option<&'i CaptureImage> {
    images.iter().find(|i| {
        i.capture == capture && i.camera == camera && i.kind == ImageKind::Raw && i.frame == k
    })
}

/// The contrast-normalised real frames a and (if present) b of one view; errors name `entry`.
fn real_frames(
    images: &[CaptureImage],
    capture: &str,
    camera: &str,
    entry: &str,
) -> Result<(GreyF32, Option<GreyF32>), ReaderError> {
    let a = raw_frame(images, capture, camera, 0)
        .ok_or_else(|| decode_err(entry, format!("no raw frame of {capture} {camera}")))?;
    let real_b = match raw_frame(images, capture, camera, 1) {
        Some(b) => Some(contrast::stretch(&grey(&b.data, entry)?)),
        None => None,
    };
    Ok((contrast::stretch(&grey(&a.data, entry)?), real_b))
}

/// The contrast-normalised render of one view at real frame a's pose, through the entry's
/// sensor model (noise seeded by the frame's index), checked against the real frame's size.
#[allow(clippy::too_many_arguments)]
fn render_view(
    view: &ReleaseView,
    entry: &str,
    scene: &Scene<'_>,
    light: &Light,
    images: &[CaptureImage],
    capture: &str,
    camera: &str,
    sensor: &SensorModel,
    real_a: &GreyF32,
) -> Result<(GreyF32, crate::render::Rendered), ReaderError> {
    let a = raw_frame(images, capture, camera, 0)
        .ok_or_else(|| decode_err(entry, format!("no raw frame of {capture} {camera}")))?;
    let calibrated = view.camera(&format!("cameras/{camera}"))?;
    let seed = images.iter().position(|i| std::ptr::eq(i, a)).unwrap_or(0) as u64;
    let at = Placement {
        ground_from_camera: a.ground_from_camera,
        rig_from_camera: view.rig_from_camera(&format!("cameras/{camera}"))?,
    };
    let sensor = sensor.at_capture(capture);
    let r = sensor.render(scene, light, &calibrated, &at, RENDER_SAMPLING, Some(seed));
    let rendered = r.rendered;
    let dn: Vec<f32> = r.dn.iter().map(|v| v / 255.0).collect();
    let sim_img = GreyF32::new(rendered.width, rendered.height, dn)
        .ok_or_else(|| decode_err(entry, "empty render".into()))?;
    let sim_img = contrast::stretch(&sim_img);
    if (sim_img.width, sim_img.height) != (real_a.width, real_a.height) {
        return Err(decode_err(
            entry,
            format!(
                "render {}x{} vs image {}x{}",
                sim_img.width, sim_img.height, real_a.width, real_a.height
            ),
        ));
    }
    Ok((sim_img, rendered))
}

/// The keypoints of one detector in one view, for a report.
#[derive(Debug, Clone)]
pub struct DetectorKeypoints {
    /// The detector.
    pub detector: Detector,
    /// Keypoints of real frame a.
    pub real: Vec<features::Keypoint>,
    /// Keypoints of the render.
    pub render: Vec<features::Keypoint>,
    /// `(index in real, index in render)` of the pairs repeated at the certified ε.
    pub repeated: Vec<(usize, usize)>,
}

/// What one (capture, camera) view was measured on: the images, keypoints and spectra behind
/// the figures of the certificate, which keeps only the figures. Handed to the observer of
/// [`Validator::entry`] (the HTML report draws them).
#[derive(Debug)]
pub struct ViewArtifacts<'a> {
    /// Capture name.
    pub capture: &'a str,
    /// Camera name.
    pub camera: &'a str,
    /// Real frame a, contrast-normalised.
    pub real_a: &'a GreyF32,
    /// Real frame b (the repeat frame), contrast-normalised, if present.
    pub real_b: Option<&'a GreyF32>,
    /// The render, contrast-normalised.
    pub render: &'a GreyF32,
    /// Where the render sees terrain (255), row-major like the images.
    pub mask: &'a [u8],
    /// Per detector, in the order of the options.
    pub keypoints: Vec<DetectorKeypoints>,
    /// Radial spectra of real frame a and of the render (grey levels 0–255, 8 bands).
    pub spectra: [&'a RadialSpectrum; 2],
}

/// The (capture, camera) views of `images`, sorted, each once: what [`validate_entry`] renders
/// and compares, one per view.
pub fn capture_views(images: &[CaptureImage]) -> Vec<(String, String)> {
    let mut views: Vec<(String, String)> = images
        .iter()
        .map(|i| (i.capture.clone(), i.camera.clone()))
        .collect();
    views.sort();
    views.dedup();
    views
}

/// Validates one entry against every capture of the release (a [`Validator`] for one entry).
pub fn validate_entry(
    view: &ReleaseView,
    entry: &str,
    opts: &ValidateOptions,
) -> Result<Certificate, ReaderError> {
    Validator::new(view, opts.clone())?.entry(entry, None)
}

/// Validates entries of one release against its captures. The real side of every comparison —
/// the captures' raw frames, decoded and contrast-normalised, and what each detector finds in
/// them — is the same whatever entry is compared with it, so it is made once per view, on first
/// use, and kept for the next entry: validating estec's ten entries decoded its 32 real frames
/// and ran five detectors on them ten times over. Certificates are the same either way.
pub struct Validator<'v> {
    view: &'v ReleaseView,
    opts: ValidateOptions,
    light: Light,
    images: Vec<CaptureImage>,
    views: Vec<(String, String)>,
    real: Vec<Mutex<Option<Arc<RealView>>>>,
    /// The cameras' ray tables, shared by every entry's scene.
    rays: Arc<RayTables>,
}

/// One view's real frames and each detector's output on them, in the options' order.
struct RealView {
    a: GreyF32,
    b: Option<GreyF32>,
    found: Vec<(Detected, Option<RepeatFrame>)>,
    /// Radial spectrum of frame a in grey levels 0–255 (the render's is compared with it).
    spectrum: RadialSpectrum,
}

impl<'v> Validator<'v> {
    /// A validator of `view`'s entries with `opts`.
    pub fn new(view: &'v ReleaseView, opts: ValidateOptions) -> Result<Self, ReaderError> {
        let light = campaign_light(view)?;
        let images = view.captures("captures")?.images()?;
        let views = capture_views(&images);
        let real = views.iter().map(|_| Mutex::new(None)).collect();
        Ok(Validator {
            view,
            opts,
            light,
            images,
            views,
            real,
            rays: Arc::default(),
        })
    }

    /// The release validated.
    pub fn release(&self) -> &'v ReleaseView {
        self.view
    }

    /// The (capture, camera) views every entry is compared at (see [`capture_views`]).
    pub fn views(&self) -> &[(String, String)] {
        &self.views
    }

    /// View `k`'s real side, made on first use (decode errors name `entry`).
    fn real(&self, k: usize, entry: &str) -> Result<Arc<RealView>, ReaderError> {
        let mut slot = self.real[k]
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(r) = slot.as_ref() {
            return Ok(Arc::clone(r));
        }
        let (capture, camera) = &self.views[k];
        let (a, b) = real_frames(&self.images, capture, camera, entry)?;
        let params = DetectorParams::default();
        let found = self
            .opts
            .detectors
            .iter()
            .map(|&d| {
                let on_a = detect(&a, d, &params);
                let on_b = b
                    .as_ref()
                    .map(|b| RepeatFrame::new(&on_a, detect(b, d, &params)));
                (on_a, on_b)
            })
            .collect();
        let spectrum = radial_spectrum(&to255(&a), a.width, a.height, SPECTRUM_BANDS);
        let r = Arc::new(RealView {
            a,
            b,
            found,
            spectrum,
        });
        *slot = Some(Arc::clone(&r));
        Ok(r)
    }

    /// Validates `entry`, handing each view's images and keypoints to `observe` (called once
    /// per view, from several threads, in no fixed order). The figures are the same with or
    /// without it.
    pub fn entry(
        &self,
        entry: &str,
        observe: Option<&(dyn Fn(&ViewArtifacts<'_>) + Sync)>,
    ) -> Result<Certificate, ReaderError> {
        let all: Vec<usize> = (0..self.views.len()).collect();
        let results = self.view_results(entry, &all, observe)?;
        self.certify(entry, results)
    }

    /// The results of `entry` at the views numbered `ks` (indices into [`Validator::views`]),
    /// in that order, computed in parallel: a shard of a validation, or all of it.
    pub fn view_results(
        &self,
        entry: &str,
        ks: &[usize],
        observe: Option<&(dyn Fn(&ViewArtifacts<'_>) + Sync)>,
    ) -> Result<Vec<ViewResult>, ReaderError> {
        if ks.is_empty() {
            return Ok(Vec::new());
        }
        let view = self.view;
        view.entry(entry)?;
        let sensor = stored_model(view, entry)?;
        let geometry = entry_geometry(view, entry)?;
        // Renders here are samples (with the model's noise), so they carry its texture detail too.
        let geometry = sensor.detailed(&geometry).unwrap_or(geometry);
        let scene = Scene::new(&geometry).sharing_rays(Arc::clone(&self.rays));
        let work = EntryWork {
            entry,
            scene: &scene,
            sensor: &sensor,
            curve: self.epsilon_curve(),
        };
        ks.par_iter()
            .map(|&k| self.view_result(&work, k, observe))
            .collect()
    }

    /// The ε curve measured: the standard one and the certified ε.
    fn epsilon_curve(&self) -> Vec<f64> {
        let eps = self.opts.thresholds.epsilon_px;
        let mut curve: Vec<f64> = EPSILONS.to_vec();
        if !curve.iter().any(|e| (e - eps).abs() < 1e-9) {
            curve.push(eps);
        }
        curve
    }

    /// Renders `work.entry` at view `k` and measures it against the real frames.
    fn view_result(
        &self,
        work: &EntryWork<'_>,
        k: usize,
        observe: Option<&(dyn Fn(&ViewArtifacts<'_>) + Sync)>,
    ) -> Result<ViewResult, ReaderError> {
        let entry = work.entry;
        let Some((capture, camera)) = self.views.get(k) else {
            return Err(decode_err(
                entry,
                format!(
                    "view {k} does not exist (the release has {} views)",
                    self.views.len()
                ),
            ));
        };
        let opts = &self.opts;
        let params = DetectorParams::default();
        let eps = opts.thresholds.epsilon_px;
        let real = self.real(k, entry)?;
        let (real_a, real_b) = (&real.a, real.b.as_ref());
        let (sim_img, rendered) = render_view(
            self.view,
            entry,
            work.scene,
            &self.light,
            &self.images,
            capture,
            camera,
            work.sensor,
            real_a,
        )?;
        let w = sim_img.width;
        let seen = |p: [f64; 2]| {
            let (x, y) = (p[0].round(), p[1].round());
            x >= 0.0
                && y >= 0.0
                && (x as usize) < w
                && (y as usize) < sim_img.height
                && rendered.mask[y as usize * w + x as usize] == 255
        };
        let seen_px = rendered.mask.iter().filter(|&&m| m == 255).count() as f64;
        let mut metrics = Vec::new();
        let mut kps = Vec::new();
        for (&d, (on_a, on_b)) in opts.detectors.iter().zip(&real.found) {
            let on_render = detect(&sim_img, d, &params);
            let found = ViewDetections {
                real_a: on_a,
                render: &on_render,
                real_b: on_b.as_ref(),
            };
            let c = compare(found, d, seen, seen_px, &work.curve, eps);
            metrics.push(ViewMetrics {
                capture: capture.clone(),
                camera: camera.clone(),
                detector: d,
                counts: [c.real.len(), c.render.len()],
                sim: c.sim,
                ceiling: c.ceiling,
                regions: c
                    .regions
                    .map(|(sim, ceiling)| RegionMetrics { sim, ceiling }),
                matching: c
                    .matching
                    .map(|(sim, ceiling)| MatchingMetrics { sim, ceiling }),
            });
            if observe.is_some() {
                kps.push(DetectorKeypoints {
                    detector: d,
                    repeated: c.repeated,
                    real: c.real,
                    render: c.render,
                });
            }
        }
        let mask: Vec<bool> = rendered.mask.iter().map(|&m| m == 255).collect();
        let (ra, rs) = (to255(real_a), to255(&sim_img));
        let photometric = photometric::compare(&ra, &rs, &mask, w, sim_img.height);
        let spec_s = radial_spectrum(&rs, w, sim_img.height, SPECTRUM_BANDS);
        let spec_a = &real.spectrum;
        let spectrum_log_ratio = log_ratio(&spec_s, spec_a);
        if let Some(observe) = observe {
            observe(&ViewArtifacts {
                capture,
                camera,
                real_a,
                real_b,
                render: &sim_img,
                mask: &rendered.mask,
                keypoints: kps,
                spectra: [spec_a, &spec_s],
            });
        }
        Ok(ViewResult {
            metrics,
            photometric,
            spectrum_log_ratio,
        })
    }

    /// The certificate of `entry` from the results of every view, in [`Validator::views`]
    /// order (from [`Validator::view_results`] here or in shards).
    pub fn certify(
        &self,
        entry: &str,
        results: Vec<ViewResult>,
    ) -> Result<Certificate, ReaderError> {
        if results.len() != self.views.len() {
            return Err(decode_err(
                entry,
                format!(
                    "{} view results for {} views: a certificate needs every view",
                    results.len(),
                    self.views.len()
                ),
            ));
        }
        let view = self.view;
        let e = view.entry(entry)?;
        let sensor = stored_model(view, entry)?;
        let caps_entry = view.entry_of_kind("captures", kinds::CAPTURES)?;
        certificate(
            view,
            entry,
            e,
            caps_entry,
            &self.opts,
            &self.light,
            &sensor,
            &self.views,
            results,
        )
    }

    /// The content key of the unit (`entry`, view `k`): the SHA-256 of the canonical JSON of
    /// everything its result depends on — the release (its manifest fixes the entry, the
    /// captures, the sensor model and the light), the entry, the view, the detectors, the
    /// thresholds and the validator's version. Shards store a unit's result under it, so a
    /// re-run finds what is done and a changed input is never served a stale result.
    pub fn unit_key(&self, entry: &str, k: usize) -> Result<ObjectId, ReaderError> {
        let Some((capture, camera)) = self.views.get(k) else {
            return Err(decode_err(entry, format!("view {k} does not exist")));
        };
        let key = json!({
            "schema": UNIT_SCHEMA,
            "release_id": self.view.id.to_hex(),
            "entry": entry,
            "capture": capture,
            "camera": camera,
            "detectors": self.opts.detectors,
            "thresholds": self.opts.thresholds,
            "validator_version": VALIDATOR_VERSION,
        });
        let bytes = regolith_format::canonical_json::to_vec(&key)
            .map_err(|e| decode_err(entry, e.to_string()))?;
        Ok(ObjectId::of_bytes(&bytes))
    }
}

/// Schema of a validation unit's key and stored result (SPEC §2, `units/` refs).
pub const UNIT_SCHEMA: &str = "regolith.validate-unit/1";

/// What every view of one entry shares: the scene, the sensor model, the ε curve.
struct EntryWork<'a> {
    entry: &'a str,
    scene: &'a Scene<'a>,
    sensor: &'a SensorModel,
    curve: Vec<f64>,
}

/// The certificate of `entry` from its per-view figures.
#[allow(clippy::too_many_arguments)]
fn certificate(
    view: &ReleaseView,
    entry: &str,
    e: &Entry,
    caps_entry: &Entry,
    opts: &ValidateOptions,
    light: &Light,
    sensor: &SensorModel,
    views_in: &[(String, String)],
    per_view: Vec<ViewResult>,
) -> Result<Certificate, ReaderError> {
    let eps = opts.thresholds.epsilon_px;
    let mut views = Vec::new();
    let mut photo = Vec::new();
    let mut spectrum = vec![0.0; 8];
    for (r, (capture, camera)) in per_view.into_iter().zip(views_in) {
        views.extend(r.metrics);
        photo.push((capture.clone(), camera.clone(), r.photometric));
        for (s, x) in spectrum.iter_mut().zip(&r.spectrum_log_ratio) {
            *s += x / views_in.len().max(1) as f64;
        }
    }
    let th = &opts.thresholds;
    let mut summary = BTreeMap::new();
    let mut failures = Vec::new();
    for &d in &opts.detectors {
        let vs: Vec<&ViewMetrics> = views.iter().filter(|v| v.detector == d).collect();
        let cert: Vec<CertifiedFigures> = vs.iter().filter_map(|v| v.certified(eps)).collect();
        let of = |f: &dyn Fn(&CertifiedFigures) -> Option<f64>| -> Vec<f64> {
            cert.iter().filter_map(f).collect()
        };
        let ceil = of(&|c| c.ceiling);
        let score_ceil = of(&|c| c.ceiling_score);
        let ratio = of(&|c| Some(c.excess / c.ceiling.filter(|c| *c > 0.0)?));
        let ms: Vec<&MatchingMetrics> = vs.iter().filter_map(|v| v.matching.as_ref()).collect();
        let agg = |f: &dyn Fn(&MatchingMetrics) -> Option<f64>| {
            let x: Vec<f64> = ms.iter().filter_map(|m| f(m)).collect();
            (!x.is_empty()).then(|| mean_ci(&x))
        };
        let s = DetectorSummary {
            sim: mean_ci(&of(&|c| Some(c.excess))),
            ceiling: (!ceil.is_empty()).then(|| mean_ci(&ceil)),
            ratio: (!ratio.is_empty()).then(|| mean_ci(&ratio)),
            one_directional: mean_ci(&of(&|c| Some(c.one_directional))),
            chance: mean_ci(&of(&|c| Some(c.chance))),
            score: mean_ci(&of(&|c| Some(c.score))),
            score_ceiling: (!score_ceil.is_empty()).then(|| mean_ci(&score_ceil)),
            matching_score: agg(&|m| Some(m.sim.score.score)),
            matching_score_ceiling: agg(&|m| Some(m.ceiling?.score.score)),
            inlier_ratio: agg(&|m| Some(m.sim.ransac.inlier_ratio)),
            inlier_ratio_ceiling: agg(&|m| Some(m.ceiling?.ransac.inlier_ratio)),
        };
        let floor = th.detector_floor(d);
        match (s.ratio, floor) {
            (Some(r), Some(floor)) if r.mean < floor => failures.push(format!(
                "{}: repeatability over chance, ratio to the real-vs-real ceiling {:.3} (95% CI {:.3}–{:.3}) < {:.3}, short by {:.3}",
                d.name(), r.mean, r.low, r.high, floor, floor - r.mean
            )),
            (None, _) if s.sim.mean < th.min_repeatability => failures.push(format!(
                "{}: repeatability over chance {:.3} < {:.3} (no repeat frames: absolute threshold), short by {:.3}",
                d.name(), s.sim.mean, th.min_repeatability, th.min_repeatability - s.sim.mean
            )),
            _ => {}
        }
        summary.insert(d.name().to_string(), s);
    }
    let mean_ratio = mean_ratio_over_detectors(&views, eps);
    if let Some(r) = mean_ratio.filter(|r| r.mean < th.min_mean_ratio_to_ceiling) {
        failures.push(format!(
            "mean over detectors: repeatability over chance, ratio to the ceiling {:.3} (95% CI {:.3}–{:.3}) < {:.3}, short by {:.3}",
            r.mean, r.low, r.high, th.min_mean_ratio_to_ceiling, th.min_mean_ratio_to_ceiling - r.mean
        ));
    }
    let high_band = high_band_log_ratio(&spectrum);
    if high_band < th.min_high_band_log_ratio {
        failures.push(format!(
            "fine detail: the render's power at 0.25–0.5 cycles/px is 10^{:.2} = {:.0} % of the real image's (log ratio {:.2} < {:.2}, short by {:.2})",
            high_band, 100.0 * 10f64.powf(high_band), high_band, th.min_high_band_log_ratio, th.min_high_band_log_ratio - high_band
        ));
    }
    for (capture, camera, p) in &photo {
        if p.rms > th.max_photometric_rms {
            failures.push(format!(
                "photometric RMS {:.1} > {:.1} grey levels at {capture} {camera}",
                p.rms, th.max_photometric_rms
            ));
        }
    }
    let captures = caps_entry
        .files
        .values()
        .map(|f| f.object.to_hex())
        .collect();
    Ok(Certificate {
        schema: "regolith.certificate/2".into(),
        release_id: view.id.to_hex(),
        entry: entry.into(),
        entry_hash: e
            .hash()
            .map_err(|s| decode_err(entry, s.to_string()))?
            .to_hex(),
        captures,
        validator_version: VALIDATOR_VERSION.into(),
        protocol: json!({
            "images": "raw (distorted) real frames vs renders through the calibrated distortion; no resampling of real images",
            "contrast": "linear 1-99 % stretch on both images",
            "repeatability": "one-directional (real keypoints re-detected within ε ÷ real keypoints) over chance: (r - p) / (1 - p), p = 1 - exp(-n_render π ε² / area), identity mapping (same pose), region = render sees terrain, one-to-one greedy pairing; MSER, SIFT and SURF by ellipse overlap error < 40 % (SIFT and SURF keypoints as circles of their size; 30 px normalisation, regions fully inside the region, no chance term); Mikolajczyk & Schmid ÷ min(n) reported as score",
            "matching": "SIFT: Lowe ratio 0.8, matching score = correct one-to-one matches within ε / min(n); RANSAC homography (3 px symmetric transfer error, seeded), inliers / matches; reported, not gated",
            "ceiling": if views.iter().any(|v| v.ceiling.is_some()) { "real frame a vs real frame b at the same pose" } else { "none: absolute thresholds" },
            "render": {"supersample": RENDER_SAMPLING.supersample(), "samples_at": "edge pixels (occlusion, outline, cast-shadow edges, creases); one sample with a pixel-wide texture filter elsewhere", "light": light, "sensor_model": sensor},
        }),
        thresholds: th.clone(),
        views,
        photometric: photo,
        spectrum_log_ratio: spectrum,
        mean_ratio_to_ceiling: mean_ratio,
        high_band_log_ratio: high_band,
        passed: failures.is_empty(),
        failures,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(json: &str) -> Result<Thresholds, serde_json::Error> {
        serde_json::from_str(json)
    }

    #[test]
    fn thresholds_files_set_floors_for_all_or_some_detectors() {
        let all = parse(r#"{"min_ratio_to_ceiling": 0.2}"#).unwrap();
        for d in Detector::ALL {
            assert_eq!(all.detector_floor(d), Some(0.2), "{}", d.name());
        }
        let some = parse(r#"{"min_ratio_to_ceiling": {"fast": 0.3}, "epsilon_px": 2.0}"#).unwrap();
        assert_eq!(some.detector_floor(Detector::Fast), Some(0.3));
        assert_eq!(
            some.detector_floor(Detector::Harris),
            Thresholds::default().detector_floor(Detector::Harris)
        );
        assert_eq!(some.epsilon_px, 2.0);
        assert_eq!(parse("{}").unwrap(), Thresholds::default());
        let err = parse(r#"{"min_ratio_to_ceiling": {"orb": 0.3}}"#).unwrap_err();
        assert!(err.to_string().contains("orb"), "{err}");
        assert!(parse(r#"{"min_ratio": 0.3}"#).is_err());
    }

    #[test]
    fn every_detector_has_a_default_floor() {
        let th = Thresholds::default();
        for d in Detector::ALL {
            assert!(th.detector_floor(d).is_some(), "{}", d.name());
        }
    }
}
