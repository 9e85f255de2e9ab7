//! `captures.build`: cameras, the stereo rig and every capture into the captures MCAP.
//!
//! Per capture the rig balls' Vicon trajectories give a robust `ground_from_left` (Umeyama per
//! frame, outlier-rejecting mean; see `ingest::markers`), and `ground_from_right =
//! ground_from_left · right_from_left⁻¹`. Raw frames are stored as the PNG bytes the camera
//! wrote (re-encoded only when the source is not PNG); rectified frames are undistorted to the
//! pinhole model of SPEC.md §6 with OpenCV-matching bilinear sampling. Images are processed in
//! parallel with indexed collection, so the MCAP bytes do not depend on the thread count.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;
use regolith_format::kinds::{CapturesIndex, RigMeta};
use regolith_format::limits::Limits;
use serde_json::json;

use crate::encode::mcap::{self, CameraFrames, CaptureFrames};
use crate::error::IngestError;
use crate::ingest::campaign::Campaign;
use crate::ingest::{calib_opencv, images, markers, undistort, vicon_csv};
use crate::stage::{Stage, StageCx, StageError};

/// The stage.
#[derive(Debug, Clone, Default)]
pub struct BuildCaptures {
    /// Input limits.
    pub limits: Limits,
}

/// Cameras of the campaign, by name.
#[derive(Debug, Clone)]
pub struct NamedModel {
    /// Campaign camera name (`navcam_left`).
    pub name: String,
    /// Its intrinsics.
    pub model: CameraModel,
}

/// What the stage produces.
#[derive(Debug, Clone)]
pub struct CapturesOutput {
    /// Every campaign camera.
    pub cameras: Vec<NamedModel>,
    /// The rig, when the campaign has one (camera names are campaign names).
    pub rig: Option<RigMeta>,
    /// The MCAP bytes (empty when there is no capture).
    pub mcap: Vec<u8>,
    /// Its index.
    pub index: CapturesIndex,
    /// Per-capture pose-fit figures for the report.
    pub report: serde_json::Value,
}

const NAME: &str = "captures.build";

fn err(e: IngestError) -> StageError {
    StageError::new(NAME, e.to_string())
}

/// Reads every camera's calibration.
pub fn read_cameras(c: &Campaign) -> Result<Vec<NamedModel>, StageError> {
    c.cameras
        .iter()
        .map(|cam| {
            let mut model = calib_opencv::read_calibration_entry(
                &c.root.join(&cam.calibration),
                cam.entry.as_deref(),
                &regolith_format::limits::Limits::default(),
            )
            .map_err(err)?;
            if let Some([w, h]) = cam.image_size {
                model.width = w;
                model.height = h;
            }
            model.validate().map_err(|e| {
                StageError::new(
                    NAME,
                    format!("camera {:?}: {e} ({})", cam.name, cam.calibration.display()),
                )
            })?;
            Ok(NamedModel {
                name: cam.name.clone(),
                model,
            })
        })
        .collect()
}

/// The message for a capture image whose size is not its camera's: both files, both sizes,
/// what to do. `image` is relative to the campaign folder.
fn size_mismatch(
    c: &Campaign,
    capture: &str,
    camera: &NamedModel,
    image: &Path,
    size: (u32, u32),
) -> String {
    let (w, h) = (camera.model.width, camera.model.height);
    let cam = c.cameras.iter().find(|k| k.name == camera.name);
    let source = match cam {
        Some(k) if k.image_size.is_some() => format!(
            "`image_size = [{w}, {h}]` of [[camera]] {:?} in campaign.toml (calibration {})",
            k.name,
            k.calibration.display()
        ),
        Some(k) => format!("its calibration {}", k.calibration.display()),
        None => "its calibration".to_string(),
    };
    format!(
        "capture {capture:?}: image {} is {}x{} pixels, but camera {:?} is calibrated for \
         {w}x{h} images ({source}); point [[camera]] {:?} `calibration` at a calibration made at \
         {}x{} (intrinsics do not carry over between image sizes), or use the {w}x{h} images \
         that calibration was made for",
        image.display(),
        size.0,
        size.1,
        camera.name,
        camera.name,
        size.0,
        size.1
    )
}

/// Checks that every capture image has its camera's calibrated size, from the image headers
/// alone: cheap, so a compile runs it before any heavy work. (`compile --check` parses each
/// file on its own and does not compare them.)
pub fn check_image_sizes(c: &Campaign) -> Result<(), StageError> {
    let Some(rig) = &c.rig else { return Ok(()) };
    if c.captures.is_empty() {
        return Ok(());
    }
    let cameras = read_cameras(c)?;
    let (Some(left), Some(right)) = (cameras.get(rig.left), cameras.get(rig.right)) else {
        return Err(StageError::new(NAME, "rig cameras out of range"));
    };
    for cap in &c.captures {
        let sides = cap
            .left
            .iter()
            .map(|p| (left, p))
            .chain(cap.right.iter().map(|p| (right, p)));
        for (camera, rel) in sides {
            let size = images::dimensions_path(&c.root.join(rel)).map_err(err)?;
            if size != (camera.model.width, camera.model.height) {
                return Err(StageError::new(
                    NAME,
                    size_mismatch(c, &cap.name, camera, rel, size),
                ));
            }
        }
    }
    Ok(())
}

/// Raw bytes as PNG (kept as is when already PNG) and the undistorted frame as PNG.
fn frame_pair(
    path: &Path,
    map: &undistort::UndistortMap,
    model: &CameraModel,
    limits: &Limits,
    mismatch: &dyn Fn((u32, u32)) -> String,
) -> Result<(Vec<u8>, Vec<u8>), IngestError> {
    let bytes = std::fs::read(path).map_err(|e| IngestError::Io(e).in_file(path))?;
    let img = images::decode(&bytes, limits).map_err(|e| e.in_file(path))?;
    if img.width != model.width || img.height != model.height {
        return Err(IngestError::invalid(mismatch((img.width, img.height))));
    }
    let encode = |g: &images::GreyImage| {
        if g.bit_depth > 8 {
            g.to_u16()
        } else {
            g.to_u8()
        }
    };
    let raw = if bytes.starts_with(b"\x89PNG") {
        bytes
    } else {
        encode(&img)?
    };
    let rect = map.apply(&img).map_err(|e| e.in_file(path))?;
    Ok((raw, encode(&rect.image)?))
}

impl Stage for BuildCaptures {
    const NAME: &'static str = NAME;
    const VERSION: u32 = 1;
    const DESCRIPTION: &'static str =
        "rig poses from Vicon, raw and undistorted frames, cameras and rig into the captures MCAP";
    type Input = Campaign;
    type Output = CapturesOutput;

    fn params(&self) -> serde_json::Value {
        json!({"undistort": "bilinear, positions rounded to 1/32 px (OpenCV remap)", "frame_spacing_ns": mcap::FRAME_SPACING_NS})
    }

    fn run(&self, cx: &StageCx, c: &Campaign) -> Result<CapturesOutput, StageError> {
        let cameras = read_cameras(c)?;
        let Some(rig) = &c.rig else {
            if !c.captures.is_empty() {
                return Err(StageError::new(
                    NAME,
                    "captures need a [rig] (markers, left, right, right_from_left)",
                ));
            }
            let index = CapturesIndex {
                schema: "regolith.captures/1".into(),
                captures: Vec::new(),
            };
            return Ok(CapturesOutput {
                cameras,
                rig: None,
                mcap: Vec::new(),
                index,
                report: json!([]),
            });
        };
        let (left, right) = match (cameras.get(rig.left), cameras.get(rig.right)) {
            (Some(l), Some(r)) => (l.clone(), r.clone()),
            _ => return Err(StageError::new(NAME, "rig cameras out of range")),
        };
        let balls =
            markers::read_rig_markers(&c.root.join(&rig.markers), &self.limits).map_err(err)?;
        let right_from_left =
            calib_opencv::read_any_stereo(&c.root.join(&rig.right_from_left)).map_err(err)?;
        let rig_meta = RigMeta {
            left: left.name.clone(),
            right: right.name.clone(),
            right_from_left,
            rig_from_left: Pose::IDENTITY,
        };
        let maps = [
            undistort::UndistortMap::new(&left.model, &self.limits).map_err(err)?,
            undistort::UndistortMap::new(&right.model, &self.limits).map_err(err)?,
        ];
        let mut frames = Vec::new();
        let mut report = Vec::new();
        for cap in &c.captures {
            let traj =
                vicon_csv::read_path(&c.root.join(&cap.rig_pose), &self.limits).map_err(err)?;
            let pose = markers::fit_rig_pose(&balls, &traj).map_err(|e| {
                StageError::new(
                    NAME,
                    format!(
                        "capture {:?}: {e} (rig pose {}, [rig].markers {})",
                        cap.name,
                        cap.rig_pose.display(),
                        rig.markers.display()
                    ),
                )
            })?;
            if pose.translation_rms_m > 0.005 || pose.rotation_rms_deg > 0.5 {
                cx.reporter.warn(
                    NAME,
                    "rig-pose-spread",
                    format!(
                        "capture {:?}: rig pose spread {:.1} mm / {:.2}° over {} frames",
                        cap.name,
                        pose.translation_rms_m * 1e3,
                        pose.rotation_rms_deg,
                        pose.frames_used
                    ),
                );
            }
            let gfl = pose.ground_from_left;
            let gfr = gfl.compose(&right_from_left.inverse());
            report.push(json!({
                "capture": cap.name, "frames_used": pose.frames_used, "frames_rejected": pose.frames_rejected,
                "translation_rms_m": pose.translation_rms_m, "rotation_rms_deg": pose.rotation_rms_deg,
                "fit_rms_m": pose.fit_rms_m,
            }));
            let jobs: Vec<(usize, &PathBuf)> = cap
                .left
                .iter()
                .map(|p| (0, p))
                .chain(cap.right.iter().map(|p| (1, p)))
                .collect();
            let done: Vec<(usize, Vec<u8>, Vec<u8>)> = jobs
                .par_iter()
                .map(|(side, rel)| {
                    let (named, map) = if *side == 0 {
                        (&left, &maps[0])
                    } else {
                        (&right, &maps[1])
                    };
                    let mismatch = |size| size_mismatch(c, &cap.name, named, rel, size);
                    frame_pair(
                        &c.root.join(rel),
                        map,
                        &named.model,
                        &self.limits,
                        &mismatch,
                    )
                    .map(|(raw, rect)| (*side, raw, rect))
                })
                .collect::<Result<_, _>>()
                .map_err(err)?;
            let mut cams = Vec::new();
            for (side, named, pose) in [(0, &left, gfl), (1, &right, gfr)] {
                let (raw_png, rect_png): (Vec<_>, Vec<_>) = done
                    .iter()
                    .filter(|d| d.0 == side)
                    .map(|d| (d.1.clone(), d.2.clone()))
                    .unzip();
                cams.push(CameraFrames {
                    camera: named.name.clone(),
                    model: named.model.clone(),
                    ground_from_camera: pose,
                    raw_png,
                    rect_png,
                });
            }
            frames.push(CaptureFrames {
                name: cap.name.clone(),
                cameras: cams,
                pose_spread: (pose.translation_rms_m, pose.rotation_rms_deg),
            });
        }
        let (mcap_bytes, index) =
            mcap::encode(&frames).map_err(|e| StageError::new(NAME, e.to_string()))?;
        Ok(CapturesOutput {
            cameras,
            rig: Some(rig_meta),
            mcap: mcap_bytes,
            index,
            report: json!(report),
        })
    }
}
