//! Hidden effects: which ones, with which parameters, and the baseline every real image has.
//!
//! The catalogue, parameter names and plausible ranges are `regolith_format::effects`' (the
//! words shared with the gap workflow, so the generator cannot hide something the fit cannot
//! name); how an effect acts on the data is this crate's own ([`Hidden`] for geometry and
//! texture, [`crate::camera`] for the images), never the validator's.
//! Each requested effect gets its parameters drawn from its range with the stage RNG
//! `hidden.<name>`, then the user's `--effect-param E.name=value` overrides are applied.
//! `shadows` is special: the lab light is the one casting the shadows, so the generator moves
//! the lab light (and `[lighting]`) to the hidden effect's direction — drawn from the documented
//! range (elevation 15–30°) like any effect's parameters, or given by the user — and shading and
//! shadows share one light. (The campaign's own light is drawn at 45–70°, where a `mini`
//! terrain casts no shadow its cameras see, so a hidden `shadows` taking that light changed
//! nothing in the images.) The campaign file then records that light as a lab surveys it,
//! not exactly: [`recorded_light`] is off the true direction by 2–4° in azimuth and 1–2° in
//! elevation, so the light direction is a parameter the gap workflow must find, not one it is
//! given (`truth/lighting.json` and `truth/hidden.json` hold the true light).
//!
//! Independently of the hidden list, every real image gets a mild *baseline* sensor noise
//! (gain 0.05 DN/DN, read σ 0.8 DN) so that the two frames of a pose differ and real-vs-real
//! repeatability is measurable; a hidden `noise` replaces it. The baseline is recorded in
//! `truth/hidden.json` next to the hidden effects.

use std::collections::BTreeMap;

use rand::Rng;
use regolith_format::camera_model::CameraModel;
use regolith_format::effects::{Effect, ParamRange};
use regolith_format::frames::{quat_from_axis_angle, Pose};
use regolith_format::grid::AlbedoGrid;
use regolith_format::lighting::Light;

use crate::seeding::stage_rng;
use crate::CorpusError;

/// A requested hidden effect with parameter overrides.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HiddenSpec {
    /// Catalogue name (`vignetting`, `pose-bias`...).
    pub name: String,
    /// Parameter overrides (`strength` → 0.3; `translation_m.x` → 0.01).
    pub params: BTreeMap<String, f64>,
}

impl HiddenSpec {
    /// An effect with drawn defaults.
    pub fn named(name: &str) -> HiddenSpec {
        HiddenSpec {
            name: name.to_string(),
            params: BTreeMap::new(),
        }
    }
}

/// Parses `E[,E...]` (the `--hidden-effect` list).
pub fn parse_list(list: &str) -> Result<Vec<HiddenSpec>, CorpusError> {
    let mut out: Vec<HiddenSpec> = Vec::new();
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        check_name(name)?;
        if !out.iter().any(|h| h.name == name) {
            out.push(HiddenSpec::named(name));
        }
    }
    Ok(out)
}

/// Applies one `E.param=value` override (`--effect-param`) to `specs`.
pub fn apply_param(specs: &mut [HiddenSpec], arg: &str) -> Result<(), CorpusError> {
    let bad = |expected: &str| CorpusError::Option {
        option: "--effect-param",
        expected: expected.to_string(),
        found: arg.to_string(),
    };
    let (lhs, value) = arg.split_once('=').ok_or_else(|| bad("E.name=value"))?;
    let (effect, param) = lhs
        .trim()
        .split_once('.')
        .ok_or_else(|| bad("E.name=value"))?;
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|_| bad("a number after '='"))?;
    let ranges = check_name(effect)?;
    if !ranges.iter().any(|r| r.name == param) {
        let names: Vec<&str> = ranges.iter().map(|r| r.name).collect();
        return Err(bad(&format!(
            "one of the parameters of {effect}: {}",
            names.join(", ")
        )));
    }
    let spec = specs.iter_mut().find(|s| s.name == effect).ok_or_else(|| {
        bad(&format!(
            "an effect listed in --hidden-effect (not {effect})"
        ))
    })?;
    spec.params.insert(param.to_string(), value);
    Ok(())
}

fn check_name(name: &str) -> Result<&'static [ParamRange], CorpusError> {
    Effect::default_range(name).ok_or_else(|| CorpusError::Option {
        option: "--hidden-effect",
        expected: format!("one of {}", Effect::NAMES.join(", ")),
        found: name.to_string(),
    })
}

/// The hidden effects of a campaign, and what they do to its geometry and texture.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Hidden {
    /// The effects, in the order requested.
    pub effects: Vec<Effect>,
    /// Spread of an auto-exposing camera (0: the same exposure at every capture): each capture
    /// location's exposure gain is the hidden exposure's (or 1) times `e^u`
    /// ([`Hidden::capture_gain`]).
    pub auto_exposure: f64,
}

impl Hidden {
    /// The exposure gain factor `e^u` of the capture location drawn `index`-th (1 without an
    /// auto-exposure): `|u|` uniform in `[spread/2, spread]` (stage RNG
    /// `hidden.auto-exposure.<index>`), its sign alternating from one location to the next
    /// from a sign drawn for the campaign (stage RNG `hidden.auto-exposure`) — a camera that
    /// exposes each view for its own brightness, brighter and darker by turns, so that every
    /// two neighbouring locations differ by at least the spread.
    pub fn capture_gain(&self, seed: u64, index: usize) -> f64 {
        let s = self.auto_exposure;
        if s <= 0.0 || !s.is_finite() {
            return 1.0;
        }
        let first: bool = stage_rng(seed, "hidden.auto-exposure").gen();
        let magnitude =
            stage_rng(seed, &format!("hidden.auto-exposure.{index}")).gen_range(0.5 * s..=s);
        let up = first == index.is_multiple_of(2);
        (if up { magnitude } else { -magnitude }).exp()
    }

    /// The true camera: `base` with every `distortion` added to its `k1`, `k2`.
    pub fn camera(&self, base: &CameraModel) -> CameraModel {
        let mut cam = base.clone();
        for e in &self.effects {
            if let Effect::Distortion { dk1, dk2 } = e {
                cam.distortion.k1 += dk1;
                cam.distortion.k2 += dk2;
            }
        }
        cam
    }

    /// The true pose of the rig's reference (left) camera whose Vicon pose is
    /// `ground_from_rig`: every `pose-bias` `B` (true rig in calibrated-rig coordinates,
    /// rotations applied x, then y, then z) composed on the right, as the registry defines it.
    pub fn rig_pose(&self, ground_from_rig: Pose) -> Pose {
        let mut bias = Pose::IDENTITY;
        for e in &self.effects {
            if let Effect::PoseBias {
                translation_m,
                rotation_deg,
            } = e
            {
                let [rx, ry, rz] = rotation_deg.map(f64::to_radians);
                let about = |axis: [f64; 3], a: f64| Pose {
                    translation_m: [0.0; 3],
                    rotation_xyzw: quat_from_axis_angle(axis, a),
                };
                let rot = about([0.0, 0.0, 1.0], rz)
                    .compose(&about([0.0, 1.0, 0.0], ry))
                    .compose(&about([1.0, 0.0, 0.0], rx));
                bias = bias.compose(&Pose {
                    translation_m: *translation_m,
                    rotation_xyzw: rot.rotation_xyzw,
                });
            }
        }
        ground_from_rig
            .compose(&Pose::IDENTITY.inverse())
            .compose(&bias)
            .compose(&Pose::IDENTITY)
    }

    /// The albedo an entry's texture is made from: `grid` low-passed by every
    /// `texture-lowpass` (its `sigma_m` in cells of the grid).
    pub fn albedo(&self, grid: &AlbedoGrid) -> AlbedoGrid {
        let mut out = grid.clone();
        for e in &self.effects {
            if let Effect::TextureLowpass { sigma_m } = e {
                if grid.cell_m > 0.0 {
                    out.value = crate::terrain::gaussian_blur(
                        &out.value,
                        out.width,
                        out.height,
                        sigma_m / grid.cell_m,
                    );
                }
            }
        }
        out
    }

    /// The light casting hidden shadows, if any (the last `shadows` wins).
    pub fn shadow_light(&self) -> Option<(f64, f64)> {
        self.effects.iter().rev().find_map(|e| match *e {
            Effect::Shadows {
                azimuth_deg,
                elevation_deg,
            } => Some((azimuth_deg, elevation_deg)),
            _ => None,
        })
    }
}

/// Draws the hidden model: defaults from the seed, then overrides.
pub fn resolve(specs: &[HiddenSpec], seed: u64) -> Result<Hidden, CorpusError> {
    let mut effects = Vec::new();
    for spec in specs {
        check_name(&spec.name)?;
        let mut rng = stage_rng(seed, &format!("hidden.{}", spec.name));
        let drawn = Effect::sample(&spec.name, |a, b| rng.gen_range(a..=b)).ok_or_else(|| {
            CorpusError::Option {
                option: "--hidden-effect",
                expected: "a catalogue effect".into(),
                found: spec.name.clone(),
            }
        })?;
        let mut values: BTreeMap<&str, f64> = BTreeMap::new();
        for (k, v) in &spec.params {
            values.insert(k.as_str(), *v);
        }
        effects.push(drawn.with_params(&values));
    }
    Ok(Hidden {
        effects,
        auto_exposure: 0.0,
    })
}

/// The baseline noise of every real image.
pub const BASELINE_NOISE: Effect = Effect::Noise {
    gain: 0.05,
    read_sigma: 0.8,
};

/// The model the real images are made with: the hidden effects plus the baseline noise
/// unless a hidden `noise` replaces it.
pub fn real_model(hidden: &Hidden) -> Vec<Effect> {
    let mut effects = hidden.effects.clone();
    if !effects.iter().any(|e| matches!(e, Effect::Noise { .. })) {
        effects.push(BASELINE_NOISE);
    }
    effects
}

/// Azimuth error of a surveyed light that casts hidden shadows, degrees (either sign).
pub const RECORD_AZIMUTH_ERROR_DEG: std::ops::Range<f64> = 2.0..4.0;
/// Elevation error of a surveyed light that casts hidden shadows, degrees (either sign).
pub const RECORD_ELEVATION_ERROR_DEG: std::ops::Range<f64> = 1.0..2.0;

/// The light the campaign file records: `light` itself, or, when hidden `shadows` cast by it
/// must be found, `light` off by a drawn survey error ([`RECORD_AZIMUTH_ERROR_DEG`],
/// [`RECORD_ELEVATION_ERROR_DEG`], random signs, stage RNG `lighting.record`; rounded to
/// 0.1° like the light itself). The ambient share is recorded as it is.
pub fn recorded_light(light: &Light, hidden: &Hidden, seed: u64) -> Light {
    if hidden.shadow_light().is_none() {
        return *light;
    }
    let mut rng = stage_rng(seed, "lighting.record");
    let mut off = |range: std::ops::Range<f64>| {
        let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        sign * rng.gen_range(range)
    };
    let (daz, del) = (
        off(RECORD_AZIMUTH_ERROR_DEG),
        off(RECORD_ELEVATION_ERROR_DEG),
    );
    let round = |v: f64| (v * 10.0).round() / 10.0;
    Light {
        azimuth_deg: round((light.azimuth_deg + daz).rem_euclid(360.0)),
        elevation_deg: round((light.elevation_deg + del).clamp(1.0, 89.0)),
        ambient: light.ambient,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_win_and_defaults_are_in_range() {
        let mut specs = parse_list("vignetting,pose-bias,shadows").unwrap();
        apply_param(&mut specs, "vignetting.strength=0.3").unwrap();
        apply_param(&mut specs, "pose-bias.translation_m.x=0.01").unwrap();
        apply_param(&mut specs, "shadows.azimuth_deg=210").unwrap();
        let m = resolve(&specs, 5).unwrap();
        assert_eq!(m.effects[0], Effect::Vignetting { strength: 0.3 });
        match m.effects[1] {
            Effect::PoseBias {
                translation_m,
                rotation_deg,
            } => {
                assert_eq!(translation_m[0], 0.01);
                assert!(rotation_deg.iter().all(|r| r.abs() <= 0.5));
            }
            e => panic!("{e:?}"),
        }
        // The shadows' light: the azimuth given, the elevation drawn in the documented range.
        match m.effects[2] {
            Effect::Shadows {
                azimuth_deg,
                elevation_deg,
            } => {
                assert_eq!(azimuth_deg, 210.0);
                assert!((15.0..=30.0).contains(&elevation_deg), "{elevation_deg}");
            }
            e => panic!("{e:?}"),
        }
        assert_eq!(resolve(&specs, 5).unwrap(), m, "same seed, same draw");
    }

    #[test]
    fn a_shadow_casting_light_is_recorded_off_by_a_survey_error_and_others_exactly() {
        let light = Light {
            azimuth_deg: 359.0,
            elevation_deg: 20.0,
            ambient: 0.3,
        };
        let plain = resolve(&parse_list("vignetting").unwrap(), 7).unwrap();
        assert_eq!(recorded_light(&light, &plain, 7), light);
        let shadows = resolve(&parse_list("shadows").unwrap(), 7).unwrap();
        for seed in 0..40 {
            let r = recorded_light(&light, &shadows, seed);
            let daz = (r.azimuth_deg - light.azimuth_deg + 540.0).rem_euclid(360.0) - 180.0;
            let del = r.elevation_deg - light.elevation_deg;
            assert!((0.0..360.0).contains(&r.azimuth_deg), "{r:?}");
            assert!((1.95..=4.05).contains(&daz.abs()), "seed {seed}: {daz}");
            assert!((0.95..=2.05).contains(&del.abs()), "seed {seed}: {del}");
            assert_eq!(r.ambient, light.ambient);
            assert_eq!(recorded_light(&light, &shadows, seed), r, "deterministic");
        }
    }

    #[test]
    fn bad_names_are_rejected_with_the_catalogue() {
        let e = parse_list("vignetting,sparkle").unwrap_err().to_string();
        assert!(
            e.contains("sparkle") && e.contains("texture-lowpass"),
            "{e}"
        );
        let mut specs = parse_list("blur").unwrap();
        assert!(apply_param(&mut specs, "blur.radius=2")
            .unwrap_err()
            .to_string()
            .contains("sigma_px"));
        assert!(apply_param(&mut specs, "gamma.gamma=2").is_err());
        assert!(apply_param(&mut specs, "blur.sigma_px=abc").is_err());
    }

    #[test]
    fn baseline_noise_only_without_hidden_noise() {
        let plain = real_model(&Hidden::default());
        assert_eq!(plain, vec![BASELINE_NOISE]);
        let noisy = Hidden {
            effects: vec![Effect::Noise {
                gain: 0.3,
                read_sigma: 2.0,
            }],
            ..Hidden::default()
        };
        assert_eq!(real_model(&noisy).len(), 1);
    }
}
