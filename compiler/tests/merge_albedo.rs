//! `merge.clean`'s incidence correction against ground truth constructed here: a tilted plane of
//! known albedo scanned, noise-free, from two known scanner origins, with reflectance written as
//! the corpus's RIEGL writer does (minus its noise): `dB = 10·log10(albedo · cos i) − 0.05 dB/m ·
//! range`. The range term (an imperfect instrument range correction) is undone by the stage's
//! cross-scan calibration, which must find it from the overlap of the two scans alone.

#![allow(clippy::unwrap_used)]

use nalgebra::{Rotation3, Vector3};
use regolith_compiler::ingest::types::{transform, Matrix4, PointCloud};
use regolith_compiler::stage::{Stage, StageCx};
use regolith_compiler::stages::geometry::{compose, invert_rigid};
use regolith_compiler::stages::merge_clean::{MergeClean, MergeScan, MIN_COS_INCIDENCE};

const ALBEDO: f64 = 0.31;
/// Distance from each scanner to the plane, metres.
const HEIGHT_M: f64 = 1.0;

/// Unit normal of the plane: 30° from vertical.
fn plane_normal() -> Vector3<f64> {
    Rotation3::from_euler_angles(30f64.to_radians(), 0.0, 0.4) * Vector3::z()
}

/// One scan of the plane from `origin` (ground), polar ray pattern around the plane's
/// perpendicular out to 70° incidence, expressed in a rotated SOCS.
fn scan(name: &str, origin: Vector3<f64>, yaw: f64) -> MergeScan {
    let n = plane_normal();
    let u = n.cross(&Vector3::x()).normalize();
    let v = n.cross(&u);
    let ground_from_socs: Matrix4 = compose(
        &Rotation3::from_euler_angles(0.02, -0.01, yaw).into_inner(),
        &origin,
    );
    let socs_from_ground = invert_rigid(&ground_from_socs);
    let (mut points, mut db) = (Vec::new(), Vec::new());
    for ia in 0..=140 {
        let alpha = (f64::from(ia) * 0.5).to_radians();
        let steps = (f64::from(ia) * 4.0).max(1.0) as u32;
        for ib in 0..steps {
            let beta = std::f64::consts::TAU * f64::from(ib) / f64::from(steps);
            let dir = -n * alpha.cos() + (u * beta.cos() + v * beta.sin()) * alpha.sin();
            let range = HEIGHT_M / alpha.cos();
            let p = origin + dir * range;
            points.push(transform(&socs_from_ground, p.into()));
            db.push((10.0 * (ALBEDO * alpha.cos()).log10() - 0.05 * range) as f32);
        }
    }
    MergeScan {
        name: name.into(),
        cloud: PointCloud {
            points,
            reflectance_db: Some(db),
            ..PointCloud::default()
        },
        ground_from_socs,
    }
}

#[test]
fn incidence_correction_recovers_the_albedo_of_a_tilted_plane() {
    let n = plane_normal();
    let o1 = Vector3::new(0.2, -0.1, 0.3) + n * HEIGHT_M;
    let o2 = o1 + n.cross(&Vector3::y()).normalize() * 0.8;
    let scans = [scan("a", o1, 0.3), scan("b", o2, -1.1)];
    let merged = MergeClean::default()
        .run(&StageCx::default(), &scans)
        .unwrap();
    let albedo = merged.albedo.as_ref().unwrap();
    let rho = merged.reflectance.as_ref().unwrap();
    let origins = [o1, o2];
    // Worst relative error per 10° band of true incidence, 0–60°.
    let mut worst = [0.0f64; 6];
    let mut count = [0usize; 6];
    for (((p, &s), &a), &r) in merged.points.iter().zip(&merged.scan).zip(albedo).zip(rho) {
        let beam = origins[s as usize] - Vector3::from(*p);
        let incidence = (n.dot(&beam).abs() / beam.norm()).acos().to_degrees();
        let band = (incidence / 10.0) as usize;
        if incidence <= 60.0 {
            let band = band.min(5);
            worst[band] = worst[band].max((f64::from(a) / ALBEDO - 1.0).abs());
            count[band] += 1;
        } else {
            assert!(f64::from(a) <= f64::from(r) / MIN_COS_INCIDENCE * 1.0001);
        }
    }
    eprintln!("points per 10° band {count:?}, worst relative error {worst:.4?}");
    let cal = merged.radiometry.as_ref().unwrap();
    assert!(cal.slope_fitted, "{cal:?}");
    assert!((cal.range_slope_db_per_m + 0.05).abs() < 1e-3, "{cal:?}");
    assert!(
        cal.scan_offsets_db.iter().all(|c| c.offset_db.abs() < 0.01),
        "{cal:?}"
    );
    assert!(count.iter().all(|&c| c > 50), "{count:?}");
    // Noise-free points on a plane: the window normals are exact, and so is the albedo once
    // the range term is gone (it alone would cost up to 2.3 % at these ranges).
    assert!(worst.iter().all(|&w| w < 0.005), "{worst:?}");
    // Without the correction the 50–60° band would be off by ~40 %.
    let raw_worst = merged
        .points
        .iter()
        .zip(rho)
        .map(|(_, &r)| (f64::from(r) / ALBEDO - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(raw_worst > 0.4, "{raw_worst}");
}

#[test]
fn too_few_points_for_a_normal_keep_the_reflectance() {
    let s = MergeScan {
        name: "tiny".into(),
        cloud: PointCloud {
            points: vec![[1.0, 0.0, 0.0], [1.0, 0.1, 0.0]],
            reflectance_db: Some(vec![-3.0, -6.0]),
            ..PointCloud::default()
        },
        ground_from_socs: compose(&Rotation3::identity().into_inner(), &Vector3::zeros()),
    };
    let m = MergeClean::default()
        .run(&StageCx::default(), &[s])
        .unwrap();
    assert_eq!(m.albedo, m.reflectance);
    let empty = MergeClean::default().run(&StageCx::default(), &[]).unwrap();
    assert_eq!(empty.albedo, Some(Vec::new()));
}

/// A dense, noisy survey of flat ground of known albedo from two tripods 1.6 m high: points
/// 4 mm apart (as near a RIEGL station at the thesis' step), 8 mm range noise along the beam
/// (the instrument's), reflectance noise-free. The incidence correction must not turn range
/// noise into albedo noise: a normal from the 16 nearest points did (2.0 dB RMS here; the
/// ground window gives 0.12 dB).
#[test]
fn range_noise_does_not_become_albedo_noise() {
    use rand::{Rng, SeedableRng};
    let origins = [Vector3::new(-0.5, 1.0, 1.6), Vector3::new(2.5, 1.0, 1.6)];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let spacing = 0.004;
    let n = (2.0 / spacing) as usize;
    let mut scans: Vec<(Vec<[f64; 3]>, Vec<f32>)> = vec![(Vec::new(), Vec::new()); 2];
    for iy in 0..n {
        for ix in 0..n {
            let s = (ix + iy) % 2;
            let p = Vector3::new(ix as f64 * spacing, iy as f64 * spacing, 0.0);
            let beam = p - origins[s];
            let range = beam.norm();
            let cos = beam.z.abs() / range;
            // Gaussian-ish noise from the sum of four uniforms (σ = 8 mm).
            let noise: f64 =
                (0..4).map(|_| rng.gen::<f64>() - 0.5).sum::<f64>() * 0.008 / (1.0f64 / 3.0).sqrt();
            let q = origins[s] + beam / range * (range + noise);
            // Ground frame = SOCS shifted to the station (identity rotation).
            scans[s].0.push((q - origins[s]).into());
            scans[s].1.push((10.0 * (ALBEDO * cos).log10()) as f32);
        }
    }
    let merge_in: Vec<MergeScan> = scans
        .into_iter()
        .zip(origins)
        .enumerate()
        .map(|(i, ((points, db), o))| MergeScan {
            name: format!("s{i}"),
            cloud: PointCloud {
                points,
                reflectance_db: Some(db),
                ..PointCloud::default()
            },
            ground_from_socs: compose(&Rotation3::identity().into_inner(), &o),
        })
        .collect();
    let merged = MergeClean::default()
        .run(&StageCx::default(), &merge_in)
        .unwrap();
    let err_db: Vec<f64> = merged
        .albedo
        .as_ref()
        .unwrap()
        .iter()
        .map(|&a| 10.0 * (f64::from(a) / ALBEDO).log10())
        .collect();
    let rms = (err_db.iter().map(|e| e * e).sum::<f64>() / err_db.len() as f64).sqrt();
    eprintln!("{} points, albedo error {rms:.3} dB RMS", err_db.len());
    assert!(err_db.len() > 200_000);
    assert!(rms < 0.3, "albedo error {rms} dB RMS");
}

/// Points 20 cm off the plane are statistical outliers: the filter drops them (and the sparse
/// rim of the ray pattern), every kept point keeps its own reflectance and scan (the arrays are
/// filtered together, in place), in merge order, whether the stage borrows the scans or frees
/// them as it merges.
#[test]
fn outliers_are_dropped_with_their_values_and_scans_may_be_freed() {
    let mut scans = vec![
        scan("a", Vector3::new(0.0, 0.0, HEIGHT_M), 0.3),
        scan("b", Vector3::new(0.4, 0.1, HEIGHT_M), -1.1),
    ];
    let mut spikes = Vec::new();
    for s in &mut scans {
        let socs_from_ground = invert_rigid(&s.ground_from_socs);
        let n = s.cloud.points.len();
        for k in (n / 7..n / 2).step_by(n / 20) {
            let p = transform(&s.ground_from_socs, s.cloud.points[k]);
            let off = Vector3::from(p) + plane_normal() * 0.2;
            s.cloud.points[k] = transform(&socs_from_ground, off.into());
            spikes.push(off);
        }
    }
    let inputs: Vec<([f64; 3], f32, u32)> = scans
        .iter()
        .zip(0u32..)
        .flat_map(|(s, si)| {
            let db = s.cloud.reflectance_db.as_ref().unwrap();
            s.cloud
                .points
                .iter()
                .zip(db)
                .map(move |(p, &d)| (transform(&s.ground_from_socs, *p), d, si))
        })
        .collect();
    let cx = StageCx::default();
    let merged = MergeClean::default().run(&cx, &scans).unwrap();
    let kept = merged.points.len();
    assert_eq!(merged.stats.outliers_removed, inputs.len() - kept);
    assert!(kept > inputs.len() * 9 / 10, "{kept} of {}", inputs.len());
    let db = merged.reflectance_db.as_ref().unwrap();
    let mut next = inputs.iter();
    for ((p, d), si) in merged.points.iter().zip(db).zip(&merged.scan) {
        let found = next
            .find(|(q, _, _)| q == p)
            .expect("kept points in merge order");
        assert_eq!((found.1, found.2), (*d, *si));
        assert!(!spikes
            .iter()
            .any(|s| (Vector3::from(found.0) - s).norm() < 1e-9));
    }
    let owned = MergeClean::default()
        .merge_owned(&StageCx::default(), scans)
        .unwrap();
    assert_eq!(owned, merged);
}

/// Voxel thinning after the outlier filter keeps, per voxel of the merged cloud, the point
/// nearest the voxel's centre (brute force over the unthinned cleaned cloud), with its values.
#[test]
fn voxel_thinning_keeps_the_point_nearest_each_voxel_centre() {
    let scans = [
        scan("a", Vector3::new(0.0, 0.0, HEIGHT_M), 0.3),
        scan("b", Vector3::new(0.4, 0.1, HEIGHT_M), -1.1),
    ];
    let cx = StageCx::default();
    let voxel = 0.05;
    let clean = MergeClean::default().run(&cx, &scans).unwrap();
    let thin = MergeClean::new(8, 3.0, Some(voxel), 10.0)
        .unwrap()
        .run(&cx, &scans)
        .unwrap();
    let key = |p: &[f64; 3]| p.map(|v| (v / voxel).floor() as i64);
    let d2 = |p: &[f64; 3]| {
        let k = key(p);
        (0..3)
            .map(|a| (p[a] - (k[a] as f64 + 0.5) * voxel).powi(2))
            .sum::<f64>()
    };
    let mut best = std::collections::BTreeMap::new();
    for (i, p) in clean.points.iter().enumerate() {
        let e = best.entry(key(p)).or_insert(i);
        if d2(p) < d2(&clean.points[*e]) {
            *e = i;
        }
    }
    assert_eq!(thin.stats.outliers_removed, clean.stats.outliers_removed);
    assert_eq!(thin.stats.thinned, clean.points.len() - best.len());
    let db = clean.reflectance_db.as_ref().unwrap();
    let expected: Vec<([f64; 3], f32)> = best.values().map(|&i| (clean.points[i], db[i])).collect();
    let got: Vec<([f64; 3], f32)> = thin
        .points
        .iter()
        .copied()
        .zip(thin.reflectance_db.unwrap())
        .collect();
    assert_eq!(got, expected);
}
