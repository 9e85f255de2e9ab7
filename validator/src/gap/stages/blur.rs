//! The blur stage: a PSF from the width of the skyline edges ([`crate::gap::blur`]), real
//! against rendered; a pixel fit would mistake the render's own noise for it.

use std::collections::BTreeMap;

use rayon::prelude::*;

use crate::gap::blur::EdgeView;
use crate::gap::blur_spectrum::{Spectrum, SpectrumView};
use crate::gap::context::{has, jackknife, named, upsert, Ctx};
use crate::gap::one_sample::Shading;
use crate::gap::views::{GapView, Prediction};
use crate::gap::{blur, Named, Withheld};
use crate::sensor::{Effect, SensorModel};

/// Smallest excess width of the real edges over the render's (in quadrature) named as `blur`,
/// px (the catalogue's lower bound: below it the edge widths of anti-aliasing, geometry and
/// the frames' noise dominate).
const BLUR_MIN_PX: f64 = 0.3;

/// Blur, measured on the skyline ([`blur`]). Updates `model`; says why when the skyline could
/// not witness a blur because the background behind the terrain is lit.
pub(crate) fn blur_stage(
    ctx: &Ctx<'_>,
    model: &mut SensorModel,
    min_share: f64,
    out: &mut Vec<Named>,
) -> Option<Withheld> {
    if has(model, "blur") {
        return None;
    }
    // The first step's one-sample renders while the model's rays and light are its.
    let preds = ctx
        .one_sample(model, Shading::Lit)
        .unwrap_or_else(|| ctx.predict_sampled(model, 1));
    let means: Vec<Vec<f32>> = ctx.views.iter().map(GapView::mean).collect();
    // The expected image (no noise); each view's render through it with a PSF of σ added,
    // on the 8-bit range.
    let mut quiet = model.clone();
    quiet.effects.retain(|e| !matches!(e, Effect::Noise { .. }));
    let quiet = &quiet;
    let renders: Vec<Box<dyn Fn(f64) -> Vec<f32> + Sync + '_>> = ctx
        .views
        .iter()
        .zip(&preds)
        .map(|(v, p)| {
            Box::new(move |sigma_px: f64| {
                let mut with = quiet.clone();
                if sigma_px > 0.0 {
                    upsert(&mut with, Effect::Blur { sigma_px });
                }
                let mut dn = with.image(&p.radiance, v.width, v.height, &v.camera_model, 0);
                dn.iter_mut().for_each(|x| *x = x.clamp(0.0, 255.0));
                dn
            }) as Box<dyn Fn(f64) -> Vec<f32> + Sync + '_>
        })
        .collect();
    let views: Vec<EdgeView<'_>> = ctx
        .views
        .iter()
        .zip(&preds)
        .zip(&means)
        .zip(&renders)
        .map(|(((v, p), m), r)| EdgeView {
            real: m,
            mask: &p.mask,
            w: v.width,
            h: v.height,
            render: r.as_ref(),
        })
        .collect();
    let skyline = blur::Skyline::sample(&views);
    let Some(m) = skyline.measure(&|_| true) else {
        if skyline.lit_views == 0 {
            return None;
        }
        let plains: Vec<Vec<f32>> = renders.par_iter().map(|r| r(0.0)).collect();
        return Some(Withheld {
            effect: "blur".to_string(),
            stage: "blur".to_string(),
            reason: format!(
                "not measured: the background beyond the terrain's skyline is lit in {} of {} \
                 views ({} profiles more than {:.1} DN above the render's sky), so its edges are \
                 steps between lit surfaces, not a PSF's; a blur needs an unlit background \
                 (sky, black drape) behind part of the terrain{}",
                skyline.lit_views,
                ctx.views.len(),
                skyline.lit_profiles,
                blur::dark_background_dn(),
                spectrum_reading(ctx, &preds, &means, &plains)
            ),
        });
    };
    // Named on the edges' excess width (the evidence), valued by the matched PSF.
    let share = if m.real_var > 0.0 {
        (m.excess_px.powi(2) / m.real_var).min(1.0)
    } else {
        0.0
    };
    if m.excess_px < BLUR_MIN_PX || share < min_share {
        return None;
    }
    // The captures' spread (each left out in turn) and the estimator's calibration in
    // quadrature.
    let jack = jackknife(ctx.n_folds, &|hold| {
        let kept = skyline.measure(&|i| ctx.folds[i] != hold);
        vec![kept.map_or(m.sigma_px, |k| k.sigma_px)]
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
    None
}

/// The textured ground's reading of the camera's blur across ranges ([`crate::gap::blur_spectrum`]),
/// said beside a blind skyline; empty when there is none (single frames, too few depth bands).
fn spectrum_reading(
    ctx: &Ctx<'_>,
    preds: &[Prediction],
    means: &[Vec<f32>],
    plains: &[Vec<f32>],
) -> String {
    let views: Vec<SpectrumView<'_>> = ctx
        .views
        .iter()
        .zip(preds)
        .zip(means)
        .zip(plains)
        .zip(&ctx.folds)
        .map(|((((v, p), m), r), &fold)| SpectrumView {
            real: m,
            frames: match v.frames.as_slice() {
                [a, b, ..] => Some((a.as_slice(), b.as_slice(), v.frames.len())),
                _ => None,
            },
            render: r,
            mask: &p.mask,
            depth: &p.depth,
            fx: p.camera.fx,
            w: v.width,
            h: v.height,
            fold,
        })
        .collect();
    let spectrum = Spectrum::sample(&views);
    let Some(all) = spectrum.fit(&|_| true) else {
        return String::new();
    };
    let (each, agreement) = spectrum.per_capture();
    let each: Vec<String> = each
        .iter()
        .map(|f| format!("{:.2} ± {:.2}", f.sigma2_px2, f.std_err))
        .collect();
    format!(
        "; the textured ground's spectrum across ranges ({} tiles) reads the camera's blur \
         over the render's as σ² = {:.2} ± {:.2} px² (per capture {}{}), a reading that names \
         nothing: through a laser texture it moves as much with nothing hidden",
        all.tiles,
        all.sigma2_px2,
        all.std_err,
        each.join(", "),
        agreement.map_or(String::new(), |a| format!("; agreement p = {:.2}", a.p))
    )
}
