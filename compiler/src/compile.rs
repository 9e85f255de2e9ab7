//! `regolith compile`: the pipeline from a resolved campaign to a committed release.
//!
//! The pipeline is plain Rust (house style): ground control (Vicon markers, GCP files) → per
//! laser terrain `register.tiepoints` → `register.icp` → `merge.clean` → `dem.tin` →
//! `dem.raster` → per reconstruction terrain `sfm.align` (laser, control points, or both) →
//! encode heightfields, textures and meshes → `captures.build` → reports → release. Every
//! stage that ran is recorded with its version and params in the release plan. Nothing time-
//! or machine-dependent enters an object: timings go to the returned summary only.
//!
//! `sfm.align` runs as soon as the first laser terrain's points are merged, before its TIN, so
//! the 18 M merged points of a full survey are freed once the TIN holds them instead of being
//! kept through `dem.tin` and `dem.raster` for the alignment; it is recorded in the plan where
//! it always stood and seeds its randomness by its name, so the release does not depend on
//! when it ran.
//!
//! Whole-compile cache: the key is the SHA-256 of the compiler version, the options and every
//! input file's hash; `refs/cache/<key>` remembers the release it produced, so an unchanged
//! recompile only rehashes the inputs and re-tags the release.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;
use regolith_format::kinds::{self, media, roles, CameraMeta, MeshMeta, TextureMeta};
use regolith_format::manifest::{new_release, CampaignRef, InputFile, PlanStep, Producer};
use regolith_format::{Entry, FileRef, ObjectId, Release, Tile};
use regolith_reader::{ReaderError, Writer};
use serde::Serialize;
use serde_json::{json, Value};

use crate::encode::{heightfield, png, terrain, EncodeError};
use crate::error::IngestError;
use crate::ingest::campaign::{
    Align, Campaign, Registration, Scan, Terrain, TerrainSource, Texture,
};
use crate::ingest::types::{NamedPoint, PointCloud};
use crate::ingest::{gcp, markers, vicon_csv};
use crate::inventory::{load_reconstruction, load_scan, load_sop, load_tiepoints};
use crate::stage::{Stage, StageCx, StageError};
use crate::stages::captures::BuildCaptures;
use crate::stages::dem_raster::{DemRaster, MaxEdge, Raster};
use crate::stages::dem_tin::DemTin;
use crate::stages::dem_tin::Tin;
use crate::stages::merge_clean::{MergeClean, MergeScan};
use crate::stages::register_icp::{IcpInput, IcpScan, RegisterIcp};
use crate::stages::register_tiepoints::{RegisterTiepoints, ScanTiepoints, TiepointInput};
use crate::stages::sfm_align::{AlignSfm, ControlPoint};

/// Anything that stops a compile. The database is left as it was.
#[derive(Debug, thiserror::Error)]
pub enum CompileError {
    /// A raw input is bad.
    #[error(transparent)]
    Ingest(#[from] IngestError),
    /// A stage failed.
    #[error(transparent)]
    Stage(#[from] StageError),
    /// Encoding failed.
    #[error(transparent)]
    Encode(#[from] EncodeError),
    /// Writing the database failed.
    #[error(transparent)]
    Store(#[from] ReaderError),
    /// The release name and version are taken by a release compiled from other inputs.
    #[error(
        "release {label} already exists in this database (id {id}) and was compiled from other \
         inputs ({changed}); releases are immutable: compile a new version with `--release \
         {next}`"
    )]
    ReleaseExists {
        /// `name@version`.
        label: String,
        /// The existing release's short id.
        id: String,
        /// Which inputs differ (`changed: campaign.toml, scans/pos1.asc`).
        changed: String,
        /// A free `name@version` to suggest.
        next: String,
    },
}

/// Compile options.
#[derive(Debug, Clone)]
pub struct CompileOptions {
    /// Release name (default: the campaign name).
    pub name: String,
    /// Release version.
    pub version: String,
    /// Mesh levels of detail (each halves the vertex spacing of the previous).
    pub lods: u32,
    /// Input limits.
    pub limits: regolith_format::limits::Limits,
}

/// What `compile --json` prints.
#[derive(Debug, Clone, Serialize)]
pub struct CompileSummary {
    /// `name@version`.
    pub release: String,
    /// Release id.
    pub id: String,
    /// Entry names.
    pub entries: Vec<String>,
    /// Registration figures.
    pub registration: Value,
    /// Alignment figures per reconstruction.
    pub alignment: Value,
    /// DEM statistics per raster.
    pub dem: Vec<Value>,
    /// Structured warnings.
    pub warnings: Vec<Value>,
    /// True when the whole-compile cache was hit.
    pub cached: bool,
    /// Wall time per stage (not stored anywhere).
    pub stage_seconds: Vec<(String, f64)>,
}

struct Ctx<'a> {
    writer: &'a Writer,
    cx: StageCx,
    plan: Vec<PlanStep>,
    entries: Vec<Entry>,
    times: Vec<(String, f64)>,
    clock: Instant,
}

impl Ctx<'_> {
    fn lap(&mut self, name: &str) {
        self.times
            .push((name.to_string(), self.clock.elapsed().as_secs_f64()));
        self.clock = Instant::now();
    }
    fn record<S: Stage>(&mut self, s: &S) {
        if !self
            .plan
            .iter()
            .any(|p| p.stage == S::NAME && p.params == s.params())
        {
            self.plan.push(PlanStep {
                stage: S::NAME.into(),
                version: S::VERSION,
                params: s.params(),
            });
        }
    }
    fn put(&self, bytes: &[u8], media_type: &str) -> Result<FileRef, CompileError> {
        Ok(self.writer.put(bytes, media_type)?)
    }
    fn report(&mut self, name: &str, report: &str, body: &Value) -> Result<(), CompileError> {
        let f = self.writer.put_json(body)?;
        self.entries.push(Entry {
            name: format!("reports/{name}"),
            kind: kinds::REPORT.into(),
            meta: json!({"report": report}),
            files: [(roles::REPORT.to_string(), f)].into(),
            tiles: Vec::new(),
        });
        Ok(())
    }
}

fn hash_inputs(c: &Campaign) -> Result<Vec<InputFile>, CompileError> {
    let mut files = c.input_files();
    files.push("campaign.toml".into());
    files.sort();
    files.dedup();
    // Files are read and hashed in parallel (a full-resolution survey is ~1 GB of scans).
    files
        .par_iter()
        .map(|rel| {
            let bytes = std::fs::read(c.root.join(rel))
                .map_err(|e| IngestError::Io(e).in_file(c.root.join(rel)))?;
            Ok(InputFile {
                path: rel.to_string_lossy().replace('\\', "/"),
                sha256: ObjectId::of_bytes(&bytes),
                size: bytes.len() as u64,
            })
        })
        .collect()
}

/// Ball centres of the ground markers (mean over valid frames).
fn ground_control(
    c: &Campaign,
    cx: &StageCx,
    limits: &regolith_format::limits::Limits,
) -> Result<(Vec<NamedPoint>, Value), CompileError> {
    let traj = vicon_csv::read_path(&c.root.join(&c.ground_markers), limits)?;
    let (stats, warnings) = markers::static_markers(&traj, 10);
    for w in warnings {
        cx.reporter
            .warn("ground.markers", "marker-few-frames", format!("{w:?}"));
    }
    let report = json!(stats
        .iter()
        .map(|m| json!({"marker": m.name, "mean_m": m.mean, "std_m": m.std, "rms_3d_m": m.rms_3d, "frames": m.frames, "radius_m": c.marker_radius_m}))
        .collect::<Vec<_>>());
    Ok((
        stats
            .into_iter()
            .map(|m| NamedPoint {
                name: m.name,
                xyz: m.mean,
            })
            .collect(),
        report,
    ))
}

fn cell_label(cell: f64) -> String {
    format!("{cell}")
}

/// The 8-bit texture of a raster's linear albedo estimate (laser: incidence-corrected
/// reflectance; SfM: vertex grey / 255), holes filled: `pixel = round(255 · clamp(albedo, 0, 1))`,
/// so `pixel / 255` is the albedo (SPEC §5.2) and a plain render matches real grey levels. No
/// stretch: a stretch would make the scale depend on the terrain's own histogram. `None` when
/// the raster has no albedo or not one finite value.
fn albedo_png(r: &Raster) -> Result<Option<Vec<u8>>, CompileError> {
    let Some(albedo) = r
        .albedo
        .as_deref()
        .filter(|v| v.iter().any(|x| x.is_finite()))
    else {
        return Ok(None);
    };
    let filled = heightfield::fill_holes(albedo, r.cols, r.rows);
    let px: Vec<u8> = filled.iter().map(|&a| albedo_to_u8(a)).collect();
    Ok(Some(png::grey8(r.cols as u32, r.rows as u32, &px)?))
}

/// `round(255 · clamp(a, 0, 1))`; NaN (a hole `fill_holes` could not fill) gives 0.
fn albedo_to_u8(a: f32) -> u8 {
    (a.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The `dem` summary row of one raster.
fn dem_row(name: &str, r: &Raster) -> Value {
    json!({"entry": name, "cell_m": r.cell_m, "area_m2": r.stats.surface_area_m2, "volume_m3": r.stats.volume_m3,
        "points": r.stats.points, "triangles": r.stats.triangles, "stats": r.stats})
}

/// What a laser terrain leaves for the rest of the compile: its registration report, the merged
/// points (the SfM alignment target) and its rasters (for `drape_on`).
struct LaserTerrain {
    report: Value,
    rasters: Vec<Raster>,
}

/// What is done with a laser terrain's merged points before its DEM is made (the
/// reconstructions' alignment onto them), so they need not be held through `dem.tin` and
/// `dem.raster`.
type OnMerged<'f> = dyn FnMut(&mut Ctx<'_>, &[[f64; 3]]) -> Result<(), CompileError> + 'f;

/// A laser terrain: its scans registered, merged, triangulated and rasterised. `on_merged`
/// gets the merged points after `merge.clean`; they are freed once the TIN holds its vertices.
#[allow(clippy::too_many_arguments)]
fn laser_terrain(
    ctx: &mut Ctx<'_>,
    c: &Campaign,
    t: &Terrain,
    scans: &[usize],
    markers: &[NamedPoint],
    opts: &CompileOptions,
    dem_out: &mut Vec<Value>,
    on_merged: &mut OnMerged<'_>,
) -> Result<LaserTerrain, CompileError> {
    // The scans are read side by side (a reader of a binary format is one thread, and one
    // scan's file I/O overlaps another's parsing); in scan order, the first failing scan's
    // error is the one a scan-by-scan read would have stopped at.
    let load = |s: &Scan| -> Result<(String, PointCloud, ScanTiepoints), CompileError> {
        let cloud = load_scan(&c.root, s, &opts.limits)?;
        let tp = match &s.registration {
            Registration::Tiepoints(p) => ScanTiepoints {
                scan: s.name.clone(),
                tiepoints: load_tiepoints(&c.root, s, p, &opts.limits)?,
                sop: None,
            },
            Registration::Sop(p) => ScanTiepoints {
                scan: s.name.clone(),
                tiepoints: Vec::new(),
                sop: Some(load_sop(&c.root, s, p, &opts.limits)?),
            },
        };
        Ok((s.name.clone(), cloud, tp))
    };
    let clouds: Vec<(String, PointCloud, ScanTiepoints)> = scans
        .par_iter()
        .filter_map(|&i| c.scans.get(i))
        .map(load)
        .collect::<Vec<_>>()
        .into_iter()
        .collect::<Result<_, _>>()?;
    ctx.lap("ingest.scans");
    let reg = RegisterTiepoints::default();
    let input = TiepointInput {
        markers: markers.to_vec(),
        scans: clouds.iter().map(|c| c.2.clone()).collect(),
    };
    let regs = reg.run(&ctx.cx, &input).map_err(|e| {
        // The stage names the scan (`scan pos1: ...`); add the files behind it.
        let scan = scans
            .iter()
            .filter_map(|&i| c.scans.get(i))
            .find(|s| e.message.starts_with(&format!("scan {}:", s.name)));
        match scan {
            Some(s) => {
                let (Registration::Tiepoints(f) | Registration::Sop(f)) = &s.registration;
                StageError::new(
                    e.stage,
                    format!(
                        "{} (registration {}, ground markers {})",
                        e.message,
                        f.display(),
                        c.ground_markers.display()
                    ),
                )
            }
            None => e,
        }
    })?;
    ctx.record(&reg);
    ctx.lap(RegisterTiepoints::NAME);
    let icp = RegisterIcp::default();
    let icp_in = IcpInput {
        markers: markers.to_vec(),
        scans: clouds
            .iter()
            .zip(&regs)
            .map(|((name, cloud, tp), r)| IcpScan {
                name: name.clone(),
                points: cloud.points.clone(),
                tiepoints: tp.tiepoints.clone(),
                ground_from_socs: r.ground_from_socs,
            })
            .collect(),
    };
    let icp_out = icp.run(&ctx.cx, &icp_in)?;
    drop(icp_in);
    ctx.record(&icp);
    ctx.lap(RegisterIcp::NAME);
    let merge = MergeClean::default();
    let merge_in: Vec<MergeScan> = clouds
        .into_iter()
        .zip(&icp_out.scans)
        .map(|((name, cloud, _), r)| MergeScan {
            name,
            cloud,
            ground_from_socs: r.ground_from_socs,
        })
        .collect();
    let mut merged = merge.merge_owned(&ctx.cx, merge_in)?;
    // The TIN reads the points and the albedo; what else is per point is not needed again.
    merged.reflectance_db = None;
    merged.reflectance = None;
    merged.scan = Vec::new();
    ctx.record(&merge);
    ctx.lap(MergeClean::NAME);
    on_merged(ctx, &merged.points)?;
    let dem_tin = DemTin {
        max_edge_m: LASER_MAX_EDGE_M,
    };
    // The TIN's vertices carry the points and their albedo from here on.
    let tin = dem_tin.run_owned(&mut merged)?;
    ctx.record(&dem_tin);
    ctx.lap(DemTin::NAME);
    let raster = DemRaster::new(
        t.raster_m.clone(),
        t.bounds_m,
        MaxEdge::Absolute(LASER_MAX_EDGE_M),
        -0.1,
        1 << 28,
    )?
    .with_regression(Some(DEM_REGRESSION_SPACINGS));
    let rasters = raster.run(&ctx.cx, &tin)?;
    ctx.record(&raster);
    ctx.lap(DemRaster::NAME);
    dem_out.extend(
        rasters
            .iter()
            .map(|r| dem_row(&raster_entry(&t.name, r), r)),
    );
    let report = json!({
        "terrain": t.name,
        "scans": regs.iter().zip(&icp_out.scans).map(|(r, i)| json!({
            "name": r.scan, "rms_m": r.rms_m, "max_m": r.max_m, "n_tiepoints": r.n_tiepoints, "method": r.method,
            "rejected": r.rejected, "residuals": r.residuals, "ground_from_socs": r.ground_from_socs,
            "icp": i,
        })).collect::<Vec<_>>(),
        "icp": {"iterations": icp_out.iterations, "converged": icp_out.converged},
        "merge": merged.stats,
        "radiometry": merged.radiometry,
    });
    Ok(LaserTerrain { report, rasters })
}

/// The ground control points of every reconstruction aligned by a GCP file, by reconstruction
/// name: its markers with their ground positions (the file's, else the ground marker of the
/// same name). Read before any heavy stage runs, so a bad file fails the compile at once.
/// Fewer than 3 points is an error naming the file.
fn gcp_control(
    c: &Campaign,
    markers: &[NamedPoint],
    limits: &regolith_format::limits::Limits,
) -> Result<BTreeMap<String, Vec<gcp::MatchedGcp>>, CompileError> {
    let mut out = BTreeMap::new();
    for r in &c.reconstructions {
        let Align::Gcp(path) = &r.align else {
            continue;
        };
        let file = c.root.join(path);
        let rows = gcp::read_path(&file, limits)?;
        let matched = gcp::match_markers(&rows, markers).map_err(|e| e.in_file(&file))?;
        if matched.len() < 3 {
            return Err(IngestError::invalid(format!(
                "reconstruction {:?}: {} control point(s), expected at least 3 with ground positions (given, or matched by name to the ground markers)",
                r.name,
                matched.len()
            ))
            .in_file(&file)
            .into());
        }
        out.insert(r.name.clone(), matched);
    }
    Ok(out)
}

/// A reconstruction aligned onto the ground frame by `sfm.align`, not yet rasterised.
struct AlignedRecon {
    mesh: crate::ingest::types::TriMesh,
    out: crate::stages::sfm_align::AlignOutput,
    /// The GCP file and its control points, when the alignment used them.
    gcps: Option<(std::path::PathBuf, Vec<gcp::MatchedGcp>)>,
}

/// Loads and aligns the reconstructions of every reconstruction terrain, terrain by terrain:
/// similarity-align each SfM mesh onto the merged laser cloud `laser_points` (`align =
/// "laser"`) or onto ground control points (`align = "<GCP file>"`, refined on the laser
/// cloud when the campaign has a laser terrain). The stage is recorded in the plan by
/// [`sfm_terrain`], where it has always stood, so the release does not depend on when the
/// alignment ran (its randomness is seeded by its name).
fn align_reconstructions(
    ctx: &mut Ctx<'_>,
    c: &Campaign,
    terrains: &[&Terrain],
    laser_points: &[[f64; 3]],
    control: &BTreeMap<String, Vec<gcp::MatchedGcp>>,
    opts: &CompileOptions,
) -> Result<Vec<Vec<AlignedRecon>>, CompileError> {
    let mut all = Vec::new();
    for t in terrains {
        let mut aligned = Vec::new();
        let recons: &[usize] = match &t.from {
            TerrainSource::Reconstructions(idx) => idx,
            TerrainSource::Scans(_) => &[],
        };
        for &i in recons {
            let Some(r) = c.reconstructions.get(i) else {
                continue;
            };
            let gcps = match &r.align {
                Align::Laser if laser_points.is_empty() => {
                    return Err(StageError::new(
                        AlignSfm::NAME,
                        format!(
                            "reconstruction {:?}: align = \"laser\" needs a laser terrain in the campaign",
                            r.name
                        ),
                    )
                    .into());
                }
                Align::Laser => None,
                Align::Gcp(p) => Some((
                    p.clone(),
                    control
                        .get(&r.name)
                        .ok_or_else(|| {
                            StageError::new(
                                AlignSfm::NAME,
                                format!("reconstruction {:?}: control points not read", r.name),
                            )
                        })?
                        .clone(),
                )),
            };
            let mesh = load_reconstruction(&c.root, &r.file, r.format, &opts.limits)?;
            ctx.lap("ingest.reconstruction");
            let points: Vec<ControlPoint> = gcps
                .iter()
                .flat_map(|(_, g)| g.iter())
                .map(|g| ControlPoint {
                    name: g.name.clone(),
                    sfm: g.sfm,
                    ground: g.ground,
                })
                .collect();
            // The borrowed form of `Stage::run` (no copy of the merged cloud).
            let out = AlignSfm::default()
                .align(&ctx.cx, &mesh, laser_points, &points)
                .map_err(|e| match &gcps {
                    Some((p, _)) => StageError::new(
                        e.stage,
                        format!(
                            "reconstruction {:?}, control points {}: {}",
                            r.name,
                            p.display(),
                            e.message
                        ),
                    ),
                    None => e,
                })?;
            ctx.lap(AlignSfm::NAME);
            aligned.push(AlignedRecon { mesh, out, gcps });
        }
        all.push(aligned);
    }
    Ok(all)
}

/// A reconstruction terrain from its aligned reconstructions ([`align_reconstructions`]):
/// rasterise each aligned mesh (its vertex colours as the texture) at every requested cell
/// size, and drape it on a laser terrain's rasters when asked.
#[allow(clippy::too_many_arguments)]
fn sfm_terrain(
    ctx: &mut Ctx<'_>,
    c: &Campaign,
    t: &Terrain,
    recons: &[usize],
    aligned: Vec<AlignedRecon>,
    laser_rasters: &BTreeMap<String, Vec<Raster>>,
    opts: &CompileOptions,
    dem_out: &mut Vec<Value>,
) -> Result<Value, CompileError> {
    let mut reports = serde_json::Map::new();
    let names = recons
        .iter()
        .filter_map(|&i| c.reconstructions.get(i))
        .map(|r| &r.name);
    for (name, a) in names.zip(aligned) {
        let AlignedRecon { mesh, out, gcps } = a;
        ctx.record(&AlignSfm::default());
        // Vertex colours are read as linear albedo (grey / 255, Rec. 601 luma for RGB), the
        // convention of the laser texture (SPEC §5.2); no sRGB decoding.
        let colour: Option<Vec<f32>> = mesh.colors.as_ref().map(|cs| {
            cs.iter()
                .map(|c| {
                    (0.299 * f32::from(c[0]) + 0.587 * f32::from(c[1]) + 0.114 * f32::from(c[2]))
                        / 255.0
                })
                .collect()
        });
        let tin = Tin {
            vertices: mesh
                .positions
                .iter()
                .map(|p| out.similarity.apply(*p))
                .collect(),
            albedo: colour,
            triangles: mesh.triangles,
            duplicates_merged: 0,
            max_edge_m: None,
        };
        let raster = DemRaster::new(
            t.raster_m.clone(),
            t.bounds_m,
            MaxEdge::SpacingFactor(4.0),
            -0.1,
            1 << 28,
        )?
        .with_regression(Some(DEM_REGRESSION_SPACINGS));
        encode_rasters(
            ctx,
            &t.name,
            &raster.rasterize_all(&tin)?,
            (t.texture == Texture::VertexColor).then_some("vertex-color"),
            opts.lods,
            Some(dem_out),
        )?;
        if let Some(target) = &t.drape_on {
            drape(ctx, t, target, &tin, laser_rasters, opts)?;
        }
        ctx.lap("encode.terrain");
        let mut row = json!({
            "scale": out.similarity.scale,
            "rms_m": out.report.icp.as_ref().map(|i| i.rms_nearest_m),
            "report": out.report,
        });
        // Only GCP alignments add fields, so a laser alignment's report bytes stay as they were.
        if let (Some((p, g)), Some(cr)) = (&gcps, &out.report.control) {
            row["method"] = json!(out.report.method);
            row["gcp_file"] = json!(p.to_string_lossy().replace('\\', "/"));
            row["gcp_rms_m"] = json!(cr.rms_m);
            row["gcp_residuals_m"] = json!(cr
                .residuals_m
                .iter()
                .cloned()
                .collect::<BTreeMap<String, f64>>());
            row["control_points"] = json!(g
                .iter()
                .map(|g| json!({"name": g.name, "sfm": g.sfm, "ground_m": g.ground, "ground_from": g.ground_from.as_str()}))
                .collect::<Vec<_>>());
        }
        reports.insert(name.clone(), row);
    }
    Ok(Value::Object(reports))
}

/// `sfm-on-laser`: the reconstruction's vertex colours on the laser geometry, the combination
/// the thesis recommended (laser heights are the more accurate, SfM colours the more faithful
/// albedo). Per raster step of the reconstruction terrain, the aligned reconstruction is
/// rasterised on exactly the laser raster's grid (its bounds and cell), and the laser raster is
/// encoded with that albedo as entry `<terrain>-on-<laser>/<cell>`: its height objects are the
/// laser entry's (same bytes, stored once), its texture and mesh carry the SfM colours.
fn drape(
    ctx: &mut Ctx<'_>,
    t: &Terrain,
    target: &str,
    tin: &Tin,
    laser_rasters: &BTreeMap<String, Vec<Raster>>,
    opts: &CompileOptions,
) -> Result<(), CompileError> {
    let err = |m: String| -> CompileError { StageError::new(DemRaster::NAME, m).into() };
    let rasters = laser_rasters.get(target).ok_or_else(|| {
        err(format!(
            "terrain {:?}: drape_on {target:?} was not built",
            t.name
        ))
    })?;
    let mut draped = Vec::new();
    for &cell in &t.raster_m {
        let laser = rasters.iter().find(|r| r.cell_m == cell).ok_or_else(|| {
            err(format!(
                "terrain {target:?} has no {cell} m raster to drape on"
            ))
        })?;
        let on_grid = DemRaster::new(
            vec![cell],
            Some(laser.bounds),
            MaxEdge::SpacingFactor(4.0),
            -0.1,
            1 << 28,
        )?
        .with_regression(Some(DEM_REGRESSION_SPACINGS))
        .rasterize_all(tin)?
        .pop()
        .ok_or_else(|| err("no raster".into()))?;
        if (on_grid.rows, on_grid.cols, on_grid.origin) != (laser.rows, laser.cols, laser.origin) {
            return Err(err(format!(
                "the draped grid {}x{} differs from the laser grid {}x{}",
                on_grid.cols, on_grid.rows, laser.cols, laser.rows
            )));
        }
        draped.push(Raster {
            albedo: on_grid.albedo,
            ..laser.clone()
        });
    }
    encode_rasters(
        ctx,
        &format!("{}-on-{target}", t.name),
        &draped,
        Some("sfm-on-laser"),
        opts.lods,
        None,
    )
}

/// Encodes a terrain's rasters (entries `<terrain>/<cell>`) and stores them: see
/// [`encode_all`] and [`store_rasters`].
fn encode_rasters(
    ctx: &mut Ctx<'_>,
    terrain: &str,
    rasters: &[Raster],
    texture: Option<&str>,
    lods: u32,
    dem_out: Option<&mut Vec<Value>>,
) -> Result<(), CompileError> {
    let encoded = encode_all(terrain, rasters, texture, lods)?;
    store_rasters(ctx, terrain, rasters, encoded, texture, dem_out)
}

/// Encodes a terrain's rasters in parallel (pure: no store access), returned in raster order.
/// `texture`: the content of the texture made from each raster's albedo (none: no texture).
fn encode_all(
    terrain: &str,
    rasters: &[Raster],
    texture: Option<&str>,
    lods: u32,
) -> Result<Vec<terrain::EncodedTerrain>, CompileError> {
    // Largest raster first, one task each: the finest grid's LOD chain is the longest single
    // piece of work, so it starts at once while the other rasters share the other threads.
    let mut order: Vec<usize> = (0..rasters.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(rasters.get(i).map_or(0, |r| r.rows * r.cols)));
    let by_size = order
        .par_iter()
        .with_max_len(1)
        .filter_map(|&i| rasters.get(i))
        .map(|r| {
            let png = match texture {
                Some(_) => albedo_png(r)?,
                None => None,
            };
            let grid = heightfield::GridInput {
                origin_m: r.origin,
                cell_m: r.cell_m,
                width: r.cols as u32,
                height: r.rows as u32,
                heights: &r.heights,
                site_origin_m: [0.0; 3],
                source: terrain,
            };
            Ok(terrain::encode(&grid, png, lods)?)
        })
        .collect::<Result<Vec<_>, CompileError>>()?;
    let mut encoded: Vec<Option<terrain::EncodedTerrain>> = rasters.iter().map(|_| None).collect();
    for (&i, e) in order.iter().zip(by_size) {
        if let Some(slot) = encoded.get_mut(i) {
            *slot = Some(e);
        }
    }
    Ok(encoded.into_iter().flatten().collect())
}

/// Entry name of a terrain's raster: `<terrain>/<cell>`.
fn raster_entry(terrain: &str, r: &Raster) -> String {
    format!("{terrain}/{}", cell_label(r.cell_m))
}

/// Stores encoded rasters in raster order, so entries and bytes do not depend on the thread
/// count, and appends each raster's statistics row to `dem_out`.
fn store_rasters(
    ctx: &mut Ctx<'_>,
    terrain: &str,
    rasters: &[Raster],
    encoded: Vec<terrain::EncodedTerrain>,
    texture: Option<&str>,
    mut dem_out: Option<&mut Vec<Value>>,
) -> Result<(), CompileError> {
    for (r, enc) in rasters.iter().zip(encoded) {
        let name = raster_entry(terrain, r);
        store_raster(ctx, &name, enc, texture.unwrap_or_default())?;
        if let Some(rows) = dem_out.as_deref_mut() {
            rows.push(dem_row(&name, r));
        }
    }
    Ok(())
}

/// Stores one encoded raster as its heightfield entry `name`, texture entry `<name>/texture`
/// (of `content`) and mesh entry `<name>/mesh`.
fn store_raster(
    ctx: &mut Ctx<'_>,
    name: &str,
    enc: terrain::EncodedTerrain,
    content: &str,
) -> Result<(), CompileError> {
    let hf = &enc.heightfield;
    let bounds = hf.meta.bounds();
    let tile = |files: BTreeMap<String, FileRef>| {
        vec![Tile {
            level: 0,
            x: 0,
            y: 0,
            bounds_m: bounds,
            files,
        }]
    };
    let files: BTreeMap<String, FileRef> = [
        (
            roles::HEIGHT.to_string(),
            ctx.put(&hf.height_png, media::PNG)?,
        ),
        (
            roles::HEIGHT_F32.to_string(),
            ctx.put(&hf.height_exr, media::EXR)?,
        ),
        (roles::MASK.to_string(), ctx.put(&hf.mask_png, media::PNG)?),
    ]
    .into();
    ctx.entries.push(Entry {
        name: name.into(),
        kind: kinds::HEIGHTFIELD.into(),
        meta: serde_json::to_value(&hf.meta)
            .map_err(|e| StageError::new("encode.heightfield", e.to_string()))?,
        files: BTreeMap::new(),
        tiles: tile(files),
    });
    let texture_entry = format!("{name}/texture");
    if let Some(png_bytes) = &enc.texture {
        let meta = TextureMeta {
            grid_of: name.into(),
            content: content.into(),
            pixels_per_cell: 1,
            bit_depth: 8,
        };
        let f = ctx.put(png_bytes, media::PNG)?;
        ctx.entries.push(Entry {
            name: texture_entry.clone(),
            kind: kinds::TEXTURE.into(),
            meta: json!(meta),
            files: BTreeMap::new(),
            tiles: tile([(roles::IMAGE.to_string(), f)].into()),
        });
    }
    let mut lod_meta = Vec::new();
    let mut lod_files = BTreeMap::new();
    for (n, (glb_bytes, meta)) in enc.lods.into_iter().enumerate() {
        lod_files.insert(roles::lod(n as u32), ctx.put(&glb_bytes, media::GLB)?);
        lod_meta.push(meta);
    }
    let meta = MeshMeta {
        frame: "ground".into(),
        local_origin_m: enc.local_origin_m,
        lods: lod_meta,
        texture: enc.texture.as_ref().map(|_| texture_entry),
    };
    ctx.entries.push(Entry {
        name: format!("{name}/mesh"),
        kind: kinds::MESH.into(),
        meta: json!(meta),
        files: BTreeMap::new(),
        tiles: tile(lod_files),
    });
    Ok(())
}

/// Bumped whenever the pipeline's output bytes change for the same inputs (a stage's version,
/// the entry layout, report contents), so the whole-compile cache never returns stale releases.
pub const PIPELINE_VERSION: u32 = 10;

fn cache_key(inputs: &[InputFile], opts: &CompileOptions) -> String {
    let v = json!({"compiler": env!("CARGO_PKG_VERSION"), "pipeline": PIPELINE_VERSION, "name": opts.name,
        "version": opts.version, "lods": opts.lods, "inputs": inputs});
    ObjectId::of_bytes(regolith_format::canonical_json::to_string(&v).as_bytes()).to_hex()
}

/// Compiles a campaign into a new release of the database `writer` holds. A compile that fails
/// leaves the database as it was: the objects it stored before failing are taken back
/// ([`Writer::roll_back`]).
pub fn compile(
    c: &Campaign,
    writer: &Writer,
    opts: &CompileOptions,
    progress: &dyn Fn(&str, f64),
) -> Result<CompileSummary, CompileError> {
    let result = compile_unchecked(c, writer, opts, progress);
    if result.is_err() {
        // Best effort: the compile's own error is the one to report.
        let _ = writer.roll_back();
    }
    result
}

/// Refuses early (before any work) a `name@version` already taken by a release of other inputs,
/// which the commit at the end would refuse anyway.
fn check_label_free(
    writer: &Writer,
    opts: &CompileOptions,
    inputs: &[InputFile],
) -> Result<(), CompileError> {
    let db = writer.database();
    let label = format!("{}@{}", opts.name, opts.version);
    let taken = |l: &str| -> Option<ObjectId> {
        db.read_ref(&format!(
            "{}{l}",
            regolith_reader::database::RELEASES_PREFIX
        ))
        .unwrap_or(None)
    };
    let Some(existing) = taken(&label) else {
        return Ok(());
    };
    let Ok(view) = db.release_by_id(&existing) else {
        return Ok(()); // unreadable: the commit will say what is wrong
    };
    let old = &view.manifest.campaign.inputs;
    if old.len() == inputs.len() && inputs.iter().all(|f| old.contains(f)) {
        return Ok(()); // the same inputs: the commit decides (same manifest, or another version)
    }
    let mut changed: Vec<&str> = inputs
        .iter()
        .filter(|f| !old.contains(f))
        .chain(
            old.iter()
                .filter(|f| !inputs.iter().any(|n| n.path == f.path)),
        )
        .map(|f| f.path.as_str())
        .collect();
    changed.sort_unstable();
    changed.dedup();
    let changed = if changed.is_empty() {
        "other inputs".to_string()
    } else if changed.len() > 5 {
        let first: Vec<&str> = changed.iter().take(5).copied().collect();
        format!(
            "changed: {} and {} more",
            first.join(", "),
            changed.len() - 5
        )
    } else {
        format!("changed: {}", changed.join(", "))
    };
    // The next free version: x.y.z → x.y.(z+1), anything else → <version>.1, .2, ...
    let bump = |v: &str, k: u64| -> String {
        match v.rsplit_once('.') {
            Some((head, last)) if last.parse::<u64>().is_ok() && head.split('.').count() == 2 => {
                format!("{head}.{}", last.parse::<u64>().unwrap_or(0) + k)
            }
            _ => format!("{v}.{k}"),
        }
    };
    let mut next = format!("{}@{}", opts.name, bump(&opts.version, 1));
    for k in 2..1000 {
        if taken(&next).is_none() {
            break;
        }
        next = format!("{}@{}", opts.name, bump(&opts.version, k));
    }
    Err(CompileError::ReleaseExists {
        label,
        id: existing.short(),
        changed,
        next,
    })
}

fn compile_unchecked(
    c: &Campaign,
    writer: &Writer,
    opts: &CompileOptions,
    progress: &dyn Fn(&str, f64),
) -> Result<CompileSummary, CompileError> {
    let start = Instant::now();
    progress("hashing inputs", 0.0);
    let inputs = hash_inputs(c)?;
    let key = cache_key(&inputs, opts);
    let db = writer.database();
    if let Some(id) = db.read_ref(&format!("cache/{key}"))? {
        if let Ok(view) = db.release_by_id(&id) {
            let id = writer.commit(view.manifest.clone(), true)?;
            let summary_body = view.report("reports/summary").unwrap_or(Value::Null);
            return Ok(CompileSummary {
                release: view.label(),
                id: id.to_hex(),
                entries: view.entries().iter().map(|e| e.name.clone()).collect(),
                registration: summary_body["registration"].clone(),
                alignment: summary_body["alignment"].clone(),
                dem: summary_body["dem"].as_array().cloned().unwrap_or_default(),
                warnings: summary_body["warnings"]
                    .as_array()
                    .cloned()
                    .unwrap_or_default(),
                cached: true,
                stage_seconds: vec![("cache".into(), start.elapsed().as_secs_f64())],
            });
        }
    }
    // Cheap checks first, so a mistake stops the compile before minutes of work.
    check_label_free(writer, opts, &inputs)?;
    crate::stages::captures::check_image_sizes(c)?;
    let mut ctx = Ctx {
        writer,
        cx: StageCx::default(),
        plan: Vec::new(),
        entries: Vec::new(),
        times: Vec::new(),
        // Hashing the inputs (and the cache lookup) is the first lap.
        clock: start,
    };
    ctx.lap("hash.inputs");
    progress("ground control", 0.05);
    let (markers, marker_report) = ground_control(c, &ctx.cx, &opts.limits)?;
    let control = gcp_control(c, &markers, &opts.limits)?;
    ctx.lap("ground.markers");
    let mut registration = Vec::new();
    let mut dem = Vec::new();
    let n_terrains = c.terrains.len().max(1) as f64;
    // Every laser terrain's rasters, by name (encoded below; reconstructions drape on them).
    let mut laser_rasters: BTreeMap<String, Vec<Raster>> = BTreeMap::new();
    let (lasers, recons): (Vec<&Terrain>, Vec<&Terrain>) = c
        .terrains
        .iter()
        .partition(|t| matches!(t.from, TerrainSource::Scans(_)));
    let mut aligned: Option<Vec<Vec<AlignedRecon>>> = None;
    for (k, t) in lasers.iter().enumerate() {
        progress(
            &format!("terrain {}", t.name),
            0.1 + 0.7 * k as f64 / n_terrains,
        );
        let TerrainSource::Scans(idx) = &t.from else {
            continue;
        };
        // The reconstructions are aligned onto the first laser terrain with points, as soon
        // as its points are merged, so the points need not outlive its TIN.
        let mut on_merged = |ctx: &mut Ctx<'_>, points: &[[f64; 3]]| {
            if aligned.is_none() && !points.is_empty() {
                aligned = Some(align_reconstructions(
                    ctx, c, &recons, points, &control, opts,
                )?);
            }
            Ok(())
        };
        let out = laser_terrain(
            &mut ctx,
            c,
            t,
            idx,
            &markers,
            opts,
            &mut dem,
            &mut on_merged,
        )?;
        registration.push(out.report);
        laser_rasters.insert(t.name.clone(), out.rasters);
    }
    let aligned = match aligned {
        Some(a) => a,
        None => align_reconstructions(&mut ctx, c, &recons, &[], &control, opts)?,
    };
    // The laser rasters are encoded (pure work; the finest grid's LOD chain holds one thread
    // for seconds) while this thread aligns the reconstructions and builds the captures; the
    // laser entries are then stored and put where a sequential compile puts them, before the
    // reconstructions', so the release does not depend on the overlap.
    let laser_texture = |t: &Terrain| (t.texture == Texture::Reflectance).then_some("reflectance");
    let mut encoded = None;
    let mark = ctx.entries.len();
    let rest = rayon::in_place_scope(|scope| {
        let (encoded, lasers, rasters) = (&mut encoded, &lasers, &laser_rasters);
        scope.spawn(move |_| {
            let all = lasers
                .iter()
                .map(|t| {
                    let r = rasters.get(&t.name).map_or(&[][..], Vec::as_slice);
                    encode_all(&t.name, r, laser_texture(t), opts.lods)
                })
                .collect::<Result<Vec<_>, CompileError>>();
            *encoded = Some(all);
        });
        let mut alignment = serde_json::Map::new();
        for (k, (t, a)) in recons.iter().zip(aligned).enumerate() {
            progress(
                &format!("terrain {}", t.name),
                0.1 + 0.7 * (lasers.len() + k) as f64 / n_terrains,
            );
            let TerrainSource::Reconstructions(idx) = &t.from else {
                continue;
            };
            if let Value::Object(m) =
                sfm_terrain(&mut ctx, c, t, idx, a, &laser_rasters, opts, &mut dem)?
            {
                alignment.extend(m);
            }
        }
        progress("captures", 0.85);
        let caps = BuildCaptures {
            limits: opts.limits,
        };
        let out = caps.run(&ctx.cx, c)?;
        ctx.record(&caps);
        ctx.lap(BuildCaptures::NAME);
        Ok::<_, CompileError>((alignment, out))
    });
    let (alignment, out) = rest?;
    let encoded =
        encoded.ok_or_else(|| StageError::new("encode.terrain", "encoding did not run"))??;
    let before = ctx.entries.len();
    for (t, enc) in lasers.iter().zip(encoded) {
        let rasters = laser_rasters.get(&t.name).map_or(&[][..], Vec::as_slice);
        store_rasters(&mut ctx, &t.name, rasters, enc, laser_texture(t), None)?;
    }
    let added = ctx.entries.len() - before;
    if let Some(tail) = ctx.entries.get_mut(mark..) {
        tail.rotate_right(added);
    }
    ctx.lap("encode.terrain");
    drop(laser_rasters);
    let alignment_full = Value::Object(alignment);
    let alignment: Value = alignment_full
        .as_object()
        .map(|m| {
            m.iter()
                .map(|(k, v)| {
                    let mut row = json!({"scale": v["scale"], "rms_m": v["rms_m"]});
                    if v.get("method").is_some() {
                        for key in ["method", "gcp_file", "gcp_rms_m", "gcp_residuals_m"] {
                            row[key] = v[key].clone();
                        }
                    }
                    (k.clone(), row)
                })
                .collect::<serde_json::Map<_, _>>()
        })
        .map(Value::Object)
        .unwrap_or_default();
    for cam in &out.cameras {
        let f = writer.put_json(&cam.model)?;
        ctx.entries.push(Entry {
            name: format!("cameras/{}", cam.name),
            kind: kinds::CAMERA.into(),
            meta: json!(CameraMeta {
                model: cam.model.clone()
            }),
            files: [(roles::CALIBRATION.to_string(), f)].into(),
            tiles: Vec::new(),
        });
    }
    if let Some(rig) = &out.rig {
        let mut rig = rig.clone();
        rig.left = format!("cameras/{}", rig.left);
        rig.right = format!("cameras/{}", rig.right);
        let f = writer.put_json(&rig)?;
        ctx.entries.push(Entry {
            name: "rig".into(),
            kind: kinds::RIG.into(),
            meta: json!(rig),
            files: [(roles::CALIBRATION.to_string(), f)].into(),
            tiles: Vec::new(),
        });
    }
    if !out.index.captures.is_empty() {
        let files = [
            (roles::MCAP.to_string(), writer.put(&out.mcap, media::MCAP)?),
            (roles::INDEX.to_string(), writer.put_json(&out.index)?),
        ]
        .into();
        ctx.entries.push(Entry {
            name: "captures".into(),
            kind: kinds::CAPTURES.into(),
            meta: json!({"captures": out.index.captures.len(), "lighting": c.lighting}),
            files,
            tiles: Vec::new(),
        });
    }
    progress("reports", 0.95);
    let warnings: Vec<Value> = ctx
        .cx
        .reporter
        .warnings()
        .iter()
        .map(|w| json!(w))
        .collect();
    let registration = json!(registration);
    ctx.report(
        "registration",
        "registration",
        &json!({"ground_markers": marker_report, "terrains": registration}),
    )?;
    ctx.report("dem", "dem", &json!(dem))?;
    ctx.report("captures", "captures", &out.report)?;
    if alignment_full.as_object().is_some_and(|m| !m.is_empty()) {
        ctx.report("alignment", "alignment", &alignment_full)?;
    }
    let summary_body = json!({"registration": registration, "alignment": alignment, "dem": dem, "warnings": warnings});
    ctx.report("summary", "summary", &summary_body)?;
    let mut rel: Release = new_release(
        &opts.name,
        &opts.version,
        Producer {
            name: "regolith-compiler".into(),
            version: env!("CARGO_PKG_VERSION").into(),
        },
    );
    rel.campaign = CampaignRef {
        name: c.name.clone(),
        inputs,
    };
    rel.plan = std::mem::take(&mut ctx.plan);
    rel.entries = std::mem::take(&mut ctx.entries);
    let entries: Vec<String> = {
        let mut v: Vec<String> = rel.entries.iter().map(|e| e.name.clone()).collect();
        v.sort();
        v
    };
    let label = rel.label();
    let id = writer.commit(rel, true)?;
    writer.set_ref(&format!("cache/{key}"), &id)?;
    ctx.lap("release.commit");
    progress("done", 1.0);
    Ok(CompileSummary {
        release: label,
        id: id.to_hex(),
        entries,
        registration: summary_body["registration"].clone(),
        alignment: summary_body["alignment"].clone(),
        dem: summary_body["dem"].as_array().cloned().unwrap_or_default(),
        warnings,
        cached: false,
        stage_seconds: ctx.times,
    })
}

/// Default options for a campaign: release `name@version`.
pub fn options(c: &Campaign, release: Option<&str>) -> CompileOptions {
    let (name, version) = match release.and_then(|r| r.split_once('@')) {
        Some((n, v)) => (n.to_string(), v.to_string()),
        None => (c.name.clone(), release.unwrap_or("1.0.0").to_string()),
    };
    CompileOptions {
        name,
        version,
        lods: 3,
        limits: regolith_format::limits::Limits::default(),
    }
}

/// Loads a campaign and compiles it (convenience for the CLI and tests).
pub fn compile_path(
    campaign: &Path,
    db: &Path,
    release: Option<&str>,
    progress: &dyn Fn(&str, f64),
) -> Result<CompileSummary, CompileError> {
    let c = crate::ingest::campaign::load(campaign)?;
    let writer = Writer::create_or_open(db)?;
    compile(&c, &writer, &options(&c, release), progress)
}

/// Support of the terrain rasters' local-regression height estimate, in median TIN edges (see
/// `stages::dem_regress`): about a dozen points per estimate at the usual scan density, which
/// divides the range noise by about 3; albedo keeps its own cell-sized support.
pub const DEM_REGRESSION_SPACINGS: f64 = 2.0;

/// The laser DEM's hole limit (`dem.raster`'s long-edge rule, and the longest TIN edge
/// `dem.tin` keeps): 0.1 m, about 10× the spacing of the thesis' 0.030° scans at 5–10 m range
/// and larger than every raster cell used.
pub const LASER_MAX_EDGE_M: f64 = 0.1;
