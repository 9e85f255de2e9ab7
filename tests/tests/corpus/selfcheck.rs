//! Self-checks of a generated mini campaign against its own truth (issue "Done when").

use super::common;

use common::*;
use regolith_validator::render::HeightfieldTracer;

/// Laser points mapped through their true SOCS → ground transform lie on the true surface:
/// the along-ray residual has the configured σ (8 mm) within 10 % and no bias.
#[test]
fn scans_lie_on_the_true_surface() {
    let dir = plain();
    let truth = json(dir, "truth/scans.json");
    let sigma = truth["range_noise_sigma_m"].as_f64().unwrap();
    assert_eq!(sigma, 0.008);
    let tracer = HeightfieldTracer::new(&height_grid(dir));
    let scans = truth["scans"].as_array().unwrap();
    assert_eq!(scans.len(), 2);
    let (mut sum, mut sum2, mut n, mut outliers) = (0.0, 0.0, 0usize, 0usize);
    for s in scans {
        let pose = pose(&s["ground_from_socs"]);
        let pts = asc(&dir.join(s["file"].as_str().unwrap()));
        assert_eq!(pts.len() as u64, s["points"].as_u64().unwrap());
        assert!(pts.len() > 5000, "{} points", pts.len());
        let o = pose.translation_m;
        for p in &pts {
            let g = pose.transform_point([p[0], p[1], p[2]]);
            let d = [g[0] - o[0], g[1] - o[1], g[2] - o[2]];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let dir = [d[0] / r, d[1] / r, d[2] / r];
            // Re-traced through the 0.1 mm-rounded point, a ray grazing a silhouette may pass
            // the edge or hit the other side: count those as outliers (must be rare).
            let Some(hit) = tracer.trace(o, dir, 50.0) else {
                outliers += 1;
                continue;
            };
            let e = r - hit.t;
            if e.abs() > 5.0 * sigma {
                outliers += 1;
                continue;
            }
            sum += e;
            sum2 += e * e;
            n += 1;
            assert!((-30.0..=5.0).contains(&p[3]), "reflectance {} dB", p[3]);
        }
    }
    assert!(outliers * 200 < n, "{outliers} silhouette outliers of {n}");
    let mean = sum / n as f64;
    let rms = (sum2 / n as f64).sqrt();
    assert!(
        (rms - sigma).abs() <= 0.1 * sigma,
        "rms {rms} vs sigma {sigma}"
    );
    assert!(mean.abs() < 0.1 * sigma, "bias {mean}");
}

/// Every tie point maps (true transform) to within 1 cm of its true ball centre, and that
/// ball is the first surface on the scanner's line of sight; markers.json matches Vicon.
#[test]
fn tiepoints_name_visible_markers() {
    let dir = plain();
    let tracer = HeightfieldTracer::new(&height_grid(dir));
    let markers = json(dir, "truth/markers.json");
    let centre = |name: &str| -> [f64; 3] {
        let m = markers
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["name"] == name)
            .unwrap();
        serde_json::from_value(m["centre_m"].clone()).unwrap()
    };
    let mut seen = 0;
    for s in json(dir, "truth/scans.json")["scans"].as_array().unwrap() {
        let pose = pose(&s["ground_from_socs"]);
        let tps = named_points(&dir.join(format!(
            "scans/{}_tiepoints.csv",
            s["name"].as_str().unwrap()
        )));
        assert!(tps.len() >= 3, "a scan needs 3 tie points to register");
        for (name, p) in tps {
            let g = pose.transform_point(p);
            let c = centre(&name);
            let err =
                ((g[0] - c[0]).powi(2) + (g[1] - c[1]).powi(2) + (g[2] - c[2]).powi(2)).sqrt();
            assert!(err < 0.01, "{name}: {err} m");
            let o = pose.translation_m;
            let d = [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let hit = tracer
                .trace(o, [d[0] / len, d[1] / len, d[2] / len], len + 1.0)
                .unwrap();
            assert!(
                hit.t > len - 0.02,
                "{name} occluded: hit at {} of {len}",
                hit.t
            );
            seen += 1;
        }
    }
    assert!(seen >= 6);
    // The Vicon static markers are the true centres (mm, 0.2 mm jitter).
    let text = std::fs::read_to_string(dir.join("vicon/markers.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let names: Vec<&str> = lines[4].split(',').filter(|s| !s.is_empty()).collect();
    assert_eq!(names.len(), 5);
    let row: Vec<&str> = lines[7..]
        .iter()
        .find(|l| !l.contains(",,"))
        .unwrap()
        .split(',')
        .collect();
    for (i, n) in names.iter().enumerate() {
        let c = centre(n.trim_start_matches("Testbed:"));
        for k in 0..3 {
            let v: f64 = row[2 + 3 * i + k].parse().unwrap();
            assert!(
                (v / 1000.0 - c[k]).abs() < 0.0015,
                "{n} axis {k}: {v} mm vs {}",
                c[k]
            );
        }
    }
}

/// Captures are neither black nor saturated, and the two frames of a pose differ by noise only.
#[test]
fn captures_are_exposed_and_noisy() {
    let dir = plain();
    for c in json(dir, "truth/captures.json").as_array().unwrap() {
        for side in ["left", "right"] {
            let files = c[side]["files"].as_array().unwrap();
            let (w, h, a) = grey(&dir.join(files[0].as_str().unwrap()));
            let (_, _, b) = grey(&dir.join(files[1].as_str().unwrap()));
            assert_eq!((w, h), (640, 512));
            let lit: Vec<u8> = a.iter().copied().filter(|&v| v > 0).collect();
            assert!(
                lit.len() > a.len() / 3,
                "terrain covers a third of the frame ({} px)",
                lit.len()
            );
            let mut sorted = lit.clone();
            sorted.sort_unstable();
            let median = sorted[sorted.len() / 2];
            assert!((30..=200).contains(&median), "median {median}");
            let saturated = a.iter().filter(|&&v| v == 255).count();
            assert!(saturated * 1000 < a.len(), "{saturated} saturated");
            let diff: f64 = a
                .iter()
                .zip(&b)
                .map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2))
                .sum::<f64>()
                / a.len() as f64;
            // Baseline noise: var = 0.05 * DN + 0.8^2 per frame, difference of two frames doubles it.
            assert!(
                diff > 0.5 && diff < 20.0,
                "frame difference variance {diff}"
            );
        }
    }
}

/// Intensity-weighted centroid of the bright blob nearest to `(u, v)`.
pub fn blob_centroid(w: usize, h: usize, img: &[u8], u: f64, v: f64, r: usize) -> (f64, f64) {
    let (cu, cv) = (u.round() as usize, v.round() as usize);
    let (x0, x1, y0, y1) = (
        cu.saturating_sub(r),
        (cu + r).min(w - 1),
        cv.saturating_sub(r),
        (cv + r).min(h - 1),
    );
    let mut vals: Vec<u8> = Vec::new();
    for y in y0..=y1 {
        for x in x0..=x1 {
            vals.push(img[y * w + x]);
        }
    }
    vals.sort_unstable();
    let bg = f64::from(vals[vals.len() / 2]);
    let peak = f64::from(vals[vals.len() - 1]);
    let thr = bg + 0.5 * (peak - bg);
    let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let val = f64::from(img[y * w + x]);
            if val > thr {
                sx += (val - bg) * x as f64;
                sy += (val - bg) * y as f64;
                sw += val - bg;
            }
        }
    }
    (sx / sw, sy / sw)
}

/// Projecting each capture's target marker with the true pose and camera lands on the bright
/// ball in the image (≤ 2 px).
#[test]
fn markers_appear_where_the_true_cameras_project_them() {
    let dir = plain();
    let markers = json(dir, "truth/markers.json");
    for c in json(dir, "truth/captures.json").as_array().unwrap() {
        let target = c["target_marker"].as_str().unwrap();
        let m = markers
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["name"] == target)
            .unwrap();
        let mut centre: [f64; 3] = serde_json::from_value(m["centre_m"].clone()).unwrap();
        // The heightfield holds the visible upper half of the ball: aim at the dome's centroid.
        centre[2] += 0.5 * m["radius_m"].as_f64().unwrap();
        for (side, cam) in [("left", "navcam_left"), ("right", "navcam_right")] {
            let camera = camera(dir, cam, "true");
            let p = pose(&c[side]["ground_from_camera"])
                .inverse()
                .transform_point(centre);
            let [u, v] = camera.project(p).unwrap();
            let (w, h, img) = grey(&dir.join(c[side]["files"][0].as_str().unwrap()));
            assert!(
                u > 10.0 && v > 10.0 && u < w as f64 - 10.0 && v < h as f64 - 10.0,
                "{u} {v}"
            );
            let (bu, bv) = blob_centroid(w, h, &img, u, v, 6);
            let err = ((bu - u).powi(2) + (bv - v).powi(2)).sqrt();
            assert!(
                err <= 2.0,
                "{} {side}: blob at ({bu:.1}, {bv:.1}), projected ({u:.1}, {v:.1})",
                c["name"]
            );
        }
    }
}

/// The campaign references every raw file it needs, each exists, and none lies in truth/.
#[test]
fn campaign_references_existing_raw_files_only() {
    let dir = plain();
    let text = std::fs::read_to_string(dir.join("campaign.toml")).unwrap();
    let doc: toml::Value = toml::from_str(&text).unwrap();
    assert_eq!(doc["schema"].as_str(), Some("regolith.campaign/1"));
    let light = json(dir, "truth/lighting.json");
    assert_eq!(
        doc["lighting"]["azimuth_deg"].as_float(),
        light["azimuth_deg"].as_f64()
    );
    assert_eq!(
        doc["lighting"]["elevation_deg"].as_float(),
        light["elevation_deg"].as_f64()
    );
    let mut refs = 0;
    for cell in text.split('"').skip(1).step_by(2) {
        if cell.contains('/') && !cell.starts_with("regolith.") {
            assert!(!cell.starts_with("truth/"), "{cell}");
            assert!(dir.join(cell).is_file(), "{cell} missing");
            refs += 1;
        }
    }
    // ground markers + 2 scans x (file, tiepoints) + sfm + 3 cameras + rig (markers, stereo)
    // + 2 captures x (4 frames + rig pose)
    assert_eq!(refs, 1 + 2 * 2 + 1 + 3 + 2 + 2 * 5);
}

/// The E57 and PLY copies hold the same points as the ASCII export.
#[test]
fn format_copies_match_the_ascii_scan() {
    let dir = plain();
    let pts = asc(&dir.join("scans/pos2.asc"));
    let ply = std::fs::read(dir.join("scans/pos2.ply")).unwrap();
    let end = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let body = &ply[end..];
    assert_eq!(body.len(), pts.len() * 16);
    for (i, p) in pts.iter().enumerate().step_by(97) {
        let x = f32::from_le_bytes(body[i * 16..i * 16 + 4].try_into().unwrap());
        assert!((f64::from(x) - p[0]).abs() < 1e-4);
    }
}

/// `sfm/mesh_gcp.csv` holds every Vicon marker, placed in the SfM frame: mapped back through the
/// true similarity each lies within a few mm of its true ball centre (the picking noise
/// `truth/gcp.json` records), and the noise has the documented size.
#[test]
fn gcp_file_places_the_vicon_markers_in_the_sfm_frame() {
    let dir = plain();
    let text = std::fs::read_to_string(dir.join("sfm/mesh_gcp.csv")).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows[0], ["Label", "X", "Y", "Z"]);
    let markers = json(dir, "truth/markers.json");
    let markers = markers.as_array().unwrap();
    assert_eq!(rows.len(), 1 + markers.len());
    let sfm = json(dir, "truth/sfm.json");
    let s = sfm["scale"].as_f64().unwrap();
    let r: Vec<Vec<f64>> = (0..3)
        .map(|i| {
            (0..3)
                .map(|j| sfm["rotation"][i][j].as_f64().unwrap())
                .collect()
        })
        .collect();
    let t: Vec<f64> = (0..3)
        .map(|i| sfm["translation"][i].as_f64().unwrap())
        .collect();
    let truth = json(dir, "truth/gcp.json");
    assert_eq!(truth["file"], "sfm/mesh_gcp.csv");
    let sigma = truth["picking_noise_sigma_m_per_axis"].as_f64().unwrap();
    assert_eq!(sigma, 0.0015);
    let mut sum2 = 0.0;
    for ((row, m), g) in rows[1..]
        .iter()
        .zip(markers)
        .zip(truth["points"].as_array().unwrap())
    {
        assert_eq!(row[0], m["name"].as_str().unwrap());
        assert_eq!(g["name"], m["name"]);
        let q: Vec<f64> = row[1..].iter().map(|v| v.parse().unwrap()).collect();
        // ground = Rᵀ (q − t) / s
        let d: Vec<f64> = (0..3).map(|i| q[i] - t[i]).collect();
        let back: Vec<f64> = (0..3)
            .map(|j| (0..3).map(|i| r[i][j] * d[i]).sum::<f64>() / s)
            .collect();
        let centre: Vec<f64> = (0..3).map(|k| m["centre_m"][k].as_f64().unwrap()).collect();
        let err: Vec<f64> = (0..3).map(|k| back[k] - centre[k]).collect();
        for k in 0..3 {
            let noise = g["noise_m"][k].as_f64().unwrap();
            // The file rounds to 1e-6 SfM units.
            assert!((err[k] - noise).abs() < 2e-6, "{} axis {k}", row[0]);
        }
        let e = err.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(e < 5.0 * sigma, "{}: {e} m", row[0]);
        sum2 += e * e;
    }
    let rms = (sum2 / markers.len() as f64).sqrt();
    println!(
        "GCP picking error over {} markers: 3D RMS {:.2} mm",
        markers.len(),
        rms * 1e3
    );
    assert!(rms > 0.0005 && rms < 0.006, "3D RMS {rms} m");
}
