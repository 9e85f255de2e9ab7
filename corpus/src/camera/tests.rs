//! Tests of the corpus camera: each checks one physical property against an independent
//! computation (the format crate's projection, Monte-Carlo optics, photon transfer).

use super::*;
use regolith_format::camera_model::Distortion;

/// `optics` with a noiseless, pattern-free sensor.
fn quiet(optics: CameraPhysics) -> CameraPhysics {
    CameraPhysics {
        prnu_sigma: 0.0,
        dsnu_sigma_dn: 0.0,
        column_fpn_sigma_dn: 0.0,
        black_level_dn: 0.0,
        ..optics
    }
}

fn noiseless(hidden: HiddenOptics) -> HiddenOptics {
    HiddenOptics {
        noise: (0.0, 0.0),
        ..hidden
    }
}

fn distorted_camera() -> CameraModel {
    CameraModel {
        distortion: Distortion {
            k1: -0.2,
            k2: 0.08,
            p1: 3e-4,
            p2: 0.0,
            k3: 0.0,
        },
        ..CameraModel::pinhole(320, 256, 260.0, 260.0, 159.5, 127.5)
    }
}

/// A flat pinhole render of radiance `r` on `camera`'s 2× canvas.
fn flat(
    camera: &CameraModel,
    physics: &CameraPhysics,
    hidden: &HiddenOptics,
    r: f32,
) -> PinholeImage {
    let spec = pinhole_canvas(camera, 2, psf_margin_px(physics, hidden));
    PinholeImage::from_spec(&spec, vec![r; spec.width * spec.height])
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn variance(v: &[f64]) -> f64 {
    let m = mean(v);
    v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() as f64 - 1.0)
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let (ma, mb) = (mean(a), mean(b));
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

fn as_f64(v: &[u8]) -> Vec<f64> {
    v.iter().map(|&x| f64::from(x)).collect()
}

#[test]
fn bessel_functions_match_known_values() {
    // J0's first zero, J1's first zero, tabulated J1(1) and J0(10).
    assert!(lens::bessel_j(0, 2.404_825_557_695_773).abs() < 1e-12);
    assert!(lens::bessel_j(1, 3.831_705_970_207_512_3).abs() < 1e-12);
    assert!((lens::bessel_j(1, 1.0) - 0.440_050_585_744_933_5).abs() < 1e-12);
    assert!((lens::bessel_j(0, 10.0) + 0.245_935_764_451_348_3).abs() < 1e-12);
}

#[test]
fn undistort_inverts_brown_conrady_with_the_right_jacobian() {
    let cam = distorted_camera();
    for i in 0..40 {
        for j in 0..30 {
            let (u, v) = (
                -5.0 + 330.0 * i as f64 / 39.0,
                -5.0 + 266.0 * j as f64 / 29.0,
            );
            let (xd, yd) = ((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy);
            let (x, y) = undistort(&cam, xd, yd).expect("converges inside the image");
            let (ax, ay) = cam.distort(x, y);
            assert!((ax - xd).abs() < 1e-10 && (ay - yd).abs() < 1e-10);
            let jac = lens::distortion_jacobian(&cam, x, y);
            let h = 1e-6;
            let (px, py) = cam.distort(x + h, y);
            let (qx, qy) = cam.distort(x, y + h);
            let numeric = [(px - ax) / h, (qx - ax) / h, (py - ay) / h, (qy - ay) / h];
            for (a, b) in jac.iter().zip(numeric) {
                assert!((a - b).abs() < 1e-5, "{jac:?} vs {numeric:?}");
            }
        }
    }
    // Far beyond the fold-over of a strong barrel there is no inverse.
    let strong = CameraModel {
        distortion: Distortion {
            k1: -0.5,
            ..Distortion::default()
        },
        ..cam
    };
    assert!(undistort(&strong, 2.0, 0.0).is_none());
}

#[test]
fn canvas_covers_every_sub_position_of_the_padded_image() {
    let cam = distorted_camera();
    let margin = 9.0;
    let spec = pinhole_canvas(&cam, 2, margin);
    assert_eq!((spec.fx, spec.fy), (520.0, 520.0));
    let mut touched = [false; 4];
    for j in 0..(256 + 18) * 2 {
        for i in 0..(320 + 18) * 2 {
            let u = i as f64 / 2.0 - 9.25;
            let v = j as f64 / 2.0 - 9.25;
            let (x, y) = undistort(&cam, (u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy).unwrap();
            let [cu, cv] = spec.to_pixel(x, y);
            assert!(cu >= 0.0 && cv >= 0.0, "{cu} {cv}");
            assert!(cu <= (spec.width - 1) as f64 && cv <= (spec.height - 1) as f64);
            touched[0] |= cu < 3.0;
            touched[1] |= cv < 3.0;
            touched[2] |= cu > (spec.width - 4) as f64;
            touched[3] |= cv > (spec.height - 4) as f64;
        }
    }
    assert_eq!(touched, [true; 4], "the canvas is tight");
}

#[test]
fn dots_land_where_the_camera_model_projects_them() {
    let cam = distorted_camera();
    let physics = quiet(CameraPhysics::NAVCAM);
    let hidden = noiseless(HiddenOptics::BASELINE);
    let spec = pinhole_canvas(&cam, 2, psf_margin_px(&physics, &hidden));
    let mut radiance = vec![0f32; spec.width * spec.height];
    let mut dots = Vec::new();
    for i in -8..=8 {
        for j in -7..=7 {
            let (x, y) = (0.09 * i as f64 + 0.013, 0.085 * j as f64 - 0.021);
            let [u, v] = cam.project([x, y, 1.0]).unwrap();
            if u < 10.0 || v < 10.0 || u > 309.0 || v > 245.0 {
                continue;
            }
            dots.push(((x, y), (u, v)));
            let [cu, cv] = spec.to_pixel(x, y);
            let s = 2.0; // canvas pixels = 1 real pixel
            for b in (cv as i64 - 12).max(0)..(cv as i64 + 13).min(spec.height as i64) {
                for a in (cu as i64 - 12).max(0)..(cu as i64 + 13).min(spec.width as i64) {
                    let d2 = (a as f64 - cu).powi(2) + (b as f64 - cv).powi(2);
                    radiance[b as usize * spec.width + a as usize] +=
                        (0.8 * (-d2 / (2.0 * s * s)).exp()) as f32;
                }
            }
        }
    }
    assert!(dots.len() > 100, "{}", dots.len());
    let img = PinholeImage::from_spec(&spec, radiance);
    let frame = expose(&img, &cam, &physics, &hidden, 1, 2);
    let mut worst: f64 = 0.0;
    for &(_, (u, v)) in &dots {
        let (ui, vi) = (u.round() as i64, v.round() as i64);
        let (mut s, mut su, mut sv) = (0.0, 0.0, 0.0);
        for b in vi - 4..=vi + 4 {
            for a in ui - 4..=ui + 4 {
                let w = f64::from(frame[b as usize * 320 + a as usize]);
                s += w;
                su += w * a as f64;
                sv += w * b as f64;
            }
        }
        let err = ((su / s - u).powi(2) + (sv / s - v).powi(2)).sqrt();
        worst = worst.max(err);
    }
    assert!(worst < 0.1, "worst dot centroid error {worst} px");
    // The pinhole position itself (no distortion) is far off near the corners: the test sees
    // the distortion.
    let far = dots
        .iter()
        .map(|&((x, y), (u, v))| {
            ((cam.fx * x + cam.cx - u).powi(2) + (cam.fy * y + cam.cy - v).powi(2)).sqrt()
        })
        .fold(0.0, f64::max);
    assert!(far > 5.0, "{far}");
}

#[test]
fn vignetting_corner_to_centre_ratio_is_one_minus_strength() {
    let cam = CameraModel::pinhole(200, 150, 180.0, 180.0, 110.3, 70.2);
    let s = 0.35;
    // Farthest corner pixel centre from (110.3, 70.2) is (0, 149).
    assert!((lens::vignetting_factor(&cam, s, 0.0, 149.0) - (1.0 - s)).abs() < 1e-12);
    assert!((lens::vignetting_factor(&cam, s, 110.3, 70.2) - 1.0).abs() < 1e-12);
    assert!(lens::vignetting_factor(&cam, s, 199.0, 0.0) > 1.0 - s);
    let physics = quiet(CameraPhysics::NAVCAM);
    let hidden = noiseless(HiddenOptics {
        vignetting_strength: Some(s),
        ..HiddenOptics::BASELINE
    });
    let r: f32 = 0.9;
    let frame = expose(
        &flat(&cam, &physics, &hidden, r),
        &cam,
        &physics,
        &hidden,
        3,
        4,
    );
    // Fit the cos⁴ profile y = c / (1 + a ρ²)²: y^(−1/2) is linear in ρ².
    let c2 = (110.3f64).powi(2) + (149.0f64 - 70.2).powi(2);
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for v in 0..150 {
        for u in 0..200 {
            let rho2 = ((u as f64 - 110.3).powi(2) + (v as f64 - 70.2).powi(2)) / c2;
            let y = f64::from(frame[v * 200 + u]).powf(-0.5);
            n += 1.0;
            sx += rho2;
            sy += y;
            sxx += rho2 * rho2;
            sxy += rho2 * y;
        }
    }
    let b1 = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    let b0 = (sy - b1 * sx) / n;
    let ratio = (b0 / (b0 + b1)).powi(2);
    assert!((ratio / (1.0 - s) - 1.0).abs() < 0.005, "ratio {ratio}");
    let centre = 255.0 * f64::from(r);
    assert!((1.0 / (b0 * b0) / centre - 1.0).abs() < 0.005);
    // And without the hidden effect the field is flat.
    let plain = noiseless(HiddenOptics::BASELINE);
    let frame = expose(
        &flat(&cam, &physics, &plain, 0.8),
        &cam,
        &physics,
        &plain,
        3,
        4,
    );
    assert!(frame.iter().all(|&x| x == 204));
}

/// erf by Abramowitz & Stegun 7.1.26 (|error| < 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let y = 1.0 - poly * (-x * x).exp();
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// A slanted edge (normal at `theta` to the x axis, radiance 0.1 → 0.9) through `camera`;
/// returns the edge-spread function binned by signed distance (bin width 0.05 px, |d| < 14),
/// normalised to the plateaus.
fn slanted_edge_esf(physics: &CameraPhysics, hidden: &HiddenOptics, theta: f64) -> Vec<(f64, f64)> {
    let cam = CameraModel::pinhole(160, 120, 200.0, 200.0, 79.5, 59.5);
    let spec = pinhole_canvas(&cam, 2, psf_margin_px(physics, hidden));
    let (c, s) = (theta.cos(), theta.sin());
    let (u0, v0) = (80.3, 60.0);
    let dist = |u: f64, v: f64| (u - u0) * c + (v - v0) * s;
    let mut radiance = vec![0f32; spec.width * spec.height];
    for j in 0..spec.height {
        for i in 0..spec.width {
            // Area coverage of the canvas pixel (a renderer's box pixel filter), 8×8 samples.
            let mut bright = 0;
            for b in 0..8 {
                for a in 0..8 {
                    let cu = i as f64 - 0.5 + (a as f64 + 0.5) / 8.0;
                    let cv = j as f64 - 0.5 + (b as f64 + 0.5) / 8.0;
                    let u = cam.cx + (cu - spec.cx) / 2.0;
                    let v = cam.cy + (cv - spec.cy) / 2.0;
                    bright += i32::from(dist(u, v) >= 0.0);
                }
            }
            radiance[j * spec.width + i] = (0.1 + 0.8 * f64::from(bright) / 64.0) as f32;
        }
    }
    let img = PinholeImage::from_spec(&spec, radiance);
    let frame = expose(&img, &cam, physics, hidden, 5, 6);
    let nbins = 560;
    let mut sum = vec![0.0; nbins];
    let mut cnt = vec![0.0; nbins];
    for v in 12..108 {
        for u in 12..148 {
            let d = dist(u as f64, v as f64);
            if d.abs() < 14.0 {
                let b = ((d + 14.0) / 0.05) as usize;
                sum[b] += f64::from(frame[v * 160 + u]);
                cnt[b] += 1.0;
            }
        }
    }
    let esf: Vec<(f64, f64)> = (0..nbins)
        .filter(|&b| cnt[b] > 0.0)
        .map(|b| (-14.0 + (b as f64 + 0.5) * 0.05, sum[b] / cnt[b]))
        .collect();
    let plateau = |lo: f64, hi: f64| {
        let v: Vec<f64> = esf
            .iter()
            .filter(|(d, _)| *d > lo && *d < hi)
            .map(|p| p.1)
            .collect();
        mean(&v)
    };
    let (dark, light) = (plateau(-14.0, -10.0), plateau(10.0, 14.0));
    esf.iter()
        .map(|&(d, y)| (d, (y - dark) / (light - dark)))
        .collect()
}

/// The crossing of `level` nearest to the edge.
fn crossing(esf: &[(f64, f64)], level: f64) -> f64 {
    let mut best = f64::INFINITY;
    for w in esf.windows(2) {
        let ((d0, y0), (d1, y1)) = (w[0], w[1]);
        if (y0 - level) * (y1 - level) <= 0.0 && y0 != y1 {
            let d = d0 + (level - y0) / (y1 - y0) * (d1 - d0);
            if d.abs() < best.abs() {
                best = d;
            }
        }
    }
    best
}

/// Best-fit Gaussian ESF (free sigma and shift): RMS residual over |d| < 6.
fn gaussian_fit_residual(esf: &[(f64, f64)]) -> (f64, f64) {
    let mut best = (f64::INFINITY, 0.0);
    for si in 0..600 {
        let sigma = 0.2 + si as f64 * 0.005;
        for mi in -20..=20 {
            let mu = mi as f64 * 0.01;
            let pts: Vec<f64> = esf
                .iter()
                .filter(|(d, _)| d.abs() < 6.0)
                .map(|&(d, y)| y - 0.5 * (1.0 + erf((d - mu) / (sigma * 2f64.sqrt()))))
                .collect();
            let rms = (pts.iter().map(|e| e * e).sum::<f64>() / pts.len() as f64).sqrt();
            if rms < best.0 {
                best = (rms, sigma);
            }
        }
    }
    best
}

/// Monte-Carlo 10–90 % width of the optics chain along the edge normal, from first principles:
/// a uniform defocus disc, the Airy pattern (radius drawn from its encircled energy
/// `1 − J0² − J1²`), the pixel square, and the render's canvas pixel (box) and bilinear
/// interpolation (triangle) at half-pixel spacing.
fn monte_carlo_rise(physics: &CameraPhysics, theta: f64) -> f64 {
    use rand::{Rng, SeedableRng};
    let cut = lens::diffraction_cutoff(physics).unwrap();
    let dx = 0.01;
    let table: Vec<f64> = (0..30_000)
        .map(|k| {
            let x = k as f64 * dx;
            1.0 - lens::bessel_j(0, x).powi(2) - lens::bessel_j(1, x).powi(2)
        })
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (c, s) = (theta.cos(), theta.sin());
    let mut proj: Vec<f64> = (0..400_000)
        .map(|_| {
            let e: f64 = rng.gen();
            let k = table.partition_point(|&t| t < e).min(table.len() - 1);
            let r_airy = k as f64 * dx / (std::f64::consts::PI * cut);
            let a1: f64 = rng.gen::<f64>() * std::f64::consts::TAU;
            let r_disc = physics.defocus_radius_px * rng.gen::<f64>().sqrt();
            let a2: f64 = rng.gen::<f64>() * std::f64::consts::TAU;
            let mut x = r_airy * a1.cos() + r_disc * a2.cos();
            let mut y = r_airy * a1.sin() + r_disc * a2.sin();
            for width in [1.0, 0.5, 0.5, 0.5] {
                x += width * (rng.gen::<f64>() - 0.5);
                y += width * (rng.gen::<f64>() - 0.5);
            }
            x * c + y * s
        })
        .collect();
    proj.sort_by(f64::total_cmp);
    let q = |p: f64| proj[(p * proj.len() as f64) as usize];
    q(0.9) - q(0.1)
}

#[test]
fn psf_edge_width_matches_disc_plus_airy_and_is_not_gaussian() {
    let theta = 5f64.to_radians();
    let physics = quiet(CameraPhysics::NAVCAM);
    let hidden = noiseless(HiddenOptics::BASELINE);
    let esf = slanted_edge_esf(&physics, &hidden, theta);
    let rise = crossing(&esf, 0.9) - crossing(&esf, 0.1);
    let expected = monte_carlo_rise(&physics, theta);
    eprintln!("10-90 rise {rise:.4} px, Monte-Carlo optics {expected:.4} px");
    assert!(
        (rise / expected - 1.0).abs() < 0.1,
        "rise {rise} px, optics {expected} px"
    );

    // The same camera with a Gaussian PSF instead: a best-fit Gaussian ESF explains it far
    // better than it explains the disc + Airy camera.
    let gauss_hidden = noiseless(HiddenOptics {
        blur_sigma_px: Some(0.6),
        ..HiddenOptics::BASELINE
    });
    let gauss_esf = slanted_edge_esf(&quiet(CameraPhysics::IDEAL), &gauss_hidden, theta);
    let (res_phys, _) = gaussian_fit_residual(&esf);
    let (res_gauss, _) = gaussian_fit_residual(&gauss_esf);
    eprintln!("Gaussian-fit RMS residual: camera {res_phys:.5}, Gaussian camera {res_gauss:.5}");
    assert!(
        res_phys > 2.0 * res_gauss,
        "residuals {res_phys} vs {res_gauss}"
    );

    // Diffraction wings: the kernel's line-spread function is strongly leptokurtic, the
    // Gaussian camera's is not.
    let kurtosis = |k: &PsfKernel| {
        let lsf = k.line_spread_x();
        let m: f64 = lsf.iter().map(|(d, w)| d * w).sum();
        let var: f64 = lsf.iter().map(|(d, w)| (d - m).powi(2) * w).sum();
        let m4: f64 = lsf.iter().map(|(d, w)| (d - m).powi(4) * w).sum();
        m4 / (var * var) - 3.0
    };
    let k_phys = kurtosis(&psf_kernel(&physics, None, 2));
    let k_gauss = kurtosis(&psf_kernel(&CameraPhysics::IDEAL, Some(0.6), 2));
    eprintln!("LSF excess kurtosis: camera {k_phys:.3}, Gaussian camera {k_gauss:.3}");
    assert!(
        k_phys > 1.0 && k_gauss.abs() < 0.3,
        "kurtosis {k_phys} vs {k_gauss}"
    );
}

#[test]
fn psf_kernel_conserves_energy_and_widens_with_blur() {
    for (physics, blur) in [
        (CameraPhysics::NAVCAM, None),
        (CameraPhysics::NAVCAM, Some(1.2)),
        (CameraPhysics::IDEAL, None),
    ] {
        for n in [1, 2, 3] {
            let k = psf_kernel(&physics, blur, n);
            for phase in &k.phases {
                let s: f64 = phase.iter().map(|&w| f64::from(w)).sum();
                assert!((s * (n * n) as f64 - 1.0).abs() < 1e-5);
                assert!(phase.iter().all(|&w| w >= 0.0));
            }
        }
    }
    // Ideal optics: every sub-position stays in its own pixel.
    assert_eq!(psf_kernel(&CameraPhysics::IDEAL, None, 2).radius, 0);
    let var = |k: &PsfKernel| {
        k.line_spread_x()
            .iter()
            .map(|(d, w)| d * d * w)
            .sum::<f64>()
    };
    // Without diffraction (whose truncated wings have no closed-form variance) the line-spread
    // variance is the sum of the pixel's 1/12, the disc's r²/4, the apodisation's 0.08² and
    // the hidden blur's sigma² (sampled finely: the sampled moments alias the spectrum at
    // multiples of `n` cycles/pixel, which a disc without diffraction still has).
    let disc = CameraPhysics {
        defocus_radius_px: 0.6,
        ..CameraPhysics::IDEAL
    };
    let base = var(&psf_kernel(&disc, None, 8));
    let want = 1.0 / 12.0 + 0.09 + 0.0064;
    assert!((base / want - 1.0).abs() < 0.02, "{base} vs {want}");
    let blurred = var(&psf_kernel(&disc, Some(1.0), 8));
    assert!((blurred - base - 1.0).abs() < 0.02, "{base} {blurred}");
}

#[test]
fn fixed_pattern_repeats_across_frames_and_temporal_noise_does_not() {
    let cam = CameraModel::pinhole(48, 40, 60.0, 60.0, 23.5, 19.5);
    let physics = CameraPhysics {
        prnu_sigma: 0.05,
        ..CameraPhysics::NAVCAM
    };
    let hidden = HiddenOptics::BASELINE;
    let img = flat(&cam, &physics, &hidden, 0.5);
    let a = as_f64(&expose(&img, &cam, &physics, &hidden, 7, 1));
    let b = as_f64(&expose(&img, &cam, &physics, &hidden, 7, 2));
    let c = as_f64(&expose(&img, &cam, &physics, &hidden, 7, 3));
    let d = as_f64(&expose(&img, &cam, &physics, &hidden, 8, 4));
    let (gain, read) = hidden.noise;
    let temporal = gain * 127.5 + read * read + 1.0 / 12.0;
    let diff: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x - y).collect();
    let dv = variance(&diff);
    assert!(
        (dv / (2.0 * temporal) - 1.0).abs() < 0.2,
        "{dv} vs {}",
        2.0 * temporal
    );
    // With the PRNU (6.4 DN) the frame's own variance is far larger.
    assert!(variance(&a) > 3.0 * temporal);
    let avg: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 0.5 * (x + y)).collect();
    let same = correlation(&avg, &c);
    let other = correlation(&c, &d);
    assert!(same > 0.5, "{same}");
    assert!(other.abs() < 0.15, "{other}");
}

#[test]
fn noise_variance_follows_photon_transfer() {
    let cam = CameraModel::pinhole(24, 24, 30.0, 30.0, 11.5, 11.5);
    let physics = CameraPhysics::NAVCAM;
    let hidden = HiddenOptics {
        noise: (0.2, 1.5),
        ..HiddenOptics::BASELINE
    };
    for r in [0.15f32, 0.6] {
        let img = flat(&cam, &physics, &hidden, r);
        let frames: Vec<Vec<f64>> = (0..40)
            .map(|f| as_f64(&expose(&img, &cam, &physics, &hidden, 1, 100 + f)))
            .collect();
        let per_pixel: Vec<f64> = (0..24 * 24)
            .map(|p| variance(&frames.iter().map(|fr| fr[p]).collect::<Vec<_>>()))
            .collect();
        let measured = mean(&per_pixel);
        let signal = 255.0 * f64::from(r);
        let expected = hidden.noise.0 * signal + hidden.noise.1.powi(2) + 1.0 / 12.0;
        assert!(
            (measured / expected - 1.0).abs() < 0.1,
            "r {r}: variance {measured} vs {expected}"
        );
    }
}

#[test]
fn response_and_exposure_on_noiseless_flat_fields() {
    let cam = CameraModel::pinhole(16, 12, 20.0, 20.0, 7.5, 5.5);
    let physics = quiet(CameraPhysics::NAVCAM);
    let cases = [
        (Some((1.2, -0.03)), Some(2.2)),
        (None, Some(1.6)),
        (Some((0.8, 0.04)), None),
        (None, None),
    ];
    let mut checked = 0;
    for (exposure, gamma) in cases {
        let hidden = noiseless(HiddenOptics {
            exposure,
            gamma,
            ..HiddenOptics::BASELINE
        });
        for k in 0..=20 {
            let r = 0.05 * k as f64;
            let (g, o) = exposure.unwrap_or((1.0, 0.0));
            let lin = (g * r + o).clamp(0.0, 1.0);
            let want = 255.0 * lin.powf(1.0 / gamma.unwrap_or(1.0));
            if (want.fract() - 0.5).abs() < 0.02 {
                continue; // a tie: f32 radiance may round either way
            }
            let frame = expose(
                &flat(&cam, &physics, &hidden, r as f32),
                &cam,
                &physics,
                &hidden,
                1,
                2,
            );
            assert!(
                frame.iter().all(|&x| f64::from(x) == want.round()),
                "r {r} {exposure:?} {gamma:?}: {} vs {want}",
                frame[0]
            );
            checked += 1;
        }
    }
    assert!(checked > 70);
}

#[test]
fn bytes_do_not_depend_on_the_thread_count() {
    let cam = CameraModel {
        distortion: Distortion {
            k1: -0.1,
            k2: 0.02,
            ..Distortion::default()
        },
        ..CameraModel::pinhole(64, 48, 70.0, 70.0, 31.5, 23.5)
    };
    let physics = CameraPhysics::NAVCAM;
    let hidden = HiddenOptics {
        vignetting_strength: Some(0.3),
        blur_sigma_px: Some(0.7),
        ..HiddenOptics::BASELINE
    };
    let spec = pinhole_canvas(&cam, 2, psf_margin_px(&physics, &hidden));
    let radiance = (0..spec.width * spec.height)
        .map(|i| {
            let (x, y) = ((i % spec.width) as f32, (i / spec.width) as f32);
            0.5 + 0.4 * (x * 0.3).sin() * (y * 0.2).cos()
        })
        .collect();
    let img = PinholeImage::from_spec(&spec, radiance);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| expose(&img, &cam, &physics, &hidden, 42, 43))
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
    assert_ne!(one, expose(&img, &cam, &physics, &hidden, 42, 44));
}

/// Runtime of one 640 × 512 NAVCAM frame from a 2× canvas (`cargo test ... -- --ignored`).
#[test]
#[ignore]
fn timing_640x512() {
    let cam = CameraModel {
        distortion: Distortion {
            k1: -0.21,
            k2: 0.09,
            p1: 4e-4,
            p2: -2e-4,
            k3: -0.01,
        },
        ..CameraModel::pinhole(640, 512, 416.0, 415.5, 319.5, 255.5)
    };
    let physics = CameraPhysics::NAVCAM;
    let hidden = HiddenOptics {
        vignetting_strength: Some(0.3),
        blur_sigma_px: Some(0.8),
        ..HiddenOptics::BASELINE
    };
    let t = std::time::Instant::now();
    let spec = pinhole_canvas(&cam, 2, psf_margin_px(&physics, &hidden));
    let canvas_time = t.elapsed();
    let radiance = (0..spec.width * spec.height)
        .map(|i| 0.3 + 0.2 * ((i % 97) as f32 / 97.0))
        .collect();
    let img = PinholeImage::from_spec(&spec, radiance);
    let t = std::time::Instant::now();
    let frame = expose(&img, &cam, &physics, &hidden, 1, 2);
    eprintln!(
        "canvas {}x{} in {canvas_time:?}; frame in {:?}; kernel radius {}",
        spec.width,
        spec.height,
        t.elapsed(),
        psf_kernel(&physics, hidden.blur_sigma_px, 2).radius
    );
    assert_eq!(frame.len(), 640 * 512);
    let t = std::time::Instant::now();
    let plain = expose(&img, &cam, &physics, &HiddenOptics::BASELINE, 1, 2);
    eprintln!("frame without hidden blur in {:?}", t.elapsed());
    assert_eq!(plain.len(), 640 * 512);
}
