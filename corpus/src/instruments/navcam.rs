//! The NavCam stereo head: intrinsics, rig balls, capture poses and the rendered raw frames.
//!
//! * Intrinsics: thesis Table 5.7 (1280 x 1024, f ≈ 832 px), scaled by the preset's image
//!   scale (`f·s`, `c' = (c + 0.5)·s − 0.5` for the pixel-centre convention), with plausible
//!   Brown–Conrady distortion drawn from the seed (k1 ∈ [−0.25, −0.15], k2 ∈ [0.05, 0.12],
//!   |p| ≤ 5e-4). The right camera sits 10 cm along +x of the left, rotated by ≤ 0.3°.
//! * The rig frame *is* the left-camera frame (x right, y down, z forward); four Vicon balls are
//!   fixed in it above the cameras (`calib/rig_markers.csv`).
//! * Capture poses: each location looks at one marker (so every capture shows one), from
//!   0.9–1.0 m above the local surface, pitched down 25–40°, rolled ≤ 2°, with the marker
//!   offset from the image centre by a few degrees; poses whose camera would leave the bed or
//!   whose marker is hidden are redrawn.
//! * Shots: the *true* cameras ([`Hidden::camera`] = calibration + hidden distortion, and
//!   [`Hidden::rig_pose`] = rig pose · hidden bias for the left camera, the right following
//!   rigidly) are what a [`crate::captures::CaptureRenderer`] renders; two frames per pose get
//!   independent noise seeds.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use regolith_format::camera_model::{CameraModel, Distortion};
use regolith_format::frames::{quat_from_axis_angle, Pose};

use super::riegl::marker_visible;
use crate::captures::Shot;
use crate::effects::Hidden;
use crate::presets::PresetConfig;
use crate::terrain::raycast::TerrainCaster;
use crate::terrain::Terrain;

/// Vicon balls on the stereo head, in the left-camera (rig) frame, metres.
pub const RIG_BALLS: [(&str, [f64; 3]); 4] = [
    ("Ball1", [-0.07, -0.09, -0.02]),
    ("Ball2", [0.17, -0.09, -0.02]),
    ("Ball3", [0.05, -0.13, 0.06]),
    ("Ball4", [0.05, -0.06, -0.11]),
];

/// The calibrated stereo head.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoHead {
    /// Left camera (as calibrated).
    pub left: CameraModel,
    /// Right camera (as calibrated).
    pub right: CameraModel,
    /// `X_right = R X_left + T`.
    pub right_from_left: Pose,
}

/// One rover location.
#[derive(Debug, Clone, PartialEq)]
pub struct CapturePose {
    /// Location name (`loc01`...).
    pub name: String,
    /// The rig (left-camera) pose the Vicon sees.
    pub ground_from_rig: Pose,
    /// The marker the camera looks at.
    pub target: String,
}

/// Draws the calibrated stereo head of a preset.
pub fn stereo_head(cfg: &PresetConfig, rng: &mut ChaCha8Rng) -> StereoHead {
    let s = cfg.image_scale;
    let mut cam = |i: usize| {
        let n = cfg.navcam.get(i).copied().unwrap_or(cfg.navcam[0]);
        let w = (f64::from(n.size[0]) * s).round() as u32;
        let h = (f64::from(n.size[1]) * s).round() as u32;
        let c = |v: f64| (v + 0.5) * s - 0.5;
        CameraModel {
            distortion: Distortion {
                k1: rng.gen_range(-0.25..-0.15),
                k2: rng.gen_range(0.05..0.12),
                p1: rng.gen_range(-5e-4..5e-4),
                p2: rng.gen_range(-5e-4..5e-4),
                k3: 0.0,
            },
            ..CameraModel::pinhole(w, h, n.f[0] * s, n.f[1] * s, c(n.c[0]), c(n.c[1]))
        }
    };
    let left = cam(0);
    let right = cam(1);
    let axis = [
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    ];
    let q = quat_from_axis_angle(axis, rng.gen_range(0.05..0.3f64).to_radians());
    let rot = Pose {
        translation_m: [0.0; 3],
        rotation_xyzw: q,
    };
    // Right camera centre at (+0.10, 0, 0) in the left frame: T = -R * c.
    let c = rot.rotate([
        0.10,
        rng.gen_range(-0.001..0.001),
        rng.gen_range(-0.001..0.001),
    ]);
    StereoHead {
        left,
        right,
        right_from_left: Pose {
            translation_m: [-c[0], -c[1], -c[2]],
            rotation_xyzw: q,
        },
    }
}

/// Camera pose looking along heading `h`, pitched down `p`, rolled `roll` (radians).
pub fn look_pose(eye: [f64; 3], h: f64, p: f64, roll: f64) -> Pose {
    let f = [p.cos() * h.cos(), p.cos() * h.sin(), -p.sin()];
    let r = [h.sin(), -h.cos(), 0.0];
    let d = [
        f[1] * r[2] - f[2] * r[1],
        f[2] * r[0] - f[0] * r[2],
        f[0] * r[1] - f[1] * r[0],
    ];
    let base = Pose::from_matrix(
        [[r[0], d[0], f[0]], [r[1], d[1], f[1]], [r[2], d[2], f[2]]],
        eye,
    );
    base.compose(&Pose {
        translation_m: [0.0; 3],
        rotation_xyzw: quat_from_axis_angle([0.0, 0.0, 1.0], roll),
    })
}

/// Draws the capture locations.
pub fn capture_poses(
    cfg: &PresetConfig,
    terrain: &Terrain,
    tracer: &TerrainCaster,
    rng: &mut ChaCha8Rng,
) -> Vec<CapturePose> {
    let mut out = Vec::new();
    let n = terrain.markers.len();
    for k in 0..cfg.captures {
        // Preferred target (k * 7) mod n spreads the locations; if no pose sees it, try the next.
        let found = (0..n).find_map(|j| {
            let m = terrain.markers.get((k * 7 + j) % n)?;
            let pose = pose_seeing(cfg, terrain, tracer, m, rng)?;
            Some(CapturePose {
                name: format!("loc{:02}", k + 1),
                ground_from_rig: pose,
                target: m.name.clone(),
            })
        });
        out.extend(found);
    }
    out
}

/// A pose 0.9–1.0 m above the surface, pitched 27–38° down, whose line of sight reaches `m`.
fn pose_seeing(
    cfg: &PresetConfig,
    terrain: &Terrain,
    tracer: &TerrainCaster,
    m: &crate::terrain::TrueMarker,
    rng: &mut ChaCha8Rng,
) -> Option<Pose> {
    let margin = 0.1;
    for _ in 0..200 {
        let h = rng.gen_range(0.0..std::f64::consts::TAU);
        let p = rng.gen_range(27.0..38.0f64).to_radians();
        let above = rng.gen_range(0.9..1.0);
        let mut d = above / p.tan();
        let mut eye = [0.0; 3];
        for _ in 0..4 {
            eye[0] = m.centre_m[0] - d * h.cos();
            eye[1] = m.centre_m[1] - d * h.sin();
            eye[2] = terrain.height_at(eye[0], eye[1]) + above;
            d = ((eye[2] - m.centre_m[2]) / p.tan()).max(0.3);
        }
        let inside = eye[0] > margin
            && eye[1] > margin
            && eye[0] < cfg.extent_m[0] - margin
            && eye[1] < cfg.extent_m[1] - margin;
        if !inside || !marker_visible(tracer, eye, m) {
            continue;
        }
        let dh = rng.gen_range(-8.0..8.0f64).to_radians();
        let dp = rng.gen_range(-2.0..2.0f64).to_radians();
        let roll = rng.gen_range(-2.0..2.0f64).to_radians();
        return Some(look_pose(eye, h + dh, p + dp, roll));
    }
    None
}

/// The two shots (left, right) of one capture: true cameras and poses; `noise_seed` is the
/// capture's, the left camera's frames use `+0`, `+1` and the right's `+4`, `+5`;
/// `exposure_gain` the capture's exposure factor ([`Hidden::capture_gain`]).
pub fn shots(
    head: &StereoHead,
    capture: &CapturePose,
    hidden: &Hidden,
    noise_seed: u64,
    exposure_gain: f64,
) -> [Shot; 2] {
    let left_pose = hidden.rig_pose(capture.ground_from_rig);
    let right_pose = left_pose.compose(&head.right_from_left.inverse());
    let shot = |i: usize, side: &str, calibrated: &CameraModel, pose: Pose| Shot {
        name: format!("{}_{side}", capture.name),
        camera: hidden.camera(calibrated),
        calibrated: calibrated.clone(),
        ground_from_camera: pose,
        camera_index: i,
        noise_seed: noise_seed.wrapping_add(4 * i as u64),
        exposure_gain,
    };
    [
        shot(0, "left", &head.left, left_pose),
        shot(1, "right", &head.right, right_pose),
    ]
}

/// Encodes an 8-bit grey image as PNG (fixed encoder settings, reproducible bytes).
pub fn png_grey(pixels: &[u8], width: u32, height: u32) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        let mut w = enc.write_header()?;
        w.write_image_data(pixels)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_pose_points_forward_and_down() {
        let pose = look_pose([0.0, 0.0, 1.0], 0.0, 30f64.to_radians(), 0.0);
        let f = pose.rotate([0.0, 0.0, 1.0]);
        assert!((f[0] - 30f64.to_radians().cos()).abs() < 1e-12 && (f[2] + 0.5).abs() < 1e-12);
        // Camera y (down) has a negative z component; camera x points to -y (right of +x).
        assert!(pose.rotate([0.0, 1.0, 0.0])[2] < 0.0);
        assert!((pose.rotate([1.0, 0.0, 0.0])[1] + 1.0).abs() < 1e-12);
    }
}
