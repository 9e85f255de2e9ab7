//! The blur stage: a PSF from the width of the skyline edges ([`crate::gap::blur`]), real
//! against rendered; a pixel fit would mistake the render's own noise for it.

use std::collections::BTreeMap;

use crate::gap::context::{has, jackknife, named, upsert, Ctx};
use crate::gap::views::{GapView, ImagePair};
use crate::gap::{blur, Named};
use crate::sensor::{Effect, SensorModel};

/// Smallest PSF σ named as `blur`, px (the catalogue's lower bound: below it the edge widths
/// of anti-aliasing and geometry dominate).
const BLUR_MIN_PX: f64 = 0.3;

/// Blur, measured on the skyline ([`blur`]). Updates `model`.
pub(crate) fn blur_stage(
    ctx: &Ctx<'_>,
    model: &mut SensorModel,
    min_share: f64,
    out: &mut Vec<Named>,
) {
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
