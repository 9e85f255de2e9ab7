//! The gap workflow on captures its model did not make: `mini` campaigns whose NavCam frames
//! Mitsuba 3 path-traced in a lit lab hall through the corpus's own camera (the checked-in
//! renders of `corpus/renders/`), examined on the laser entry, whose texture is the scanner's
//! reflectance, not the camera's albedo.
//!
//! The seeds are the **test** seeds 301–303, disjoint from the training seeds 311–313 on which
//! the workflow's rules were examined (`corpus/renders-train/`, docs/gap-findings.md). The
//! cases asserted here are those the workflow got exactly right on every training seed: nothing
//! hidden (nothing may be named: the lab's lit rim and walls behind the terrain must not read
//! as a blur, nor the texture's radiometry as an exposure), a response curve, a texture
//! low-pass, and an exposure that differs between the capture locations (an auto-exposing
//! camera, [`AUTO_EXPOSURE`]; one exposure for every frame is the texture's transfer as much
//! as the camera's, docs/gap-findings.md); and a distortion, named on every training seed
//! (beside a pose bias on one), so only it is asserted. Each case's line is printed with its parameters
//! against the truth; the full confusion matrix over every case is the `gap_matrix` example's
//! (`FRAMES` = `corpus/renders`, `AUTO_EXPOSURE` = 0.1).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_tests::gap_case::{run_case, CaseResult, Frames, Setup};

/// The test seeds (training: 311–313).
const SEEDS: [u64; 3] = [301, 302, 303];

/// The spread of a hidden exposure between capture locations (`corpus generate
/// --auto-exposure`): neighbouring locations' gains differ by 10–20 % in log.
const AUTO_EXPOSURE: f64 = 0.1;

fn setup() -> Setup {
    Setup {
        auto_exposure: AUTO_EXPOSURE,
        frames: Frames::Mitsuba {
            renders: regolith_tests::workspace_root().join("corpus/renders"),
            render_missing: false,
        },
        ..Setup::default()
    }
}

/// Runs case `label` (hiding `hidden`) on every test seed and asserts exactly `hidden` is
/// named on each; the cases' results.
fn assert_named_exactly(label: &str, hidden: &[&str]) -> Vec<CaseResult> {
    assert_named(label, hidden, true)
}

/// Runs case `label` (hiding `hidden`) on every test seed and asserts `hidden` is named on
/// each, and nothing else when `exactly`; the cases' results.
fn assert_named(label: &str, hidden: &[&str], exactly: bool) -> Vec<CaseResult> {
    let root = tempfile::tempdir().unwrap();
    let setup = setup();
    let mut bad = Vec::new();
    let mut lines = Vec::new();
    let mut results = Vec::new();
    for seed in SEEDS {
        let r = run_case(root.path(), label, seed, hidden, &setup);
        lines.push(r.line(label, seed));
        for w in &r.gap.withheld {
            lines.push(format!("{:<22} withheld {}: {}", "", w.effect, w.reason));
        }
        let mut named = r.named();
        named.sort();
        let mut want: Vec<String> = hidden.iter().map(ToString::to_string).collect();
        want.sort();
        let missing = want.iter().any(|w| !named.contains(w));
        if missing || (exactly && named != want) {
            bad.push(format!(
                "{label} seed {seed}: named {named:?}, hidden {want:?}"
            ));
        }
        results.push(r);
    }
    println!("{}", lines.join("\n"));
    assert!(bad.is_empty(), "{}\n\n{}", bad.join("\n"), lines.join("\n"));
    results
}

#[test]
fn nothing_is_named_when_nothing_is_hidden() {
    assert_named_exactly("none", &[]);
}

#[test]
fn a_hidden_response_curve_is_named() {
    assert_named_exactly("gamma", &["gamma"]);
}

#[test]
fn a_hidden_texture_low_pass_is_named() {
    assert_named_exactly("texture-lowpass", &["texture-lowpass"]);
}

#[test]
fn a_hidden_distortion_is_named() {
    // Decided by the stereo pairs, which the entry's texture does not enter; on one training
    // seed a pose bias was named beside it, so only the distortion is asserted.
    for r in assert_named("distortion", &["distortion"], false) {
        let named = r
            .gap
            .named
            .iter()
            .find(|n| n.effect == "distortion")
            .unwrap();
        assert!(
            named.evidence.contains("stereo pairs"),
            "{}",
            named.evidence
        );
    }
}

#[test]
fn an_exposure_that_differs_between_captures_is_named() {
    for r in assert_named_exactly("exposure", &["exposure"]) {
        // Every capture has its gain, and the plain form is the brightest over the darkest.
        let gains = r.fitted_capture_gains();
        assert_eq!(gains.len(), r.capture_exposure.len(), "{gains:?}");
        let (lo, hi) = gains.values().fold((f64::INFINITY, 0.0f64), |(lo, hi), g| {
            (lo.min(*g), hi.max(*g))
        });
        let named = r.gap.named.iter().find(|n| n.effect == "exposure").unwrap();
        let ratio = named.plain["capture_gain_ratio"];
        assert!((ratio - hi / lo).abs() < 1e-12, "{ratio} for {gains:?}");
    }
}
