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
//!
//! The test is taken under the light's direction as found, not as recorded: a lab surveys its
//! light to a few degrees, and shadows tested where a wrong light casts them are half missed.
//! So when the recorded light casts shadows the views would see, and they remove some of the
//! error there ([`MIN_EXPLAINED_AT_RECORD`]; otherwise the scene has none), its direction is
//! first searched ([`refine_direction`], within [`MAX_RECORD_ERROR_DEG`] of the record) for the
//! least mean absolute log residual near the record's shadows ([`direction_score`]: it
//! depends on where shadows fall, not on the render's level); the found direction replaces the
//! record only if it scores better in every capture fold (a lab light casts the same shadows
//! in every capture; with few shadow pixels the overall optimum can sit degrees off the true
//! light). Its standard error is the jackknife over captures and the search's calibration on
//! the laser entry ([`CALIBRATION_AZIMUTH_DEG`], [`CALIBRATION_ELEVATION_DEG`]) in quadrature.
//!
//! Through a laser entry the found elevation reads low: the entry's smoothed boulders cast
//! shorter shadows, which a lower light lengthens. The measured accuracy, on the true terrain,
//! through the laser entry and on `estec`, and the coverage of the reported errors are in
//! docs/gap-findings.md ("The shadow stage's light search").

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
/// Fewest shadow pixels (all views) for a shadow test: a light that shadows fewer of the
/// entry's pixels changes too little of any view to be told from the texture's own dark
/// patches, and its share explained is a ratio of a few pixels' errors (figures:
/// docs/gap-findings.md, "The shadow stage's light search").
pub const MIN_SHADOW_PIXELS: usize = 50;
/// Least share of the shadow pixels' error the recorded light's shadows must remove for its
/// direction to be searched at all. Where the record casts its shadows, a real shadow makes
/// the shadowed prediction right and the lit one wrong, and a shadow the scene does not have
/// the reverse, so the share is about `1 − missed / hit`: below 0 the record's shadows miss
/// more than they hit, which a light within the survey error of the true one does not do.
pub const MIN_EXPLAINED_AT_RECORD: f64 = 0.0;
/// Fewest shadow pixels for a capture to vote: a low light can shadow a few dozen pixels of
/// one capture's views and none of another's, whose share explained is then noise.
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

/// Farthest the refined light direction may move from the campaign's record, degrees per
/// axis: a lab surveys its light's direction to a few degrees (the corpus records it 2–4° off
/// in azimuth and 1–2° in elevation when it casts hidden shadows).
pub const MAX_RECORD_ERROR_DEG: f64 = 8.0;
/// RMS error of the found azimuth on the laser entry, degrees: the search's calibration, part
/// of the direction's standard error, measured on calibration seeds apart from those its
/// coverage was checked on (docs/gap-findings.md, "The shadow stage's light search").
pub const CALIBRATION_AZIMUTH_DEG: f64 = 0.65;
/// RMS error of the found elevation on the laser entry, degrees: as
/// [`CALIBRATION_AZIMUTH_DEG`] (it holds the entry's bias: the found elevation reads low).
pub const CALIBRATION_ELEVATION_DEG: f64 = 0.70;
/// Step sizes of the direction search, degrees: down to the quarter degree the score still
/// resolves on `mini`'s few hundred to few thousand shadow pixels.
const SEARCH_STEPS_DEG: [f64; 5] = [4.0, 2.0, 1.0, 0.5, 0.25];
/// Most moves per step size (bounds the renders a search costs).
const MAX_MOVES_PER_STEP: usize = 6;

/// The light direction (azimuth, elevation in degrees) minimising `cost`, by a pattern search
/// from `start`: at each step size the four neighbours (azimuth ±, elevation ±) are polled and
/// the best improving one taken, until none improves, then the step halves. The elevation stays
/// within 5–89° and each axis within [`MAX_RECORD_ERROR_DEG`] of `start`. Returns the direction
/// and its cost; `cost` is called once per distinct direction.
pub fn refine_direction(
    start: (f64, f64),
    mut cost: impl FnMut((f64, f64)) -> f64,
) -> ((f64, f64), f64) {
    let mut seen: Vec<((f64, f64), f64)> = Vec::new();
    let mut eval = |d: (f64, f64)| -> f64 {
        if let Some(&(_, c)) = seen
            .iter()
            .find(|(x, _)| (x.0 - d.0).abs() < 1e-9 && (x.1 - d.1).abs() < 1e-9)
        {
            return c;
        }
        let c = cost(d);
        seen.push((d, c));
        c
    };
    let inside = |d: (f64, f64)| {
        (d.0 - start.0).abs() <= MAX_RECORD_ERROR_DEG + 1e-9
            && (d.1 - start.1).abs() <= MAX_RECORD_ERROR_DEG + 1e-9
            && (5.0..=89.0).contains(&d.1)
    };
    let mut best = (start, eval(start));
    for step in SEARCH_STEPS_DEG {
        for _ in 0..MAX_MOVES_PER_STEP {
            let (c, _) = best;
            let mut moved = None;
            for d in [
                (c.0 - step, c.1),
                (c.0 + step, c.1),
                (c.0, c.1 - step),
                (c.0, c.1 + step),
            ] {
                if !inside(d) {
                    continue;
                }
                let e = eval(d);
                if e < moved.map_or(best.1, |(_, m)| m) {
                    moved = Some((d, e));
                }
            }
            match moved {
                Some(m) => best = m,
                None => break,
            }
        }
    }
    best
}

/// `ln((real + 1) / (prediction + 1))` at pixel `i` of `v`.
fn log_ratio(v: &ShadowView<'_>, i: usize) -> f64 {
    ((f64::from(v.real[i]) + 1.0) / (f64::from(v.shadowed[i]) + 1.0)).ln()
}

/// [`log_ratio`] of every terrain pixel of every view.
fn log_ratios<'a>(views: &'a [ShadowView<'a>]) -> impl Iterator<Item = f64> + 'a {
    views.iter().flat_map(|v| {
        (0..v.w * v.h)
            .filter(|&i| v.mask[i])
            .map(|i| log_ratio(v, i))
    })
}

/// How far around the campaign record's cast shadows the direction search scores, pixels:
/// where the shadows of lights up to [`MAX_RECORD_ERROR_DEG`] off move to on `mini` (a 5 cm
/// boulder's shadow under a 20° light moves about 2.5 px per degree of elevation).
pub const NEAR_SHADOW_PX: usize = 20;

/// Per view, the terrain within [`NEAR_SHADOW_PX`] of where its shadowed prediction casts a
/// shadow (drawn at least 20 % darker than the lit one): the pixels the direction search
/// scores, fixed for every candidate.
pub fn near_shadows(views: &[ShadowView<'_>]) -> Vec<Vec<bool>> {
    views
        .iter()
        .map(|v| {
            let open: Vec<bool> = (0..v.w * v.h)
                .map(|i| !(v.mask[i] && v.shadowed[i] < 0.8 * v.lit[i]))
                .collect();
            erode(&open, v.w, v.h, NEAR_SHADOW_PX)
                .iter()
                .zip(v.mask)
                .map(|(&far, &m)| m && !far)
                .collect()
        })
        .collect()
}

/// The score the light direction search minimises: the mean absolute log residual
/// ([`log_residual`]) over the `near` pixels ([`near_shadows`]), after each candidate's own
/// level over the whole terrain ([`log_level`]). The level follows the candidate because a
/// light's elevation sets the level of all it lights (the direct share goes as the sine of the
/// elevation: 9 % brighter from 17.3° to 19°), and a level held at the record's holds the
/// search near the record. The score stays near the shadows because over the whole terrain
/// the entry's texture errors outweigh them. (The alternatives tried and their figures:
/// docs/gap-findings.md, "The shadow stage's light search".)
pub fn direction_score(views: &[ShadowView<'_>], near: &[&[bool]]) -> f64 {
    let level = log_level(views);
    let (sum, n) = views
        .iter()
        .zip(near)
        .flat_map(|(v, near)| (0..v.w * v.h).filter(|&i| near[i]).map(|i| log_ratio(v, i)))
        .fold((0.0, 0usize), |(s, n), r| (s + (r - level).abs(), n + 1));
    if n == 0 {
        f64::INFINITY
    } else {
        sum / n as f64
    }
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
/// terrain, after removing `level`. In the log domain a texture error scales the lit and the
/// shadowed prediction alike.
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

    /// A `w x h` image at `level` times 35 left of column `edge` (in shadow) and 100 beyond.
    fn edge_image(w: usize, h: usize, edge: usize, level: f32) -> Vec<f32> {
        (0..w * h)
            .map(|i| level * if (i % w) < edge { 35.0 } else { 100.0 })
            .collect()
    }

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
    fn the_direction_search_finds_the_minimum_within_the_survey_error_and_no_farther() {
        let bowl = |centre: (f64, f64)| {
            move |d: (f64, f64)| (d.0 - centre.0).powi(2) + 2.0 * (d.1 - centre.1).powi(2)
        };
        let start = (358.0, 20.0);
        let (d, c) = refine_direction(start, bowl((361.3, 18.4)));
        assert!(
            (d.0 - 361.3).abs() <= 0.125 && (d.1 - 18.4).abs() <= 0.125,
            "{d:?}"
        );
        assert!(c < 0.05, "{c}");
        // A minimum beyond the survey's error: the search stops at its bound.
        let (d, _) = refine_direction(start, bowl((330.0, 20.0)));
        assert!(
            (d.0 - (start.0 - MAX_RECORD_ERROR_DEG)).abs() < 1e-9,
            "{d:?}"
        );
        // Never below 5° of elevation.
        let (d, _) = refine_direction((10.0, 7.0), bowl((10.0, -3.0)));
        assert!(d.1 >= 5.0, "{d:?}");
        // One call per distinct direction.
        let mut calls: Vec<(f64, f64)> = Vec::new();
        refine_direction(start, |d| {
            calls.push(d);
            bowl((356.0, 21.0))(d)
        });
        let n = calls.len();
        calls.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        calls.dedup();
        assert_eq!(calls.len(), n);
        // Already at the minimum: it stays.
        assert_eq!(refine_direction(start, bowl(start)).0, start);
    }

    #[test]
    fn the_direction_score_is_taken_near_the_shadows_after_each_candidates_level() {
        let (w, h) = (80, 40);
        let mask = vec![true; w * h];
        let image = |edge: usize, level: f32| edge_image(w, h, edge, level);
        let real = image(20, 1.0);
        let lit = image(0, 1.0);
        let view = |shadowed: &'static [f32]| ShadowView {
            real: &real,
            lit: &lit,
            shadowed,
            mask: &mask,
            w,
            h,
            fold: 0,
        };
        let leak = |v: Vec<f32>| -> &'static [f32] { Box::leak(v.into_boxed_slice()) };
        let record = [view(leak(image(18, 1.0)))];
        let near = near_shadows(&record);
        // Within NEAR_SHADOW_PX of the record's shadow (columns 0..18), not beyond.
        assert!(near[0][17 + NEAR_SHADOW_PX] && !near[0][18 + NEAR_SHADOW_PX]);
        let near: Vec<&[bool]> = near.iter().map(Vec::as_slice).collect();
        let score =
            |edge: usize, level: f32| direction_score(&[view(leak(image(edge, level)))], &near);
        // A brighter candidate is scored on its shadows, not on its level.
        assert!(score(20, 1.3) < 0.005 && score(20, 1.3) < 0.2 * score(19, 1.0));
        assert!(score(19, 1.0) < score(18, 1.0) && score(21, 1.0) < score(23, 1.0));
    }

    #[test]
    fn the_log_residual_ignores_the_level_and_sees_where_shadows_fall() {
        let (w, h) = (40, 40);
        let mask = vec![true; w * h];
        let shadow_at = |edge: usize, level: f32| edge_image(w, h, edge, level);
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
