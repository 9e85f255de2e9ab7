//! # regolith-model-captures
//!
//! A [`CaptureRenderer`] for the corpus generator that makes the "real" NavCam frames with the
//! validator's own ray caster, shading and sensor model — the very forward model `validate`
//! re-renders with and `gap` fits. A residual between such a frame and a validator render is,
//! by construction, a catalogue effect or an error of the entry's heights: testing the
//! validator on these frames is the "inverse crime" of inverse problems. They exist because
//! they are fast and exact, which is what unit tests of the fitting code need (does the fit
//! find a parameter the model can express?); no figure about how `gap` or `validate` fare on
//! real captures may come from them. Campaigns made this way say so in `truth/renderer.json`
//! (`"name": "validator-model"`, `"independent_of_validator": false`).
//!
//! It lives in its own crate because the corpus must not depend on the validator (the
//! layering test forbids the edge); the frames are the corpus's first format (corpus v1):
//! point-sampled true albedo, cast shadows only when `shadows` is hidden, the image effects
//! and baseline noise of the validator's `SensorModel`.

use regolith_corpus::captures::{CaptureRenderer, CaptureScene, RendererInfo, Shot};
use regolith_corpus::terrain::materials::MARKER_ALBEDO;
use regolith_corpus::CorpusError;
use regolith_validator::render::{Geometry, RenderOptions, Scene, Sphere, View};
use regolith_validator::sensor::{quantise_u8, SensorModel};

/// The validator's forward model as a capture renderer (see the crate docs).
#[derive(Debug, Clone, Copy, Default)]
pub struct ModelCaptures;

impl CaptureRenderer for ModelCaptures {
    fn frames(
        &self,
        scene: &CaptureScene<'_>,
        shots: &[Shot],
        progress: &dyn Fn(f64),
    ) -> Result<Vec<[Vec<u8>; 2]>, CorpusError> {
        let geometry = Geometry::Heightfield {
            grid: scene.terrain.height.clone(),
            albedo: scene.terrain.albedo.clone(),
        };
        // The balls are exact spheres in the captures (their caps in the grid lie inside them).
        let balls = scene
            .terrain
            .markers
            .iter()
            .map(|m| Sphere {
                centre: m.centre_m,
                radius: m.radius_m,
                albedo: MARKER_ALBEDO as f32,
            })
            .collect();
        let render_scene = Scene::new(&geometry).with_spheres(balls);
        let model = SensorModel::from(scene.effects.to_vec());
        let (opts, _) = model.render_options(&RenderOptions {
            distort: true,
            shadows: false,
            supersample: scene.cfg.supersample,
            // Point-sampled true albedo: the corpus v1 camera.
            filter_textures: false,
            adaptive: false,
        });
        let mut out = Vec::with_capacity(shots.len());
        for (i, shot) in shots.iter().enumerate() {
            progress(i as f64 / shots.len().max(1) as f64);
            let mut r = render_scene.render(
                &scene.light,
                &View {
                    camera: shot.camera.clone(),
                    ground_from_camera: shot.ground_from_camera,
                },
                &opts,
            );
            if shot.exposure_gain != 1.0 {
                let g = shot.exposure_gain as f32;
                r.radiance.iter_mut().for_each(|x| *x *= g);
            }
            let frame = |k: u64| {
                quantise_u8(&model.image(
                    &r.radiance,
                    r.width,
                    r.height,
                    &shot.camera,
                    shot.noise_seed.wrapping_add(k),
                ))
            };
            out.push([frame(0), frame(1)]);
        }
        Ok(out)
    }

    fn info(&self) -> RendererInfo {
        RendererInfo {
            name: "validator-model".into(),
            independent_of_validator: false,
            details: serde_json::json!({
                "crate": "regolith-model-captures",
                "purpose": "unit tests of the fitting code only: the validator's own renderer and sensor model (inverse crime)",
                "renderer": "regolith_validator::render (ray cast heightfield, Lambertian + ambient, cast shadows only with hidden shadows)",
                "sensor": "regolith_validator::sensor::SensorModel (hidden effects + baseline noise)",
            }),
        }
    }
}
