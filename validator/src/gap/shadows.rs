//! The `shadows` effect: cast shadows of the campaign light, tested where they would fall.
//!
//! Cast shadows are small and sharp (behind boulders, in the lee of hills), so a whole-image
//! photometric fit, which has to low-pass the images, barely sees them. They are tested where
//! they matter instead: the **shadow pixels** are those the shadowed render draws at least 20 %
//! darker than the lit one (eroded by 2 px, so a shadow edge a pixel off does not count). If the
//! real scene has the shadows, the shadowed prediction is far better there (the lit one misses
//! by the whole direct share of the light); if it does not, the shadowed prediction is far worse.
//! The explained fraction is `1 − MSE_shadowed / MSE_lit` over the shadow pixels, required in
//! every capture that sees enough of them (a capture looking away from the shadows has no say).
//! The light direction is then refined by a coordinate search minimising the
//! mean absolute log residual over the terrain ([`log_residual`]), which depends on where
//! shadows fall and not on the render's level; the refined direction replaces the campaign's
//! only if it scores better in every capture fold (a lab light casts the same shadows in every
//! capture; with few shadow pixels the overall optimum can sit degrees off the true light).

use super::photometry::erode;

/// One view for the shadow test (DN images, `w x h`).
#[derive(Debug, Clone, Copy)]
pub struct ShadowView<'a> {
    /// Real frame mean.
    pub real: &'a [f32],
    /// Prediction without cast shadows.
    pub lit: &'a [f32],
    /// Prediction with cast shadows.
    pub shadowed: &'a [f32],
    /// The render sees terrain.
    pub mask: &'a [bool],
    /// Width.
    pub w: usize,
    /// Height.
    pub h: usize,
    /// Cross-validation fold (capture).
    pub fold: usize,
}

/// The evidence for cast shadows.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowEvidence {
    /// Shadow pixels over all views.
    pub pixels: usize,
    /// MSE of the lit prediction on them, DN².
    pub mse_lit: f64,
    /// MSE of the shadowed prediction on them, DN².
    pub mse_shadowed: f64,
    /// `1 − mse_shadowed / mse_lit` over all views.
    pub explained: f64,
    /// Per fold: its shadow pixels and their explained fraction (0 without any).
    pub per_fold: Vec<(usize, f64)>,
}

/// Share of the shadow pixels' error the shadowed prediction must remove, overall and (at half
/// of it) in every capture that sees at least [`MIN_FOLD_SHADOW_PIXELS`], for `shadows` to be
/// named.
pub const MIN_SHADOW_EXPLAINED: f64 = 0.5;
/// Fewest shadow pixels (all views) for a shadow test. Shadows hidden in `mini` campaigns
/// (seeds 101–107) gave 66 to 5315 pixels explained 0.91–0.98; with none hidden the light's
/// shadow pixels numbered 0 or 2 (explained −33).
pub const MIN_SHADOW_PIXELS: usize = 50;
/// Fewest shadow pixels for a capture to vote: seed 106's light (elevation 28°) shadows 66
/// pixels of one capture's views and none of the other's.
pub const MIN_FOLD_SHADOW_PIXELS: usize = 20;

impl ShadowEvidence {
    /// Whether the evidence names `shadows`: enough shadow pixels, [`MIN_SHADOW_EXPLAINED`] of
    /// their error removed overall and half of it in every capture with a say.
    pub fn convincing(&self) -> bool {
        self.pixels >= MIN_SHADOW_PIXELS
            && self.explained >= MIN_SHADOW_EXPLAINED
            && self
                .per_fold
                .iter()
                .all(|&(n, f)| n < MIN_FOLD_SHADOW_PIXELS || f >= 0.5 * MIN_SHADOW_EXPLAINED)
    }
}

/// The shadow pixels of one view: terrain the shadowed prediction draws at least 20 % darker
/// than the lit one, eroded by 2 px.
pub fn shadow_pixels(
    lit: &[f32],
    shadowed: &[f32],
    mask: &[bool],
    w: usize,
    h: usize,
) -> Vec<bool> {
    let shadow: Vec<bool> = (0..w * h)
        .map(|i| mask[i] && shadowed[i] < 0.8 * lit[i])
        .collect();
    erode(&shadow, w, h, 2)
}

/// Compares the lit and shadowed predictions on the shadow pixels.
pub fn evidence(views: &[ShadowView<'_>]) -> ShadowEvidence {
    let folds = views.iter().map(|v| v.fold + 1).max().unwrap_or(0);
    let mut lit = vec![0.0f64; folds];
    let mut sh = vec![0.0f64; folds];
    let mut count = vec![0usize; folds];
    for v in views {
        let core = shadow_pixels(v.lit, v.shadowed, v.mask, v.w, v.h);
        for i in (0..v.w * v.h).filter(|&i| core[i]) {
            let r = f64::from(v.real[i]);
            lit[v.fold] += (r - f64::from(v.lit[i])).powi(2);
            sh[v.fold] += (r - f64::from(v.shadowed[i])).powi(2);
            count[v.fold] += 1;
        }
    }
    let ratio = |l: f64, s: f64| if l > 0.0 { 1.0 - s / l } else { 0.0 };
    let (tl, ts): (f64, f64) = (lit.iter().sum(), sh.iter().sum());
    let n: usize = count.iter().sum();
    ShadowEvidence {
        pixels: n,
        mse_lit: tl / n.max(1) as f64,
        mse_shadowed: ts / n.max(1) as f64,
        explained: ratio(tl, ts),
        per_fold: count
            .iter()
            .zip(lit.iter().zip(&sh))
            .map(|(c, (l, s))| (*c, ratio(*l, *s)))
            .collect(),
    }
}

/// `ln((real + 1) / (prediction + 1))` of every terrain pixel of every view.
fn log_ratios<'a>(views: &'a [ShadowView<'a>]) -> impl Iterator<Item = f64> + 'a {
    views.iter().flat_map(|v| {
        (0..v.w * v.h)
            .filter(|&i| v.mask[i])
            .map(|i| ((f64::from(v.real[i]) + 1.0) / (f64::from(v.shadowed[i]) + 1.0)).ln())
    })
}

/// The median log ratio of real to predicted over the terrain: the level [`log_residual`]
/// removes.
pub fn log_level(views: &[ShadowView<'_>]) -> f64 {
    let mut r: Vec<f64> = log_ratios(views).collect();
    if r.is_empty() {
        return 0.0;
    }
    let mid = r.len() / 2;
    *r.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Mean absolute log residual between the real images and the shadowed predictions over the
/// terrain, after removing `level`: the score the light direction search minimises. In the log
/// domain a texture error scales the lit and the shadowed prediction alike, and the level is
/// the campaign light's, the same for every candidate. Measured on `mini` campaigns with a 25°
/// light: seed 31 266.5°/25.0° for a true 266.5°/25°, seed 101 214.7°/29.0° for 214.2°/25°.
/// (A thresholded overlap of shadow masks gave 265°/21.5° and 217.2°/22.5°: dark pebbles the
/// render lacks pass for shadows and pull them longer; a squared residual after a common gain
/// gave 261°/24° and 219.7°/32.5°.)
pub fn log_residual(views: &[ShadowView<'_>], level: f64) -> f64 {
    let (sum, n) =
        log_ratios(views).fold((0.0, 0usize), |(s, n), r| (s + (r - level).abs(), n + 1));
    if n == 0 {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn real_shadows_are_explained_and_absent_ones_are_not() {
        let (w, h) = (40, 40);
        let mask = vec![true; w * h];
        let lit = vec![100.0f32; w * h];
        let shadowed: Vec<f32> = (0..w * h)
            .map(|i| if (i % w) < 20 { 35.0 } else { 100.0 })
            .collect();
        let view = |real: &'static [f32]| ShadowView {
            real,
            lit: &lit,
            shadowed: &shadowed,
            mask: &mask,
            w,
            h,
            fold: 0,
        };
        let with: &'static [f32] = Box::leak(
            shadowed
                .iter()
                .map(|v| v + 2.0)
                .collect::<Vec<f32>>()
                .into_boxed_slice(),
        );
        let without: &'static [f32] = Box::leak(vec![98.0f32; w * h].into_boxed_slice());
        let e = evidence(&[view(with)]);
        assert!(e.explained > 0.99 && e.pixels > 500, "{e:?}");
        let e = evidence(&[view(without)]);
        assert!(e.explained < -10.0, "{e:?}");
        assert!(!e.convincing());
    }

    #[test]
    fn a_capture_without_shadow_pixels_has_no_say_but_one_that_disagrees_vetoes() {
        let ev = |per_fold: Vec<(usize, f64)>| ShadowEvidence {
            pixels: per_fold.iter().map(|f| f.0).sum(),
            mse_lit: 280.0,
            mse_shadowed: 23.0,
            explained: 0.9,
            per_fold,
        };
        assert!(ev(vec![(0, 0.0), (66, 0.92)]).convincing());
        assert!(!ev(vec![(MIN_FOLD_SHADOW_PIXELS, 0.1), (66, 0.92)]).convincing());
        assert!(!ev(vec![(0, 0.0), (MIN_SHADOW_PIXELS - 1, 0.92)]).convincing());
    }

    #[test]
    fn the_log_residual_ignores_the_level_and_sees_where_shadows_fall() {
        let (w, h) = (40, 40);
        let mask = vec![true; w * h];
        let shadow_at = |edge: usize, level: f32| -> Vec<f32> {
            (0..w * h)
                .map(|i| level * if (i % w) < edge { 35.0 } else { 100.0 })
                .collect()
        };
        let real = shadow_at(20, 1.0);
        let score = |pred: &[f32]| {
            let v = [ShadowView {
                real: &real,
                lit: pred,
                shadowed: pred,
                mask: &mask,
                w,
                h,
                fold: 0,
            }];
            log_residual(&v, log_level(&v))
        };
        let (right, dimmer, longer) = (
            score(&shadow_at(20, 1.0)),
            score(&shadow_at(20, 0.7)),
            score(&shadow_at(24, 1.0)),
        );
        assert!(right < 1e-9 && dimmer < 0.005, "{right} {dimmer}");
        assert!(longer > 0.05, "{longer}");
        assert!(score(&shadow_at(22, 1.0)) < longer);
    }
}
