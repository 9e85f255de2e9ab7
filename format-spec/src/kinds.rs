//! Entry kinds, their roles, media types and metadata (SPEC.md §5).
//!
//! Kinds are an open set (`registry.md`); the ones below are those regolith writes and reads.
//! Metadata structs are plain serde types so readers in other languages can mirror them.

use serde::{Deserialize, Serialize};

use crate::camera_model::CameraModel;
use crate::frames::Pose;

/// A terrain height grid (16-bit PNG + float32 EXR + 8-bit validity mask).
pub const HEIGHTFIELD: &str = "heightfield";
/// A triangle mesh as binary glTF, with levels of detail.
pub const MESH: &str = "mesh";
/// An image aligned with a heightfield grid (orthophoto, reflectance).
pub const TEXTURE: &str = "texture";
/// Camera intrinsics.
pub const CAMERA: &str = "camera";
/// Stereo rig extrinsics.
pub const RIG: &str = "rig";
/// Captured images with ground-truth poses (MCAP).
pub const CAPTURES: &str = "captures";
/// A JSON report (registration, DEM statistics, certificate, ...).
pub const REPORT: &str = "report";
/// A sensor/render model fitted by `regolith gap` for one entry.
pub const SENSOR_MODEL: &str = "sensor-model";

/// Whether entries of this kind carry their payload in tiles.
pub fn is_tiled(kind: &str) -> bool {
    matches!(kind, HEIGHTFIELD | MESH | TEXTURE)
}

/// Well-known roles.
pub mod roles {
    /// Heightfield: 16-bit greyscale PNG of quantised heights.
    pub const HEIGHT: &str = "height";
    /// Heightfield: single-channel float32 EXR of heights in metres (NaN = nodata).
    pub const HEIGHT_F32: &str = "height_f32";
    /// Heightfield: 8-bit PNG validity mask (255 measured, 0 filled/nodata).
    pub const MASK: &str = "mask";
    /// Texture: the image.
    pub const IMAGE: &str = "image";
    /// Camera: intrinsics JSON; rig: extrinsics JSON.
    pub const CALIBRATION: &str = "calibration";
    /// Captures: the MCAP file.
    pub const MCAP: &str = "mcap";
    /// Captures: the JSON index.
    pub const INDEX: &str = "index";
    /// Report: the JSON body.
    pub const REPORT: &str = "report";
    /// Sensor model: the JSON body.
    pub const MODEL: &str = "model";
    /// Mesh: level of detail `n` is the role `lod<n>` (lod0 = full detail).
    pub fn lod(n: u32) -> String {
        format!("lod{n}")
    }
}

/// Well-known media types.
pub mod media {
    /// PNG image.
    pub const PNG: &str = "image/png";
    /// OpenEXR image.
    pub const EXR: &str = "image/x-exr";
    /// Binary glTF.
    pub const GLB: &str = "model/gltf-binary";
    /// MCAP container.
    pub const MCAP: &str = "application/x-mcap";
    /// JSON.
    pub const JSON: &str = "application/json";
}

/// Heightfield metadata: everything needed to turn pixel values into ground coordinates.
///
/// Cell `(col, row)` has its centre at `x = origin_m[0] + col * cell_m`,
/// `y = origin_m[1] - row * cell_m` (row 0 is the north edge, the maximum y), and its height is
/// `z = z_offset_m + value * z_scale_m` in the ground frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeightfieldMeta {
    /// Frame of x, y, z: always `ground` in v1.
    pub frame: String,
    /// Ground coordinates of the centre of cell (0, 0), the north-west cell, in metres.
    pub origin_m: [f64; 2],
    /// Cell size in metres (square cells).
    pub cell_m: f64,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Always `north-up`: row 0 is the maximum-y edge.
    pub row_order: String,
    /// Height of PNG value 0, metres.
    pub z_offset_m: f64,
    /// Metres per PNG step.
    pub z_scale_m: f64,
    /// Largest quantisation error of the PNG, `z_scale_m / 2`.
    pub quantisation_error_m: f64,
    /// Smallest and largest height over valid cells.
    pub z_range_m: [f64; 2],
    /// Number of measured (mask = 255) cells.
    pub valid_cells: u64,
    /// True when nodata cells of the PNG were filled for a continuous surface.
    pub holes_filled: bool,
    /// Survey-frame coordinates of the ground origin (kept in f64, subtracted before f32).
    #[serde(default)]
    pub site_origin_m: [f64; 3],
    /// The terrain this grid came from (e.g. `laser`, `sfm`).
    #[serde(default)]
    pub source: String,
}

impl HeightfieldMeta {
    /// Ground x, y of the centre of cell (col, row).
    pub fn cell_centre(&self, col: u32, row: u32) -> [f64; 2] {
        [
            self.origin_m[0] + f64::from(col) * self.cell_m,
            self.origin_m[1] - f64::from(row) * self.cell_m,
        ]
    }

    /// Bounds `[x_min, y_min, x_max, y_max]` of the grid's cell edges.
    pub fn bounds(&self) -> [f64; 4] {
        let h = self.cell_m / 2.0;
        [
            self.origin_m[0] - h,
            self.origin_m[1] - f64::from(self.height.saturating_sub(1)) * self.cell_m - h,
            self.origin_m[0] + f64::from(self.width.saturating_sub(1)) * self.cell_m + h,
            self.origin_m[1] + h,
        ]
    }

    /// Height of a PNG value.
    pub fn height_of(&self, value: u16) -> f64 {
        self.z_offset_m + f64::from(value) * self.z_scale_m
    }

    /// The PNG value nearest to a height (clamped to 0..=65535).
    pub fn value_of(&self, z: f64) -> u16 {
        let v = ((z - self.z_offset_m) / self.z_scale_m).round();
        v.clamp(0.0, 65535.0) as u16
    }
}

/// Texture metadata: the grid it is aligned with, and what its values mean.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TextureMeta {
    /// The heightfield entry whose grid the texture shares.
    pub grid_of: String,
    /// What the pixels hold: `reflectance`, `vertex-color`, `sfm-on-laser`, `albedo` — for all
    /// four a linear albedo estimate, `value / (2^bit_depth − 1)`, not sRGB (SPEC §5.2).
    pub content: String,
    /// Pixels per heightfield cell along each axis (1 = same grid).
    pub pixels_per_cell: u32,
    /// Bits per sample (8 or 16).
    pub bit_depth: u8,
}

/// Mesh metadata.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshMeta {
    /// Frame of the node translation: `ground`, mapped to glTF axes as
    /// `gltf = (x_ground, z_ground, -y_ground)` (+Y up).
    pub frame: String,
    /// Ground coordinates of the mesh's local origin (the root node translation, mapped).
    pub local_origin_m: [f64; 3],
    /// Levels of detail, lod0 first.
    pub lods: Vec<LodMeta>,
    /// The texture entry used, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture: Option<String>,
}

/// One level of detail.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LodMeta {
    /// Vertex count.
    pub vertices: u64,
    /// Triangle count.
    pub triangles: u64,
    /// Largest vertical distance to lod0, metres.
    pub max_height_error_m: f64,
}

/// Camera entry metadata (the full model is the `calibration` object).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraMeta {
    /// The camera model, duplicated from the calibration object for quick listing.
    pub model: CameraModel,
}

/// Stereo rig extrinsics: `X_right = right_from_left * X_left`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigMeta {
    /// Left camera entry name.
    pub left: String,
    /// Right camera entry name.
    pub right: String,
    /// Pose of the left camera frame in the right camera frame.
    pub right_from_left: Pose,
    /// Pose of the left camera in the rig (Vicon body) frame.
    pub rig_from_left: Pose,
}

impl RigMeta {
    /// `rig_from_camera` of the camera entry `camera` (`cameras/navcam_right`), `None` when
    /// the rig does not hold it.
    pub fn rig_from_camera(&self, camera: &str) -> Option<Pose> {
        if camera == self.left {
            Some(self.rig_from_left)
        } else if camera == self.right {
            Some(self.rig_from_left.compose(&self.right_from_left.inverse()))
        } else {
            None
        }
    }
}

/// The JSON index written next to a captures MCAP.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CapturesIndex {
    /// Schema id, `regolith.captures/1`.
    pub schema: String,
    /// Captures in order.
    pub captures: Vec<CaptureRecord>,
}

/// One capture pose with its frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureRecord {
    /// Capture name.
    pub name: String,
    /// Log time of the capture's first message (ns); frame `k` is at `time_ns + k * 1e8`.
    pub time_ns: u64,
    /// Per camera (e.g. `navcam_left`): its pose and number of frames.
    pub cameras: Vec<CaptureCamera>,
    /// Spread of the per-frame rig poses (translation RMS, m).
    #[serde(default)]
    pub pose_spread_m: f64,
    /// Spread of the per-frame rig poses (rotation RMS, degrees).
    #[serde(default)]
    pub pose_spread_deg: f64,
}

/// One camera of a capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureCamera {
    /// Camera entry name (also the MCAP frame id and topic prefix).
    pub camera: String,
    /// `ground_from_camera`.
    pub ground_from_camera: Pose,
    /// Number of raw frames at this pose.
    pub frames: u32,
}

/// MCAP topics of one camera, following SPEC.md §5.6.
pub fn capture_topic(camera: &str, what: &str) -> String {
    format!("/{camera}/{what}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rig_places_its_cameras() {
        let right_from_left = Pose {
            translation_m: [-0.1, 0.0, 0.0],
            rotation_xyzw: crate::frames::quat_from_axis_angle([0.0, 1.0, 0.0], 0.004),
        };
        let rig = RigMeta {
            left: "cameras/navcam_left".into(),
            right: "cameras/navcam_right".into(),
            right_from_left,
            rig_from_left: Pose {
                translation_m: [0.0, 0.05, 0.0],
                ..Pose::IDENTITY
            },
        };
        let left = rig.rig_from_camera("cameras/navcam_left").unwrap();
        let right = rig.rig_from_camera("cameras/navcam_right").unwrap();
        assert_eq!(left, rig.rig_from_left);
        // The right camera's centre is the baseline away from the left one's, in the rig.
        let c = right.transform_point([0.0; 3]);
        let expected = [0.1 * 0.004f64.cos(), 0.05, 0.1 * 0.004f64.sin()];
        assert!((0..3).all(|k| (c[k] - expected[k]).abs() < 1e-6), "{c:?}");
        // right_from_left = right_from_rig * rig_from_left.
        let back = right.inverse().compose(&left);
        assert!(back.distance_to_m(&right_from_left) < 1e-12);
        assert_eq!(rig.rig_from_camera("cameras/hazcam"), None);
    }

    #[test]
    fn heightfield_geometry() {
        let m = HeightfieldMeta {
            frame: "ground".into(),
            origin_m: [0.005, 8.6],
            cell_m: 0.01,
            width: 3,
            height: 2,
            row_order: "north-up".into(),
            z_offset_m: -0.1,
            z_scale_m: 1e-5,
            quantisation_error_m: 5e-6,
            z_range_m: [0.0, 0.5],
            valid_cells: 6,
            holes_filled: false,
            site_origin_m: [0.0; 3],
            source: "laser".into(),
        };
        assert_eq!(m.cell_centre(2, 1), [0.025, 8.59]);
        let b = m.bounds();
        assert!((b[0] - 0.0).abs() < 1e-12 && (b[2] - 0.03).abs() < 1e-12);
        assert!((b[1] - 8.585).abs() < 1e-12 && (b[3] - 8.605).abs() < 1e-12);
        let z = 0.123456;
        assert!((m.height_of(m.value_of(z)) - z).abs() <= m.quantisation_error_m + 1e-12);
    }
}
