//! Photometric calibration check of an entry's texture: per view, the mean over terrain pixels
//! of `real DN / (255 · render radiance)` (1 when the texture holds the albedo the camera saw and
//! the camera is linear), and, given the campaign folder of a synthetic corpus, the texture
//! against the true albedo (`truth/albedo.png`) over measured cells.
//! `cargo run --release -p regolith-validator --example albedo_ratio -- DB ENTRY [CAMPAIGN]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_reader::heightfield::decode_grey_png;
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
    let hf = view.heightfield(entry).unwrap();
    let tex_name = format!("{entry}/texture");
    let tex = decode_grey_png(&view.read_file(&tex_name, "image").unwrap(), 32_768).unwrap();
    let scale = if tex.bit_depth == 16 { 65535.0 } else { 255.0 };
    let truth_meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(format!("{campaign}/truth/height.json")).unwrap())
            .unwrap();
    let truth = decode_grey_png(
        &std::fs::read(format!("{campaign}/truth/albedo.png")).unwrap(),
        32_768,
    )
    .unwrap();
    let t_origin = [
        truth_meta["origin_m"][0].as_f64().unwrap(),
        truth_meta["origin_m"][1].as_f64().unwrap(),
    ];
    let t_cell = truth_meta["cell_m"].as_f64().unwrap();
    let m = &hf.meta;
    let (mut ratio, mut sq, mut n) = (Vec::new(), 0.0, 0usize);
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for row in 0..m.height as usize {
        for col in 0..m.width as usize {
            let i = row * m.width as usize + col;
            if hf.valid[i] != 255 {
                continue;
            }
            let x = m.origin_m[0] + col as f64 * m.cell_m;
            let y = m.origin_m[1] - row as f64 * m.cell_m;
            let tc = ((x - t_origin[0]) / t_cell).round();
            let tr = ((t_origin[1] - y) / t_cell).round();
            if tc < 0.0 || tr < 0.0 || tc >= f64::from(truth.width) || tr >= f64::from(truth.height)
            {
                continue;
            }
            let t = f64::from(truth.samples[tr as usize * truth.width as usize + tc as usize])
                / 65535.0;
            let e = f64::from(tex.samples[i]) / scale;
            ratio.push(e / t.max(1e-3));
            pairs.push((t, e));
            sq += (e - t) * (e - t);
            n += 1;
        }
    }
    println!(
        "{entry} texture vs truth albedo over {n} measured cells: median ratio {:.3}, RMS difference {:.4}",
        median(ratio),
        (sq / n.max(1) as f64).sqrt()
    );
    // The truth is exact, so the least-squares line of texture on truth is unbiased.
    let k = pairs.len().max(1) as f64;
    let (mt, me) = (
        pairs.iter().map(|p| p.0).sum::<f64>() / k,
        pairs.iter().map(|p| p.1).sum::<f64>() / k,
    );
    let cov = pairs.iter().map(|p| (p.0 - mt) * (p.1 - me)).sum::<f64>();
    let var = pairs.iter().map(|p| (p.0 - mt).powi(2)).sum::<f64>();
    let slope = cov / var.max(1e-12);
    println!(
        "{entry} texture = {slope:.3} · truth {:+.4} (truth mean {mt:.4}, texture mean {me:.4})",
        me - slope * mt
    );
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}
