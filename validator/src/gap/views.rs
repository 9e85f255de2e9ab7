//! The views the gap workflow compares: every (capture, camera) with its real frames, and the
//! prediction of the simulation for a given sensor model.
//!
//! The real side is the **mean of the frames** of a pose (halving the noise variance that no
//! deterministic model can predict), and their difference gives the sensor noise directly. The
//! simulated side is the entry rendered through [`SensorModel`] *without* its noise (the
//! expected image): geometry effects move the camera and its distortion, `shadows` turns on
//! cast shadows of the campaign light, image effects map radiance to digital numbers.
//!
//! A `pose-bias` moves the rig: each view carries its camera's place on the release's `rig`
//! ([`Placement`]), so the right camera of a stereo head follows the left one rigidly.

use regolith_format::camera_model::CameraModel;
use regolith_reader::captures::ImageKind;
use regolith_reader::{ReaderError, ReleaseView};

use crate::render::{Light, PrimaryHits, Sampling, Scene};
use crate::sensor::{Placement, SensorModel, SensorRender};
use crate::validate::grey;

/// One (capture, camera) pair with its real frames.
#[derive(Debug, Clone)]
pub struct GapView {
    /// Capture name.
    pub capture: String,
    /// Camera name.
    pub camera: String,
    /// The calibrated camera.
    pub camera_model: CameraModel,
    /// The measured `ground_from_camera` and the camera's place on the rig.
    pub at: Placement,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Real frames, DN (0–255) as floats; at least one.
    pub frames: Vec<Vec<f32>>,
}

impl GapView {
    /// Mean of the real frames.
    pub fn mean(&self) -> Vec<f32> {
        let k = self.frames.len().max(1) as f32;
        let mut out = vec![0.0f32; self.width * self.height];
        for f in &self.frames {
            for (o, v) in out.iter_mut().zip(f) {
                *o += v / k;
            }
        }
        out
    }
}

/// What the simulation predicts for one view.
#[derive(Debug, Clone)]
pub struct Prediction {
    /// Linear radiance of the render (before image effects).
    pub radiance: Vec<f32>,
    /// Expected digital numbers (image effects without noise), unclamped.
    pub dn: Vec<f32>,
    /// Camera-frame depth, metres; `NaN` off terrain.
    pub depth: Vec<f32>,
    /// The render sees terrain.
    pub mask: Vec<bool>,
    /// The camera the render used (calibration + the model's distortion).
    pub camera: CameraModel,
}

fn err(entry: &str, message: String) -> ReaderError {
    ReaderError::Decode {
        entry: entry.to_string(),
        what: "gap input",
        message,
    }
}

/// Loads every (capture, camera) of the release's `captures` entry, optionally only the named
/// captures and cameras (a name that matches no raw image is an error). With one camera of a
/// stereo head the views have no stereo pairs: the workflow then runs as for a lone camera.
pub fn load_views(
    view: &ReleaseView,
    captures: &[String],
    cameras: &[String],
) -> Result<Vec<GapView>, ReaderError> {
    let caps = view.captures("captures")?;
    let mut images = caps.images()?;
    images.retain(|i| i.kind == ImageKind::Raw);
    let capture_names: Vec<&String> = images.iter().map(|i| &i.capture).collect();
    let camera_names: Vec<&String> = images.iter().map(|i| &i.camera).collect();
    known(captures, &capture_names, "capture")?;
    known(cameras, &camera_names, "camera")?;
    let wanted = |names: &[String], n: &String| names.is_empty() || names.contains(n);
    images.retain(|i| wanted(captures, &i.capture) && wanted(cameras, &i.camera));
    images.sort_by(|a, b| (&a.capture, &a.camera, a.frame).cmp(&(&b.capture, &b.camera, b.frame)));
    let mut out: Vec<GapView> = Vec::new();
    for img in images {
        let g = grey(&img.data, "captures")?;
        let (w, h) = (g.width, g.height);
        let data: Vec<f32> = g.data.iter().map(|v| v * 255.0).collect();
        match out.last_mut() {
            Some(v) if v.capture == img.capture && v.camera == img.camera => {
                if (v.width, v.height) != (w, h) {
                    return Err(err(
                        "captures",
                        format!("{} {}: frames of different sizes", img.capture, img.camera),
                    ));
                }
                v.frames.push(data);
            }
            _ => {
                let camera_model = view.camera(&format!("cameras/{}", img.camera))?;
                if (camera_model.width as usize, camera_model.height as usize) != (w, h) {
                    return Err(err(
                        "captures",
                        format!(
                            "{} {}: image {w}x{h} but calibration {}x{}",
                            img.capture, img.camera, camera_model.width, camera_model.height
                        ),
                    ));
                }
                let entry = format!("cameras/{}", img.camera);
                out.push(GapView {
                    capture: img.capture.clone(),
                    camera: img.camera.clone(),
                    camera_model,
                    at: Placement {
                        ground_from_camera: img.ground_from_camera,
                        rig_from_camera: view.rig_from_camera(&entry)?,
                    },
                    width: w,
                    height: h,
                    frames: vec![data],
                });
            }
        }
    }
    if out.is_empty() {
        return Err(err(
            "captures",
            "no raw capture images to compare with".into(),
        ));
    }
    Ok(out)
}

/// An error naming the first of `names` not among `have`.
fn known(names: &[String], have: &[&String], what: &str) -> Result<(), ReaderError> {
    match names.iter().find(|n| !have.contains(n)) {
        None => Ok(()),
        Some(n) => {
            let mut have = have.to_vec();
            have.sort();
            have.dedup();
            Err(err(
                "captures",
                format!("no {what} named {n:?} (the release has {have:?})"),
            ))
        }
    }
}

/// Renders `v` through `model` without noise (see the module docs), with `supersample` ×
/// `supersample` samples where they change the pixel ([`Sampling::Edges`], as `validate`
/// renders): a pixel whose centre ray sees what its neighbours' see, within one digital
/// number of shading, is one sample with its texture filtered over the pixel.
pub fn predict(
    scene: &Scene<'_>,
    light: &Light,
    v: &GapView,
    model: &SensorModel,
    supersample: u32,
) -> Prediction {
    let sampling = Sampling::Edges(supersample);
    let model = model.at_capture(&v.capture);
    Prediction::from(model.render(scene, light, &v.camera_model, &v.at, sampling, None))
}

/// [`predict`] given the view's camera rays' first `hits` at one sample a pixel, traced under
/// a model of the same geometry as `model`: the same prediction, only the edge pixels'
/// samples traced.
pub fn predict_from_hits(
    scene: &Scene<'_>,
    light: &Light,
    v: &GapView,
    model: &SensorModel,
    supersample: u32,
    hits: &PrimaryHits,
) -> Prediction {
    let sampling = Sampling::Edges(supersample);
    let model = model.at_capture(&v.capture);
    Prediction::from(model.render_from_hits(
        scene,
        hits,
        light,
        &v.camera_model,
        &v.at,
        sampling,
        None,
    ))
}

/// [`predict`] at supersample 1 from the view's camera rays' first `hits`, traced under a
/// model of the same geometry as `model` ([`SensorModel::relight`]): the same prediction.
pub fn predict_relit(
    scene: &Scene<'_>,
    light: &Light,
    v: &GapView,
    model: &SensorModel,
    hits: &PrimaryHits,
) -> Prediction {
    let model = model.at_capture(&v.capture);
    Prediction::from(model.relight(scene, hits, light, &v.camera_model, None))
}

impl From<SensorRender> for Prediction {
    fn from(r: SensorRender) -> Prediction {
        Prediction {
            mask: r.rendered.mask.iter().map(|&m| m == 255).collect(),
            radiance: r.rendered.radiance,
            dn: r.dn,
            depth: r.rendered.depth,
            camera: r.camera,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_selected_name_the_release_lacks_is_an_error_naming_what_it_has() {
        let (l, r) = ("navcam_left".to_string(), "navcam_right".to_string());
        let have = [&r, &l, &l];
        assert!(known(&[], &have, "camera").is_ok());
        assert!(known(std::slice::from_ref(&l), &have, "camera").is_ok());
        let e = known(&["navcam_middle".into()], &have, "camera")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no camera named \"navcam_middle\"")
                && e.contains("[\"navcam_left\", \"navcam_right\"]"),
            "{e}"
        );
    }
}
