//! An entry's texture against the true albedo of a synthetic corpus campaign
//! (`truth/albedo.png` on the `truth/height.json` grid): the one comparison behind the texture
//! accuracy tests and the `albedo_ratio` example.

use std::path::Path;

use regolith_reader::heightfield::decode_grey_png;
use regolith_reader::{ReaderError, ReleaseView};

/// Texture vs truth over the entry's measured cells (nearest truth cell to each cell centre).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureTruth {
    /// Cells compared.
    pub cells: usize,
    /// RMS of texture − truth.
    pub rms: f64,
    /// Median of texture ÷ truth.
    pub median_ratio: f64,
    /// Least-squares line texture = slope · truth + intercept (unbiased: the truth is exact).
    pub slope: f64,
    /// Its intercept.
    pub intercept: f64,
    /// Mean true albedo and mean texture over the cells.
    pub means: [f64; 2],
}

fn bad(what: &str, e: impl std::fmt::Display) -> ReaderError {
    ReaderError::Decode {
        entry: "truth".into(),
        what: "corpus truth",
        message: format!("{what}: {e}"),
    }
}

/// Compares `entry`'s texture (`<entry>/texture`) with the truth of the campaign at `campaign`.
pub fn texture_vs_truth(
    view: &ReleaseView,
    entry: &str,
    campaign: &Path,
) -> Result<TextureTruth, ReaderError> {
    let hf = view.heightfield(entry)?;
    let tex_name = format!("{entry}/texture");
    let tex = decode_grey_png(&view.read_file(&tex_name, "image")?, 32_768)
        .map_err(|e| bad(&tex_name, e))?;
    let scale = if tex.bit_depth == 16 { 65535.0 } else { 255.0 };
    let read = |name: &str| std::fs::read(campaign.join(name)).map_err(|e| bad(name, e));
    let meta: serde_json::Value =
        serde_json::from_slice(&read("truth/height.json")?).map_err(|e| bad("height.json", e))?;
    let truth =
        decode_grey_png(&read("truth/albedo.png")?, 32_768).map_err(|e| bad("albedo.png", e))?;
    let num = |v: &serde_json::Value| v.as_f64().ok_or_else(|| bad("height.json", "not a number"));
    let origin = [num(&meta["origin_m"][0])?, num(&meta["origin_m"][1])?];
    let cell = num(&meta["cell_m"])?;
    let m = &hf.meta;
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for row in 0..m.height as usize {
        for col in 0..m.width as usize {
            let i = row * m.width as usize + col;
            if hf.valid.get(i) != Some(&255) {
                continue;
            }
            let x = m.origin_m[0] + col as f64 * m.cell_m;
            let y = m.origin_m[1] - row as f64 * m.cell_m;
            let (tc, tr) = (
                ((x - origin[0]) / cell).round(),
                ((origin[1] - y) / cell).round(),
            );
            if tc < 0.0 || tr < 0.0 || tc >= f64::from(truth.width) || tr >= f64::from(truth.height)
            {
                continue;
            }
            let (Some(t), Some(e)) = (
                truth
                    .samples
                    .get(tr as usize * truth.width as usize + tc as usize),
                tex.samples.get(i),
            ) else {
                continue;
            };
            pairs.push((f64::from(*t) / 65535.0, f64::from(*e) / scale));
        }
    }
    let k = pairs.len().max(1) as f64;
    let (mt, me) = (
        pairs.iter().map(|p| p.0).sum::<f64>() / k,
        pairs.iter().map(|p| p.1).sum::<f64>() / k,
    );
    let cov = pairs.iter().map(|p| (p.0 - mt) * (p.1 - me)).sum::<f64>();
    let var = pairs.iter().map(|p| (p.0 - mt).powi(2)).sum::<f64>();
    let slope = cov / var.max(1e-12);
    let mut ratios: Vec<f64> = pairs.iter().map(|(t, e)| e / t.max(1e-3)).collect();
    let median_ratio = if ratios.is_empty() {
        f64::NAN
    } else {
        let mid = ratios.len() / 2;
        *ratios.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    Ok(TextureTruth {
        cells: pairs.len(),
        rms: (pairs.iter().map(|(t, e)| (e - t).powi(2)).sum::<f64>() / k).sqrt(),
        median_ratio,
        slope,
        intercept: me - slope * mt,
        means: [mt, me],
    })
}
