//! The shadows stage: cast shadows of the campaign light ([`crate::gap::shadows`]). The light's
//! direction, recorded as the lab surveyed it, is searched first, then the shadows are tested
//! where the found light casts them.

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};

use crate::gap::context::{has, jackknife, named, upsert, Ctx};
use crate::gap::one_sample::Shading;
use crate::gap::views::{predict_relit, GapView, Prediction};
use crate::gap::{shadows, Named};
use crate::render::{CastShadow, Light, PrimaryHits};
use crate::sensor::{Effect, SensorModel};

/// The views of a shadow test: the real frame means against `lit` and `shadowed` predictions.
pub(crate) fn shadow_views<'a>(
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
pub(crate) fn shadows_stage(ctx: &Ctx<'_>, model: &mut SensorModel, out: &mut Vec<Named>) {
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
    let trace = |v: &GapView| model.primary_hits(&ctx.scene, &v.camera_model, &v.at, 1);
    let means: Vec<Vec<f32>> = ctx.views.iter().map(GapView::mean).collect();
    let record = (ctx.light.azimuth_deg, ctx.light.elevation_deg);
    // The views lit and shadowed by the recorded light, each from its camera rays traced for
    // it alone: most campaigns stop at the test below, and the rays of every view kept
    // together are the stage's largest memory (estec: 94 MB a view, 1.5 GB).
    // The first step's, when the model's rays are its (nothing geometric named).
    let kept = ctx
        .one_sample(model, Shading::Lit)
        .zip(ctx.one_sample(&with(record), Shading::Shadowed));
    let (lit, shadowed): (Vec<Prediction>, Vec<Prediction>) = match kept {
        Some(pair) => pair,
        None => ctx
            .views
            .iter()
            .map(|v| {
                let hits = trace(v);
                (
                    predict_relit(&ctx.scene, &ctx.light, v, model, &hits),
                    predict_relit(&ctx.scene, &ctx.light, v, &with(record), &hits),
                )
            })
            .unzip(),
    };
    // A light that casts no shadow the views would see has nothing to test or refine, and
    // shadows that make the prediction worse where the record casts them are not in the scene
    // (see `shadows::MIN_EXPLAINED_AT_RECORD`): the direction search would only confirm it.
    let at_record = shadows::evidence(&shadow_views(ctx, &means, &lit, &shadowed));
    if at_record.pixels < shadows::MIN_SHADOW_PIXELS
        || at_record.explained < shadows::MIN_EXPLAINED_AT_RECORD
    {
        return;
    }
    // Every view's camera rays, traced once more and kept: a light's direction changes only
    // their shading (the search renders each view under some 30 lights, and a fold's search
    // again).
    let hits: Vec<PrimaryHits> = ctx.views.iter().map(trace).collect();
    // View `i` under `m` and `light`, from its traced rays.
    let relit = |i: usize, m: &SensorModel, light: &Light| {
        predict_relit(&ctx.scene, light, &ctx.views[i], m, &hits[i])
    };
    let all = |m: &SensorModel, light: &Light| -> Vec<Prediction> {
        (0..ctx.views.len()).map(|i| relit(i, m, light)).collect()
    };
    // The model's render under a light from `d`, without cast shadows.
    let lit_at = |d: (f64, f64)| -> Vec<Prediction> {
        let light = Light {
            azimuth_deg: d.0,
            elevation_deg: d.1,
            ..ctx.light
        };
        all(model, &light)
    };
    // The direction first: the campaign records its light as surveyed, a few degrees off, and
    // shadows tested where a wrong light casts them are half missed.
    let near = shadows::near_shadows(&shadow_views(ctx, &means, &lit, &shadowed));
    // View `i`'s shadowed DN under a light from `d`. Its cast shadow is kept for the next
    // search that asks: the search over every view and each fold's search walk the same
    // lattice of directions from the record, so most directions recur, and shading kept hits
    // under a kept cast shadow costs no ray.
    let seen = ShadowCache::default();
    let shadowed_dn = |d: (f64, f64), i: usize| -> Vec<f32> {
        let m = with(d);
        let cast = seen.get_or_trace(d, i, || m.cast_shadow(&ctx.scene, &hits[i], &ctx.light));
        match cast {
            Some(cast) => {
                let v = &ctx.views[i];
                m.relight_cast(&ctx.scene, &hits[i], &ctx.light, &cast, &v.camera_model)
                    .dn
            }
            None => relit(i, &m, &ctx.light).dn,
        }
    };
    // The direction scored on the views `keep` selects, searched from the record.
    let search = |keep: &dyn Fn(usize) -> bool| {
        let idx: Vec<usize> = (0..ctx.views.len()).filter(|&i| keep(i)).collect();
        let near: Vec<&[bool]> = idx.iter().map(|&i| near[i].as_slice()).collect();
        shadows::refine_direction(record, |d| {
            let dn: Vec<Vec<f32>> = idx.iter().map(|&i| shadowed_dn(d, i)).collect();
            let v: Vec<shadows::ShadowView<'_>> = idx
                .iter()
                .zip(&dn)
                .map(|(&i, dn)| shadows::ShadowView {
                    real: &means[i],
                    lit: &lit[i].dn,
                    shadowed: dn,
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
    let mut refined = (direction != record).then(|| all(&with(direction), &ctx.light));
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

/// Most bytes of cast shadows a stage keeps for its searches (beyond it, shadow rays are
/// traced again): a bound like the rest of the stage's memory, some 6500 view-directions of
/// 1280 x 1024 views, where estec's searches (sixteen views, about 60 directions) need a
/// seventh of it.
const CACHE_BYTES: usize = 1 << 30;

/// Cast shadows by (light direction, view), up to [`CACHE_BYTES`].
#[derive(Default)]
struct ShadowCache {
    kept: Mutex<Kept>,
}

/// The kept shadows by (azimuth bits, elevation bits, view) and their bytes.
type Kept = (HashMap<(u64, u64, usize), Arc<CastShadow>>, usize);

impl ShadowCache {
    /// The cast shadow on view `i` of a light from `d`: the kept one, or `trace`'s.
    fn get_or_trace(
        &self,
        d: (f64, f64),
        i: usize,
        trace: impl FnOnce() -> Option<CastShadow>,
    ) -> Option<Arc<CastShadow>> {
        // Exact bits: a direction reached along another path (other float roundings) is
        // traced again, so a kept shadow is exactly the one a trace would give.
        let key = (d.0.to_bits(), d.1.to_bits(), i);
        if let Some(cast) = self.kept.lock().ok().and_then(|k| k.0.get(&key).cloned()) {
            return Some(cast);
        }
        let cast = Arc::new(trace()?);
        if let Ok(mut k) = self.kept.lock() {
            let bytes = cast.bytes();
            // Another fold's search may have traced the same shadow meanwhile.
            if !k.0.contains_key(&key) && k.1 + bytes <= CACHE_BYTES {
                k.1 += bytes;
                k.0.insert(key, cast.clone());
            }
        }
        Some(cast)
    }
}
