//! The two campaign presets: `estec` (the ESTEC ARL Mars-yard of the thesis) and `mini`.
//!
//! Everything that is a *fact of the lab* lives here, as data, with its thesis source: the
//! 8.69 m x 8.605 m extent and height range (§5.2.2), the 12 marker positions (Table 5.2), the
//! six scanner fields of view (Table 5.1), the NavCam intrinsics (Table 5.7) and the texture
//! camera (Table 5.4 and the distortion quoted below it). What the thesis does not give (the
//! scanner stations, the hills' layout, the capture locations) is chosen here or drawn from
//! the seed by the stages, within the ranges the issue states. `mini` is the same machinery at
//! test scale: a 2 m x 2 m patch, 5 markers, 2 scans, 2 captures, half-resolution images.

/// Which campaign to generate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// The full ESTEC ARL testbed.
    Estec,
    /// A 2 m x 2 m test-scale campaign.
    Mini,
}

impl Preset {
    /// Parses `estec` or `mini`.
    pub fn parse(s: &str) -> Option<Preset> {
        match s {
            "estec" => Some(Preset::Estec),
            "mini" => Some(Preset::Mini),
            _ => None,
        }
    }

    /// The preset's name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Estec => "estec",
            Preset::Mini => "mini",
        }
    }
}

/// A marker to place: name, ground x/y and, when the survey fixes it, the ball-centre z.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerSpec {
    /// Name (`Marker1`...), shared by the Vicon CSV and the tie-point lists.
    pub name: &'static str,
    /// Ground x, y of the ball centre, metres.
    pub xy: [f64; 2],
    /// Ball-centre height if fixed by the survey; `None` = on the synthetic surface.
    pub z: Option<f64>,
}

/// One laser-scanner station.
#[derive(Debug, Clone, PartialEq)]
pub struct ScannerSpec {
    /// Scan name (`pos1`...).
    pub name: &'static str,
    /// Scanner origin in the ground frame, metres.
    pub position: [f64; 3],
    /// Vertical angle range from the zenith, degrees (Table 5.1: 90–129.96).
    pub theta_deg: [f64; 2],
    /// Horizontal angle range in the scanner's own frame, degrees (Table 5.1).
    pub phi_deg: [f64; 2],
}

/// Terrain relief parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Relief {
    /// Lowest height (crater floor), metres.
    pub floor_m: f64,
    /// Highest height (hill top), metres.
    pub top_m: f64,
    /// Main hill: centre x, y and radius (Gaussian sigma), metres.
    pub main_hill: [f64; 3],
    /// Number of secondary hills.
    pub hills: usize,
    /// Crater: centre x, y and rim radius, metres.
    pub crater: [f64; 3],
    /// Number of gypsum boulders (5–40 cm).
    pub boulders: usize,
    /// Number of pebbles (1–4 cm).
    pub pebbles: usize,
}

/// Intrinsics as surveyed (thesis tables): size, focal lengths, principal point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Width, height in pixels.
    pub size: [u32; 2],
    /// fx, fy in pixels.
    pub f: [f64; 2],
    /// cx, cy in pixels.
    pub c: [f64; 2],
}

/// Everything a preset fixes.
#[derive(Debug, Clone, PartialEq)]
pub struct PresetConfig {
    /// Campaign name written to campaign.toml.
    pub campaign_name: &'static str,
    /// Terrain extent along x and y, metres (origin at the testbed corner).
    pub extent_m: [f64; 2],
    /// True height-grid cell, metres (default run).
    pub cell_m: f64,
    /// True height-grid cell with `--full`.
    pub cell_full_m: f64,
    /// Relief.
    pub relief: Relief,
    /// Markers.
    pub markers: Vec<MarkerSpec>,
    /// Scanner stations.
    pub scanners: Vec<ScannerSpec>,
    /// Angular scan step, degrees (default run).
    pub scan_step_deg: f64,
    /// Angular scan step with `--full` (the real 0.030°).
    pub scan_step_full_deg: f64,
    /// Number of rover capture locations.
    pub captures: usize,
    /// NavCam left and right intrinsics (before `image_scale`).
    pub navcam: [Intrinsics; 2],
    /// Image scale applied to the NavCam intrinsics (1 = 1280 x 1024).
    pub image_scale: f64,
    /// Texture camera (Bouguet file).
    pub texture_camera: Intrinsics,
    /// Texture-camera distortion k1, k2, p1, p2, k3 (thesis §5.4.1).
    pub texture_kc: [f64; 5],
    /// SfM vertex spacing, metres.
    pub sfm_cell_m: f64,
    /// Frames in the static-marker Vicon CSV.
    pub vicon_frames: usize,
    /// Frames in each rig-pose Vicon CSV.
    pub rig_frames: usize,
    /// Laser range noise sigma, metres.
    pub range_noise_m: f64,
    /// Render supersampling for captures.
    pub supersample: u32,
}

/// Ball radius of the Vicon/RIEGL markers, metres (ball centre 13 mm above the surface).
pub const MARKER_RADIUS_M: f64 = 0.013;

/// Thesis Table 5.2: marker positions on the testbed (metres, ground = Vicon frame).
const ESTEC_MARKERS: [(&str, [f64; 3]); 12] = [
    ("Marker1", [0.490766, 1.931042, 0.277539]),
    ("Marker2", [2.505144, 0.736717, 0.035237]),
    ("Marker3", [4.321479, 1.712909, 0.308652]),
    ("Marker4", [2.673920, 3.609800, 0.485498]),
    ("Marker5", [1.198011, 4.878947, 0.061847]),
    ("Marker6", [4.670933, 4.559106, 0.141789]),
    ("Marker7", [6.313473, 0.743458, 0.151778]),
    ("Marker8", [6.805769, 4.432093, 0.175847]),
    ("Marker9", [7.797544, 1.090224, 0.397679]),
    ("Marker10", [7.371297, 6.884144, 0.608227]),
    ("Marker11", [3.432952, 8.108245, 0.083629]),
    ("Marker12", [1.414247, 8.040763, 0.029089]),
];

/// Thesis Table 5.7 (left, right): focal lengths and principal points at 1280 x 1024.
const NAVCAM: [Intrinsics; 2] = [
    Intrinsics {
        size: [1280, 1024],
        f: [832.159, 832.693],
        c: [672.502, 510.394],
    },
    Intrinsics {
        size: [1280, 1024],
        f: [831.471, 832.024],
        c: [642.985, 506.628],
    },
];

/// Thesis Table 5.4: Sony DSC-H7 on 1024 x 768 images.
const TEXTURE_CAMERA: Intrinsics = Intrinsics {
    size: [1024, 768],
    f: [970.31, 973.12],
    c: [509.42, 393.54],
};

/// Thesis §5.4.1: c1..c5 of the texture camera (Bouguet kc order k1 k2 p1 p2 k3).
const TEXTURE_KC: [f64; 5] = [-0.18429, 0.17718, 0.00079, -0.00056, 0.0];

fn scanner(name: &'static str, position: [f64; 3], phi_deg: [f64; 2]) -> ScannerSpec {
    ScannerSpec {
        name,
        position,
        theta_deg: [90.0, 129.96],
        phi_deg,
    }
}

impl PresetConfig {
    /// The configuration of a preset.
    pub fn of(preset: Preset) -> PresetConfig {
        match preset {
            Preset::Estec => Self::estec(),
            Preset::Mini => Self::mini(),
        }
    }

    fn estec() -> PresetConfig {
        PresetConfig {
            campaign_name: "estec-arl-synthetic",
            extent_m: [8.69, 8.605],
            cell_m: 0.005,
            cell_full_m: 0.0025,
            relief: Relief {
                floor_m: -0.025,
                top_m: 0.764,
                main_hill: [1.3, 7.2, 1.3],
                hills: 7,
                crater: [5.6, 2.9, 0.75],
                boulders: 160,
                pebbles: 4000,
            },
            markers: ESTEC_MARKERS
                .iter()
                .map(|&(name, p)| MarkerSpec {
                    name,
                    xy: [p[0], p[1]],
                    z: Some(p[2]),
                })
                .collect(),
            // Stations around the bed (Figure 5.1 shows them at the edges), tripod heads
            // 1.9–2.3 m above the floor; horizontal fields of Table 5.1.
            scanners: vec![
                scanner("pos1", [4.3, -0.6, 2.0], [103.0, 230.32]),
                scanner("pos2", [9.3, -0.5, 2.1], [125.0, 237.77]),
                scanner("pos3", [9.4, 9.2, 2.2], [145.0, 220.84]),
                scanner("pos4", [4.4, 9.3, 2.0], [110.0, 240.20]),
                scanner("pos5", [-0.6, 9.2, 2.3], [155.0, 241.19]),
                scanner("pos6", [-0.7, 4.3, 1.9], [180.0, 330.20]),
            ],
            scan_step_deg: 0.12,
            scan_step_full_deg: 0.03,
            captures: 8,
            navcam: NAVCAM,
            image_scale: 1.0,
            texture_camera: TEXTURE_CAMERA,
            texture_kc: TEXTURE_KC,
            sfm_cell_m: 0.02,
            vicon_frames: 200,
            rig_frames: 100,
            range_noise_m: 0.008,
            supersample: 1,
        }
    }

    fn mini() -> PresetConfig {
        PresetConfig {
            campaign_name: "mini-synthetic",
            extent_m: [2.0, 2.0],
            cell_m: 0.004,
            cell_full_m: 0.0025,
            relief: Relief {
                floor_m: -0.02,
                top_m: 0.25,
                main_hill: [0.4, 1.6, 0.45],
                hills: 2,
                crater: [1.35, 0.7, 0.3],
                boulders: 12,
                pebbles: 150,
            },
            markers: vec![
                MarkerSpec {
                    name: "Marker1",
                    xy: [0.45, 0.5],
                    z: None,
                },
                MarkerSpec {
                    name: "Marker2",
                    xy: [1.55, 0.35],
                    z: None,
                },
                MarkerSpec {
                    name: "Marker3",
                    xy: [1.0, 1.05],
                    z: None,
                },
                MarkerSpec {
                    name: "Marker4",
                    xy: [0.35, 1.55],
                    z: None,
                },
                MarkerSpec {
                    name: "Marker5",
                    xy: [1.6, 1.6],
                    z: None,
                },
            ],
            scanners: vec![
                scanner("pos1", [-1.1, -0.9, 1.3], [130.0, 230.0]),
                scanner("pos2", [3.1, 2.8, 1.4], [140.0, 240.0]),
            ],
            scan_step_deg: 0.25,
            scan_step_full_deg: 0.1,
            captures: 2,
            navcam: NAVCAM,
            image_scale: 0.5,
            texture_camera: TEXTURE_CAMERA,
            texture_kc: TEXTURE_KC,
            sfm_cell_m: 0.02,
            vicon_frames: 200,
            rig_frames: 50,
            range_noise_m: 0.008,
            supersample: 1,
        }
    }
}
