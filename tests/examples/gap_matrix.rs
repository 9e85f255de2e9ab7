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

use regolith_tests::gap_case::{cases, run_case};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: Vec<u64> = args
        .first()
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or_else(|| vec![101, 102]);
    let root = Path::new(args.get(1).map_or("/tmp/gap_matrix", String::as_str)).to_path_buf();
    let mut cases = cases();
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
            let r = run_case(&root, label, seed, hidden, captures);
            println!("{}", r.line(label, seed));
            let named = r.named();
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
