//! The run's shared context: the views of the release with the entry's geometry and the
//! campaign light ([`Ctx`]), their capture folds, and the cross-validation and jackknife every
//! stage scores and bounds its effects with.

use std::collections::BTreeMap;

use rayon::prelude::*;
use regolith_reader::{ReaderError, ReleaseView};

use super::consistency::chi2_sf;
use super::measure::{self, Metrics};
use super::one_sample::{OneSample, Shading};
use super::select::Candidate;
use super::stages::geometry::geometric_masks;
use super::stages::texture::TextureInputs;
use super::views::{load_views, predict, predict_from_hits, GapView, Prediction};
use super::{markers, param_map, shadows, texture, GapOptions, Named, ScoredCandidate};
use crate::render::{Geometry, Light, Scene};
use crate::sensor::{Effect, SensorModel};
use crate::validate::campaign_light;

/// Standard errors by which a fitted effect must differ from its neutral values to be named (a
/// photometric effect's parameters; a distortion's displacement at 0.7 of the radius). With
/// nothing hidden, the full-resolution estec `laser/0.015` entry chose `vignetting` (5.4 DN²
/// held out, over its 3 DN² floor) whose final strength, next to the free gain, was
/// 0.0007 ± 0.0083.
pub(crate) const SIGNIFICANCE: f64 = 2.0;

/// Whether a χ² test over several parameters, of p-value `p`, rejects "none": `p` below the
/// false-alarm rate of a [`SIGNIFICANCE`]-σ departure of one parameter.
pub(crate) fn beyond_chance(p: f64) -> bool {
    p < chi2_sf(SIGNIFICANCE * SIGNIFICANCE, 1.0)
}

/// Fold of each view: the index of its capture (views of one capture are held out together).
pub(crate) fn folds(views: &[GapView]) -> Vec<usize> {
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
/// fold, the in-sample error. The folds are fitted in parallel (a fit's own parallel parts
/// leave a core idle in its serial ones) and their errors summed in fold order, so the figure
/// does not depend on the thread count; `fit_and_test` must not hold a lock while it works.
pub(crate) fn cross_validate(
    n_folds: usize,
    fit_and_test: &(dyn Fn(Option<usize>) -> f64 + Sync),
) -> f64 {
    if n_folds < 2 {
        return fit_and_test(None);
    }
    let errors: Vec<f64> = (0..n_folds)
        .into_par_iter()
        .map(|f| fit_and_test(Some(f)))
        .collect();
    errors.iter().sum::<f64>() / n_folds as f64
}

/// Jackknife standard errors over folds: `fit(f)` gives the parameters fitted without fold `f`;
/// `sqrt((n − 1) / n · Σ (θ_f − θ̄)²)` per parameter. `None` with fewer than two folds.
pub(crate) fn jackknife(
    n_folds: usize,
    fit: &(dyn Fn(usize) -> Vec<f64> + Sync),
) -> Option<Vec<f64>> {
    if n_folds < 2 {
        return None;
    }
    // In parallel, kept in fold order (see [`cross_validate`]).
    jackknife_spread(&(0..n_folds).into_par_iter().map(fit).collect::<Vec<_>>())
}

/// The jackknife standard errors of leave-one-fold-out `fits` (see [`jackknife`]); `None` with
/// fewer than two.
pub(crate) fn jackknife_spread(fits: &[Vec<f64>]) -> Option<Vec<f64>> {
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
pub(crate) fn honest_std_err<const K: usize>(formal: [f64; K], jack: Option<Vec<f64>>) -> [f64; K] {
    let mut out = formal;
    if let Some(j) = jack {
        for (o, j) in out.iter_mut().zip(j) {
            *o = o.max(j);
        }
    }
    out
}

pub(crate) struct Ctx<'a> {
    pub(crate) geometry: &'a Geometry,
    pub(crate) scene: Scene<'a>,
    pub(crate) light: Light,
    pub(crate) views: Vec<GapView>,
    pub(crate) folds: Vec<usize>,
    pub(crate) n_folds: usize,
    pub(crate) supersample: u32,
    /// Ground-frame survey markers, kept out of the geometric fit ([`markers`]).
    pub(crate) markers: Vec<markers::SurveyMarker>,
    /// The last renders of [`Ctx::predict_all`] and the model they are of: a stage that
    /// changes nothing leaves the next one the model it rendered last.
    last: std::sync::Mutex<Option<(SensorModel, Vec<Prediction>)>>,
    /// The first step's one-sample renders, for the later stages ([`OneSample`]).
    one_sample: std::sync::Mutex<Option<OneSample>>,
}

impl<'a> Ctx<'a> {
    /// The views of `opts.captures` and `opts.cameras` (all when empty) of the release, with
    /// the entry's `geometry`, rendered at `opts.supersample`.
    pub(crate) fn load(
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
            last: std::sync::Mutex::new(None),
            one_sample: std::sync::Mutex::new(None),
        })
    }

    /// Per view, the pixels in cast shadow of the campaign light (as [`shadows::shadow_pixels`])
    /// when the scene is seen through `model`'s geometry: where [`Metrics::shadow_rms_dn`] is
    /// measured.
    pub(crate) fn shadow_pixels(&self, model: &SensorModel) -> Vec<Vec<bool>> {
        self.shadow_pixels_and_flat(model, None).0
    }

    /// [`Ctx::shadow_pixels`] and, given the texture measure's uniform albedo `flat`
    /// ([`crate::gap::stages::texture::flat_albedo`]), `model`'s renders under it: all from
    /// one set of camera rays per view (the flat renders' albedo is then exactly the uniform
    /// one, where a render of a uniform grid interpolates it to within a rounding).
    pub(crate) fn shadow_pixels_and_flat(
        &self,
        model: &SensorModel,
        flat: Option<f32>,
    ) -> (Vec<Vec<bool>>, Option<Vec<Prediction>>) {
        let (_, pixels, flats) = self.traced(model, flat, false);
        (pixels, flats)
    }

    /// [`Ctx::predict_all`] of `model` and [`Ctx::shadow_pixels_and_flat`] together, from one
    /// set of camera rays per view: the renders take their pixel centres from the rays the
    /// other two shade and trace only their edge pixels' samples (the same bytes as
    /// [`Ctx::predict_all`]; estec, 16 views: the gap's loading step 21.7 → 16.9 s). The
    /// one-sample renders are kept for the later stages ([`Ctx::one_sample`]).
    pub(crate) fn predict_with_shadows_and_flat(
        &self,
        model: &SensorModel,
        flat: Option<f32>,
    ) -> (Vec<Prediction>, Vec<Vec<bool>>, Option<Vec<Prediction>>) {
        let (preds, pixels, flats) = self.traced(model, flat, true);
        *self
            .last
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) =
            Some((model.clone(), preds.clone()));
        (preds, pixels, flats)
    }

    /// `model`'s one-sample renders of every view under `shading` from the first step's kept
    /// ones ([`OneSample`]): `None` when it traces other rays or casts other shadows than
    /// they were made with, or none were kept.
    pub(crate) fn one_sample(
        &self,
        model: &SensorModel,
        shading: Shading,
    ) -> Option<Vec<Prediction>> {
        self.one_sample
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .as_ref()?
            .renders(model, shading, &self.views)
    }

    /// The uniform albedo of the kept flat renders ([`Ctx::one_sample`]), if kept.
    pub(crate) fn one_sample_flat_albedo(&self) -> Option<f32> {
        self.one_sample
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .as_ref()?
            .flat_albedo()
    }

    /// Per view from one set of camera rays: `model`'s render at the context's sampling when
    /// `renders` (none otherwise; with them the one-sample renders are kept), the cast-shadow
    /// pixels and the flat renders (see [`Ctx::shadow_pixels_and_flat`]).
    fn traced(
        &self,
        model: &SensorModel,
        flat: Option<f32>,
        renders: bool,
    ) -> (Vec<Prediction>, Vec<Vec<bool>>, Option<Vec<Prediction>>) {
        let mut lit = model.clone();
        lit.effects.retain(|e| e.name() != "shadows");
        let mut shadowed = lit.clone();
        let record = Effect::Shadows {
            azimuth_deg: self.light.azimuth_deg,
            elevation_deg: self.light.elevation_deg,
        };
        shadowed.effects.push(record);
        let mut kept = renders.then(|| OneSample::new(model, record, flat));
        let (mut preds, mut pixels, mut flats) = (Vec::new(), Vec::new(), Vec::new());
        for v in &self.views {
            let hits = lit.primary_hits(&self.scene, &v.camera_model, &v.at, 1);
            if renders {
                preds.push(predict_from_hits(
                    &self.scene,
                    &self.light,
                    v,
                    model,
                    self.supersample,
                    &hits,
                ));
            }
            let l = lit.relight_radiance(&self.scene, &hits, &self.light);
            let s = shadowed.relight_radiance(&self.scene, &hits, &self.light);
            let f = flat.map(|a| {
                model.relight_radiance(&self.scene, &hits.with_geometry_albedo(a), &self.light)
            });
            drop(hits);
            if let Some(k) = kept.as_mut() {
                k.push(&l, &s, f.as_ref());
            }
            let finish =
                |m: &SensorModel, r| Prediction::from(m.finish_rendered(r, &v.camera_model, None));
            let (l, s) = (finish(&lit, l), finish(&shadowed, s));
            pixels.push(shadows::shadow_pixels(
                &l.dn, &s.dn, &l.mask, v.width, v.height,
            ));
            flats.push(f.map(|f| finish(model, f)));
        }
        if kept.is_some() {
            *self
                .one_sample
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner) = kept;
        }
        (preds, pixels, flats.into_iter().collect())
    }

    /// Measures `preds` (made with `model`) against the real views; with a `texture-lowpass`
    /// in `model`, the spectrum is taken on renders with its texture detail.
    ///
    /// `flat`, when given, are `model`'s renders under the texture measure's uniform albedo
    /// ([`Ctx::shadow_pixels_and_flat`]); otherwise they are made here.
    pub(crate) fn measure(
        &self,
        preds: &[Prediction],
        model: &SensorModel,
        shadow: &[Vec<bool>],
        flat: Option<Vec<Prediction>>,
    ) -> Metrics {
        let detailed_geometry = model.detailed(self.geometry);
        let detailed = detailed_geometry.as_ref().map(|g| {
            let scene = Scene::new(g);
            self.views
                .iter()
                .map(|v| predict(&scene, &self.light, v, model, self.supersample).radiance)
                .collect::<Vec<_>>()
        });
        let inputs = match self.geometry {
            Geometry::Heightfield { grid, albedo } => Some(match flat {
                Some(flat) => TextureInputs::with_flat(self, model, flat),
                None => TextureInputs::kept_or_new(self, grid, albedo, model),
            }),
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
    pub(crate) fn fold_names(&self) -> Vec<String> {
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

    /// The renders of every view through `model` (the last ones again when `model` is theirs:
    /// a render depends on nothing else).
    pub(crate) fn predict_all(&self, model: &SensorModel) -> Vec<Prediction> {
        let mut last = self
            .last
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, preds)) = last.as_ref().filter(|(m, _)| m == model) {
            return preds.clone();
        }
        let preds = self.predict_sampled(model, self.supersample);
        *last = Some((model.clone(), preds.clone()));
        preds
    }

    pub(crate) fn predict_sampled(&self, model: &SensorModel, supersample: u32) -> Vec<Prediction> {
        self.views
            .iter()
            .map(|v| predict(&self.scene, &self.light, v, model, supersample))
            .collect()
    }
}

pub(crate) fn has(model: &SensorModel, name: &str) -> bool {
    model.effects.iter().any(|e| e.name() == name)
}

/// Adds `e` to `model`: an effect already present is replaced by `e`.
pub(crate) fn upsert(model: &mut SensorModel, e: Effect) {
    match model.effects.iter_mut().find(|x| x.name() == e.name()) {
        Some(x) => *x = e,
        None => model.effects.push(e),
    }
}

pub(crate) fn named(
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
        plain: BTreeMap::new(),
        per_capture: Vec::new(),
    }
}

pub(crate) fn scored(cands: &[Candidate]) -> Vec<ScoredCandidate> {
    cands
        .iter()
        .map(|c| ScoredCandidate {
            effects: c.effects.iter().map(|s| s.to_string()).collect(),
            k: c.k,
            cv_error: c.cv_error,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

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
