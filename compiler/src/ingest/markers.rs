//! Marker geometry: static ground markers, the rig's ball layout, and the rig pose per capture.
//!
//! * (a) [`static_markers`]: per marker mean position, per-axis standard deviation, 3D RMS and
//!   valid-frame count over a static Vicon trial; markers seen in fewer than `min_frames`
//!   frames are reported as [`MarkerWarning::FewFrames`] (house style 10: warnings go into the
//!   report, not the log) and left out.
//! * (b) [`parse_rig_markers`]: the rig geometry CSV `Name,X,Y,Z` (ball centres in the
//!   left-camera frame, metres; an optional header row).
//! * (c) [`fit_rig_pose`]: per frame, `ground_from_left` by the Umeyama/Horn SVD solution
//!   (rigid, no scale) over the balls matched by name, then a robust mean: frames whose
//!   translation or rotation lies beyond `max(3 * 1.4826 * MAD, floor)` of the median are
//!   rejected, the rest averaged (translations arithmetically, rotations by Markley's
//!   eigenvector quaternion mean). The spread (translation RMS in m, rotation RMS in deg) of
//!   the kept frames is returned so stages can judge the capture.
//!
//! Rotation helpers shared by the calibration readers (rotation vectors, orthonormality
//! checks) live here because this module already depends on `nalgebra`.

use std::path::Path;

use nalgebra::{Matrix3, Matrix4, UnitQuaternion, Vector3};
use regolith_format::frames::{quat_from_axis_angle, Pose};
use regolith_format::limits::Limits;

use super::types::{NamedPoint, Trajectories};
use super::yaml_lite;
use crate::error::{IngestError, Result};

/// Statistics of one static marker.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticMarker {
    /// Marker name (no subject prefix).
    pub name: String,
    /// Subject, if any.
    pub subject: Option<String>,
    /// Mean position, metres.
    pub mean: [f64; 3],
    /// Per-axis standard deviation, metres.
    pub std: [f64; 3],
    /// 3D RMS distance to the mean, metres.
    pub rms_3d: f64,
    /// Frames in which the marker was seen.
    pub frames: usize,
}

/// A partial failure worth reporting.
#[derive(Debug, Clone, PartialEq)]
pub enum MarkerWarning {
    /// A marker was seen in too few frames and was left out.
    FewFrames {
        /// Marker name.
        marker: String,
        /// Frames seen.
        frames: usize,
        /// Minimum required.
        min: usize,
    },
    /// A rig ball has no trajectory of the same name.
    BallNotTracked {
        /// Ball name.
        ball: String,
    },
}

/// Means of every marker with enough frames, plus warnings for the others.
pub fn static_markers(
    traj: &Trajectories,
    min_frames: usize,
) -> (Vec<StaticMarker>, Vec<MarkerWarning>) {
    let mut out = Vec::new();
    let mut warnings = Vec::new();
    for m in &traj.markers {
        let pts: Vec<[f64; 3]> = m.frames.iter().flatten().copied().collect();
        if pts.len() < min_frames.max(1) {
            warnings.push(MarkerWarning::FewFrames {
                marker: m.name.clone(),
                frames: pts.len(),
                min: min_frames,
            });
            continue;
        }
        let n = pts.len() as f64;
        let mean = [0, 1, 2].map(|a| pts.iter().map(|p| comp(p, a)).sum::<f64>() / n);
        let var = [0, 1, 2].map(|a| {
            pts.iter()
                .map(|p| (comp(p, a) - comp(&mean, a)).powi(2))
                .sum::<f64>()
                / n
        });
        out.push(StaticMarker {
            name: m.name.clone(),
            subject: m.subject.clone(),
            mean,
            std: var.map(f64::sqrt),
            rms_3d: (var[0] + var[1] + var[2]).sqrt(),
            frames: pts.len(),
        });
    }
    (out, warnings)
}

/// Reads the rig geometry CSV.
pub fn read_rig_markers(path: &Path, limits: &Limits) -> Result<Vec<NamedPoint>> {
    yaml_lite::read_with(path, limits, |b| parse_rig_markers(b, limits))
}

/// Parses `Name,X,Y,Z` rows (metres); blank lines and `#` comments are skipped, and a first
/// row whose coordinates are not numbers is taken as the header.
pub fn parse_rig_markers(bytes: &[u8], limits: &Limits) -> Result<Vec<NamedPoint>> {
    Limits::check_len(
        "rig marker bytes",
        bytes.len() as u64,
        limits.max_object_bytes,
    )?;
    let text = yaml_lite::decode_text(bytes)?;
    let mut out: Vec<NamedPoint> = Vec::new();
    let mut seen_row = false;
    for (i, line) in text.lines().enumerate() {
        let no = i as u64 + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = line.split([',', ';', '\t']).map(str::trim).collect();
        let first_row = !seen_row;
        seen_row = true;
        let [name, x, y, z] = cells.as_slice() else {
            return Err(IngestError::syntax("4 columns: Name,X,Y,Z", line).at_line(no));
        };
        let xyz = [x, y, z].map(|c| yaml_lite::parse_number(c));
        let [Some(x), Some(y), Some(z)] = xyz else {
            if first_row {
                continue;
            }
            let bad = [x, y, z]
                .into_iter()
                .zip(xyz)
                .find(|(_, v)| v.is_none())
                .map_or("", |(c, _)| *c);
            return Err(IngestError::syntax("a number (metres)", bad).at_line(no));
        };
        if name.is_empty() || out.iter().any(|p| p.name == *name) {
            return Err(
                IngestError::invalid(format!("ball name {name:?} is empty or repeated"))
                    .at_line(no),
            );
        }
        out.push(NamedPoint {
            name: name.to_string(),
            xyz: [x, y, z],
        });
    }
    if out.len() < 3 {
        return Err(IngestError::invalid(format!(
            "the rig needs at least 3 balls, found {}",
            out.len()
        )));
    }
    Ok(out)
}

/// Least-squares rigid transform `dst ≈ R src + t` (Umeyama without scale). Needs ≥ 3
/// non-collinear pairs; returns the pose and the RMS residual in the units of the inputs.
pub fn fit_rigid(src: &[[f64; 3]], dst: &[[f64; 3]]) -> Result<(Pose, f64)> {
    if src.len() != dst.len() || src.len() < 3 {
        return Err(IngestError::invalid(format!(
            "rigid fit needs ≥ 3 point pairs, got {}",
            src.len().min(dst.len())
        )));
    }
    let v = |p: &[f64; 3]| Vector3::new(p[0], p[1], p[2]);
    let n = src.len() as f64;
    let cs = src.iter().map(v).sum::<Vector3<f64>>() / n;
    let cd = dst.iter().map(v).sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (s, d) in src.iter().zip(dst) {
        h += (v(d) - cd) * (v(s) - cs).transpose();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(IngestError::invalid("rigid fit: SVD failed"));
    };
    let mut sv: Vec<f64> = svd.singular_values.iter().copied().collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    if sv.get(1).copied().unwrap_or(0.0) <= 1e-12 * sv.first().copied().unwrap_or(0.0).max(1e-300) {
        return Err(IngestError::invalid("rigid fit: the points are collinear"));
    }
    let d = (u * vt).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt;
    let t = cd - r * cs;
    let rows = [0, 1, 2].map(|i| [0, 1, 2].map(|j| r.get((i, j)).copied().unwrap_or(0.0)));
    let pose = Pose::from_matrix(rows, [t.x, t.y, t.z]);
    let sq: f64 = src
        .iter()
        .zip(dst)
        .map(|(s, d)| (r * v(s) + t - v(d)).norm_squared())
        .sum();
    Ok((pose, (sq / n).sqrt()))
}

/// A robust mean pose and its spread.
#[derive(Debug, Clone, PartialEq)]
pub struct RigPose {
    /// Mean `ground_from_left`.
    pub ground_from_left: Pose,
    /// RMS distance of the kept frames' translations to the mean, metres.
    pub translation_rms_m: f64,
    /// RMS rotation angle of the kept frames to the mean, degrees.
    pub rotation_rms_deg: f64,
    /// Frames averaged.
    pub frames_used: usize,
    /// Frames rejected as outliers.
    pub frames_rejected: usize,
    /// Mean per-frame fit residual (ball RMS), metres.
    pub fit_rms_m: f64,
    /// Warnings (untracked balls).
    pub warnings: Vec<MarkerWarning>,
}

/// Fits `ground_from_left` in every frame where ≥ 3 balls are seen, then robustly averages.
pub fn fit_rig_pose(rig: &[NamedPoint], traj: &Trajectories) -> Result<RigPose> {
    let mut warnings = Vec::new();
    let mut tracks = Vec::new();
    for ball in rig {
        match traj.markers.iter().find(|m| m.name == ball.name) {
            Some(m) => tracks.push((ball.xyz, m)),
            None => warnings.push(MarkerWarning::BallNotTracked {
                ball: ball.name.clone(),
            }),
        }
    }
    let frames = tracks
        .iter()
        .map(|(_, m)| m.frames.len())
        .max()
        .unwrap_or(0);
    let mut fits = Vec::new();
    for f in 0..frames {
        let (src, dst): (Vec<[f64; 3]>, Vec<[f64; 3]>) = tracks
            .iter()
            .filter_map(|(b, m)| m.frames.get(f).copied().flatten().map(|p| (*b, p)))
            .unzip();
        if src.len() >= 3 {
            if let Ok(fit) = fit_rigid(&src, &dst) {
                fits.push(fit);
            }
        }
    }
    if fits.is_empty() {
        let names = |v: Vec<&str>| v.join(", ");
        let rig_names = names(rig.iter().map(|b| b.name.as_str()).collect());
        if tracks.len() < 3 {
            let labels: Vec<String> = traj
                .markers
                .iter()
                .map(|m| match &m.subject {
                    Some(s) => format!("{s}:{}", m.name),
                    None => m.name.clone(),
                })
                .collect();
            let seen = names(labels.iter().map(String::as_str).collect());
            return Err(IngestError::invalid(format!(
                "{} of the rig balls ({rig_names}) are in the rig-pose file, whose markers are \
                 named {seen}; expected at least 3: name the balls in the Vicon file as in \
                 [rig].markers (matched on the part after `Subject:`)",
                tracks.len()
            )));
        }
        return Err(IngestError::invalid(format!(
            "no frame shows 3 or more of the rig balls ({rig_names}) at once; expected at least \
             3 in some frame: check the balls were tracked during the capture"
        )));
    }
    let fit_rms_m = fits.iter().map(|f| f.1).sum::<f64>() / fits.len() as f64;
    let poses: Vec<Pose> = fits.into_iter().map(|f| f.0).collect();
    let mut out = robust_mean_pose(&poses)?;
    out.fit_rms_m = fit_rms_m;
    out.warnings = warnings;
    Ok(out)
}

/// Component `i` of a small fixed array (0 outside it; keeps ingest code free of indexing).
fn comp<const N: usize>(v: &[f64; N], i: usize) -> f64 {
    v.get(i).copied().unwrap_or(0.0)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match (v.get(n / 2), n.checked_sub(1).and_then(|m| v.get(m / 2))) {
        (Some(a), Some(b)) => 0.5 * (a + b),
        _ => 0.0,
    }
}

/// Median-based outlier rejection, then the mean pose and its spread.
pub fn robust_mean_pose(poses: &[Pose]) -> Result<RigPose> {
    let first = poses
        .first()
        .ok_or_else(|| IngestError::invalid("no poses to average"))?;
    let med_t =
        [0, 1, 2].map(|a| median(poses.iter().map(|p| comp(&p.translation_m, a)).collect()));
    let med = Pose {
        translation_m: med_t,
        rotation_xyzw: median_quat(poses, first),
    };
    let dt: Vec<f64> = poses.iter().map(|p| p.distance_to_m(&med)).collect();
    let dr: Vec<f64> = poses.iter().map(|p| p.angle_to_deg(&med)).collect();
    let thr = |d: &[f64], floor: f64| (3.0 * 1.4826 * median(d.to_vec())).max(floor);
    let (tt, tr) = (thr(&dt, 1e-3), thr(&dr, 0.1));
    let kept: Vec<&Pose> = poses
        .iter()
        .zip(dt.iter().zip(&dr))
        .filter(|(_, (a, b))| **a <= tt && **b <= tr)
        .map(|(p, _)| p)
        .collect();
    let n = kept.len() as f64;
    let t = [0, 1, 2].map(|a| kept.iter().map(|p| comp(&p.translation_m, a)).sum::<f64>() / n);
    let mean = Pose {
        translation_m: t,
        rotation_xyzw: mean_quat(&kept, med.rotation_xyzw),
    };
    let rms =
        |f: &dyn Fn(&Pose) -> f64| (kept.iter().map(|p| f(p).powi(2)).sum::<f64>() / n).sqrt();
    Ok(RigPose {
        ground_from_left: mean,
        translation_rms_m: rms(&|p| p.distance_to_m(&mean)),
        rotation_rms_deg: rms(&|p| p.angle_to_deg(&mean)),
        frames_used: kept.len(),
        frames_rejected: poses.len() - kept.len(),
        fit_rms_m: 0.0,
        warnings: Vec::new(),
    })
}

/// Component-wise median of sign-aligned quaternions, normalised: a cheap robust centre.
fn median_quat(poses: &[Pose], reference: &Pose) -> [f64; 4] {
    let r = reference.rotation_xyzw;
    let aligned: Vec<[f64; 4]> = poses.iter().map(|p| align(p.rotation_xyzw, r)).collect();
    let q = [0, 1, 2, 3].map(|i| median(aligned.iter().map(|q| comp(q, i)).collect()));
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if n > 1e-9 {
        q.map(|v| v / n)
    } else {
        r
    }
}

fn align(q: [f64; 4], r: [f64; 4]) -> [f64; 4] {
    if q.iter().zip(&r).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
        q.map(|v| -v)
    } else {
        q
    }
}

/// Markley's average: the principal eigenvector of `Σ q qᵀ`.
fn mean_quat(poses: &[&Pose], fallback: [f64; 4]) -> [f64; 4] {
    let mut m = Matrix4::zeros();
    for p in poses {
        let q = nalgebra::Vector4::from(p.rotation_xyzw);
        m += q * q.transpose();
    }
    let eig = m.symmetric_eigen();
    let best = eig
        .eigenvalues
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i);
    match best {
        Some(i) => {
            let c = eig.eigenvectors.column(i);
            let q = align(
                [0, 1, 2, 3].map(|k| c.get(k).copied().unwrap_or(0.0)),
                fallback,
            );
            Pose {
                translation_m: [0.0; 3],
                rotation_xyzw: q,
            }
            .compose(&Pose::IDENTITY)
            .rotation_xyzw
        }
        None => fallback,
    }
}

/// A rotation matrix from 9 row-major values, if orthonormal with determinant +1 (tolerance 1e-3
/// for the 6-digit values calibration files print); re-orthonormalised.
pub(crate) fn rotation_from_rows(v: &[f64]) -> Option<[[f64; 3]; 3]> {
    let m = Matrix3::from_row_iterator(v.iter().copied().take(9));
    if v.len() != 9 || !v.iter().all(|x| x.is_finite()) {
        return None;
    }
    let err = (m * m.transpose() - Matrix3::identity()).abs().max();
    if err > 1e-3 || m.determinant() <= 0.0 {
        return None;
    }
    let q = UnitQuaternion::from_matrix(&m);
    let r = q.to_rotation_matrix();
    Some([0, 1, 2].map(|i| [0, 1, 2].map(|j| r[(i, j)])))
}

/// The rotation of a rotation (Rodrigues / helical) vector: axis × angle in radians.
pub(crate) fn rotation_from_vector(r: [f64; 3]) -> Option<[[f64; 3]; 3]> {
    if !r.iter().all(|v| v.is_finite()) {
        return None;
    }
    let angle = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    let q = quat_from_axis_angle(r, angle);
    Some(
        Pose {
            translation_m: [0.0; 3],
            rotation_xyzw: q,
        }
        .rotation_matrix(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ingest::types::MarkerTrack;
    use proptest::prelude::*;

    fn rig() -> Vec<NamedPoint> {
        [
            ("a", [0.1, 0.0, 0.02]),
            ("b", [-0.1, 0.03, 0.0]),
            ("c", [0.0, 0.12, -0.01]),
            ("d", [0.05, -0.08, 0.04]),
        ]
        .map(|(n, p)| NamedPoint {
            name: n.into(),
            xyz: p,
        })
        .to_vec()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn recovers_random_rigid_pose(axis in proptest::array::uniform3(-1.0..1.0f64), ang in -3.1..3.1f64,
                                      t in proptest::array::uniform3(-5.0..5.0f64),
                                      noise in proptest::collection::vec(-3e-4..3e-4f64, 40 * 4 * 3)) {
            let truth = Pose { translation_m: t, rotation_xyzw: quat_from_axis_angle(axis, ang) };
            let mut noise = noise.into_iter();
            let rig = rig();
            let mut markers: Vec<MarkerTrack> = rig.iter().map(|b| MarkerTrack { name: b.name.clone(), ..Default::default() }).collect();
            for f in 0..40 {
                for (m, b) in markers.iter_mut().zip(&rig) {
                    let p = truth.transform_point(b.xyz);
                    let noise = [0; 3].map(|_| noise.next().unwrap_or(0.0));
                    // Frame 7 is a gross outlier (a ball swap); the robust mean must reject it.
                    let off = if f == 7 { 0.05 } else { 0.0 };
                    m.frames.push(Some([p[0] + noise[0] + off, p[1] + noise[1], p[2] + noise[2]]));
                }
            }
            let traj = Trajectories { rate_hz: 100.0, first_frame: 1, markers };
            let est = fit_rig_pose(&rig, &traj).unwrap();
            prop_assert!(est.ground_from_left.distance_to_m(&truth) < 3e-4, "{est:?}");
            prop_assert!(est.ground_from_left.angle_to_deg(&truth) < 0.2, "{est:?}");
            prop_assert!(est.frames_rejected >= 1 && est.translation_rms_m < 1e-3);
        }
    }

    #[test]
    fn collinear_balls_are_an_error_and_few_frames_warn() {
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!(fit_rigid(&line, &line)
            .unwrap_err()
            .to_string()
            .contains("collinear"));
        let traj = Trajectories {
            rate_hz: 100.0,
            first_frame: 1,
            markers: vec![MarkerTrack {
                name: "m".into(),
                subject: None,
                frames: vec![Some([1.0, 2.0, 3.0]), None],
            }],
        };
        let (m, w) = static_markers(&traj, 2);
        assert!(m.is_empty());
        assert_eq!(
            w,
            vec![MarkerWarning::FewFrames {
                marker: "m".into(),
                frames: 1,
                min: 2
            }]
        );
    }

    #[test]
    fn rig_csv_header_and_errors() {
        let l = Limits::default();
        let r = parse_rig_markers(b"Name,X,Y,Z\nb1,0.1,0,0\nb2,0,0.1,0\nb3,0,0,0.1\n", &l).unwrap();
        assert_eq!(
            r[2],
            NamedPoint {
                name: "b3".into(),
                xyz: [0.0, 0.0, 0.1]
            }
        );
        let e = parse_rig_markers(b"b1,0.1,0,0\nb2,0,x,0\n", &l)
            .unwrap_err()
            .to_string();
        assert_eq!(e, "line 2: expected a number (metres), found \"x\"");
    }
}
