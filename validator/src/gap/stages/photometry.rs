//! Stage 2, photometry: `exposure`, `vignetting` and `gamma` chosen jointly on the render's
//! low-passed samples ([`crate::gap::photometry`]), with the response curve and black level the
//! repeat frames' noise shows ([`crate::gap::response`]) and the stereo overlap's witness for a
//! vignetting ([`crate::gap::overlap`]).

use std::collections::BTreeMap;

use crate::gap::context::{
    cross_validate, has, honest_std_err, jackknife, named, scored, upsert, Ctx, SIGNIFICANCE,
};
use crate::gap::select::{choose_with, subsets, Candidate};
use crate::gap::views::Prediction;
use crate::gap::{capture_exposure, consistency};
use crate::gap::{
    overlap, photometry, response, CaptureParams, Named, ScoredCandidate, TransferFit, Withheld,
};
use crate::sensor::{Effect, SensorModel, TextureTransfer};

/// Smallest held-out MSE reduction (DN², on the low-passed images of [`photometry`]) for which
/// a photometric effect is named: a 5 DN RMS change of the image. Renders of a laser DEM are
/// systematically a little darker and flatter than the real images (laser range noise roughens
/// the normals; the reflectance keeps a small range bias), which a response curve or exposure
/// reduces with nothing hidden by less than this (figures: docs/gap-findings.md, "The
/// photometric stage's floors").
const MIN_PHOTOMETRIC_DN2: f64 = 25.0;

/// The same floor for `vignetting`. The no-effect bias above is a level and contrast change,
/// which a radial falloff cannot mimic, while a weak hidden falloff lowers the held-out error
/// by less than the general floor; where a falloff is chosen with nothing hidden, its strength
/// is within its error of zero and [`SIGNIFICANCE`] keeps it from being named (figures:
/// docs/gap-findings.md, "The photometric stage's floors").
const MIN_VIGNETTING_DN2: f64 = 3.0;

/// Held-out share of the stereo overlap pairs' squared log ratio ([`overlap`]) a vignetting
/// must remove for its render-side floor ([`MIN_VIGNETTING_DN2`]) to be waived (the share of
/// the error without it, `min_share`, still applies, as do [`SIGNIFICANCE`] and
/// [`VIGNETTING_MIN_STRENGTH`]). The pairs do not see the entry's radiance errors, so the
/// share they lose to a falloff is the falloff's alone (figures: docs/gap-findings.md, "The
/// photometric stage's floors").
const MIN_OVERLAP_WITNESS: f64 = 0.3;

/// Smallest vignetting strength named: half the catalogue's lower bound (0.1, the falloff a
/// camera visibly has). A smaller fitted falloff is within a laser render's own radial level
/// error, however significant (figures: docs/gap-findings.md, "The photometric stage's
/// floors").
const VIGNETTING_MIN_STRENGTH: f64 = 0.05;

/// Smallest departure from a linear response the noise witness names, and the largest it
/// calls linear (γ within 1 ± this): over four times the largest departure it reads on linear
/// cameras (figures: docs/gap-findings.md, "The photometric stage's floors").
const MIN_CURVE: f64 = 0.05;

/// The photon-transfer witness of a run: the fit over every view, and each view's dark
/// background (the render's no-terrain pixels, eroded) for the fits of one capture.
pub(crate) struct NoiseWitness {
    pub(crate) fit: Option<response::ResponseFit>,
    pub(crate) backgrounds: Vec<Vec<bool>>,
}

impl NoiseWitness {
    /// The witness of the views under the renders `preds`.
    pub(crate) fn new(ctx: &Ctx<'_>, preds: &[Prediction]) -> NoiseWitness {
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
pub(crate) fn response_witness<B: AsRef<[bool]>>(
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

/// The closing words of an effect's evidence on its captures' agreement ([`consistency`]):
/// parameter `param`'s per-capture `values` with their `errs` (shown times `scale`), their
/// χ², degrees of freedom and p-value; empty without two captures with errors.
fn agreement(param: &str, values: &[f64], errs: &[f64], scale: f64) -> String {
    consistency::across(values, errs).map_or(String::new(), |c| {
        format!(
            "; its {param} per capture {} (χ² {:.1} on {} degrees of freedom, p = {:.2})",
            values
                .iter()
                .zip(errs)
                .map(|(v, e)| format!("{:.3} ± {:.3}", scale * v, scale * e))
                .collect::<Vec<_>>()
                .join(", "),
            c.chi2,
            c.dof,
            c.p
        )
    })
}

/// Frees the exposure gain in a final fit of `set` unless an exposure or a response curve is
/// in it. The gain is a nuisance of every final fit: the entry's albedo and shading are never
/// exactly at the camera's level, and an effect fitted without a free gain absorbs that level
/// (a darkening effect comes out too weak under a render that is too dark). Exposure is
/// written into the model only when it was chosen. Not with a response curve: over the narrow
/// intensity range of a terrain, gain and gamma trade off (a free gain moved a fitted gamma of
/// 2.0 to 2.3-2.4), while the level bias alone moves it by only ~0.05.
pub(crate) fn with_level_nuisance(set: &mut Vec<&str>) {
    if !set.contains(&"exposure") && !set.contains(&"gamma") {
        set.push("gain");
    }
}

/// The overlap pairs' witness for a vignetting: the held-out share (over capture folds) of
/// their squared log ratio that adding a vignetting removes, next to the other effects of the
/// best-scoring candidate with a vignetting and the `present` ones. `None` with fewer than two
/// folds, [`photometry::MIN_PAIRS`] pairs or no such candidate.
pub(crate) fn overlap_witness(
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

/// Stage 2: photometry (+ shadows). Updates `model`; an effect chosen but not named for a
/// reason the data gave goes to `withheld`. A chosen exposure's gain is the texture's
/// transfer ([`TransferFit`], into `texture_transfer` and the model): the exposure is named
/// only for its offset, when that is significant.
pub(crate) fn photometry_stage(
    ctx: &Ctx<'_>,
    model: &mut SensorModel,
    min_share: f64,
    noise: &NoiseWitness,
    out: &mut Vec<Named>,
    withheld: &mut Vec<Withheld>,
    texture_transfer: &mut Option<TransferFit>,
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
        .map(|(v, p)| photometry::Analysis::new(v, p, psf))
        .collect();
    let mut plain = photometry::Samples::default();
    for (k, ((v, a), f)) in ctx.views.iter().zip(&analyses).zip(&ctx.folds).enumerate() {
        plain.add((k, *f), v, a);
    }
    let poses: Vec<_> = ctx.views.iter().map(|v| model.pose(&v.at)).collect();
    let pairs = overlap::pairs(
        &ctx.views,
        &preds,
        &analyses,
        &ctx.folds,
        &poses,
        overlap::Pairing::WithinCaptures,
    );
    // The response curve the noise shows ([`response`]) decides the curve when it can: then
    // `gamma` is no candidate of the render-side choice, which is made with the curve fixed.
    let noise_curve = noise.fit.clone();
    let shows = noise_curve
        .as_ref()
        .and_then(|w| w.shows_curve(MIN_CURVE, SIGNIFICANCE));
    // An auto-exposing camera: the captures' relative gains, measured where they see the same
    // terrain ([`capture_exposure`]), under the curve and black level the noise shows. When
    // they differ, every render sample carries its capture's gain from here on, so the choice
    // below sees one exposure for all captures, as its model has.
    let first_guess = [
        1.0,
        noise_curve
            .as_ref()
            .filter(|_| shows.is_some())
            .map_or(0.0, |w| w.black_dn / 255.0),
        0.0,
        noise_curve
            .as_ref()
            .filter(|_| shows == Some(true))
            .map_or(1.0, |w| w.gamma),
    ];
    let cross = if ctx.n_folds >= 2 {
        overlap::pairs(
            &ctx.views,
            &preds,
            &analyses,
            &ctx.folds,
            &poses,
            overlap::Pairing::AcrossCaptures,
        )
    } else {
        Vec::new()
    };
    let gains = capture_exposure::measure(&pairs, &cross, ctx.n_folds, &first_guess)
        .filter(capture_exposure::CaptureGains::differ);
    if let Some(g) = &gains {
        for (r, f) in plain.radiance.iter_mut().zip(&plain.fold) {
            let l = g.log_gain.get(*f).copied().unwrap_or(0.0);
            if l.is_finite() {
                *r *= l.exp();
            }
        }
    }
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
    let fit_on =
        |s: &photometry::Samples, set: &[&str], use_fold: &(dyn Fn(usize) -> bool + Sync)| {
            let by_radiance = set.contains(&"exposure");
            photometry::refit_with_overlap(s, &pairs, set, use_fold, by_radiance)
        };
    let fit_final =
        |set: &[&str], use_fold: &(dyn Fn(usize) -> bool + Sync)| fit_on(&plain, set, use_fold);
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
            let per: Vec<(String, response::ResponseFit)> = ctx
                .fold_names()
                .into_iter()
                .enumerate()
                .filter(|_| ctx.n_folds >= 2)
                .filter_map(|(k, c)| Some((c, response_witness(ctx, &noise.backgrounds, Some(k))?)))
                .collect();
            let gammas: Vec<f64> = per.iter().map(|(_, r)| r.gamma).collect();
            let errs: Vec<f64> = per.iter().map(|(_, r)| r.gamma_se).collect();
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
                ) + &agreement("gamma", &gammas, &errs, 1.0),
            );
            n.per_capture = per
                .iter()
                .map(|(c, r)| CaptureParams::new(c, &Effect::Gamma { gamma: r.gamma }))
                .collect();
            out.push(n);
        }
    }
    let (choice, chosen, fit_set, f) = loop {
        let Some(choice) = choose_with(&allowed, min_share, &floor) else {
            if gains.is_some() {
                let at = (&pairs[..], &cross[..], &plain, &first_guess);
                name_capture_exposure(ctx, at, model, out, withheld);
            }
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
    std_err[2] = std_err[2].hypot(photometry::CALIBRATION_VIGNETTING);
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
    let fold_fits: Vec<photometry::PhotometricFit> = if ctx.n_folds >= 2 {
        (0..ctx.n_folds)
            .map(|k| fit_final(&fit_set, &|fold| fold == k))
            .collect()
    } else {
        Vec::new()
    };
    let per_fold: Vec<[f64; 4]> = fold_fits.iter().map(|f| f.params).collect();
    // Each capture's fit's standard errors: the larger of the least-squares one and the
    // jackknife over the capture's image blocks ([`photometry::BLOCKS`]), which sees how the
    // entry's errors vary over the terrain that capture shows.
    let per_fold_err: Vec<[f64; 4]> = fold_fits
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let blocks = plain.blocks_of(k);
            let jack = jackknife(blocks.len(), &|b| {
                let sub = plain.subset(&|i| plain.fold[i] == k && plain.block[i] != blocks[b]);
                fit_on(&sub, &fit_set, &|fold| fold == k).params.to_vec()
            });
            honest_std_err(f.std_err, jack)
        })
        .collect();
    // The agreement of the captures' fits of free parameter `i`, as evidence.
    let free = plain.free(&fit_set);
    let captures_agree = |i: usize, scale: f64| -> String {
        if !free.contains(&i) {
            return String::new();
        }
        let values: Vec<f64> = per_fold.iter().map(|q| q[i]).collect();
        let errs: Vec<f64> = per_fold_err.iter().map(|e| e[i]).collect();
        agreement(photometry::PARAMS[i], &values, &errs, scale)
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
    // A chosen effect with a free parameter on its fit's bound is not named either: the fit
    // pushed it past every camera of the catalogue, so it stands in for what the catalogue
    // lacks (on independently rendered lab campaigns, an exposure offset of −0.10 with a gain
    // of 1.30 where nothing was hidden: the laser texture's own radiometry and the hall's
    // interreflections). An offset held at the black level is not free.
    let base_err = cands
        .iter()
        .find(|c| c.effects.is_empty())
        .map_or(0.0, |c| c.cv_error);
    let pinned = |name: &str| -> Option<usize> {
        let idx: &[usize] = match name {
            "exposure" if plain.black.is_some() => &[0],
            "exposure" => &[0, 1],
            "vignetting" => &[2],
            "gamma" => &[3],
            _ => &[],
        };
        idx.iter().copied().find(|&i| photometry::at_bound(i, p[i]))
    };
    for name in chosen.iter().filter(|n| significant(n)) {
        if let Some(i) = pinned(name) {
            withheld.push(Withheld {
                effect: (*name).to_string(),
                stage: "photometry".to_string(),
                reason: format!(
                    "chosen (held-out photometric MSE {:.1} DN² with no effect, {:.1} DN² with \
                     the chosen set) but its {} {:.4} lies on the fit's bound, beyond any \
                     camera of the catalogue: it stands in for something the catalogue lacks \
                     (the texture's radiometry, interreflections, the BRDF)",
                    base_err,
                    allowed[choice.index].cv_error,
                    photometry::PARAMS[i],
                    p[i]
                ),
            });
        }
    }
    let significant = |name: &str| significant(name) && pinned(name).is_none();
    // A chosen exposure's gain goes to the texture's transfer; the camera keeps its offset,
    // named only when it is significant on its own.
    let level = chosen.contains(&"exposure") && significant("exposure");
    let offset_named = level
        && (p[1] - photometry::NEUTRAL[1]).abs() > SIGNIFICANCE * std_err[1].max(f64::EPSILON);
    let camera_side = |name: &str, e: Effect| -> Option<Effect> {
        match e {
            Effect::Exposure { offset, .. } if level && name == "exposure" => {
                offset_named.then_some(Effect::Exposure { gain: 1.0, offset })
            }
            e => Some(e),
        }
    };
    for name in chosen.iter().filter(|n| significant(n)).chain(&present) {
        if let Some(e) = built(name).and_then(|(e, _)| camera_side(name, e)) {
            upsert(model, e);
        }
    }
    if level {
        let stored = model.texture_transfer.map_or(1.0, |t| t.gain);
        model.texture_transfer = Some(TextureTransfer {
            gain: stored * p[0],
        });
        *texture_transfer = Some(TransferFit {
            gain: stored * p[0],
            std_err: stored * std_err[0],
            evidence: format!(
                "held-out photometric MSE {:.1} DN² with no effect, {:.1} DN² with the chosen \
                 set, whose level change has gain {:.3} ± {:.3} and offset {:.1} ± {:.1} DN; \
                 the texture's level in the camera's terms is unknown, so the gain is the \
                 entry's{}",
                base_err,
                allowed[choice.index].cv_error,
                p[0],
                std_err[0],
                255.0 * p[1],
                255.0 * std_err[1],
                if offset_named {
                    " and the offset the camera's exposure"
                } else {
                    ", and the offset is within its error of none"
                }
            ) + &captures_agree(0, stored),
            per_capture: fold_names
                .iter()
                .zip(&per_fold)
                .map(|(c, q)| CaptureParams {
                    capture: c.clone(),
                    params: BTreeMap::from([("gain".to_string(), stored * q[0])]),
                })
                .collect(),
        });
    }
    for (name, share) in choice.explained.iter().filter(|(n, _)| significant(n)) {
        if let Some((e, mut errs)) = built(name) {
            // An exposure whose gain went to the transfer and whose offset is none: not named.
            let Some(e) = camera_side(name, e) else {
                continue;
            };
            if level && *name == "exposure" {
                errs.insert("gain".to_string(), 0.0);
            }
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
                ) + &effect_at(name, &p).map_or(String::new(), |(_, idx)| {
                    idx.iter()
                        .filter(|&&i| !(level && i == 0))
                        .map(|&i| captures_agree(i, if i == 1 { 255.0 } else { 1.0 }))
                        .collect::<String>()
                }),
            );
            n.per_capture = fold_names
                .iter()
                .zip(&per_fold)
                .filter_map(|(c, q)| {
                    let e = camera_side(name, effect_at(name, q)?.0)?;
                    Some(CaptureParams::new(c, &e))
                })
                .collect();
            out.push(n);
        }
    }
    if gains.is_some() {
        name_capture_exposure(
            ctx,
            (&pairs, &cross, &plain, &first_guess),
            model,
            out,
            withheld,
        );
    }
    report(&cands)
}

/// The mean squared change, DN², that the captures' relative gains `g` make to the real DN of
/// the samples `s` (reported; not held against [`MIN_PHOTOMETRIC_DN2`], which guards against
/// the entry's own radiometric error, and that cancels in the captures' double ratio).
fn gain_change_dn2(s: &photometry::Samples, g: &capture_exposure::CaptureGains) -> f64 {
    let (sum, n) = s
        .real
        .iter()
        .zip(&s.fold)
        .filter_map(|(r, f)| {
            let l = g.log_gain.get(*f).copied().filter(|l| l.is_finite())?;
            Some((l.exp_m1() * r).powi(2))
        })
        .fold((0.0, 0usize), |(a, n), x| (a + x, n + 1));
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// Names the captures' own exposure gains measured from the `cross` and `within` pairs under
/// the response curve and exposure offset the stage left in `model` (a fitted parameter the
/// stage withheld does not enter; without them those of `first_guess`): into
/// `model.capture_exposure`, and into `exposure`'s entry in `out` (added, at gain 1 and the
/// model's offset, when the stage named no offset), its per-capture gains with their errors
/// (the image change they make over the `samples` as evidence). Withheld when, under the
/// model's final effects, the captures agree after all.
fn name_capture_exposure(
    ctx: &Ctx<'_>,
    (within, cross, samples, first_guess): (
        &[overlap::Pair],
        &[overlap::Pair],
        &photometry::Samples,
        &[f64; 4],
    ),
    model: &mut SensorModel,
    out: &mut Vec<Named>,
    withheld: &mut Vec<Withheld>,
) {
    let (mut offset, mut gamma) = (first_guess[1], first_guess[3]);
    for e in &model.effects {
        match *e {
            Effect::Exposure { offset: o, .. } => offset = o,
            Effect::Gamma { gamma: g } => gamma = g,
            _ => {}
        }
    }
    let Some(g) = capture_exposure::measure(within, cross, ctx.n_folds, &[1.0, offset, 0.0, gamma])
    else {
        return;
    };
    let names = ctx.fold_names();
    let listed: Vec<(String, f64, f64)> = names
        .iter()
        .zip(g.log_gain.iter().zip(&g.std_err))
        .filter(|(_, (l, _))| l.is_finite())
        .map(|(c, (l, e))| (c.clone(), l.exp(), l.exp() * e))
        .collect();
    let shown = listed
        .iter()
        .map(|(c, v, e)| format!("{c} {v:.3} ± {e:.3}"))
        .collect::<Vec<_>>()
        .join(", ");
    let change = gain_change_dn2(samples, &g);
    let evidence = format!(
        "the captures' relative gains where they see the same terrain ({} samples in {} ground \
         blocks; real over rendered radiance, so the entry's texture cancels): {shown}; χ² {:.1} \
         on {} degrees of freedom against one gain for all, p = {:.2e}, under the falloff the \
         pairs prefer ({:.2}); they change the images by {change:.1} DN² (mean square)",
        g.samples, g.blocks, g.chi2, g.dof, g.p, g.falloff
    );
    if !g.differ() {
        withheld.push(Withheld {
            effect: "exposure".into(),
            stage: "photometry".into(),
            reason: evidence
                + "; under the stage's final response curve and falloff they agree within \
                   their errors",
        });
        return;
    }
    model.capture_exposure = listed.iter().map(|(c, v, _)| (c.clone(), *v)).collect();
    let per_capture: Vec<CaptureParams> = listed
        .iter()
        .map(|(c, v, _)| CaptureParams {
            capture: c.clone(),
            params: BTreeMap::from([("gain".to_string(), *v)]),
        })
        .collect();
    if let Some(n) = out.iter_mut().find(|n| n.effect == "exposure") {
        n.evidence += &format!("; and {evidence}");
        n.per_capture = per_capture;
        return;
    }
    let offset = model
        .effects
        .iter()
        .find_map(|e| match e {
            Effect::Exposure { offset, .. } => Some(*offset),
            _ => None,
        })
        .unwrap_or(0.0);
    let mut n = named(
        &Effect::Exposure { gain: 1.0, offset },
        BTreeMap::from([("gain".to_string(), 0.0), ("offset".to_string(), 0.0)]),
        0.0,
        "photometry",
        format!("an exposure that differs between captures: {evidence}"),
    );
    n.per_capture = per_capture;
    out.push(n);
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
            s.block.push(0);
            pairs.push(overlap::Pair {
                fold: k % 2,
                other_fold: k % 2,
                real: [dn(rad, rho2) * (1.0 + noise), dn(rad, other)],
                render: [rad; 2],
                ground: [0.0; 2],
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
}
