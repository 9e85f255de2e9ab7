//! Each hidden effect changes the "real" data the way its parameter says, compared with the
//! plain campaign of the same seed (same terrain, poses, light and noise draws).

use super::common;

use std::path::Path;

use common::*;
use regolith_corpus::instruments::riegl::marker_visible;
use regolith_corpus::terrain::TrueMarker;
use regolith_validator::gap::markers::sight;
use regolith_validator::render::Light;
use regolith_validator::sensor::image::vignetting_factor;

fn frame(dir: &Path, cap: usize, side: &str, k: usize) -> (usize, usize, Vec<f32>) {
    let caps = json(dir, "truth/captures.json");
    let (w, h, px) = grey(&dir.join(caps[cap][side]["files"][k].as_str().unwrap()));
    (w, h, px.into_iter().map(f32::from).collect())
}

#[test]
fn vignetting_darkens_corners_by_the_strength() {
    let dir = mini(7, &[("vignetting", &[("strength", 0.4)])]);
    let cam = camera(&dir, "navcam_left", "true");
    let (w, h, vig) = frame(&dir, 0, "left", 0);
    let (_, _, plain_px) = frame(plain(), 0, "left", 0);
    // The model's promise: the farthest corner gets exactly 1 - strength.
    let corners = [
        (0.0, 0.0),
        ((w - 1) as f64, 0.0),
        (0.0, (h - 1) as f64),
        ((w - 1) as f64, (h - 1) as f64),
    ];
    let min = corners
        .iter()
        .map(|&(u, v)| vignetting_factor(0.4, u, v, w, h, &cam))
        .fold(1.0, f64::min);
    assert!((min - 0.6).abs() < 1e-9);
    let mut checked = 0;
    for (u, v) in [
        (8, h - 9),
        (w - 9, h - 9),
        (w / 2, h - 9),
        (w / 2, h / 2 + 60),
        (60, h - 60),
    ] {
        let p = window_mean(w, &plain_px, u, v, 6);
        if p < 25.0 {
            continue;
        }
        let ratio = window_mean(w, &vig, u, v, 6) / p;
        let expect = vignetting_factor(0.4, u as f64, v as f64, w, h, &cam);
        assert!(
            (ratio - expect).abs() < 0.03,
            "({u}, {v}): ratio {ratio:.3} vs {expect:.3}"
        );
        checked += 1;
    }
    assert!(checked >= 3, "{checked} windows on the terrain");
}

#[test]
fn exposure_is_gain_and_offset() {
    let dir = mini(7, &[("exposure", &[("gain", 1.2), ("offset", 0.02)])]);
    let (_, _, e) = frame(&dir, 1, "left", 0);
    let (_, _, p) = frame(plain(), 1, "left", 0);
    let pairs: Vec<(f64, f64)> = p
        .iter()
        .zip(&e)
        .filter(|(&a, _)| a > 20.0 && a < 180.0)
        .map(|(&a, &b)| (f64::from(a), f64::from(b)))
        .collect();
    let n = pairs.len() as f64;
    let (mx, my) = (
        pairs.iter().map(|p| p.0).sum::<f64>() / n,
        pairs.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pairs.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = pairs.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    assert!((slope - 1.2).abs() < 0.04, "slope {slope}");
    assert!(
        (intercept - 0.02 * 255.0).abs() < 2.0,
        "intercept {intercept}"
    );
}

#[test]
fn gamma_follows_the_response_curve() {
    let dir = mini(7, &[("gamma", &[("gamma", 2.0)])]);
    let (_, _, g) = frame(&dir, 0, "right", 0);
    let (_, _, p) = frame(plain(), 0, "right", 0);
    let mut errs: Vec<f64> = p
        .iter()
        .zip(&g)
        .filter(|(&a, _)| a > 20.0)
        .map(|(&a, &b)| (f64::from(b) - 255.0 * (f64::from(a) / 255.0).powf(0.5)).abs())
        .collect();
    errs.sort_by(f64::total_cmp);
    let median = errs[errs.len() / 2];
    assert!(median < 1.5, "median error {median} DN");
}

#[test]
fn blur_removes_fine_detail_but_keeps_brightness() {
    let dir = mini(7, &[("blur", &[("sigma_px", 1.5)])]);
    let (w, h, b) = frame(&dir, 0, "left", 0);
    let (_, _, p) = frame(plain(), 0, "left", 0);
    let grad = |img: &[f32]| -> (f64, f64) {
        let (mut g, mut s, mut n) = (0.0, 0.0, 0.0);
        for y in h / 2..h - 2 {
            for x in 2..w - 2 {
                g += f64::from((img[y * w + x + 1] - img[y * w + x]).abs());
                s += f64::from(img[y * w + x]);
                n += 1.0;
            }
        }
        (g / n, s / n)
    };
    let ((gb, mb), (gp, mp)) = (grad(&b), grad(&p));
    // Fresh sensor noise is added after the blur, so the gradient drops less than the PSF alone
    // would make it; the model check below is the precise one.
    assert!(gb < 0.75 * gp, "gradient {gb} vs plain {gp}");
    let model = regolith_validator::sensor::gaussian_blur(&p, w, h, 1.5);
    let rms = |a: &[f32], b: &[f32]| {
        (a.iter()
            .zip(b)
            .map(|(x, y)| f64::from(x - y).powi(2))
            .sum::<f64>()
            / a.len() as f64)
            .sqrt()
    };
    let (to_model, to_plain) = (rms(&b, &model), rms(&b, &p));
    assert!(
        to_model < 0.6 * to_plain && to_model < 3.0,
        "rms to blurred plain {to_model}, to plain {to_plain}"
    );
    assert!((mb - mp).abs() < 0.02 * mp, "mean {mb} vs {mp}");
}

#[test]
fn noise_variance_matches_gain_and_read_sigma() {
    let dir = mini(7, &[("noise", &[("gain", 0.4), ("read_sigma", 2.0)])]);
    let (_, _, a) = frame(&dir, 0, "left", 0);
    let (_, _, b) = frame(&dir, 0, "left", 1);
    let (_, _, p) = frame(plain(), 0, "left", 0);
    // Pixels whose plain value is 50..70 DN: var(a - b) = 2 (gain * DN + read^2) (+ rounding).
    let d: Vec<(f64, f64)> = p
        .iter()
        .zip(a.iter().zip(&b))
        .filter(|(&x, _)| (50.0..70.0).contains(&x))
        .map(|(&x, (&u, &v))| (f64::from(x), f64::from(u - v)))
        .collect();
    let n = d.len() as f64;
    assert!(n > 2000.0);
    let mean_dn = d.iter().map(|x| x.0).sum::<f64>() / n;
    let var = d.iter().map(|x| x.1 * x.1).sum::<f64>() / n;
    let expect = 2.0 * (0.4 * mean_dn + 4.0) + 2.0 / 12.0;
    assert!((var / expect - 1.0).abs() < 0.15, "var {var} vs {expect}");
}

#[test]
fn shadows_only_darken_and_some_pixels_fall_to_ambient() {
    // The plain campaign's own light, given explicitly: the frames differ only by the shadows.
    let plain_light = json(plain(), "truth/lighting.json");
    let (az, el) = (
        plain_light["azimuth_deg"].as_f64().unwrap(),
        plain_light["elevation_deg"].as_f64().unwrap(),
    );
    let dir = mini(
        7,
        &[("shadows", &[("azimuth_deg", az), ("elevation_deg", el)])],
    );
    assert_eq!(
        json(&dir, "truth/lighting.json"),
        plain_light,
        "the shadows' light is the lab light"
    );
    let (mut darker, mut brighter, mut n) = (0usize, 0usize, 0usize);
    for cap in 0..2 {
        let (_, _, s) = frame(&dir, cap, "left", 0);
        let (_, _, p) = frame(plain(), cap, "left", 0);
        for (&x, &y) in p.iter().zip(&s) {
            if x > 30.0 {
                n += 1;
                darker += usize::from(y < 0.7 * x);
                brighter += usize::from(y > x + 12.0);
            }
        }
    }
    assert!(darker >= 20, "{darker} shadowed pixels of {n}");
    assert!(brighter * 2000 < n, "{brighter} brighter pixels");
}

#[test]
fn default_shadows_draw_a_low_light_and_move_the_lab_light_there() {
    let dir = mini(7, &[("shadows", &[])]);
    let hidden = &json(&dir, "truth/hidden.json")["effects"][0];
    let light = json(&dir, "truth/lighting.json");
    let el = hidden["elevation_deg"].as_f64().unwrap();
    assert!((15.0..=30.0).contains(&el), "elevation {el}");
    assert_eq!(light["elevation_deg"], hidden["elevation_deg"]);
    assert_eq!(light["azimuth_deg"], hidden["azimuth_deg"]);
    assert_eq!(
        light["ambient"],
        json(plain(), "truth/lighting.json")["ambient"]
    );
    // The campaign file records that light as surveyed: a few degrees off.
    let campaign: toml::Value =
        toml::from_str(&std::fs::read_to_string(dir.join("campaign.toml")).unwrap()).unwrap();
    let recorded = &campaign["lighting"];
    let off = |k: &str| recorded[k].as_float().unwrap() - light[k].as_f64().unwrap();
    let daz = (off("azimuth_deg") + 540.0).rem_euclid(360.0) - 180.0;
    assert!((1.95..=4.05).contains(&daz.abs()), "azimuth off {daz}");
    assert!((0.95..=2.05).contains(&off("elevation_deg").abs()));
    assert_eq!(
        recorded["ambient"].as_float(),
        light["ambient"].as_f64(),
        "the ambient share is recorded as it is"
    );
}

/// Every visible marker, sighted in the left frame (`markers::sight`, the gap workflow's
/// Lambertian sphere under the true light): within half a pixel of the true projection of its
/// centre, and for geometric effects away from where the calibrated (nominal) model puts it.
fn check_markers(dir: &Path, nominal_pose: bool) -> (usize, usize) {
    let tracer = regolith_corpus::terrain::raycast::TerrainCaster::new(&height_grid(dir));
    let markers: Vec<TrueMarker> = json(dir, "truth/markers.json")
        .as_array()
        .unwrap()
        .iter()
        .map(|m| TrueMarker {
            name: m["name"].as_str().unwrap().into(),
            centre_m: serde_json::from_value(m["centre_m"].clone()).unwrap(),
            radius_m: m["radius_m"].as_f64().unwrap(),
        })
        .collect();
    let true_cam = camera(dir, "navcam_left", "true");
    let cal_cam = camera(dir, "navcam_left", "calibrated");
    let lighting = json(dir, "truth/lighting.json");
    let light = Light {
        azimuth_deg: lighting["azimuth_deg"].as_f64().unwrap(),
        elevation_deg: lighting["elevation_deg"].as_f64().unwrap(),
        ambient: lighting["ambient"].as_f64().unwrap(),
    };
    let (mut checked, mut displaced) = (0, 0);
    for c in json(dir, "truth/captures.json").as_array().unwrap() {
        let true_pose = pose(&c["left"]["ground_from_camera"]);
        let nominal = if nominal_pose {
            pose(&c["ground_from_rig"])
        } else {
            true_pose
        };
        let (w, h, img) = grey(&dir.join(c["left"]["files"][0].as_str().unwrap()));
        let img: Vec<f32> = img.into_iter().map(f32::from).collect();
        for m in &markers {
            if !marker_visible(&tracer, true_pose.translation_m, m) {
                continue;
            }
            let Some([u, v]) = true_cam.project(true_pose.inverse().transform_point(m.centre_m))
            else {
                continue;
            };
            if u < 15.0 || v < 15.0 || u > w as f64 - 15.0 || v > h as f64 - 15.0 {
                continue;
            }
            let [nu, nv] = cal_cam
                .project(nominal.inverse().transform_point(m.centre_m))
                .unwrap();
            let seen = sight(
                &img, w, h, &true_cam, &true_pose, m.centre_m, m.radius_m, &light,
            )
            .unwrap_or_else(|| panic!("{}: not sighted", m.name));
            let [bu, bv] = seen.pixel;
            let err = (bu - u).hypot(bv - v);
            assert!(
                err <= 0.5,
                "{}: sighted at ({bu:.2},{bv:.2}), true projection ({u:.2},{v:.2})",
                m.name
            );
            checked += 1;
            if (nu - u).hypot(nv - v) > 5.0 {
                assert!(
                    (bu - nu).hypot(bv - nv) > 3.0,
                    "{}: the blob follows the calibrated model",
                    m.name
                );
                displaced += 1;
            }
        }
    }
    (checked, displaced)
}

#[test]
fn hidden_distortion_moves_markers_off_the_calibrated_projection() {
    let dir = mini(7, &[("distortion", &[("dk1", 0.06), ("dk2", 0.03)])]);
    let (t, c) = (
        camera(&dir, "navcam_left", "true"),
        camera(&dir, "navcam_left", "calibrated"),
    );
    assert!((t.distortion.k1 - c.distortion.k1 - 0.06).abs() < 1e-12);
    assert_eq!(
        c,
        camera(plain(), "navcam_left", "calibrated"),
        "the calibration file does not know it"
    );
    let (checked, displaced) = check_markers(&dir, false);
    assert!(
        checked >= 3 && displaced >= 1,
        "{checked} markers, {displaced} displaced"
    );
}

#[test]
fn hidden_pose_bias_moves_the_true_camera() {
    let params: &[(&str, f64)] = &[
        ("translation_m.x", 0.02),
        ("rotation_deg.x", 0.6),
        ("rotation_deg.y", -0.6),
    ];
    let dir = mini(7, &[("pose-bias", params)]);
    let c = &json(&dir, "truth/captures.json")[0];
    let (rig, cam) = (
        pose(&c["ground_from_rig"]),
        pose(&c["left"]["ground_from_camera"]),
    );
    assert!((rig.inverse().compose(&cam).translation_m[0] - 0.02).abs() < 1e-9);
    assert_eq!(
        rig,
        pose(&json(plain(), "truth/captures.json")[0]["ground_from_rig"]),
        "the rig pose is unchanged"
    );
    let (checked, displaced) = check_markers(&dir, true);
    assert!(
        checked >= 3 && displaced >= 2,
        "{checked} markers, {displaced} displaced"
    );
}

#[test]
fn plain_markers_sit_at_their_projections() {
    let (checked, displaced) = check_markers(plain(), true);
    assert!(checked >= 3, "{checked}");
    assert_eq!(displaced, 0);
}

#[test]
fn texture_lowpass_blurs_only_the_texture_sources() {
    let dir = mini(7, &[("texture-lowpass", &[("sigma_m", 0.02)])]);
    let colours = |d: &Path| -> Vec<u8> {
        let ply = std::fs::read(d.join("sfm/mesh.ply")).unwrap();
        let end = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let text = String::from_utf8_lossy(&ply[..end]).to_string();
        let n: usize = text
            .lines()
            .find(|l| l.starts_with("element vertex"))
            .unwrap()[15..]
            .parse()
            .unwrap();
        (0..n).map(|i| ply[end + i * 15 + 12]).collect()
    };
    let roughness = |c: &[u8]| {
        c.windows(2)
            .map(|p| (f64::from(p[0]) - f64::from(p[1])).abs())
            .sum::<f64>()
            / c.len() as f64
    };
    let (lp, pl) = (roughness(&colours(&dir)), roughness(&colours(plain())));
    assert!(lp < 0.8 * pl, "vertex colour roughness {lp} vs plain {pl}");
    // The real images use the true albedo: identical bytes.
    assert_eq!(
        std::fs::read(dir.join("captures/loc01_left_a.png")).unwrap(),
        std::fs::read(plain().join("captures/loc01_left_a.png")).unwrap()
    );
    let (a, b) = (
        asc(&dir.join("scans/pos1.asc")),
        asc(&plain().join("scans/pos1.asc")),
    );
    assert_eq!(a.len(), b.len());
    assert!(
        a.iter().zip(&b).all(|(p, q)| p[..3] == q[..3]),
        "geometry unchanged"
    );
    assert!(
        a.iter().zip(&b).any(|(p, q)| (p[3] - q[3]).abs() > 0.5),
        "reflectance follows the low-passed albedo"
    );
}
