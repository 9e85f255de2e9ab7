//! The `noise` effect, measured directly from the repeat frames of a pose.
//!
//! Two frames at one pose differ only by sensor noise, so `Var(a − b) / 2` per intensity bin of
//! the frame mean is the noise variance at that intensity, independent of the render. A
//! weighted linear fit `Var = gain · DN + read²` gives the catalogue parameters (shot noise and
//! read noise). Every camera has some noise; the effect is named only when its standard
//! deviation at mid-grey (DN 128) exceeds [`NOISE_FLOOR_DN`], the noise of a good 8-bit
//! machine-vision camera, and the current model does not already predict it. Its explained
//! fraction is the share of the measured variance above the floor.
//!
//! The fit here is of the output levels: right for a linear camera only. Where the views show a
//! dark background, the gap's noise stage takes the gain and read noise from the photon-transfer
//! fit of [`super::response`] instead, on the linear signal under the response curve (mini
//! seeds 101–105: within 1.1 %, where this fit read up to 11 % off).

/// Noise standard deviation at DN 128 below which noise is nominal and not named.
pub const NOISE_FLOOR_DN: f64 = 3.0;
const BINS: usize = 16;

/// The measured noise.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseFit {
    /// DN of variance per DN of signal.
    pub gain: f64,
    /// Read noise standard deviation, DN.
    pub read_sigma: f64,
    /// Standard deviation at DN 128.
    pub sigma_at_128: f64,
    /// `(bin centre DN, variance, pixels)` per intensity bin.
    pub by_intensity: Vec<(f64, f64, usize)>,
}

/// Measures noise from pairs of frames (`a`, `b`) on the pixels where `mask` is true; `None`
/// when no view has two frames.
pub fn measure(pairs: &[(&[f32], &[f32], &[bool])]) -> Option<NoiseFit> {
    let mut sum = [0.0f64; BINS];
    let mut n = [0usize; BINS];
    for (a, b, mask) in pairs {
        for ((x, y), m) in a.iter().zip(b.iter()).zip(mask.iter()) {
            let mean = 0.5 * f64::from(x + y);
            if !*m || !(2.0..=253.0).contains(&mean) {
                continue;
            }
            let bin = ((mean / 256.0) * BINS as f64) as usize;
            sum[bin.min(BINS - 1)] += 0.5 * f64::from(x - y).powi(2);
            n[bin.min(BINS - 1)] += 1;
        }
    }
    let by_intensity: Vec<(f64, f64, usize)> = (0..BINS)
        .filter(|&i| n[i] >= 50)
        .map(|i| {
            (
                (i as f64 + 0.5) * 256.0 / BINS as f64,
                sum[i] / n[i] as f64,
                n[i],
            )
        })
        .collect();
    if by_intensity.is_empty() {
        return None;
    }
    // Weighted least squares of var = gain * dn + c.
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(x, y, k) in &by_intensity {
        let w = k as f64;
        sw += w;
        sx += w * x;
        sy += w * y;
        sxx += w * x * x;
        sxy += w * x * y;
    }
    let det = sw * sxx - sx * sx;
    let (gain, c) = if det.abs() > 1e-9 {
        let gain = ((sw * sxy - sx * sy) / det).max(0.0);
        (gain, ((sy - gain * sx) / sw).max(0.0))
    } else {
        (0.0, sy / sw)
    };
    Some(NoiseFit {
        gain,
        read_sigma: c.sqrt(),
        sigma_at_128: (gain * 128.0 + c).sqrt(),
        by_intensity,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::{Effect, SensorModel};

    #[test]
    fn recovers_the_sensor_noise_model() {
        let (w, h) = (256, 256);
        let radiance: Vec<f32> = (0..w * h)
            .map(|i| (i % w) as f32 / w as f32 * 0.95)
            .collect();
        let model = SensorModel::from(vec![Effect::Noise {
            gain: 0.3,
            read_sigma: 2.0,
        }]);
        let cam = regolith_format::camera_model::CameraModel::pinhole(
            256, 256, 200.0, 200.0, 127.5, 127.5,
        );
        let a = model.image(&radiance, w, h, &cam, 1);
        let b = model.image(&radiance, w, h, &cam, 2);
        let mask = vec![true; w * h];
        let f = measure(&[(&a, &b, &mask)]).unwrap();
        assert!((f.gain - 0.3).abs() < 0.03, "{f:?}");
        assert!((f.read_sigma - 2.0).abs() < 0.3, "{f:?}");
    }
}
