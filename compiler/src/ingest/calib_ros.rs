//! ROS `camera_info` calibration YAML (camera_calibration_parsers' `ost.yaml`) → [`CameraModel`].
//!
//! Real files vary (formats.md §14), and we tolerate all the variants seen:
//! * `distortion_model` may be missing (then the coefficient count decides), or be written as
//!   `camera_model`; `plumb_bob` (5) and `rational_polynomial` (8, with k4..k6 = 0) are read,
//!   `equidistant` (fisheye) is `Unsupported`;
//! * the `distortion_coefficents` typo;
//! * flat lists (`distortion_coefficients: [..]`) instead of `{rows, cols, data}`;
//! * the message form with `K`/`D` (ROS 1) or `k`/`d` (ROS 2), and `%YAML:1.0` hybrids.
//!
//! `camera_matrix` is the raw (distorted) camera. `rectification_matrix` and
//! `projection_matrix` describe the rectified image and are not used: captures are stored raw
//! and undistorted by regolith with this model. ROS uses OpenCV's pixel-centre convention.

use std::path::Path;

use regolith_format::camera_model::CameraModel;
use regolith_format::limits::Limits;

use super::calib_opencv::{camera_from_k, distortion};
use super::yaml_lite::{self, Node};
use crate::error::{IngestError, Result};

/// Reads a `camera_info` YAML file.
pub fn read_path(path: &Path, limits: &Limits) -> Result<CameraModel> {
    yaml_lite::read_with(path, limits, |b| parse(b, limits))
}

/// Parses a `camera_info` YAML document.
pub fn parse(bytes: &[u8], limits: &Limits) -> Result<CameraModel> {
    let root = yaml_lite::parse(bytes, limits)?;
    let missing = |what: &str| IngestError::syntax(what, "nothing").at_line(root.line.max(1));
    let (key, k) = root
        .get_any(&["camera_matrix", "K"])
        .ok_or_else(|| missing("`camera_matrix` (or `K`)"))?;
    let k_matrix = k.as_matrix().map(|mut m| {
        if m.rows == 1 && m.data.len() == 9 {
            (m.rows, m.cols) = (3, 3);
        }
        m
    })?;
    let model = root
        .get_any(&["distortion_model", "camera_model"])
        .and_then(|(_, n)| n.as_str());
    let coeffs = match root.get_any(&["distortion_coefficients", "distortion_coefficents", "D"]) {
        Some((_, d)) => (d.as_matrix()?.data, d.line),
        None => (Vec::new(), k.line),
    };
    let dist = match model.map(str::to_ascii_lowercase).as_deref() {
        None | Some("plumb_bob" | "rational_polynomial" | "radtan" | "pinhole") => {
            distortion(&coeffs.0, coeffs.1, model.unwrap_or(""))?
        }
        Some(other) => {
            let line = root
                .get_any(&["distortion_model", "camera_model"])
                .map_or(0, |(_, n)| n.line);
            return Err(IngestError::Unsupported(format!(
                "distortion model `{other}`; regolith reads plumb_bob and rational_polynomial with k4..k6 = 0"
            ))
            .at_line(line));
        }
    };
    let size = (
        dim(&root, &["image_width", "width"])?,
        dim(&root, &["image_height", "height"])?,
    );
    camera_from_k(&k_matrix, dist, size, key, k.line)
}

fn dim(root: &Node, aliases: &[&str]) -> Result<u32> {
    let (_, n) = root.get_any(aliases).ok_or_else(|| {
        IngestError::syntax(format!("`{}`", aliases.first().unwrap_or(&"")), "nothing")
    })?;
    u32::try_from(n.as_u64()?).map_err(|_| n.error("an image side that fits in 32 bits"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_typo_flat_list_message_form() {
        let l = Limits::default();
        let typo = b"image_width: 800\nimage_height: 600\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [538.63, 0, 457.698, 0, 539.723, 297.003, 0, 0, 1]\ndistortion_coefficents: [-0.30678, 0.0825017, 0.0028784, -0.00015829, 0]\n";
        let c = parse(typo, &l).unwrap();
        assert_eq!(
            (c.width, c.fx, c.cy, c.distortion.k1),
            (800, 538.63, 297.003, -0.30678)
        );
        let msg = b"width: 640\nheight: 480\nK: [500, 0, 320, 0, 500, 240, 0, 0, 1]\nD: []\n";
        assert_eq!(parse(msg, &l).unwrap().cx, 320.0);
        let fisheye = b"width: 640\nheight: 480\nK: [500, 0, 320, 0, 500, 240, 0, 0, 1]\ndistortion_model: equidistant\nD: [0.1, 0, 0, 0]\n";
        assert!(parse(fisheye, &l)
            .unwrap_err()
            .to_string()
            .contains("equidistant"));
    }
}
