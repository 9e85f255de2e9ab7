//! `merge.clean` benchmark on a generated campaign: loads every `[[scan]]` as `regolith compile`
//! does, places it with the generator's true `ground_from_socs` (`truth/scans.json`; registration
//! is not what is measured), runs the stage and prints its seconds, the output counts and a
//! SHA-256 of every output array (points, scan, reflectance, albedo, stats) so two builds can be
//! compared byte for byte. `--phases` also times the neighbourhood parts on their own: the SOR
//! neighbours by the column grid `merge.clean` uses, and the same and the normal-sized queries
//! by the kd-tree `KnnIndex`. Timing lives here, never in tests.
//!
//! `cargo run --release -p regolith-compiler --example bench_merge -- CAMPAIGN_DIR [--phases]`
//! (e.g. after `regolith corpus generate --preset estec --seed 1 --full --out /tmp/estec_m/camp`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;
use regolith_compiler::ingest::campaign;
use regolith_compiler::ingest::types::{transform, Matrix4};
use regolith_compiler::inventory;
use regolith_compiler::stage::{Stage, StageCx};
use regolith_compiler::stages::geometry::{build_tree, knn, KnnIndex};
use regolith_compiler::stages::merge_clean::{MergeClean, MergeScan, MergedCloud};
use regolith_compiler::stages::self_knn::map_self_knn;

/// Neighbours of the normal-sized queries timed and checked (the incidence normals of
/// `merge.clean` used the 16 nearest points before they moved to a ground window).
const NORMAL_K: usize = 16;
use regolith_format::limits::Limits;
use sha2::{Digest, Sha256};

fn truth_transforms(dir: &Path) -> Vec<(String, Matrix4)> {
    let text = std::fs::read_to_string(dir.join("truth/scans.json")).expect("truth/scans.json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("json");
    v["scans"]
        .as_array()
        .expect("scans")
        .iter()
        .map(|s| {
            let m: Matrix4 =
                serde_json::from_value(s["ground_from_socs_matrix"].clone()).expect("matrix");
            (s["name"].as_str().expect("name").to_string(), m)
        })
        .collect()
}

fn digest(m: &MergedCloud) -> String {
    let mut h = Sha256::new();
    for p in &m.points {
        for v in p {
            h.update(v.to_le_bytes());
        }
    }
    for s in &m.scan {
        h.update(s.to_le_bytes());
    }
    for v in [&m.reflectance_db, &m.reflectance, &m.albedo] {
        match v {
            Some(v) => v.iter().for_each(|x| h.update(x.to_le_bytes())),
            None => h.update(b"none"),
        }
    }
    h.update(serde_json::to_vec(&m.stats).expect("stats"));
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = Path::new(
        args.first()
            .expect("usage: bench_merge CAMPAIGN_DIR [--phases]"),
    );
    let phases = args.iter().any(|a| a == "--phases");
    let c = campaign::load(dir).expect("campaign");
    let truth = truth_transforms(dir);
    let t0 = Instant::now();
    let scans: Vec<MergeScan> = c
        .scans
        .iter()
        .map(|s| {
            let cloud = inventory::load_scan(&c.root, s, &Limits::default()).expect("load");
            let m = truth
                .iter()
                .find(|(n, _)| *n == s.name)
                .map(|(_, m)| *m)
                .expect("truth transform");
            MergeScan {
                name: s.name.clone(),
                cloud,
                ground_from_socs: m,
            }
        })
        .collect();
    let n: usize = scans.iter().map(|s| s.cloud.points.len()).sum();
    println!(
        "loaded {} scans, {n} points in {:.1} s; {} threads",
        scans.len(),
        t0.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    if phases {
        let t = Instant::now();
        let pts: Vec<[f64; 3]> = scans
            .iter()
            .flat_map(|s| {
                let m = s.ground_from_socs;
                s.cloud.points.iter().map(move |p| transform(&m, *p))
            })
            .collect();
        println!(
            "phase transform+merge     {:7.2} s",
            t.elapsed().as_secs_f64()
        );
        let t = Instant::now();
        let s: f64 = map_self_knn(&pts, 9, |d2| d2.iter().map(|d| d.sqrt()).sum::<f64>())
            .expect("points")
            .iter()
            .sum();
        println!(
            "column grid knn (k= 9)    {:7.2} s  ({s:.6})",
            t.elapsed().as_secs_f64()
        );
        let t = Instant::now();
        let ix = KnnIndex::new(&pts).expect("points");
        println!(
            "KnnIndex build            {:7.2} s",
            t.elapsed().as_secs_f64()
        );
        for k in [9, NORMAL_K] {
            let t = Instant::now();
            let s: f64 = ix
                .points()
                .par_iter()
                .map_init(Vec::new, |nb, p| {
                    ix.knn(p, k, None, nb);
                    nb.iter().map(|x| x.d2.sqrt()).sum::<f64>()
                })
                .sum();
            println!(
                "KnnIndex knn (k={k:2})       {:7.2} s  ({s:.6})",
                t.elapsed().as_secs_f64()
            );
        }
    }
    let cx = StageCx::default();
    let t = Instant::now();
    let out = MergeClean::default().run(&cx, &scans).expect("merge");
    let dt = t.elapsed().as_secs_f64();
    println!("merge.clean {dt:.2} s: {:?}", out.stats);
    println!("radiometry {:?}", out.radiometry);
    println!("digest {}", digest(&out));
    if args.iter().any(|a| a == "--check") {
        check_neighbours(&out.points);
    }
}

/// Compares the normal neighbourhoods of `KnnIndex` with kiddo's on every point.
fn check_neighbours(pts: &[[f64; 3]]) {
    let t = Instant::now();
    let tree = build_tree(pts).expect("points");
    let ix = KnnIndex::new(pts).expect("points");
    let bad: Vec<(usize, u8)> = pts
        .par_iter()
        .enumerate()
        .map_init(Vec::new, |nb, (i, p)| {
            let a = knn(&tree, p, NORMAL_K);
            ix.knn(p, NORMAL_K, None, nb);
            let da: Vec<f64> = a.iter().map(|x| x.1).collect();
            let db: Vec<f64> = nb.iter().map(|x| x.d2.sqrt()).collect();
            let ia: Vec<usize> = a.iter().map(|x| x.0).collect();
            let ib: Vec<usize> = nb.iter().map(|x| x.id as usize).collect();
            let kind = if da != db {
                1
            } else if ia != ib {
                let (mut sa, mut sb) = (ia.clone(), ib.clone());
                sa.sort_unstable();
                sb.sort_unstable();
                if sa == sb {
                    2
                } else {
                    3
                }
            } else {
                0
            };
            (i, kind)
        })
        .filter(|x| x.1 != 0)
        .collect();
    let count = |k| bad.iter().filter(|x| x.1 == k).count();
    println!(
        "check {:.1} s: {} points, distances differ {}, same set other order {}, other set (ties) {}",
        t.elapsed().as_secs_f64(),
        pts.len(),
        count(1),
        count(2),
        count(3)
    );
    for &(i, kind) in bad.iter().take(5) {
        let p = pts[i];
        let mut nb = Vec::new();
        ix.knn(&p, NORMAL_K, None, &mut nb);
        println!("point {i} kind {kind} {p:?}");
        println!("  kiddo    {:?}", knn(&tree, &p, NORMAL_K));
        println!(
            "  KnnIndex {:?}",
            nb.iter().map(|x| (x.id, x.d2.sqrt())).collect::<Vec<_>>()
        );
        for x in &nb {
            println!("    {} {:?}", x.id, pts[x.id as usize]);
        }
    }
}
