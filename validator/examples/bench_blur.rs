//! Gaussian blur benchmark (no criterion): blurs a 1280 x 1024 float raster at the sigmas the
//! gap's band-passes use (1.5–20 px) and prints the median ms per blur; with `--peer` it also
//! runs OpenCV's `GaussianBlur` on the same raster with the same kernel and borders
//! (`tools/peers/blur_opencv.py`, in the same run), and prints the time ratio and the largest
//! difference between the two results.
//!
//! Run: `cargo run -p regolith-validator --release --example bench_blur [-- --peer] [--threads N] [--reps N]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use regolith_validator::sensor::{gaussian_blur, kernel_radius};

const SIGMAS: [f64; 5] = [1.5, 3.0, 8.0, 12.0, 20.0];
const W: usize = 1280;
const H: usize = 1024;

/// A deterministic texture with detail at every scale, in DN.
fn raster() -> Vec<f32> {
    (0..W * H)
        .map(|i| {
            let (x, y) = ((i % W) as f64, (i / W) as f64);
            let hash = ((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f64 / 16_777_216.0;
            (100.0
                + 40.0 * (x * 0.011).sin() * (y * 0.017).cos()
                + 15.0 * (x * 0.13 + y * 0.07).sin()
                + 10.0 * hash) as f32
        })
        .collect()
}

fn median_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1000.0
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let (mut peer, mut threads, mut reps) = (false, rayon::current_num_threads(), 5usize);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--peer" => peer = true,
            "--threads" => threads = args.next().expect("--threads N").parse().unwrap(),
            "--reps" => reps = args.next().expect("--reps N").parse().unwrap(),
            other => panic!("unknown argument {other}"),
        }
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let data = raster();
    let ours: Vec<(f64, Vec<f32>)> = SIGMAS
        .iter()
        .map(|&sigma| {
            let mut out = Vec::new();
            let ms = pool.install(|| median_ms(reps, || out = gaussian_blur(&data, W, H, sigma)));
            (ms, out)
        })
        .collect();
    println!("{W} x {H} f32 raster, {threads} thread(s), median of {reps}");
    if !peer {
        for (sigma, (ms, _)) in SIGMAS.iter().zip(&ours) {
            let r = kernel_radius(*sigma, W.max(H));
            println!("  sigma {sigma:>4} px (radius {r:>2}): {ms:8.2} ms");
        }
        return;
    }
    let dir = std::env::temp_dir().join(format!("regolith-bench-blur-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(dir.join("input.f32"), bytes).unwrap();
    let runs: Vec<serde_json::Value> = SIGMAS
        .iter()
        .map(|&s| serde_json::json!({"sigma": s, "radius": kernel_radius(s, W.max(H))}))
        .collect();
    let job = serde_json::json!({"width": W, "height": H, "threads": threads, "reps": reps, "runs": runs});
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/peers/blur_opencv.py");
    let status = Command::new("python3")
        .arg(&script)
        .arg(&dir)
        .status()
        .expect("python3");
    assert!(status.success(), "{} failed", script.display());
    let peer: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("opencv.json")).unwrap()).unwrap();
    println!("peer: OpenCV {}", peer["version"]);
    for (i, (sigma, (ms, out))) in SIGMAS.iter().zip(&ours).enumerate() {
        let theirs: Vec<f32> = std::fs::read(dir.join(format!("opencv_{i}.f32")))
            .unwrap()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let diff = out
            .iter()
            .zip(&theirs)
            .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
        let cv = peer["ms"][i].as_f64().unwrap();
        let r = kernel_radius(*sigma, W.max(H));
        println!(
            "  sigma {sigma:>4} px (radius {r:>2}): ours {ms:8.2} ms, OpenCV {cv:8.2} ms, ratio {:5.2}, max |diff| {diff:.2e} DN",
            ms / cv
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
