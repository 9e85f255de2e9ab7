//! Ingest benchmark: RiSCAN ASCII parse speed (1 thread and all threads) next to a peer parser
//! measured in the same run (pandas `read_csv`, C engine, and numpy `loadtxt` on a slice), plus
//! LAS decode speed. Timing lives here, never in pass/fail tests.
//!
//! `cargo run --release -p regolith-compiler --example bench_ingest [-- FILE.asc | --points N]`
//! The peer needs `pip install pandas numpy`; without it the peer line says so.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::Write;
use std::process::Command;
use std::time::Instant;

use regolith_compiler::ingest::{las, riscan_ascii};
use regolith_format::limits::Limits;

fn best_of<T>(n: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..n {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    (best, last.expect("n > 0"))
}

fn synthetic_ascii(points: usize) -> Vec<u8> {
    let mut s = String::with_capacity(points * 36);
    s.push_str("X[m] Y[m] Z[m] Reflectance[dB]\n");
    let mut x: u64 = 0x2545_F491_4F6C_DD1D;
    for _ in 0..points {
        let mut r = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % 1_000_000) as f64 / 1e6
        };
        let (a, b, c, d) = (
            r() * 20.0 - 10.0,
            r() * 20.0 - 10.0,
            r() * 2.0 - 1.5,
            -(r() * 20.0),
        );
        s.push_str(&format!("{a:.4} {b:.4} {c:.4} {d:.2}\n"));
    }
    s.into_bytes()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let points: usize = args
        .iter()
        .position(|a| a == "--points")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(3_000_000);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = match args.first().filter(|a| !a.starts_with("--")) {
        Some(p) => std::path::PathBuf::from(p),
        None => {
            let p = dir.path().join("bench.asc");
            std::fs::write(&p, synthetic_ascii(points)).expect("write");
            p
        }
    };
    let bytes = std::fs::read(&path).expect("read");
    let mb = bytes.len() as f64 / 1e6;
    let limits = Limits::default();
    let threads = rayon::current_num_threads();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let (t1, cloud) = best_of(3, || {
        one.install(|| riscan_ascii::read_ascii(&bytes, None, &limits).expect("parse"))
    });
    let (tn, _) = best_of(3, || {
        riscan_ascii::read_ascii(&bytes, None, &limits).expect("parse")
    });
    let n = cloud.points.len() as f64;
    println!(
        "file: {} ({mb:.1} MB, {} points)",
        path.display(),
        cloud.points.len()
    );
    println!(
        "regolith riscan_ascii  1 thread : {:7.1} MB/s  {:6.2} Mpoints/s",
        mb / t1,
        n / t1 / 1e6
    );
    println!(
        "regolith riscan_ascii {threads} threads: {:7.1} MB/s  {:6.2} Mpoints/s",
        mb / tn,
        n / tn / 1e6
    );

    let peer = r#"
import sys, time
import numpy as np, pandas as pd
p = sys.argv[1]
best = 1e9
for _ in range(2):
    t = time.perf_counter(); df = pd.read_csv(p, sep=' ', skiprows=1, header=None, engine='c'); best = min(best, time.perf_counter() - t)
print(f"pandas {best:.4f} {len(df)}")
t = time.perf_counter(); a = np.loadtxt(p, skiprows=1, max_rows=200000); dt = time.perf_counter() - t
print(f"numpy_per_point {dt / len(a):.4e}")
"#;
    match Command::new("python3")
        .arg("-c")
        .arg(peer)
        .arg(&path)
        .output()
    {
        Ok(o) if o.status.success() => {
            let out = String::from_utf8_lossy(&o.stdout);
            for line in out.lines() {
                let f: Vec<&str> = line.split_whitespace().collect();
                match f.as_slice() {
                    ["pandas", t, _] => {
                        let t: f64 = t.parse().unwrap_or(f64::NAN);
                        println!("peer pandas.read_csv (C)    : {:7.1} MB/s  -> regolith 1 thread is {:.1}x, {threads} threads {:.1}x", mb / t, t / t1, t / tn);
                    }
                    ["numpy_per_point", t] => {
                        let t: f64 = t.parse().unwrap_or(f64::NAN);
                        println!("peer numpy.loadtxt          : {:7.1} MB/s (200k-row slice) -> regolith 1 thread is {:.0}x", mb / (t * n), t * n / t1);
                    }
                    _ => {}
                }
            }
        }
        Ok(o) => println!(
            "peer unavailable: {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("")
        ),
        Err(e) => println!("peer unavailable: {e}"),
    }

    // LAS: write the same points with the las crate, then decode from memory.
    let las_bytes = {
        let mut builder = ::las::Builder::from((1, 2));
        builder.point_format = ::las::point::Format::new(0).expect("format");
        builder.transforms = ::las::Vector {
            x: ::las::Transform {
                scale: 0.0001,
                offset: 0.0,
            },
            y: ::las::Transform {
                scale: 0.0001,
                offset: 0.0,
            },
            z: ::las::Transform {
                scale: 0.0001,
                offset: 0.0,
            },
        };
        let header = builder.into_header().expect("header");
        let mut w = ::las::Writer::new(std::io::Cursor::new(Vec::new()), header).expect("writer");
        for p in &cloud.points {
            w.write_point(::las::Point {
                x: p[0],
                y: p[1],
                z: p[2],
                ..Default::default()
            })
            .expect("write");
        }
        w.into_inner().expect("close").into_inner()
    };
    let (tl, lc) = best_of(3, || las::read_las(&las_bytes, &limits).expect("las"));
    let lmb = las_bytes.len() as f64 / 1e6;
    println!(
        "regolith las (page cache)   : {:7.1} MB/s  {:6.2} Mpoints/s ({} points, {lmb:.1} MB)",
        lmb / tl,
        lc.points.len() as f64 / tl / 1e6,
        lc.points.len()
    );
    let _ = std::io::stdout().flush();
}
