//! RIEGL terrestrial laser scans: ray casting against the true surface, written as RiSCAN ASCII.
//!
//! Each station has the vertical (90–129.96° from the zenith) and horizontal fields of thesis
//! Table 5.1. In the scanner's own frame (SOCS: z up along the scanner axis, φ from +x toward
//! +y, θ from the zenith) the ray of `(θ, φ)` is `(sinθ cosφ, sinθ sinφ, cosθ)`. The true
//! SOCS → ground pose is a yaw that points the middle of the φ range at the bed centre, times a
//! small levelling error (≤ 0.3°, drawn from the seed), at the station position; it is written
//! only to `truth/scans.json`. Rays are cast column by column (the scanner's line order) with
//! the corpus's own [`TerrainCaster`], so occlusion is exact, and the range gets Gaussian noise
//! (default σ 8 mm) *along the ray*. Reflectance in dB is `10·log10(albedo · cos(incidence))`,
//! minus 0.05 dB per metre of range (imperfect range correction), plus 0.3 dB noise; the
//! retro-reflective balls therefore read close to 0 dB and the soil around −5 dB.
//! Tie points: every marker whose ball is the first surface on the line of sight from the
//! scanner, and inside the field of view, is listed by name at its centre in SOCS plus 2 mm noise.

use rand::Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use regolith_format::frames::{quat_from_axis_angle, Pose};
use regolith_format::grid::AlbedoGrid;

use crate::presets::ScannerSpec;
use crate::seeding::{item_rng, stage_rng};
use crate::sink::push_fixed;
use crate::terrain::raycast::TerrainCaster;
use crate::terrain::{GridShape, TrueMarker};

/// Longest range considered, metres.
const MAX_RANGE_M: f64 = 40.0;
/// The simulated instrument's residual range dependence of `Reflectance[dB]`: a real scanner's
/// amplitude calibration is never exact, so the same surface reads darker from farther away.
/// Recorded in the truth so a compiler's cross-scan calibration can be checked against it.
pub const REFLECTANCE_RANGE_SLOPE_DB_PER_M: f64 = -0.05;
/// Standard deviation of the simulated reflectance noise, dB.
pub const REFLECTANCE_NOISE_DB: f64 = 0.3;

/// A simulated scan in its own frame.
#[derive(Debug, Clone)]
pub struct Scan {
    /// Scan name.
    pub name: String,
    /// True SOCS → ground pose.
    pub ground_from_socs: Pose,
    /// Points in SOCS, metres.
    pub points: Vec<[f64; 3]>,
    /// Reflectance per point, dB.
    pub reflectance_db: Vec<f32>,
    /// Visible markers: name and noisy centre in SOCS.
    pub tiepoints: Vec<(String, [f64; 3])>,
    /// Rays cast.
    pub rays: usize,
}

/// Scan simulation settings shared by all stations.
pub struct ScanSetup<'a> {
    /// Tracer of the true surface.
    pub tracer: &'a TerrainCaster,
    /// Albedo the reflectance is computed from (true, or low-passed when hidden).
    pub albedo: &'a AlbedoGrid,
    /// The return falls as `cos(incidence)^incidence_exponent` (1: Lambert).
    pub incidence_exponent: f64,
    /// Markers.
    pub markers: &'a [TrueMarker],
    /// Centre of the bed (x, y) the stations point at.
    pub bed_centre: [f64; 2],
    /// Angular step, degrees.
    pub step_deg: f64,
    /// Range noise σ, metres.
    pub range_noise_m: f64,
    /// Campaign seed.
    pub seed: u64,
}

/// The SOCS ray direction of `(θ, φ)` in degrees.
pub fn socs_direction(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    [st * cp, st * sp, ct]
}

/// Simulates one station.
pub fn simulate(setup: &ScanSetup<'_>, spec: &ScannerSpec) -> Scan {
    let stage = format!("scan.{}", spec.name);
    let mut rng = stage_rng(setup.seed, &stage);
    let pos = spec.position;
    let bearing = (setup.bed_centre[1] - pos[1])
        .atan2(setup.bed_centre[0] - pos[0])
        .to_degrees();
    let yaw = bearing - 0.5 * (spec.phi_deg[0] + spec.phi_deg[1]);
    let tilt_axis: f64 = rng.gen_range(0.0..360.0);
    let tilt = rng.gen_range(0.0..0.3f64).to_radians();
    let level = quat_from_axis_angle(
        [
            tilt_axis.to_radians().cos(),
            tilt_axis.to_radians().sin(),
            0.0,
        ],
        tilt,
    );
    let heading = quat_from_axis_angle([0.0, 0.0, 1.0], yaw.to_radians());
    let ground_from_socs = Pose {
        translation_m: pos,
        rotation_xyzw: level,
    }
    .compose(&Pose {
        translation_m: [0.0; 3],
        rotation_xyzw: heading,
    });
    let step = setup.step_deg;
    let columns = ((spec.phi_deg[1] - spec.phi_deg[0]) / step).floor() as usize + 1;
    let rows = ((spec.theta_deg[1] - spec.theta_deg[0]) / step + 1e-9).floor() as usize + 1;
    let noise = Normal::new(0.0, setup.range_noise_m.max(0.0)).ok();
    let refl_noise = Normal::new(0.0, REFLECTANCE_NOISE_DB).ok();
    let shape = GridShape::of(
        setup.albedo.origin_m,
        setup.albedo.cell_m,
        setup.albedo.width,
        setup.albedo.height,
    );
    let per_column: Vec<(Vec<[f64; 3]>, Vec<f32>)> = (0..columns)
        .into_par_iter()
        .map(|col| {
            let mut rng = item_rng(setup.seed, &stage, col as u64);
            let phi = spec.phi_deg[0] + col as f64 * step;
            let mut pts = Vec::new();
            let mut refl = Vec::new();
            for row in 0..rows {
                let theta = spec.theta_deg[0] + row as f64 * step;
                let d = socs_direction(theta, phi);
                let dg = ground_from_socs.rotate(d);
                let Some(hit) = setup.tracer.trace(pos, dg, MAX_RANGE_M) else {
                    continue;
                };
                let range = hit.t + noise.map_or(0.0, |n| n.sample(&mut rng));
                let cos_i =
                    -(dg[0] * hit.normal[0] + dg[1] * hit.normal[1] + dg[2] * hit.normal[2]);
                let a = shape.bilinear(&setup.albedo.value, hit.point[0], hit.point[1]);
                let db = 10.0
                    * (a * cos_i.max(0.02).powf(setup.incidence_exponent))
                        .max(1e-3)
                        .log10()
                    + REFLECTANCE_RANGE_SLOPE_DB_PER_M * hit.t
                    + refl_noise.map_or(0.0, |n| n.sample(&mut rng));
                pts.push([d[0] * range, d[1] * range, d[2] * range]);
                refl.push(db as f32);
            }
            (pts, refl)
        })
        .collect();
    let mut points = Vec::new();
    let mut reflectance_db = Vec::new();
    for (p, r) in per_column {
        points.extend(p);
        reflectance_db.extend(r);
    }
    let tiepoints = tiepoints(setup, spec, &ground_from_socs, &mut rng);
    Scan {
        name: spec.name.to_string(),
        ground_from_socs,
        points,
        reflectance_db,
        tiepoints,
        rays: columns * rows,
    }
}

/// Markers seen by the station: inside the field of view and first on the line of sight.
fn tiepoints(
    setup: &ScanSetup<'_>,
    spec: &ScannerSpec,
    ground_from_socs: &Pose,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> Vec<(String, [f64; 3])> {
    let socs_from_ground = ground_from_socs.inverse();
    let noise = Normal::new(0.0, 0.002).ok();
    let mut out = Vec::new();
    for m in setup.markers {
        let s = socs_from_ground.transform_point(m.centre_m);
        let r = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        let theta = (s[2] / r).acos().to_degrees();
        let phi = s[1].atan2(s[0]).to_degrees().rem_euclid(360.0);
        let in_fov = (spec.theta_deg[0]..=spec.theta_deg[1]).contains(&theta)
            && (spec.phi_deg[0]..=spec.phi_deg[1]).contains(&phi);
        if !in_fov || !marker_visible(setup.tracer, spec.position, m) {
            continue;
        }
        let mut n = || noise.map_or(0.0, |n| n.sample(rng));
        out.push((m.name.clone(), [s[0] + n(), s[1] + n(), s[2] + n()]));
    }
    out
}

/// Whether the first surface on the line from `eye` to the ball centre is the ball itself.
pub fn marker_visible(tracer: &TerrainCaster, eye: [f64; 3], m: &TrueMarker) -> bool {
    let d = [
        m.centre_m[0] - eye[0],
        m.centre_m[1] - eye[1],
        m.centre_m[2] - eye[2],
    ];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let dir = [d[0] / len, d[1] / len, d[2] / len];
    match tracer.trace(eye, dir, len + m.radius_m) {
        Some(hit) => {
            let e = [
                hit.point[0] - m.centre_m[0],
                hit.point[1] - m.centre_m[1],
                hit.point[2] - m.centre_m[2],
            ];
            (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt() <= 1.5 * m.radius_m
        }
        None => false,
    }
}

/// RiSCAN ASCII export: header `X[m] Y[m] Z[m] Reflectance[dB]`, space-separated, 4 decimals.
pub fn ascii(scan: &Scan) -> Vec<u8> {
    let chunks: Vec<String> = scan
        .points
        .par_chunks(65_536)
        .zip(scan.reflectance_db.par_chunks(65_536))
        .map(|(pts, refl)| {
            let mut s = String::with_capacity(pts.len() * 40);
            for (p, r) in pts.iter().zip(refl) {
                for v in p {
                    push_fixed(&mut s, *v, 4);
                    s.push(' ');
                }
                push_fixed(&mut s, f64::from(*r), 2);
                s.push('\n');
            }
            s
        })
        .collect();
    let mut out = b"X[m] Y[m] Z[m] Reflectance[dB]\n".to_vec();
    for c in chunks {
        out.extend_from_slice(c.as_bytes());
    }
    out
}

/// Tie-point list `Name,X,Y,Z` (SOCS, metres).
pub fn tiepoint_csv(scan: &Scan) -> Vec<u8> {
    let mut s = String::from("Name,X,Y,Z\n");
    for (name, p) in &scan.tiepoints {
        s.push_str(name);
        for v in p {
            s.push(',');
            push_fixed(&mut s, *v, 5);
        }
        s.push('\n');
    }
    s.into_bytes()
}
