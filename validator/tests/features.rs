//! Feature detector tests: known geometry (rectangle corners, ellipses), repeatability under
//! known warps of an analytic scene, contrast maps on known histograms, thread-count
//! determinism, degenerate input, and SIFT matching on the real Curiosity NavCam stereo pair.

// Helpers outside `#[test]` functions unwrap known-good fixtures too.
#![allow(clippy::unwrap_used, clippy::panic)]

use regolith_validator::features::contrast::{clahe, equalize, stretch, stretch_limits};
use regolith_validator::features::synthetic::{BlobScene, Ellipse};
use regolith_validator::features::{
    brute_force_match, describe, detect, mser::mser_regions, Detector, DetectorParams, GreyF32,
    Keypoint, MserParams,
};

fn rectangle() -> (GreyF32, [(f32, f32); 4]) {
    // Inside, the level rises by 1/255 per pixel towards each corner: on a perfectly flat
    // rectangle neighbouring FAST scores tie and strict non-maximum suppression (OpenCV's too)
    // keeps nothing. A blurred corner would move FAST's maximum ~1.5 px inside (OpenCV agrees).
    let (w, h) = (100, 80);
    let levels: Vec<u8> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            if (30.0..70.0).contains(&x) && (20.0..60.0).contains(&y) {
                (180.0 + (x - 49.5).abs() + (y - 39.5).abs()).round() as u8
            } else {
                50
            }
        })
        .collect();
    // Geometric corners: pixel edges, half a pixel outside the first/last inside pixel.
    let corners = [(29.5, 19.5), (69.5, 19.5), (29.5, 59.5), (69.5, 59.5)];
    (GreyF32::from_u8(w, h, &levels).unwrap(), corners)
}

fn dist(a: (f32, f32), b: (f32, f32)) -> f32 {
    ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt()
}

#[test]
fn harris_and_fast_find_rectangle_corners() {
    let (img, corners) = rectangle();
    for d in [Detector::Harris, Detector::Fast] {
        let kps = detect(&img, d, &DetectorParams::default());
        for c in corners {
            assert!(
                kps.iter().any(|k| dist((k.x, k.y), c) <= 1.0),
                "{d}: no keypoint within 1 px of corner {c:?}: {kps:?}"
            );
        }
        for k in &kps {
            let near = corners
                .iter()
                .map(|&c| dist((k.x, k.y), c))
                .fold(f32::MAX, f32::min);
            assert!(
                near <= 2.0,
                "{d}: keypoint {k:?} is {near} px from every corner"
            );
        }
    }
}

/// A textured analytic scene and its image.
fn scene(w: usize, h: usize, seed: u64) -> (BlobScene, GreyF32) {
    let s = BlobScene::random(w, h, w * h / 500, (3.0, 14.0), seed);
    let img = s.render(w, h, |x, y| (x, y));
    (s, img)
}

/// Similarity about the image centre.
#[derive(Clone, Copy)]
struct Similarity {
    cx: f64,
    cy: f64,
    cos: f64,
    sin: f64,
    scale: f64,
}

impl Similarity {
    fn new(w: usize, h: usize, angle_deg: f64, scale: f64) -> Similarity {
        let r = angle_deg.to_radians();
        let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
        Similarity {
            cx,
            cy,
            cos: r.cos(),
            sin: r.sin(),
            scale,
        }
    }
    fn fwd(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.cx, y - self.cy);
        let (c, s, k) = (self.cos, self.sin, self.scale);
        (
            self.cx + k * (c * dx - s * dy),
            self.cy + k * (s * dx + c * dy),
        )
    }
    fn inv(&self, u: f64, v: f64) -> (f64, f64) {
        let (dx, dy) = ((u - self.cx) / self.scale, (v - self.cy) / self.scale);
        let (c, s) = (self.cos, self.sin);
        (self.cx + c * dx + s * dy, self.cy - s * dx + c * dy)
    }
}

/// Repeatability (Schmid et al.: matched / min of the counts in the common region) and, with
/// descriptors, the fraction of ratio-test matches that land within 3 px of the true position.
///
/// With `scale_tol`, tolerances are in units of the keypoint's scale in the warped image
/// (SURF's `s = 1.2 · size / 9`, at least 1), as Mikolajczyk et al. normalise by scale: a
/// size-27 SURF point samples its Hessian every pixel but has a 3.6 px support.
fn warp_check(d: Detector, angle: f64, scale: f64, scale_tol: bool) -> (f64, f64, usize) {
    let (w, h) = (480, 360);
    let (s, img1) = scene(w, h, 11);
    let t = Similarity::new(w, h, angle, scale);
    let (fwd, inv) = (|x, y| t.fwd(x, y), |u, v| t.inv(u, v));
    let img2 = s.render(w, h, inv);
    let p = DetectorParams::default();
    let (k1, k2) = (detect(&img1, d, &p), detect(&img2, d, &p));
    let margin = 12.0;
    let inside = |(x, y): (f64, f64)| {
        x >= margin && y >= margin && x <= w as f64 - 1.0 - margin && y <= h as f64 - 1.0 - margin
    };
    let mapped: Vec<(usize, (f64, f64))> = k1
        .iter()
        .enumerate()
        .map(|(i, k)| (i, fwd(f64::from(k.x), f64::from(k.y))))
        .filter(|&(_, q)| inside(q))
        .collect();
    let common2: Vec<&Keypoint> = k2
        .iter()
        .filter(|k| inside(inv(f64::from(k.x), f64::from(k.y))))
        .collect();
    let near = |q: (f64, f64), k: &Keypoint, tol: f64| {
        let unit = if scale_tol {
            (f64::from(k.size) * 1.2 / 9.0).max(1.0)
        } else {
            1.0
        };
        (f64::from(k.x) - q.0).hypot(f64::from(k.y) - q.1) <= tol * unit
    };
    let repeated = mapped
        .iter()
        .filter(|(_, q)| common2.iter().any(|k| near(*q, k, 1.5)))
        .count();
    let rep = repeated as f64 / mapped.len().min(common2.len()).max(1) as f64;
    let (d1, d2) = (describe(&img1, &k1, d), describe(&img2, &k2, d));
    assert_eq!(d1.len(), k1.len());
    assert!(d1.iter().all(|v| Some(v.len()) == d.descriptor_len()));
    let matches = brute_force_match(&d1, &d2, 0.8);
    let correct = matches
        .iter()
        .filter(|&&(i, j)| {
            let q = fwd(f64::from(k1[i].x), f64::from(k1[i].y));
            near(q, &k2[j], 3.0)
        })
        .count();
    (
        rep,
        correct as f64 / matches.len().max(1) as f64,
        matches.len(),
    )
}

#[test]
fn sift_repeats_and_matches_under_rotation_and_scale() {
    let (rep, precision, n) = warp_check(Detector::Sift, 30.0, 1.25, false);
    assert!(rep >= 0.6, "SIFT repeatability {rep:.3} < 0.6");
    assert!(
        n >= 50 && precision >= 0.7,
        "SIFT: {n} matches, {precision:.3} correct"
    );
}

#[test]
fn surf_repeats_and_matches_under_scale_change() {
    let (rep, precision, n) = warp_check(Detector::Surf, 0.0, 1.5, true);
    assert!(rep >= 0.6, "SURF repeatability {rep:.3} < 0.6");
    assert!(
        n >= 50 && precision >= 0.7,
        "SURF: {n} matches, {precision:.3} correct"
    );
}

#[test]
fn mser_finds_dark_and_bright_ellipses() {
    let blobs = vec![
        Ellipse {
            x: 60.3,
            y: 70.0,
            a: 20.0,
            b: 12.0,
            theta: 0.5,
            value: 0.15,
        },
        Ellipse {
            x: 140.0,
            y: 90.6,
            a: 15.0,
            b: 9.0,
            theta: -0.3,
            value: 0.85,
        },
    ];
    let s = BlobScene::new(200.0, 160.0, blobs.clone());
    let img = s.render(200, 160, |x, y| (x, y));
    let regions = mser_regions(&img, &MserParams::default());
    // The edge is a one-pixel ramp, so a stable region lies between the fully covered core
    // (semi-axes − 1) and the 50 % contour (the nominal ellipse) plus half a pixel.
    for (e, bright) in blobs.iter().zip([false, true]) {
        let pi = std::f64::consts::PI;
        let (lo, hi) = (
            pi * (e.a - 1.0) * (e.b - 1.0),
            pi * (e.a + 0.5) * (e.b + 0.5),
        );
        let found = regions.iter().find(|r| {
            r.bright == bright
                && (r.x - e.x).hypot(r.y - e.y) < 0.5
                && (lo..=hi).contains(&(r.area as f64))
        });
        let r = found.unwrap_or_else(|| panic!("no region for {e:?}: {regions:?}"));
        let (ma, mi) = r.semi_axes();
        assert!(
            (ma - e.a).abs() < 1.0 && (mi - e.b).abs() < 1.0,
            "{r:?} ({ma}, {mi}) vs {e:?}"
        );
    }
    let kps = detect(&img, Detector::Mser, &DetectorParams::default());
    assert!(kps.len() >= 2);
}

fn levels_image(levels: &[u8]) -> GreyF32 {
    GreyF32::from_u8(levels.len(), 1, levels).unwrap()
}

#[test]
fn stretch_uses_one_and_ninety_nine_percent_quantiles() {
    // 1000 px: 5 at level 20, 10 at each of 60..=158, 5 at 240. The 1 % point is the first
    // level whose cdf exceeds 0.01 (60); the 99 % point the first with cdf ≥ 0.99 (158).
    let mut v = vec![20u8; 5];
    for l in 60..=158u8 {
        v.extend(std::iter::repeat_n(l, 10));
    }
    v.extend([240u8; 5]);
    v.push(109);
    v.pop();
    let img = levels_image(&v);
    let (lo, hi) = stretch_limits(&img, 0.01, 0.99);
    assert_eq!((lo * 255.0).round(), 60.0);
    assert_eq!((hi * 255.0).round(), 158.0);
    let out = stretch(&img);
    let map = |level: u8| out.data[v.iter().position(|&x| x == level).unwrap()];
    assert_eq!(map(20), 0.0);
    assert_eq!(map(240), 1.0);
    assert!((map(109) - 0.5).abs() < 1e-6);
}

#[test]
fn equalize_and_clahe_follow_the_cdf() {
    let v: Vec<u8> = [10u8, 20, 30, 40]
        .iter()
        .flat_map(|&l| std::iter::repeat_n(l, 25))
        .collect();
    let img = levels_image(&v);
    let eq = equalize(&img).to_u8();
    // equalizeHist: (cdf − h(first)) · 255 / (N − h(first)).
    assert_eq!([eq[0], eq[25], eq[50], eq[75]], [0, 85, 170, 255]);
    // CLAHE, one tile, no clipping: round(cdf · 255 / N).
    let c = clahe(&img, 1000.0, (1, 1)).to_u8();
    assert_eq!([c[0], c[25], c[50], c[75]], [64, 128, 191, 255]);
    // A flat image stays flat under every map.
    let flat = GreyF32::from_u8(16, 16, &[77u8; 256]).unwrap();
    for out in [stretch(&flat), equalize(&flat), clahe(&flat, 40.0, (8, 8))] {
        assert!(out.data.iter().all(|&x| x == out.data[0]));
    }
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let (_, img) = scene(320, 240, 5);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            Detector::ALL
                .into_iter()
                .map(|d| {
                    let kps = detect(&img, d, &DetectorParams::default());
                    let desc = describe(&img, &kps, d);
                    (kps, desc)
                })
                .collect::<Vec<_>>()
        })
    };
    let (one, two) = (run(1), run(2));
    for (d, (a, b)) in Detector::ALL.iter().zip(one.iter().zip(&two)) {
        assert!(!a.0.is_empty(), "{d} found nothing");
        assert_eq!(a, b, "{d} differs between 1 and 2 threads");
    }
}

#[test]
fn degenerate_images_give_empty_results() {
    let truncated = GreyF32 {
        width: 100,
        height: 100,
        data: vec![0.5; 50],
    };
    let cases = [
        GreyF32::zeros(0, 0),
        GreyF32::zeros(0, 10),
        truncated,
        GreyF32::zeros(1, 1),
        GreyF32::from_u8(3, 3, &[0, 255, 0, 255, 0, 255, 0, 255, 0]).unwrap(),
        GreyF32::new(4, 4, vec![f32::NAN; 16]).unwrap(),
    ];
    for img in &cases {
        for d in Detector::ALL {
            let kps = detect(img, d, &DetectorParams::default());
            if img.is_degenerate() {
                assert!(kps.is_empty(), "{d} on {}x{}", img.width, img.height);
            }
            assert_eq!(
                describe(img, &kps, d).len(),
                if d.descriptor_len().is_some() {
                    kps.len()
                } else {
                    0
                }
            );
        }
    }
    assert!(GreyF32::new(3, 3, vec![0.0; 8]).is_none());
}

#[test]
fn detector_names_and_ratio_test() {
    for d in Detector::ALL {
        assert_eq!(d.name().parse::<Detector>(), Ok(d));
        assert_eq!(
            serde_json::to_string(&d).unwrap(),
            format!("\"{}\"", d.name())
        );
    }
    assert!("orb".parse::<Detector>().is_err());
    let p: DetectorParams = serde_json::from_str(r#"{"fast": {"threshold": 0.1}}"#).unwrap();
    assert_eq!(p.fast.threshold, 0.1);
    assert_eq!(p.sift.octave_layers, 3);
    let a = vec![vec![0.0, 0.0], vec![10.0, 10.0], vec![0.0, 0.0]];
    let b = vec![vec![0.0, 1.0], vec![10.0, 9.0], vec![5.0, 5.0]];
    assert_eq!(brute_force_match(&a, &b, 0.8), vec![(0, 0), (1, 1), (2, 0)]);
    // Second-nearest at 1.05× the nearest distance: ambiguous, rejected.
    let amb = brute_force_match(&[vec![0.0, 0.0]], &[vec![1.0, 0.0], vec![0.0, 1.05]], 0.8);
    assert!(amb.is_empty());
}

fn load_navcam(name: &str) -> GreyF32 {
    let path = format!("/work/shared/realdata/rover/{name}_524534514EDR_F0562034NCAM00280M_.jpeg");
    let img = image::open(&path)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .to_luma8();
    GreyF32::from_u8(img.width() as usize, img.height() as usize, img.as_raw()).unwrap()
}

/// PROVENANCE.md: the Curiosity NavCam pair (sol 1431) has about 1,400 RANSAC-consistent SIFT
/// matches. Without RANSAC we check the ratio-test matches: at least 1,000 of them, and most
/// agree with the pair's dominant vertical offset (a stereo pair differs mainly along x).
#[test]
fn sift_matches_the_real_navcam_stereo_pair() {
    let (l, r) = (load_navcam("NLB"), load_navcam("NRB"));
    assert_eq!((l.width, l.height), (1024, 1024));
    let p = DetectorParams::default();
    let (kl, kr) = (
        detect(&l, Detector::Sift, &p),
        detect(&r, Detector::Sift, &p),
    );
    let (dl, dr) = (
        describe(&l, &kl, Detector::Sift),
        describe(&r, &kr, Detector::Sift),
    );
    let m = brute_force_match(&dl, &dr, 0.8);
    assert!(m.len() >= 1000, "only {} ratio-test matches", m.len());
    let mut dy: Vec<f32> = m.iter().map(|&(i, j)| kr[j].y - kl[i].y).collect();
    dy.sort_by(f32::total_cmp);
    let med = dy[dy.len() / 2];
    let consistent = dy.iter().filter(|v| (*v - med).abs() <= 3.0).count();
    assert!(
        consistent >= 1000,
        "{consistent} of {} matches within 3 px of the median dy {med}",
        m.len()
    );
}
