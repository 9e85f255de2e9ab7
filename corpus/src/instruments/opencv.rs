//! OpenCV FileStorage YAML writers: one file per camera and a stereo file.
//!
//! Layout as `cv::FileStorage` writes it (formats.md §13.1): the `%YAML:1.0` directive and
//! `---`, `!!opencv-matrix` maps with `rows`, `cols`, `dt: d` and a row-major `data` list that
//! wraps after four numbers, numbers in `%.16e` with a two-digit signed exponent and integral
//! values as `0.` / `1.`. Distortion is written `rows: 1, cols: 5` (k1 k2 p1 p2 k3). The stereo
//! file holds `R` and `T` with `X_right = R * X_left + T`, T in metres.

use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;

/// One number the way OpenCV prints doubles.
pub fn number(v: f64) -> String {
    if v == v.trunc() && v.abs() < 1e15 {
        return format!("{}.", v as i64);
    }
    crate::sink::sci(v, 16)
}

/// Appends one `!!opencv-matrix` entry.
pub fn matrix(out: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]) {
    out.push_str(&format!(
        "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ "
    ));
    for (i, v) in data.iter().enumerate() {
        if i > 0 {
            out.push_str(if i % 4 == 0 { ",\n       " } else { ", " });
        }
        out.push_str(&number(*v));
    }
    out.push_str(" ]\n");
}

/// The calibration file of one camera.
pub fn camera_yaml(cam: &CameraModel, reprojection_error_px: f64) -> String {
    let mut s = format!(
        "%YAML:1.0\n---\ncalibration_time: \"simulated by regolith-corpus\"\nimage_width: {}\nimage_height: {}\n",
        cam.width, cam.height
    );
    matrix(&mut s, "camera_matrix", 3, 3, &cam.k_matrix());
    matrix(&mut s, "distortion_coefficients", 1, 5, &cam.d_vector());
    s.push_str(&format!(
        "avg_reprojection_error: {}\n",
        number(reprojection_error_px)
    ));
    s
}

/// The stereo extrinsics file: `R`, `T` of `right_from_left`.
pub fn stereo_yaml(right_from_left: &Pose) -> String {
    let mut s = String::from("%YAML:1.0\n---\n");
    let r = right_from_left.rotation_matrix();
    let flat: Vec<f64> = r.iter().flatten().copied().collect();
    matrix(&mut s, "R", 3, 3, &flat);
    matrix(&mut s, "T", 3, 1, &right_from_left.translation_m);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::excessive_precision)]
    fn numbers_look_like_opencv() {
        // formats.md §13.1 sample values.
        assert_eq!(number(657.46697810243404), "6.5746697810243404e+02");
        assert_eq!(number(0.0), "0.");
        assert_eq!(number(1.0), "1.");
        assert_eq!(number(-0.41802327018241026), "-4.1802327018241026e-01");
    }

    #[test]
    fn camera_file_has_directive_and_wrapped_data() {
        let c = CameraModel::pinhole(640, 480, 657.5, 657.5, 319.5, 239.5);
        let y = camera_yaml(&c, 0.3);
        assert!(y.starts_with("%YAML:1.0\n---\n"));
        assert!(y.contains("camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 6.5750000000000000e+02, 0., 3.1950000000000000e+02, 0.,\n       6.5750000000000000e+02,"));
        assert!(y.contains("distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n"));
    }
}
