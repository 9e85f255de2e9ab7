//! Shared helpers of the corpus self-checks: one mini campaign per process, truth readers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use regolith_corpus::{generate, GenerateOptions, HiddenSpec, Preset};
use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;
use regolith_validator::render::HeightGrid;
use serde_json::Value;

/// Generates mini with `hidden` effects into a fresh temp dir (kept for the process).
pub fn mini(seed: u64, hidden: &[(&str, &[(&str, f64)])]) -> PathBuf {
    let dir = tempfile::tempdir().unwrap().keep();
    let mut specs: Vec<HiddenSpec> = Vec::new();
    for (name, params) in hidden {
        let mut h = HiddenSpec::named(name);
        for (k, v) in *params {
            h.params.insert(k.to_string(), *v);
        }
        specs.push(h);
    }
    generate(
        &GenerateOptions {
            preset: Preset::Mini,
            seed,
            full: false,
            captures: None,
            hidden: specs,
            auto_exposure: 0.0,
        },
        &dir,
        &regolith_model_captures::ModelCaptures,
        &|_, _| {},
    )
    .unwrap();
    dir
}

/// The plain mini campaign of seed 7, generated once.
pub fn plain() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| mini(7, &[]))
}

pub fn json(dir: &Path, rel: &str) -> Value {
    serde_json::from_slice(&std::fs::read(dir.join(rel)).unwrap()).unwrap()
}

pub fn pose(v: &Value) -> Pose {
    serde_json::from_value(v.clone()).unwrap()
}

pub fn camera(dir: &Path, name: &str, which: &str) -> CameraModel {
    serde_json::from_value(json(dir, "truth/cameras.json")["cameras"][name][which].clone()).unwrap()
}

/// Reads the truth height grid back from height.exr + height.json.
pub fn height_grid(dir: &Path) -> HeightGrid {
    let meta = json(dir, "truth/height.json");
    let img = exr::prelude::read_first_flat_layer_from_file(dir.join("truth/height.exr")).unwrap();
    let ch = &img.layer_data.channel_data.list[0];
    assert_eq!(ch.name.to_string(), "Z");
    let z = match &ch.sample_data {
        exr::prelude::FlatSamples::F32(v) => v.clone(),
        other => panic!("expected f32 samples, got {other:?}"),
    };
    HeightGrid {
        origin_m: [
            meta["origin_m"][0].as_f64().unwrap(),
            meta["origin_m"][1].as_f64().unwrap(),
        ],
        cell_m: meta["cell_m"].as_f64().unwrap(),
        width: meta["width"].as_u64().unwrap() as usize,
        height: meta["height"].as_u64().unwrap() as usize,
        z,
    }
}

/// Decodes an 8-bit grey PNG.
pub fn grey(path: &Path) -> (usize, usize, Vec<u8>) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Grayscale);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width as usize, info.height as usize, buf)
}

/// Parses a RiSCAN ASCII file written as `X[m] Y[m] Z[m] Reflectance[dB]`.
pub fn asc(path: &Path) -> Vec<[f64; 4]> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("X[m] Y[m] Z[m] Reflectance[dB]"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(' ').map(|t| t.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect()
}

/// Parses `Name,X,Y,Z` CSV.
pub fn named_points(path: &Path) -> Vec<(String, [f64; 3])> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[0].to_string(),
                [
                    f[1].parse().unwrap(),
                    f[2].parse().unwrap(),
                    f[3].parse().unwrap(),
                ],
            )
        })
        .collect()
}

/// Mean of `img` over a square window of half-size `r` around `(u, v)`.
pub fn window_mean(w: usize, img: &[f32], u: usize, v: usize, r: usize) -> f64 {
    let mut s = 0.0;
    let mut n = 0.0;
    for y in v - r..=v + r {
        for x in u - r..=u + r {
            s += f64::from(img[y * w + x]);
            n += 1.0;
        }
    }
    s / n
}

/// Every file under `dir`, by path relative to it, with its bytes.
pub fn files(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(
                    p.strip_prefix(dir).unwrap().to_string_lossy().into_owned(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}
