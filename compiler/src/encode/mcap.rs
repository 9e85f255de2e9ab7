//! The captures MCAP (SPEC.md §5.6): Foxglove JSON-schema messages so Foxglove Studio opens the
//! file as is, with every writer option pinned (library string, zstd level, one compression
//! thread, chunk size) so the bytes do not depend on the machine or the crate's defaults.

use std::collections::BTreeMap;
use std::io::Cursor;

use base64::Engine;
use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;
use regolith_format::kinds::{capture_topic, CaptureCamera, CaptureRecord, CapturesIndex};
use serde_json::{json, Value};

use super::EncodeError;

/// Spacing of frames within one capture (SPEC.md §5.6).
pub const FRAME_SPACING_NS: u64 = 100_000_000;
/// Spacing of captures.
pub const CAPTURE_SPACING_NS: u64 = 1_000_000_000;

/// One camera's frames at one capture pose.
#[derive(Debug, Clone)]
pub struct CameraFrames {
    /// Camera name (frame id and topic prefix, e.g. `navcam_left`).
    pub camera: String,
    /// Its intrinsics.
    pub model: CameraModel,
    /// `ground_from_camera`.
    pub ground_from_camera: Pose,
    /// Raw frames, PNG.
    pub raw_png: Vec<Vec<u8>>,
    /// Undistorted frames, PNG (same count as raw).
    pub rect_png: Vec<Vec<u8>>,
}

/// One capture pose.
#[derive(Debug, Clone)]
pub struct CaptureFrames {
    /// Capture name.
    pub name: String,
    /// Its cameras.
    pub cameras: Vec<CameraFrames>,
    /// Rig-pose spread (m, deg) from the motion-capture fit.
    pub pose_spread: (f64, f64),
}

fn schema(title: &str, props: Value) -> Vec<u8> {
    let v = json!({"title": title, "type": "object", "properties": props});
    regolith_format::canonical_json::to_string(&v).into_bytes()
}

fn time_props() -> Value {
    json!({"type": "object", "title": "time", "properties": {
        "sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}})
}

fn vec3() -> Value {
    json!({"type": "object", "title": "foxglove.Vector3", "properties": {
        "x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}})
}

fn quat() -> Value {
    json!({"type": "object", "title": "foxglove.Quaternion", "properties": {
        "x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}})
}

fn schemas() -> [(&'static str, Vec<u8>); 4] {
    [
        (
            "foxglove.CompressedImage",
            schema(
                "foxglove.CompressedImage",
                json!({
            "timestamp": time_props(), "frame_id": {"type": "string"},
            "data": {"type": "string", "contentEncoding": "base64"}, "format": {"type": "string"}}),
            ),
        ),
        (
            "foxglove.CameraCalibration",
            schema(
                "foxglove.CameraCalibration",
                json!({
            "timestamp": time_props(), "frame_id": {"type": "string"},
            "width": {"type": "integer"}, "height": {"type": "integer"},
            "distortion_model": {"type": "string"},
            "D": {"type": "array", "items": {"type": "number"}},
            "K": {"type": "array", "items": {"type": "number"}},
            "R": {"type": "array", "items": {"type": "number"}},
            "P": {"type": "array", "items": {"type": "number"}}}),
            ),
        ),
        (
            "foxglove.PoseInFrame",
            schema(
                "foxglove.PoseInFrame",
                json!({
            "timestamp": time_props(), "frame_id": {"type": "string"},
            "pose": {"type": "object", "title": "foxglove.Pose", "properties": {"position": vec3(), "orientation": quat()}}}),
            ),
        ),
        (
            "foxglove.FrameTransform",
            schema(
                "foxglove.FrameTransform",
                json!({
            "timestamp": time_props(), "parent_frame_id": {"type": "string"}, "child_frame_id": {"type": "string"},
            "translation": vec3(), "rotation": quat()}),
            ),
        ),
    ]
}

fn stamp(t: u64) -> Value {
    json!({"sec": t / 1_000_000_000, "nsec": t % 1_000_000_000})
}

fn pose_json(p: &Pose) -> (Value, Value) {
    let t = p.translation_m;
    let q = p.rotation_xyzw;
    (
        json!({"x": t[0], "y": t[1], "z": t[2]}),
        json!({"x": q[0], "y": q[1], "z": q[2], "w": q[3]}),
    )
}

/// Encodes the captures into MCAP bytes and returns them with the index.
pub fn encode(captures: &[CaptureFrames]) -> Result<(Vec<u8>, CapturesIndex), EncodeError> {
    let err = |e: mcap::McapError| EncodeError::new("MCAP", e);
    let mut buf = Cursor::new(Vec::new());
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(3)
        .compression_threads(1)
        .chunk_size(Some(4 << 20))
        .profile("")
        .library("regolith/1")
        .create(&mut buf)
        .map_err(err)?;
    let mut schema_ids = BTreeMap::new();
    for (name, data) in schemas() {
        schema_ids.insert(name, w.add_schema(name, "jsonschema", &data).map_err(err)?);
    }
    let mut channels: BTreeMap<String, u16> = BTreeMap::new();
    let mut channel = |w: &mut mcap::Writer<&mut Cursor<Vec<u8>>>, topic: String, schema: &str| {
        if let Some(id) = channels.get(&topic) {
            return Ok(*id);
        }
        let sid = schema_ids.get(schema).copied().unwrap_or(0);
        let id = w
            .add_channel(sid, &topic, "json", &BTreeMap::new())
            .map_err(err)?;
        channels.insert(topic, id);
        Ok::<u16, EncodeError>(id)
    };
    // (log_time, topic) → message: written in that order.
    let mut messages: BTreeMap<(u64, String), (String, Value)> = BTreeMap::new();
    let mut index = CapturesIndex {
        schema: "regolith.captures/1".to_string(),
        captures: Vec::new(),
    };
    for (i, cap) in captures.iter().enumerate() {
        let t0 = (i as u64 + 1) * CAPTURE_SPACING_NS;
        let mut record = CaptureRecord {
            name: cap.name.clone(),
            time_ns: t0,
            cameras: Vec::new(),
            pose_spread_m: cap.pose_spread.0,
            pose_spread_deg: cap.pose_spread.1,
        };
        for cam in &cap.cameras {
            if cam.raw_png.len() != cam.rect_png.len() {
                return Err(EncodeError::new(
                    "MCAP",
                    "raw and rectified frame counts differ",
                ));
            }
            record.cameras.push(CaptureCamera {
                camera: cam.camera.clone(),
                ground_from_camera: cam.ground_from_camera,
                frames: cam.raw_png.len() as u32,
            });
            let m = &cam.model;
            let k = m.k_matrix();
            let calib = json!({
                "timestamp": stamp(t0), "frame_id": cam.camera, "width": m.width, "height": m.height,
                "distortion_model": "plumb_bob", "D": m.d_vector(), "K": k,
                "R": [1, 0, 0, 0, 1, 0, 0, 0, 1],
                "P": [k[0], k[1], k[2], 0, k[3], k[4], k[5], 0, 0, 0, 1, 0],
            });
            let (position, orientation) = pose_json(&cam.ground_from_camera);
            let pose = json!({"timestamp": stamp(t0), "frame_id": "ground",
                "pose": {"position": position.clone(), "orientation": orientation.clone()}});
            let tf = json!({"timestamp": stamp(t0), "parent_frame_id": "ground", "child_frame_id": cam.camera,
                "translation": position, "rotation": orientation});
            messages.insert(
                (t0, capture_topic(&cam.camera, "calibration")),
                ("foxglove.CameraCalibration".into(), calib),
            );
            messages.insert(
                (t0, capture_topic(&cam.camera, "pose")),
                ("foxglove.PoseInFrame".into(), pose),
            );
            messages.insert(
                (t0, format!("/tf/{}", cam.camera)),
                ("foxglove.FrameTransform".into(), tf),
            );
            for (f, (raw, rect)) in cam.raw_png.iter().zip(&cam.rect_png).enumerate() {
                let t = t0 + f as u64 * FRAME_SPACING_NS;
                for (what, png) in [("image_raw", raw), ("image_rect", rect)] {
                    let img = json!({"timestamp": stamp(t), "frame_id": cam.camera, "format": "png",
                        "data": base64::engine::general_purpose::STANDARD.encode(png)});
                    messages.insert(
                        (t, capture_topic(&cam.camera, what)),
                        ("foxglove.CompressedImage".into(), img),
                    );
                }
            }
        }
        index.captures.push(record);
    }
    let mut sequence: BTreeMap<u16, u32> = BTreeMap::new();
    for ((t, topic), (schema, msg)) in messages {
        // All transforms share the `/tf` topic; the map key only keeps them apart.
        let topic = if topic.starts_with("/tf/") {
            "/tf".to_string()
        } else {
            topic
        };
        let id = channel(&mut w, topic, &schema)?;
        let seq = sequence.entry(id).or_insert(0);
        let header = mcap::records::MessageHeader {
            channel_id: id,
            sequence: *seq,
            log_time: t,
            publish_time: t,
        };
        *seq += 1;
        let data = regolith_format::canonical_json::to_string(&msg).into_bytes();
        w.write_to_known_channel(&header, &data).map_err(err)?;
    }
    w.finish().map_err(err)?;
    drop(w);
    Ok((buf.into_inner(), index))
}
