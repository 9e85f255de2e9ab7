//! OpenCV FileStorage calibrations (YAML, XML and JSON) → [`CameraModel`]s and stereo
//! extrinsics, plus the format dispatchers the campaign uses for `[[camera]].calibration` and
//! `[rig].right_from_left`.
//!
//! Design: the XML form (here) and the JSON form ([`super::opencv_json`]) are converted into
//! the same [`yaml_lite::Node`] tree as the YAML form, so one interpreter serves all three
//! (formats.md §13). Key names are not standardised, so keys are
//! matched case-insensitively against alias lists and grouped into cameras:
//! * plain keys (`camera_matrix`, `distortion_coefficients`, `image_width`, ...) → camera `""`;
//! * stereo pairs `M1 D1 M2 D2` (or `K1`/`K2`) → cameras `"1"` and `"2"`;
//! * dotted keys (`LEFT.K`, `LEFT.D`, `LEFT.width`, ORB-SLAM `Camera.fx`) → camera `"LEFT"`;
//! * nested maps holding a camera matrix (`omni0: {K, D, R, T, width, height}`) → `"omni0"`.
//!
//! A camera needs a 3x3 `K` (a 3x2 is an error naming the key) or `fx fy cx cy` scalars.
//! OpenCV already uses the pixel-centre convention of `camera_model`, so `cx, cy` are copied
//! unchanged. Distortion may have 0 or 4–14 coefficients (`k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4
//! [τx τy]]]]`, as 5x1 or 1x5); regolith's model keeps `k1 k2 p1 p2 k3`, so a non-zero
//! coefficient beyond the fifth is an `Unsupported` error naming the OpenCV model it implies.
//! Image size comes from `image_width`/`image_height` (or `width`/`height`); when the file has
//! none, `width = height = 0` and the campaign's `[[camera]].image_size` must supply it.
//!
//! Translations (`T`): OpenCV writes them in the calibration board's unit. We assume metres,
//! unless `|T| > 10`, which no stereo baseline in metres reaches: then the file is in
//! millimetres and T is divided by 1000 (campaign.md states the same rule).

use std::path::Path;

use regolith_format::camera_model::{CameraModel, Distortion, MODEL_ID};
use regolith_format::frames::Pose;
use regolith_format::limits::Limits;

use super::yaml_lite::{self, Matrix, Node, Value};
use super::{
    calib_bouguet, calib_bouguet_mat, calib_kalibr, calib_ros, markers, opencv_json, opencv_storage,
};
use crate::error::{IngestError, Result};

const K_ALIASES: &[&str] = &[
    "camera_matrix",
    "cameramatrix",
    "k",
    "intrinsic_matrix",
    "intrinsics",
];
const D_ALIASES: &[&str] = &[
    "distortion_coefficients",
    "distortion_coeffs",
    "distcoeffs",
    "dist_coeffs",
    "d",
    "distortion",
];
const W_ALIASES: &[&str] = &["image_width", "width", "imagewidth"];
const H_ALIASES: &[&str] = &["image_height", "height", "imageheight"];

/// One camera of a calibration file.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedCamera {
    /// Group name in the file (`""` for a single-camera file, `"1"` for `M1`, `"LEFT"`, `"omni0"`).
    pub name: String,
    /// The intrinsics.
    pub model: CameraModel,
    /// The camera's own `R`, `T` when the file gives both (`X_cam = R X_ref + T`), metres.
    pub extrinsics: Option<Pose>,
}

/// The pose of the right camera of a stereo pair relative to the left.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoExtrinsics {
    /// `X_right = R X_left + T`, T in metres.
    pub right_from_left: Pose,
}

/// Everything a FileStorage calibration holds that regolith uses.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OpencvCalibration {
    /// Cameras in file order.
    pub cameras: Vec<NamedCamera>,
    /// Top-level `R`, `T` of a stereo calibration.
    pub stereo: Option<StereoExtrinsics>,
}

/// Reads a `.yml`/`.yaml`/`.xml`/`.json` FileStorage file.
pub fn read_path(path: &Path, limits: &Limits) -> Result<OpencvCalibration> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Parses YAML, XML or JSON ([`opencv_storage::parse`]) and interprets the calibration.
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<OpencvCalibration> {
    interpret(&opencv_storage::parse(bytes, limits)?)
}

/// Builds the cameras and stereo extrinsics of a parsed FileStorage root.
fn interpret(root: &Node) -> Result<OpencvCalibration> {
    let mut groups: Groups<'_> = Vec::new();
    let mut root_entries = Vec::new();
    for (key, node) in root.entries() {
        if let Some((g, k)) = key.split_once('.') {
            add(&mut groups, g, k, node);
        } else if let Some(n) = stereo_index(key) {
            add(
                &mut groups,
                n,
                if key.starts_with(['D', 'd']) {
                    "D"
                } else {
                    "K"
                },
                node,
            );
        } else if node.get_any(K_ALIASES).is_some()
            && matches!(node.value, Value::Map(_))
            && node.get("rows").is_none()
        {
            for (k, v) in node.entries() {
                add(&mut groups, key, k, v);
            }
        } else {
            root_entries.push((key.clone(), node));
        }
    }
    let root_size = size_of(&root_entries)?;
    let mut out = OpencvCalibration::default();
    let mut all = vec![(String::new(), root_entries)];
    all.extend(groups);
    for (name, keys) in &all {
        if let Some(model) = camera_of(keys, root_size)? {
            let extrinsics = match (find(keys, &["r"]), find(keys, &["t"])) {
                (Some(r), Some(t)) if !name.is_empty() => Some(pose_from_rt(r, t)?),
                _ => None,
            };
            out.cameras.push(NamedCamera {
                name: name.clone(),
                model,
                extrinsics,
            });
        }
    }
    if let Some((_, keys)) = all.first() {
        if let (Some(r), Some(t)) = (find(keys, &["r"]), find(keys, &["t"])) {
            out.stereo = Some(StereoExtrinsics {
                right_from_left: pose_from_rt(r, t)?,
            });
        }
    }
    if out.cameras.is_empty() && out.stereo.is_none() {
        return Err(IngestError::invalid(
            "no camera matrix (camera_matrix, K, M1, LEFT.K, ...) and no stereo R, T found",
        )
        .at_line(root.line.max(1)));
    }
    Ok(out)
}

type Groups<'a> = Vec<(String, Vec<(String, &'a Node)>)>;

fn add<'a>(groups: &mut Groups<'a>, group: &str, key: &str, node: &'a Node) {
    match groups.iter_mut().find(|(g, _)| g == group) {
        Some((_, v)) => v.push((key.to_string(), node)),
        None => groups.push((group.to_string(), vec![(key.to_string(), node)])),
    }
}

/// `M1`/`K1`/`D1` → `"1"`.
fn stereo_index(key: &str) -> Option<&str> {
    let (head, tail) = key.split_at_checked(1)?;
    let ok =
        ["M", "K", "D"].iter().any(|h| head.eq_ignore_ascii_case(h)) && matches!(tail, "1" | "2");
    ok.then_some(tail)
}

fn find<'a>(keys: &[(String, &'a Node)], aliases: &[&str]) -> Option<&'a Node> {
    keys.iter()
        .find(|(k, _)| aliases.iter().any(|a| k.eq_ignore_ascii_case(a)))
        .map(|(_, n)| *n)
}

fn size_of(keys: &[(String, &Node)]) -> Result<Option<(u32, u32)>> {
    match (find(keys, W_ALIASES), find(keys, H_ALIASES)) {
        (Some(w), Some(h)) => Ok(Some((dim(w)?, dim(h)?))),
        _ => Ok(None),
    }
}

fn dim(n: &Node) -> Result<u32> {
    u32::try_from(n.as_u64()?).map_err(|_| n.error("an image side that fits in 32 bits"))
}

/// The camera of one key group, if it has intrinsics.
fn camera_of(
    keys: &[(String, &Node)],
    fallback_size: Option<(u32, u32)>,
) -> Result<Option<CameraModel>> {
    let (w, h) = size_of(keys)?.or(fallback_size).unwrap_or((0, 0));
    let dist = match find(keys, D_ALIASES) {
        Some(d) => distortion(&d.as_matrix()?.data, d.line, "")?,
        None => coefficients_by_name(keys)?,
    };
    if let Some((name, k)) = keys
        .iter()
        .find(|(k, _)| K_ALIASES.iter().any(|a| k.eq_ignore_ascii_case(a)))
    {
        return camera_from_k(&k.as_matrix()?, dist, (w, h), name, k.line).map(Some);
    }
    let scalars: Option<Vec<&Node>> = ["fx", "fy", "cx", "cy"]
        .iter()
        .map(|a| find(keys, &[a]))
        .collect();
    let Some(s) = scalars else { return Ok(None) };
    let v: Vec<f64> = s.iter().map(|n| n.as_f64()).collect::<Result<_>>()?;
    let (line, k) = (s.first().map_or(0, |n| n.line), v);
    let get = |i: usize| k.get(i).copied().unwrap_or(0.0);
    let m = Matrix {
        rows: 3,
        cols: 3,
        data: vec![get(0), 0.0, get(2), 0.0, get(1), get(3), 0.0, 0.0, 1.0],
    };
    camera_from_k(&m, dist, (w, h), "fx fy cx cy", line).map(Some)
}

/// ORB-SLAM style `k1 k2 p1 p2 [k3]` scalars (absent → zero).
fn coefficients_by_name(keys: &[(String, &Node)]) -> Result<Distortion> {
    let mut c = [0.0; 5];
    for (slot, name) in c.iter_mut().zip(["k1", "k2", "p1", "p2", "k3"]) {
        if let Some(n) = find(keys, &[name]) {
            *slot = n.as_f64()?;
        }
    }
    Ok(Distortion {
        k1: c[0],
        k2: c[1],
        p1: c[2],
        p2: c[3],
        k3: c[4],
    })
}

/// Checks a 3x3 camera matrix and builds the model (shared by the ROS and Kalibr readers).
pub(crate) fn camera_from_k(
    k: &Matrix,
    distortion: Distortion,
    size: (u32, u32),
    key: &str,
    line: u64,
) -> Result<CameraModel> {
    camera_from_k_with(k, distortion, size, key, |e| e.at_line(line))
}

/// [`camera_from_k`] with the location given by `locate` (a byte offset for `.mat` files).
pub(crate) fn camera_from_k_with(
    k: &Matrix,
    distortion: Distortion,
    size: (u32, u32),
    key: &str,
    locate: impl Fn(IngestError) -> IngestError,
) -> Result<CameraModel> {
    if (k.rows, k.cols) != (3, 3) {
        return Err(locate(IngestError::invalid(format!(
            "camera matrix `{key}` is {}x{}; expected 3x3",
            k.rows, k.cols
        ))));
    }
    let at = |i: usize| k.data.get(i).copied().unwrap_or(f64::NAN);
    let tail_ok = at(3).abs() < 1e-9
        && at(6).abs() < 1e-9
        && at(7).abs() < 1e-9
        && (at(8) - 1.0).abs() < 1e-9;
    if !tail_ok || at(0) <= 0.0 || at(4) <= 0.0 {
        return Err(locate(IngestError::invalid(format!(
            "camera matrix `{key}` must be [fx s cx; 0 fy cy; 0 0 1] with fx, fy > 0"
        ))));
    }
    Ok(CameraModel {
        model: MODEL_ID.to_string(),
        width: size.0,
        height: size.1,
        fx: at(0),
        fy: at(4),
        cx: at(2),
        cy: at(5),
        skew: at(1),
        distortion,
    })
}

/// Maps OpenCV's 0 or 4–14 coefficients to Brown–Conrady; `model` names the source's
/// distortion model for the error message when coefficients beyond `k3` are non-zero.
pub(crate) fn distortion(c: &[f64], line: u64, model: &str) -> Result<Distortion> {
    let n = c.len();
    if n != 0 && !(4..=14).contains(&n) {
        return Err(IngestError::invalid(format!(
            "distortion has {n} coefficients; expected 0 or 4 to 14"
        ))
        .at_line(line));
    }
    if let Some(i) = c.iter().skip(5).position(|v| *v != 0.0) {
        let implied = match i + 5 {
            5..=7 => "rational (k4 k5 k6)",
            8..=11 => "thin-prism (s1..s4)",
            _ => "tilted (τx τy)",
        };
        let from = if model.is_empty() {
            String::new()
        } else {
            format!(" `{model}`")
        };
        return Err(IngestError::Unsupported(format!(
            "distortion model{from} with non-zero {implied} coefficients; regolith models k1 k2 p1 p2 k3 only"
        ))
        .at_line(line));
    }
    let g = |i: usize| c.get(i).copied().unwrap_or(0.0);
    Ok(Distortion {
        k1: g(0),
        k2: g(1),
        p1: g(2),
        p2: g(3),
        k3: g(4),
    })
}

/// `R` (3x3, or a 3-vector Rodrigues) and `T` (3 values) → pose, T metres (mm if `|T| > 10`).
fn pose_from_rt(r: &Node, t: &Node) -> Result<Pose> {
    let rm = r.as_matrix()?;
    let rot = match rm.data.len() {
        9 => markers::rotation_from_rows(&rm.data),
        3 => markers::rotation_from_vector(
            [rm.data.first(), rm.data.get(1), rm.data.get(2)].map(|v| v.copied().unwrap_or(0.0)),
        ),
        _ => None,
    }
    .ok_or_else(|| r.error("a 3x3 rotation matrix or a rotation vector"))?;
    let tv = t.as_matrix()?.data;
    let [x, y, z] =
        <[f64; 3]>::try_from(tv.as_slice()).map_err(|_| t.error("a 3-element translation"))?;
    Ok(Pose::from_matrix(rot, metres_from_file_units([x, y, z])))
}

/// The unit rule for stereo translations: metres unless `|T| > 10`, then millimetres.
pub(crate) fn metres_from_file_units(t: [f64; 3]) -> [f64; 3] {
    let norm = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    if norm > 10.0 {
        t.map(|v| v / 1000.0)
    } else {
        t
    }
}

/// The formats [`read_any_calibration`] recognises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibrationFormat {
    /// OpenCV FileStorage YAML, XML or JSON.
    Opencv,
    /// ROS `camera_info` YAML.
    Ros,
    /// Kalibr camchain YAML.
    Kalibr,
    /// Bouguet `Calib_Results.m` (or a user-made `Calib_Results_stereo.m`).
    Bouguet,
    /// Bouguet `Calib_Results_stereo.mat` / `Calib_Results.mat` (MATLAB Level-5 binary).
    BouguetMat,
}

/// Detects the format from the extension and content.
pub fn detect_format(path: &Path, bytes: &[u8], limits: &Limits) -> Result<CalibrationFormat> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if ext == "m" {
        return Ok(CalibrationFormat::Bouguet);
    }
    if ext == "mat" || bytes.starts_with(b"MATLAB ") {
        return Ok(CalibrationFormat::BouguetMat);
    }
    if ext == "xml" || ext == "json" || opencv_storage::is_xml(bytes) || opencv_json::is_json(bytes)
    {
        return Ok(CalibrationFormat::Opencv);
    }
    let root = yaml_lite::parse(bytes, limits)?;
    let has = |k: &[&str]| root.get_any(k).is_some();
    Ok(
        if root
            .get("cam0")
            .is_some_and(|c| c.get("intrinsics").is_some())
        {
            CalibrationFormat::Kalibr
        } else if has(&[
            "distortion_model",
            "camera_name",
            "distortion_coefficents",
            "projection_matrix",
        ]) {
            CalibrationFormat::Ros
        } else {
            CalibrationFormat::Opencv
        },
    )
}

/// All cameras of any supported calibration file, by name.
pub fn read_any_cameras(path: &Path, limits: &Limits) -> Result<Vec<NamedCamera>> {
    yaml_lite::read_with(path, limits, |bytes| {
        match detect_format(path, bytes, limits)? {
            CalibrationFormat::Opencv => parse(bytes, limits).map(|c| c.cameras),
            CalibrationFormat::Ros => calib_ros::parse(bytes, limits).map(|m| vec![single(m)]),
            CalibrationFormat::Kalibr => calib_kalibr::parse(bytes, limits).map(|c| c.cameras),
            CalibrationFormat::Bouguet => {
                calib_bouguet::parse(bytes, limits).map(|m| vec![single(m)])
            }
            CalibrationFormat::BouguetMat => calib_bouguet_mat::parse_cameras(bytes, limits),
        }
    })
}

fn single(model: CameraModel) -> NamedCamera {
    NamedCamera {
        name: String::new(),
        model,
        extrinsics: None,
    }
}

/// The camera of a calibration file; `entry` picks one of several (`"1"`, `"LEFT"`, `"cam0"`).
pub fn read_calibration_entry(
    path: &Path,
    entry: Option<&str>,
    limits: &Limits,
) -> Result<CameraModel> {
    let cams = read_any_cameras(path, limits)?;
    let names = || {
        cams.iter()
            .map(|c| format!("{:?}", c.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let pick = match entry {
        Some(e) => cams.iter().find(|c| c.name.eq_ignore_ascii_case(e)),
        None if cams.len() == 1 => cams.first(),
        None => None,
    };
    pick.map(|c| c.model.clone()).ok_or_else(|| {
        let what = entry.map_or("exactly one camera".to_string(), |e| {
            format!("a camera named {e:?}")
        });
        IngestError::invalid(format!("expected {what}; the file has {}", names())).in_file(path)
    })
}

/// The single camera of any supported calibration file (`[[camera]].calibration`).
pub fn read_any_calibration(path: &Path) -> Result<CameraModel> {
    read_calibration_entry(path, None, &Limits::default())
}

/// `right_from_left` of any supported stereo file (`[rig].right_from_left`): OpenCV `R`,`T`,
/// Bouguet `om`,`T` (`.m` or `.mat`), or Kalibr `cam1.T_cn_cnm1`.
pub fn read_any_stereo(path: &Path) -> Result<Pose> {
    let limits = Limits::default();
    yaml_lite::read_with(path, &limits, |bytes| {
        let pose = match detect_format(path, bytes, &limits)? {
            CalibrationFormat::Bouguet => Some(calib_bouguet::parse_stereo(bytes, &limits)?),
            CalibrationFormat::BouguetMat => Some(calib_bouguet_mat::parse_stereo(bytes, &limits)?),
            CalibrationFormat::Kalibr => calib_kalibr::parse(bytes, &limits)?.right_from_left,
            CalibrationFormat::Opencv | CalibrationFormat::Ros => {
                parse(bytes, &limits)?.stereo.map(|s| s.right_from_left)
            }
        };
        pose.ok_or_else(|| {
            IngestError::invalid("no stereo extrinsics (R and T, om and T, or T_cn_cnm1) found")
        })
    })
}
