//! Ingest benchmark: RiSCAN ASCII parse speed (1 thread and all threads) next to a peer parser
//! measured in the same run (pandas `read_csv`, C engine, and numpy `loadtxt` on a slice), plus
//! LAS decode speed (formats 0 and 7, from memory and from a file in the page cache, 1 thread
//! and all threads: the rayon pool's size; reading a file adds one block-reader thread) next to
//! laspy's `read` and the `las` crate's reader. Timing lives here, never in pass/fail tests.
//!
//! `cargo run --release -p regolith-compiler --example bench_ingest [-- FILE.asc | --points N]`
//! `cargo run --release -p regolith-compiler --example bench_ingest -- --campaign DIR` loads
//! every `[[scan]]` of a campaign the way `regolith compile` does (page cache warmed first) and
//! prints MB, points, seconds and MB/s per scan and in total, on 1 thread and all threads.
//! The peers need `pip install pandas numpy laspy`; without them the peer lines say so.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::{BufReader, BufWriter, Write};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use regolith_compiler::ingest::{campaign, las, riscan_ascii};
use regolith_compiler::inventory;
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
    if let Some(dir) = args
        .iter()
        .position(|a| a == "--campaign")
        .and_then(|i| args.get(i + 1))
    {
        bench_campaign(Path::new(dir), &Limits::default());
        return;
    }
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

    bench_las(&cloud.points, dir.path(), &limits, &one, threads);
    let _ = std::io::stdout().flush();
}

/// Writes `points` as LAS `version` with point format `format` (16-bit colour when it has one).
fn write_las(path: &Path, points: &[[f64; 3]], version: (u8, u8), format: u8) {
    let mut builder = ::las::Builder::from(version);
    builder.point_format = ::las::point::Format::new(format).expect("format");
    let t = ::las::Transform {
        scale: 0.0001,
        offset: 0.0,
    };
    builder.transforms = ::las::Vector { x: t, y: t, z: t };
    let header = builder.into_header().expect("header");
    let has_color = header.point_format().has_color;
    let file = BufWriter::new(std::fs::File::create(path).expect("create"));
    let mut w = ::las::Writer::new(file, header).expect("writer");
    for (i, p) in points.iter().enumerate() {
        let c = |v: f64| ((v.abs() * 6553.5) as u64 % 65_536) as u16;
        w.write_point(::las::Point {
            x: p[0],
            y: p[1],
            z: p[2],
            intensity: (i % 65_536) as u16,
            gps_time: header_needs_gps(format).then_some(i as f64 * 1e-5),
            color: has_color.then(|| ::las::Color::new(c(p[0]), c(p[1]), c(p[2]))),
            ..Default::default()
        })
        .expect("write");
    }
    w.close().expect("close");
}

fn header_needs_gps(format: u8) -> bool {
    ::las::point::Format::new(format).is_ok_and(|f| f.has_gps_time)
}

fn rate(mb: f64, n: usize, t: f64) -> String {
    format!("{:7.1} MB/s  {:6.2} Mpoints/s", mb / t, n as f64 / t / 1e6)
}

/// LAS decode speed: regolith's fast path (memory and file, 1 and all threads) next to the
/// `las` crate's reader and laspy, on the same files in the same run.
fn bench_las(
    points: &[[f64; 3]],
    dir: &Path,
    limits: &Limits,
    one: &rayon::ThreadPool,
    threads: usize,
) {
    let files = [
        ("LAS 1.2 format 0", dir.join("bench_f0.las"), (1, 2), 0),
        ("LAS 1.4 format 7", dir.join("bench_f7.las"), (1, 4), 7),
    ];
    for (_, path, version, format) in &files {
        write_las(path, points, *version, *format);
    }
    let peer = r#"
import sys, time
import numpy as np, laspy
for p in sys.argv[1:]:
    best_read = best_all = 1e9
    for _ in range(3):
        t = time.perf_counter()
        f = laspy.read(p)
        t1 = time.perf_counter()
        xyz = np.stack([np.asarray(f.x), np.asarray(f.y), np.asarray(f.z)], axis=1)
        inten = np.asarray(f.intensity, dtype=np.float32)
        if 'red' in f.point_format.dimension_names:
            rgb = np.stack([np.asarray(f.red), np.asarray(f.green), np.asarray(f.blue)], axis=1)
        t2 = time.perf_counter()
        best_read = min(best_read, t1 - t)
        best_all = min(best_all, t2 - t)
    print(f"laspy {p} {best_read:.6f} {best_all:.6f} {len(xyz)}")
"#;
    let laspy: Vec<(String, f64, f64)> = match Command::new("python3")
        .arg("-c")
        .arg(peer)
        .args(files.iter().map(|f| &f.1))
        .output()
    {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter_map(
                |l| match l.split_whitespace().collect::<Vec<_>>().as_slice() {
                    ["laspy", p, r, a, _] => {
                        Some((p.to_string(), r.parse().ok()?, a.parse().ok()?))
                    }
                    _ => None,
                },
            )
            .collect(),
        Ok(o) => {
            let err = String::from_utf8_lossy(&o.stderr);
            println!(
                "peer laspy unavailable: {}",
                err.lines().last().unwrap_or("")
            );
            Vec::new()
        }
        Err(e) => {
            println!("peer laspy unavailable: {e}");
            Vec::new()
        }
    };
    for (name, path, _, _) in &files {
        let bytes = std::fs::read(path).expect("read");
        let mb = bytes.len() as f64 / 1e6;
        // 1 thread and all threads alternate, so a burst of load from elsewhere hits both.
        let [mut t_mem1, mut t_memn, mut t_file1, mut t_filen] = [f64::INFINITY; 4];
        let mut c = None;
        for _ in 0..7 {
            let (t, v) = best_of(1, || {
                one.install(|| las::read_las(&bytes, limits).expect("las"))
            });
            t_mem1 = t_mem1.min(t);
            c = Some(v);
            t_memn = t_memn.min(best_of(1, || las::read_las(&bytes, limits).expect("las")).0);
            t_file1 = t_file1.min(
                best_of(1, || {
                    one.install(|| las::read_path(path, limits).expect("las"))
                })
                .0,
            );
            t_filen = t_filen.min(best_of(1, || las::read_path(path, limits).expect("las")).0);
        }
        let c = c.expect("ran");
        let n = c.points.len();
        let (t_crate, c2) = best_of(3, || {
            let f = BufReader::new(std::fs::File::open(path).expect("open"));
            las::read_las_from(f, limits).expect("las crate")
        });
        assert!(
            c2 == c,
            "the las crate and the fast path disagree on {name}"
        );
        println!("{name}: {n} points, {mb:.1} MB");
        println!(
            "  regolith las, memory,  1 thread : {}",
            rate(mb, n, t_mem1)
        );
        println!(
            "  regolith las, memory, {threads} threads: {}",
            rate(mb, n, t_memn)
        );
        println!(
            "  regolith las, file,    1 thread : {}",
            rate(mb, n, t_file1)
        );
        println!(
            "  regolith las, file,   {threads} threads: {}",
            rate(mb, n, t_filen)
        );
        println!(
            "  peer las crate 0.11 reader, file : {}  -> regolith file {threads} threads is {:.1}x",
            rate(mb, n, t_crate),
            t_crate / t_filen
        );
        let key = path.display().to_string();
        if let Some((_, r, a)) = laspy.iter().find(|(p, _, _)| *p == key) {
            println!(
                "  peer laspy.read, file            : {}  (read only; {} with scaled x/y/z, \
                 intensity, rgb as arrays) -> regolith file {threads} threads is {:.1}x",
                rate(mb, n, *r),
                rate(mb, n, *a).trim_start(),
                a / t_filen
            );
        }
    }
}

/// Loads every `[[scan]]` of a campaign as `regolith compile` does, timing only the loading.
fn bench_campaign(dir: &Path, limits: &Limits) {
    let c = campaign::load(dir).expect("campaign");
    let sizes: Vec<u64> = c
        .scans
        .iter()
        .map(|s| {
            let p = c.root.join(&s.file);
            // Warm the page cache: the figures are for parsing, not for the disk.
            std::fs::read(&p).expect("read").len() as u64
        })
        .collect();
    let total_mb = sizes.iter().sum::<u64>() as f64 / 1e6;
    let threads = rayon::current_num_threads();
    for t in [1, threads] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .expect("pool");
        println!(
            "{} ({} scans), {t} thread(s):",
            dir.display(),
            c.scans.len()
        );
        let all = Instant::now();
        let mut total_points = 0usize;
        for (s, bytes) in c.scans.iter().zip(&sizes) {
            let t0 = Instant::now();
            let cloud = pool
                .install(|| inventory::load_scan(&c.root, s, limits))
                .expect("load");
            let dt = t0.elapsed().as_secs_f64();
            let mb = *bytes as f64 / 1e6;
            total_points += cloud.points.len();
            println!(
                "  {:<10} {:>8.1} MB {:>10} points {:6.3} s  {}",
                s.name,
                mb,
                cloud.points.len(),
                dt,
                rate(mb, cloud.points.len(), dt)
            );
        }
        let dt = all.elapsed().as_secs_f64();
        println!(
            "  {:<10} {:>8.1} MB {:>10} points {:6.3} s  {}",
            "total",
            total_mb,
            total_points,
            dt,
            rate(total_mb, total_points, dt)
        );
    }
}
