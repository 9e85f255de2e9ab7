//! Deterministic randomness: one `ChaCha8Rng` per stage, seeded from `hash(seed, stage name)`.
//!
//! House style practice 11: a stage's random stream must not depend on which other stages ran
//! before it or on thread scheduling. Each stage (and each parallel work item, via an index)
//! gets its own generator derived with FNV-1a over the seed and the name, so adding a stage
//! never changes the bytes of another. FNV-1a is used because it is tiny, stable across Rust
//! versions (unlike `DefaultHasher`) and good enough to decorrelate seeds fed to ChaCha.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// FNV-1a 64 over the seed's little-endian bytes, the name and the index.
pub fn stage_hash(seed: u64, stage: &str, index: u64) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |b: u8| {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    seed.to_le_bytes().into_iter().for_each(&mut eat);
    stage.bytes().for_each(&mut eat);
    eat(0xff);
    index.to_le_bytes().into_iter().for_each(&mut eat);
    h
}

/// The generator of one stage.
pub fn stage_rng(seed: u64, stage: &str) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(stage_hash(seed, stage, 0))
}

/// The generator of work item `index` of a stage (parallel loops use one per item).
pub fn item_rng(seed: u64, stage: &str, index: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(stage_hash(seed, stage, index.wrapping_add(1)))
}

/// Integer lattice hash in [0, 1) for value noise: a pure function of (key, i, j).
pub fn lattice(key: u64, i: i64, j: i64) -> f64 {
    let mut z = key
        ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f);
    // splitmix64 finaliser
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in [-1, 1] at `(x, y)` in lattice units.
pub fn value_noise(key: u64, x: f64, y: f64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (i, j) = (fx as i64, fy as i64);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (u, v) = (s(x - fx), s(y - fy));
    let a = lattice(key, i, j);
    let b = lattice(key, i + 1, j);
    let c = lattice(key, i, j + 1);
    let d = lattice(key, i + 1, j + 1);
    let top = a + (b - a) * u;
    let bottom = c + (d - c) * u;
    2.0 * (top + (bottom - top) * v) - 1.0
}

/// Fractal (fBm) noise: octaves from `largest_m` down to `smallest_m`, amplitude ∝ wavelength^h.
pub fn fractal(key: u64, x: f64, y: f64, largest_m: f64, smallest_m: f64, h: f64) -> f64 {
    let mut wavelength = largest_m;
    let mut sum = 0.0;
    let mut octave = 0u64;
    while wavelength >= smallest_m * 0.999 {
        let amp = (wavelength / largest_m).powf(h);
        let k = key.wrapping_add(octave.wrapping_mul(0x632b_e59b_d9b4_e019));
        sum += amp * value_noise(k, x / wavelength + 0.37 * octave as f64, y / wavelength);
        wavelength *= 0.5;
        octave += 1;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn stages_are_independent_and_repeatable() {
        let a: u64 = stage_rng(7, "terrain").gen();
        let b: u64 = stage_rng(7, "terrain").gen();
        let c: u64 = stage_rng(7, "scans").gen();
        let d: u64 = stage_rng(8, "terrain").gen();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
        assert_ne!(stage_hash(1, "x", 0), stage_hash(1, "x", 1));
    }

    #[test]
    fn value_noise_is_bounded_and_continuous() {
        for k in 0..200 {
            let x = k as f64 * 0.173;
            let v = value_noise(3, x, 0.5 * x);
            assert!((-1.0..=1.0).contains(&v));
            let w = value_noise(3, x + 1e-6, 0.5 * x);
            assert!((v - w).abs() < 1e-4);
        }
    }
}
