//! Fixed test vectors with known answers for the matching metrics, so the numbers never drift
//! (the region metrics are in `region_overlap.rs`): descriptor matching (ratio test, cross
//! check, ties, planted near-copies found), the matching score on
//! keypoints where k of n matches are correct, RANSAC on correspondences generated from a
//! known F / H with 30 % outliers (inlier recovery, identical on 1 and 4 threads), degenerate
//! input, SIFT + RANSAC on a synthetic warp and on the real Curiosity NavCam stereo pair, and
//! property tests (scores are fractions).
//!
//! `REGOLITH_MATCHING_OUT=DIR cargo test -p regolith-validator --test matching navcam` also
//! writes the NavCam inputs as PNG, our SIFT keypoints/descriptors and our figures for
//! `tools/peers/matching_opencv.py`.

// Helpers outside `#[test]` functions unwrap known-good fixtures too.
#![allow(clippy::unwrap_used, clippy::panic)]

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use regolith_validator::features::synthetic::BlobScene;
use regolith_validator::features::{
    brute_force_match, sift::detect_and_describe_sift, GreyF32, Keypoint, SiftParams,
};
use regolith_validator::metrics::matching::{
    match_and_verify, match_descriptors, matching_score, sift_ransac, Match, MatchParams,
};
use regolith_validator::metrics::ransac::{
    fit_fundamental, ransac, sampson_distance, transfer_error, ModelKind, RansacParams,
};

type Mat3 = [[f64; 3]; 3];
type Points = Vec<[f64; 2]>;
/// One image of the NavCam export: 8-bit image, SIFT keypoints, descriptors.
type Side<'a> = (&'a image::GrayImage, &'a Vec<Keypoint>, &'a Vec<Vec<f32>>);

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

// ---------------------------------------------------------------- descriptor matching

fn random_descriptors(rng: &mut ChaCha8Rng, n: usize, dim: usize) -> Vec<Vec<f32>> {
    (0..n)
        .map(|_| (0..dim).map(|_| rng.gen_range(0.0f32..1.0)).collect())
        .collect()
}

#[test]
fn planted_copies_are_matched_and_cross_check_is_a_subset() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let a = random_descriptors(&mut rng, 300, 16);
    let mut b = random_descriptors(&mut rng, 250, 16);
    // Plant near-copies so the ratio test passes for some queries.
    for k in 0..100 {
        b[k] = a[2 * k].iter().map(|v| v + 0.01).collect();
    }
    let ours = match_descriptors(&a, &b, &MatchParams::default());
    let pairs: Vec<(usize, usize)> = ours.iter().map(|m| (m.a, m.b)).collect();
    // Every planted near-copy is found, and `features::brute_force_match` (the same matcher
    // without distances) agrees.
    for k in 0..100 {
        assert!(
            pairs.contains(&(2 * k, k)),
            "planted pair ({}, {k}) missing",
            2 * k
        );
    }
    assert_eq!(pairs, brute_force_match(&a, &b, 0.8));
    let mutual = match_descriptors(
        &a,
        &b,
        &MatchParams {
            mutual: true,
            ..MatchParams::default()
        },
    );
    assert!(mutual.iter().all(|m| ours.contains(m)));
    assert!(mutual.len() >= 100 && mutual.len() <= ours.len());
    // Each mutual match's B descriptor has its A query as nearest neighbour.
    for m in &mutual {
        let d = |i: usize| -> f32 {
            a[i].iter()
                .zip(&b[m.b])
                .map(|(x, y)| (x - y) * (x - y))
                .sum()
        };
        assert!((0..a.len()).all(|i| d(i) >= d(m.a)));
    }
}

#[test]
fn cross_check_known_answer() {
    let a = vec![vec![0.0, 0.0], vec![1.0, 0.0]];
    let b = vec![vec![0.9, 0.0], vec![5.0, 5.0]];
    let no_ratio = MatchParams {
        ratio: 1.0,
        mutual: false,
    };
    let m: Vec<(usize, usize)> = match_descriptors(&a, &b, &no_ratio)
        .iter()
        .map(|m| (m.a, m.b))
        .collect();
    assert_eq!(m, vec![(0, 0), (1, 0)]);
    let mutual = MatchParams {
        mutual: true,
        ..no_ratio
    };
    let m = match_descriptors(&a, &b, &mutual);
    assert_eq!(m.len(), 1);
    assert_eq!((m[0].a, m[0].b), (1, 0));
    assert!(close(f64::from(m[0].distance), 0.1, 1e-6));
    assert!(match_descriptors(&[], &b, &mutual).is_empty());
    assert!(match_descriptors(&a, &[], &mutual).is_empty());
}

#[test]
fn matching_is_identical_on_1_and_4_threads() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let a = random_descriptors(&mut rng, 700, 32);
    let b = random_descriptors(&mut rng, 600, 32);
    for mutual in [false, true] {
        let p = MatchParams {
            ratio: 0.95,
            mutual,
        };
        let one = pool(1).install(|| match_descriptors(&a, &b, &p));
        let four = pool(4).install(|| match_descriptors(&a, &b, &p));
        assert_eq!(one, four);
        assert!(!one.is_empty());
    }
}

/// `n_a = 10` keypoints in A, `n_b = 12` in B; every A descriptor's nearest neighbour is a
/// distinct B descriptor (a permutation), and the first `k` of those B keypoints sit where
/// A's keypoint maps to (within 0.5 px), the others 5 px away.
fn k_of_n(k: usize, shift: [f64; 2]) -> (Points, Points, Vec<Match>) {
    let (n_a, n_b) = (10usize, 12usize);
    let dim = 16;
    let one_hot =
        |i: usize, v: f32| -> Vec<f32> { (0..dim).map(|d| if d == i { v } else { 0.0 }).collect() };
    let a_pts: Vec<[f64; 2]> = (0..n_a).map(|i| [10.0 + 20.0 * i as f64, 30.0]).collect();
    let da: Vec<Vec<f32>> = (0..n_a).map(|i| one_hot(i, 10.0)).collect();
    // B index of A's i-th match: a fixed permutation.
    let perm = |i: usize| (i * 7 + 3) % n_a;
    let mut b_pts = vec![[0.0, 0.0]; n_b];
    let mut db = vec![Vec::new(); n_b];
    for i in 0..n_a {
        let off = if i < k { 0.5 } else { 5.0 };
        let q = a_pts[i];
        b_pts[perm(i)] = [q[0] + shift[0] + off, q[1] + shift[1]];
        db[perm(i)] = one_hot(i, 9.5);
    }
    for j in n_a..n_b {
        b_pts[j] = [500.0 + 10.0 * j as f64, 300.0];
        db[j] = one_hot(dim - 1 - (j - n_a), 10.0);
    }
    let m = match_descriptors(&da, &db, &MatchParams::default());
    assert_eq!(m.len(), n_a);
    (a_pts, b_pts, m)
}

#[test]
fn matching_score_counts_k_correct_of_n() {
    for k in [0, 1, 7, 10] {
        let (a, b, m) = k_of_n(k, [0.0, 0.0]);
        let s = matching_score(&a, &b, &m, Some, |_| true, 1.5);
        assert_eq!((s.n_a, s.n_b, s.matches, s.correct), (10, 12, 10, k));
        assert_eq!(s.score, k as f64 / 10.0);
        // Through a known mapping (B shifted by (3, −2)).
        let (a, b, m) = k_of_n(k, [3.0, -2.0]);
        let map = |p: [f64; 2]| Some([p[0] + 3.0, p[1] - 2.0]);
        assert_eq!(matching_score(&a, &b, &m, map, |_| true, 1.5).correct, k);
        // Without the mapping no match is correct.
        assert_eq!(matching_score(&a, &b, &m, Some, |_| true, 1.5).correct, 0);
    }
    // ε larger than the 5 px offset of the wrong matches: all 10 correct.
    let (a, b, m) = k_of_n(7, [0.0, 0.0]);
    assert_eq!(matching_score(&a, &b, &m, Some, |_| true, 6.0).score, 1.0);
    // Common region x < 100: A keypoints at x = 10, 30, 50, 70, 90 count.
    let s = matching_score(&a, &b, &m, Some, |p| p[0] < 100.0, 1.5);
    assert_eq!(s.n_a, 5);
    assert!(s.correct <= s.matches && s.matches <= s.n_a.min(s.n_b));
}

#[test]
fn matching_score_pairs_one_to_one_by_descriptor_distance() {
    let a = [[10.0, 10.0], [10.2, 10.0]];
    let b = [[10.0, 10.0]];
    let m = [
        Match {
            a: 0,
            b: 0,
            distance: 3.0,
        },
        Match {
            a: 1,
            b: 0,
            distance: 2.0,
        },
    ];
    let s = matching_score(&a, &b, &m, Some, |_| true, 1.0);
    assert_eq!((s.matches, s.correct, s.score), (1, 1, 1.0));
    // Out-of-range indices are ignored, never a panic.
    let bad = [Match {
        a: 9,
        b: 9,
        distance: 0.0,
    }];
    assert_eq!(matching_score(&a, &b, &bad, Some, |_| true, 1.0).matches, 0);
    assert_eq!(
        matching_score(&[], &[], &[], Some, |_| true, 1.0).score,
        0.0
    );
}

// ---------------------------------------------------------------- RANSAC

fn mul(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

fn rot(ax: f64, ay: f64) -> Mat3 {
    let (cx, sx, cy, sy) = (ax.cos(), ax.sin(), ay.cos(), ay.sin());
    // R = Ry · Rx
    [
        [cy, sy * sx, sy * cx],
        [0.0, cx, -sx],
        [-sy, cy * sx, cy * cx],
    ]
}

const W: f64 = 1280.0;
const H: f64 = 1024.0;

/// Correspondences of a two-view scene (f = 800 px, baseline 0.5 m, 5° / 2° rotation, depths
/// 4–12 m), noise ±0.25 px; indices with `i % 10 < 3` are outliers (uniform in B).
fn two_view(n: usize, seed: u64) -> (Points, Points, Vec<bool>, Points) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (f, cx, cy) = (800.0, 640.0, 512.0);
    let r = rot(2f64.to_radians(), 5f64.to_radians());
    let t = [-0.5, 0.05, 0.1];
    let (mut a, mut b, mut truth, mut clean) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    while a.len() < n {
        let (u, v, z) = (
            rng.gen_range(0.0..W),
            rng.gen_range(0.0..H),
            rng.gen_range(4.0..12.0),
        );
        let x = [(u - cx) / f * z, (v - cy) / f * z, z];
        let y = mul(&r, x);
        let y = [y[0] + t[0], y[1] + t[1], y[2] + t[2]];
        let (ub, vb) = (f * y[0] / y[2] + cx, f * y[1] / y[2] + cy);
        if !(0.0..W).contains(&ub) || !(0.0..H).contains(&vb) {
            continue;
        }
        let outlier = a.len() % 10 < 3;
        let mut noise = || rng.gen_range(-0.25..0.25);
        a.push([u + noise(), v + noise()]);
        clean.push([ub, vb]);
        if outlier {
            b.push([rng.gen_range(0.0..W), rng.gen_range(0.0..H)]);
        } else {
            b.push([ub + noise(), vb + noise()]);
        }
        truth.push(!outlier);
    }
    (a, b, truth, clean)
}

const H_TRUE: Mat3 = [[1.05, 0.08, 12.0], [-0.06, 0.98, -7.0], [2e-5, -1e-5, 1.0]];

fn apply_h(h: &Mat3, p: [f64; 2]) -> [f64; 2] {
    let v = mul(h, [p[0], p[1], 1.0]);
    [v[0] / v[2], v[1] / v[2]]
}

/// Correspondences under `H_TRUE` with noise ±0.5 px; `i % 10 < 3` are outliers.
fn planar(n: usize, seed: u64) -> (Points, Points, Vec<bool>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut a, mut b, mut truth) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let p = [rng.gen_range(0.0..W), rng.gen_range(0.0..H)];
        let outlier = i % 10 < 3;
        let q = if outlier {
            [rng.gen_range(0.0..W), rng.gen_range(0.0..H)]
        } else {
            let q = apply_h(&H_TRUE, p);
            [
                q[0] + rng.gen_range(-0.5..0.5),
                q[1] + rng.gen_range(-0.5..0.5),
            ]
        };
        a.push(p);
        b.push(q);
        truth.push(!outlier);
    }
    (a, b, truth)
}

/// (share of true inliers recovered, share of outliers accepted).
fn recovery(found: &[bool], truth: &[bool]) -> (f64, f64) {
    let tp = found.iter().zip(truth).filter(|(f, t)| **f && **t).count();
    let fp = found.iter().zip(truth).filter(|(f, t)| **f && !**t).count();
    let pos = truth.iter().filter(|t| **t).count();
    (
        tp as f64 / pos as f64,
        fp as f64 / (truth.len() - pos) as f64,
    )
}

#[test]
fn ransac_fundamental_recovers_the_inliers_of_a_known_geometry() {
    let (a, b, truth, clean) = two_view(400, 21);
    let p = RansacParams::fundamental();
    let one = pool(1).install(|| ransac(&a, &b, &p));
    let four = pool(4).install(|| ransac(&a, &b, &p));
    assert_eq!(one, four, "RANSAC differs between 1 and 4 threads");
    let (tp, fp) = recovery(&one.inliers, &truth);
    println!(
        "F: recovered {tp:.4}, accepted {fp:.4}, {} iterations",
        one.iterations
    );
    assert_eq!(one.model, ModelKind::Fundamental);
    assert!(tp >= 0.95, "recovered {tp:.3} of the inliers");
    assert!(fp <= 0.05, "accepted {fp:.3} of the outliers");
    // Adaptive: 70 % inliers and 8-point samples need ~80 iterations, far below the cap.
    assert!(
        one.iterations > 0 && one.iterations < 500,
        "{}",
        one.iterations
    );
    // The fitted F explains the noise-free geometry.
    let f = one.matrix.unwrap();
    let mut d: Vec<f64> = (0..a.len())
        .filter(|&i| truth[i])
        .map(|i| sampson_distance(&f, a[i], clean[i]))
        .collect();
    d.sort_by(f64::total_cmp);
    assert!(
        d[d.len() / 2] < 0.3,
        "median Sampson distance {}",
        d[d.len() / 2]
    );
    // Another seed finds the same inliers up to a few borderline points.
    let other = ransac(&a, &b, &RansacParams { seed: 99, ..p });
    let (tp2, _) = recovery(&other.inliers, &truth);
    assert!(tp2 >= 0.95);
}

#[test]
fn ransac_homography_recovers_the_inliers_and_the_matrix() {
    let (a, b, truth) = planar(300, 4);
    let p = RansacParams::homography();
    let one = pool(1).install(|| ransac(&a, &b, &p));
    let four = pool(4).install(|| ransac(&a, &b, &p));
    assert_eq!(one, four, "RANSAC differs between 1 and 4 threads");
    let (tp, fp) = recovery(&one.inliers, &truth);
    println!(
        "H: recovered {tp:.4}, accepted {fp:.4}, {} iterations",
        one.iterations
    );
    assert_eq!(one.model, ModelKind::Homography);
    assert!(tp >= 0.95, "recovered {tp:.3} of the inliers");
    assert!(fp <= 0.05, "accepted {fp:.3} of the outliers");
    assert!(
        one.iterations > 0 && one.iterations < 100,
        "{}",
        one.iterations
    );
    // Corners of the image land within 0.5 px of where H_TRUE puts them.
    let h = one.matrix.unwrap();
    for c in [[0.0, 0.0], [W, 0.0], [0.0, H], [W, H]] {
        let (p, q) = (apply_h(&h, c), apply_h(&H_TRUE, c));
        assert!(
            (p[0] - q[0]).hypot(p[1] - q[1]) < 0.5,
            "{c:?}: {p:?} vs {q:?}"
        );
        assert!(transfer_error(&h, c, q) < 0.5);
    }
}

#[test]
fn ransac_degenerate_input_gives_an_empty_fit() {
    let p = RansacParams::fundamental();
    let empty = ransac(&[], &[], &p);
    assert_eq!(
        (empty.inlier_count(), empty.iterations, empty.matrix),
        (0, 0, None)
    );
    // Seven matches: below the minimum.
    let (a, b, _, _) = two_view(7, 1);
    assert_eq!(ransac(&a, &b, &p).inlier_count(), 0);
    // Collinear points in one image.
    let line: Vec<[f64; 2]> = (0..50).map(|i| [i as f64, 2.0 * i as f64 + 1.0]).collect();
    let spread: Vec<[f64; 2]> = (0..50)
        .map(|i| [(i * 37 % 50) as f64, (i * 11 % 50) as f64])
        .collect();
    for p in [RansacParams::fundamental(), RansacParams::homography()] {
        let fit = ransac(&line, &spread, &p);
        assert_eq!((fit.inlier_count(), fit.matrix), (0, None));
        assert_eq!(ransac(&spread, &line, &p).inlier_count(), 0);
        // One point repeated; a NaN coordinate.
        let same = vec![[3.0, 4.0]; 20];
        assert_eq!(ransac(&same, &same, &p).inlier_count(), 0);
        let mut nan = spread.clone();
        nan[3] = [f64::NAN, 1.0];
        assert_eq!(ransac(&nan, &spread, &p).inlier_count(), 0);
    }
    // The least-squares fit itself refuses too few points.
    assert!(fit_fundamental(&spread, &spread, &[0, 1, 2]).is_none());
}

#[test]
fn match_report_of_degenerate_keypoints_is_zero() {
    let r = match_and_verify(
        &[],
        &[],
        &[],
        &[],
        &MatchParams::default(),
        &RansacParams::default(),
    );
    assert_eq!(
        (r.keypoints_a, r.matches, r.inliers, r.iterations),
        (0, 0, 0, 0)
    );
    assert_eq!(r.inlier_ratio, 0.0);
    // SIFT on a flat image finds nothing.
    let flat = GreyF32::zeros(64, 64);
    let r = sift_ransac(
        &flat,
        &flat,
        &SiftParams::default(),
        &MatchParams::default(),
        &RansacParams::homography(),
    );
    assert_eq!((r.keypoints_a, r.inliers), (0, 0));
    let broken = GreyF32 {
        width: 10,
        height: 10,
        data: vec![0.5; 3],
    };
    let r = sift_ransac(
        &broken,
        &flat,
        &SiftParams::default(),
        &MatchParams::default(),
        &RansacParams::default(),
    );
    assert_eq!(r.inliers, 0);
}

// ---------------------------------------------------------------- SIFT + RANSAC

#[test]
fn sift_ransac_on_a_synthetic_scene() {
    let scene = BlobScene::random(480, 360, 480 * 360 / 500, (3.0, 14.0), 17);
    let img = scene.render(480, 360, |x, y| (x, y));
    let sift = SiftParams::default();
    let m = MatchParams::default();
    // Same pose, same image: every match is an inlier of either model.
    for g in [RansacParams::fundamental(), RansacParams::homography()] {
        let r = sift_ransac(&img, &img, &sift, &m, &g);
        assert!(r.matches >= 100, "{r:?}");
        assert_eq!(r.inliers, r.matches, "{r:?}");
        assert_eq!(r.inlier_ratio, 1.0);
    }
    // B = A under a known homography (rendered exactly from the analytic scene).
    let h_inv = {
        let m = nalgebra::Matrix3::from_fn(|i, j| H_SMALL[i][j]);
        let i = m.try_inverse().unwrap();
        [
            [i[(0, 0)], i[(0, 1)], i[(0, 2)]],
            [i[(1, 0)], i[(1, 1)], i[(1, 2)]],
            [i[(2, 0)], i[(2, 1)], i[(2, 2)]],
        ]
    };
    let warped = scene.render(480, 360, |x, y| {
        let p = apply_h(&h_inv, [x, y]);
        (p[0], p[1])
    });
    let (ka, da) = detect_and_describe_sift(&img, &sift);
    let (kb, db) = detect_and_describe_sift(&warped, &sift);
    let g = RansacParams::homography();
    let one = pool(1).install(|| match_and_verify(&ka, &da, &kb, &db, &m, &g));
    let four = pool(4).install(|| sift_ransac(&img, &warped, &sift, &m, &g));
    assert_eq!(one, four);
    assert!(one.matches >= 100, "{one:?}");
    assert!(one.inlier_ratio >= 0.8, "{one:?}");
    // The matching score through the true homography agrees: most matches are correct.
    let pts = |k: &[Keypoint]| -> Vec<[f64; 2]> {
        k.iter().map(|p| [f64::from(p.x), f64::from(p.y)]).collect()
    };
    let matches = match_descriptors(&da, &db, &m);
    let inside = |q: [f64; 2]| (0.0..479.0).contains(&q[0]) && (0.0..359.0).contains(&q[1]);
    let s = matching_score(
        &pts(&ka),
        &pts(&kb),
        &matches,
        |p| Some(apply_h(&H_SMALL, p)),
        inside,
        3.0,
    );
    println!("synthetic warp: {one:?}\nmatching score: {s:?}");
    assert!(s.correct as f64 >= 0.8 * s.matches as f64, "{s:?}");
    assert!(s.score > 0.2 && s.score <= 1.0, "{s:?}");
}

const H_SMALL: Mat3 = [[0.98, 0.12, 4.0], [-0.1, 1.01, 12.0], [3e-5, 1e-5, 1.0]];

fn load_navcam(name: &str) -> (image::GrayImage, GreyF32) {
    let path = format!("/work/shared/realdata/rover/{name}_524534514EDR_F0562034NCAM00280M_.jpeg");
    let img = image::open(&path)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .to_luma8();
    let grey = GreyF32::from_u8(img.width() as usize, img.height() as usize, img.as_raw()).unwrap();
    (img, grey)
}

/// Thesis Table 6.1 analogue on the real Curiosity NavCam stereo pair (sol 1431): PROVENANCE
/// of the pair says about 1,400 RANSAC-consistent SIFT matches.
#[test]
fn navcam_stereo_pair_sift_ransac() {
    let (l8, l) = load_navcam("NLB");
    let (r8, r) = load_navcam("NRB");
    let sift = SiftParams::default();
    let (kl, dl) = detect_and_describe_sift(&l, &sift);
    let (kr, dr) = detect_and_describe_sift(&r, &sift);
    let m = MatchParams::default();
    let f = match_and_verify(&kl, &dl, &kr, &dr, &m, &RansacParams::fundamental());
    let f_mutual = match_and_verify(
        &kl,
        &dl,
        &kr,
        &dr,
        &MatchParams { mutual: true, ..m },
        &RansacParams::fundamental(),
    );
    let h = match_and_verify(&kl, &dl, &kr, &dr, &m, &RansacParams::homography());
    println!("fundamental: {f:?}\nfundamental, cross-checked: {f_mutual:?}\nhomography: {h:?}");
    assert!(f.matches >= 1000, "{f:?}");
    assert!(f.inliers >= 1000, "{f:?}");
    assert!(f.inlier_ratio >= 0.6, "{f:?}");
    assert!(f_mutual.matches <= f.matches && f_mutual.inliers >= 1000);
    // A stereo pair of a 3-D scene is not a homography: fewer inliers than F.
    assert!(h.inliers < f.inliers, "{h:?} vs {f:?}");
    if let Ok(dir) = std::env::var("REGOLITH_MATCHING_OUT") {
        export_for_peer(&dir, [(&l8, &kl, &dl), (&r8, &kr, &dr)], &[f, f_mutual, h]);
    }
}

/// Writes what `tools/peers/matching_opencv.py` reads: `left.png` / `right.png` (the exact
/// 8-bit inputs), `<side>.keypoints.json` (x, y, size, angle, response, octave),
/// `<side>.descriptors.f32` (little-endian f32, 128 per keypoint), `matches.json` (our ratio
/// test matches) and `ours.json` (the three reports).
fn export_for_peer(
    dir: &str,
    sides: [Side<'_>; 2],
    reports: &[regolith_validator::metrics::matching::MatchReport],
) {
    let dir = std::path::Path::new(dir);
    std::fs::create_dir_all(dir).unwrap();
    for ((img, kps, desc), name) in sides.into_iter().zip(["left", "right"]) {
        img.save(dir.join(format!("{name}.png"))).unwrap();
        let kj: Vec<[f32; 6]> = kps
            .iter()
            .map(|k| [k.x, k.y, k.size, k.angle, k.response, k.octave as f32])
            .collect();
        std::fs::write(
            dir.join(format!("{name}.keypoints.json")),
            serde_json::to_string(&kj).unwrap(),
        )
        .unwrap();
        let bytes: Vec<u8> = desc
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        std::fs::write(dir.join(format!("{name}.descriptors.f32")), bytes).unwrap();
    }
    let (dl, dr) = (sides[0].2, sides[1].2);
    let matches = match_descriptors(dl, dr, &MatchParams::default());
    let pairs: Vec<[usize; 2]> = matches.iter().map(|m| [m.a, m.b]).collect();
    std::fs::write(
        dir.join("matches.json"),
        serde_json::to_string(&pairs).unwrap(),
    )
    .unwrap();
    let labels = ["fundamental", "fundamental_mutual", "homography"];
    let ours: serde_json::Map<String, serde_json::Value> = labels
        .iter()
        .zip(reports)
        .map(|(k, r)| (k.to_string(), serde_json::to_value(r).unwrap()))
        .collect();
    std::fs::write(
        dir.join("ours.json"),
        serde_json::to_string_pretty(&ours).unwrap(),
    )
    .unwrap();
    println!("wrote peer inputs to {}", dir.display());
}

// ---------------------------------------------------------------- properties

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn matching_score_is_a_fraction(
        pa in prop::collection::vec((0.0f64..100.0, 0.0f64..100.0), 0..40),
        pb in prop::collection::vec((0.0f64..100.0, 0.0f64..100.0), 0..40),
        raw in prop::collection::vec((0usize..45, 0usize..45, 0.0f32..10.0), 0..80),
        eps in 0.0f64..200.0,
    ) {
        let a: Vec<[f64; 2]> = pa.iter().map(|p| [p.0, p.1]).collect();
        let b: Vec<[f64; 2]> = pb.iter().map(|p| [p.0, p.1]).collect();
        let m: Vec<Match> = raw.iter().map(|r| Match { a: r.0, b: r.1, distance: r.2 }).collect();
        let s = matching_score(&a, &b, &m, Some, |p| p[0] < 80.0, eps);
        prop_assert!((0.0..=1.0).contains(&s.score));
        prop_assert!(s.correct <= s.matches && s.matches <= s.n_a.min(s.n_b));
    }
}
