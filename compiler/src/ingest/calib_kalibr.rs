//! Kalibr camchain YAML (`camchain.yaml`) → `CameraModel`s and the stereo extrinsics.
//!
//! Kalibr writes one map per camera (`cam0`, `cam1`, ...; keys sometimes alphabetically
//! sorted, long lists wrapped onto continuation lines), formats.md §15:
//! * `camera_model: pinhole` with `intrinsics: [fu, fv, pu, pv]` (omni, ds, eucm → `Unsupported`);
//! * `distortion_model: radtan` → `[k1, k2, p1, p2]` (Kalibr's radtan has no k3), `none` → no
//!   distortion, `equidistant`/`fov` → `Unsupported` (regolith's model is Brown–Conrady);
//! * `resolution: [width, height]`;
//! * `T_cn_cnm1` (4x4, metres) maps camera n−1 into camera n, so for `cam1` it is exactly
//!   `right_from_left` when cam0 is the left camera.
//!
//! Kalibr uses the OpenCV pixel-centre convention, so `pu, pv` are copied unchanged.

use std::path::Path;

use regolith_format::camera_model::Distortion;
use regolith_format::frames::Pose;
use regolith_format::limits::Limits;

use super::calib_opencv::{camera_from_k, NamedCamera};
use super::markers;
use super::yaml_lite::{self, Matrix, Node};
use crate::error::{IngestError, Result};

/// The cameras of a camchain and cam1's pose relative to cam0.
#[derive(Debug, Clone, PartialEq)]
pub struct KalibrChain {
    /// `cam0`, `cam1`, ... in order.
    pub cameras: Vec<NamedCamera>,
    /// `cam1.T_cn_cnm1` as a pose (`X_cam1 = R X_cam0 + t`), when present.
    pub right_from_left: Option<Pose>,
}

/// Reads a camchain YAML file.
pub fn read_path(path: &Path, limits: &Limits) -> Result<KalibrChain> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Parses a camchain YAML document.
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<KalibrChain> {
    let root = yaml_lite::parse(bytes, limits)?;
    let mut cameras = Vec::new();
    let mut right_from_left = None;
    for i in 0.. {
        let name = format!("cam{i}");
        let Some(cam) = root.get(&name) else { break };
        cameras.push(NamedCamera {
            name,
            model: camera(cam)?,
            extrinsics: None,
        });
        if i == 1 {
            right_from_left = cam.get("T_cn_cnm1").map(pose_4x4).transpose()?;
        }
    }
    if cameras.is_empty() {
        return Err(IngestError::syntax("a `cam0` map", "nothing").at_line(root.line.max(1)));
    }
    Ok(KalibrChain {
        cameras,
        right_from_left,
    })
}

fn field<'a>(cam: &'a Node, key: &str) -> Result<&'a Node> {
    cam.get(key)
        .ok_or_else(|| cam.error(&format!("`{key}` in the camera map")))
}

fn camera(cam: &Node) -> Result<regolith_format::camera_model::CameraModel> {
    let model = field(cam, "camera_model")?;
    if model.as_str() != Some("pinhole") {
        return Err(IngestError::Unsupported(format!(
            "Kalibr camera_model {:?}; regolith reads pinhole",
            model.as_str().unwrap_or("?")
        ))
        .at_line(model.line));
    }
    let intr = field(cam, "intrinsics")?;
    let [fu, fv, pu, pv] = <[f64; 4]>::try_from(intr.as_f64_list()?.as_slice())
        .map_err(|_| intr.error("4 pinhole intrinsics [fu, fv, pu, pv]"))?;
    let dm = field(cam, "distortion_model")?;
    let coeffs = match cam.get("distortion_coeffs") {
        Some(d) => d.as_f64_list()?,
        None => Vec::new(),
    };
    let dist = match (dm.as_str(), coeffs.as_slice()) {
        (Some("radtan"), [k1, k2, p1, p2]) => Distortion {
            k1: *k1,
            k2: *k2,
            p1: *p1,
            p2: *p2,
            k3: 0.0,
        },
        (Some("none"), []) => Distortion::default(),
        (Some("radtan"), _) => return Err(dm.error("radtan with 4 distortion_coeffs")),
        (m, _) => {
            return Err(IngestError::Unsupported(format!(
                "Kalibr distortion_model {:?}; regolith reads radtan and none",
                m.unwrap_or("?")
            ))
            .at_line(dm.line))
        }
    };
    let res = field(cam, "resolution")?;
    let size = match res.as_f64_list()?.as_slice() {
        [w, h] if *w >= 1.0 && *h >= 1.0 && *w < 1e6 && *h < 1e6 => (*w as u32, *h as u32),
        _ => return Err(res.error("resolution [width, height]")),
    };
    let k = Matrix {
        rows: 3,
        cols: 3,
        data: vec![fu, 0.0, pu, 0.0, fv, pv, 0.0, 0.0, 1.0],
    };
    camera_from_k(&k, dist, size, "intrinsics", intr.line)
}

/// A 4x4 rigid matrix (metres) with bottom row `0 0 0 1` → pose.
fn pose_4x4(node: &Node) -> Result<Pose> {
    let m = node.as_matrix()?;
    let v = |i: usize| m.data.get(i).copied().unwrap_or(f64::NAN);
    let bottom = [v(12), v(13), v(14), v(15)];
    if (m.rows, m.cols) != (4, 4) || bottom != [0.0, 0.0, 0.0, 1.0] {
        return Err(node.error("a 4x4 transform with last row [0, 0, 0, 1]"));
    }
    let rows = [v(0), v(1), v(2), v(4), v(5), v(6), v(8), v(9), v(10)];
    let r =
        markers::rotation_from_rows(&rows).ok_or_else(|| node.error("an orthonormal rotation"))?;
    Ok(Pose::from_matrix(r, [v(3), v(7), v(11)]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The camchain example of the Kalibr wiki (formats.md §15), with the omni cam1 made pinhole.
    const WIKI: &str = "cam0:\n  camera_model: pinhole\n  intrinsics: [461.629, 460.152, 362.680, 246.049]\n  distortion_model: radtan\n  distortion_coeffs: [-0.27695497, 0.06712482, 0.00087538, 0.00011556]\n  rostopic: /cam0/image_raw\n  resolution: [752, 480]\ncam1:\n  camera_model: pinhole\n  distortion_coeffs: [-0.33518750, 0.13211436, 0.00055967,\n    0.00057686]\n  distortion_model: radtan\n  intrinsics: [833.006, 830.345, 373.850, 253.749]\n  T_cn_cnm1:\n  - [ 0.99998854, 0.00216014, 0.00427195,-0.11003785]\n  - [-0.00221074, 0.99992702, 0.01187697, 0.00045792]\n  - [-0.00424598,-0.01188627, 0.99992034,-0.00064487]\n  - [0.0, 0.0, 0.0, 1.0]\n  resolution: [752, 480]\n";

    #[test]
    fn wiki_camchain() {
        let c = parse(WIKI.as_bytes(), &Limits::default()).unwrap();
        assert_eq!(c.cameras.len(), 2);
        let m = &c.cameras[0].model;
        assert_eq!(
            (m.fx, m.cy, m.width, m.distortion.p2),
            (461.629, 246.049, 752, 0.00011556)
        );
        assert_eq!(c.cameras[1].model.distortion.p2, 0.00057686);
        let p = c.right_from_left.unwrap();
        assert!((p.translation_m[0] + 0.11003785).abs() < 1e-12);
        assert!(p.transform_point([0.0, 0.0, 1.0])[0] - 0.00427195 + 0.11003785 < 1e-6);
        let omni = WIKI.replacen("camera_model: pinhole", "camera_model: omni", 1);
        assert!(parse(omni.as_bytes(), &Limits::default())
            .unwrap_err()
            .to_string()
            .contains("line 2"));
    }
}
