//! Ellipse overlap error and region repeatability for region detectors such as MSER
//! (Mikolajczyk, Tuytelaars, Schmid et al., IJCV 65, 2005).
//!
//! A region is an [`Ellipse`] (MSER: the ellipse with the region's second moments). Two regions
//! correspond when their *overlap error* `1 − |A ∩ B| / |A ∪ B|` is below 40 %, after mapping
//! A into B's image. Region repeatability pairs regions one-to-one, greedily by increasing
//! overlap error, and divides the pairs by `min(n_A, n_B)` over the region both images see:
//! the same protocol, closures and pairing as point repeatability
//! ([`super::repeatability`]), with overlap error instead of distance.
//!
//! Design decisions:
//! * **Exact area, not a grid.** The intersection area comes from Green's theorem on the
//!   boundary of `A ∩ B`: arcs of A inside B and arcs of B inside A, each integrated in closed
//!   form. Boundary crossings are found by sampling A's boundary (512 points) and bisecting
//!   each sign change of B's implicit function to machine precision; near-tangent slivers
//!   (two crossings between the same two samples) are caught by refining every sampled local
//!   extremum with a golden-section search. Results agree with the lens formula to ~1e-15.
//!   Because the boundary is closed from the same crossing points on both ellipses, even a
//!   missed crossing could not leave the contour open; it would only drop a sliver.
//! * **Mapping by local linearisation.** A's ellipse is mapped with the Jacobian of the point
//!   map at its centre (central differences, 1 px), VLBenchmarks' `linearise` warp: exact for
//!   identity (same pose) and any affine map.
//! * **Common region = fully visible.** A region counts only if its centre and its four
//!   extreme points (leftmost, rightmost, top, bottom) are all in the common region, as
//!   VLBenchmarks' `CropFrames` keeps frames fully inside both images.
//! * **Scale normalisation** (default on, 30 px as in IJCV05 / VLBenchmarks / OpenCV): before
//!   the overlap of a candidate pair is computed, both ellipses are scaled about their own
//!   centres by the factor that gives B's ellipse the area of a 30 px circle. Large regions
//!   then do not score better than small ones just for being large; centre offsets are not
//!   scaled, so localisation error still counts. `None` compares the ellipses as detected.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::repeatability::{common_points, fraction, greedy_one_to_one};
use crate::features::Region;

use std::f64::consts::{PI, TAU};

/// Boundary samples per ellipse when searching for crossings.
const BOUNDARY_SAMPLES: usize = 512;
/// Bisection steps per crossing (2π/512 / 2⁶⁰ is far below f64 resolution).
const BISECTION_STEPS: usize = 60;
/// Step of the central differences that linearise the point map, px.
const JACOBIAN_STEP_PX: f64 = 1.0;

/// A filled ellipse `{x : (x − c)ᵀ Σ⁻¹ (x − c) ≤ 1}` in pixel coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ellipse {
    /// Centre `c`, px (same convention as keypoints: `(0, 0)` is the top-left pixel centre).
    pub center: [f64; 2],
    /// Shape matrix `Σ`, symmetric positive definite, px²; a circle of radius `r` has
    /// `Σ = r² I`, an ellipse with semi-axes `a, b` has eigenvalues `a², b²`.
    pub shape: [[f64; 2]; 2],
}

impl Ellipse {
    /// A circle of radius `r`.
    pub fn circle(center: [f64; 2], r: f64) -> Ellipse {
        Ellipse {
            center,
            shape: [[r * r, 0.0], [0.0, r * r]],
        }
    }

    /// An ellipse with semi-axis `a` along the direction `theta` (radians, from +x towards
    /// +y) and semi-axis `b` across it.
    pub fn from_axes(center: [f64; 2], a: f64, b: f64, theta: f64) -> Ellipse {
        let (c, s) = (theta.cos(), theta.sin());
        let (a2, b2) = (a * a, b * b);
        let xy = (a2 - b2) * c * s;
        Ellipse {
            center,
            shape: [[a2 * c * c + b2 * s * s, xy], [xy, a2 * s * s + b2 * c * c]],
        }
    }

    /// The ellipse of an MSER region: same centroid and second moments, so `Σ = 4 · cov`
    /// (its semi-axes are [`Region::semi_axes`]).
    pub fn from_region(r: &Region) -> Ellipse {
        let [[xx, xy], [_, yy]] = r.cov;
        Ellipse {
            center: [r.x, r.y],
            shape: [[4.0 * xx, 4.0 * xy], [4.0 * xy, 4.0 * yy]],
        }
    }

    /// `det Σ`.
    fn det(&self) -> f64 {
        let [[p, q], [_, r]] = self.shape;
        p * r - q * q
    }

    /// True when the centre and shape are finite and `Σ` is symmetric positive definite.
    pub fn is_valid(&self) -> bool {
        let [[p, q], [q2, r]] = self.shape;
        [self.center[0], self.center[1], p, q, q2, r]
            .iter()
            .all(|v| v.is_finite())
            && (q - q2).abs() <= 1e-9 * (p.abs() + r.abs())
            && p > 0.0
            && self.det() > 0.0
    }

    /// Area `π √det Σ`, px² (0 for an invalid ellipse).
    pub fn area(&self) -> f64 {
        if self.is_valid() {
            PI * self.det().sqrt()
        } else {
            0.0
        }
    }

    /// Whether `p` lies inside (or on) the ellipse; false for an invalid ellipse.
    pub fn contains(&self, p: [f64; 2]) -> bool {
        self.implicit(p).is_some_and(|v| v <= 0.0)
    }

    /// `(p − c)ᵀ Σ⁻¹ (p − c) − 1`: negative inside, zero on the boundary.
    fn implicit(&self, p: [f64; 2]) -> Option<f64> {
        let l = self.cholesky()?;
        let (dx, dy) = (p[0] - self.center[0], p[1] - self.center[1]);
        let u = dx / l[0][0];
        let v = (dy - l[1][0] * u) / l[1][1];
        Some(u * u + v * v - 1.0)
    }

    /// The radius, when the ellipse is a circle (a valid `Σ = r² I`).
    fn circle_radius(&self) -> Option<f64> {
        let [[p, q], [q2, r]] = self.shape;
        (q == 0.0 && q2 == 0.0 && p == r && p > 0.0 && p.is_finite()).then(|| p.sqrt())
    }

    /// The same ellipse with its semi-axes multiplied by `k`, about the same centre.
    pub fn scaled(&self, k: f64) -> Ellipse {
        let k2 = k * k;
        let [[p, q], [_, r]] = self.shape;
        Ellipse {
            center: self.center,
            shape: [[p * k2, q * k2], [q * k2, r * k2]],
        }
    }

    /// The image of the ellipse under the affine map `x ↦ center + J (x − c)`: `Σ' = J Σ Jᵀ`.
    pub fn transformed(&self, jacobian: [[f64; 2]; 2], center: [f64; 2]) -> Ellipse {
        let j = jacobian;
        let s = self.shape;
        // J Σ
        let js = [
            [
                j[0][0] * s[0][0] + j[0][1] * s[1][0],
                j[0][0] * s[0][1] + j[0][1] * s[1][1],
            ],
            [
                j[1][0] * s[0][0] + j[1][1] * s[1][0],
                j[1][0] * s[0][1] + j[1][1] * s[1][1],
            ],
        ];
        let xx = js[0][0] * j[0][0] + js[0][1] * j[0][1];
        let xy = js[0][0] * j[1][0] + js[0][1] * j[1][1];
        let yy = js[1][0] * j[1][0] + js[1][1] * j[1][1];
        Ellipse {
            center,
            shape: [[xx, xy], [xy, yy]],
        }
    }

    /// The image of the ellipse under a point map, linearised at the centre (central
    /// differences, 1 px). `None` when the map rejects the centre or a difference point.
    pub fn mapped(&self, map: impl Fn([f64; 2]) -> Option<[f64; 2]>) -> Option<Ellipse> {
        let [x, y] = self.center;
        let h = JACOBIAN_STEP_PX;
        let c = map([x, y])?;
        let (xp, xm) = (map([x + h, y])?, map([x - h, y])?);
        let (yp, ym) = (map([x, y + h])?, map([x, y - h])?);
        let jac = [
            [(xp[0] - xm[0]) / (2.0 * h), (yp[0] - ym[0]) / (2.0 * h)],
            [(xp[1] - xm[1]) / (2.0 * h), (yp[1] - ym[1]) / (2.0 * h)],
        ];
        let e = self.transformed(jac, c);
        e.is_valid().then_some(e)
    }

    /// The four extreme points of the boundary: leftmost, rightmost, topmost (smallest y)
    /// and bottommost. The extreme point in direction `n` is `c + Σ n / √(nᵀ Σ n)`.
    pub fn extremes(&self) -> [[f64; 2]; 4] {
        let [[p, q], [_, r]] = self.shape;
        let [cx, cy] = self.center;
        let (sp, sr) = (p.max(0.0).sqrt(), r.max(0.0).sqrt());
        let (dx, dy) = (
            [sp, if sp > 0.0 { q / sp } else { 0.0 }],
            [if sr > 0.0 { q / sr } else { 0.0 }, sr],
        );
        [
            [cx - dx[0], cy - dx[1]],
            [cx + dx[0], cy + dx[1]],
            [cx - dy[0], cy - dy[1]],
            [cx + dy[0], cy + dy[1]],
        ]
    }

    /// Largest semi-axis, px.
    fn max_radius(&self) -> f64 {
        let [[p, q], [_, r]] = self.shape;
        let half_trace = 0.5 * (p + r);
        let disc = (0.25 * (p - r) * (p - r) + q * q).sqrt();
        (half_trace + disc).max(0.0).sqrt()
    }

    /// Lower-triangular `L` with `L Lᵀ = Σ` (positive diagonal, so `det L > 0` and the
    /// boundary `c + L (cos t, sin t)` runs counter-clockwise in `(x, y)`).
    fn cholesky(&self) -> Option<[[f64; 2]; 2]> {
        if !self.is_valid() {
            return None;
        }
        let [[p, q], [_, r]] = self.shape;
        let l11 = p.sqrt();
        let l21 = q / l11;
        let l22 = (r - l21 * l21).sqrt();
        (l22 > 0.0 && l22.is_finite()).then_some([[l11, 0.0], [l21, l22]])
    }
}

/// One ellipse ready for boundary integration, in a frame where A's centre is the origin.
struct Param {
    c: [f64; 2],
    l: [[f64; 2]; 2],
}

impl Param {
    fn point(&self, t: f64) -> [f64; 2] {
        let (s, c) = t.sin_cos();
        [
            self.c[0] + self.l[0][0] * c,
            self.c[1] + self.l[1][0] * c + self.l[1][1] * s,
        ]
    }

    /// `(p − c)ᵀ Σ⁻¹ (p − c) − 1`.
    fn implicit(&self, p: [f64; 2]) -> f64 {
        let [u, v] = self.local(p);
        u * u + v * v - 1.0
    }

    /// `L⁻¹ (p − c)`.
    fn local(&self, p: [f64; 2]) -> [f64; 2] {
        let u = (p[0] - self.c[0]) / self.l[0][0];
        let v = (p[1] - self.c[1] - self.l[1][0] * u) / self.l[1][1];
        [u, v]
    }

    /// Twice the signed area swept by the boundary arc from `t0` to `t1` (Green's theorem:
    /// `∮ x dy − y dx = det L · Δt + c × L (u(t1) − u(t0))`).
    fn arc2(&self, t0: f64, t1: f64) -> f64 {
        let det = self.l[0][0] * self.l[1][1];
        let (du, dv) = (t1.cos() - t0.cos(), t1.sin() - t0.sin());
        let w = [self.l[0][0] * du, self.l[1][0] * du + self.l[1][1] * dv];
        det * (t1 - t0) + (self.c[0] * w[1] - self.c[1] * w[0])
    }
}

/// Parameters `t` in `[0, 2π)` where `a`'s boundary crosses `b`'s, in increasing order, and
/// the implicit value of `b` at each boundary sample of `a`.
///
/// A sign change between two samples is bisected. Two crossings between the same samples
/// (a near-tangent sliver) show no sign change, so every sampled local extremum of `b`'s
/// implicit function is refined by a golden-section search; if the true extremum changes
/// sign, both crossings are bisected on either side of it.
fn crossings(a: &Param, b: &Param) -> (Vec<f64>, Vec<f64>) {
    let step = TAU / BOUNDARY_SAMPLES as f64;
    let g_at = |t: f64| b.implicit(a.point(t));
    let g: Vec<f64> = (0..BOUNDARY_SAMPLES)
        .map(|k| g_at(k as f64 * step))
        .collect();
    let at = |k: isize| -> f64 {
        let n = BOUNDARY_SAMPLES as isize;
        g.get(k.rem_euclid(n) as usize).copied().unwrap_or(0.0)
    };
    // The crossing between `lo` (whose side is `lo_inside`) and `hi`.
    let bisect = |mut lo: f64, mut hi: f64, lo_inside: bool| -> f64 {
        for _ in 0..BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            if (g_at(mid) < 0.0) == lo_inside {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    let mut roots = Vec::new();
    for k in 0..BOUNDARY_SAMPLES as isize {
        let (g_prev, g0, g1) = (at(k - 1), at(k), at(k + 1));
        let t0 = k as f64 * step;
        if (g0 < 0.0) != (g1 < 0.0) {
            roots.push(bisect(t0, t0 + step, g0 < 0.0));
            continue;
        }
        // A local extremum on one side of B's boundary: search for a hidden double crossing.
        let inside = g0 < 0.0;
        let is_min = !inside && g_prev > g0 && g1 >= g0;
        let is_max = inside && g_prev < g0 && g1 <= g0;
        if !(is_min || is_max) || (g_prev < 0.0) != inside {
            continue;
        }
        let sign = if inside { -1.0 } else { 1.0 };
        let (mut lo, mut hi) = (t0 - step, t0 + step);
        let phi = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..BISECTION_STEPS {
            let (m1, m2) = (hi - phi * (hi - lo), lo + phi * (hi - lo));
            if sign * g_at(m1) < sign * g_at(m2) {
                hi = m2;
            } else {
                lo = m1;
            }
        }
        let te = 0.5 * (lo + hi);
        if (g_at(te) < 0.0) != inside {
            roots.push(bisect(t0 - step, te, inside));
            roots.push(bisect(te, t0 + step, !inside));
        }
    }
    let mut roots: Vec<f64> = roots.into_iter().map(|t| t.rem_euclid(TAU)).collect();
    roots.sort_by(f64::total_cmp);
    (roots, g)
}

/// Area of `A ∩ B`, px² (0 if either ellipse is invalid).
pub fn intersection_area(a: &Ellipse, b: &Ellipse) -> f64 {
    let valid = a.area() > 0.0 && b.area() > 0.0;
    match (a.circle_radius(), b.circle_radius()) {
        (Some(ra), Some(rb)) if valid => lens_area(
            ra,
            rb,
            (a.center[0] - b.center[0]).hypot(a.center[1] - b.center[1]),
        ),
        _ => ellipses_intersection_area(a, b),
    }
}

/// The area shared by two circles of radii `ra` and `rb` whose centres are `d` apart (the lens
/// formula). Why: SIFT's and SURF's regions are circles, thousands a view, and the general
/// boundary search of [`ellipses_intersection_area`] was most of their comparison's time.
fn lens_area(ra: f64, rb: f64, d: f64) -> f64 {
    if d >= ra + rb {
        return 0.0;
    }
    if d <= (ra - rb).abs() {
        return PI * ra.min(rb).powi(2);
    }
    let ca = ((d * d + ra * ra - rb * rb) / (2.0 * d * ra)).clamp(-1.0, 1.0);
    let cb = ((d * d + rb * rb - ra * ra) / (2.0 * d * rb)).clamp(-1.0, 1.0);
    let k = ((-d + ra + rb) * (d + ra - rb) * (d - ra + rb) * (d + ra + rb)).max(0.0);
    ra * ra * ca.acos() + rb * rb * cb.acos() - 0.5 * k.sqrt()
}

/// [`intersection_area`] of any two ellipses: crossings of the boundaries found by sampling
/// and bisection, the area closed from arcs between them.
fn ellipses_intersection_area(a: &Ellipse, b: &Ellipse) -> f64 {
    let (area_a, area_b) = (a.area(), b.area());
    let (Some(la), Some(lb)) = (a.cholesky(), b.cholesky()) else {
        return 0.0;
    };
    // Identical ellipses: every boundary sample is a numerical crossing; answer directly.
    let scale = a.max_radius().max(b.max_radius());
    let same_center = (a.center[0] - b.center[0]).hypot(a.center[1] - b.center[1]) <= 1e-12 * scale;
    let same_shape = (0..2)
        .all(|i| (0..2).all(|j| (a.shape[i][j] - b.shape[i][j]).abs() <= 1e-12 * scale * scale));
    if same_center && same_shape {
        return area_a.min(area_b);
    }
    let pa = Param {
        c: [0.0, 0.0],
        l: la,
    };
    let pb = Param {
        c: [b.center[0] - a.center[0], b.center[1] - a.center[1]],
        l: lb,
    };
    let (roots, g) = crossings(&pa, &pb);
    if roots.len() < 2 {
        // No proper crossing: one contains the other, or they are disjoint (a single
        // tangent contact changes no area). Decide by the majority of boundary samples.
        let inside = g.iter().filter(|v| **v < 0.0).count();
        if 2 * inside > g.len() {
            return area_a;
        }
        let step = TAU / BOUNDARY_SAMPLES as f64;
        let b_inside = (0..BOUNDARY_SAMPLES)
            .filter(|&k| pa.implicit(pb.point(k as f64 * step)) < 0.0)
            .count();
        return if 2 * b_inside > BOUNDARY_SAMPLES {
            area_b
        } else {
            0.0
        };
    }
    // B's parameter at each crossing point.
    let s: Vec<f64> = roots
        .iter()
        .map(|&t| {
            let [u, v] = pb.local(pa.point(t));
            v.atan2(u)
        })
        .collect();
    let m = roots.len();
    let mut twice = 0.0;
    for k in 0..m {
        let t0 = roots[k];
        let t1 = if k + 1 < m {
            roots[k + 1]
        } else {
            roots[0] + TAU
        };
        if pb.implicit(pa.point(0.5 * (t0 + t1))) < 0.0 {
            // A's arc between consecutive crossings lies inside B: it bounds A ∩ B.
            twice += pa.arc2(t0, t1);
        } else {
            // Otherwise B's arc between the same two points (counter-clockwise) does.
            let s0 = s[k];
            let s1 = s[(k + 1) % m];
            twice += pb.arc2(s0, s0 + (s1 - s0).rem_euclid(TAU));
        }
    }
    (0.5 * twice).clamp(0.0, area_a.min(area_b))
}

/// Overlap error `1 − |A ∩ B| / |A ∪ B|` in `[0, 1]`: 0 for identical ellipses, 1 for
/// disjoint ones (and when either is invalid).
pub fn overlap_error(a: &Ellipse, b: &Ellipse) -> f64 {
    let inter = intersection_area(a, b);
    let union = a.area() + b.area() - inter;
    if union > 0.0 && union.is_finite() {
        (1.0 - inter / union).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Parameters of region repeatability.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RegionParams {
    /// A pair corresponds when its overlap error is strictly below this (0.4).
    pub max_overlap_error: f64,
    /// Scale normalisation radius, px (`Some(30.0)`; `None` = compare as detected).
    pub normalised_radius: Option<f64>,
}

impl Default for RegionParams {
    fn default() -> Self {
        RegionParams {
            max_overlap_error: 0.4,
            normalised_radius: Some(30.0),
        }
    }
}

/// The figures of one region comparison (the counterpart of
/// [`super::repeatability::Repeatability`], with an overlap-error tolerance instead of ε).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RegionRepeatability {
    /// Overlap-error tolerance.
    pub max_overlap_error: f64,
    /// Scale normalisation radius, px, if any.
    pub normalised_radius: Option<f64>,
    /// Regions of A fully inside the common region (after mapping).
    pub n_a: usize,
    /// Regions of B fully inside the common region.
    pub n_b: usize,
    /// One-to-one pairs with overlap error below the tolerance.
    pub repeated: usize,
    /// `repeated / min(n_a, n_b)` (0 when either is empty).
    pub score: f64,
    /// `repeated / n_a`: the thesis's one-directional ratio.
    pub one_directional: f64,
}

/// Whether the ellipse is fully visible: centre and four extreme points in the region.
fn fully_in(e: Ellipse, in_common: &impl Fn([f64; 2]) -> bool) -> bool {
    e.is_valid() && in_common(e.center) && e.extremes().into_iter().all(in_common)
}

/// The overlap error of a candidate pair under `p`'s normalisation (B's ellipse sets the
/// scale), or `None` when it cannot be below the tolerance.
fn pair_error(a: &Ellipse, b: &Ellipse, p: &RegionParams) -> Option<f64> {
    let (mut ea, mut eb) = (*a, *b);
    if let Some(r) = p.normalised_radius {
        let rb = (b.area() / PI).sqrt();
        if rb > 0.0 && r > 0.0 {
            let k = r / rb;
            ea = ea.scaled(k);
            eb = eb.scaled(k);
        }
    }
    let dist = (ea.center[0] - eb.center[0]).hypot(ea.center[1] - eb.center[1]);
    if dist >= ea.max_radius() + eb.max_radius() {
        return None;
    }
    // |A ∩ B| / |A ∪ B| ≤ min(area) / max(area).
    let (aa, ab) = (ea.area(), eb.area());
    if aa.min(ab) <= (1.0 - p.max_overlap_error) * aa.max(ab) {
        return None;
    }
    let err = overlap_error(&ea, &eb);
    (err < p.max_overlap_error).then_some(err)
}

/// How far apart (in pixels, along each axis) the centres of a pair [`pair_error`] can accept
/// may be, so a region is compared only with those near it: with scale normalisation the
/// centres' distance must be under `k (r_A + r_B)` (`r` the largest semi-axes, `k` the factor
/// that gives B the normalised radius; the offset itself is not scaled), and the area test
/// bounds B's equivalent radius below by `sqrt(1 − max_overlap_error)` times A's, so the
/// distance is under `R (r_A / (sqrt(1 − e) ρ_A) + max_B r_B / ρ_B)` (`ρ` the equivalent
/// radius); without it, under `r_A + max_B r_B`. A relative margin covers rounding.
struct Reach {
    /// The normalised radius, when pairs are normalised.
    normalised: Option<f64>,
    /// `sqrt(1 − max_overlap_error)`.
    min_radius_ratio: f64,
    /// Largest `r_B / ρ_B` (normalised) or `r_B` (not) over B's valid regions.
    b_term: f64,
}

impl Reach {
    fn of<'e>(b: impl Iterator<Item = &'e Ellipse>, p: &RegionParams) -> Reach {
        let normalised = p.normalised_radius.filter(|r| *r > 0.0);
        let b_term = b
            .filter(|e| e.area() > 0.0)
            .map(|e| match normalised {
                Some(_) => e.max_radius() / (e.area() / PI).sqrt(),
                None => e.max_radius(),
            })
            .fold(0.0, f64::max);
        Reach {
            normalised,
            min_radius_ratio: (1.0 - p.max_overlap_error).max(0.0).sqrt(),
            b_term,
        }
    }

    /// The reach of A's region `a` (`INFINITY`: compare with every region of B).
    fn of_a(&self, a: &Ellipse) -> f64 {
        let w = match self.normalised {
            Some(r) => {
                let rho = (a.area() / PI).sqrt();
                r * (a.max_radius() / (self.min_radius_ratio * rho) + self.b_term)
            }
            None => a.max_radius() + self.b_term,
        };
        if w.is_finite() {
            w * (1.0 + 1e-9) + 1e-9
        } else {
            f64::INFINITY
        }
    }
}

/// The corresponding pairs `(index in a, index in b, overlap error)`, one-to-one, by
/// increasing overlap error, in input indices; `map_a_to_b` and `in_common` as for
/// [`super::repeatability::repeatability`].
pub fn repeated_region_pairs(
    a: &[Ellipse],
    b: &[Ellipse],
    map_a_to_b: impl Fn([f64; 2]) -> Option<[f64; 2]>,
    in_common: impl Fn([f64; 2]) -> bool,
    p: &RegionParams,
) -> Vec<(usize, usize, f64)> {
    pairs_in_common(a, b, map_a_to_b, in_common, p).2
}

/// `(n_a, n_b, pairs)` over the common region.
#[allow(clippy::type_complexity)]
fn pairs_in_common(
    a: &[Ellipse],
    b: &[Ellipse],
    map_a_to_b: impl Fn([f64; 2]) -> Option<[f64; 2]>,
    in_common: impl Fn([f64; 2]) -> bool,
    p: &RegionParams,
) -> (usize, usize, Vec<(usize, usize, f64)>) {
    let (a_in, b_in) = common_points(
        a,
        b,
        |e: Ellipse| e.mapped(&map_a_to_b),
        |e| fully_in(e, &in_common),
    );
    let reach = Reach::of(b_in.iter().map(|(_, e)| e), p);
    // B's regions by centre x, so each of A's reads only those within its reach.
    let mut by_x: Vec<(f64, usize)> = b_in
        .iter()
        .enumerate()
        .map(|(j, (_, e))| (e.center[0], j))
        .collect();
    by_x.sort_by(|u, v| u.0.total_cmp(&v.0).then(u.1.cmp(&v.1)));
    let b_regions = &b_in;
    let cand: Vec<(f64, usize, usize)> = a_in
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, (_, ea))| {
            let w = reach.of_a(ea);
            let near: &[(f64, usize)] = if w.is_finite() {
                let lo = by_x.partition_point(|(x, _)| *x < ea.center[0] - w);
                let hi = by_x.partition_point(|(x, _)| *x <= ea.center[0] + w);
                by_x.get(lo..hi).unwrap_or(&[])
            } else {
                &by_x
            };
            near.iter().filter_map(move |&(_, j)| {
                let (_, eb) = b_regions.get(j)?;
                let close = !w.is_finite() || (eb.center[1] - ea.center[1]).abs() <= w;
                close.then_some(())?;
                Some((pair_error(ea, eb, p)?, i, j))
            })
        })
        .collect();
    let pairs = greedy_one_to_one(cand, a_in.len(), b_in.len())
        .into_iter()
        .filter_map(|(err, i, j)| Some((a_in.get(i)?.0, b_in.get(j)?.0, err)))
        .collect();
    (a_in.len(), b_in.len(), pairs)
}

/// Region repeatability of `a` (mapped into B by `map_a_to_b`, linearised per region) against
/// `b`: one-to-one pairs with overlap error below `p.max_overlap_error`, divided by
/// `min(n_a, n_b)` over the regions fully inside the common region.
pub fn region_repeatability(
    a: &[Ellipse],
    b: &[Ellipse],
    map_a_to_b: impl Fn([f64; 2]) -> Option<[f64; 2]>,
    in_common: impl Fn([f64; 2]) -> bool,
    p: &RegionParams,
) -> RegionRepeatability {
    let (n_a, n_b, pairs) = pairs_in_common(a, b, map_a_to_b, in_common, p);
    let repeated = pairs.len();
    RegionRepeatability {
        max_overlap_error: p.max_overlap_error,
        normalised_radius: p.normalised_radius,
        n_a,
        n_b,
        repeated,
        score: fraction(repeated, n_a.min(n_b)),
        one_directional: fraction(repeated, n_a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Comparing each region only with B's regions within its reach finds every pair that
    /// comparing all pairs finds: circles of many sizes (SIFT's and SURF's keypoints) and
    /// elongated ellipses, with and without scale normalisation, at two tolerances.
    #[test]
    fn regions_within_reach_are_all_the_pairs() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut unit = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut a = Vec::new();
        for _ in 0..300 {
            let c = [unit() * 400.0, unit() * 300.0];
            a.push(if unit() < 0.5 {
                Ellipse::circle(c, 1.0 + unit() * 40.0)
            } else {
                Ellipse::from_axes(c, 2.0 + unit() * 20.0, 1.0 + unit() * 5.0, unit() * 3.0)
            });
        }
        // B: A's regions moved by up to 12 px and rescaled by up to 30 %, and some new ones.
        let mut b: Vec<Ellipse> = a
            .iter()
            .map(|e| {
                let (dx, dy, k) = (
                    unit() * 24.0 - 12.0,
                    unit() * 24.0 - 12.0,
                    0.7 + unit() * 0.6,
                );
                let moved = Ellipse {
                    center: [e.center[0] + dx, e.center[1] + dy],
                    ..*e
                };
                moved.scaled(k)
            })
            .collect();
        b.push(Ellipse::circle([10.0, 10.0], 0.0));
        for params in [
            RegionParams::default(),
            RegionParams {
                max_overlap_error: 0.6,
                normalised_radius: None,
            },
            RegionParams {
                max_overlap_error: 0.2,
                normalised_radius: Some(30.0),
            },
        ] {
            let all = |_: [f64; 2]| true;
            let (_, _, got) = pairs_in_common(&a, &b, Some, all, &params);
            // Every pair of the regions as `pairs_in_common` sees them (mapped, in common).
            let (a_in, b_in) =
                common_points(&a, &b, |e: Ellipse| e.mapped(Some), |e| fully_in(e, &all));
            let mut cand = Vec::new();
            for (i, (_, ea)) in a_in.iter().enumerate() {
                for (j, (_, eb)) in b_in.iter().enumerate() {
                    if let Some(err) = pair_error(ea, eb, &params) {
                        cand.push((err, i, j));
                    }
                }
            }
            let brute: Vec<(usize, usize, f64)> = greedy_one_to_one(cand, a_in.len(), b_in.len())
                .into_iter()
                .map(|(err, i, j)| (a_in[i].0, b_in[j].0, err))
                .collect();
            assert!(brute.len() > 10, "{} pairs", brute.len());
            assert_eq!(got, brute);
        }
    }

    /// Two circles' shared area by the lens formula is the general boundary search's: apart,
    /// crossing, one inside the other, of equal and unequal radii.
    #[test]
    fn circles_share_the_area_the_general_search_finds() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut unit = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut crossing, mut inside, mut apart) = (0, 0, 0);
        for _ in 0..400 {
            let (ra, rb) = (1.0 + unit() * 30.0, 1.0 + unit() * 30.0);
            let d = unit() * 1.2 * (ra + rb);
            let a = Ellipse::circle([3.0, -2.0], ra);
            let theta = unit() * TAU;
            let b = Ellipse::circle([3.0 + d * theta.cos(), -2.0 + d * theta.sin()], rb);
            let (fast, general) = (
                intersection_area(&a, &b),
                ellipses_intersection_area(&a, &b),
            );
            assert!(
                (fast - general).abs() <= 1e-9 * a.area().max(b.area()),
                "{ra} {rb} {d}: {fast} vs {general}"
            );
            if d >= ra + rb {
                apart += 1;
            } else if d <= (ra - rb).abs() {
                inside += 1;
            } else {
                crossing += 1;
            }
        }
        assert!(
            crossing > 100 && inside > 10 && apart > 10,
            "{crossing} {inside} {apart}"
        );
    }

    #[test]
    fn arc_of_full_circle_is_twice_its_area() {
        let e = Ellipse::from_axes([3.0, -2.0], 4.0, 1.5, 0.7);
        let p = Param {
            c: e.center,
            l: e.cholesky().unwrap(),
        };
        assert!((0.5 * p.arc2(0.3, 0.3 + TAU) - e.area()).abs() < 1e-12);
        assert!((e.area() - PI * 6.0).abs() < 1e-12);
    }

    #[test]
    fn extremes_of_an_axis_aligned_ellipse() {
        let e = Ellipse::from_axes([10.0, 20.0], 3.0, 2.0, 0.0);
        let x = e.extremes();
        assert!((x[0][0] - 7.0).abs() < 1e-12 && (x[1][0] - 13.0).abs() < 1e-12);
        assert!((x[2][1] - 18.0).abs() < 1e-12 && (x[3][1] - 22.0).abs() < 1e-12);
        for q in x {
            assert!(e.implicit(q).unwrap().abs() < 1e-12);
        }
    }
}
