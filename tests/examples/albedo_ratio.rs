//! Photometric calibration check of an entry's texture: per view, the mean over terrain pixels
//! of `real DN / (255 · render radiance)` (1 when the texture holds the albedo the camera saw and
//! the camera is linear), and, given the campaign folder of a synthetic corpus, the texture
//! against the true albedo (`truth/albedo.png`) over measured cells.
//! `cargo run --release -p regolith-tests --example albedo_ratio -- DB ENTRY [CAMPAIGN]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_reader::heightfield::decode_grey_png;
use regolith_tests::albedo_truth::texture_vs_truth;
use regolith_validator::render::{Light, RenderOptions, Scene, View};

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let db = regolith_reader::Database::open(&a[0]).expect("db");
    let view = db.release("latest").expect("release");
    let entry = &a[1];
    let geometry = regolith_validator::validate::entry_geometry(&view, entry).expect("geometry");
    let scene = Scene::new(&geometry);
    let light: Light =
        serde_json::from_value(view.entry("captures").unwrap().meta["lighting"].clone()).unwrap();
    let images = view.captures("captures").unwrap().images().unwrap();
    let mut all = Vec::new();
    for img in images
        .iter()
        .filter(|i| i.frame == 0 && i.kind == regolith_reader::captures::ImageKind::Raw)
    {
        let camera = view.camera(&format!("cameras/{}", img.camera)).unwrap();
        let r = scene.render(
            &light,
            &View {
                camera,
                ground_from_camera: img.ground_from_camera,
            },
            &RenderOptions {
                distort: true,
                shadows: false,
                supersample: 2,
                filter_textures: true,
                adaptive: false,
            },
        );
        let real = decode_grey_png(&img.data, 32_768).unwrap();
        let ratios: Vec<f64> = (0..r.radiance.len())
            .filter(|&i| r.mask[i] == 255 && r.radiance[i] > 0.02 && real.samples[i] < 255)
            .map(|i| f64::from(real.samples[i]) / (255.0 * f64::from(r.radiance[i])))
            .collect();
        let mean = ratios.iter().sum::<f64>() / ratios.len().max(1) as f64;
        println!(
            "{entry} {} {}: mean real/(255·radiance) {mean:.3} over {} px, median {:.3}",
            img.capture,
            img.camera,
            ratios.len(),
            median(ratios.clone())
        );
        all.extend(ratios);
    }
    let mean = all.iter().sum::<f64>() / all.len().max(1) as f64;
    println!(
        "{entry} all views: mean {mean:.3}, median {:.3}",
        median(all)
    );
    if let Some(campaign) = a.get(2) {
        truth_check(&view, entry, campaign);
    }
}

/// Texture vs true albedo (nearest truth cell) over measured cells.
fn truth_check(view: &regolith_reader::ReleaseView, entry: &str, campaign: &str) {
    let t = texture_vs_truth(view, entry, std::path::Path::new(campaign)).unwrap();
    println!(
        "{entry} texture vs truth albedo over {} measured cells: median ratio {:.3}, RMS difference {:.4}",
        t.cells, t.median_ratio, t.rms
    );
    println!(
        "{entry} texture = {:.3} · truth {:+.4} (truth mean {:.4}, texture mean {:.4})",
        t.slope, t.intercept, t.means[0], t.means[1]
    );
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}
