//! The gap workflow's confusion matrix: mini campaigns with each catalogue effect hidden in
//! turn (random parameters within the documented ranges, several seeds), pairs, and nothing
//! hidden; each is compiled and `gap` runs on its finest laser entry. Prints one line per case
//! (hidden → named, fitted vs true parameters, gap before → after) and the matrix.
//!
//! `cargo run --release -p regolith-tests --example gap_matrix -- [SEEDS] [OUT_DIR] [CASES] [CAPTURES]`
//! (`CASES`: comma-separated case labels, e.g. `none,distortion`, or `all`; `CAPTURES`: capture
//! locations per campaign, default the preset's 2).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::path::Path;

use regolith_corpus::effects::HiddenSpec;
use regolith_corpus::presets::Preset;
use regolith_corpus::{generate, GenerateOptions};
use regolith_reader::{Database, Writer};
use regolith_validator::gap::{self, GapOptions};
use regolith_validator::sensor::Effect;

fn run_case(
    root: &Path,
    label: &str,
    seed: u64,
    hidden: &[&str],
    captures: Option<usize>,
) -> (Vec<String>, String) {
    let dir = root.join(format!("{label}-{seed}"));
    let _ = std::fs::remove_dir_all(&dir);
    let camp = dir.join("camp");
    let opts = GenerateOptions {
        preset: Preset::Mini,
        seed,
        full: false,
        captures,
        hidden: hidden.iter().map(|h| HiddenSpec::named(h)).collect(),
    };
    generate(&opts, &camp, &|_, _| {}).unwrap();
    let c = regolith_compiler::ingest::campaign::load(&camp).unwrap();
    let writer = Writer::create_or_open(dir.join("db")).unwrap();
    regolith_compiler::compile::compile(
        &c,
        &writer,
        &regolith_compiler::compile::options(&c, Some("mini@1")),
        &|_, _| {},
    )
    .unwrap();
    drop(writer);
    let db = Database::open(dir.join("db")).unwrap();
    let view = db.release("mini@1").unwrap();
    let r = gap::run(&view, "laser/0.01", &GapOptions::default()).unwrap();
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(camp.join("truth/hidden.json")).unwrap()).unwrap();
    let truth: Vec<Effect> = serde_json::from_value(truth["effects"].clone()).unwrap();
    let named: Vec<String> = r.named.iter().map(|n| n.effect.clone()).collect();
    let mut detail = String::new();
    for t in &truth {
        let fitted = r.named.iter().find(|n| n.effect == t.name());
        for (k, v) in t.params() {
            let f = fitted.and_then(|n| n.params.get(k)).copied();
            detail += &format!(
                " {}.{k}={v:.4}→{}",
                t.name(),
                f.map_or("-".into(), |f| format!("{f:.4}"))
            );
        }
    }
    let line = format!(
        "{label:<22} seed {seed}: named {:?}{detail}; gap {:.2}→{:.2} DN",
        named, r.gap_before, r.gap_after
    );
    (named, line)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: Vec<u64> = args
        .first()
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or_else(|| vec![101, 102]);
    let root = Path::new(args.get(1).map_or("/tmp/gap_matrix", String::as_str)).to_path_buf();
    let mut cases: Vec<(String, Vec<&str>)> = vec![("none".into(), vec![])];
    for e in Effect::NAMES {
        cases.push((e.to_string(), vec![e]));
    }
    for pair in [
        ["vignetting", "gamma"],
        ["blur", "exposure"],
        ["pose-bias", "vignetting"],
    ] {
        cases.push((pair.join("+"), pair.to_vec()));
    }
    let captures: Option<usize> = args.get(3).map(|s| s.parse().unwrap());
    if let Some(only) = args.get(2).filter(|s| *s != "all") {
        let only: Vec<&str> = only.split(',').collect();
        cases.retain(|(label, _)| only.contains(&label.as_str()));
    }
    // matrix[hidden][named] = count
    let mut matrix: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let mut correct = 0usize;
    let mut total = 0usize;
    for (label, hidden) in &cases {
        for &seed in &seeds {
            let (named, line) = run_case(&root, label, seed, hidden, captures);
            println!("{line}");
            let row = matrix.entry(label.clone()).or_default();
            if named.is_empty() {
                *row.entry("(none)".into()).or_default() += 1;
            }
            for n in &named {
                *row.entry(n.clone()).or_default() += 1;
            }
            let mut want: Vec<String> = hidden.iter().map(|s| s.to_string()).collect();
            let mut got = named.clone();
            want.sort();
            got.sort();
            total += 1;
            correct += usize::from(want == got);
        }
    }
    println!("\nconfusion (hidden → named counts):");
    for (h, row) in &matrix {
        let cells: Vec<String> = row.iter().map(|(n, c)| format!("{n}×{c}")).collect();
        println!("  {h:<22} {}", cells.join(" "));
    }
    println!("\nexactly right: {correct}/{total}");
}
