//! Times each detector as `validate` runs it on one image, on one thread, for the comparison
//! with OpenCV's detectors (`tools/bench/detectors.sh` runs both and prints the ratios).
//!
//! ```text
//! cargo run --release -p regolith-validator --example bench_detectors -- IMAGE... [--repeat N] [--json]
//! ```
//! Each image (PNG or JPEG; colour is converted to grey) becomes values in `[0, 1]` (8-bit
//! levels / 255, 16-bit / 65535, as `validate` decodes captures) and gets the contrast stretch
//! `validate` applies (`features::contrast::stretch`, not timed). Then every detector runs
//! `metrics::compare::detect` with `DetectorParams::default()` — exactly what `validate` calls
//! per image, so SIFT includes its descriptors and MSER its regions' ellipses — once untimed,
//! then `N` times (default 3) timed, inside a rayon pool of one thread. It prints the median wall time and the
//! keypoint count per image and detector, as a table or (`--json`) as one JSON object.

use std::error::Error;
use std::path::{Path, PathBuf};
use std::time::Instant;

use regolith_validator::features::{contrast, Detector, DetectorParams, GreyF32};
use regolith_validator::metrics::compare;
use serde_json::json;

const USAGE: &str = "usage: bench_detectors IMAGE... [--repeat N] [--json]";

/// An image as `validate` sees a capture: grey values in `[0, 1]` (16-bit images / 65535).
fn load(path: &Path) -> Result<GreyF32, Box<dyn Error>> {
    let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let color = img.color();
    let sixteen = color.bits_per_pixel() > 8 * u16::from(color.channel_count());
    let data: Vec<f32> = if sixteen {
        img.to_luma16()
            .as_raw()
            .iter()
            .map(|&v| f32::from(v) / 65535.0)
            .collect()
    } else {
        img.to_luma8()
            .as_raw()
            .iter()
            .map(|&v| f32::from(v) / 255.0)
            .collect()
    };
    GreyF32::new(w, h, data).ok_or_else(|| format!("{}: empty image", path.display()).into())
}

struct Row {
    detector: Detector,
    runs_ms: Vec<f64>,
    median_ms: f64,
    keypoints: usize,
}

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let (mut repeat, mut as_json, mut paths) = (3usize, false, Vec::new());
    while let Some(a) = args.next() {
        match a.as_str() {
            "--repeat" => repeat = args.next().ok_or(USAGE)?.parse()?,
            "--json" => as_json = true,
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            s if s.starts_with("--") => return Err(format!("unknown option {s}; {USAGE}").into()),
            _ => paths.push(PathBuf::from(a)),
        }
    }
    if paths.is_empty() || repeat == 0 {
        return Err(USAGE.into());
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let params = DetectorParams::default();
    let mut images = Vec::new();
    if !as_json {
        println!(
            "{:<40} {:>9} {:>8} {:>10} {:>10}",
            "image", "size", "detector", "keypoints", "median ms"
        );
    }
    for path in &paths {
        let img = contrast::stretch(&load(path)?);
        let mut rows = Vec::new();
        for d in Detector::ALL {
            // One untimed run first: the first call pays for fresh pages and allocator growth
            // that a `validate` over many views pays once.
            let mut found = pool.install(|| compare::detect(&img, d, &params));
            let mut runs_ms = Vec::with_capacity(repeat);
            for _ in 0..repeat {
                let t = Instant::now();
                let f = pool.install(|| compare::detect(&img, d, &params));
                runs_ms.push(t.elapsed().as_secs_f64() * 1e3);
                found = f;
            }
            let keypoints = found.keypoints().len();
            let mut sorted = runs_ms.clone();
            sorted.sort_by(f64::total_cmp);
            let median_ms = sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN);
            if !as_json {
                let name = path.file_name().and_then(|s| s.to_str()).unwrap_or("?");
                let size = format!("{}x{}", img.width, img.height);
                println!(
                    "{name:<40} {size:>9} {:>8} {keypoints:>10} {median_ms:>10.1}",
                    d.name()
                );
            }
            rows.push(Row {
                detector: d,
                runs_ms,
                median_ms,
                keypoints,
            });
        }
        images.push(json!({
            "path": path,
            "width": img.width,
            "height": img.height,
            "detectors": rows.iter().map(|r| json!({
                "detector": r.detector,
                "median_ms": r.median_ms,
                "runs_ms": r.runs_ms,
                "keypoints": r.keypoints,
            })).collect::<Vec<_>>(),
        }));
    }
    if as_json {
        let out = json!({
            "implementation": "regolith",
            "threads": 1,
            "repeat": repeat,
            "images": images,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    Ok(())
}
