//! Procedural texture detail: what a `texture-lowpass` adds to renders.
//!
//! A texture low-passed by a ground Gaussian of σ has lost detail that no filter can bring
//! back (sharpening it amplifies its noise, see `gap::texture`). What can be given back is
//! detail with the right *statistics*: a Gaussian random field whose power spectrum is the
//! power the low-pass removed, so renders hold as much fine texture as the real surface
//! shows, and feature detectors and the spectrum see it, though not the real pattern. The
//! detail has zero mean, so the expected render (the photometric comparison) is unchanged;
//! like sensor noise it is a property of a sample.
//!
//! The spectrum, per texture cell, in cycles per cell `f` (normative, `format-spec/registry.md`):
//! 1. The texture's periodogram `P(f)` (mean removed, separable Hann window, `|F|² / Σ w²`)
//!    averaged over annuli one frequency step `1 / min(width, height)` wide.
//! 2. The texture's noise floor `N` (what its instrument added after any low-pass: range and
//!    reflectance noise) is the mean of `P` over `f ≥ 0.4` ([`NOISE_BAND`]).
//! 3. The real albedo's spectrum is modelled as `R(f) = a · f^(−β)`, fitted by least squares in
//!    log–log to `(P(f) − N) / (G_σ(f)² · G_o(f)²)`. `G_s(f) = exp(−2π² s² f²)` is the transfer
//!    of a Gaussian of `s` cells, `σ` the low-pass and `o` the texture's own blur
//!    ([`own_blur_m`]), both in cells. The division is trusted from the second
//!    annulus up to the last one before it multiplies by more than [`MAX_RESTORE`] or `P` falls
//!    under `2 N`, at `f_c`; the fit uses `[f_c / 2, f_c]` (the fall-off where the signal is
//!    last seen: the coarse patches' slope is shallower and would overstate the fine detail),
//!    `β` clamped to [[`MIN_SLOPE`], [`MAX_SLOPE`]].
//! 4. The detail's spectrum is `R(f) · G_o(f)² · (1 − G_σ(f)²)`: the power between a faithful
//!    texture of these cells (the real albedo blurred by its own blur) and this one.
//!
//! The field is white Gaussian noise (ChaCha8, seeded from the grid's size, cell and σ, so the
//! same entry and model always give the same detail) shaped by that spectrum in the Fourier
//! domain; it is added to every cell whose albedo is above 0 and the sum is clamped to [0, 1].
//! A texture without three usable annuli gets no detail.
//!
//! Measured on mini's laser textures (1 cm cells) with a hidden low-pass of 18.0 and 18.9 mm
//! (seeds 101, 102; the same campaigns with nothing hidden give the faithful texture): in the
//! bands 0.09–0.25 cycles per cell the low-passed texture holds 0.56–0.91 of the faithful
//! one's power, with the detail 0.94–1.45 (seed 101) and 0.80–1.59 (seed 102). Fitting over
//! the whole trusted band instead of its upper octave overshot seed 102 by 2–2.5×. What
//! limits it: much of a laser texture's power at those frequencies is the instrument's noise,
//! coloured by the gridding (seed 102 at 0.094 cycles per cell: about half of the faithful
//! texture's power), and it survives the low-pass, so the division by `G_σ²` reads part of it
//! as lost signal; the white floor of step 2 removes only its tail.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rustfft::num_complex::Complex;

use crate::metrics::spectrum::{dft_frequency, fft2, hann_fft};
use crate::render::AlbedoGrid;

/// The `A` of [`own_blur_m`], metres (see [`OWN_BLUR_PER_CELL`]).
pub const OWN_BLUR_BASE_M: f64 = 0.0123;

/// The `b` of [`own_blur_m`]. With [`OWN_BLUR_BASE_M`] a least-squares fit to the effective
/// blur of faithful laser textures: estec seed 1 (full scans) at 1, 1.5, 2 and 3 cm cells
/// read 13.6, 16.4, 18.7 and 22.8 mm (model 13.9, 15.6, 17.7, 22.7); mini seeds 101–106 at
/// 1 cm 13.8 mm on average (11.7–16.2), at 2 cm 15.9 mm (14.3–18.4).
pub const OWN_BLUR_PER_CELL: f64 = 0.64;

/// Expected effective blur of a faithful laser texture of `cell_m` cells, metres:
/// `sqrt(A² + (b·c)²)` (measured by `gap::texture`).
pub fn own_blur_m(cell_m: f64) -> f64 {
    (OWN_BLUR_BASE_M.powi(2) + (OWN_BLUR_PER_CELL * cell_m).powi(2)).sqrt()
}

/// Largest factor the fitted band divides the periodogram by (the low-pass's power transfer at
/// least 1/4): beyond it the texture's noise, not its signal, would set the fit.
pub const MAX_RESTORE: f64 = 4.0;

/// Share of the frequency range (from the top, in cycles per cell up to 0.5) whose mean power
/// is taken as the texture's noise floor.
pub const NOISE_BAND: f64 = 0.8;

/// Smallest spectral slope β of the fitted power law.
pub const MIN_SLOPE: f64 = 0.5;

/// Largest spectral slope β of the fitted power law.
pub const MAX_SLOPE: f64 = 6.0;

/// Power transfer `G_s(f)²` of a Gaussian of `s` cells at `f` cycles per cell.
fn gauss2(s: f64, f: f64) -> f64 {
    (-4.0 * std::f64::consts::PI.powi(2) * s * s * f * f).exp()
}

/// The power law `(a, β)` of the texture's spectrum without the low-pass, or `None` without
/// three usable annuli.
fn fit_power_law(grid: &AlbedoGrid, sigma: f64, own: f64) -> Option<(f64, f64)> {
    let (w, h) = (grid.width, grid.height);
    let values: Vec<f64> = grid
        .value
        .iter()
        .map(|&v| if v.is_finite() { f64::from(v) } else { 0.0 })
        .collect();
    let (spectrum, energy) = hann_fft(&values, w, h);
    if energy <= 0.0 {
        return None;
    }
    let step = 1.0 / w.min(h) as f64;
    let annuli = (0.5 / step) as usize;
    let (mut sum, mut count) = (vec![0.0; annuli + 1], vec![0usize; annuli + 1]);
    for y in 0..h {
        let fy = dft_frequency(y, h);
        for x in 0..w {
            let f = dft_frequency(x, w).hypot(fy);
            let k = (f / step).round() as usize;
            if k >= 1 && k <= annuli {
                sum[k] += spectrum[y * w + x].norm_sqr() / energy;
                count[k] += 1;
            }
        }
    }
    let power: Vec<(f64, f64)> = (1..=annuli)
        .filter(|&k| count[k] > 0)
        .map(|k| (k as f64 * step, sum[k] / count[k] as f64))
        .collect();
    // The texture's white noise floor (what its instrument adds, which a low-pass applied to
    // the albedo before does not remove): the mean power of the top fifth of the band.
    let top: Vec<f64> = power
        .iter()
        .filter(|(f, _)| *f >= NOISE_BAND * 0.5)
        .map(|p| p.1)
        .collect();
    let floor = top.iter().sum::<f64>() / top.len().max(1) as f64;
    let points: Vec<(f64, f64)> = power
        .iter()
        .skip(1)
        .map(|&(f, p)| (f, p, gauss2(sigma, f) * gauss2(own, f)))
        .take_while(|&(_, p, t)| t * MAX_RESTORE >= 1.0 && p > 2.0 * floor)
        .map(|(f, p, t)| (f.ln(), ((p - floor) / t).ln()))
        .collect();
    // The fall-off where the signal is last seen, not the coarse patches' (shallower) one.
    let top = points.last()?.0;
    let points: Vec<(f64, f64)> = points
        .into_iter()
        .filter(|p| p.0 >= top - std::f64::consts::LN_2)
        .collect();
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = (
        points.iter().map(|p| p.0).sum::<f64>() / n,
        points.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let beta = if sxx > 0.0 { -sxy / sxx } else { MIN_SLOPE };
    let beta = beta.clamp(MIN_SLOPE, MAX_SLOPE);
    // With the slope fixed, the intercept is the mean of ln R + β ln f.
    let ln_a = my + beta * mx;
    Some((ln_a.exp(), beta))
}

/// `grid` with the procedural detail a low-pass of `sigma_m` (metres) removed (see the module
/// docs); a copy of `grid` when there is nothing to add.
pub fn restore_detail(grid: &AlbedoGrid, sigma_m: f64) -> AlbedoGrid {
    let mut out = grid.clone();
    let (w, h) = (grid.width, grid.height);
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if w < 8 || h < 8 || grid.value.len() != w * h || !positive(grid.cell_m) || !positive(sigma_m) {
        return out;
    }
    let (sigma, own) = (sigma_m / grid.cell_m, own_blur_m(grid.cell_m) / grid.cell_m);
    let Some((a, beta)) = fit_power_law(grid, sigma, own) else {
        return out;
    };
    let seed = (w as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (h as u64).rotate_left(21)
        ^ grid.cell_m.to_bits().rotate_left(42)
        ^ sigma_m.to_bits();
    let field = shaped_noise(w, h, seed, |f| {
        (a * f.powf(-beta) * gauss2(own, f) * (1.0 - gauss2(sigma, f))).sqrt()
    });
    for (v, d) in out.value.iter_mut().zip(&field) {
        if *v > 0.0 {
            *v = (f64::from(*v) + d).clamp(0.0, 1.0) as f32;
        }
    }
    out
}

/// A `w x h` Gaussian random field: white noise (ChaCha8 from `seed`) whose Fourier
/// coefficient at radial frequency `f > 0` (cycles per cell) is multiplied by `amplitude(f)`
/// (the square root of the field's power spectrum per cell) and the mean set to 0.
fn shaped_noise(w: usize, h: usize, seed: u64, amplitude: impl Fn(f64) -> f64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut field: Vec<Complex<f64>> = (0..w * h)
        .map(|_| Complex::new(StandardNormal.sample(&mut rng), 0.0))
        .collect();
    fft2(&mut field, w, h, false);
    for y in 0..h {
        let fy = dft_frequency(y, h);
        for x in 0..w {
            let f = dft_frequency(x, w).hypot(fy);
            field[y * w + x] *= if f > 0.0 { amplitude(f) } else { 0.0 };
        }
    }
    fft2(&mut field, w, h, true);
    let n = (w * h) as f64;
    field.iter().map(|c| c.re / n).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::gaussian_blur;

    /// A power-law random texture (β = 2) around 0.35, `n x n` cells of 1 cm.
    fn power_law_grid(n: usize, seed: u64) -> AlbedoGrid {
        let field = shaped_noise(n, n, seed, |f| 6e-3 / f);
        AlbedoGrid {
            origin_m: [0.0, 0.0],
            cell_m: 0.01,
            width: n,
            height: n,
            value: field.iter().map(|d| (0.35 + d) as f32).collect(),
        }
    }

    /// Mean power of `v` (row-major `n x n`) in the annulus of `lo..hi` cycles per cell.
    fn band_power(v: &[f32], n: usize, lo: f64, hi: f64) -> f64 {
        let values: Vec<f64> = v.iter().map(|&x| f64::from(x)).collect();
        let (s, e) = hann_fft(&values, n, n);
        let (mut sum, mut count) = (0.0, 0usize);
        for y in 0..n {
            for x in 0..n {
                let f = dft_frequency(x, n).hypot(dft_frequency(y, n));
                if f >= lo && f < hi {
                    sum += s[y * n + x].norm_sqr() / e;
                    count += 1;
                }
            }
        }
        sum / count.max(1) as f64
    }

    #[test]
    fn detail_gives_back_the_power_a_low_pass_removed() {
        let n = 256;
        let truth = power_law_grid(n, 7);
        // A faithful texture holds the truth blurred by its own blur; this one by more.
        let own = own_blur_m(0.01) / 0.01;
        let faithful = gaussian_blur(&truth.value, n, n, own);
        let sigma_m = 0.02;
        let total = (own * own + (sigma_m / 0.01_f64).powi(2)).sqrt();
        let smooth = AlbedoGrid {
            value: gaussian_blur(&truth.value, n, n, total),
            ..truth.clone()
        };
        let restored = restore_detail(&smooth, sigma_m);
        // In the band the low-pass takes most from (wavelengths 4–8 cm), the smooth texture
        // holds a small part of the faithful one's power; with the detail, about all of it.
        let (lo, hi) = (0.125, 0.25);
        let p_faithful = band_power(&faithful, n, lo, hi);
        let p_smooth = band_power(&smooth.value, n, lo, hi);
        let p_restored = band_power(&restored.value, n, lo, hi);
        assert!(p_smooth < 0.1 * p_faithful, "{p_smooth} vs {p_faithful}");
        let ratio = p_restored / p_faithful;
        assert!(
            (0.5..2.0).contains(&ratio),
            "restored/faithful power {ratio}"
        );
        // The coarse pattern is untouched: the detail has no power at the lowest frequencies.
        let coarse = |v: &[f32]| band_power(v, n, 0.0, 0.02);
        assert!((coarse(&restored.value) / coarse(&smooth.value) - 1.0).abs() < 0.1);
        // Deterministic, and a different σ gives different detail.
        assert_eq!(restore_detail(&smooth, sigma_m), restored);
        assert_ne!(restore_detail(&smooth, 0.025).value, restored.value);
    }

    #[test]
    fn nothing_to_add_leaves_the_grid_as_it_is() {
        let g = power_law_grid(64, 3);
        assert_eq!(restore_detail(&g, 0.0), g);
        let tiny = AlbedoGrid {
            width: 4,
            height: 4,
            value: vec![0.3; 16],
            ..g.clone()
        };
        assert_eq!(restore_detail(&tiny, 0.02), tiny);
        // A constant texture has no spectrum to fit.
        let flat = AlbedoGrid {
            value: vec![0.3; 64 * 64],
            ..g
        };
        assert_eq!(restore_detail(&flat, 0.02), flat);
    }
}
