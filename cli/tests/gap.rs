//! `regolith gap` on mini corpus campaigns: the hidden sensor noise is named with its
//! parameters, the no-effect campaign's nominal noise is not, and `--apply` writes the model
//! into a child release that `inspect` shows.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;
use std::process::Command;

use serde_json::Value;

fn regolith(args: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_regolith"))
        .args(args)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Generates mini seed 31 into `dir/camp` with the `extra` generator arguments.
fn generate(dir: &Path, extra: &[&str]) -> std::path::PathBuf {
    generate_seed(dir, "31", extra)
}

/// Generates mini `seed` into `dir/camp` with the `extra` generator arguments.
fn generate_seed(dir: &Path, seed: &str, extra: &[&str]) -> std::path::PathBuf {
    let camp = dir.join("camp");
    let mut args = vec![
        "corpus",
        "generate",
        "--renderer",
        "model",
        "--preset",
        "mini",
        "--seed",
        seed,
        "--out",
        camp.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    regolith(&args);
    camp
}

/// Compiles `camp` into `dir/db` as `mini@1`; returns the database path.
fn compile(dir: &Path, camp: &Path) -> String {
    let db = dir.join("db");
    regolith(&[
        "compile",
        camp.to_str().unwrap(),
        "--db",
        db.to_str().unwrap(),
        "--release",
        "mini@1",
    ]);
    db.to_string_lossy().into_owned()
}

/// Generates and compiles a mini campaign; returns the database path.
fn campaign(dir: &Path, extra: &[&str]) -> String {
    let camp = generate(dir, extra);
    compile(dir, &camp)
}

fn named(v: &Value) -> Vec<String> {
    v["named"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["effect"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn hidden_noise_is_named_fitted_and_applied() {
    let dir = tempfile::tempdir().unwrap();
    let db = campaign(
        dir.path(),
        &[
            "--hidden-effect",
            "noise",
            "--effect-param",
            "noise.gain=0.35",
            "--effect-param",
            "noise.read_sigma=2.0",
        ],
    );
    let report = dir.path().join("report");
    let v = regolith(&[
        "gap",
        &db,
        "--entry",
        "laser/0.01",
        "--captures",
        "loc01",
        "--apply",
        "--report",
        report.to_str().unwrap(),
    ]);
    common::assert_matches_doc_schema("gap", &v);
    // The report page links charts that exist and decode.
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(html.contains("noise"));
    for png in ["radius.png", "intensity.png", "spectrum.png"] {
        assert!(html.contains(png), "{png} not linked");
        let file = std::fs::File::open(report.join(png)).unwrap();
        let info = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .unwrap();
        assert!(info.info().width > 100);
    }
    for key in ["gap_before", "gap_after", "metrics_before", "metrics_after"] {
        assert!(!v[key].is_null(), "{key} missing");
    }
    let noise = v["named"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["effect"] == "noise")
        .unwrap_or_else(|| panic!("noise not named: {:?}", named(&v)));
    // The read noise is the variance line extrapolated to DN 0 from the terrain's intensity
    // range (about 40-160 DN here), so it is the looser figure; 8-bit quantisation adds 1/12 DN².
    let gain = noise["params"]["gain"].as_f64().unwrap();
    let read = noise["params"]["read_sigma"].as_f64().unwrap();
    assert!((gain - 0.35).abs() < 0.05, "gain {gain}");
    assert!((read - 2.0).abs() < 0.6, "read {read}");
    assert!(noise["explained_fraction"].as_f64().unwrap() > 0.0);
    // The child release carries the model, and its parent is the examined release.
    let child = v["applied"]["release"].as_str().unwrap();
    let info = regolith(&["inspect", &db, child, "laser/0.01/sensor-model"]);
    assert!(info.to_string().contains("sensor-model"), "{info}");
    let database = regolith_reader::Database::open(&db).unwrap();
    let view = database.release(child).unwrap();
    assert_eq!(
        view.manifest.parent,
        Some(database.release("mini@1").unwrap().id)
    );
    let model = regolith_validator::sensor::stored_model(&view, "laser/0.01").unwrap();
    assert!(model.effects.iter().any(|e| e.name() == "noise"));
}

/// Runs gap on `laser/0.01` of a campaign with `extra` generator arguments.
fn gap(extra: &[&str]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let db = campaign(dir.path(), extra);
    regolith(&["gap", &db, "--entry", "laser/0.01"])
}

fn param(v: &Value, effect: &str, name: &str) -> f64 {
    let n = v["named"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["effect"] == effect)
        .unwrap_or_else(|| panic!("{effect} not named: {:?}", named(v)));
    n["params"][name].as_f64().unwrap()
}

#[test]
fn nothing_is_named_when_nothing_is_hidden() {
    let v = gap(&[]);
    assert!(named(&v).is_empty(), "{:?}", named(&v));
    // The texture measure ran and found the texture as sharp as a faithful one.
    let excess = v["texture"]["excess_m"].as_f64().unwrap();
    assert!(excess < 0.01, "texture excess {excess}");
    assert_eq!(v["gap_metric"], "photometric_rms_dn");
    assert!((v["gap_before"].as_f64().unwrap() - v["gap_after"].as_f64().unwrap()).abs() < 1e-9);
}

/// A texture 20 mm too smooth (the laser reflectance and the SfM colours were computed from the
/// albedo blurred by it) is named with its low-pass. Its procedural detail has zero mean, so the
/// photometric RMS (against the expected render) stays where it was, while the texture's band
/// power against the real albedo's comes back up: that deficit is the run's headline.
#[test]
fn hidden_texture_lowpass_is_named_with_its_blur() {
    let v = gap(&[
        "--hidden-effect",
        "texture-lowpass",
        "--effect-param",
        "texture-lowpass.sigma_m=0.02",
    ]);
    assert_eq!(named(&v), ["texture-lowpass"]);
    let sigma = param(&v, "texture-lowpass", "sigma_m");
    assert!((sigma - 0.02).abs() < 0.005, "sigma_m {sigma}");
    assert!((v["texture"]["excess_m"].as_f64().unwrap() - sigma).abs() < 1e-12);
    let rms = |m: &str| v[m]["photometric_rms_dn"].as_f64().unwrap();
    assert!((rms("metrics_before") - rms("metrics_after")).abs() < 1e-9);
    let band = |m: &str| v[m]["texture_band_log_ratio"].as_f64().unwrap();
    let (before, after) = (band("metrics_before"), band("metrics_after"));
    assert!(
        after > before + 0.05,
        "texture band power {before} -> {after}"
    );
    assert_eq!(v["gap_metric"], "texture_band_deficit");
    assert_eq!(v["gap_before"].as_f64(), Some(-before));
    assert_eq!(v["gap_after"].as_f64(), Some(-after));
}

/// Mini seed 103 with nothing hidden: a pose bias of 1.1° and 2.9 cm once fitted its
/// band-passed texture better on held-out captures while making every view's intensities
/// worse (the geometric stage's photometric-RMS check kept it from being named). With smooth
/// residuals the fit no longer finds such a pose bias; the case stays: nothing may be named,
/// with all four geometric subsets scored.
#[test]
fn nothing_geometric_is_named_on_seed_103_with_nothing_hidden() {
    let dir = tempfile::tempdir().unwrap();
    let camp = generate_seed(dir.path(), "103", &[]);
    let db = compile(dir.path(), &camp);
    let v = regolith(&["gap", &db, "--entry", "laser/0.01"]);
    assert!(named(&v).is_empty(), "{:?}", named(&v));
    let geometry = v["candidates"]["geometry"].as_array().unwrap();
    assert_eq!(
        geometry.len(),
        4,
        "every subset of distortion, pose-bias is scored"
    );
}

// Tolerances below are what the workflow achieves today on mini campaigns (the issue's
// targets are tighter: vignetting ±5 %, gamma ±0.02); the named effect must be the hidden one.

#[test]
fn hidden_vignetting_is_named_alone() {
    let v = gap(&[
        "--hidden-effect",
        "vignetting",
        "--effect-param",
        "vignetting.strength=0.4",
    ]);
    assert_eq!(named(&v), ["vignetting"]);
    let strength = param(&v, "vignetting", "strength");
    assert!((strength - 0.4).abs() < 0.08, "strength {strength}");
    assert!(v["gap_after"].as_f64().unwrap() < v["gap_before"].as_f64().unwrap());
}

/// A distortion the calibration misses (dk1 −0.045: 35 px at the image corners, 4 px at half
/// the radius) is found by the dense alignment and named alone; the radial terms trade off over
/// the terrain's part of the image, so dk1 is checked for sign and size, not to the catalogue's
/// ±5 % (see the gap issue notes).
#[test]
fn hidden_distortion_is_named_alone() {
    let v = gap(&[
        "--hidden-effect",
        "distortion",
        "--effect-param",
        "distortion.dk1=-0.045",
        "--effect-param",
        "distortion.dk2=0.0",
    ]);
    assert_eq!(named(&v), ["distortion"]);
    let dk1 = param(&v, "distortion", "dk1");
    assert!((dk1 + 0.045).abs() < 0.015, "dk1 {dk1}");
    assert_eq!(v["gap_metric"], "alignment_residual");
    assert!(v["gap_after"].as_f64().unwrap() < v["gap_before"].as_f64().unwrap());
}

/// A pair: a strong response curve with a weaker vignetting. The curve alone removes most of
/// the error; the vignetting must still be named (its share is judged against the error left
/// without it, not against the error before anything was fitted).
#[test]
fn hidden_gamma_and_vignetting_are_both_named() {
    let v = gap(&[
        "--hidden-effect",
        "gamma,vignetting",
        "--effect-param",
        "gamma.gamma=1.6",
        "--effect-param",
        "vignetting.strength=0.2",
    ]);
    let mut both = named(&v);
    both.sort();
    assert_eq!(both, ["gamma", "vignetting"], "in either order");
    let (g, s) = (
        param(&v, "gamma", "gamma"),
        param(&v, "vignetting", "strength"),
    );
    eprintln!("gamma {g:.4} vignetting {s:.4}");
    assert!((g - 1.6).abs() < 0.05, "gamma {g}");
    assert!((s - 0.2).abs() < 0.05, "strength {s}");
}

/// A constant exposure over the laser entry is the texture's level in the camera's terms: its
/// gain is reported as the entry's texture transfer, not an exposure of the camera, `--apply`
/// writes it into the model, and a second run on the child release renders through it and
/// finds no level left to change.
#[test]
fn a_hidden_gain_is_the_texture_transfer_and_is_applied() {
    let dir = tempfile::tempdir().unwrap();
    let db = campaign(
        dir.path(),
        &[
            "--hidden-effect",
            "exposure",
            "--effect-param",
            "exposure.gain=1.25",
            "--effect-param",
            "exposure.offset=0.0",
        ],
    );
    let report = dir.path().join("report");
    let v = regolith(&[
        "gap",
        &db,
        "--entry",
        "laser/0.01",
        "--apply",
        "--report",
        report.to_str().unwrap(),
    ]);
    common::assert_matches_doc_schema("gap", &v);
    let gain = v["texture_transfer"]["gain"].as_f64().unwrap();
    assert!((gain - 1.25).abs() < 0.125, "transfer gain {gain}");
    // One gain for every frame: the two captures' fits agree within their errors.
    let evidence = v["texture_transfer"]["evidence"].as_str().unwrap();
    let p: f64 = evidence
        .rsplit_once("p = ")
        .and_then(|(_, p)| p.trim_end_matches(')').parse().ok())
        .unwrap_or_else(|| panic!("no per-capture agreement in {evidence:?}"));
    assert!(p > 0.01, "the captures disagree: {evidence}");
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(html.contains("Texture transfer"), "no transfer section");
    // An exposure, if named, is the camera's offset alone.
    if let Some(n) = v["named"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["effect"] == "exposure")
    {
        assert_eq!(n["params"]["gain"].as_f64(), Some(1.0), "{n}");
    }
    let child = v["applied"]["release"].as_str().unwrap();
    let database = regolith_reader::Database::open(&db).unwrap();
    let model =
        regolith_validator::sensor::stored_model(&database.release(child).unwrap(), "laser/0.01")
            .unwrap();
    assert_eq!(model.texture_transfer.map(|t| t.gain), Some(gain));
    let again = regolith(&["gap", &db, "--release", child, "--entry", "laser/0.01"]);
    assert!(
        again["texture_transfer"].is_null(),
        "{}",
        again["texture_transfer"]
    );
    assert!(
        !named(&again).contains(&"exposure".to_string()),
        "{:?}",
        named(&again)
    );
    assert!(
        again["gap_before"].as_f64().unwrap() < 0.8 * v["gap_before"].as_f64().unwrap(),
        "{} then {}",
        v["gap_before"],
        again["gap_before"]
    );
}

#[test]
fn hidden_gamma_is_named_alone() {
    let v = gap(&[
        "--hidden-effect",
        "gamma",
        "--effect-param",
        "gamma.gamma=2.0",
    ]);
    assert_eq!(named(&v), ["gamma"]);
    assert!((param(&v, "gamma", "gamma") - 2.0).abs() < 0.1);
    // The gap shrinks by more than half.
    assert!(v["gap_after"].as_f64().unwrap() < 0.5 * v["gap_before"].as_f64().unwrap());
}

#[test]
fn hidden_blur_is_measured_on_the_skyline() {
    let v = gap(&[
        "--hidden-effect",
        "blur",
        "--effect-param",
        "blur.sigma_px=1.2",
    ]);
    assert_eq!(named(&v), ["blur"]);
    assert!((param(&v, "blur", "sigma_px") - 1.2).abs() < 0.15);
}

#[test]
fn nominal_noise_is_not_named() {
    let dir = tempfile::tempdir().unwrap();
    let db = campaign(dir.path(), &[]);
    let args = ["gap", &db, "--entry", "laser/0.01", "--captures", "loc01"];
    let v = regolith(&args);
    assert!(!named(&v).contains(&"noise".to_string()), "{:?}", named(&v));
    // Every step of the workflow is timed, in the order it ran.
    let steps: Vec<&str> = v["step_seconds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s[0].as_str().unwrap())
        .collect();
    let expected: Vec<&str> = regolith_validator::gap::STEPS.iter().map(|s| s.0).collect();
    assert_eq!(steps, expected);
    // Without --json, a log (stderr not a terminal) gets one line per step as it begins.
    let out = Command::new(env!("CARGO_BIN_EXE_regolith"))
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success());
    let log = String::from_utf8_lossy(&out.stderr);
    let logged: Vec<&str> = log
        .lines()
        .filter_map(|l| l.split_once("] ").map(|(_, step)| step))
        .collect();
    assert_eq!(logged, expected, "{log}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("  time: loading"));
}

#[test]
fn the_demo_finds_its_hidden_vignetting_and_shrinks_the_gap() {
    let dir = tempfile::tempdir().unwrap();
    let campaign = Path::new(env!("CARGO_MANIFEST_DIR")).join("../corpus/demo");
    let v = regolith(&[
        "demo",
        "--campaign",
        campaign.to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    common::assert_matches_doc_schema("demo", &v);
    let gap = &v["gap"];
    let truth = gap["hidden_truth"][0]["strength"].as_f64().unwrap();
    let fitted = gap["named"][0]["params"]["strength"].as_f64().unwrap();
    assert_eq!(gap["named"][0]["effect"], "vignetting");
    assert!((fitted - truth).abs() < 0.05 * truth, "{fitted} vs {truth}");
    // A falloff of the camera: each capture location alone finds about the same.
    let per_capture = gap["named"][0]["per_capture"].as_array().unwrap();
    assert_eq!(per_capture.len(), 2, "{per_capture:?}");
    for c in per_capture {
        let s = c["params"]["strength"].as_f64().unwrap();
        assert!((s - truth).abs() < 0.15 * truth, "{c}: {s} vs {truth}");
    }
    assert!(gap["gap_after"].as_f64().unwrap() < gap["gap_before"].as_f64().unwrap());
    assert!(gap["applied"].as_str().unwrap().ends_with("+gap.1"));
}

#[test]
fn hidden_low_light_shadows_are_named_with_their_direction() {
    // At the default lab light (elevation ~60°) a mini terrain casts almost no shadow; at 25°
    // boulders and hills do.
    let dir = tempfile::tempdir().unwrap();
    let db = campaign(
        dir.path(),
        &[
            "--hidden-effect",
            "shadows",
            "--effect-param",
            "shadows.elevation_deg=25",
        ],
    );
    let v = regolith(&["gap", &db, "--entry", "laser/0.01"]);
    assert_eq!(named(&v), ["shadows"]);
    let truth: Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("camp/truth/hidden.json")).unwrap())
            .unwrap();
    let truth = &truth["effects"][0];
    let el = param(&v, "shadows", "elevation_deg");
    let az = param(&v, "shadows", "azimuth_deg");
    let true_az = truth["azimuth_deg"].as_f64().unwrap();
    assert!((el - 25.0).abs() <= 3.0, "elevation {el}");
    let daz = (az - true_az + 540.0).rem_euclid(360.0) - 180.0;
    assert!(daz.abs() <= 3.0, "azimuth {az} vs {true_az}");
}

#[test]
fn a_documented_light_five_degrees_off_is_refined_to_the_true_one() {
    // The lab's `[lighting]` says 5° more azimuth than the light that cast the shadows (more
    // than the corpus's own 2–4° survey error): the direction search must move it back, and
    // only because it fits better in every capture.
    let dir = tempfile::tempdir().unwrap();
    let camp = generate(
        dir.path(),
        &[
            "--hidden-effect",
            "shadows",
            "--effect-param",
            "shadows.elevation_deg=25",
        ],
    );
    let toml_path = camp.join("campaign.toml");
    let toml = std::fs::read_to_string(&toml_path).unwrap();
    let at = toml.find("[lighting]\nazimuth_deg = ").unwrap() + "[lighting]\nazimuth_deg = ".len();
    let end = at + toml[at..].find('\n').unwrap();
    let truth: Value =
        serde_json::from_slice(&std::fs::read(camp.join("truth/lighting.json")).unwrap()).unwrap();
    let true_az = truth["azimuth_deg"].as_f64().unwrap();
    let edited = format!("{}{:?}{}", &toml[..at], true_az + 5.0, &toml[end..]);
    std::fs::write(&toml_path, edited).unwrap();
    let db = compile(dir.path(), &camp);
    let v = regolith(&["gap", &db, "--entry", "laser/0.01"]);
    assert_eq!(named(&v), ["shadows"]);
    let az = param(&v, "shadows", "azimuth_deg");
    let el = param(&v, "shadows", "elevation_deg");
    let daz = (az - true_az + 540.0).rem_euclid(360.0) - 180.0;
    assert!(
        daz.abs() <= 2.0,
        "azimuth {az} vs true {true_az} (documented +5°)"
    );
    assert!((el - 25.0).abs() <= 3.0, "elevation {el}");
}
