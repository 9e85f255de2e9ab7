//! Step 1 of the gap workflow: the disagreement as residual fields, not one score.
//!
//! Per view, over the render's terrain mask (eroded by 4 px): the photometric residual of the
//! real frames' mean against the expected render, overall and binned by normalised image radius
//! (vignetting, distortion), by predicted intensity (exposure, response curve); the radial
//! power-spectrum log-ratio render/real (blur, noise, missing texture detail) with the render
//! carrying the model's noise; the photometric RMS over the pixels in cast shadow of the
//! campaign light (occlusion by the light); the residual binned by the terrain's illumination
//! (the shading of a uniform-albedo render: a shading or slope error of the entry, and a
//! response curve, bend it); the frame-to-frame noise variance by intensity next to what the
//! model predicts (noise); and the geometric misalignment (pose, distortion) as the residual
//! of the dense alignment of [`geometry`] at zero increment (normalised band-pass units: 0 for
//! a perfect alignment, about 2 for unrelated images).
//!
//! Every catalogue effect shrinks one [`Figure`] of these: a level, contrast, falloff or blur
//! the photometric RMS (with the noise of the frame mean removed, because noise is the one
//! disagreement no deterministic render removes pixel by pixel), a distortion or pose bias the
//! alignment residual (a 4 % radial term moves pixels by a few px, which changes the
//! photometric RMS of a textured render by less than its noise: mini seed 101, 16.04 → 16.06
//! DN while the alignment residual fell 1.211 → 1.154), cast shadows the RMS in shadow, noise
//! the spectrum, a texture low-pass the texture's band-power deficit (its procedural detail has
//! zero mean, so the photometric RMS against the expected render stays). A gap run's headline
//! is the figure its named effects are read on ([`Figure::headline`]).

use rayon::prelude::*;
use serde::Serialize;

use super::geometry;
use super::noise;
use super::photometry::erode;
use super::views::{GapView, Prediction};
use crate::metrics::spectrum::{log_ratio, radial_spectrum};
use crate::sensor::SensorModel;

const BINS: usize = 8;

/// The figures of one view.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewFigures {
    /// Capture.
    pub capture: String,
    /// Camera.
    pub camera: String,
    /// Photometric RMS of real mean vs expected render, DN (noise of the mean removed).
    pub photometric_rms_dn: f64,
    /// Mean residual real − render, DN.
    pub mean_residual_dn: f64,
    /// Mean squared band-pass residual of the geometric alignment.
    pub alignment_residual: f64,
}

/// The figures of one model over all views.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// Photometric RMS over all views, DN, noise of the frame mean removed.
    pub photometric_rms_dn: f64,
    /// Mean squared band-pass residual of the geometric alignment over all views.
    pub alignment_residual: f64,
    /// Photometric RMS, DN (noise of the mean removed), over the pixels in cast shadow of the
    /// campaign light: the residual where the light is occluded, which a whole-image RMS
    /// dilutes (shadows cover a few per cent of a view). 0 when no pixel is in shadow.
    pub shadow_rms_dn: f64,
    /// Pixels in cast shadow over all views (those of `shadow_rms_dn`).
    pub shadow_pixels: usize,
    /// Mean ratio real/render per normalised-radius bin (0 = principal point, 1 = corner).
    pub residual_by_radius: Vec<f64>,
    /// `(render DN, real DN)` means per bin of rendered intensity.
    pub real_by_intensity: Vec<(f64, f64)>,
    /// `(illumination, mean ratio real/render)` per bin of the terrain's illumination: the
    /// radiance of a uniform-albedo render over its 99th percentile (so 1 is the brightest lit
    /// terrain, 0 the unlit). Empty without such a render (mesh entries). The bins select on
    /// the entry's own shading, so its shading errors regress towards the mean here: an entry
    /// whose slopes are rougher than the terrain's reads too dark where it is least lit (mini,
    /// nothing hidden, seed 103: 1.34 at 0.33, 1.03 at 0.95).
    pub residual_by_illumination: Vec<(f64, f64)>,
    /// `(DN, real variance, model variance)` per intensity bin, DN²: the real frames' noise
    /// from frame pairs ([`noise::measure`]) and the model's noise at that level (through its
    /// response curve, [`super::response::output_variance`]). Empty without repeat frames.
    pub noise_by_intensity: Vec<(f64, f64, f64)>,
    /// log10 power ratio render/real per spectral band (8 bands to 0.5 cycles/px), mean over views.
    pub spectrum_log_ratio: Vec<f64>,
    /// log10 band power of the model's texture (with its detail) over the real albedo's, on the
    /// ground in the texture's cells ([`super::texture::band_power_log_ratio`]); heightfield
    /// entries only.
    pub texture_band_log_ratio: Option<f64>,
    /// Noise variance of the real frames (from frame pairs), DN², used to correct the RMS.
    pub noise_variance_dn2: f64,
    /// Per view.
    pub views: Vec<ViewFigures>,
}

/// A figure of [`Metrics`] that a gap is read on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Figure {
    /// [`Metrics::photometric_rms_dn`].
    PhotometricRmsDn,
    /// [`Metrics::alignment_residual`].
    AlignmentResidual,
    /// RMS over the bands of [`Metrics::spectrum_log_ratio`].
    SpectrumRmsLogRatio,
    /// [`Metrics::shadow_rms_dn`].
    ShadowRmsDn,
    /// [`Metrics::texture_band_log_ratio`], negated (`NaN` without one).
    TextureBandDeficit,
}

impl Figure {
    /// Every figure.
    pub const ALL: [Figure; 5] = [
        Figure::PhotometricRmsDn,
        Figure::AlignmentResidual,
        Figure::SpectrumRmsLogRatio,
        Figure::ShadowRmsDn,
        Figure::TextureBandDeficit,
    ];

    /// What the figure is, with its unit.
    pub fn label(self) -> &'static str {
        match self {
            Figure::PhotometricRmsDn => "photometric RMS, DN",
            Figure::AlignmentResidual => "geometric alignment residual",
            Figure::SpectrumRmsLogRatio => "spectrum RMS log ratio",
            Figure::ShadowRmsDn => "photometric RMS in cast shadow of the light, DN",
            Figure::TextureBandDeficit => {
                "texture band-power deficit against the real albedo, log10"
            }
        }
    }

    /// The figure's value in `m`.
    pub fn of(self, m: &Metrics) -> f64 {
        match self {
            Figure::PhotometricRmsDn => m.photometric_rms_dn,
            Figure::AlignmentResidual => m.alignment_residual,
            Figure::SpectrumRmsLogRatio => {
                let lr = &m.spectrum_log_ratio;
                (lr.iter().map(|x| x * x).sum::<f64>() / lr.len().max(1) as f64).sqrt()
            }
            Figure::ShadowRmsDn => m.shadow_rms_dn,
            Figure::TextureBandDeficit => m.texture_band_log_ratio.map_or(f64::NAN, |r| -r),
        }
    }

    /// The figure a catalogue effect shrinks (see the module docs); `None` for other names.
    pub fn for_effect(effect: &str) -> Option<Figure> {
        match effect {
            "vignetting" | "gamma" | "exposure" | "blur" => Some(Figure::PhotometricRmsDn),
            "distortion" | "pose-bias" => Some(Figure::AlignmentResidual),
            "noise" => Some(Figure::SpectrumRmsLogRatio),
            "shadows" => Some(Figure::ShadowRmsDn),
            "texture-lowpass" => Some(Figure::TextureBandDeficit),
            _ => None,
        }
    }

    /// The headline of a run that named `named` (in the order named): the photometric RMS
    /// when nothing is named or any named effect is read on it (it is what a simulator user
    /// sees), otherwise the figure of the first named effect.
    pub fn headline(named: &[&str]) -> Figure {
        let figures: Vec<Figure> = named.iter().filter_map(|e| Figure::for_effect(e)).collect();
        if figures.contains(&Figure::PhotometricRmsDn) {
            Figure::PhotometricRmsDn
        } else {
            figures.first().copied().unwrap_or(Figure::PhotometricRmsDn)
        }
    }
}

/// Means of a value over `BINS` equal bins of a key in [0, 1].
#[derive(Debug, Clone, Copy, Default)]
struct Binned {
    sum: [f64; BINS],
    key: [f64; BINS],
    n: [usize; BINS],
}

impl Binned {
    fn add(&mut self, key: f64, value: f64) {
        let b = ((key.max(0.0) * BINS as f64) as usize).min(BINS - 1);
        self.sum[b] += value;
        self.key[b] += key;
        self.n[b] += 1;
    }

    /// The mean value per bin (`NaN` for an empty bin).
    fn means(&self) -> Vec<f64> {
        (0..BINS)
            .map(|b| {
                if self.n[b] > 0 {
                    self.sum[b] / self.n[b] as f64
                } else {
                    f64::NAN
                }
            })
            .collect()
    }

    /// `(mean key, mean value)` of the bins holding at least `min` values.
    fn pairs(&self, min: usize) -> Vec<(f64, f64)> {
        (0..BINS)
            .filter(|&b| self.n[b] >= min.max(1))
            .map(|b| {
                (
                    self.key[b] / self.n[b] as f64,
                    self.sum[b] / self.n[b] as f64,
                )
            })
            .collect()
    }
}

/// Fewest pixels in an illumination bin for it to be reported.
const MIN_BIN_PIXELS: usize = 50;

/// The model's noise variance at `dn`, DN² (its `noise` effects, before the response curve).
fn model_noise_variance(model: &SensorModel, dn: f64) -> f64 {
    let gamma = model
        .effects
        .iter()
        .find_map(|e| match *e {
            crate::sensor::Effect::Gamma { gamma } => Some(gamma),
            _ => None,
        })
        .unwrap_or(1.0);
    model
        .effects
        .iter()
        .map(|e| match *e {
            crate::sensor::Effect::Noise { gain, read_sigma } => {
                super::response::output_variance(dn, gamma, gain, read_sigma)
            }
            _ => 0.0,
        })
        .fold(0.0, |a, v| a + v)
}

/// The 99th percentile of `shading` over the pixels `mask` keeps (`None` when it keeps none or
/// the terrain is unlit).
fn bright_level(shading: &[f32], mask: &[bool]) -> Option<f64> {
    let mut v: Vec<f32> = shading
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .map(|(s, _)| *s)
        .collect();
    if v.is_empty() {
        return None;
    }
    let k = ((v.len() as f64 * 0.99) as usize).min(v.len() - 1);
    let level = f64::from(*v.select_nth_unstable_by(k, f32::total_cmp).1);
    (level > 0.0).then_some(level)
}

/// One view's part of [`measure`] that needs no running sums.
struct PerView {
    /// The real frames' mean.
    real: Vec<f32>,
    /// The render's terrain, eroded by 4 px: the pixels measured.
    mask: Vec<bool>,
    /// Log ratio of the radial spectra of the render with the model's noise and of one real
    /// frame.
    log_ratio: Vec<f64>,
    /// The alignment residual and the number of samples it is the mean of.
    align: f64,
    align_n: usize,
}

impl PerView {
    /// View `k`, `v`, predicted as `p` by `model`, `radiance` its render with the model's
    /// texture detail (or the plain one), `align_mask` the terrain its alignment samples.
    fn new(
        k: usize,
        v: &GapView,
        p: &Prediction,
        model: &SensorModel,
        radiance: &[f32],
        align_mask: Option<&Vec<bool>>,
    ) -> PerView {
        let (w, h) = (v.width, v.height);
        let real = v.mean();
        // Spectrum of the render with the model's noise against one real frame.
        let sim = model.image(radiance, w, h, &v.camera_model, 0x9a9 + k as u64);
        let log_ratio = log_ratio(
            &radial_spectrum(&sim, w, h, BINS),
            &radial_spectrum(&v.frames[0], w, h, BINS),
        );
        let band = geometry::LEVELS[geometry::LEVELS.len() - 1];
        let (img, obs) = geometry::prepare(
            0,
            0,
            &p.dn,
            &real,
            align_mask.unwrap_or(&p.mask),
            &p.depth,
            &p.camera,
            v.at.rig_from_camera,
            w,
            h,
            band,
        );
        let align = geometry::mse(&obs, std::slice::from_ref(&img), &[0.0; 8]);
        PerView {
            mask: erode(&p.mask, w, h, 4),
            real,
            log_ratio,
            align,
            align_n: obs.len(),
        }
    }
}

/// Measures the disagreement of `preds` (made with `model`) against the real `views`;
/// `shadow[k]` marks view `k`'s pixels in cast shadow of the campaign light. `detailed[k]`,
/// when given, is view `k`'s radiance rendered with the model's texture detail
/// ([`SensorModel::detailed`]): like the model's noise, a sample's detail enters the spectrum
/// only (its expectation is the plain render). `shading[k]`, when given, is view `k`'s radiance
/// rendered with a uniform albedo (the terrain's illumination). `align_mask[k]` is the
/// terrain of view `k` the alignment residual samples: the geometric stage's own, without the
/// survey markers (see the gap module's `markers`), so the figure a geometric effect is judged
/// by is the one its fit lowered.
#[allow(clippy::too_many_arguments)]
pub fn measure(
    views: &[GapView],
    preds: &[Prediction],
    model: &SensorModel,
    shadow: &[Vec<bool>],
    detailed: Option<&[Vec<f32>]>,
    shading: Option<&[&[f32]]>,
    align_mask: &[Vec<bool>],
) -> Metrics {
    let mut sq = 0.0;
    let mut n = 0usize;
    let mut noise_sum = 0.0;
    let mut noise_n = 0usize;
    let mut by_radius = Binned::default();
    let mut by_light = Binned::default();
    let mut noise_pairs = Vec::new();
    // What each view needs apart from the per-pixel sums, made for the views in parallel: the
    // sums below then run over the views in order, so the figures do not depend on threads.
    let per_view: Vec<PerView> = views
        .par_iter()
        .zip(preds)
        .enumerate()
        .map(|(k, (v, p))| {
            let radiance = detailed.and_then(|d| d.get(k)).unwrap_or(&p.radiance);
            PerView::new(k, v, p, model, radiance, align_mask.get(k))
        })
        .collect();
    let mut int_sum = [(0.0f64, 0.0f64); BINS];
    let mut int_n = [0usize; BINS];
    let mut spectrum = vec![0.0; BINS];
    let (mut align_sum, mut align_n) = (0.0, 0usize);
    let (mut shadow_sq, mut shadow_n) = (0.0, 0usize);
    let mut figures = Vec::new();
    for (k, ((v, p), pv)) in views.iter().zip(preds).zip(&per_view).enumerate() {
        let (w, h) = (v.width, v.height);
        let (real, mask) = (&pv.real, &pv.mask);
        if let [a, b, ..] = v.frames.as_slice() {
            noise_pairs.push((a.as_slice(), b.as_slice(), mask.as_slice()));
        }
        let light = shading.and_then(|s| s.get(k)).copied();
        let light_level = light.and_then(|l| bright_level(l, mask));
        let frames = v.frames.len() as f64;
        let cam = &v.camera_model;
        let in_shadow = shadow.get(k).map_or(&[][..], Vec::as_slice);
        let (mut view_shadow_sq, mut view_shadow_n) = (0.0, 0usize);
        let corner = ((w as f64 / 2.0).powi(2) + (h as f64 / 2.0).powi(2)).sqrt();
        let (mut vs, mut vn, mut vm) = (0.0, 0usize, 0.0);
        let (mut pair_sum, mut pair_n) = (0.0, 0usize);
        for i in 0..w * h {
            if !mask[i] || !(2.0..=253.0).contains(&real[i]) {
                continue;
            }
            let (r, s) = (f64::from(real[i]), f64::from(p.dn[i]));
            vs += (r - s).powi(2);
            vm += r - s;
            vn += 1;
            if in_shadow.get(i) == Some(&true) {
                view_shadow_sq += (r - s).powi(2);
                view_shadow_n += 1;
            }
            if v.frames.len() >= 2 {
                pair_sum += 0.5 * f64::from(v.frames[0][i] - v.frames[1][i]).powi(2);
                pair_n += 1;
            }
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let rho = ((x - cam.cx).powi(2) + (y - cam.cy).powi(2)).sqrt() / corner;
            if s > 1.0 {
                by_radius.add(rho, r / s);
                if let (Some(l), Some(level)) = (light, light_level) {
                    by_light.add(f64::from(l[i]) / level, r / s);
                }
            }
            let bi = ((s / 256.0 * BINS as f64).max(0.0) as usize).min(BINS - 1);
            int_sum[bi].0 += s;
            int_sum[bi].1 += r;
            int_n[bi] += 1;
        }
        let noise_var = if pair_n > 0 {
            pair_sum / pair_n as f64
        } else {
            0.0
        };
        noise_sum += noise_var * pair_n as f64;
        noise_n += pair_n;
        let view_mse = if vn > 0 { vs / vn as f64 } else { 0.0 };
        sq += vs - noise_var / frames * vn as f64;
        shadow_sq += view_shadow_sq - noise_var / frames * view_shadow_n as f64;
        shadow_n += view_shadow_n;
        n += vn;
        for (s, x) in spectrum.iter_mut().zip(&pv.log_ratio) {
            *s += x / views.len().max(1) as f64;
        }
        let align = pv.align;
        align_sum += align * pv.align_n as f64;
        align_n += pv.align_n;
        figures.push(ViewFigures {
            capture: v.capture.clone(),
            camera: v.camera.clone(),
            photometric_rms_dn: (view_mse - noise_var / frames).max(0.0).sqrt(),
            mean_residual_dn: if vn > 0 { vm / vn as f64 } else { 0.0 },
            alignment_residual: align,
        });
    }
    Metrics {
        photometric_rms_dn: if n > 0 {
            (sq / n as f64).max(0.0).sqrt()
        } else {
            0.0
        },
        shadow_rms_dn: if shadow_n > 0 {
            (shadow_sq / shadow_n as f64).max(0.0).sqrt()
        } else {
            0.0
        },
        shadow_pixels: shadow_n,
        alignment_residual: if align_n > 0 {
            align_sum / align_n as f64
        } else {
            0.0
        },
        residual_by_radius: by_radius.means(),
        residual_by_illumination: by_light.pairs(MIN_BIN_PIXELS),
        noise_by_intensity: noise::measure(&noise_pairs).map_or_else(Vec::new, |f| {
            f.by_intensity
                .iter()
                .map(|&(dn, var, _)| (dn, var, model_noise_variance(model, dn)))
                .collect()
        }),
        real_by_intensity: (0..BINS)
            .filter(|&b| int_n[b] > 0)
            .map(|b| {
                (
                    int_sum[b].0 / int_n[b] as f64,
                    int_sum[b].1 / int_n[b] as f64,
                )
            })
            .collect(),
        spectrum_log_ratio: spectrum,
        texture_band_log_ratio: None,
        noise_variance_dn2: if noise_n > 0 {
            noise_sum / noise_n as f64
        } else {
            0.0
        },
        views: figures,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::Effect;

    #[test]
    fn bins_average_keys_and_values_and_report_only_full_bins() {
        let mut b = Binned::default();
        for k in 0..100 {
            b.add(0.05, f64::from(k));
        }
        b.add(0.99, 3.0);
        b.add(1.7, 5.0); // beyond 1: the last bin
        let means = b.means();
        assert_eq!(means[0], 49.5);
        assert!(means[1..BINS - 1].iter().all(|m| m.is_nan()));
        assert_eq!(means[BINS - 1], 4.0);
        let full = b.pairs(50);
        assert_eq!(full.len(), 1);
        assert!(
            (full[0].0 - 0.05).abs() < 1e-12 && full[0].1 == 49.5,
            "{full:?}"
        );
        assert_eq!(b.pairs(2).len(), 2);
    }

    #[test]
    fn the_model_noise_is_shot_plus_read_through_the_curve_and_nothing_without_noise() {
        let noise = Effect::Noise {
            gain: 0.3,
            read_sigma: 2.0,
        };
        let linear = SensorModel::from(vec![noise]);
        assert!((model_noise_variance(&linear, 100.0) - 34.0).abs() < 1e-12);
        assert!((model_noise_variance(&linear, -5.0) - 4.0).abs() < 1e-12);
        // Under a curve of 2.2, output level 100 is linear signal 255 (100/255)^2.2 = 32.52,
        // whose variance 0.3 · 32.04 + 4 the curve's slope (100/255)^(-1.2) / 2.2 scales.
        let curved = SensorModel::from(vec![Effect::Gamma { gamma: 2.2 }, noise]);
        let t: f64 = 100.0 / 255.0;
        let slope = t.powf(-1.2) / 2.2;
        let expected = slope * slope * (0.3 * 255.0 * t.powf(2.2) + 4.0);
        assert!((model_noise_variance(&curved, 100.0) - expected).abs() < 1e-9);
        assert!((expected - 26.87).abs() < 0.01, "{expected}");
        let clean = model_noise_variance(&SensorModel::default(), 100.0);
        assert!(clean == 0.0 && clean.is_sign_positive());
    }

    #[test]
    fn the_bright_level_is_the_99th_percentile_of_the_masked_shading() {
        let shading: Vec<f32> = (0..1000).map(|i| i as f32 / 1000.0).collect();
        let mut mask = vec![true; 1000];
        mask[990..].fill(false);
        let level = bright_level(&shading, &mask).expect("lit");
        assert!((level - 0.980).abs() < 1e-6, "{level}");
        assert_eq!(bright_level(&shading, &[false; 1000]), None);
        assert_eq!(bright_level(&[0.0; 10], &[true; 10]), None);
    }

    #[test]
    fn the_headline_is_the_figure_the_named_effects_are_read_on() {
        let h = |n: &[&str]| Figure::headline(n);
        assert_eq!(h(&[]), Figure::PhotometricRmsDn);
        assert_eq!(h(&["distortion"]), Figure::AlignmentResidual);
        assert_eq!(h(&["pose-bias", "vignetting"]), Figure::PhotometricRmsDn);
        assert_eq!(h(&["texture-lowpass"]), Figure::TextureBandDeficit);
        assert_eq!(h(&["shadows", "noise"]), Figure::ShadowRmsDn);
        for e in crate::sensor::Effect::NAMES {
            assert!(Figure::for_effect(e).is_some(), "{e}");
        }
        let key = serde_json::to_value(Figure::TextureBandDeficit).unwrap_or_default();
        assert_eq!(key, "texture_band_deficit");
    }
}
