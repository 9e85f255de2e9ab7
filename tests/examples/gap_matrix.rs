//! The gap workflow's confusion matrix: mini campaigns with each catalogue effect hidden in
//! turn (random parameters within the documented ranges, several seeds), pairs, and nothing
//! hidden; each is compiled and `gap` runs on its finest laser entry. Prints one line per case
//! (hidden → named, fitted vs true parameters, gap before → after) with the parameters off
//! their targets, then the matrix and, per parameter, how many fits met the workflow's target
//! (`gap_case::targets`: vignetting ±5 %, gamma ±0.02, blur ±0.15 px, `dk1` ±5 %, pose bias
//! ±0.1° / ±3 mm per axis, shadows ±3°) and how many errors lay within twice the standard
//! error the workflow reported (about 95 % should, if that uncertainty is honest).
//!
//! `cargo run --release -p regolith-tests --example gap_matrix -- [SEEDS] [OUT_DIR] [CASES] [CAPTURES] [CAMERAS] [PARAMS] [TERRAIN] [ENTRY] [FRAMES] [AUTO_EXPOSURE]`
//! (`CASES`: comma-separated case labels, e.g. `none,distortion`, or `all`; `CAPTURES`: capture
//! locations per campaign, default the preset's 2, `-` for it, `test` for each case's in the
//! hidden-effect test (`gap_case::test_captures`: four for a distortion and a pose bias beside
//! a vignetting); `CAMERAS`: comma-separated
//! cameras to examine, e.g. `navcam_left` for a lone camera, default (or `-`) all; `PARAMS`:
//! comma-separated hidden-effect parameters set rather than drawn, e.g. `gamma.gamma=1.15`, or
//! `-`; `TERRAIN`: `truth` to run on the campaign's true terrain instead of the laser entry,
//! `truth-albedo` for the entry's heights with the true albedo, default `entry`; `ENTRY`: the
//! entry to run on, default `laser/0.01`, e.g. `sfm/0.02`; `FRAMES`: who makes the "real"
//! frames, `model` (default: the validator's own model) or a Mitsuba render cache folder, e.g.
//! `corpus/renders` (`+` after it renders the shots it lacks: `/tmp/renders+`); `AUTO_EXPOSURE`:
//! a hidden exposure's spread between capture locations, `corpus generate --auto-exposure`,
//! default 0).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::path::Path;

use regolith_tests::gap_case::{
    cases, run_case, test_captures, Confusion, Frames, Setup, TerrainChoice,
};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: Vec<u64> = args
        .first()
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or_else(|| vec![101, 102]);
    let root = Path::new(args.get(1).map_or("/tmp/gap_matrix", String::as_str)).to_path_buf();
    let mut cases = cases();
    let as_tested = args.get(3).is_some_and(|s| s == "test");
    let setup = Setup {
        captures: args
            .get(3)
            .filter(|s| *s != "-" && !as_tested)
            .map(|s| s.parse().unwrap()),
        cameras: args
            .get(4)
            .filter(|s| *s != "-")
            .map(|s| s.split(',').map(String::from).collect())
            .unwrap_or_default(),
        effect_params: args
            .get(5)
            .filter(|s| *s != "-")
            .map(|s| s.split(',').map(String::from).collect())
            .unwrap_or_default(),
        terrain: args.get(6).map_or(TerrainChoice::Entry, |s| {
            TerrainChoice::parse(s).expect("TERRAIN: entry, truth or truth-albedo")
        }),
        entry: args.get(7).filter(|s| *s != "-").cloned(),
        frames: match args.get(8).map(String::as_str) {
            None | Some("model" | "-") => Frames::Model,
            Some(dir) => Frames::Mitsuba {
                renders: dir.trim_end_matches('+').into(),
                render_missing: dir.ends_with('+'),
            },
        },
        auto_exposure: args.get(9).map_or(0.0, |s| s.parse().unwrap()),
    };
    if let Some(only) = args.get(2).filter(|s| *s != "all") {
        let only: Vec<&str> = only.split(',').collect();
        cases.retain(|(label, _)| only.contains(&label.as_str()));
    }
    let mut matrix = Confusion::default();
    // `effect.parameter` → (within the target, checked, error within 2 reported σ, with a σ).
    let mut tally: BTreeMap<String, (usize, usize, usize, usize)> = BTreeMap::new();
    for (label, hidden) in &cases {
        for &seed in &seeds {
            let setup = if as_tested {
                Setup {
                    captures: test_captures(label),
                    ..setup.clone()
                }
            } else {
                setup.clone()
            };
            let r = run_case(&root, label, seed, hidden, &setup);
            println!("{}", r.line(label, seed));
            for w in &r.gap.withheld {
                println!("{:<22} withheld {}: {}", "", w.effect, w.reason);
            }
            let checks = r.target_checks();
            let off: Vec<String> = checks
                .iter()
                .filter(|c| !c.ok())
                .map(ToString::to_string)
                .collect();
            if !off.is_empty() {
                println!("{:<22} seed {seed}: off target: {}", "", off.join(", "));
            }
            for c in checks {
                let t = tally.entry(c.what.clone()).or_default();
                t.0 += usize::from(c.ok());
                t.1 += 1;
                if let Some(covered) = c.covered() {
                    t.2 += usize::from(covered);
                    t.3 += 1;
                }
            }
            // On another renderer's frames the laser texture has a level of its own, so a
            // texture transfer is no exposure there (`CaseResult::found`).
            let found = if setup.frames == Frames::Model {
                r.found()
            } else {
                r.named()
            };
            matrix.add(label, hidden, &found);
        }
    }
    println!("\n{matrix}");
    println!("\nwithin the parameter targets (and within twice the reported σ):");
    for (what, (ok, n, covered, with_se)) in &tally {
        println!("  {what:<30} {ok}/{n}   ({covered}/{with_se})");
    }
}
