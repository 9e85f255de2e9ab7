//! Aggregation over captures: mean with a two-sided 95 % Student-t confidence interval.

use serde::Serialize;

/// Mean and 95 % confidence interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    /// Number of values.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Lower bound.
    pub low: f64,
    /// Upper bound.
    pub high: f64,
}

/// Two-sided 97.5 % quantile of Student's t with `df` degrees of freedom.
fn t975(df: usize) -> f64 {
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    T.get(df.saturating_sub(1)).copied().unwrap_or(1.96)
}

/// Mean and 95 % CI of `values` (a single value gives a zero-width interval).
pub fn mean_ci(values: &[f64]) -> Interval {
    let n = values.len();
    if n == 0 {
        return Interval {
            n,
            mean: 0.0,
            low: 0.0,
            high: 0.0,
        };
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n == 1 {
        return Interval {
            n,
            mean,
            low: mean,
            high: mean,
        };
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let half = t975(n - 1) * (var / n as f64).sqrt();
    Interval {
        n,
        mean,
        low: mean - half,
        high: mean + half,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_interval() {
        let i = mean_ci(&[1.0, 2.0, 3.0, 4.0]);
        // sd = 1.29099, se = 0.645497, t(3) = 3.182
        assert!((i.mean - 2.5).abs() < 1e-12);
        assert!((i.high - (2.5 + 3.182 * 0.645_497)).abs() < 1e-4);
        assert_eq!(mean_ci(&[]).n, 0);
    }
}
