//! Writes real | render | |difference| PNG strips of every view of an entry, for eyeballing a
//! validation: the images `validate` compares (contrast-normalised), as its observer sees them.
//! `cargo run -p regolith-validator --example dump_view -- DB ENTRY OUTDIR`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_validator::features::Detector;
use regolith_validator::validate::{ValidateOptions, Validator, ViewArtifacts};

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let db = regolith_reader::Database::open(&a[0]).expect("db");
    let view = db.release("latest").expect("release");
    std::fs::create_dir_all(&a[2]).unwrap();
    // One cheap detector: the strips, not the figures, are wanted.
    let opts = ValidateOptions {
        detectors: vec![Detector::Fast],
        ..ValidateOptions::default()
    };
    let validator = Validator::new(&view, opts).unwrap();
    let write = |v: &ViewArtifacts<'_>| {
        let (real, sim) = (v.real_a, v.render);
        let (w, h) = (real.width, real.height);
        let mut strip = vec![0u8; 3 * w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                strip[y * 3 * w + x] = (real.data[i] * 255.0) as u8;
                strip[y * 3 * w + w + x] = if v.mask[i] == 255 {
                    (sim.data[i] * 255.0) as u8
                } else {
                    0
                };
                strip[y * 3 * w + 2 * w + x] = ((real.data[i] - sim.data[i]).abs() * 255.0) as u8;
            }
        }
        image::save_buffer(
            format!("{}/{}_{}.png", a[2], v.capture, v.camera),
            &strip,
            (3 * w) as u32,
            h as u32,
            image::ColorType::L8,
        )
        .unwrap();
    };
    validator.entry(&a[1], Some(&write)).unwrap();
}
