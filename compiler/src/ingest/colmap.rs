//! COLMAP sparse models in text form (`cameras.txt`, `images.txt`, `points3D.txt`,
//! formats.md §11) into regolith cameras, poses and a coloured point cloud.
//!
//! Design decisions:
//!
//! - **Camera models** `SIMPLE_PINHOLE`, `PINHOLE`, `SIMPLE_RADIAL`, `RADIAL`, `OPENCV` map
//!   exactly onto the format's pinhole + Brown–Conrady [`CameraModel`] (`SIMPLE_RADIAL`'s `k`
//!   is `k1`; `RADIAL`'s `k1, k2`). `FULL_OPENCV` maps when its rational terms `k4..k6` are 0.
//!   Fisheye and the other models are reported as unsupported, naming the model.
//! - **Pixel convention.** COLMAP puts the *corner* of the top-left pixel at (0, 0), so the
//!   centre of that pixel is (0.5, 0.5); regolith (like OpenCV) puts its centre at (0, 0).
//!   Hence `cx = cx_colmap − 0.5`, `cy = cy_colmap − 0.5`, and the 2D observations of
//!   `images.txt` are shifted by the same −0.5 so they stay consistent with the camera.
//! - **Poses.** `images.txt` stores the world→camera transform (`QW QX QY QZ`, Hamilton, w
//!   first, then `TX TY TZ`). We return [`ColmapImage::world_from_camera`], its inverse (the
//!   camera pose in the model frame, what a `ground_from_camera` becomes after the model is
//!   aligned), with the quaternion reordered to regolith's x, y, z, w.
//! - `images.txt` has exactly two lines per image and the observation line **may be empty**,
//!   so only `#` comment lines are skipped, never blank ones; a missing last observation line
//!   at the end of the file is accepted. The name is the rest of the line after `CAMERA_ID`
//!   (names may contain spaces and subfolders). Ids are unordered and non-contiguous, so
//!   cameras and images are kept in `BTreeMap`s keyed by id (deterministic order).
//! - Every error names the line; [`read_dir`] adds the file.

use std::collections::BTreeMap;
use std::path::Path;

use regolith_format::camera_model::{CameraModel, Distortion};
use regolith_format::frames::Pose;
use regolith_format::limits::Limits;

use crate::error::{IngestError, Result};
use crate::ingest::images::read_file;
use crate::ingest::types::PointCloud;

/// One camera of `cameras.txt`.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapCamera {
    /// COLMAP model name as written (`SIMPLE_RADIAL`, ...).
    pub model_name: String,
    /// The same intrinsics in regolith's model and pixel convention.
    pub camera: CameraModel,
}

/// A 2D observation of `images.txt`, in regolith's pixel convention.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Pixel position (centre of the top-left pixel = (0, 0)).
    pub xy: [f64; 2],
    /// The 3D point it belongs to, if triangulated (`-1` in the file is `None`).
    pub point3d_id: Option<u64>,
}

/// One image of `images.txt`.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapImage {
    /// Camera id in `cameras.txt`.
    pub camera_id: u32,
    /// File name relative to the image folder (may contain subfolders).
    pub name: String,
    /// Camera pose in the model frame: the inverse of the file's world→camera transform.
    pub world_from_camera: Pose,
    /// 2D observations in file order (indexed by `POINT2D_IDX` in tracks).
    pub observations: Vec<Observation>,
}

/// The 3D points of `points3D.txt`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColmapPoints {
    /// Positions and colours (`rgb` is always `Some`).
    pub cloud: PointCloud,
    /// COLMAP point ids, one per point.
    pub ids: Vec<u64>,
    /// Mean reprojection error in pixels, one per point.
    pub errors: Vec<f64>,
    /// Track per point: `(image id, index into that image's observations)`.
    pub tracks: Vec<Vec<(u32, u32)>>,
}

/// A whole text model.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColmapModel {
    /// Cameras by id.
    pub cameras: BTreeMap<u32, ColmapCamera>,
    /// Images by id.
    pub images: BTreeMap<u32, ColmapImage>,
    /// Triangulated points.
    pub points: ColmapPoints,
}

/// Reads `cameras.txt`, `images.txt` and `points3D.txt` from a model folder and checks that
/// every image names a known camera. Errors name the file and the line.
pub fn read_dir(dir: &Path, limits: &Limits) -> Result<ColmapModel> {
    let load = |name: &str| -> Result<(std::path::PathBuf, Vec<u8>)> {
        let p = dir.join(name);
        Ok((p.clone(), read_file(&p, limits)?))
    };
    let (p, b) = load("cameras.txt")?;
    let cameras = parse_cameras(&b).map_err(|e| e.in_file(&p))?;
    let (p, b) = load("images.txt")?;
    let images = parse_images(&b, limits).map_err(|e| e.in_file(&p))?;
    for (id, img) in &images {
        if !cameras.contains_key(&img.camera_id) {
            let msg = format!(
                "image {id} uses camera {}, absent from cameras.txt",
                img.camera_id
            );
            return Err(IngestError::invalid(msg).in_file(&p));
        }
    }
    let (p, b) = load("points3D.txt")?;
    let points = parse_points3d(&b, limits).map_err(|e| e.in_file(&p))?;
    Ok(ColmapModel {
        cameras,
        images,
        points,
    })
}

/// Parses `cameras.txt`.
pub fn parse_cameras(bytes: &[u8]) -> Result<BTreeMap<u32, ColmapCamera>> {
    let mut out = BTreeMap::new();
    for (line_no, line) in data_lines(bytes)? {
        if line.trim().is_empty() {
            continue;
        }
        let cam = parse_camera(line).map_err(|e| e.at_line(line_no))?;
        if out.insert(cam.0, cam.1).is_some() {
            return Err(IngestError::invalid("duplicate CAMERA_ID").at_line(line_no));
        }
    }
    Ok(out)
}

fn parse_camera(line: &str) -> Result<(u32, ColmapCamera)> {
    let mut f = line.split_ascii_whitespace();
    let id = int::<u32>(f.next(), "CAMERA_ID")?;
    let model_name = f.next().unwrap_or_default().to_string();
    let width = int::<u32>(f.next(), "WIDTH")?;
    let height = int::<u32>(f.next(), "HEIGHT")?;
    let p = f
        .map(|s| num(Some(s), "a camera parameter"))
        .collect::<Result<Vec<f64>>>()?;
    let want = match model_name.as_str() {
        "SIMPLE_PINHOLE" => 3,
        "PINHOLE" | "SIMPLE_RADIAL" => 4,
        "RADIAL" => 5,
        "OPENCV" => 8,
        "FULL_OPENCV" => 12,
        other => {
            return Err(IngestError::Unsupported(format!(
                "COLMAP camera model {other:?}"
            )))
        }
    };
    if p.len() != want {
        let msg = format!("{want} parameters for {model_name}, found {}", p.len());
        return Err(IngestError::invalid(msg));
    }
    let g = |i: usize| p.get(i).copied().unwrap_or_default();
    // (fx, fy, cx, cy, distortion)
    let (fx, fy, cx, cy, d) = match model_name.as_str() {
        "SIMPLE_PINHOLE" => (g(0), g(0), g(1), g(2), Distortion::default()),
        "PINHOLE" => (g(0), g(1), g(2), g(3), Distortion::default()),
        "SIMPLE_RADIAL" => (
            g(0),
            g(0),
            g(1),
            g(2),
            Distortion {
                k1: g(3),
                ..Default::default()
            },
        ),
        "RADIAL" => (
            g(0),
            g(0),
            g(1),
            g(2),
            Distortion {
                k1: g(3),
                k2: g(4),
                ..Default::default()
            },
        ),
        _ => {
            if (9..12).any(|i| g(i) != 0.0) {
                let msg = "FULL_OPENCV with rational terms k4..k6 (not Brown–Conrady)";
                return Err(IngestError::Unsupported(msg.into()));
            }
            let d = Distortion {
                k1: g(4),
                k2: g(5),
                p1: g(6),
                p2: g(7),
                k3: g(8),
            };
            (g(0), g(1), g(2), g(3), d)
        }
    };
    let mut camera = CameraModel::pinhole(width, height, fx, fy, cx - 0.5, cy - 0.5);
    camera.distortion = d;
    camera.validate()?;
    Ok((id, ColmapCamera { model_name, camera }))
}

/// Parses `images.txt` (two lines per image; the second may be empty).
pub fn parse_images(bytes: &[u8], limits: &Limits) -> Result<BTreeMap<u32, ColmapImage>> {
    let mut out = BTreeMap::new();
    let mut lines = data_lines(bytes)?.into_iter();
    while let Some((line_no, head)) = lines.next() {
        if head.trim().is_empty() {
            continue; // blank line where a header is expected (e.g. trailing newlines)
        }
        let (id, mut img) = parse_image_header(head).map_err(|e| e.at_line(line_no))?;
        if let Some((obs_line, obs)) = lines.next() {
            img.observations = parse_observations(obs, limits).map_err(|e| e.at_line(obs_line))?;
        }
        if out.insert(id, img).is_some() {
            return Err(IngestError::invalid(format!("duplicate IMAGE_ID {id}")).at_line(line_no));
        }
    }
    Ok(out)
}

fn parse_image_header(line: &str) -> Result<(u32, ColmapImage)> {
    let mut rest = line;
    let mut field = |what: &str| -> Result<&str> {
        let s = rest.trim_start();
        let end = s.find(|c: char| c.is_ascii_whitespace()).unwrap_or(s.len());
        let (t, tail) = s.split_at_checked(end).unwrap_or((s, ""));
        rest = tail;
        if t.is_empty() {
            let expected = format!("{what} (IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME)");
            return Err(IngestError::syntax(expected, line));
        }
        Ok(t)
    };
    let id = int::<u32>(Some(field("IMAGE_ID")?), "IMAGE_ID")?;
    let mut v = [0.0; 7];
    for (slot, what) in v.iter_mut().zip(["QW", "QX", "QY", "QZ", "TX", "TY", "TZ"]) {
        *slot = num(Some(field(what)?), what)?;
    }
    let camera_id = int::<u32>(Some(field("CAMERA_ID")?), "CAMERA_ID")?;
    let name = rest.trim().to_string();
    if name.is_empty() {
        return Err(IngestError::syntax("an image NAME after CAMERA_ID", line));
    }
    let [qw, qx, qy, qz, tx, ty, tz] = v;
    let norm = (qw * qw + qx * qx + qy * qy + qz * qz).sqrt();
    if !(norm > 0.5 && norm < 2.0) {
        return Err(IngestError::invalid(format!(
            "quaternion norm {norm}: expected a unit quaternion"
        )));
    }
    let camera_from_world = Pose {
        translation_m: [tx, ty, tz],
        rotation_xyzw: [qx, qy, qz, qw],
    };
    let world_from_camera = camera_from_world.inverse();
    Ok((
        id,
        ColmapImage {
            camera_id,
            name,
            world_from_camera,
            observations: Vec::new(),
        },
    ))
}

fn parse_observations(line: &str, limits: &Limits) -> Result<Vec<Observation>> {
    let f: Vec<&str> = line.split_ascii_whitespace().collect();
    if !f.len().is_multiple_of(3) {
        return Err(IngestError::invalid(format!(
            "{} values: expected triples X Y POINT3D_ID",
            f.len()
        )));
    }
    Limits::check_len("2D observations", (f.len() / 3) as u64, limits.max_points)?;
    f.chunks_exact(3)
        .map(|c| {
            let x = num(c.first().copied(), "X")? - 0.5;
            let y = num(c.get(1).copied(), "Y")? - 0.5;
            let id = int::<i64>(c.get(2).copied(), "POINT3D_ID")?;
            Ok(Observation {
                xy: [x, y],
                point3d_id: u64::try_from(id).ok(),
            })
        })
        .collect()
}

/// Parses `points3D.txt`.
pub fn parse_points3d(bytes: &[u8], limits: &Limits) -> Result<ColmapPoints> {
    let mut out = ColmapPoints::default();
    let mut rgb = Vec::new();
    for (line_no, line) in data_lines(bytes)? {
        let at = |e: IngestError| e.at_line(line_no);
        let f: Vec<&str> = line.split_ascii_whitespace().collect();
        if f.is_empty() {
            continue;
        }
        if f.len() < 8 || !f.len().is_multiple_of(2) {
            let msg = "POINT3D_ID X Y Z R G B ERROR then (IMAGE_ID POINT2D_IDX) pairs";
            return Err(at(IngestError::syntax(msg, line)));
        }
        Limits::check_len("points", out.ids.len() as u64 + 1, limits.max_points)
            .map_err(|e| at(e.into()))?;
        let g = |i: usize, what: &str| num(f.get(i).copied(), what).map_err(at);
        let xyz = [g(1, "X")?, g(2, "Y")?, g(3, "Z")?];
        if !xyz.iter().all(|v| v.is_finite()) {
            return Err(at(IngestError::invalid(format!(
                "point {xyz:?} is not finite"
            ))));
        }
        let c = |i: usize, what: &str| int::<u8>(f.get(i).copied(), what).map_err(at);
        rgb.push([c(4, "R")?, c(5, "G")?, c(6, "B")?]);
        out.ids
            .push(int::<u64>(f.first().copied(), "POINT3D_ID").map_err(at)?);
        out.cloud.points.push(xyz);
        out.errors.push(g(7, "ERROR")?);
        let track = f
            .get(8..)
            .unwrap_or_default()
            .chunks_exact(2)
            .map(|p| {
                Ok((
                    int(p.first().copied(), "IMAGE_ID")?,
                    int(p.get(1).copied(), "POINT2D_IDX")?,
                ))
            })
            .collect::<Result<Vec<(u32, u32)>>>()
            .map_err(at)?;
        out.tracks.push(track);
    }
    out.cloud.rgb = Some(rgb);
    Ok(out)
}

/// Lines with their 1-based numbers, skipping `#` comments (blank lines are kept: they are
/// meaningful in `images.txt`).
fn data_lines(bytes: &[u8]) -> Result<Vec<(u64, &str)>> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes
            .iter()
            .take(e.valid_up_to())
            .filter(|&&b| b == b'\n')
            .count() as u64
            + 1;
        IngestError::invalid("text is not UTF-8").at_line(line)
    })?;
    Ok(text
        .lines()
        .enumerate()
        .map(|(i, l)| (i as u64 + 1, l))
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
        .collect())
}

fn num(s: Option<&str>, what: &str) -> Result<f64> {
    let s = s.unwrap_or_default();
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| IngestError::syntax(format!("{what} (a number)"), s))
}

fn int<T: std::str::FromStr>(s: Option<&str>, what: &str) -> Result<T> {
    let s = s.unwrap_or_default();
    s.parse::<T>()
        .map_err(|_| IngestError::syntax(format!("{what} (an integer)"), s))
}
