//! DEM accuracy against the ground truth of a synthetic corpus campaign: per heightfield entry
//! of the database's latest release, the valid cells compared, the height RMS and the largest
//! |error| away from the marker balls (`height_truth`, the comparison `compile_mini` asserts).
//! `cargo run --release -p regolith-tests --example dem_truth -- CAMPAIGN DB`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;

use regolith_tests::height_truth::{heights_vs_truth, HeightTruth};

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let (Some(campaign), Some(db)) = (a.first(), a.get(1)) else {
        panic!("usage: dem_truth CAMPAIGN DB");
    };
    let truth = HeightTruth::load(Path::new(campaign)).expect("campaign truth");
    let db = regolith_reader::Database::open(db).expect("db");
    let view = db.release("latest").expect("release");
    println!(
        "{:<24} {:>10} {:>9} {:>9}",
        "entry", "cells", "RMS mm", "max mm"
    );
    for e in view.entries().iter().filter(|e| e.kind == "heightfield") {
        let s = heights_vs_truth(&view, &e.name, &truth).expect("heights");
        println!(
            "{:<24} {:>10} {:>9.3} {:>9.1}",
            e.name,
            s.cells,
            s.rms * 1e3,
            s.max_abs * 1e3
        );
    }
}
