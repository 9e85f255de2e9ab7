//! Typed data produced by the ingest readers; shared by every reader and by the stages.
//!
//! Coordinates stay `f64` here (RIEGL POP and LAS coordinates reach 10^6 m); stages subtract
//! a site origin before anything becomes `f32`.

/// A 4x4 rigid (or similarity) transform, row-major, column-vector convention:
/// `p' = M * [x y z 1]^T`, translation in the 4th column (RIEGL's convention).
pub type Matrix4 = [[f64; 4]; 4];

/// The identity matrix.
pub const IDENTITY4: Matrix4 = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// Applies a [`Matrix4`] to a point.
pub fn transform(m: &Matrix4, p: [f64; 3]) -> [f64; 3] {
    let r = |row: &[f64; 4]| row[0] * p[0] + row[1] * p[1] + row[2] * p[2] + row[3];
    [r(&m[0]), r(&m[1]), r(&m[2])]
}

/// A point cloud in the frame its file uses (scanner frame for RIEGL exports).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Point coordinates in metres.
    pub points: Vec<[f64; 3]>,
    /// RIEGL reflectance in dB (signed), one per point, when the file has it.
    pub reflectance_db: Option<Vec<f32>>,
    /// Raw intensity (unitless, as stored), when the file has it and no reflectance.
    pub intensity: Option<Vec<f32>>,
    /// Colour, when the file has it.
    pub rgb: Option<Vec<[u8; 3]>>,
    /// Pose of the scan in the file's own project frame (E57 data3D pose, PTX matrix), if any.
    pub pose: Option<Matrix4>,
}

/// A triangle mesh, e.g. an SfM reconstruction.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions (in the producer's frame, after applying file-level transforms).
    pub positions: Vec<[f64; 3]>,
    /// Triangles as vertex indices, counter-clockwise as the file gives them.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex colours, when present.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Per-vertex texture coordinates with the glTF convention (origin top-left, v down).
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Texture image path referenced by the file, relative to the file's folder.
    pub texture: Option<String>,
}

/// A named 3D point (tie point, reflector, marker), metres.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedPoint {
    /// Name as written in the file.
    pub name: String,
    /// Coordinates in metres.
    pub xyz: [f64; 3],
}

/// Marker trajectories from a motion-capture export, converted to metres.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trajectories {
    /// Frame rate in Hz (from the file, or supplied by the user).
    pub rate_hz: f64,
    /// Frame number of the first row.
    pub first_frame: i64,
    /// Markers in file order.
    pub markers: Vec<MarkerTrack>,
}

/// One marker's samples; `None` where the marker was not seen.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MarkerTrack {
    /// Name without the subject prefix (`boite:marker1` -> `marker1`).
    pub name: String,
    /// Subject name, when the file gives `Subject:Marker`.
    pub subject: Option<String>,
    /// Position per frame, metres.
    pub frames: Vec<Option<[f64; 3]>>,
}

/// Segment poses from a Vicon Nexus `Segments` section.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Segments {
    /// Frame rate in Hz.
    pub rate_hz: f64,
    /// Frame number of the first row.
    pub first_frame: i64,
    /// Segments in file order.
    pub segments: Vec<SegmentTrack>,
}

/// One segment's samples; `None` where any of its six cells is empty.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SegmentTrack {
    /// Name without the subject prefix (`Subject01:Head` -> `Head`).
    pub name: String,
    /// Subject name, when the file gives `Subject:Segment`.
    pub subject: Option<String>,
    /// Pose per frame.
    pub frames: Vec<Option<SegmentSample>>,
}

/// A segment pose as exported: `RX RY RZ` in degrees, `TX TY TZ` in metres.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SegmentSample {
    /// `RX, RY, RZ` in degrees. Nexus does not write which representation these are (helical
    /// or an Euler sequence: an export setting, formats.md §5.2), so they are kept as written.
    pub rotation_deg: [f64; 3],
    /// `TX, TY, TZ` in metres.
    pub translation_m: [f64; 3],
}

/// Named model outputs (Plug-in Gait angles, powers, ...) from a Vicon Nexus `Model Outputs`
/// section.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelOutputs {
    /// Frame rate in Hz.
    pub rate_hz: f64,
    /// Frame number of the first row.
    pub first_frame: i64,
    /// Outputs in file order.
    pub outputs: Vec<ModelOutput>,
}

/// One model output: a name over one or more columns (not always 3).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelOutput {
    /// Name without the subject prefix (`Subject01:LAnkleAngles` -> `LAnkleAngles`).
    pub name: String,
    /// Subject name, when the file gives `Subject:Output`.
    pub subject: Option<String>,
    /// The output's columns in file order.
    pub columns: Vec<ModelColumn>,
}

/// One column of a model output, values as written (no unit conversion: units such as `deg`,
/// `N/kg`, `W/kg` or `mm` are kept in [`ModelColumn::unit`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelColumn {
    /// Column role from the header row (`X`, `Y`, `Z`, `Count`, ...).
    pub label: String,
    /// Unit from the units row (may be empty).
    pub unit: String,
    /// Value per frame; `None` for an empty cell.
    pub values: Vec<Option<f64>>,
}
