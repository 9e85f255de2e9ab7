//! Whether an effect fitted on each capture location alone comes out the same everywhere.
//!
//! An effect of the camera (a falloff, a response curve, an exposure offset) or of the entry
//! (its texture's transfer) is one number for every capture; a disagreement it stands in for
//! (a pose or lighting error of one capture, a part of the terrain the entry gets wrong) is
//! not. Given each capture's estimate and its standard error, the weighted spread about their
//! weighted mean is χ²-distributed with one degree of freedom fewer than the captures when
//! they agree; its upper tail probability is the test's p-value.

/// The agreement of per-capture estimates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Consistency {
    /// `Σ (θₖ − θ̄)² / σₖ²` about the inverse-variance weighted mean `θ̄`.
    pub chi2: f64,
    /// Degrees of freedom: the captures less one.
    pub dof: usize,
    /// Probability of a χ² at least this large if every capture measured the same value.
    pub p: f64,
    /// The inverse-variance weighted mean.
    pub mean: f64,
}

/// The agreement of `values` with standard errors `std_errs` (one per capture); `None` with
/// fewer than two captures or a non-positive or non-finite error or value.
pub fn across(values: &[f64], std_errs: &[f64]) -> Option<Consistency> {
    if values.len() < 2
        || values.len() != std_errs.len()
        || values.iter().any(|v| !v.is_finite())
        || std_errs.iter().any(|s| !(s.is_finite() && *s > 0.0))
    {
        return None;
    }
    let w: Vec<f64> = std_errs.iter().map(|s| 1.0 / (s * s)).collect();
    let mean = values.iter().zip(&w).map(|(v, w)| v * w).sum::<f64>() / w.iter().sum::<f64>();
    let chi2: f64 = values
        .iter()
        .zip(&w)
        .map(|(v, w)| (v - mean).powi(2) * w)
        .sum();
    let dof = values.len() - 1;
    Some(Consistency {
        chi2,
        dof,
        p: chi2_sf(chi2, dof as f64),
        mean,
    })
}

/// The upper tail `P(X ≥ x)` of a χ² distribution with `dof` degrees of freedom: the
/// regularized upper incomplete gamma function `Q(dof/2, x/2)`.
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    gamma_q(0.5 * dof, 0.5 * x)
}

/// `Q(a, x)`: by its series below `x = a + 1`, by its continued fraction above (where each
/// converges fast).
fn gamma_q(a: f64, x: f64) -> f64 {
    if x < a + 1.0 {
        1.0 - gamma_p_series(a, x)
    } else {
        gamma_q_fraction(a, x)
    }
}

const ITERATIONS: usize = 500;
const TINY: f64 = 1e-300;

fn gamma_p_series(a: f64, x: f64) -> f64 {
    let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
    for _ in 0..ITERATIONS {
        n += 1.0;
        term *= x / n;
        sum += term;
        if term.abs() < sum.abs() * f64::EPSILON {
            break;
        }
    }
    sum * (-x + a * x.ln() - ln_gamma(a)).exp()
}

/// Lentz's evaluation of the continued fraction of `Q(a, x)`.
fn gamma_q_fraction(a: f64, x: f64) -> f64 {
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..=ITERATIONS {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < f64::EPSILON {
            break;
        }
    }
    (-x + a * x.ln() - ln_gamma(a)).exp() * h
}

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, nine coefficients: about 15 digits).
fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1 − x) = π / sin(πx).
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against SciPy 1.17's `scipy.stats.chi2.sf(x, dof)`.
    #[test]
    fn the_tail_matches_scipy() {
        for (x, dof, scipy) in [
            (3.841_458_820_694_124, 1.0, 0.049_999_999_999_999_89),
            (0.5, 1.0, 0.479_500_122_186_953_37),
            (10.0, 3.0, 0.018_566_135_463_043_25),
            (20.0, 7.0, 0.005_569_683_072_945_574),
            (1e-3, 2.0, 0.999_500_124_979_169_3),
            (50.0, 4.0, 3.610_865_404_890_647e-10),
            (7.0, 7.0, 0.428_879_857_553_054_86),
            (0.0, 3.0, 1.0),
        ] {
            let ours = chi2_sf(x, dof);
            assert!(
                (ours - scipy).abs() <= 1e-10 * scipy.max(1e-300) + 1e-14,
                "x {x} dof {dof}: {ours} against {scipy}"
            );
        }
    }

    #[test]
    fn agreeing_captures_pass_and_a_stray_one_does_not() {
        let agree = across(&[1.00, 1.02, 0.99], &[0.02, 0.02, 0.02]).unwrap();
        assert_eq!(agree.dof, 2);
        assert!(agree.p > 0.5, "{agree:?}");
        assert!((agree.mean - 1.003_333).abs() < 1e-5);
        let stray = across(&[1.00, 1.02, 1.20], &[0.02, 0.02, 0.02]).unwrap();
        assert!(stray.p < 1e-6, "{stray:?}");
        // The same spread is consistent when the captures' errors are large.
        assert!(across(&[1.00, 1.02, 1.20], &[0.1, 0.1, 0.1]).unwrap().p > 0.05);
        assert_eq!(across(&[1.0], &[0.1]), None);
        assert_eq!(across(&[1.0, 2.0], &[0.1, 0.0]), None);
    }
}
