//! Regular ground grids: heights and albedo, with the one geometry convention every crate
//! uses (row 0 = north, cell centres on a regular lattice).
//!
//! A heightfield entry's raster, the corpus's truth and the validator's renderer all speak of
//! the terrain through these two types, so a grid written by one is read by another without a
//! conversion that could shift it by half a cell.

/// A regular height grid. Cell `(c, r)` has its centre at `x = origin_m[0] + c * cell_m`,
/// `y = origin_m[1] - r * cell_m`; row 0 is the north (max y) row. `NaN` marks a hole.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightGrid {
    /// Ground x, y of the centre of cell (0, 0), the north-west cell.
    pub origin_m: [f64; 2],
    /// Cell size in metres.
    pub cell_m: f64,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Heights in metres, row-major, `width * height` values.
    pub z: Vec<f32>,
}

/// An albedo raster with the same geometry convention as [`HeightGrid`] but its own origin,
/// cell size and dimensions (it may be finer than the height grid).
#[derive(Debug, Clone, PartialEq)]
pub struct AlbedoGrid {
    /// Ground x, y of the centre of cell (0, 0), the north-west cell.
    pub origin_m: [f64; 2],
    /// Cell size in metres.
    pub cell_m: f64,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Albedo in 0..1, row-major.
    pub value: Vec<f32>,
}
