//! The gap workflow proven on hidden effects: `mini` campaigns with each catalogue effect hidden
//! in turn, three pairs and nothing hidden, two seeds each, parameters drawn by the corpus from
//! its documented ranges (not chosen by the test). Every case must name exactly what was hidden
//! (pairs: both, in either order; nothing for nothing), fit the parameters within the
//! tolerances below, and shrink the gap by at least half of its excess over the no-effect
//! baseline: the same campaign measured with the true hidden effects added to the model (the
//! floor), on the figure the effect is judged by ([`judged_by`]). All violations are collected
//! and reported together, with the confusion matrix.
//!
//! Every case is generated with mini's two capture locations but for a distortion and a pose
//! bias beside a vignetting, which need four to meet the workflow's targets ([`test_captures`]).
//! Tolerances are those measured on these campaigns (the gap module's docs, known limits);
//! where they are looser than the workflow's targets (an exposure's gain, a lone camera), what
//! limits them is how little of the camera's field and depth range the capture locations show,
//! not the optimiser. A pose bias is held to the targets on every axis (the survey markers
//! sighted as ground control points pin it), from two locations and from six; given the
//! campaign's true terrain instead, a distortion's `dk1` is within its target from two, which
//! shows the entry is what limits it there. The last test looks through one camera alone, as
//! for a rover with a single NavCam.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;

use regolith_format::frames::Pose;
use regolith_tests::gap_case::{
    cases, figures, run_case, targets, test_captures, CaseResult, Confusion, Setup, TerrainChoice,
};
use regolith_validator::gap::Figure;
use regolith_validator::sensor::{distortion_shift, Effect, Placement, SensorModel};

const SEEDS: [u64; 2] = [101, 102];

/// Response curve exponent, absolute.
const GAMMA_TOL: f64 = targets::GAMMA;
/// PSF σ, px.
const BLUR_TOL_PX: f64 = targets::BLUR_PX;
/// Vignetting strength, relative: the workflow's target, alone and next to another effect (the
/// stereo views' overlap pins the falloff, see the gap module's `overlap`).
const VIGNETTING_TOL: f64 = targets::VIGNETTING_REL;
/// Noise gain and read noise, relative: from two repeat frames per pose, fitted on the linear
/// signal with the dark background (the gap module's `response`); seeds 101–105 within 1.1 %
/// (up to 11 % when fitted to the frames' levels alone).
const NOISE_TOL: f64 = 0.05;
/// Exposure gain, relative (the offset trades against it and against the response curve).
const EXPOSURE_GAIN_TOL: f64 = 0.10;
/// Radial displacement of the distortion at 0.7 of the radius, relative: the displacement is
/// what the images determine best (dk1 and dk2 trade off over the terrain's part of the image).
/// Seeds 101, 102 from four capture locations ([`test_captures`]): −1.2 and −0.6 %. From two,
/// −1.1 and −1.0 % with both radial terms fitted jointly to the render, the stereo pairs and
/// the survey markers' sightings and refined from a render made through the fit (seeds
/// 101–114: within 2.8 %, mean 1.0 %; without the refinement within 3.4 %, mean 0.9 %;
/// without the sightings within 14.0 %, mean 4.0 %).
const DISTORTION_SHIFT_TOL: f64 = 0.05;
/// Distortion seen by a lone camera (no stereo pairs, so no sightings in its fit; its two
/// captures paired with each other, both radial terms): the displacement at 0.7 of the radius
/// and `dk1`, relative. Seeds 101, 102 (left NavCam alone): shift −1.3 and −4.3 %, dk1 −6.0
/// and −1.6 % (before the refinement from a render made through the fit: shift −7.9 and
/// −3.7 %, dk1 −14.8 and +0.5 %).
const LONE_DISTORTION_TOL: f64 = 0.10;
/// Shadows' light direction, degrees.
const SHADOWS_TOL_DEG: f64 = targets::SHADOWS_DEG;
/// Hidden texture low-pass σ, relative.
const TEXTURE_TOL: f64 = 0.25;
/// Pose bias seen by a lone camera: displacement of a point 1.5 m ahead of the camera (the
/// terrain's distance), metres. Two cameras are held to the targets on every axis
/// ([`targets::POSE_DEG`], [`targets::POSE_M`]): the survey markers' sightings pin what the
/// pairs between the two captures cannot see.
const LONE_POSE_BIAS_TOL_M: f64 = 0.007;
/// Tolerance of an exposure hidden next to another effect is this many times wider: its gain
/// is only jointly identifiable with the falloff and response curve fitted next to it (seed
/// 101, beside a blur that a clipping offset cuts: −5.5 %). A response curve, a blur, a
/// vignetting and a pose bias (from four locations, [`test_captures`]) are held to the
/// single-effect targets in pairs too (seeds 101–108: gamma within 0.006, blur within 0.08 px
/// where named).
const PAIR_FACTOR: f64 = 2.5;
/// The figure (an index into [`Figure::ALL`]) each effect's gap is judged by — the one it
/// shrinks, [`Figure::for_effect`] — and the smallest excess of the gap over its floor (the same
/// campaign measured with the true hidden effects added) that is judged. Photometric RMS: 0.5
/// DN, since a fitted model can land that far under the floor (exposure seed 101: 0.43 DN, it
/// absorbs the laser renders' own darkness). Alignment residual: 0.02 (vignetting alone moves
/// it 0.014). Spectrum RMS log ratio: 0.05. Photometric RMS in cast shadow: 0.5 DN. Texture
/// band-power deficit: 0.05.
fn judged_by(effect: &str) -> Option<(usize, f64)> {
    let figure = Figure::for_effect(effect)?;
    let k = Figure::ALL.iter().position(|f| *f == figure)?;
    let min_excess = match figure {
        Figure::PhotometricRmsDn | Figure::ShadowRmsDn => 0.5,
        Figure::AlignmentResidual => 0.02,
        Figure::SpectrumRmsLogRatio | Figure::TextureBandDeficit => 0.05,
    };
    Some((k, min_excess))
}

/// Shrink checks of one case: every figure its hidden effects are judged by must shrink by at
/// least half of its excess over the floor; violations appended to `bad`.
fn check_shrink(r: &CaseResult, hidden: &[&str], bad: &mut Vec<String>) {
    let (before, after, floor) = (
        figures(&r.gap.metrics_before),
        figures(&r.gap.metrics_after),
        figures(&r.floor),
    );
    for h in hidden {
        let Some((k, min_excess)) = judged_by(h) else {
            continue;
        };
        let excess = before[k] - floor[k];
        let shrink = before[k] - after[k];
        if excess > min_excess && shrink < 0.5 * excess {
            bad.push(format!(
                "{h}: {} {:.3}→{:.3} shrank by {shrink:.3}, under half its excess {excess:.3} over the floor {:.3}",
                Figure::ALL[k].label(), before[k], after[k], floor[k]
            ));
        }
    }
}

fn rel(fitted: f64, truth: f64) -> f64 {
    (fitted - truth).abs() / truth.abs().max(1e-9)
}

/// Displacement (m) a pose bias makes at a point 1.5 m along the optical axis.
fn bias_displacement(e: &Effect) -> [f64; 3] {
    let model = SensorModel::from(vec![*e]);
    let p = model
        .pose(&Placement::lone(Pose::IDENTITY))
        .transform_point([0.0, 0.0, 1.5]);
    [p[0], p[1], p[2] - 1.5]
}

/// The effect `name` as the run found it ([`CaseResult::found`]; an exposure's gain through the
/// texture transfer).
fn fitted_effect(r: &CaseResult, name: &str) -> Option<Effect> {
    if !r.found().iter().any(|n| n == name) {
        return None;
    }
    let neutral = Effect::neutral(name)?;
    let values: BTreeMap<&str, f64> = neutral
        .params()
        .into_keys()
        .filter_map(|k| Some((k, r.fitted(name, k)?)))
        .collect();
    Some(neutral.with_params(&values))
}

/// Parameter checks of one named, hidden effect; every check's figure appended to `seen`, the
/// violations to `bad`.
/// `lone`: the case looked through one camera ([`LONE_DISTORTION_TOL`] for a distortion).
fn check_params(
    r: &CaseResult,
    truth: &Effect,
    lone: bool,
    seen: &mut Vec<String>,
    bad: &mut Vec<String>,
) {
    let name = truth.name();
    let widen = if r.truth.len() > 1 && name == "exposure" {
        PAIR_FACTOR
    } else {
        1.0
    };
    let (shift_tol, dk1_tol) = if lone {
        (LONE_DISTORTION_TOL, LONE_DISTORTION_TOL)
    } else {
        (DISTORTION_SHIFT_TOL, targets::DK1_REL)
    };
    let Some(fit) = fitted_effect(r, name) else {
        return;
    };
    let (t, f) = (truth.params(), fit.params());
    let mut check = |what: &str, ok: bool, detail: String| {
        let line = format!("{name} {what}: {detail}");
        seen.push(format!("    {} {line}", if ok { "ok  " } else { "FAIL" }));
        if !ok {
            bad.push(line);
        }
    };
    match name {
        "gamma" => check(
            "gamma",
            (f["gamma"] - t["gamma"]).abs() <= widen * GAMMA_TOL,
            format!("{:.4} for {:.4}", f["gamma"], t["gamma"]),
        ),
        "blur" => check(
            "sigma_px",
            (f["sigma_px"] - t["sigma_px"]).abs() <= widen * BLUR_TOL_PX,
            format!("{:.3} for {:.3}", f["sigma_px"], t["sigma_px"]),
        ),
        "vignetting" => check(
            "strength",
            rel(f["strength"], t["strength"]) <= VIGNETTING_TOL,
            format!("{:.4} for {:.4}", f["strength"], t["strength"]),
        ),
        "noise" => {
            for k in ["gain", "read_sigma"] {
                check(
                    k,
                    rel(f[k], t[k]) <= widen * NOISE_TOL,
                    format!("{:.4} for {:.4}", f[k], t[k]),
                );
            }
        }
        "exposure" => check(
            "gain",
            rel(f["gain"], t["gain"]) <= widen * EXPOSURE_GAIN_TOL,
            format!("{:.4} for {:.4}", f["gain"], t["gain"]),
        ),
        "distortion" => {
            let (a, b) = (
                distortion_shift(f["dk1"], f["dk2"]),
                distortion_shift(t["dk1"], t["dk2"]),
            );
            check(
                "shift at 0.7",
                rel(a, b) <= widen * shift_tol,
                format!("{a:.5} for {b:.5} ({:+.1} %)", 100.0 * (a / b - 1.0)),
            );
            check(
                "dk1",
                rel(f["dk1"], t["dk1"]) <= widen * dk1_tol,
                format!(
                    "{:.4} for {:.4} ({:+.1} %)",
                    f["dk1"],
                    t["dk1"],
                    100.0 * (f["dk1"] / t["dk1"] - 1.0)
                ),
            );
        }
        "shadows" => {
            let daz = ((f["azimuth_deg"] - t["azimuth_deg"] + 540.0) % 360.0) - 180.0;
            let del = f["elevation_deg"] - t["elevation_deg"];
            check(
                "direction",
                daz.abs() <= widen * SHADOWS_TOL_DEG && del.abs() <= widen * SHADOWS_TOL_DEG,
                format!("azimuth off {daz:.2}°, elevation off {del:.2}°"),
            );
        }
        "texture-lowpass" => check(
            "sigma_m",
            rel(f["sigma_m"], t["sigma_m"]) <= widen * TEXTURE_TOL,
            format!("{:.4} for {:.4}", f["sigma_m"], t["sigma_m"]),
        ),
        "pose-bias" if lone => {
            let (a, b) = (bias_displacement(&fit), bias_displacement(truth));
            let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            check(
                "displacement at 1.5 m",
                d <= widen * LONE_POSE_BIAS_TOL_M,
                format!("{:.1} mm off", d * 1e3),
            );
        }
        "pose-bias" => {
            for (k, v) in &t {
                let (tol, unit, scale) = if k.starts_with("rotation") {
                    (targets::POSE_DEG, "°", 1.0)
                } else {
                    (targets::POSE_M, " mm", 1e3)
                };
                let e = f[k] - v;
                check(
                    k,
                    e.abs() <= widen * tol,
                    format!("{:+.3}{unit} off", e * scale),
                );
            }
        }
        _ => {}
    }
}

/// What a case hid and how it was looked at.
struct Case<'a> {
    label: &'a str,
    seed: u64,
    hidden: &'a [&'a str],
    /// Through one camera alone (see [`check_params`]).
    lone: bool,
}

/// Judges one case: naming (counted in `matrix`), parameters (their figures appended to
/// `lines`) and shrink; violations appended to `bad`.
fn judge(
    r: &CaseResult,
    case: &Case<'_>,
    matrix: &mut Confusion,
    lines: &mut Vec<String>,
    bad: &mut Vec<String>,
) {
    let mut case_bad = Vec::new();
    let named = r.found();
    if !matrix.add(case.label, case.hidden, &named) {
        case_bad.push(format!("named {named:?}, hidden {:?}", case.hidden));
    }
    for t in &r.truth {
        check_params(r, t, case.lone, lines, &mut case_bad);
    }
    check_shrink(r, case.hidden, &mut case_bad);
    bad.extend(
        case_bad
            .into_iter()
            .map(|b| format!("{} seed {}: {b}", case.label, case.seed)),
    );
}

#[test]
fn every_hidden_effect_is_named_fitted_and_shrinks_the_gap() {
    let root = tempfile::tempdir().unwrap();
    let mut bad = Vec::new();
    let mut matrix = Confusion::default();
    let mut lines = Vec::new();
    for (label, hidden) in cases() {
        for seed in SEEDS {
            let setup = Setup {
                captures: test_captures(&label),
                ..Setup::default()
            };
            let r = run_case(root.path(), &label, seed, &hidden, &setup);
            lines.push(r.line(&label, seed));
            let case = Case {
                label: &label,
                seed,
                hidden: &hidden,
                lone: false,
            };
            judge(&r, &case, &mut matrix, &mut lines, &mut bad);
        }
    }
    println!("{}", lines.join("\n"));
    println!("\n{matrix}");
    assert!(
        bad.is_empty(),
        "{} violations:\n{}\n\ncases:\n{}\n\n{matrix}",
        bad.len(),
        bad.join("\n"),
        lines.join("\n")
    );
}

/// Runs the single-effect case `label` (hidden `label`) on `seeds` with `setup` and asserts it
/// is judged right on each.
fn assert_single_effect_cases(label: &'static str, seeds: &[u64], setup: &Setup) {
    let root = tempfile::tempdir().unwrap();
    let (mut bad, mut lines) = (Vec::new(), Vec::new());
    let mut matrix = Confusion::default();
    let hidden = [label];
    for &seed in seeds {
        let r = run_case(root.path(), label, seed, &hidden, setup);
        lines.push(r.line(label, seed));
        let case = Case {
            label,
            seed,
            hidden: &hidden,
            lone: false,
        };
        judge(&r, &case, &mut matrix, &mut lines, &mut bad);
    }
    println!("{}", lines.join("\n"));
    assert!(bad.is_empty(), "{}\n\n{}", bad.join("\n"), lines.join("\n"));
}

/// A mild response curve (1.15) is almost a straight line over a terrain's intensities, and
/// an exposure offset of ~0.05 fits it better held out; the repeat frames' noise over the black
/// sky shows the curve (and the sky, which the offset would lift to ~13 DN, is at 0).
#[test]
fn a_mild_response_curve_is_named_gamma_not_an_exposure() {
    let setup = Setup {
        effect_params: vec!["gamma.gamma=1.15".into()],
        ..Setup::default()
    };
    assert_single_effect_cases("gamma", &SEEDS, &setup);
}

/// An exposure that brightens with little offset (gains 1.11 and 1.14) is, over a terrain's
/// intensities, as much a response curve of 1.1–1.2 to the render (from mini's two captures
/// the curve's held-out error was the lower); the repeat frames' noise shows the response is
/// linear and where the black level is.
#[test]
fn a_brightening_exposure_is_named_exposure_not_a_response_curve() {
    assert_single_effect_cases("exposure", &[106, 110], &Setup::default());
}

/// From six capture locations (`corpus generate --captures 6`) a pose bias on the laser entry
/// must come out within the workflow's ±0.1° and ±3 mm on every axis: the cross-capture pairs
/// (the gap module's `geometry::cross_pairs`) see a bias fixed to the rig free of the entry's
/// texture. Seeds 101–104: worst axes −0.071°/−2.2 mm, −0.014°/+0.7 mm, +0.078°/−1.7 mm,
/// −0.068°/−1.6 mm (before those pairs seed 102's pitch read 0.14° off with 3 mm of y, and seed
/// 103's 0.36–0.38°).
#[test]
fn a_pose_bias_seen_from_six_capture_locations_is_within_the_targets_on_every_axis() {
    assert_within_targets_on_every_axis(
        &Setup {
            captures: Some(6),
            ..Setup::default()
        },
        &[("pose-bias", 101), ("pose-bias", 102)],
    );
}

/// The fitted parameters of `r`'s one hidden effect `label` off the truth by more than the
/// workflow's targets on any axis (±0.1°, ±3 mm, `dk1` ±5 %), one line each; also a case
/// that named anything else.
fn axis_misses(r: &CaseResult, label: &str, seed: u64, line: &str) -> Vec<String> {
    let mut bad: Vec<String> = r
        .target_checks()
        .iter()
        .filter(|c| c.what.starts_with(&format!("{label}.")) && !c.ok())
        .map(|c| format!("seed {seed}: {c}: {line}"))
        .collect();
    if r.found() != [label] {
        bad.push(format!("seed {seed}: {line}"));
    }
    bad
}

/// Runs each `(label, seed)` case under `setup` and asserts [`axis_misses`] finds nothing.
fn assert_within_targets_on_every_axis(setup: &Setup, cases: &[(&str, u64)]) {
    let root = tempfile::tempdir().unwrap();
    let mut bad = Vec::new();
    for &(label, seed) in cases {
        let r = run_case(root.path(), label, seed, &[label], setup);
        let line = r.line(
            &format!(
                "{label} ({:?}, {:?} captures)",
                setup.terrain, setup.captures
            ),
            seed,
        );
        println!("{line}");
        bad.extend(axis_misses(&r, label, seed, &line));
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The geometric stage given the campaign's true terrain instead of the laser entry: a pose
/// bias must come out within the workflow's ±0.1° and ±3 mm on every axis, and a distortion's
/// `dk1` within ±5 %, from mini's two capture locations. Seeds 101, 102 read a pose bias within
/// 0.020°/0.3 mm and 0.028°/0.3 mm, `dk1` −4.1 and −2.6 % off (seeds 101–108 mean 1.4 %,
/// `dk2` within 0.0022; before the fit was refined from a render made through it −2.8 and
/// −1.0 %, mean 1.7 %, `dk2` within 0.0036, and seed 113 +8.6 %; with the survey markers sampled
/// 0.018°/0.3 mm, 0.029°/0.3 mm, 2.7 and 0.3 %; 103, 104: 0.007°/0.2 mm, 0.006°/0.1 mm, 0.0
/// and 1.1 %), where the laser entry from these two locations leaves a pose bias's axes up to
/// 0.31° and 7.9 mm off (seed 101) and `dk1` up to 27 % off (seeds 101–114): what limits
/// those is the entry, not the fit (for the pose bias, its texture: see the next test).
#[test]
fn with_the_true_terrain_a_pose_bias_and_a_distortion_are_within_the_targets_on_every_axis() {
    assert_within_targets_on_every_axis(
        &Setup {
            terrain: TerrainChoice::Truth,
            ..Setup::default()
        },
        &[
            ("pose-bias", 101),
            ("pose-bias", 102),
            ("distortion", 101),
            ("distortion", 102),
        ],
    );
}

/// The laser entry's own heights with the campaign's true albedo in place of its texture: a
/// pose bias must come out within ±0.1° and ±3 mm on every axis from the two capture
/// locations, so the compiled geometry is good enough and what the workflow misses on the
/// entry comes from its texture (laser reflectance: see the gap module). Seeds 101–104:
/// worst axes −0.07°/−2.9 mm, +0.08°/+2.5 mm, +0.10°/+2.3 mm, −0.02°/+0.4 mm, where the entry
/// with its texture reads (101, 102) −0.31°/+7.9 mm and +0.11°/−1.2 mm (with the stereo pairs
/// alone, before the cross-capture pairs: −0.13°/−5.0 mm and +0.41°/+11.9 mm). A distortion is not
/// separated so: `dk1` still reads −9.4 and −3.6 % off on 101, 102 (its valley with `dk2`
/// depends on the heights too).
#[test]
fn with_the_entry_heights_and_the_true_albedo_a_pose_bias_is_within_the_targets_on_every_axis() {
    assert_within_targets_on_every_axis(
        &Setup {
            terrain: TerrainChoice::EntryHeightsTrueAlbedo,
            ..Setup::default()
        },
        &[("pose-bias", 101), ("pose-bias", 102)],
    );
}

/// One camera of the stereo head examined alone (`--cameras navcam_left`): no stereo pairs join
/// the geometric fits and none witnesses them, the distortion's radial terms are chosen on the
/// held-out render residual, and the rig frame is the camera's own. Nothing hidden must name
/// nothing; a distortion and a pose bias must be named alone, fitted within
/// [`LONE_DISTORTION_TOL`] and [`POSE_BIAS_TOL_M`], and shrink their gap.
#[test]
fn a_lone_camera_names_nothing_for_nothing_and_finds_a_distortion_and_a_pose_bias() {
    let root = tempfile::tempdir().unwrap();
    let setup = Setup {
        cameras: vec!["navcam_left".into()],
        ..Setup::default()
    };
    let mut bad = Vec::new();
    let mut lines = Vec::new();
    let mut matrix = Confusion::default();
    for hidden in [vec![], vec!["distortion"], vec!["pose-bias"]] {
        let label = hidden.first().copied().unwrap_or("none");
        for seed in SEEDS {
            let r = run_case(root.path(), label, seed, &hidden, &setup);
            lines.push(r.line(&format!("{label} (left alone)"), seed));
            let case = Case {
                label,
                seed,
                hidden: &hidden,
                lone: true,
            };
            judge(&r, &case, &mut matrix, &mut lines, &mut bad);
        }
    }
    println!("{}\n\n{matrix}", lines.join("\n"));
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}
