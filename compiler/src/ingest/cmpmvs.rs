//! CMPMVS digital elevation models: `DEM.png` (16-bit grey) + `DEM.txt` (its box), plus the
//! optional orthophoto beside them (formats.md §10), into a [`HeightGrid`].
//!
//! No real sample and no documentation exist: the layout below is **inferred** from the printf
//! strings in CMPMVS.exe (`0: %f %f %f`, `X: …`, `Y: …`, `Z: …`, `W: %i H: %i`), so the reader is
//! tolerant in what it parses and strict in what it assumes, and names each assumption in its
//! errors. Assumptions (all `[U]` in formats.md):
//!
//! 1. `0:` is the origin corner of the DEM box; `X:`, `Y:`, `Z:` are its edge vectors. `X`
//!    spans the image width, `Y` its height, `Z` the 16-bit value range (0 → origin height,
//!    65535 → origin + Z). The box must be axis-aligned (X along +x, Y along +y, Z along +z);
//!    anything else is reported as unsupported rather than guessed.
//! 2. The PNG is north-up: row 0 is the cell row at the largest y (`origin.y + |Y|`), column 0
//!    at `origin.x`, like a GeoTIFF.
//! 3. The value 0 means "no surface" (nodata); CMPMVS fills unobserved cells with 0.
//! 4. `W`/`H` must equal the PNG size: a mismatch means the pair does not belong together.
//!
//! Tolerance: keys may come in any order, on one line or several, with CRLF line ends, and
//! `W: … H: …` may share a line. Without `DEM.txt` a `DEM.png` has no scale, so both are
//! required. The orthophoto (`DEM_ortoPhoto.tiff`, CMPMVS's spelling, or common variants) is
//! only located, not decoded.

use std::path::{Path, PathBuf};

use image::ColorType;
use regolith_format::limits::Limits;

use crate::error::{IngestError, Result};
use crate::ingest::images::{decode_dynamic, read_file};

/// Orthophoto file names looked for next to `DEM.png`, in order.
pub const ORTHOPHOTO_NAMES: &[&str] = &[
    "DEM_ortoPhoto.tiff",
    "DEM_ortoPhoto.tif",
    "DEM_ortoPhoto.png",
    "DEM_orthoPhoto.tiff",
    "DEM_orthoPhoto.tif",
    "DEM_orthoPhoto.png",
];

/// The DEM box of `DEM.txt`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DemBox {
    /// `0:` origin corner.
    pub origin: [f64; 3],
    /// `X:` edge vector spanning the image width.
    pub x: [f64; 3],
    /// `Y:` edge vector spanning the image height.
    pub y: [f64; 3],
    /// `Z:` edge vector spanning the 16-bit value range.
    pub z: [f64; 3],
    /// `W:` image width in pixels.
    pub width: u32,
    /// `H:` image height in pixels.
    pub height: u32,
}

/// A regular height grid in the SfM frame, row 0 at the top (largest y).
#[derive(Debug, Clone, PartialEq)]
pub struct HeightGrid {
    /// x, y of the outer corner of cell (0, 0): the smallest x and the largest y.
    pub origin: [f64; 2],
    /// Cell size along x and y (both positive).
    pub cell_size: [f64; 2],
    /// Cells per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Heights (z), row-major; `None` where the DEM has no surface.
    pub heights: Vec<Option<f64>>,
}

impl HeightGrid {
    /// The height of cell `(col, row)`; `None` outside the grid or for nodata.
    pub fn get(&self, col: u32, row: u32) -> Option<f64> {
        if col >= self.width || row >= self.height {
            return None;
        }
        self.heights
            .get(row as usize * self.width as usize + col as usize)
            .copied()
            .flatten()
    }

    /// x, y of the centre of cell `(col, row)`.
    pub fn cell_centre(&self, col: u32, row: u32) -> [f64; 2] {
        [
            self.origin[0] + (f64::from(col) + 0.5) * self.cell_size[0],
            self.origin[1] - (f64::from(row) + 0.5) * self.cell_size[1],
        ]
    }
}

/// A CMPMVS DEM with its box and the orthophoto found beside it.
#[derive(Debug, Clone, PartialEq)]
pub struct CmpmvsDem {
    /// The heights.
    pub grid: HeightGrid,
    /// The box as written in `DEM.txt`.
    pub dem_box: DemBox,
    /// The orthophoto next to `DEM.png`, if present.
    pub orthophoto: Option<PathBuf>,
}

/// Reads `DEM.png` and the `DEM.txt` in the same folder; errors name the file.
pub fn read_path(dem_png: &Path, limits: &Limits) -> Result<CmpmvsDem> {
    let dir = dem_png.parent().unwrap_or(Path::new(""));
    let txt_path = dir.join("DEM.txt");
    let txt = read_file(&txt_path, limits).map_err(|e| {
        let msg = format!(
            "DEM.txt is required next to {} (a DEM.png has no scale): {e}",
            dem_png.display()
        );
        IngestError::invalid(msg)
    })?;
    let dem_box = parse_dem_txt(&txt).map_err(|e| e.in_file(&txt_path))?;
    let png = read_file(dem_png, limits)?;
    let grid = height_grid(&dem_box, &png, limits).map_err(|e| e.in_file(dem_png))?;
    let orthophoto = ORTHOPHOTO_NAMES
        .iter()
        .map(|n| dir.join(n))
        .find(|p| p.is_file());
    Ok(CmpmvsDem {
        grid,
        dem_box,
        orthophoto,
    })
}

/// Parses `DEM.txt`: `0:`, `X:`, `Y:`, `Z:` (three numbers each), `W:` and `H:` (integers).
pub fn parse_dem_txt(bytes: &[u8]) -> Result<DemBox> {
    let text = String::from_utf8_lossy(bytes);
    let mut vecs: [Option<[f64; 3]>; 4] = [None; 4];
    let (mut w, mut h) = (None, None);
    for (i, line) in text.lines().enumerate() {
        let at = |e: IngestError| e.at_line(i as u64 + 1);
        let mut tokens = line.split_ascii_whitespace().peekable();
        while let Some(key) = tokens.next() {
            let mut vals = Vec::new();
            while let Some(t) = tokens.next_if(|t| !t.ends_with(':')) {
                let v = t.parse::<f64>().ok().filter(|v| v.is_finite());
                vals.push(
                    v.ok_or_else(|| at(IngestError::syntax(format!("a number after {key}"), t)))?,
                );
            }
            let slot = match key {
                "0:" => Some(0),
                "X:" => Some(1),
                "Y:" => Some(2),
                "Z:" => Some(3),
                _ => None,
            };
            match (key, slot, vals.as_slice()) {
                (_, Some(s), &[a, b, c]) => {
                    if let Some(v) = vecs.get_mut(s) {
                        *v = Some([a, b, c]);
                    }
                }
                ("W:", _, &[v]) => w = Some(size(v, "W").map_err(at)?),
                ("H:", _, &[v]) => h = Some(size(v, "H").map_err(at)?),
                _ => {
                    let msg = "`0:`/`X:`/`Y:`/`Z:` with 3 numbers or `W:`/`H:` with one integer";
                    return Err(at(IngestError::syntax(msg, line)));
                }
            }
        }
    }
    let missing = |what: &str| IngestError::invalid(format!("DEM.txt has no `{what}` line"));
    let [o, x, y, z] = vecs;
    let dem = DemBox {
        origin: o.ok_or_else(|| missing("0:"))?,
        x: x.ok_or_else(|| missing("X:"))?,
        y: y.ok_or_else(|| missing("Y:"))?,
        z: z.ok_or_else(|| missing("Z:"))?,
        width: w.ok_or_else(|| missing("W:"))?,
        height: h.ok_or_else(|| missing("H:"))?,
    };
    for (name, v, axis) in [("X", dem.x, 0), ("Y", dem.y, 1), ("Z", dem.z, 2)] {
        let norm = v.iter().map(|c| c * c).sum::<f64>().sqrt();
        let along = v.get(axis).copied().unwrap_or_default();
        if !(along > 0.0 && (norm - along) <= 1e-9 * norm) {
            return Err(IngestError::Unsupported(format!(
                "DEM box edge {name} = {v:?} is not along +{}: regolith assumes an axis-aligned \
                 DEM box (CMPMVS DEM.txt semantics are inferred, formats.md §10)",
                ["x", "y", "z"].get(axis).unwrap_or(&"?")
            )));
        }
    }
    Ok(dem)
}

/// Decodes the DEM image and maps it through the box to heights.
pub fn height_grid(dem: &DemBox, png: &[u8], limits: &Limits) -> Result<HeightGrid> {
    let img = decode_dynamic(png, limits)?;
    if !matches!(img.color(), ColorType::L8 | ColorType::L16) {
        let msg = format!("DEM image is {:?}: expected 16-bit grey", img.color());
        return Err(IngestError::invalid(msg));
    }
    if (img.width(), img.height()) != (dem.width, dem.height) {
        return Err(IngestError::invalid(format!(
            "DEM image is {}x{} but DEM.txt says W: {} H: {} (they must belong together)",
            img.width(),
            img.height(),
            dem.width,
            dem.height
        )));
    }
    let scale_z = dem.z[2] / 65535.0;
    let heights = img
        .into_luma16()
        .into_raw()
        .into_iter()
        .map(|v| (v != 0).then(|| dem.origin[2] + f64::from(v) * scale_z))
        .collect();
    Ok(HeightGrid {
        origin: [dem.origin[0], dem.origin[1] + dem.y[1]],
        cell_size: [
            dem.x[0] / f64::from(dem.width),
            dem.y[1] / f64::from(dem.height),
        ],
        width: dem.width,
        height: dem.height,
        heights,
    })
}

fn size(v: f64, what: &str) -> Result<u32> {
    if v.fract() == 0.0 && v >= 1.0 && v <= f64::from(u32::MAX) {
        return Ok(v as u32);
    }
    Err(IngestError::invalid(format!(
        "{what}: {v} is not a positive integer"
    )))
}
