//! The one-sample renders the first step shades from every view's traced camera rays — lit by
//! the campaign light, in its cast shadow, and under the texture measure's uniform albedo —
//! kept for the stages after the geometric one.
//!
//! Why: the blur stage renders every view at one sample a pixel, the shadows stage first tests
//! the recorded light on every view lit and shadowed, and the texture stage renders every view
//! under the uniform albedo. While the model's camera rays (its distortion and pose bias) and
//! its light (a `shadows` effect) are those of the first step's model — nothing geometric and
//! no shadows named, the usual case — these are the first step's renders, and each stage traced
//! every view again for them (estec, 16 views of 1280 × 1024: some 3 s a stage).
//!
//! Kept as plain radiance (before the texture's transfer and the image effects, which the
//! stages between change), with the one depth and mask per view that the three share: 17 bytes
//! a pixel (estec: 0.36 GB).

use super::views::{GapView, Prediction};
use crate::render::Rendered;
use crate::sensor::{Effect, SensorModel};

/// Which of the kept shadings a stage asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Shading {
    /// Lit by the campaign light, no cast shadows.
    Lit,
    /// Lit by the campaign light with its cast shadows (a `shadows` effect in its direction).
    Shadowed,
    /// The first step's model's shading under the uniform albedo of the texture measure.
    Flat,
}

/// One view's kept renders.
struct KeptView {
    width: usize,
    height: usize,
    lit: Vec<f32>,
    shadowed: Vec<f32>,
    flat: Option<Vec<f32>>,
    depth: Vec<f32>,
    mask: Vec<u8>,
}

/// The kept one-sample renders of every view (see the module docs).
pub(crate) struct OneSample {
    /// The camera rays' effects of the model they were traced for ([`SensorModel::ray_effects`]).
    rays: Vec<Effect>,
    /// The shadowed renders' `shadows` effect (the campaign light's direction).
    record: Effect,
    /// The flat renders' model's `shadows` effect, if any, and their uniform albedo.
    flat: (Option<Effect>, Option<f32>),
    views: Vec<KeptView>,
}

impl OneSample {
    /// Empty, for renders traced through `model` (whose `shadows` effect the flat renders
    /// carry) with the campaign light's direction `record` and the flat renders' `albedo`.
    pub(crate) fn new(model: &SensorModel, record: Effect, albedo: Option<f32>) -> OneSample {
        OneSample {
            rays: model.ray_effects(),
            record,
            flat: (model.shadows_effect(), albedo),
            views: Vec::new(),
        }
    }

    /// Keeps the next view's plain renders, lit and shadowed (and flat): all from the same
    /// rays, so they share the lit one's depth and mask.
    pub(crate) fn push(&mut self, lit: &Rendered, shadowed: &Rendered, flat: Option<&Rendered>) {
        self.views.push(KeptView {
            width: lit.width,
            height: lit.height,
            lit: lit.radiance.clone(),
            shadowed: shadowed.radiance.clone(),
            flat: flat.map(|f| f.radiance.clone()),
            depth: lit.depth.clone(),
            mask: lit.mask.clone(),
        });
    }

    /// Whether `model` traces the kept rays and casts the shadows of `shading`.
    fn serves(&self, model: &SensorModel, shading: Shading) -> bool {
        model.ray_effects() == self.rays
            && match shading {
                Shading::Lit => model.shadows_effect().is_none(),
                Shading::Shadowed => model.shadows_effect() == Some(self.record),
                Shading::Flat => self.flat.1.is_some() && model.shadows_effect() == self.flat.0,
            }
    }

    /// `model`'s one-sample renders of `views` under `shading`, finished through its texture
    /// transfer and image effects (no noise): the bytes of its renders, when it traces the
    /// kept rays and casts their shadows; `None` otherwise.
    pub(crate) fn renders(
        &self,
        model: &SensorModel,
        shading: Shading,
        views: &[GapView],
    ) -> Option<Vec<Prediction>> {
        if !self.serves(model, shading) || self.views.len() != views.len() {
            return None;
        }
        views
            .iter()
            .zip(&self.views)
            .map(|(v, k)| {
                let radiance = match shading {
                    Shading::Lit => k.lit.clone(),
                    Shading::Shadowed => k.shadowed.clone(),
                    Shading::Flat => k.flat.clone()?,
                };
                let rendered = Rendered {
                    width: k.width,
                    height: k.height,
                    radiance,
                    depth: k.depth.clone(),
                    mask: k.mask.clone(),
                };
                Some(Prediction::from(model.finish_rendered(
                    rendered,
                    &v.camera_model,
                    None,
                )))
            })
            .collect()
    }

    /// The uniform albedo of the kept flat renders.
    pub(crate) fn flat_albedo(&self) -> Option<f32> {
        self.flat.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Sampling;
    use crate::render::{AlbedoGrid, Geometry, HeightGrid, Light, Scene, View};
    use crate::sensor::Placement;
    use regolith_format::camera_model::CameraModel;

    /// A bumpy 4 m square seen obliquely by one 160 × 120 camera, and its view.
    fn scene_and_view() -> (Geometry, GapView) {
        let n = 81;
        let z = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f32 * 0.05, (i / n) as f32 * 0.05);
                0.15 * (x * 3.1).sin() * (y * 2.3).cos()
            })
            .collect();
        let value = (0..n * n)
            .map(|i| 0.3 + 0.2 * ((i * 7919 % 97) as f32 / 97.0))
            .collect();
        let geometry = Geometry::Heightfield {
            grid: HeightGrid {
                origin_m: [0.0, 0.0],
                cell_m: 0.05,
                width: n,
                height: n,
                z,
            },
            albedo: AlbedoGrid {
                origin_m: [0.0, 0.0],
                cell_m: 0.05,
                width: n,
                height: n,
                value,
            },
        };
        let camera = CameraModel::pinhole(160, 120, 150.0, 150.0, 79.5, 59.5);
        let look = View::look_at(camera.clone(), [2.0, 1.5, 2.5], [2.0, -2.0, 0.0]);
        let view = GapView {
            capture: "c".into(),
            camera: "cam".into(),
            camera_model: camera,
            at: Placement::lone(look.ground_from_camera),
            width: 160,
            height: 120,
            frames: vec![vec![0.0; 160 * 120]],
        };
        (geometry, view)
    }

    fn bits(p: &Prediction) -> (Vec<u32>, Vec<u32>, Vec<bool>) {
        (
            p.dn.iter().map(|v| v.to_bits()).collect(),
            p.depth.iter().map(|v| v.to_bits()).collect(),
            p.mask.clone(),
        )
    }

    /// Kept renders finished through a model that differs only in image effects and the
    /// texture's transfer give the bytes of that model's own one-sample renders; a model
    /// whose rays or shadows differ is not served.
    #[test]
    fn kept_renders_are_the_models_renders_or_none() {
        let (geometry, v) = scene_and_view();
        let scene = Scene::new(&geometry);
        let light = Light {
            azimuth_deg: 210.0,
            elevation_deg: 12.0,
            ambient: 0.2,
        };
        let record = Effect::Shadows {
            azimuth_deg: 210.0,
            elevation_deg: 12.0,
        };
        let first = SensorModel::from(vec![Effect::Distortion {
            dk1: -0.02,
            dk2: 0.0,
        }]);
        let mut shadowed = first.clone();
        shadowed.effects.push(record);
        let hits = first.primary_hits(&scene, &v.camera_model, &v.at, 1);
        let albedo = 0.4;
        let mut kept = OneSample::new(&first, record, Some(albedo));
        kept.push(
            &first.relight_radiance(&scene, &hits, &light),
            &shadowed.relight_radiance(&scene, &hits, &light),
            Some(&first.relight_radiance(&scene, &hits.with_geometry_albedo(albedo), &light)),
        );
        // A later model: the same rays, image effects and a texture transfer added.
        let mut later = first.clone();
        later.effects.push(Effect::Vignetting { strength: 0.3 });
        later.effects.push(Effect::Gamma { gamma: 1.2 });
        later.texture_transfer = Some(crate::sensor::TextureTransfer { gain: 1.3 });
        let fresh = |m: &SensorModel| {
            Prediction::from(m.render(
                &scene,
                &light,
                &v.camera_model,
                &v.at,
                Sampling::Edges(1),
                None,
            ))
        };
        let views = std::slice::from_ref(&v);
        let lit = kept.renders(&later, Shading::Lit, views);
        assert_eq!(lit.map(|p| bits(&p[0])), Some(bits(&fresh(&later))));
        let mut later_shadowed = later.clone();
        later_shadowed.effects.push(record);
        let s = kept.renders(&later_shadowed, Shading::Shadowed, views);
        assert_eq!(s.map(|p| bits(&p[0])), Some(bits(&fresh(&later_shadowed))));
        assert_ne!(
            bits(&fresh(&later_shadowed)),
            bits(&fresh(&later)),
            "the shadows must show"
        );
        let flat = kept.renders(&later, Shading::Flat, views);
        let flat_fresh = Prediction::from(later.relight(
            &scene,
            &hits.with_geometry_albedo(albedo),
            &light,
            &v.camera_model,
            None,
        ));
        assert_eq!(flat.map(|p| bits(&p[0])), Some(bits(&flat_fresh)));
        assert_eq!(kept.flat_albedo(), Some(albedo));
        // Other rays, other shadows: not served.
        let mut moved = later.clone();
        moved.effects.push(Effect::PoseBias {
            translation_m: [0.0; 3],
            rotation_deg: [0.1, 0.0, 0.0],
        });
        assert!(kept.renders(&moved, Shading::Lit, views).is_none());
        assert!(kept.renders(&later_shadowed, Shading::Lit, views).is_none());
        assert!(kept.renders(&later, Shading::Shadowed, views).is_none());
        let mut elsewhere = later.clone();
        elsewhere.effects.push(Effect::Shadows {
            azimuth_deg: 100.0,
            elevation_deg: 30.0,
        });
        assert!(kept.renders(&elsewhere, Shading::Shadowed, views).is_none());
    }
}
