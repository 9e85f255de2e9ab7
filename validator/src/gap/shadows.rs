//! The `shadows` effect: cast shadows of the campaign light, tested where they would fall.
//!
//! Cast shadows are small and sharp (behind boulders, in the lee of hills), so a whole-image
//! photometric fit, which has to low-pass the images, barely sees them. They are tested where
//! they matter instead: the **shadow pixels** are those the shadowed render draws at least 20 %
//! darker than the lit one (eroded by 2 px, so a shadow edge a pixel off does not count). If the
//! real scene has the shadows, the shadowed prediction is far better there (the lit one misses
//! by the whole direct share of the light); if it does not, the shadowed prediction is far worse.
//! The explained fraction is `1 − MSE_shadowed / MSE_lit` over the shadow pixels, required in
//! every capture. The light direction is then refined by a coordinate search maximising the
//! overlap of the predicted shadows with the real image's dark regions ([`overlap`]), which
//! depends on where shadows fall and not on the render's texture or level.

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
    /// The same per fold.
    pub per_fold: Vec<f64>,
}

/// Compares the lit and shadowed predictions on the shadow pixels.
pub fn evidence(views: &[ShadowView<'_>]) -> ShadowEvidence {
    let folds = views.iter().map(|v| v.fold + 1).max().unwrap_or(0);
    let mut lit = vec![0.0f64; folds];
    let mut sh = vec![0.0f64; folds];
    let mut n = 0usize;
    for v in views {
        let shadow: Vec<bool> = (0..v.w * v.h)
            .map(|i| v.mask[i] && v.shadowed[i] < 0.8 * v.lit[i])
            .collect();
        let core = erode(&shadow, v.w, v.h, 2);
        for i in (0..v.w * v.h).filter(|&i| core[i]) {
            let r = f64::from(v.real[i]);
            lit[v.fold] += (r - f64::from(v.lit[i])).powi(2);
            sh[v.fold] += (r - f64::from(v.shadowed[i])).powi(2);
            n += 1;
        }
    }
    let ratio = |l: f64, s: f64| if l > 0.0 { 1.0 - s / l } else { 0.0 };
    let (tl, ts): (f64, f64) = (lit.iter().sum(), sh.iter().sum());
    ShadowEvidence {
        pixels: n,
        mse_lit: tl / n.max(1) as f64,
        mse_shadowed: ts / n.max(1) as f64,
        explained: ratio(tl, ts),
        per_fold: lit.iter().zip(&sh).map(|(l, s)| ratio(*l, *s)).collect(),
    }
}

/// Intersection over union of the predicted and the observed shadow masks, over all views:
/// predicted where `shadowed < 0.8 lit`, observed where the real image is below
/// [`REAL_SHADOW_RATIO`] of the lit prediction (terrain only). A score of where the shadows
/// are, indifferent to how dark the prediction draws them.
pub fn overlap(views: &[ShadowView<'_>]) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for v in views {
        for i in (0..v.w * v.h).filter(|&i| v.mask[i]) {
            let predicted = v.shadowed[i] < 0.8 * v.lit[i];
            let observed = f64::from(v.real[i]) < REAL_SHADOW_RATIO * f64::from(v.lit[i]);
            inter += usize::from(predicted && observed);
            union += usize::from(predicted || observed);
        }
    }
    if union == 0 {
        0.0
    } else {
        inter as f64 / union as f64
    }
}

/// A real pixel darker than this share of the lit prediction counts as in shadow.
pub const REAL_SHADOW_RATIO: f64 = 0.65;

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
    }
}
