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
