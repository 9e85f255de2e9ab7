//! The texture camera's calibration as a Bouguet toolbox `Calib_Results.m`.
//!
//! Layout of formats.md §12.1 (header comments, `fc`, `cc`, `alpha_c`, `kc`, their `_error`
//! twins, `nx`/`ny`, the estimation flags, and per-image extrinsics `omc_i`/`Tc_i` with one
//! inactive image written as `NaN`, as real files have). `cc` is written in Bouguet's
//! convention, which formats.md states is 0-based like OpenCV (pixel centre), so it equals our
//! `cx, cy`; `alpha_c` is skew / fx; `kc = [k1; k2; p1; p2; k3]`.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use regolith_format::camera_model::CameraModel;

fn vec_line(name: &str, v: &[f64], pad: &str) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.15}")).collect();
    format!("{name}{pad}= [ {} ];\n", parts.join(" ; "))
}

fn exp_vec(name: &str, v: &[f64], pad: &str) -> String {
    let parts: Vec<String> = v.iter().map(|x| crate::sink::sci(*x, 6)).collect();
    format!("{name}{pad}= [ {} ];\n", parts.join(" ; "))
}

/// The `Calib_Results.m` text of `cam` with `images` calibration views.
pub fn calib_results_m(cam: &CameraModel, images: usize, rng: &mut ChaCha8Rng) -> String {
    let d = cam.distortion;
    let mut s = String::from(
        "% Intrinsic and Extrinsic Camera Parameters\n%\n\
         % This script file can be directly executed under Matlab to recover the camera intrinsic and extrinsic parameters.\n\
         % IMPORTANT: This file contains neither the structure of the calibration objects nor the image coordinates of the calibration points.\n\
         %            All those complementary variables are saved in the complete matlab data file Calib_Results.mat.\n\
         % For more information regarding the calibration model visit http://www.vision.caltech.edu/bouguetj/calib_doc/\n\n\n",
    );
    s.push_str("%-- Focal length:\n");
    s.push_str(&vec_line("fc", &[cam.fx, cam.fy], " "));
    s.push_str("\n%-- Principal point:\n");
    s.push_str(&vec_line("cc", &[cam.cx, cam.cy], " "));
    s.push_str("\n%-- Skew coefficient:\n");
    s.push_str(&format!("alpha_c = {:.15};\n", cam.skew / cam.fx));
    s.push_str("\n%-- Distortion coefficients:\n");
    s.push_str(&vec_line("kc", &[d.k1, d.k2, d.p1, d.p2, d.k3], " "));
    s.push_str("\n%-- Focal length uncertainty:\n");
    s.push_str(&vec_line("fc_error", &[2.25, 2.19], " "));
    s.push_str("\n%-- Principal point uncertainty:\n");
    s.push_str(&vec_line("cc_error", &[2.45, 1.87], " "));
    s.push_str("\n%-- Skew coefficient uncertainty:\n");
    s.push_str(&format!("alpha_c_error = {:.15};\n", 0.0));
    s.push_str("\n%-- Distortion coefficients uncertainty:\n");
    s.push_str(&vec_line(
        "kc_error",
        &[0.0061, 0.0302, 0.0006, 0.0005, 0.0],
        " ",
    ));
    s.push_str(&format!(
        "\n%-- Image size:\nnx = {};\nny = {};\n\n\n",
        cam.width, cam.height
    ));
    s.push_str(
        "%-- Various other variables (may be ignored if you do not use the Matlab Calibration Toolbox):\n\
         %-- Those variables are used to control which intrinsic parameters should be optimized\n\n",
    );
    s.push_str(&format!(
        "n_ima = {images};\t\t\t\t\t\t% Number of calibration images\n"
    ));
    s.push_str("est_fc = [ 1 ; 1 ];\t\t\t\t\t% Estimation indicator of the two focal variables\n");
    s.push_str(
        "est_aspect_ratio = 1;\t\t\t\t% Estimation indicator of the aspect ratio fc(2)/fc(1)\n",
    );
    s.push_str("center_optim = 1;\t\t\t\t\t% Estimation indicator of the principal point\n");
    s.push_str("est_alpha = 0;\t\t\t\t\t\t% Estimation indicator of the skew coefficient\n");
    s.push_str("est_dist = [ 1 ; 1 ; 1 ; 1 ; 0 ];\t% Estimation indicator of the distortion coefficients\n\n\n");
    s.push_str("%-- Extrinsic parameters:\n%-- The rotation (omc_kk) and the translation (Tc_kk) vectors for every calibration image and their uncertainties\n");
    for i in 1..=images {
        let inactive = i == images.min(5);
        let mut draw = |lo: f64, hi: f64| {
            if inactive {
                f64::NAN
            } else {
                rng.gen_range(lo..hi)
            }
        };
        let om = [draw(-2.3, 2.3), draw(-2.3, 2.3), draw(-0.3, 0.3)];
        let tc = [draw(-150.0, 150.0), draw(-150.0, 150.0), draw(400.0, 900.0)];
        s.push_str(&format!("\n%-- Image #{i}:\n"));
        s.push_str(&exp_vec(&format!("omc_{i}"), &om, " "));
        s.push_str(&exp_vec(&format!("Tc_{i}"), &tc, "  "));
        s.push_str(&exp_vec(
            &format!("omc_error_{i}"),
            &om.map(|v| (v * 0.006).abs()),
            " ",
        ));
        s.push_str(&exp_vec(
            &format!("Tc_error_{i}"),
            &tc.map(|v| (v * 0.02).abs()),
            "  ",
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// Values of `name = [ a ; b ; ... ];` parsed back.
    fn values(m: &str, name: &str) -> Vec<f64> {
        let line = m
            .lines()
            .find(|l| l.split('=').next().map(str::trim) == Some(name))
            .unwrap();
        let inner = line.split('[').nth(1).unwrap().split(']').next().unwrap();
        inner
            .split(';')
            .map(|v| v.trim().parse::<f64>().unwrap())
            .collect()
    }

    #[test]
    fn layout_follows_the_toolbox_and_values_round_trip() {
        // Thesis Table 5.4 values; the formats.md §12.1 layout.
        let c = CameraModel::pinhole(1024, 768, 970.31, 973.12, 509.42, 393.54);
        let m = calib_results_m(&c, 6, &mut ChaCha8Rng::seed_from_u64(3));
        assert!(m.starts_with("% Intrinsic and Extrinsic Camera Parameters"));
        assert_eq!(values(&m, "fc"), vec![970.31, 973.12]);
        assert_eq!(values(&m, "cc"), vec![509.42, 393.54]);
        assert_eq!(values(&m, "kc").len(), 5);
        assert!(m.contains("nx = 1024;\nny = 768;"));
        assert!(
            m.contains("Tc_1  = [ "),
            "two spaces after Tc_i as the toolbox writes"
        );
        assert!(values(&m, "omc_5").iter().all(|v| v.is_nan()));
        assert!(values(&m, "Tc_2")[2] > 400.0);
    }
}
