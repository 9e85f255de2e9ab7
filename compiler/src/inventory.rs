//! `regolith compile --check`: parse every file a campaign references, with the reader its
//! format needs, and summarise what was found (counts, bounds, units, detected formats) without
//! writing anything. The loaders here ([`load_scan`], [`load_reconstruction`]) are the ones the
//! compile pipeline uses, so `--check` exercises exactly the code a compile will run.

use std::path::Path;

use rayon::prelude::*;
use regolith_format::limits::Limits;
use serde::Serialize;

use crate::error::{IngestError, Result};
use crate::ingest::campaign::{Align, Campaign, MeshFormat, Registration, Scan, ScanFormat};
use crate::ingest::types::{transform, PointCloud, TriMesh};
use crate::ingest::{
    calib_opencv, e57, gcp, images, las, markers, ply, ptx, riscan_ascii, sop_dat, tiepoints,
    vicon_csv, vrml,
};

/// Reads a scan in its scanner's own coordinates (SOCS). A file holding several scans (PTX,
/// E57) is merged after applying each scan's pose, so its points are in the file's frame.
pub fn load_scan(root: &Path, s: &Scan, limits: &Limits) -> Result<PointCloud> {
    let path = root.join(&s.file);
    let merge = |clouds: Vec<PointCloud>| -> PointCloud {
        if clouds.len() == 1 {
            return clouds.into_iter().next().unwrap_or_default();
        }
        let mut out = PointCloud::default();
        let all_refl = clouds.iter().all(|c| c.reflectance_db.is_some());
        let all_int = clouds.iter().all(|c| c.intensity.is_some());
        for c in clouds {
            let pose = c.pose;
            out.points.extend(
                c.points
                    .iter()
                    .map(|p| pose.map_or(*p, |m| transform(&m, *p))),
            );
            if all_refl {
                out.reflectance_db
                    .get_or_insert_with(Vec::new)
                    .extend(c.reflectance_db.unwrap_or_default());
            }
            if all_int {
                out.intensity
                    .get_or_insert_with(Vec::new)
                    .extend(c.intensity.unwrap_or_default());
            }
        }
        out
    };
    match s.format {
        ScanFormat::Ascii => {
            let cols = s.columns.as_ref().map(|c| c.join(" "));
            riscan_ascii::read_path(&path, cols.as_deref(), limits)
        }
        ScanFormat::Ptx => ptx::read_path(&path, limits).map(merge),
        ScanFormat::E57 => e57::read_path(&path, limits).map(merge),
        ScanFormat::Las => las::read_path(&path, limits),
        ScanFormat::Ply => ply::read_path(&path, limits),
    }
}

/// Reads a scan's tie points; errors name the scan (`[[scan]] "pos1" tiepoints: ...`).
pub fn load_tiepoints(
    root: &Path,
    s: &Scan,
    file: &Path,
    limits: &Limits,
) -> Result<Vec<crate::ingest::types::NamedPoint>> {
    tiepoints::read_path(&root.join(file), limits)
        .map_err(|e| e.context(format!("[[scan]] {:?} tiepoints", s.name)))
}

/// Reads a scan's SOP matrix; errors name the scan (`[[scan]] "pos1" sop: ...`).
pub fn load_sop(
    root: &Path,
    s: &Scan,
    file: &Path,
    limits: &Limits,
) -> Result<crate::ingest::types::Matrix4> {
    sop_dat::read_path(&root.join(file), limits)
        .map_err(|e| e.context(format!("[[scan]] {:?} sop", s.name)))
}

/// Reads a reconstruction mesh (VRML or PLY) in its own frame.
pub fn load_reconstruction(
    root: &Path,
    file: &Path,
    format: MeshFormat,
    limits: &Limits,
) -> Result<TriMesh> {
    let path = root.join(file);
    match format {
        MeshFormat::Vrml => vrml::read_path(&path, limits),
        MeshFormat::Ply => ply::read_mesh_path(&path, limits),
    }
}

/// Axis-aligned bounds of a point set.
pub fn bounds(points: &[[f64; 3]]) -> Option<[[f64; 3]; 2]> {
    let first = points.first()?;
    let mut b = [*first, *first];
    for p in points {
        for k in 0..3 {
            b[0][k] = b[0][k].min(p[k]);
            b[1][k] = b[1][k].max(p[k]);
        }
    }
    Some(b)
}

/// What one file holds.
#[derive(Debug, Clone, Serialize)]
pub struct FileSummary {
    /// Path relative to the campaign folder.
    pub path: String,
    /// What it is (`scan`, `tiepoints`, `markers`, `mesh`, `calibration`, `image`, ...).
    pub role: String,
    /// Detected format.
    pub format: String,
    /// Size in bytes.
    pub bytes: u64,
    /// Human summary: counts, bounds, units.
    pub summary: serde_json::Value,
}

/// The campaign inventory printed by `compile --check`.
#[derive(Debug, Clone, Serialize)]
pub struct Inventory {
    /// Campaign name.
    pub campaign: String,
    /// Counts by kind.
    pub counts: serde_json::Value,
    /// One row per referenced file, sorted by path.
    pub files: Vec<FileSummary>,
}

fn rel(p: &Path) -> String {
    p.to_string_lossy().replace('\\', "/")
}

fn cloud_summary(c: &PointCloud) -> serde_json::Value {
    serde_json::json!({
        "points": c.points.len(),
        "bounds_m": bounds(&c.points),
        "reflectance_db": c.reflectance_db.is_some(),
        "intensity": c.intensity.is_some(),
        "rgb": c.rgb.is_some(),
        "units": "m",
    })
}

/// One job of the inventory: a file, its role and how to summarise it.
type Job<'a> = (
    std::path::PathBuf,
    &'static str,
    String,
    Box<dyn Fn() -> Result<serde_json::Value> + Send + Sync + 'a>,
);

/// Parses every referenced file and summarises it. Stops at the first bad file, whose error
/// names the file and the place in it.
pub fn inventory(c: &Campaign, limits: &Limits) -> Result<Inventory> {
    let root = &c.root;
    let mut jobs: Vec<Job<'_>> = Vec::new();
    jobs.push((c.ground_markers.clone(), "ground-markers", "vicon-nexus-csv".into(), Box::new(move || {
        let t = vicon_csv::read_path(&root.join(&c.ground_markers), limits)?;
        let (m, warnings) = markers::static_markers(&t, 10);
        Ok(serde_json::json!({"markers": m.len(), "frames": t.markers.first().map_or(0, |m| m.frames.len()),
            "rate_hz": t.rate_hz, "first_frame": t.first_frame, "units": "mm in file, m after ingest",
            "warnings": warnings.len()}))
    })));
    for s in &c.scans {
        jobs.push((
            s.file.clone(),
            "scan",
            format!("{:?}", s.format).to_lowercase(),
            Box::new(move || Ok(cloud_summary(&load_scan(root, s, limits)?))),
        ));
        match &s.registration {
            Registration::Tiepoints(p) => jobs.push((p.clone(), "tiepoints", "csv".into(), Box::new(move || {
                let t = load_tiepoints(root, s, p, limits)?;
                Ok(serde_json::json!({"tiepoints": t.len(), "names": t.iter().map(|n| n.name.clone()).collect::<Vec<_>>()}))
            }))),
            Registration::Sop(p) => jobs.push((p.clone(), "sop", "riegl-dat".into(), Box::new(move || {
                Ok(serde_json::json!({"matrix": load_sop(root, s, p, limits)?}))
            }))),
        }
    }
    for r in &c.reconstructions {
        jobs.push((r.file.clone(), "reconstruction", format!("{:?}", r.format).to_lowercase(), Box::new(move || {
            let m = load_reconstruction(root, &r.file, r.format, limits)?;
            Ok(serde_json::json!({"vertices": m.positions.len(), "triangles": m.triangles.len(),
                "bounds": bounds(&m.positions), "colors": m.colors.is_some(), "uvs": m.uvs.is_some(),
                "texture": m.texture, "units": "arbitrary (similarity frame)"}))
        })));
        if let Align::Gcp(p) = &r.align {
            jobs.push((p.clone(), "gcp", "csv".into(), Box::new(move || {
                let g = gcp::read_path(&root.join(p), limits)?;
                Ok(serde_json::json!({"markers": g.len(), "with_ground": g.iter().filter(|m| m.ground.is_some()).count(),
                    "names": g.iter().map(|m| m.name.clone()).collect::<Vec<_>>(),
                    "units": "SfM frame (ground columns: m)"}))
            })));
        }
    }
    for cam in &c.cameras {
        jobs.push((
            cam.calibration.clone(),
            "calibration",
            "auto".into(),
            Box::new(move || {
                let m = calib_opencv::read_calibration_entry(
                    &root.join(&cam.calibration),
                    cam.entry.as_deref(),
                    &regolith_format::limits::Limits::default(),
                )?;
                serde_json::to_value(&m).map_err(|e| IngestError::invalid(e.to_string()))
            }),
        ));
    }
    if let Some(rig) = &c.rig {
        jobs.push((rig.markers.clone(), "rig-markers", "csv".into(), Box::new(move || {
            Ok(serde_json::json!({"balls": markers::read_rig_markers(&root.join(&rig.markers), limits)?.len(), "units": "m"}))
        })));
        jobs.push((rig.right_from_left.clone(), "stereo", "auto".into(), Box::new(move || {
            let p = calib_opencv::read_any_stereo(&root.join(&rig.right_from_left))?;
            Ok(serde_json::json!({"right_from_left": p, "baseline_m": p.distance_to_m(&regolith_format::frames::Pose::IDENTITY)}))
        })));
    }
    for cap in &c.captures {
        for img in cap.left.iter().chain(&cap.right) {
            jobs.push((img.clone(), "image", "image".into(), Box::new(move || {
                let g = images::read_path(&root.join(img), limits)?;
                Ok(serde_json::json!({"width": g.width, "height": g.height, "bit_depth": g.bit_depth}))
            })));
        }
        jobs.push((cap.rig_pose.clone(), "rig-pose", "vicon-nexus-csv".into(), Box::new(move || {
            let t = vicon_csv::read_path(&root.join(&cap.rig_pose), limits)?;
            Ok(serde_json::json!({"markers": t.markers.len(), "frames": t.markers.first().map_or(0, |m| m.frames.len())}))
        })));
    }
    let mut files: Vec<FileSummary> = jobs
        .par_iter()
        .map(|(path, role, format, f)| {
            let bytes = std::fs::metadata(root.join(path))
                .map(|m| m.len())
                .unwrap_or(0);
            Ok(FileSummary {
                path: rel(path),
                role: (*role).to_string(),
                format: format.clone(),
                bytes,
                summary: f()?,
            })
        })
        .collect::<Result<_>>()?;
    files.sort_by(|a, b| (&a.path, &a.role).cmp(&(&b.path, &b.role)));
    let counts = serde_json::json!({
        "scans": c.scans.len(), "reconstructions": c.reconstructions.len(), "cameras": c.cameras.len(),
        "captures": c.captures.len(), "terrains": c.terrains.len(),
        "points": files.iter().filter(|f| f.role == "scan").map(|f| f.summary["points"].as_u64().unwrap_or(0)).sum::<u64>(),
    });
    Ok(Inventory {
        campaign: c.name.clone(),
        counts,
        files,
    })
}
