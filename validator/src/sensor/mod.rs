//! The sensor/effect model: the catalogue of ways a real capture differs from a plain render.
//!
//! The corpus generator hides these effects in its synthetic "real" images and the gap
//! workflow fits them back, so both share this one definition (names are the serde tags, in
//! kebab-case, listed in `format-spec/registry.md`). Effects act at four places:
//!
//! | where | effects | method |
//! |---|---|---|
//! | geometry | `distortion`, `pose-bias` | [`SensorModel::camera`], [`SensorModel::pose`] |
//! | render | `shadows` | [`SensorModel::render_options`] |
//! | texture | `texture-lowpass`; the entry's [`TextureTransfer`] | [`SensorModel::detailed`] (the corpus: [`SensorModel::albedo`]); the render's radiance |
//! | image | `vignetting`, `blur`, `exposure`, `noise`, `gamma` | [`SensorModel::image`] |
//!
//! The image effects run in the physical order of a camera, whatever their order in the list:
//! optics (vignetting, then the blur PSF), exposure into digital numbers, sensor noise, then
//! the response curve (gamma); see [`image`]. Effects of the same kind apply in list order.
//! An empty model is the plain model: `DN = 255 * radiance`, no other change.

mod blur;
pub mod detail;
pub mod image;

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use regolith_format::camera_model::CameraModel;
use regolith_format::frames::{quat_from_axis_angle, Pose};

use crate::render::{AlbedoGrid, Geometry, Light, RenderOptions, Sampling};

pub use blur::{gaussian_blur, kernel_radius};
pub use image::quantise_u8;
pub use regolith_format::effects::{
    distortion_shift, level_change_dn, Effect, ParamRange, TextureTransfer, MIN_DISTORTION_SHIFT,
    MIN_LEVEL_CHANGE_DN,
};

/// Ambient share of the light that [`SensorModel::render_options`] returns for a `shadows`
/// effect (callers may overwrite it).
pub const SHADOW_AMBIENT: f64 = 0.15;

/// Where a camera was when it took a frame: its measured pose, and its place on the rig whose
/// frame a `pose-bias` is in (registry: the bias moves the rig, its cameras follow rigidly).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// The measured `ground_from_camera`.
    pub ground_from_camera: Pose,
    /// The camera in the rig frame: identity for the rig's reference camera and for a camera
    /// on no rig.
    pub rig_from_camera: Pose,
}

impl Placement {
    /// A camera on no rig (or the rig's reference camera): the bias is in its own frame.
    pub fn lone(ground_from_camera: Pose) -> Self {
        Placement {
            ground_from_camera,
            rig_from_camera: Pose::IDENTITY,
        }
    }
}

/// A list of effects; empty = the plain model. Beside the camera's effects it may hold the
/// entry's [`TextureTransfer`], which scales the render's radiance (albedo) before any image
/// effect.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SensorModel {
    /// The effects.
    pub effects: Vec<Effect>,
    /// The texture's transfer to the camera's albedo; `None`: the texture is taken as it is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture_transfer: Option<TextureTransfer>,
    /// An auto-exposing camera's gain per capture location (by capture name), on top of the
    /// exposure: a capture not listed has gain 1. Renders of a view apply its capture's gain
    /// ([`SensorModel::at_capture`]).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub capture_exposure: BTreeMap<String, f64>,
}

impl From<Vec<Effect>> for SensorModel {
    /// The camera effects `effects`, the texture taken as it is.
    fn from(effects: Vec<Effect>) -> SensorModel {
        SensorModel {
            effects,
            texture_transfer: None,
            capture_exposure: BTreeMap::new(),
        }
    }
}

impl SensorModel {
    /// The model as the views of capture `capture` see it: its gain from
    /// [`SensorModel::capture_exposure`] folded into the texture's transfer (both scale the
    /// radiance before any image effect), the per-capture table emptied.
    pub fn at_capture(&self, capture: &str) -> SensorModel {
        let mut m = self.clone();
        let table = std::mem::take(&mut m.capture_exposure);
        if let Some(g) = table.get(capture).copied().filter(|g| *g != 1.0) {
            let gain = m.texture_transfer.map_or(1.0, |t| t.gain) * g;
            m.texture_transfer = Some(TextureTransfer { gain });
        }
        m
    }

    /// `base` with every `distortion` effect added to its `k1`, `k2`.
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

    /// The true camera pose at `at`: every `pose-bias` `B` (which maps true-rig into
    /// calibrated-rig coordinates, `R = Rz * Ry * Rx`) moves the rig, and the camera follows
    /// rigidly: `ground_from_camera * rig_from_camera⁻¹ * B * rig_from_camera`.
    pub fn pose(&self, at: &Placement) -> Pose {
        let mut bias = Pose::IDENTITY;
        for e in &self.effects {
            if let Effect::PoseBias {
                translation_m,
                rotation_deg,
            } = e
            {
                let [rx, ry, rz] = rotation_deg.map(f64::to_radians);
                let q = |axis: [f64; 3], a: f64| Pose {
                    translation_m: [0.0; 3],
                    rotation_xyzw: quat_from_axis_angle(axis, a),
                };
                let rot = q([0.0, 0.0, 1.0], rz)
                    .compose(&q([0.0, 1.0, 0.0], ry))
                    .compose(&q([1.0, 0.0, 0.0], rx));
                bias = bias.compose(&Pose {
                    translation_m: *translation_m,
                    rotation_xyzw: rot.rotation_xyzw,
                });
            }
        }
        at.ground_from_camera
            .compose(&at.rig_from_camera.inverse())
            .compose(&bias)
            .compose(&at.rig_from_camera)
    }

    /// The render options and light implied by the model: a `shadows` effect (the last one
    /// wins) turns shadows on and returns its light with [`SHADOW_AMBIENT`].
    pub fn render_options(&self, base: &RenderOptions) -> (RenderOptions, Option<Light>) {
        let mut opts = *base;
        let mut light = None;
        for e in &self.effects {
            if let Effect::Shadows {
                azimuth_deg,
                elevation_deg,
            } = *e
            {
                opts.shadows = true;
                light = Some(Light {
                    azimuth_deg,
                    elevation_deg,
                    ambient: SHADOW_AMBIENT,
                });
            }
        }
        (opts, light)
    }

    /// `grid` low-passed by every `texture-lowpass` effect (sigma converted to cells): how the
    /// corpus makes an entry's texture too smooth. An entry's model does the opposite, see
    /// [`SensorModel::detailed`].
    pub fn albedo(&self, grid: &AlbedoGrid) -> AlbedoGrid {
        let mut out = grid.clone();
        for e in &self.effects {
            if let Effect::TextureLowpass { sigma_m } = e {
                if grid.cell_m > 0.0 {
                    out.value =
                        gaussian_blur(&out.value, out.width, out.height, sigma_m / grid.cell_m);
                }
            }
        }
        out
    }

    /// The geometry a sample render of an entry uses under this model: with a
    /// `texture-lowpass` (the last one wins), a heightfield's albedo with the procedural detail
    /// the low-pass removed ([`detail`]). `None` when the model leaves the geometry as it is
    /// (no `texture-lowpass`, or a mesh).
    pub fn detailed(&self, geometry: &Geometry) -> Option<Geometry> {
        let sigma_m = self.effects.iter().rev().find_map(|e| match e {
            Effect::TextureLowpass { sigma_m } => Some(*sigma_m),
            _ => None,
        })?;
        match geometry {
            Geometry::Heightfield { grid, albedo } => Some(Geometry::Heightfield {
                grid: grid.clone(),
                albedo: detail::restore_detail(albedo, sigma_m),
            }),
            Geometry::Mesh(_) => None,
        }
    }

    /// Turns linear radiance into digital numbers (0..255 scale, unclamped float) through the
    /// image effects, in the order documented in [`image`]. `seed` drives the noise.
    pub fn image(
        &self,
        radiance: &[f32],
        width: usize,
        height: usize,
        camera: &CameraModel,
        seed: u64,
    ) -> Vec<f32> {
        image::apply(&self.effects, radiance, width, height, camera, seed)
    }
}

/// A render through a sensor model.
#[derive(Debug, Clone)]
pub struct SensorRender {
    /// The plain render (radiance, depth, mask) from the model's camera and pose.
    pub rendered: crate::render::Rendered,
    /// Digital numbers (0–255 scale, unclamped) after the model's image effects.
    pub dn: Vec<f32>,
    /// The camera used (calibration plus the model's distortion).
    pub camera: CameraModel,
}

impl SensorModel {
    /// Renders `scene` as the camera `calibrated` placed at `at` sees it
    /// under this model: its distortion and pose bias move the camera, `shadows` turns on cast
    /// shadows (direction from the effect, ambient from `light`), and the image effects make
    /// digital numbers. `noise_seed: None` leaves the noise out (the expected image).
    pub fn render(
        &self,
        scene: &crate::render::Scene<'_>,
        light: &Light,
        calibrated: &CameraModel,
        at: &Placement,
        sampling: impl Into<Sampling>,
        noise_seed: Option<u64>,
    ) -> SensorRender {
        self.render_by(
            light,
            calibrated,
            at,
            sampling.into(),
            noise_seed,
            |l, v, o| scene.render(l, v, o),
        )
    }

    /// A render of the camera `calibrated` at `at` under this model, drawn by `draw` from the
    /// model's light, view and options: what [`SensorModel::render`] and
    /// [`SensorModel::render_from_hits`] share.
    fn render_by(
        &self,
        light: &Light,
        calibrated: &CameraModel,
        at: &Placement,
        sampling: Sampling,
        noise_seed: Option<u64>,
        draw: impl FnOnce(&Light, &crate::render::View, &RenderOptions) -> crate::render::Rendered,
    ) -> SensorRender {
        let camera = self.camera(calibrated);
        let (opts, light) = self.lighting(light, sampling);
        let view = crate::render::View {
            camera: camera.clone(),
            ground_from_camera: self.pose(at),
        };
        self.finish(draw(&light, &view, &opts), camera, calibrated, noise_seed)
    }

    /// The first hits of the camera rays of [`SensorModel::render`] (the model's distortion
    /// and pose bias move the camera; its light does not enter), to be shaded under several
    /// lights by [`SensorModel::relight`].
    pub fn primary_hits(
        &self,
        scene: &crate::render::Scene<'_>,
        calibrated: &CameraModel,
        at: &Placement,
        supersample: u32,
    ) -> crate::render::PrimaryHits {
        let (opts, _) = self.render_options(&render_options(Sampling::Full(supersample)));
        scene.primary_hits(
            &crate::render::View {
                camera: self.camera(calibrated),
                ground_from_camera: self.pose(at),
            },
            &opts,
        )
    }

    /// [`SensorModel::render`] given `hits`, this view's [`SensorModel::primary_hits`] at one
    /// sample a pixel traced with a model of the same distortion and pose bias: the same
    /// bytes, an adaptive sampling tracing only its edge pixels' samples (see
    /// [`crate::render::Scene::render_from_hits`]).
    #[allow(clippy::too_many_arguments)]
    pub fn render_from_hits(
        &self,
        scene: &crate::render::Scene<'_>,
        hits: &crate::render::PrimaryHits,
        light: &Light,
        calibrated: &CameraModel,
        at: &Placement,
        sampling: impl Into<Sampling>,
        noise_seed: Option<u64>,
    ) -> SensorRender {
        self.render_by(
            light,
            calibrated,
            at,
            sampling.into(),
            noise_seed,
            |l, v, o| scene.render_from_hits(hits, l, v, o),
        )
    }

    /// [`SensorModel::render`] from `hits`, traced by [`SensorModel::primary_hits`] with a model
    /// of the same distortion and pose bias as this one: only the light (a `shadows` effect's
    /// direction) and the image effects may differ. The same bytes as a render.
    pub fn relight(
        &self,
        scene: &crate::render::Scene<'_>,
        hits: &crate::render::PrimaryHits,
        light: &Light,
        calibrated: &CameraModel,
        noise_seed: Option<u64>,
    ) -> SensorRender {
        let rendered = self.relight_radiance(scene, hits, light);
        self.finish_rendered(rendered, calibrated, noise_seed)
    }

    /// The plain render (radiance, depth, mask) of [`SensorModel::relight`], before the image
    /// effects and the texture's transfer: what a model of the same distortion, pose bias and
    /// `shadows` effect shares with this one ([`SensorModel::finish_rendered`] makes its
    /// digital numbers).
    pub fn relight_radiance(
        &self,
        scene: &crate::render::Scene<'_>,
        hits: &crate::render::PrimaryHits,
        light: &Light,
    ) -> crate::render::Rendered {
        let (opts, light) = self.lighting(light, Sampling::Full(1));
        scene.relight(hits, &light, opts.shadows)
    }

    /// `rendered`, a plain render of the camera `calibrated` through this model's distortion
    /// and pose bias, finished through its texture transfer and image effects (the noise only
    /// with a `noise_seed`): what [`SensorModel::render`] returns for it.
    pub fn finish_rendered(
        &self,
        rendered: crate::render::Rendered,
        calibrated: &CameraModel,
        noise_seed: Option<u64>,
    ) -> SensorRender {
        self.finish(rendered, self.camera(calibrated), calibrated, noise_seed)
    }

    /// The effects that decide where this model's camera rays go (its distortion and pose
    /// bias, in order): two models with the same ones trace the same rays.
    pub fn ray_effects(&self) -> Vec<Effect> {
        self.effects
            .iter()
            .filter(|e| matches!(e, Effect::Distortion { .. } | Effect::PoseBias { .. }))
            .copied()
            .collect()
    }

    /// This model's cast-shadow effect, if any.
    pub fn shadows_effect(&self) -> Option<Effect> {
        self.effects
            .iter()
            .find(|e| matches!(e, Effect::Shadows { .. }))
            .copied()
    }

    /// The cast shadow of this model's light on `hits` (see [`crate::render::CastShadow`]), to
    /// relight them again by [`SensorModel::relight_cast`]; `None` when the model casts none.
    pub fn cast_shadow(
        &self,
        scene: &crate::render::Scene<'_>,
        hits: &crate::render::PrimaryHits,
        light: &Light,
    ) -> Option<crate::render::CastShadow> {
        let (opts, light) = self.lighting(light, Sampling::Full(1));
        opts.shadows.then(|| scene.cast_shadow(hits, &light))
    }

    /// [`SensorModel::relight`] (without noise) given the cast shadow of this model's light,
    /// made by [`SensorModel::cast_shadow`] of a model with the same `shadows` effect: the same
    /// bytes, without a shadow ray.
    pub fn relight_cast(
        &self,
        scene: &crate::render::Scene<'_>,
        hits: &crate::render::PrimaryHits,
        light: &Light,
        cast: &crate::render::CastShadow,
        calibrated: &CameraModel,
    ) -> SensorRender {
        let (opts, light) = self.lighting(light, Sampling::Full(1));
        let rendered = if opts.shadows {
            scene.relight_cast(hits, &light, cast)
        } else {
            scene.relight(hits, &light, false)
        };
        self.finish(rendered, self.camera(calibrated), calibrated, None)
    }

    /// The render options at `sampling` and the light of a render under `light`: a
    /// `shadows` effect casts shadows from its direction, with `light`'s ambient share.
    fn lighting(&self, light: &Light, sampling: Sampling) -> (RenderOptions, Light) {
        let (opts, shadow_light) = self.render_options(&render_options(sampling));
        let light = match shadow_light {
            Some(l) => Light {
                ambient: light.ambient,
                ..l
            },
            None => *light,
        };
        (opts, light)
    }

    /// The digital numbers of `rendered` through the image effects (the noise only with a
    /// `noise_seed`).
    fn finish(
        &self,
        mut rendered: crate::render::Rendered,
        camera: CameraModel,
        calibrated: &CameraModel,
        noise_seed: Option<u64>,
    ) -> SensorRender {
        if let Some(t) = self.texture_transfer {
            // Radiance is linear in the albedo, so scaling it scales the texture.
            let gain = t.gain as f32;
            rendered.radiance.iter_mut().for_each(|r| *r *= gain);
        }
        let effects = match noise_seed {
            Some(_) => self.clone(),
            None => SensorModel::from(
                self.effects
                    .iter()
                    .filter(|e| !matches!(e, Effect::Noise { .. }))
                    .copied()
                    .collect::<Vec<_>>(),
            ),
        };
        let dn = effects.image(
            &rendered.radiance,
            rendered.width,
            rendered.height,
            calibrated,
            noise_seed.unwrap_or(0),
        );
        SensorRender {
            rendered,
            dn,
            camera,
        }
    }
}

/// The options of a sensor render at `sampling`, before the model's own (shadows).
fn render_options(sampling: Sampling) -> RenderOptions {
    RenderOptions {
        distort: true,
        shadows: false,
        supersample: sampling.supersample(),
        filter_textures: true,
        adaptive: matches!(sampling, Sampling::Edges(_)),
    }
}

/// Name of the `sensor-model` entry that holds the fitted model of terrain entry `entry`.
pub fn model_entry_name(entry: &str) -> String {
    format!("{entry}/sensor-model")
}

/// The sensor model stored for `entry` in a release (written by `regolith gap --apply`), or the
/// plain model when there is none.
pub fn stored_model(
    view: &regolith_reader::ReleaseView,
    entry: &str,
) -> Result<SensorModel, regolith_reader::ReaderError> {
    let name = model_entry_name(entry);
    match view.entry(&name) {
        Ok(e) if e.kind == regolith_format::kinds::SENSOR_MODEL => {
            view.read_json(&name, regolith_format::kinds::roles::MODEL, "sensor model")
        }
        _ => Ok(SensorModel::default()),
    }
}
