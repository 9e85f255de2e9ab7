//! The `truth/` folder: everything the generator knows and the campaign does not say.
//!
//! * `height.exr`: the true heights, one float32 channel `Z`, EXR row 0 = grid row 0 = north;
//!   `height.json` gives the [`HeightGrid`] geometry (origin = centre of the north-west cell,
//!   cell size, width, height; cell `(c, r)` at `x = ox + c·cell`, `y = oy − r·cell`).
//! * `albedo.png`: the true albedo, 16-bit grey, `value = round(albedo · 65535)`, same grid.
//! * `scans.json`: per scan the true SOCS → ground pose as a 4x4 (row-major, column-vector,
//!   RIEGL convention) and as a `Pose`, the station, the point count and the visible markers.
//! * `sfm.json`: the ground → SfM similarity (scale, R, t; `p_sfm = s·R·p_ground + t`).
//! * `gcp.json`: the ground control points of `sfm/mesh_gcp.csv`: per marker the true centre,
//!   the picking noise added (ground frame) and the true and written SfM positions.
//! * `cameras.json`: calibrated and true intrinsics (true = calibrated + hidden distortion),
//!   and the stereo `right_from_left`.
//! * `captures.json`: per capture the Vicon rig pose and each camera's true
//!   `ground_from_camera` (with the hidden pose bias) and frame files.
//! * `markers.json`, `hidden.json`, `lighting.json`.
//!
//! JSON is written with struct fields in a fixed order and maps sorted, so it is reproducible.

use std::collections::BTreeMap;

use regolith_format::camera_model::CameraModel;
use regolith_format::effects::Effect;
use regolith_format::frames::Pose;
use regolith_format::grid::HeightGrid;
use regolith_format::lighting::Light;
use serde::Serialize;

use crate::effects::Hidden;
use crate::instruments::navcam::{CapturePose, StereoHead};
use crate::instruments::riegl::Scan;
use crate::instruments::sfm::{GcpTruth, Similarity};
use crate::presets::ScannerSpec;
use crate::sink::Sink;
use crate::terrain::Terrain;
use crate::CorpusError;

/// Truth of one scan.
#[derive(Debug, Clone, Serialize)]
pub struct ScanTruth {
    /// Scan name.
    pub name: String,
    /// The RiSCAN ASCII file.
    pub file: String,
    /// Another format copy of the same points, if any.
    pub copy: Option<String>,
    /// SOCS → ground, 4x4 row-major, `p_ground = M · [p_socs 1]ᵀ`.
    pub ground_from_socs_matrix: [[f64; 4]; 4],
    /// The same as a pose.
    pub ground_from_socs: Pose,
    /// Vertical field, degrees from the zenith.
    pub theta_deg: [f64; 2],
    /// Horizontal field in SOCS, degrees.
    pub phi_deg: [f64; 2],
    /// Rays cast.
    pub rays: usize,
    /// Points written.
    pub points: usize,
    /// Markers in the tie-point list.
    pub tiepoints: Vec<String>,
    /// Range slope of the reflectance error the instrument was simulated with, dB per metre
    /// (`Reflectance[dB] = 10·log10(albedo · cos i) + slope · range + noise`).
    pub reflectance_range_slope_db_per_m: f64,
    /// Standard deviation of the reflectance noise, dB.
    pub reflectance_noise_db: f64,
}

impl ScanTruth {
    /// Collects the truth of a simulated scan.
    pub fn new(scan: &Scan, spec: &ScannerSpec, copy: Option<&str>) -> ScanTruth {
        let r = scan.ground_from_socs.rotation_matrix();
        let t = scan.ground_from_socs.translation_m;
        let row = |i: usize| [r[i][0], r[i][1], r[i][2], t[i]];
        ScanTruth {
            name: scan.name.clone(),
            file: format!("scans/{}.asc", scan.name),
            copy: copy.map(str::to_string),
            ground_from_socs_matrix: [row(0), row(1), row(2), [0.0, 0.0, 0.0, 1.0]],
            ground_from_socs: scan.ground_from_socs,
            theta_deg: spec.theta_deg,
            phi_deg: spec.phi_deg,
            rays: scan.rays,
            points: scan.points.len(),
            tiepoints: scan.tiepoints.iter().map(|(n, _)| n.clone()).collect(),
            reflectance_range_slope_db_per_m:
                crate::instruments::riegl::REFLECTANCE_RANGE_SLOPE_DB_PER_M,
            reflectance_noise_db: crate::instruments::riegl::REFLECTANCE_NOISE_DB,
        }
    }
}

/// Truth of one camera of a capture.
#[derive(Debug, Clone, Serialize)]
pub struct CameraShot {
    /// True `ground_from_camera`.
    pub ground_from_camera: Pose,
    /// Frame files (a, b).
    pub files: Vec<String>,
}

/// Truth of one capture.
#[derive(Debug, Clone, Serialize)]
pub struct CaptureTruth {
    /// Location name.
    pub name: String,
    /// Marker the camera looks at.
    pub target_marker: String,
    /// The rig (= calibrated left camera) pose the Vicon balls give.
    pub ground_from_rig: Pose,
    /// Left camera.
    pub left: CameraShot,
    /// Right camera.
    pub right: CameraShot,
}

impl CaptureTruth {
    /// Collects the truth of one capture: the true left and right `ground_from_camera`, and
    /// `files` = left a, left b, right a, right b.
    pub fn new(cap: &CapturePose, poses: [Pose; 2], files: Vec<String>) -> CaptureTruth {
        let (l, r) = files.split_at(2.min(files.len()));
        CaptureTruth {
            name: cap.name.clone(),
            target_marker: cap.target.clone(),
            ground_from_rig: cap.ground_from_rig,
            left: CameraShot {
                ground_from_camera: poses[0],
                files: l.to_vec(),
            },
            right: CameraShot {
                ground_from_camera: poses[1],
                files: r.to_vec(),
            },
        }
    }
}

/// Calibrated vs true intrinsics.
#[derive(Debug, Clone, Serialize)]
pub struct CameraTruth {
    /// What the calibration file says.
    pub calibrated: CameraModel,
    /// What the real images were made with.
    pub r#true: CameraModel,
}

/// `truth/cameras.json`.
#[derive(Debug, Clone, Serialize)]
pub struct CamerasTruth {
    /// Cameras by campaign name.
    pub cameras: BTreeMap<String, CameraTruth>,
    /// `X_right = R X_left + T` of the stereo head (exact, as in calib/stereo.yaml).
    pub right_from_left: Pose,
    /// Rig balls in the left-camera frame.
    pub rig_balls: BTreeMap<String, [f64; 3]>,
}

impl CamerasTruth {
    /// Collects the camera truth.
    pub fn new(head: &StereoHead, hidden: &Hidden, texture: &CameraModel) -> CamerasTruth {
        let pair = |c: &CameraModel, hidden_applies: bool| CameraTruth {
            calibrated: c.clone(),
            r#true: if hidden_applies {
                hidden.camera(c)
            } else {
                c.clone()
            },
        };
        let mut cameras = BTreeMap::new();
        cameras.insert("navcam_left".into(), pair(&head.left, true));
        cameras.insert("navcam_right".into(), pair(&head.right, true));
        cameras.insert("texture_camera".into(), pair(texture, false));
        let rig_balls = crate::instruments::navcam::RIG_BALLS
            .iter()
            .map(|(n, p)| (n.to_string(), *p))
            .collect();
        CamerasTruth {
            cameras,
            right_from_left: head.right_from_left,
            rig_balls,
        }
    }
}

/// `truth/hidden.json`.
#[derive(Debug, Clone, Serialize)]
pub struct HiddenTruth {
    /// The hidden effects (serde tag `effect`).
    pub effects: Vec<Effect>,
    /// The full model of the real images (hidden + baseline noise).
    pub real_image_model: Vec<Effect>,
    /// How each effect reaches the data.
    pub notes: BTreeMap<&'static str, &'static str>,
    /// An auto-exposing camera's gain factor per capture location, on top of the hidden
    /// exposure (absent when every capture has the same exposure).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub capture_exposure: BTreeMap<String, f64>,
}

impl HiddenTruth {
    /// Collects the hidden-effect truth.
    pub fn new(hidden: &Hidden, real: &[Effect]) -> HiddenTruth {
        let mut notes = BTreeMap::new();
        notes.insert("image effects", "vignetting, blur, exposure, noise, gamma: applied to every captures/*.png by the capture renderer of truth/renderer.json (baseline noise gain 0.05, read 0.8 DN unless noise is hidden)");
        if hidden.auto_exposure > 0.0 {
            notes.insert("capture_exposure", "an auto-exposing camera: each capture location's radiance (so its exposure gain) times its factor here, on top of the hidden exposure");
        }
        notes.insert("shadows", "captures rendered with cast shadows of the true light (truth/lighting.json); campaign.toml [lighting] records it 2-4 deg off in azimuth and 1-2 deg in elevation, as surveyed; the validator-model renderer draws cast shadows only then, a physical renderer always (the lamp is low then)");
        notes.insert(
            "distortion",
            "captures rendered with k1+dk1, k2+dk2; calib/*.yaml hold the calibrated k1, k2",
        );
        notes.insert("pose-bias", "left camera truly at ground_from_rig * bias (right follows rigidly); rig_markers.csv and stereo.yaml do not know it");
        notes.insert("texture-lowpass", "SfM vertex colours (on top of their own 1 cm blur) and laser reflectance are computed from the albedo blurred by sigma_m; captures use the true albedo");
        HiddenTruth {
            effects: hidden.effects.clone(),
            real_image_model: real.to_vec(),
            notes,
            capture_exposure: BTreeMap::new(),
        }
    }
}

#[derive(Serialize)]
struct HeightMeta<'a> {
    file: &'a str,
    channel: &'a str,
    convention: &'a str,
    origin_m: [f64; 2],
    cell_m: f64,
    width: usize,
    height: usize,
    z_min_m: f32,
    z_max_m: f32,
    albedo_file: &'a str,
}

#[derive(Serialize)]
struct LightingTruth {
    azimuth_deg: f64,
    elevation_deg: f64,
    ambient: f64,
    convention: &'static str,
}

#[derive(Serialize)]
struct ScansFile<'a> {
    range_noise_sigma_m: f64,
    tiepoint_noise_sigma_m: f64,
    scans: &'a [ScanTruth],
}

/// The ground-control-point file of the reconstruction (not referenced by `campaign.toml`,
/// whose `align` stays `"laser"`).
pub const GCP_FILE: &str = "sfm/mesh_gcp.csv";

/// `truth/gcp.json`.
#[derive(Serialize)]
struct GcpFileTruth<'a> {
    file: &'a str,
    convention: &'a str,
    picking_noise_sigma_m_per_axis: f64,
    points: &'a [GcpTruth],
}

/// Writes every truth file.
#[allow(clippy::too_many_arguments)]
pub fn write_all(
    sink: &mut Sink,
    terrain: &Terrain,
    light: &Light,
    scans: &[ScanTruth],
    similarity: &Similarity,
    gcps: &[GcpTruth],
    cameras: &CamerasTruth,
    captures: &[CaptureTruth],
    hidden: &HiddenTruth,
    range_noise_m: f64,
) -> Result<(), CorpusError> {
    let g = &terrain.height;
    write_exr(sink, "truth/height.exr", g)?;
    let (lo, hi) =
        g.z.iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    sink.write_json(
        "truth/height.json",
        &HeightMeta {
            file: "height.exr",
            channel: "Z",
            convention: "row 0 = north (max y); cell (c, r) centre at x = origin_m[0] + c*cell_m, y = origin_m[1] - r*cell_m; metres, ground frame (= Vicon frame), z up",
            origin_m: g.origin_m,
            cell_m: g.cell_m,
            width: g.width,
            height: g.height,
            z_min_m: lo,
            z_max_m: hi,
            albedo_file: "albedo.png",
        },
    )?;
    let a = &terrain.albedo;
    let samples: Vec<u16> = a
        .value
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 65535.0).round() as u16)
        .collect();
    let png = png16(&samples, a.width as u32, a.height as u32).map_err(CorpusError::encode(
        "PNG",
        std::path::Path::new("truth/albedo.png"),
    ))?;
    sink.write("truth/albedo.png", &png)?;
    sink.write_json(
        "truth/scans.json",
        &ScansFile {
            range_noise_sigma_m: range_noise_m,
            tiepoint_noise_sigma_m: 0.002,
            scans,
        },
    )?;
    sink.write_json("truth/sfm.json", similarity)?;
    sink.write_json(
        "truth/gcp.json",
        &GcpFileTruth {
            file: GCP_FILE,
            convention: "sfm = similarity(ground_m + noise_m) with the similarity of truth/sfm.json; the file holds sfm (6 decimals); ground_m = the true ball centre (what vicon/markers.csv measures)",
            picking_noise_sigma_m_per_axis: crate::instruments::sfm::GCP_PICKING_SIGMA_M,
            points: gcps,
        },
    )?;
    sink.write_json("truth/cameras.json", cameras)?;
    sink.write_json("truth/captures.json", &captures)?;
    sink.write_json("truth/markers.json", &terrain.markers)?;
    sink.write_json("truth/hidden.json", hidden)?;
    sink.write_json(
        "truth/lighting.json",
        &LightingTruth {
            azimuth_deg: light.azimuth_deg,
            elevation_deg: light.elevation_deg,
            ambient: light.ambient,
            convention: "azimuth from +x toward +y, elevation above the horizontal, as campaign.toml [lighting]; the true light (the campaign records it as surveyed)",
        },
    )
}

fn write_exr(sink: &mut Sink, rel: &str, g: &HeightGrid) -> Result<(), CorpusError> {
    use exr::prelude::*;
    let path = sink.path(rel)?;
    let w = g.width;
    let channels = SpecificChannels::build()
        .with_channel("Z")
        .with_pixel_fn(|p: Vec2<usize>| (g.z.get(p.y() * w + p.x()).copied().unwrap_or(f32::NAN),));
    Image::from_channels((g.width, g.height), channels)
        .write()
        .non_parallel()
        .to_file(&path)
        .map_err(CorpusError::encode("EXR", &path))
}

/// 16-bit grey PNG (samples stored big-endian, as the format requires).
pub fn png16(samples: &[u16], width: u32, height: u32) -> Result<Vec<u8>, png::EncodingError> {
    let bytes: Vec<u8> = samples.iter().flat_map(|v| v.to_be_bytes()).collect();
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        enc.set_compression(png::Compression::Fast);
        let mut w = enc.write_header()?;
        w.write_image_data(&bytes)?;
    }
    Ok(out)
}
