//! Fixed test vectors with known answers for the ellipse overlap error and region
//! repeatability (MSER), so the numbers never drift: identical and concentric ellipses, the lens
//! formula for two unit circles (including near-tangent slivers), crossed ellipses in closed
//! form, containment, a fine-grid cross-check, degenerate ellipses, ellipse sets with a known
//! number of one-to-one pairs, the common region, scale normalisation, affine mapping, MSER
//! on a synthetic scene, and property tests (symmetry, bounds, affine invariance).

// Helpers outside `#[test]` functions unwrap known-good fixtures too.
#![allow(clippy::unwrap_used, clippy::panic)]

use std::f64::consts::PI;

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use regolith_validator::features::mser::mser_regions;
use regolith_validator::features::synthetic::BlobScene;
use regolith_validator::features::MserParams;
use regolith_validator::metrics::region_overlap::{
    intersection_area, overlap_error, region_repeatability, repeated_region_pairs, Ellipse,
    RegionParams,
};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// Overlap error of two unit circles whose centres are `d` apart (lens area formula).
fn lens_error(d: f64) -> f64 {
    if d >= 2.0 {
        return 1.0;
    }
    let lens = 2.0 * (d / 2.0).acos() - (d / 2.0) * (4.0 - d * d).sqrt();
    1.0 - lens / (2.0 * PI - lens)
}

// ---------------------------------------------------------------- ellipse overlap error

#[test]
fn overlap_identical_and_concentric() {
    let c = Ellipse::circle([3.0, 4.0], 2.5);
    assert_eq!(overlap_error(&c, &c), 0.0);
    let e = Ellipse::from_axes([-7.0, 11.0], 9.0, 2.0, 0.3);
    assert_eq!(overlap_error(&e, &e), 0.0);
    // Radius 1 inside radius 2: |A ∩ B| / |A ∪ B| = π / 4π.
    let (r1, r2) = (
        Ellipse::circle([0.0, 0.0], 1.0),
        Ellipse::circle([0.0, 0.0], 2.0),
    );
    assert!(close(overlap_error(&r1, &r2), 0.75, 1e-12));
    assert!(close(overlap_error(&r2, &r1), 0.75, 1e-12));
    assert!(close(intersection_area(&r1, &r2), PI, 1e-12));
    // An ellipse a = 2, b = 1 inside a circle of radius 3 (off centre): 1 − 2/9.
    let inner = Ellipse::from_axes([0.5, -0.3], 2.0, 1.0, 1.1);
    let outer = Ellipse::circle([0.0, 0.0], 3.0);
    assert!(close(overlap_error(&inner, &outer), 1.0 - 2.0 / 9.0, 1e-12));
}

#[test]
fn overlap_of_unit_circles_follows_the_lens_formula() {
    for d in [1e-3, 0.1, 0.3, 0.5, 0.6, 1.0, 1.5, 1.9, 1.999] {
        let want = lens_error(d);
        for (theta, origin) in [(0.0, [0.0, 0.0]), (0.7, [412.5, -93.25])] {
            let a = Ellipse::circle(origin, 1.0);
            let b = Ellipse::circle(
                [
                    origin[0] + d * f64::cos(theta),
                    origin[1] + d * f64::sin(theta),
                ],
                1.0,
            );
            let got = overlap_error(&a, &b);
            assert!(close(got, want, 1e-12), "d = {d}: {got} vs {want}");
        }
    }
    // Near tangency, with the centres at half a sample step (π/512) from A's first boundary
    // sample, both crossings fall between the same two of the 512 boundary samples of either
    // circle; the golden-section refinement still finds the sliver (lens ≈ 1.3e-6, 1.3e-9).
    for d in [2.0f64 - 1e-4, 2.0 - 1e-6] {
        let h = d / 2.0;
        let lens = 2.0 * h.acos() - h * (4.0 - d * d).sqrt();
        let dir = PI / 512.0;
        let a = Ellipse::circle([5.0, 5.0], 1.0);
        let b = Ellipse::circle([5.0 + d * dir.cos(), 5.0 + d * dir.sin()], 1.0);
        for got in [intersection_area(&a, &b), intersection_area(&b, &a)] {
            assert!(
                got > 0.0 && close(got, lens, 1e-4 * lens),
                "d = {d}: {got} vs {lens}"
            );
        }
    }
    // Scaled up (radius 10, centres 10·d apart): the error is scale invariant.
    let a = Ellipse::circle([0.0, 0.0], 10.0);
    let b = Ellipse::circle([3.0, 0.0], 10.0);
    assert!(close(overlap_error(&a, &b), lens_error(0.3), 1e-12));
    // Disjoint and tangent: error 1.
    assert_eq!(overlap_error(&a, &Ellipse::circle([20.0, 0.0], 10.0)), 1.0);
    assert_eq!(overlap_error(&a, &Ellipse::circle([25.0, 5.0], 3.0)), 1.0);
}

#[test]
fn crossed_ellipses_have_the_closed_form_intersection() {
    // x²/a² + y²/b² ≤ 1 and x²/b² + y²/a² ≤ 1 intersect in 4ab·atan(b/a).
    for (a, b) in [(2.0, 1.0), (5.0, 4.0), (10.0, 1.0)] {
        let e1 = Ellipse::from_axes([1.0, 2.0], a, b, 0.0);
        let e2 = Ellipse::from_axes([1.0, 2.0], a, b, PI / 2.0);
        let inter = 4.0 * a * b * f64::atan(b / a);
        assert!(close(intersection_area(&e1, &e2), inter, 1e-9 * inter));
        let want = 1.0 - inter / (2.0 * PI * a * b - inter);
        assert!(close(overlap_error(&e1, &e2), want, 1e-12));
    }
}

#[test]
fn overlap_agrees_with_a_fine_grid() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..12 {
        let mut e = || {
            Ellipse::from_axes(
                [rng.gen_range(-4.0..4.0), rng.gen_range(-4.0..4.0)],
                rng.gen_range(2.0..8.0),
                rng.gen_range(0.8..5.0),
                rng.gen_range(0.0..PI),
            )
        };
        let (a, b) = (e(), e());
        // 1200 × 1200 samples over [-14, 14]²: every ellipse above fits inside.
        let n = 1200;
        let h = 28.0 / n as f64;
        let (mut inter, mut union) = (0u64, 0u64);
        for i in 0..n {
            for j in 0..n {
                let p = [-14.0 + (i as f64 + 0.5) * h, -14.0 + (j as f64 + 0.5) * h];
                let (ia, ib) = (a.contains(p), b.contains(p));
                inter += u64::from(ia && ib);
                union += u64::from(ia || ib);
            }
        }
        let grid = 1.0 - inter as f64 / union.max(1) as f64;
        let exact = overlap_error(&a, &b);
        assert!(
            close(grid, exact, 2e-3),
            "{a:?} {b:?}: grid {grid} exact {exact}"
        );
    }
}

#[test]
fn degenerate_ellipses_do_not_overlap() {
    let good = Ellipse::circle([0.0, 0.0], 1.0);
    let flat = Ellipse::from_axes([0.0, 0.0], 1.0, 0.0, 0.0);
    let nan = Ellipse::circle([f64::NAN, 0.0], 1.0);
    for bad in [flat, nan] {
        assert_eq!(bad.area(), 0.0);
        assert_eq!(overlap_error(&good, &bad), 1.0);
        assert_eq!(overlap_error(&bad, &bad), 1.0);
        assert_eq!(intersection_area(&bad, &good), 0.0);
    }
}

// ---------------------------------------------------------------- region repeatability

fn raw() -> RegionParams {
    RegionParams {
        max_overlap_error: 0.4,
        normalised_radius: None,
    }
}

#[test]
fn region_repeatability_known_pairs() {
    let c = Ellipse::circle;
    let a = [
        c([50.0, 50.0], 10.0),
        c([100.0, 50.0], 10.0),
        c([150.0, 50.0], 10.0),
        c([200.0, 50.0], 10.0),
        c([250.0, 50.0], 10.0),
    ];
    let b = [
        c([50.0, 50.0], 10.0),   // identical: error 0
        c([103.0, 50.0], 10.0),  // d/r = 0.3: error 0.3197 < 0.4
        c([156.0, 50.0], 10.0),  // d/r = 0.6: error 0.5467, no pair
        c([200.0, 50.0], 11.0),  // concentric: 1 − 100/121 = 0.1736
        c([250.0, 50.0], 10.0),  // identical
        c([400.0, 400.0], 10.0), // unmatched
    ];
    let r = region_repeatability(&a, &b, Some, |_| true, &raw());
    assert_eq!((r.n_a, r.n_b, r.repeated), (5, 6, 4));
    assert_eq!(r.score, 0.8);
    assert_eq!(r.one_directional, 0.8);
    let pairs = repeated_region_pairs(&a, &b, Some, |_| true, &raw());
    let idx: Vec<(usize, usize)> = pairs.iter().map(|p| (p.0, p.1)).collect();
    // By increasing overlap error, ties by index.
    assert_eq!(idx, vec![(0, 0), (4, 4), (3, 3), (1, 1)]);
    assert!(close(pairs[2].2, 1.0 - 100.0 / 121.0, 1e-12));
    assert!(close(pairs[3].2, lens_error(0.3), 1e-12));
    // A stricter tolerance drops the 0.32 pair; a looser one adds the 0.55 pair.
    let strict = RegionParams {
        max_overlap_error: 0.3,
        ..raw()
    };
    assert_eq!(
        region_repeatability(&a, &b, Some, |_| true, &strict).repeated,
        3
    );
    let loose = RegionParams {
        max_overlap_error: 0.6,
        ..raw()
    };
    assert_eq!(
        region_repeatability(&a, &b, Some, |_| true, &loose).repeated,
        5
    );
}

#[test]
fn region_pairs_are_one_to_one() {
    let c = Ellipse::circle;
    // Two A regions overlap the same B region; only the better one pairs.
    let a = [c([0.0, 0.0], 10.0), c([1.0, 0.0], 10.0)];
    let b = [c([1.5, 0.0], 10.0)];
    let pairs = repeated_region_pairs(&a, &b, Some, |_| true, &raw());
    assert_eq!(pairs.len(), 1);
    assert_eq!((pairs[0].0, pairs[0].1), (1, 0));
    assert!(close(pairs[0].2, lens_error(0.05), 1e-12));
    let r = region_repeatability(&a, &b, Some, |_| true, &raw());
    assert_eq!((r.repeated, r.score, r.one_directional), (1, 1.0, 0.5));
}

#[test]
fn region_common_region_requires_full_visibility() {
    let c = Ellipse::circle;
    let a = [
        c([50.0, 50.0], 10.0),
        c([100.0, 50.0], 10.0),
        c([115.0, 50.0], 10.0),
    ];
    let b = [
        c([50.0, 50.0], 10.0),
        c([103.0, 50.0], 10.0),
        c([115.0, 50.0], 10.0),
    ];
    // x < 120 is common: the circle at 115 has its rightmost point at 125, so it is dropped
    // from both sides although its centre is inside.
    let r = region_repeatability(&a, &b, Some, |p| p[0] < 120.0, &raw());
    assert_eq!((r.n_a, r.n_b, r.repeated, r.score), (2, 2, 2, 1.0));
    // A map that rejects a region's centre drops it too.
    let r = region_repeatability(
        &a,
        &b,
        |p| (p[0] > 75.0).then_some(p),
        |p| p[0] < 120.0,
        &raw(),
    );
    assert_eq!((r.n_a, r.n_b, r.repeated), (1, 2, 1));
    let none = region_repeatability(&a, &[], Some, |_| true, &raw());
    assert_eq!((none.n_b, none.score), (0, 0.0));
}

#[test]
fn region_scale_normalisation() {
    // Radius 5, centres 3 px apart: d/r = 0.6 → error 0.5467 as detected; normalised to a
    // 30 px radius (factor 6, centres unchanged) d/r = 0.1 → error lens(0.1) = 0.0625.
    let a = [Ellipse::circle([40.0, 40.0], 5.0)];
    let b = [Ellipse::circle([43.0, 40.0], 5.0)];
    assert_eq!(
        region_repeatability(&a, &b, Some, |_| true, &raw()).repeated,
        0
    );
    let pairs = repeated_region_pairs(&a, &b, Some, |_| true, &RegionParams::default());
    assert_eq!(pairs.len(), 1);
    assert!(close(pairs[0].2, lens_error(0.1), 1e-12));
    assert_eq!(RegionParams::default().normalised_radius, Some(30.0));
    assert_eq!(RegionParams::default().max_overlap_error, 0.4);
}

#[test]
fn region_mapping_is_linearised_exactly_for_affine_maps() {
    // B is A under x ↦ J x + t with shear; mapping A's regions reproduces B's exactly.
    let j = [[1.1, 0.25], [-0.1, 0.9]];
    let t = [7.0, -3.0];
    let map = move |p: [f64; 2]| {
        Some([
            j[0][0] * p[0] + j[0][1] * p[1] + t[0],
            j[1][0] * p[0] + j[1][1] * p[1] + t[1],
        ])
    };
    let a: Vec<Ellipse> = (0..6)
        .map(|k| {
            let k = f64::from(k);
            Ellipse::from_axes([40.0 + 50.0 * k, 60.0 + 7.0 * k], 6.0 + k, 3.0, 0.4 * k)
        })
        .collect();
    let b: Vec<Ellipse> = a
        .iter()
        .map(|e| e.transformed(j, map(e.center).unwrap()))
        .collect();
    for (ea, eb) in a.iter().zip(&b) {
        let m = ea.mapped(map).unwrap();
        assert!(overlap_error(&m, eb) < 1e-9);
        assert!(close(m.area(), ea.area() * (1.1 * 0.9 + 0.25 * 0.1), 1e-9));
    }
    let r = region_repeatability(&a, &b, map, |_| true, &RegionParams::default());
    assert_eq!((r.repeated, r.score), (6, 1.0));
}

#[test]
fn mser_regions_repeat_on_the_same_image_and_under_a_shift() {
    let scene = BlobScene::random(320, 240, 150, (4.0, 14.0), 3);
    let img = scene.render(320, 240, |x, y| (x, y));
    let (dx, dy) = (2.5, -1.5);
    let shifted = scene.render(320, 240, |x, y| (x - dx, y - dy));
    let p = MserParams::default();
    let ea: Vec<Ellipse> = mser_regions(&img, &p)
        .iter()
        .map(Ellipse::from_region)
        .collect();
    let eb: Vec<Ellipse> = mser_regions(&shifted, &p)
        .iter()
        .map(Ellipse::from_region)
        .collect();
    assert!(ea.len() >= 20, "only {} MSER regions", ea.len());
    let inside = |q: [f64; 2]| q[0] >= 0.0 && q[1] >= 0.0 && q[0] <= 319.0 && q[1] <= 239.0;
    let same = region_repeatability(&ea, &ea, Some, inside, &RegionParams::default());
    assert_eq!(same.score, 1.0);
    let moved = region_repeatability(
        &ea,
        &eb,
        |q| Some([q[0] + dx, q[1] + dy]),
        inside,
        &RegionParams::default(),
    );
    println!(
        "MSER: {} / {} regions; same {same:?}; shifted {moved:?}",
        ea.len(),
        eb.len()
    );
    assert!(
        moved.score >= 0.8,
        "MSER region repeatability under a shift: {moved:?}"
    );
}

// ---------------------------------------------------------------- properties

fn ellipse() -> impl Strategy<Value = Ellipse> {
    (
        -20.0f64..20.0,
        -20.0f64..20.0,
        0.5f64..15.0,
        0.5f64..15.0,
        0.0f64..PI,
    )
        .prop_map(|(x, y, a, b, t)| Ellipse::from_axes([x, y], a, b, t))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn overlap_error_is_symmetric_and_bounded(a in ellipse(), b in ellipse()) {
        let (e_ab, e_ba) = (overlap_error(&a, &b), overlap_error(&b, &a));
        prop_assert!((0.0..=1.0).contains(&e_ab));
        prop_assert!((e_ab - e_ba).abs() < 1e-9, "{} vs {}", e_ab, e_ba);
        let inter = intersection_area(&a, &b);
        prop_assert!(inter >= 0.0 && inter <= a.area().min(b.area()) + 1e-9);
    }

    #[test]
    fn overlap_error_is_affine_invariant(
        a in ellipse(),
        b in ellipse(),
        j in (0.5f64..2.0, -0.5f64..0.5, -0.5f64..0.5, 0.5f64..2.0),
        t in (-50.0f64..50.0, -50.0f64..50.0),
    ) {
        let jac = [[j.0, j.1], [j.2, j.3]];
        let map = |e: &Ellipse| {
            let c = e.center;
            e.transformed(jac, [
                jac[0][0] * c[0] + jac[0][1] * c[1] + t.0,
                jac[1][0] * c[0] + jac[1][1] * c[1] + t.1,
            ])
        };
        let before = overlap_error(&a, &b);
        let after = overlap_error(&map(&a), &map(&b));
        prop_assert!((before - after).abs() < 1e-7, "{} vs {}", before, after);
    }

    #[test]
    fn region_repeatability_is_a_fraction(
        a in prop::collection::vec(ellipse(), 0..12),
        b in prop::collection::vec(ellipse(), 0..12),
    ) {
        let r = region_repeatability(&a, &b, Some, |p| p[0] < 25.0, &RegionParams::default());
        prop_assert!((0.0..=1.0).contains(&r.score));
        prop_assert!(r.repeated <= r.n_a.min(r.n_b));
    }
}

#[test]
fn lens_helper_sanity() {
    // The helper itself: d = 0 is identical, d = 2 is tangent (disjoint).
    assert!(close(lens_error(0.0), 0.0, 1e-15));
    assert_eq!(lens_error(2.0), 1.0);
}
