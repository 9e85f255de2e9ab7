//! Times every detector and optionally dumps keypoints for the OpenCV peer check.
//!
//! ```text
//! cargo run --release -p regolith-validator --example bench_features -- \
//!     [--threads N] [--reps N] [--out DIR] [--params JSON] [--only DETECTOR] [IMAGE ...]
//! ```
//! Always runs the synthetic 1280×1024 scene (`features::synthetic::bench_scene`), then each
//! image given (converted to 8-bit grey). With `--out DIR` it writes, per image `<stem>`, the
//! exact grey input as `<stem>.png` (so OpenCV sees the same levels, whatever the JPEG decoder),
//! `<stem>.<detector>.json` (our keypoints) and `timings.json`. Times are the median of
//! `--reps` runs (default 5) on a rayon pool of `--threads` threads (default 1). `--params`
//! takes a `DetectorParams` JSON object (missing fields keep their defaults); `--only` times one
//! detector (for profiling) and skips the descriptors.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::error::Error;
use std::path::{Path, PathBuf};
use std::time::Instant;

use regolith_validator::features::{self, synthetic, Detector, DetectorParams, GreyF32};

fn load(path: &Path) -> Result<GreyF32, Box<dyn Error>> {
    let img = image::open(path)?.to_luma8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    GreyF32::from_u8(w, h, img.as_raw())
        .ok_or_else(|| format!("{}: bad size", path.display()).into())
}

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let (mut threads, mut reps, mut out, mut paths) = (1usize, 5usize, None::<PathBuf>, Vec::new());
    let mut params = DetectorParams::default();
    let mut only: Option<Detector> = None;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--threads" => threads = args.next().ok_or("--threads N")?.parse()?,
            "--reps" => reps = args.next().ok_or("--reps N")?.parse()?,
            "--out" => out = Some(PathBuf::from(args.next().ok_or("--out DIR")?)),
            "--params" => params = serde_json::from_str(&args.next().ok_or("--params JSON")?)?,
            "--only" => only = Some(args.next().ok_or("--only DETECTOR")?.parse()?),
            _ => paths.push(PathBuf::from(a)),
        }
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let mut inputs = vec![("synthetic".to_string(), synthetic::bench_scene())];
    for p in &paths {
        let stem = p
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("image")
            .to_string();
        inputs.push((stem, load(p)?));
    }
    if let Some(dir) = &out {
        std::fs::create_dir_all(dir)?;
    }
    let mut timings = serde_json::Map::new();
    println!(
        "{:<48} {:>8} {:>8} {:>10}",
        "image", "detector", "points", "ms (med)"
    );
    for (stem, img) in &inputs {
        if let Some(dir) = &out {
            let levels = img.to_u8();
            image::save_buffer(
                dir.join(format!("{stem}.png")),
                &levels,
                img.width as u32,
                img.height as u32,
                image::ExtendedColorType::L8,
            )?;
        }
        for d in Detector::ALL
            .into_iter()
            .filter(|d| only.is_none_or(|o| o == *d))
        {
            let mut times = Vec::new();
            let mut kps = Vec::new();
            for _ in 0..reps.max(1) {
                let t = Instant::now();
                kps = pool.install(|| features::detect(img, d, &params));
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            times.sort_by(f64::total_cmp);
            let med = times.get(times.len() / 2).copied().unwrap_or(0.0);
            println!("{stem:<48} {:>8} {:>8} {med:>10.1}", d.name(), kps.len());
            timings.insert(
                format!("{stem}.{}", d.name()),
                serde_json::json!({"ms": med, "count": kps.len()}),
            );
            if let Some(dir) = &out {
                std::fs::write(
                    dir.join(format!("{stem}.{}.json", d.name())),
                    serde_json::to_vec(&kps)?,
                )?;
            }
        }
        for d in [Detector::Sift, Detector::Surf]
            .into_iter()
            .filter(|_| only.is_none())
        {
            let kps = pool.install(|| features::detect(img, d, &params));
            let t = Instant::now();
            let desc = pool.install(|| features::describe(img, &kps, d));
            let ms = t.elapsed().as_secs_f64() * 1e3;
            println!(
                "{stem:<48} {:>8} {:>8} {ms:>10.1}",
                format!("{}-desc", d.name()),
                desc.len()
            );
            timings.insert(
                format!("{stem}.{}-describe", d.name()),
                serde_json::json!({"ms": ms, "count": desc.len()}),
            );
        }
    }
    if let Some(dir) = &out {
        std::fs::write(
            dir.join("timings.json"),
            serde_json::to_vec_pretty(&timings)?,
        )?;
    }
    Ok(())
}
