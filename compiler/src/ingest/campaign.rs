//! `campaign.toml` (`regolith.campaign/1`, normative text in `format-spec/campaign.md`) →
//! a validated, typed [`Campaign`] plan.
//!
//! Parse → resolve (house style 6): [`parse_str`] deserialises the raw "low" structs
//! ([`CampaignToml`]) with serde and `deny_unknown_fields`; an unknown key becomes an error
//! naming its line with a "did you mean" hint (`strsim`, computed from the field list serde
//! reports, so the structs are the single source of truth). [`resolve`] then checks every rule
//! that needs more than types: schema id, unique names, references between tables, value
//! ranges, and paths. Every path is relative to the campaign folder; absolute paths, `..`
//! components and symlinks that lead outside the folder are errors, and referenced files must
//! exist. Resolution reads no file contents: the stages parse each input with its reader.

use std::collections::BTreeSet;
use std::path::{Component, Path, PathBuf};

use regolith_format::limits::Limits;
use serde::Deserialize;

use super::yaml_lite;
use crate::error::{IngestError, Result};

/// The schema id this reader accepts.
pub const SCHEMA: &str = "regolith.campaign/1";

/// `campaign.toml` as written (the "low" form).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CampaignToml {
    /// Must be [`SCHEMA`].
    pub schema: String,
    /// Campaign name.
    pub name: String,
    /// Ground reference (Vicon) markers.
    pub ground: GroundToml,
    /// Surveyed lab light.
    pub lighting: Option<Lighting>,
    /// Laser scans.
    #[serde(default)]
    pub scan: Vec<ScanToml>,
    /// SfM reconstructions.
    #[serde(default)]
    pub reconstruction: Vec<ReconstructionToml>,
    /// Cameras.
    #[serde(default)]
    pub camera: Vec<CameraToml>,
    /// Stereo rig.
    pub rig: Option<RigToml>,
    /// Image captures.
    #[serde(default)]
    pub capture: Vec<CaptureToml>,
    /// Terrains to build.
    #[serde(default)]
    pub terrain: Vec<TerrainToml>,
}

/// `[ground]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundToml {
    /// Vicon Nexus CSV of the static markers.
    pub markers: String,
    /// Ball radius, metres.
    pub marker_radius_m: f64,
}

/// `[lighting]` (also the resolved form).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Lighting {
    /// From +x towards +y, degrees.
    pub azimuth_deg: f64,
    /// Above the horizontal, degrees.
    pub elevation_deg: f64,
    /// Share of diffuse ambient light, 0..1.
    pub ambient: f64,
}

/// `[[scan]]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanToml {
    /// Unique name.
    pub name: String,
    /// Point-cloud file.
    pub file: String,
    /// ASCII column names, space-separated.
    pub columns: Option<String>,
    /// Reflector centres in scanner coordinates.
    pub tiepoints: Option<String>,
    /// Known SOCS → ground matrix.
    pub sop: Option<String>,
}

/// `[[reconstruction]]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReconstructionToml {
    /// Unique name.
    pub name: String,
    /// VRML or PLY file.
    pub file: String,
    /// `"laser"` or a ground-control-point file.
    pub align: String,
}

/// `[[camera]]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraToml {
    /// Unique name.
    pub name: String,
    /// Calibration file.
    pub calibration: String,
    /// Which camera of a multi-camera file (`"1"` for `M1`, `"LEFT"`, `"cam0"`).
    pub entry: Option<String>,
    /// `[width, height]` when the calibration file does not state it.
    pub image_size: Option<[u32; 2]>,
}

/// `[rig]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigToml {
    /// Ball centres in the left-camera frame.
    pub markers: String,
    /// Left camera name.
    pub left: String,
    /// Right camera name.
    pub right: String,
    /// Stereo extrinsics file.
    pub right_from_left: String,
}

/// A string or a list of strings.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum OneOrMany {
    /// One path.
    One(String),
    /// Several paths.
    Many(Vec<String>),
}

/// `[[capture]]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaptureToml {
    /// Unique name.
    pub name: String,
    /// Raw left frames.
    pub left: OneOrMany,
    /// Raw right frames.
    pub right: OneOrMany,
    /// Vicon CSV of the rig balls during the capture.
    pub rig_pose: String,
}

/// `[[terrain]]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TerrainToml {
    /// Unique name.
    pub name: String,
    /// Scan or reconstruction names.
    pub from: Vec<String>,
    /// Raster steps, metres.
    pub raster_m: Vec<f64>,
    /// Texture source.
    pub texture: String,
    /// `[xmin, ymin, xmax, ymax]` crop in the ground frame.
    pub bounds_m: Option<[f64; 4]>,
    /// Reconstruction terrains: also drape the vertex colours on this laser terrain's geometry.
    #[serde(default)]
    pub drape_on: Option<String>,
}

/// The resolved, validated campaign. Paths are relative to [`Campaign::root`].
#[derive(Debug, Clone, PartialEq)]
pub struct Campaign {
    /// The campaign folder.
    pub root: PathBuf,
    /// Campaign name.
    pub name: String,
    /// Static ground markers CSV.
    pub ground_markers: PathBuf,
    /// Ball radius, metres.
    pub marker_radius_m: f64,
    /// Surveyed light, if given.
    pub lighting: Option<Lighting>,
    /// Scans.
    pub scans: Vec<Scan>,
    /// Reconstructions.
    pub reconstructions: Vec<Reconstruction>,
    /// Cameras.
    pub cameras: Vec<Camera>,
    /// Rig, if given.
    pub rig: Option<Rig>,
    /// Captures.
    pub captures: Vec<Capture>,
    /// Terrains.
    pub terrains: Vec<Terrain>,
}

/// Point-cloud file kinds, from the extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScanFormat {
    /// `.asc .txt .xyz .csv`.
    Ascii,
    /// `.ptx`.
    Ptx,
    /// `.e57`.
    E57,
    /// `.las .laz`.
    Las,
    /// `.ply`.
    Ply,
}

/// How a scan reaches the ground frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Registration {
    /// Reflector tie points matched to ground markers by name.
    Tiepoints(PathBuf),
    /// A known SOCS → ground matrix.
    Sop(PathBuf),
}

/// A resolved scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// Name.
    pub name: String,
    /// File.
    pub file: PathBuf,
    /// Format.
    pub format: ScanFormat,
    /// ASCII columns (lower-case), when given.
    pub columns: Option<Vec<String>>,
    /// Registration source.
    pub registration: Registration,
}

/// Mesh file kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// `.wrl`.
    Vrml,
    /// `.ply`.
    Ply,
}

/// How a reconstruction is aligned.
#[derive(Debug, Clone, PartialEq)]
pub enum Align {
    /// Similarity-align to the merged laser cloud.
    Laser,
    /// Ground control points file.
    Gcp(PathBuf),
}

/// A resolved reconstruction.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstruction {
    /// Name.
    pub name: String,
    /// File.
    pub file: PathBuf,
    /// Format.
    pub format: MeshFormat,
    /// Alignment.
    pub align: Align,
}

/// A resolved camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Name.
    pub name: String,
    /// Calibration file.
    pub calibration: PathBuf,
    /// Entry in a multi-camera file.
    pub entry: Option<String>,
    /// Image size override `[width, height]`.
    pub image_size: Option<[u32; 2]>,
}

/// A resolved rig; `left`/`right` index [`Campaign::cameras`].
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// Ball geometry CSV.
    pub markers: PathBuf,
    /// Index of the left camera.
    pub left: usize,
    /// Index of the right camera.
    pub right: usize,
    /// Stereo extrinsics file.
    pub right_from_left: PathBuf,
}

/// A resolved capture.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// Name.
    pub name: String,
    /// Raw left frames.
    pub left: Vec<PathBuf>,
    /// Raw right frames.
    pub right: Vec<PathBuf>,
    /// Rig-ball Vicon CSV.
    pub rig_pose: PathBuf,
}

/// Where a terrain's geometry comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum TerrainSource {
    /// Indices into [`Campaign::scans`].
    Scans(Vec<usize>),
    /// Indices into [`Campaign::reconstructions`].
    Reconstructions(Vec<usize>),
}

/// Texture sources.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Texture {
    /// RIEGL reflectance (scans).
    Reflectance,
    /// Raw intensity (scans).
    Intensity,
    /// Mesh vertex colours (reconstructions).
    VertexColor,
    /// No texture.
    None,
}

/// A resolved terrain.
#[derive(Debug, Clone, PartialEq)]
pub struct Terrain {
    /// Name.
    pub name: String,
    /// Sources.
    pub from: TerrainSource,
    /// Raster steps, metres, as given.
    pub raster_m: Vec<f64>,
    /// Texture.
    pub texture: Texture,
    /// Optional crop.
    pub bounds_m: Option<[f64; 4]>,
    /// A reconstruction terrain's colours are also draped on this laser terrain's rasters
    /// (`sfm-on-laser` entries `<name>-on-<laser>/<cell>`, one per raster step of this terrain;
    /// the laser terrain has every one of them).
    pub drape_on: Option<String>,
}

/// Parses `campaign.toml` text into the low structs.
pub fn parse_str(text: &str) -> Result<CampaignToml> {
    toml::from_str(text).map_err(|e| {
        let line = e.span().map_or(1, |s| {
            text.get(..s.start).unwrap_or("").matches('\n').count() as u64 + 1
        });
        let msg = e.message().to_string();
        let err = match unknown_field_hint(&msg).or_else(|| missing_field_hint(&msg)) {
            Some(hint) => IngestError::invalid(hint),
            None => IngestError::invalid(msg),
        };
        err.at_line(line)
    })
}

/// serde reports "missing field `x`": say what the key holds and where it goes.
fn missing_field_hint(msg: &str) -> Option<String> {
    let key = msg.strip_prefix("missing field `")?.strip_suffix('`')?;
    Some(match key {
        "schema" => format!(
            "missing field `schema`: every campaign.toml starts with `schema = \"{SCHEMA}\"` \
             (the campaign format it is written in); add that line at the top"
        ),
        "ground" => "missing field `ground`: add a `[ground]` table with `markers = \"<Vicon \
                     CSV of the ground markers>\"` and `marker_radius_m = <ball radius, m>`"
            .to_string(),
        _ => format!(
            "missing field `{key}`: add `{key} = ...` here (format-spec/campaign.md lists every \
             table's required keys)"
        ),
    })
}

/// serde reports "unknown field `x`, expected one of `a`, `b`": add the nearest name.
fn unknown_field_hint(msg: &str) -> Option<String> {
    let rest = msg.strip_prefix("unknown field ")?;
    let names: Vec<&str> = rest.split('`').skip(1).step_by(2).collect();
    let (unknown, expected) = names.split_first()?;
    let best = expected
        .iter()
        .map(|c| (strsim::jaro_winkler(unknown, c), *c))
        .filter(|(s, _)| *s > 0.7)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    Some(match best {
        Some((_, c)) => format!("unknown key `{unknown}`: did you mean `{c}`?"),
        None => format!(
            "unknown key `{unknown}`; expected one of {}",
            expected.join(", ")
        ),
    })
}

/// Loads and resolves a campaign: `path` is `campaign.toml` or the folder holding it.
pub fn load(path: &Path) -> Result<Campaign> {
    let campaign_hint = "give the campaign folder (the folder holding campaign.toml) or its \
                         campaign.toml";
    if !path.exists() {
        return Err(IngestError::invalid(format!(
            "{}: no such file or folder; {campaign_hint}",
            path.display()
        )));
    }
    if path.is_dir() && !path.join("campaign.toml").is_file() {
        let what = if path.join("regolith.db").is_file() {
            "it is a regolith database, not a campaign".to_string()
        } else {
            let below: Vec<String> = std::fs::read_dir(path)
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.join("campaign.toml").is_file())
                .map(|p| p.display().to_string())
                .collect();
            match below.as_slice() {
                [] => "it holds no campaign.toml".to_string(),
                [one] => format!("it holds no campaign.toml (did you mean {one}?)"),
                more => format!(
                    "it holds no campaign.toml (did you mean one of {}?)",
                    more.join(", ")
                ),
            }
        };
        return Err(IngestError::invalid(format!(
            "{} is not a campaign folder: {what}; {campaign_hint}",
            path.display()
        )));
    }
    let file = if path.is_dir() {
        path.join("campaign.toml")
    } else {
        path.to_path_buf()
    };
    // A bare file name's parent is "", which names no folder: it is the working directory.
    let root = file
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let bytes = yaml_lite::read_file(&file, &Limits::default()).map_err(|e| e.in_file(&file))?;
    let text = yaml_lite::decode_text(&bytes).map_err(|e| e.in_file(&file))?;
    let low = parse_str(text).map_err(|e| e.in_file(&file))?;
    resolve(&low, &root).map_err(|e| e.locate(text).in_file(&file))
}

fn bad(msg: String) -> IngestError {
    IngestError::invalid(msg)
}

/// What to do about a referenced file that is not there (the default of [`file_in`]).
const MISSING_FILE_HINT: &str = "add the file, or correct the path in campaign.toml (relative \
                                 to the campaign folder, `/` between folders)";

/// How a scan gets to the ground frame, for errors about its registration.
const REGISTRATION_HINT: &str = "a scan is registered either by tie points, `tiepoints = \
     \"<file>.csv\"` with one `Name,X,Y,Z` row per reflector centre in the scanner's own \
     coordinates, named as the [ground].markers markers (RiSCAN PRO: export the scan \
     position's TPL), or by a known scanner-to-ground matrix, `sop = \"<file>.DAT\"` (RiSCAN \
     PRO's SOP export)";

/// Checks a relative path stays inside `root` and names an existing file.
fn file_in(root: &Path, rel: &str, what: &str) -> Result<PathBuf> {
    file_in_or(root, rel, what, MISSING_FILE_HINT)
}

/// [`file_in`], with `hint` saying what to do when the file does not exist. Errors point at the
/// line of campaign.toml holding the path.
fn file_in_or(root: &Path, rel: &str, what: &str, hint: &str) -> Result<PathBuf> {
    let near = |e: IngestError| e.near(format!("{rel:?}"));
    let p = PathBuf::from(rel);
    if rel.is_empty()
        || p.components()
            .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err(near(bad(format!(
            "{what} path {rel:?} must be relative and stay inside the campaign folder"
        ))));
    }
    let full = root.join(&p);
    let canon = full.canonicalize().map_err(|_| {
        near(bad(format!(
            "{what} file {rel:?} does not exist (looked for {}); {hint}",
            full.display()
        )))
    })?;
    let canon_root = root.canonicalize().map_err(IngestError::from)?;
    if !canon.starts_with(&canon_root) {
        return Err(near(bad(format!(
            "{what} path {rel:?} leads outside the campaign folder (symlink)"
        ))));
    }
    if !canon.is_file() {
        return Err(near(bad(format!(
            "{what} path {rel:?} is not a file; name a file inside the campaign folder"
        ))));
    }
    Ok(p.components().collect())
}

fn unique<'a>(kind: &str, names: impl IntoIterator<Item = &'a String>) -> Result<()> {
    let mut seen = BTreeSet::new();
    for n in names {
        if n.is_empty()
            || !n
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "._-".contains(c))
        {
            return Err(bad(format!(
                "{kind} name {n:?} must be non-empty and use only A-Z a-z 0-9 . _ -"
            )));
        }
        if !seen.insert(n.as_str()) {
            return Err(bad(format!("{kind} name {n:?} is used twice")));
        }
    }
    Ok(())
}

fn extension(rel: &str) -> String {
    Path::new(rel)
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

fn positive(what: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(format!("{what} must be a positive number, found {v}")))
    }
}

/// Validates the low structs against the folder `root` and builds the plan.
pub fn resolve(low: &CampaignToml, root: &Path) -> Result<Campaign> {
    if low.schema != SCHEMA {
        return Err(bad(format!(
            "schema {:?} is not {SCHEMA:?}: this regolith reads `schema = {SCHEMA:?}` \
             campaigns (format-spec/campaign.md)",
            low.schema
        ))
        .near("schema"));
    }
    unique("campaign", [&low.name])?;
    positive("[ground].marker_radius_m", low.ground.marker_radius_m)?;
    if let Some(l) = &low.lighting {
        let ok = l.azimuth_deg.is_finite()
            && (0.0..=90.0).contains(&l.elevation_deg)
            && (0.0..=1.0).contains(&l.ambient);
        if !ok {
            return Err(bad(
                "[lighting]: azimuth_deg finite, elevation_deg in 0..=90, ambient in 0..=1".into(),
            ));
        }
    }
    unique(
        "scan/reconstruction",
        low.scan
            .iter()
            .map(|s| &s.name)
            .chain(low.reconstruction.iter().map(|r| &r.name)),
    )?;
    unique("camera", low.camera.iter().map(|c| &c.name))?;
    unique("capture", low.capture.iter().map(|c| &c.name))?;
    unique("terrain", low.terrain.iter().map(|t| &t.name))?;
    let scans = low
        .scan
        .iter()
        .map(|s| resolve_scan(s, root))
        .collect::<Result<Vec<_>>>()?;
    let reconstructions = low
        .reconstruction
        .iter()
        .map(|r| resolve_reconstruction(r, root, !scans.is_empty()))
        .collect::<Result<Vec<_>>>()?;
    let cameras = low
        .camera
        .iter()
        .map(|c| resolve_camera(c, root))
        .collect::<Result<Vec<_>>>()?;
    let rig = low
        .rig
        .as_ref()
        .map(|r| resolve_rig(r, root, &cameras))
        .transpose()?;
    if rig.is_none() && !low.capture.is_empty() {
        return Err(bad("[[capture]] needs a [rig]".into()));
    }
    let captures = low
        .capture
        .iter()
        .map(|c| resolve_capture(c, root))
        .collect::<Result<Vec<_>>>()?;
    let terrains = low
        .terrain
        .iter()
        .map(|t| resolve_terrain(t, &scans, &reconstructions))
        .collect::<Result<Vec<_>>>()?;
    check_drapes(&terrains)?;
    Ok(Campaign {
        root: root.to_path_buf(),
        name: low.name.clone(),
        ground_markers: file_in(root, &low.ground.markers, "[ground].markers")?,
        marker_radius_m: low.ground.marker_radius_m,
        lighting: low.lighting,
        scans,
        reconstructions,
        cameras,
        rig,
        captures,
        terrains,
    })
}

fn resolve_scan(s: &ScanToml, root: &Path) -> Result<Scan> {
    let what = format!("[[scan]] {:?}", s.name);
    let file = file_in(root, &s.file, &what)?;
    let format = match extension(&s.file).as_str() {
        "asc" | "txt" | "xyz" | "csv" => ScanFormat::Ascii,
        "ptx" => ScanFormat::Ptx,
        "e57" => ScanFormat::E57,
        "las" | "laz" => ScanFormat::Las,
        "ply" => ScanFormat::Ply,
        e => {
            return Err(bad(format!(
                "{what}: file extension {e:?} is not .asc .txt .xyz .csv .ptx .e57 .las .laz .ply"
            )))
        }
    };
    let columns = match (&s.columns, format) {
        (None, _) => None,
        (Some(c), ScanFormat::Ascii) => {
            let cols: Vec<String> = c.split_whitespace().map(str::to_ascii_lowercase).collect();
            let mut seen = BTreeSet::new();
            if !["x", "y", "z"].iter().all(|a| cols.iter().any(|c| c == a))
                || !cols.iter().all(|c| seen.insert(c))
            {
                return Err(bad(format!(
                    "{what}: columns {c:?} must name x, y and z once each"
                )));
            }
            Some(cols)
        }
        (Some(_), _) => {
            return Err(bad(format!(
                "{what}: `columns` applies to ASCII files only"
            )))
        }
    };
    let registration = match (&s.tiepoints, &s.sop) {
        (Some(t), None) => Registration::Tiepoints(file_in_or(
            root,
            t,
            &format!("{what} tiepoints"),
            REGISTRATION_HINT,
        )?),
        (None, Some(m)) => Registration::Sop(file_in_or(
            root,
            m,
            &format!("{what} sop"),
            REGISTRATION_HINT,
        )?),
        (None, None) => {
            return Err(bad(format!(
                "{what} has no registration (neither `tiepoints` nor `sop`): {REGISTRATION_HINT}"
            ))
            .near(format!("{:?}", s.file)))
        }
        (Some(_), Some(_)) => {
            return Err(bad(format!(
                "{what}: give exactly one of `tiepoints` and `sop`, not both: {REGISTRATION_HINT}"
            ))
            .near(format!("{:?}", s.file)))
        }
    };
    Ok(Scan {
        name: s.name.clone(),
        file,
        format,
        columns,
        registration,
    })
}

fn resolve_reconstruction(
    r: &ReconstructionToml,
    root: &Path,
    have_scans: bool,
) -> Result<Reconstruction> {
    let what = format!("[[reconstruction]] {:?}", r.name);
    let file = file_in(root, &r.file, &what)?;
    let format = match extension(&r.file).as_str() {
        "wrl" => MeshFormat::Vrml,
        "ply" => MeshFormat::Ply,
        e => {
            return Err(bad(format!(
                "{what}: file extension {e:?} is not .wrl or .ply"
            )))
        }
    };
    let align = match r.align.as_str() {
        "laser" if have_scans => Align::Laser,
        "laser" => {
            return Err(bad(format!(
                "{what}: align = \"laser\" needs at least one [[scan]]"
            )))
        }
        gcp => Align::Gcp(file_in(root, gcp, &format!("{what} align"))?),
    };
    Ok(Reconstruction {
        name: r.name.clone(),
        file,
        format,
        align,
    })
}

fn resolve_camera(c: &CameraToml, root: &Path) -> Result<Camera> {
    let what = format!("[[camera]] {:?}", c.name);
    if c.image_size.is_some_and(|[w, h]| w == 0 || h == 0) {
        return Err(bad(format!("{what}: image_size must be > 0")));
    }
    Ok(Camera {
        name: c.name.clone(),
        calibration: file_in(root, &c.calibration, &what)?,
        entry: c.entry.clone(),
        image_size: c.image_size,
    })
}

fn resolve_rig(r: &RigToml, root: &Path, cameras: &[Camera]) -> Result<Rig> {
    let index = |n: &str| {
        cameras.iter().position(|c| c.name == n).ok_or_else(|| {
            let names: Vec<&str> = cameras.iter().map(|c| c.name.as_str()).collect();
            bad(format!(
                "[rig]: {n:?} is not a [[camera]] name (the cameras are: {})",
                names.join(", ")
            ))
            .near(format!("{n:?}"))
        })
    };
    let (left, right) = (index(&r.left)?, index(&r.right)?);
    if left == right {
        return Err(bad("[rig]: left and right must be different cameras".into()));
    }
    Ok(Rig {
        markers: file_in(root, &r.markers, "[rig].markers")?,
        left,
        right,
        right_from_left: file_in(root, &r.right_from_left, "[rig].right_from_left")?,
    })
}

fn resolve_capture(c: &CaptureToml, root: &Path) -> Result<Capture> {
    let what = format!("[[capture]] {:?}", c.name);
    let list = |v: &OneOrMany, side: &str| -> Result<Vec<PathBuf>> {
        let items: Vec<&String> = match v {
            OneOrMany::One(s) => vec![s],
            OneOrMany::Many(v) => v.iter().collect(),
        };
        if items.is_empty() {
            return Err(bad(format!("{what}: `{side}` needs at least one image")));
        }
        items
            .into_iter()
            .map(|p| file_in(root, p, &format!("{what} {side}")))
            .collect()
    };
    Ok(Capture {
        name: c.name.clone(),
        left: list(&c.left, "left")?,
        right: list(&c.right, "right")?,
        rig_pose: file_in(root, &c.rig_pose, &format!("{what} rig_pose"))?,
    })
}

fn resolve_terrain(t: &TerrainToml, scans: &[Scan], recs: &[Reconstruction]) -> Result<Terrain> {
    let what = format!("[[terrain]] {:?}", t.name);
    let mut seen = BTreeSet::new();
    let (mut si, mut ri) = (Vec::new(), Vec::new());
    for n in &t.from {
        if !seen.insert(n) {
            return Err(bad(format!("{what}: {n:?} is listed twice in `from`")));
        }
        match (
            scans.iter().position(|s| s.name == *n),
            recs.iter().position(|r| r.name == *n),
        ) {
            (Some(i), _) => si.push(i),
            (_, Some(i)) => ri.push(i),
            _ => {
                let names: Vec<&str> = scans
                    .iter()
                    .map(|s| s.name.as_str())
                    .chain(recs.iter().map(|r| r.name.as_str()))
                    .collect();
                return Err(bad(format!(
                    "{what}: `from` entry {n:?} names no [[scan]] or [[reconstruction]] (they \
                     are: {})",
                    names.join(", ")
                ))
                .near(format!("{n:?}")));
            }
        }
    }
    let from = match (si.is_empty(), ri.is_empty()) {
        (false, true) => TerrainSource::Scans(si),
        (true, false) => TerrainSource::Reconstructions(ri),
        (true, true) => return Err(bad(format!("{what}: `from` is empty"))),
        (false, false) => {
            return Err(bad(format!(
                "{what}: `from` mixes scans and reconstructions"
            )))
        }
    };
    if t.raster_m.is_empty() {
        return Err(bad(format!("{what}: raster_m is empty")));
    }
    for (i, r) in t.raster_m.iter().enumerate() {
        positive(&format!("{what}: raster_m[{i}]"), *r)?;
        if t.raster_m.iter().take(i).any(|o| o == r) {
            return Err(bad(format!("{what}: raster_m repeats {r}")));
        }
    }
    let texture = match (t.texture.as_str(), &from) {
        ("reflectance", TerrainSource::Scans(_)) => Texture::Reflectance,
        ("intensity", TerrainSource::Scans(_)) => Texture::Intensity,
        ("vertex-color", TerrainSource::Reconstructions(_)) => Texture::VertexColor,
        ("none", _) => Texture::None,
        (x, _) => {
            return Err(bad(format!(
                "{what}: texture {x:?} is not valid here (scans: reflectance, intensity, none; reconstructions: vertex-color, none)"
            )))
        }
    };
    if let Some([x0, y0, x1, y1]) = t.bounds_m {
        if !(x0.is_finite()
            && y0.is_finite()
            && x1.is_finite()
            && y1.is_finite()
            && x0 < x1
            && y0 < y1)
        {
            return Err(bad(format!(
                "{what}: bounds_m must be [xmin, ymin, xmax, ymax] with min < max"
            )));
        }
    }
    if t.drape_on.is_some() && !matches!(from, TerrainSource::Reconstructions(_)) {
        return Err(bad(format!(
            "{what}: drape_on is for reconstruction terrains (it drapes their colours on a laser terrain)"
        )));
    }
    Ok(Terrain {
        name: t.name.clone(),
        from,
        raster_m: t.raster_m.clone(),
        texture,
        bounds_m: t.bounds_m,
        drape_on: t.drape_on.clone(),
    })
}

/// Every `drape_on` names a laser terrain that has each of the draping terrain's raster steps.
fn check_drapes(terrains: &[Terrain]) -> Result<()> {
    for t in terrains {
        let Some(target) = &t.drape_on else { continue };
        let what = format!("[[terrain]] {:?}: drape_on = {target:?}", t.name);
        let laser = terrains
            .iter()
            .find(|l| l.name == *target && matches!(l.from, TerrainSource::Scans(_)))
            .ok_or_else(|| bad(format!("{what} names no laser (scans) terrain")))?;
        if let Some(r) = t.raster_m.iter().find(|r| !laser.raster_m.contains(r)) {
            return Err(bad(format!(
                "{what}: the laser terrain has no raster_m {r} (it has {:?}); the colours are draped on the laser raster of the same step",
                laser.raster_m
            )));
        }
    }
    Ok(())
}

impl Campaign {
    /// Every file the campaign references, relative to the root, sorted and deduplicated.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut v: BTreeSet<PathBuf> = BTreeSet::new();
        v.insert(self.ground_markers.clone());
        for s in &self.scans {
            v.insert(s.file.clone());
            v.insert(match &s.registration {
                Registration::Tiepoints(p) | Registration::Sop(p) => p.clone(),
            });
        }
        for r in &self.reconstructions {
            v.insert(r.file.clone());
            if let Align::Gcp(p) = &r.align {
                v.insert(p.clone());
            }
        }
        v.extend(self.cameras.iter().map(|c| c.calibration.clone()));
        if let Some(r) = &self.rig {
            v.insert(r.markers.clone());
            v.insert(r.right_from_left.clone());
        }
        for c in &self.captures {
            v.extend(c.left.iter().chain(&c.right).cloned());
            v.insert(c.rig_pose.clone());
        }
        v.into_iter().collect()
    }
}
