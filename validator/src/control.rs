//! Negative controls: a deliberately degraded copy of a terrain entry in a child release, so a
//! user can check on their own campaign that `validate` fails what it should, and calibrate
//! thresholds between good entries and degraded ones (`tools/calibrate/validate_thresholds.py`).
//!
//! The degradation is a Gaussian blur of the entry's texture, σ given in metres on the ground:
//! the geometry stays exactly the same, so the control isolates the texture's fine detail — what
//! a lower-resolution orthophoto or an over-smoothed albedo loses (a coarse raster, the other
//! classic control, is made by compiling with a larger `raster_m`). The copy is a heightfield
//! entry `<entry>-blur<σ in mm>mm` sharing the original's height objects (no bytes duplicated)
//! plus its blurred texture `<entry>-blur<σ>mm/texture` (8-bit, SPEC §5.2). The child release is
//! `<version>+control.<n>` with the examined release as its parent and a `control.texture-blur`
//! plan step recording what was done; `latest` does not move.

use regolith_format::kinds::{self, media, roles, TextureMeta};
use regolith_format::manifest::{Entry, PlanStep, Tile};
use regolith_format::ObjectId;
use regolith_reader::{ReaderError, ReleaseView, Writer};
use serde_json::json;

use crate::child::commit_child;
use crate::report::plot::encode_png;
use crate::sensor::gaussian_blur;
use crate::validate::grey;

/// Version of the `control.texture-blur` plan step.
pub const TEXTURE_BLUR_VERSION: u32 = 1;

/// What [`blurred_texture`] wrote.
#[derive(Debug, Clone)]
pub struct Control {
    /// The degraded entry's name.
    pub entry: String,
    /// The child release's label.
    pub release: String,
    /// Its id.
    pub id: ObjectId,
    /// The blur in texture pixels.
    pub sigma_px: f64,
}

fn bad(entry: &str, message: String) -> ReaderError {
    ReaderError::Decode {
        entry: entry.to_string(),
        what: "negative control",
        message,
    }
}

/// The name of the control entry of `entry` blurred by `sigma_m`.
pub fn control_name(entry: &str, sigma_m: f64) -> String {
    format!("{entry}-blur{}mm", (sigma_m * 1000.0).round() as i64)
}

/// Writes the child release holding `entry` with its texture blurred by `sigma_m` (metres).
pub fn blurred_texture(
    writer: &Writer,
    view: &ReleaseView,
    entry: &str,
    sigma_m: f64,
) -> Result<Control, ReaderError> {
    if !(sigma_m.is_finite() && sigma_m > 0.0 && sigma_m <= 1.0) {
        return Err(bad(
            entry,
            format!("texture blur σ must be in (0, 1] m, got {sigma_m}"),
        ));
    }
    let hf = view.entry_of_kind(entry, kinds::HEIGHTFIELD)?.clone();
    let hf_meta: kinds::HeightfieldMeta = serde_json::from_value(hf.meta.clone())
        .map_err(|e| bad(entry, format!("heightfield meta: {e}")))?;
    let tex_name = format!("{entry}/texture");
    let tex = view
        .entry_of_kind(&tex_name, kinds::TEXTURE)
        .map_err(|_| bad(entry, "the entry has no texture to blur".into()))?
        .clone();
    let mut meta: TextureMeta = serde_json::from_value(tex.meta.clone())
        .map_err(|e| bad(&tex_name, format!("texture meta: {e}")))?;
    let g = grey(&view.read_file(&tex_name, roles::IMAGE)?, &tex_name)?;
    let sigma_px = sigma_m * f64::from(meta.pixels_per_cell.max(1)) / hf_meta.cell_m;
    let blurred = gaussian_blur(&g.data, g.width, g.height, sigma_px);
    let bytes: Vec<u8> = blurred
        .iter()
        .map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8)
        .collect();
    let png = encode_png(
        g.width as u32,
        g.height as u32,
        ::png::ColorType::Grayscale,
        &bytes,
    )
    .map_err(|e| bad(&tex_name, format!("encoding the blurred texture: {e}")))?;
    let file = writer.put(&png, media::PNG)?;
    let object = file.object;

    let name = control_name(entry, sigma_m);
    let mut m = view.manifest.clone();
    let texture_name = format!("{name}/texture");
    m.entries
        .retain(|e| e.name != name && e.name != texture_name);
    meta.grid_of.clone_from(&name);
    meta.bit_depth = 8;
    m.entries.push(Entry {
        name: name.clone(),
        ..hf
    });
    // One level-0 tile covering the grid, with the original's bounds (SPEC §3: textures are
    // tiled; the control does not need more than the root tile).
    let root = tex
        .root_tile()
        .ok_or_else(|| bad(&tex_name, "the texture has no level-0 tile".into()))?;
    m.entries.push(Entry {
        name: texture_name.clone(),
        kind: kinds::TEXTURE.to_string(),
        meta: json!(meta),
        files: Default::default(),
        tiles: vec![Tile {
            files: [(roles::IMAGE.to_string(), file)].into_iter().collect(),
            ..root.clone()
        }],
    });
    m.entries.sort_by(|a, b| a.name.cmp(&b.name));
    m.plan.push(PlanStep {
        stage: "control.texture-blur".into(),
        version: TEXTURE_BLUR_VERSION,
        params: json!({"entry": entry, "control": name, "sigma_m": sigma_m, "sigma_px": sigma_px}),
    });
    let (label, id) = commit_child(writer, view, m, "control", false, |e| {
        e.name == texture_name && e.file(roles::IMAGE).map(|f| f.object) == Some(object)
    })?;
    Ok(Control {
        entry: name,
        release: label,
        id,
        sigma_px,
    })
}
