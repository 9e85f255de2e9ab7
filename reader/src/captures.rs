//! Captures: the MCAP file of real images with ground-truth poses, and its JSON index.
//!
//! Topics (SPEC.md §5.6): `/<camera>/image_raw` and `/<camera>/image_rect`
//! (`foxglove.CompressedImage`, PNG), `/<camera>/calibration` (`foxglove.CameraCalibration`),
//! `/<camera>/pose` (`foxglove.PoseInFrame`, frame `ground`). Frame `k` of a capture is logged
//! at `time_ns + k * 100 ms`; the index gives each capture's `time_ns`.

use base64::Engine;
use regolith_format::frames::Pose;
use regolith_format::kinds::{self, roles, CapturesIndex};
use serde_json::Value;

use crate::database::ReleaseView;
use crate::error::{ReaderError, Result};

/// Spacing of the frames of one capture in log time.
pub const FRAME_SPACING_NS: u64 = 100_000_000;

/// Whether an image is the raw (distorted) frame or its undistorted version.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageKind {
    /// As the camera recorded it (`image_raw`).
    Raw,
    /// Undistorted to the pinhole model (`image_rect`).
    Rectified,
}

/// One image of a capture.
#[derive(Debug, Clone)]
pub struct CaptureImage {
    /// Capture name.
    pub capture: String,
    /// Camera entry name.
    pub camera: String,
    /// Frame number within the capture (0-based).
    pub frame: u32,
    /// Raw or rectified.
    pub kind: ImageKind,
    /// Encoded image bytes (PNG).
    pub data: Vec<u8>,
    /// The image's `ground_from_camera` pose.
    pub ground_from_camera: Pose,
}

/// A loaded captures entry.
#[derive(Debug, Clone)]
pub struct Captures {
    /// The index.
    pub index: CapturesIndex,
    mcap: Vec<u8>,
    entry: String,
}

impl Captures {
    /// The verified MCAP bytes (for tools such as Foxglove).
    pub fn mcap_bytes(&self) -> &[u8] {
        &self.mcap
    }

    /// Decodes every image message, in log-time order.
    pub fn images(&self) -> Result<Vec<CaptureImage>> {
        let err = |message: String| ReaderError::Decode {
            entry: self.entry.clone(),
            what: "captures MCAP",
            message,
        };
        let stream = mcap::MessageStream::new(&self.mcap).map_err(|e| err(e.to_string()))?;
        let mut out = Vec::new();
        for m in stream {
            let m = m.map_err(|e| err(e.to_string()))?;
            let topic = m.channel.topic.as_str();
            let Some((camera, kind)) = parse_image_topic(topic) else {
                continue;
            };
            let (capture, frame) = self
                .locate(m.log_time)
                .ok_or_else(|| err(format!("message at {} ns matches no capture", m.log_time)))?;
            let cam = capture
                .cameras
                .iter()
                .find(|c| c.camera == camera)
                .ok_or_else(|| {
                    err(format!(
                        "camera {camera:?} not in capture {:?}",
                        capture.name
                    ))
                })?;
            let v: Value =
                serde_json::from_slice(&m.data).map_err(|e| err(format!("{topic}: {e}")))?;
            let b64 = v
                .get("data")
                .and_then(Value::as_str)
                .ok_or_else(|| err(format!("{topic}: no data field")))?;
            let data = base64::engine::general_purpose::STANDARD
                .decode(b64)
                .map_err(|e| err(format!("{topic}: base64: {e}")))?;
            out.push(CaptureImage {
                capture: capture.name.clone(),
                camera: camera.to_string(),
                frame,
                kind,
                data,
                ground_from_camera: cam.ground_from_camera,
            });
        }
        Ok(out)
    }

    fn locate(&self, t: u64) -> Option<(&kinds::CaptureRecord, u32)> {
        self.index.captures.iter().find_map(|c| {
            let d = t.checked_sub(c.time_ns)?;
            let frame = d / FRAME_SPACING_NS;
            let max = c.cameras.iter().map(|k| k.frames).max().unwrap_or(0);
            (d % FRAME_SPACING_NS == 0 && frame < u64::from(max)).then_some((c, frame as u32))
        })
    }
}

fn parse_image_topic(topic: &str) -> Option<(&str, ImageKind)> {
    let rest = topic.strip_prefix('/')?;
    let (camera, what) = rest.rsplit_once('/')?;
    match what {
        "image_raw" => Some((camera, ImageKind::Raw)),
        "image_rect" => Some((camera, ImageKind::Rectified)),
        _ => None,
    }
}

impl ReleaseView {
    /// Loads a captures entry (index and MCAP, verified).
    pub fn captures(&self, entry: &str) -> Result<Captures> {
        self.entry_of_kind(entry, kinds::CAPTURES)?;
        let index: CapturesIndex = self.read_json(entry, roles::INDEX, "captures index")?;
        let mcap = self.read_file(entry, roles::MCAP)?;
        Ok(Captures {
            index,
            mcap,
            entry: entry.to_string(),
        })
    }
}
