//! The noise stage: shot and read noise from the repeat frames, on the linear signal where the
//! photon-transfer fit over the dark background has it ([`crate::gap::response`]).

use std::collections::BTreeMap;

use super::photometry::NoiseWitness;
use crate::gap::context::{has, named, upsert, Ctx};
use crate::gap::views::Prediction;
use crate::gap::{noise, Named};
use crate::sensor::{Effect, SensorModel};

/// Stage 3: noise from the repeat frames. Updates `model`.
pub(crate) fn noise_stage(
    ctx: &Ctx<'_>,
    preds: &[Prediction],
    model: &mut SensorModel,
    witness: &NoiseWitness,
    out: &mut Vec<Named>,
) {
    if has(model, "noise") {
        return;
    }
    let pairs: Vec<(&[f32], &[f32], &[bool])> = ctx
        .views
        .iter()
        .zip(preds)
        .filter(|(v, _)| v.frames.len() >= 2)
        .map(|(v, p)| {
            (
                v.frames[0].as_slice(),
                v.frames[1].as_slice(),
                p.mask.as_slice(),
            )
        })
        .collect();
    let Some(fit) = noise::measure(&pairs) else {
        return;
    };
    // The sensor's noise is on the linear signal, before the response curve: the photon
    // transfer fit over the dark background ([`response`]) has it there; the level fit of
    // `noise::measure` only without a curve.
    let linear = &witness.fit;
    let sigma_at_128 = linear
        .as_ref()
        .map_or(fit.sigma_at_128, |w| w.sigma_at(128.0));
    if sigma_at_128 <= noise::NOISE_FLOOR_DN {
        return;
    }
    let e = linear.as_ref().map_or(
        Effect::Noise {
            gain: fit.gain,
            read_sigma: fit.read_sigma,
        },
        |w| Effect::Noise {
            gain: w.shot_gain,
            read_sigma: w.read_sigma,
        },
    );
    upsert(model, e);
    let share = 1.0 - (noise::NOISE_FLOOR_DN / sigma_at_128).powi(2);
    out.push(named(
        &e,
        BTreeMap::new(),
        share,
        "noise",
        format!(
            "repeat frames: noise σ {:.2} DN at DN 128 > nominal {:.1} DN{}",
            sigma_at_128,
            noise::NOISE_FLOOR_DN,
            if linear.is_some() {
                " (photon transfer with the dark background: shot and read noise of the linear signal)"
            } else {
                ""
            }
        ),
    ));
}
