//! Sensor-model tests: each effect changes an image the way its parameter says (vignetting
//! corner/centre ratio, blur variance of a checkerboard against its Fourier prediction,
//! gamma and exposure on a ramp, noise variance against `gain * signal + read_sigma²`), the
//! geometric and texture effects, the catalogue and the serde form.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;
use regolith_validator::render::{
    AlbedoGrid, Geometry, HeightGrid, Light, RenderOptions, Scene, View,
};
use regolith_validator::sensor::{quantise_u8, Effect, Placement, SensorModel, TextureTransfer};

fn model(effects: Vec<Effect>) -> SensorModel {
    SensorModel::from(effects)
}

fn cam(w: u32, h: u32) -> CameraModel {
    CameraModel::pinhole(
        w,
        h,
        100.0,
        100.0,
        (w - 1) as f64 / 2.0,
        (h - 1) as f64 / 2.0,
    )
}

#[test]
fn vignetting_corner_to_centre_ratio_is_one_minus_strength() {
    let (w, h) = (101, 81);
    let img = vec![0.5f32; w * h];
    for strength in [0.1, 0.3, 0.6] {
        let out = model(vec![Effect::Vignetting { strength }]).image(&img, w, h, &cam(101, 81), 0);
        let centre = out[40 * w + 50];
        assert!((centre - 127.5).abs() < 1e-3);
        for corner in [0, w - 1, (h - 1) * w, h * w - 1] {
            assert!((f64::from(out[corner] / centre) - (1.0 - strength)).abs() < 1e-5);
        }
        // Monotone falloff along the diagonal.
        let diag: Vec<f32> = (0..40).map(|k| out[(40 - k) * w + 50 - k]).collect();
        assert!(diag.windows(2).all(|p| p[1] < p[0] + 1e-6));
    }
}

/// Mean power of one period of the ±1 square wave (period `n` samples) after a continuous
/// Gaussian of `sigma` samples, from its discrete Fourier series.
fn square_wave_power_after_gaussian(n: usize, sigma: f64) -> f64 {
    let s: Vec<f64> = (0..n).map(|i| if i < n / 2 { 1.0 } else { -1.0 }).collect();
    let mut power = 0.0;
    for k in 0..n {
        let (mut re, mut im) = (0.0, 0.0);
        for (i, v) in s.iter().enumerate() {
            let a = -2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64;
            re += v * a.cos();
            im += v * a.sin();
        }
        let f = k.min(n - k) as f64 / n as f64;
        let h = (-2.0 * std::f64::consts::PI.powi(2) * sigma * sigma * f * f).exp();
        power += (re * re + im * im) * h * h;
    }
    power / (n * n) as f64
}

#[test]
fn blur_reduces_checkerboard_variance_as_predicted() {
    let (w, h, square) = (128usize, 128usize, 8usize);
    let img: Vec<f32> = (0..w * h)
        .map(|i| {
            if ((i % w) / square + (i / w) / square) % 2 == 0 {
                0.75
            } else {
                0.25
            }
        })
        .collect();
    let variance = |v: &[f32]| {
        // Interior only (the border replicates edge values).
        let vals: Vec<f64> = (16..h - 16)
            .flat_map(|r| (16..w - 16).map(move |c| r * w + c))
            .map(|i| f64::from(v[i]))
            .collect();
        let mean = vals.iter().sum::<f64>() / vals.len() as f64;
        (
            vals.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / vals.len() as f64,
            mean,
        )
    };
    let (v0, m0) = variance(&model(vec![]).image(&img, w, h, &cam(128, 128), 0));
    assert!((v0 - 63.75f64.powi(2)).abs() < 1e-3 && (m0 - 127.5).abs() < 1e-3);
    for sigma in [1.0, 2.0, 3.0] {
        let (v, m) = variance(&model(vec![Effect::Blur { sigma_px: sigma }]).image(
            &img,
            w,
            h,
            &cam(128, 128),
            0,
        ));
        let want = square_wave_power_after_gaussian(2 * square, sigma).powi(2);
        assert!(
            (v / v0 / want - 1.0).abs() < 0.02,
            "sigma {sigma}: ratio {} vs {want}",
            v / v0
        );
        assert!((m - 127.5).abs() < 0.01, "blur keeps the mean");
    }
}

#[test]
fn gamma_and_exposure_on_a_ramp() {
    let ramp: Vec<f32> = (0..=100).map(|i| i as f32 / 100.0).collect();
    let c = cam(101, 1);
    let g = model(vec![Effect::Gamma { gamma: 2.2 }]).image(&ramp, 101, 1, &c, 0);
    let e = model(vec![Effect::Exposure {
        gain: 1.2,
        offset: -0.05,
    }])
    .image(&ramp, 101, 1, &c, 0);
    for (i, x) in ramp.iter().enumerate() {
        let x = f64::from(*x);
        assert!((f64::from(g[i]) - 255.0 * x.powf(1.0 / 2.2)).abs() < 1e-3);
        assert!((f64::from(e[i]) - 255.0 * (1.2 * x - 0.05)).abs() < 1e-3);
    }
    // Fixed physical order whatever the list order: exposure before the response curve.
    let both = model(vec![
        Effect::Gamma { gamma: 2.2 },
        Effect::Exposure {
            gain: 0.5,
            offset: 0.0,
        },
    ])
    .image(&ramp, 101, 1, &c, 0);
    assert!((f64::from(both[100]) - 255.0 * 0.5f64.powf(1.0 / 2.2)).abs() < 1e-3);
}

#[test]
fn noise_variance_follows_gain_and_read_sigma() {
    let (w, h) = (200, 200);
    let (gain, read_sigma) = (0.5, 2.0);
    let noisy = model(vec![Effect::Noise { gain, read_sigma }]);
    for level in [0.1f32, 0.4, 0.8] {
        let img = vec![level; w * h];
        let out = noisy.image(&img, w, h, &cam(200, 200), 7);
        let n = out.len() as f64;
        let mean = out.iter().map(|v| f64::from(*v)).sum::<f64>() / n;
        let var = out
            .iter()
            .map(|v| (f64::from(*v) - mean).powi(2))
            .sum::<f64>()
            / n;
        let signal = 255.0 * f64::from(level);
        let want = gain * signal + read_sigma * read_sigma;
        assert!((mean - signal).abs() < 0.1, "mean {mean} vs {signal}");
        assert!(
            (var / want - 1.0).abs() < 0.04,
            "variance {var} vs {want} at {signal} DN"
        );
    }
    let img = vec![0.5f32; 64];
    assert_eq!(
        noisy.image(&img, 8, 8, &cam(8, 8), 3),
        noisy.image(&img, 8, 8, &cam(8, 8), 3)
    );
    assert_ne!(
        noisy.image(&img, 8, 8, &cam(8, 8), 3),
        noisy.image(&img, 8, 8, &cam(8, 8), 4)
    );
}

#[test]
fn neutral_effects_change_nothing_and_samples_stay_in_range() {
    let img: Vec<f32> = (0..30 * 20).map(|i| (i % 17) as f32 / 17.0).collect();
    let plain = model(vec![]).image(&img, 30, 20, &cam(30, 20), 1);
    let neutral: Vec<Effect> = Effect::NAMES
        .iter()
        .map(|n| Effect::neutral(n).unwrap())
        .collect();
    let m = model(neutral.clone());
    let out = m.image(&img, 30, 20, &cam(30, 20), 1);
    assert!(plain.iter().zip(&out).all(|(a, b)| (a - b).abs() < 1e-3));
    assert_eq!(m.camera(&cam(30, 20)), cam(30, 20));
    let pose = Pose {
        translation_m: [1.0, 2.0, 3.0],
        rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
    };
    let at = Placement::lone(pose);
    assert!(m.pose(&at).distance_to_m(&pose) < 1e-12 && m.pose(&at).angle_to_deg(&pose) < 1e-9);

    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for name in Effect::NAMES {
        let e = Effect::sample(name, |a, b| rng.gen_range(a..=b)).unwrap();
        assert_eq!(e.name(), name);
        let ranges = Effect::default_range(name).unwrap();
        let params = e.params();
        assert_eq!(params.len(), ranges.len());
        for r in ranges {
            let v = params[r.name];
            assert!(v >= r.min && v <= r.max, "{name}.{} = {v}", r.name);
        }
        // JSON round trip with the kebab-case tag.
        let json = serde_json::to_string(&e).unwrap();
        assert!(json.contains(&format!("\"effect\":\"{name}\"")), "{json}");
        assert_eq!(serde_json::from_str::<Effect>(&json).unwrap(), e);
    }
    assert!(Effect::default_range("sharpen").is_none());
    let blur = Effect::Blur { sigma_px: 1.0 }
        .with_params(&BTreeMap::from([("sigma_px", 2.5), ("other", 1.0)]));
    assert_eq!(blur, Effect::Blur { sigma_px: 2.5 });
}

#[test]
fn geometric_render_and_texture_effects() {
    let m = model(vec![
        Effect::Distortion {
            dk1: 0.01,
            dk2: -0.002,
        },
        Effect::PoseBias {
            translation_m: [0.1, 0.0, 0.0],
            rotation_deg: [0.0, 0.0, 90.0],
        },
        Effect::Shadows {
            azimuth_deg: 200.0,
            elevation_deg: 30.0,
        },
        Effect::TextureLowpass { sigma_m: 0.03 },
    ]);
    let c = m.camera(&cam(64, 48));
    assert!((c.distortion.k1 - 0.01).abs() < 1e-12 && (c.distortion.k2 + 0.002).abs() < 1e-12);

    // A camera looking down: camera x = ground +x, camera y = ground -y.
    let view = View::look_at(cam(64, 48), [1.0, 2.0, 3.0], [1.0, 2.0, 0.0]);
    let biased = m.pose(&Placement::lone(view.ground_from_camera));
    let moved: Vec<f64> = (0..3)
        .map(|k| biased.translation_m[k] - view.ground_from_camera.translation_m[k])
        .collect();
    assert!(
        (moved[0] - 0.1).abs() < 1e-9 && moved[1].abs() < 1e-9 && moved[2].abs() < 1e-9,
        "{moved:?}"
    );
    // Rotated 90° about the optical axis, the new image right is the old image down.
    let right = biased.rotate([1.0, 0.0, 0.0]);
    let old_down = view.ground_from_camera.rotate([0.0, 1.0, 0.0]);
    assert!((0..3).all(|k| (right[k] - old_down[k]).abs() < 1e-9));

    // The bias moves the rig: a second camera 10 cm to the right and turned 2° follows the
    // biased reference camera rigidly (a bias in its own frame would swing it 10 cm around).
    let rig_from_right = Pose {
        translation_m: [0.1, 0.0, 0.0],
        rotation_xyzw: regolith_format::frames::quat_from_axis_angle([0.0, 1.0, 0.0], 0.035),
    };
    let right_cam = m.pose(&Placement {
        ground_from_camera: view.ground_from_camera.compose(&rig_from_right),
        rig_from_camera: rig_from_right,
    });
    let rigid = biased.compose(&rig_from_right);
    assert!(right_cam.distance_to_m(&rigid) < 1e-9 && right_cam.angle_to_deg(&rigid) < 1e-7);
    let own_frame = m.pose(&Placement::lone(
        view.ground_from_camera.compose(&rig_from_right),
    ));
    assert!(own_frame.distance_to_m(&rigid) > 0.1);

    let (opts, light) = m.render_options(&RenderOptions::default());
    let light = light.unwrap();
    assert!(opts.shadows && light.azimuth_deg == 200.0 && light.elevation_deg == 30.0);

    // An albedo impulse spreads into a Gaussian of sigma 0.03 m = 3 cells.
    let mut value = vec![0.0f32; 41 * 41];
    value[20 * 41 + 20] = 1.0;
    let grid = AlbedoGrid {
        origin_m: [0.0, 0.0],
        cell_m: 0.01,
        width: 41,
        height: 41,
        value,
    };
    let out = m.albedo(&grid);
    let total: f64 = out.value.iter().map(|v| f64::from(*v)).sum();
    let second: f64 = out
        .value
        .iter()
        .enumerate()
        .map(|(i, v)| f64::from(*v) * ((i % 41) as f64 - 20.0).powi(2))
        .sum();
    assert!((total - 1.0).abs() < 1e-4);
    assert!(
        (second / total / 9.0 - 1.0).abs() < 0.05,
        "variance {} cells²",
        second / total
    );
}

#[test]
fn quantise_rounds_and_clamps() {
    assert_eq!(
        quantise_u8(&[-3.0, 0.49, 0.5, 127.4, 254.6, 300.0, f32::NAN]),
        vec![0, 0, 1, 127, 255, 255, 0]
    );
}

#[test]
fn a_texture_transfer_scales_the_albedo_and_older_bodies_read_without_one() {
    let n = 21;
    let geometry = Geometry::Heightfield {
        grid: HeightGrid {
            origin_m: [0.0, 0.0],
            cell_m: 0.05,
            width: n,
            height: n,
            z: (0..n * n)
                .map(|i| 0.02 * ((i % n) as f32 * 0.7).sin())
                .collect(),
        },
        albedo: AlbedoGrid {
            origin_m: [0.0, 0.0],
            cell_m: 0.05,
            width: n,
            height: n,
            value: (0..n * n)
                .map(|i| 0.2 + 0.1 * ((i / n) % 3) as f32)
                .collect(),
        },
    };
    let scene = Scene::new(&geometry);
    let light = Light {
        azimuth_deg: 200.0,
        elevation_deg: 50.0,
        ambient: 0.2,
    };
    let view = View::look_at(cam(48, 40), [0.5, -0.5, 1.5], [0.5, -0.5, 0.0]);
    let at = Placement::lone(view.ground_from_camera);
    let vignetted = vec![Effect::Vignetting { strength: 0.3 }];
    let plain = model(vignetted.clone()).render(&scene, &light, &view.camera, &at, 1, None);
    let mut with = model(vignetted);
    with.texture_transfer = Some(TextureTransfer { gain: 1.25 });
    let scaled = with.render(&scene, &light, &view.camera, &at, 1, None);
    let lit: Vec<usize> = (0..plain.dn.len())
        .filter(|&i| plain.rendered.mask[i] != 0)
        .collect();
    assert!(lit.len() > plain.dn.len() / 2);
    for i in lit {
        let (a, b) = (plain.dn[i], scaled.dn[i]);
        assert!((b - 1.25 * a).abs() <= 1e-3 * a.max(1.0), "{a} {b}");
    }
    // A 1.11 body has no transfer; the field round-trips and is left out when absent.
    let old: SensorModel =
        serde_json::from_str(r#"{"effects":[{"effect":"gamma","gamma":1.5}]}"#).unwrap();
    assert_eq!(old, model(vec![Effect::Gamma { gamma: 1.5 }]));
    assert!(!serde_json::to_string(&old)
        .unwrap()
        .contains("texture_transfer"));
    let back: SensorModel = serde_json::from_str(&serde_json::to_string(&with).unwrap()).unwrap();
    assert_eq!(back, with);
}

#[test]
fn a_capture_exposure_scales_its_capture_only_and_older_bodies_read_without_one() {
    let mut m = model(vec![Effect::Gamma { gamma: 1.5 }]);
    m.texture_transfer = Some(TextureTransfer { gain: 1.25 });
    m.capture_exposure = [("loc01".to_string(), 0.9), ("loc02".to_string(), 1.1)]
        .into_iter()
        .collect();
    // The capture's gain folds into the texture's transfer (both scale the radiance before any
    // image effect); a capture the table does not list keeps the transfer as it is.
    let at1 = m.at_capture("loc01");
    assert!((at1.texture_transfer.unwrap().gain - 1.125).abs() < 1e-12);
    assert!(at1.capture_exposure.is_empty());
    assert_eq!(at1.effects, m.effects);
    assert!((m.at_capture("loc02").texture_transfer.unwrap().gain - 1.375).abs() < 1e-12);
    assert_eq!(m.at_capture("loc03").texture_transfer, m.texture_transfer);
    let bare = model(vec![]);
    assert_eq!(bare.at_capture("loc01"), bare);
    // A 1.12 body has no table; the field round-trips and is left out when empty.
    let old: SensorModel = serde_json::from_str(
        r#"{"effects":[{"effect":"gamma","gamma":1.5}],"texture_transfer":{"gain":1.25}}"#,
    )
    .unwrap();
    assert!(old.capture_exposure.is_empty());
    assert!(!serde_json::to_string(&old)
        .unwrap()
        .contains("capture_exposure"));
    let back: SensorModel = serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
    assert_eq!(back, m);
}
