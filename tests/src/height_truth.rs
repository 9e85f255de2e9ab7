//! An entry's heights against the true surface of a synthetic corpus campaign
//! (`truth/height.exr` on the `truth/height.json` grid): the one comparison behind the DEM
//! accuracy tests and the `dem_truth` example.

use std::path::Path;

use regolith_compiler::encode::exr::read_grey_f32;
use regolith_reader::{ReaderError, ReleaseView};

fn bad(what: &str, e: impl std::fmt::Display) -> ReaderError {
    ReaderError::Decode {
        entry: "truth".into(),
        what: "corpus truth",
        message: format!("{what}: {e}"),
    }
}

/// The true surface, bilinear between its grid's cell centres.
pub struct HeightTruth {
    origin: [f64; 2],
    cell: f64,
    w: usize,
    h: usize,
    z: Vec<f32>,
    /// Horizontal centres of the survey marker balls (`truth/markers.json`), metres.
    pub balls: Vec<[f64; 2]>,
}

impl HeightTruth {
    /// Reads the truth of the campaign at `campaign`.
    pub fn load(campaign: &Path) -> Result<HeightTruth, ReaderError> {
        let read = |name: &str| std::fs::read(campaign.join(name)).map_err(|e| bad(name, e));
        let meta: serde_json::Value = serde_json::from_slice(&read("truth/height.json")?)
            .map_err(|e| bad("height.json", e))?;
        let (w, h, z) =
            read_grey_f32(&read("truth/height.exr")?).map_err(|e| bad("height.exr", e))?;
        let num =
            |v: &serde_json::Value| v.as_f64().ok_or_else(|| bad("height.json", "not a number"));
        let markers: serde_json::Value = serde_json::from_slice(&read("truth/markers.json")?)
            .map_err(|e| bad("markers.json", e))?;
        let balls = markers
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|b| Some([b["centre_m"][0].as_f64()?, b["centre_m"][1].as_f64()?]))
            .collect();
        Ok(HeightTruth {
            origin: [num(&meta["origin_m"][0])?, num(&meta["origin_m"][1])?],
            cell: num(&meta["cell_m"])?,
            w,
            h,
            z,
            balls,
        })
    }

    /// The true height at ground `(x, y)`, `None` outside the truth grid.
    pub fn at(&self, x: f64, y: f64) -> Option<f64> {
        let fc = (x - self.origin[0]) / self.cell;
        let fr = (self.origin[1] - y) / self.cell;
        if fc < 0.0 || fr < 0.0 || fc >= (self.w - 1) as f64 || fr >= (self.h - 1) as f64 {
            return None;
        }
        let (c, r) = (fc.floor() as usize, fr.floor() as usize);
        let (tx, ty) = (fc - c as f64, fr - r as f64);
        let z =
            |c: usize, r: usize| f64::from(self.z.get(r * self.w + c).copied().unwrap_or(f32::NAN));
        Some(
            (z(c, r) * (1.0 - tx) + z(c + 1, r) * tx) * (1.0 - ty)
                + (z(c, r + 1) * (1.0 - tx) + z(c + 1, r + 1) * tx) * ty,
        )
    }

    /// Within `radius` metres (horizontally) of a marker ball: the balls' near-vertical
    /// faces are where a DEM's worst single cells are by construction.
    pub fn near_ball(&self, x: f64, y: f64, radius: f64) -> bool {
        self.balls
            .iter()
            .any(|b| (b[0] - x).hypot(b[1] - y) < radius)
    }
}

/// Heights vs truth over an entry's valid cells.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightStats {
    /// Cells compared.
    pub cells: usize,
    /// RMS of height − truth, metres.
    pub rms: f64,
    /// Largest |height − truth| farther than 3 cm from a marker ball, metres.
    pub max_abs: f64,
}

/// Compares heightfield `entry` of `view` with `truth`.
pub fn heights_vs_truth(
    view: &ReleaseView,
    entry: &str,
    truth: &HeightTruth,
) -> Result<HeightStats, ReaderError> {
    let hf = view.heightfield(entry)?;
    let (mut sum, mut cells, mut max_abs) = (0.0, 0usize, 0.0f64);
    for r in 0..hf.meta.height {
        for c in 0..hf.meta.width {
            let i = (r * hf.meta.width + c) as usize;
            if hf.valid.get(i).is_none_or(|v| *v == 0) {
                continue;
            }
            let [x, y] = hf.meta.cell_centre(c, r);
            let (Some(zt), Some(z)) = (truth.at(x, y), hf.heights.get(i)) else {
                continue;
            };
            let d = f64::from(*z) - zt;
            sum += d * d;
            cells += 1;
            if !truth.near_ball(x, y, 0.03) {
                max_abs = max_abs.max(d.abs());
            }
        }
    }
    Ok(HeightStats {
        cells,
        rms: (sum / cells.max(1) as f64).sqrt(),
        max_abs,
    })
}
