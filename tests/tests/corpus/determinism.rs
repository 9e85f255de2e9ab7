//! Byte-identical output per seed on any thread count, and seeds matter.

use std::collections::BTreeMap;

use regolith_corpus::{generate, GenerateOptions, HiddenSpec, Preset};
use regolith_model_captures::ModelCaptures;

use super::common::files;

fn run(threads: usize, seed: u64) -> BTreeMap<String, Vec<u8>> {
    run_with(threads, seed, None)
}

fn run_with(threads: usize, seed: u64, captures: Option<usize>) -> BTreeMap<String, Vec<u8>> {
    let dir = tempfile::tempdir().unwrap();
    let opts = GenerateOptions {
        preset: Preset::Mini,
        seed,
        full: false,
        captures,
        hidden: vec![
            HiddenSpec::named("vignetting"),
            HiddenSpec::named("noise"),
            HiddenSpec::named("texture-lowpass"),
        ],
        auto_exposure: 0.0,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let summary = pool
        .install(|| generate(&opts, dir.path(), &ModelCaptures, &|_, _| {}))
        .unwrap();
    let got = files(dir.path());
    assert_eq!(
        summary.files,
        got.keys().cloned().collect::<Vec<_>>(),
        "summary lists exactly the files"
    );
    got
}

#[test]
fn same_seed_same_bytes_on_one_and_two_threads() {
    let one = run(1, 11);
    let two = run(2, 11);
    assert_eq!(
        one.keys().collect::<Vec<_>>(),
        two.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &one {
        assert!(
            bytes == &two[name],
            "{name} differs between 1 and 2 threads"
        );
    }
    assert!(one.len() >= 30);
    let other = run(2, 12);
    assert_ne!(
        one["scans/pos1.asc"], other["scans/pos1.asc"],
        "the seed changes the data"
    );
    assert_ne!(
        one["truth/hidden.json"], other["truth/hidden.json"],
        "hidden defaults are drawn from the seed"
    );
}

#[test]
fn bad_inputs_cover_every_kind_with_a_readme() {
    let dir = tempfile::tempdir().unwrap();
    let written = regolith_corpus::write_bad_inputs(dir.path()).unwrap();
    for f in [
        "truncated.ply",
        "nan_coordinates.asc",
        "vrml_index_out_of_range.wrl",
        "vicon_no_units.csv",
        "vicon_text_in_numeric.csv",
        "mixed_delimiters.asc",
        "camera_matrix_3x2.yaml",
        "truncated.png",
        "missing_file/campaign.toml",
        "path_escape/campaign.toml",
        "empty.csv",
    ] {
        assert!(written.iter().any(|w| w == f), "{f}");
    }
    let readme = std::fs::read_to_string(dir.path().join("README.md")).unwrap();
    assert!(readme.contains("`truncated.ply`") && readme.contains("escapes the campaign"));
    let yaml = std::fs::read_to_string(dir.path().join("camera_matrix_3x2.yaml")).unwrap();
    let data = yaml
        .split("data: [")
        .nth(1)
        .unwrap()
        .split(']')
        .next()
        .unwrap();
    assert_eq!(data.split(',').count(), 6, "a 3x2 matrix holds 6 numbers");
    assert!(yaml.contains("cols: 2"));
    let csv = std::fs::read_to_string(dir.path().join("vicon_no_units.csv")).unwrap();
    assert!(csv.contains("Frame,Sub Frame") && !csv.contains("mm"));
    let png = std::fs::read(dir.path().join("truncated.png")).unwrap();
    assert!(
        png.starts_with(b"\x89PNG")
            && png::Decoder::new(std::io::Cursor::new(&png))
                .read_info()
                .and_then(|mut r| {
                    let mut b = vec![0; r.output_buffer_size()];
                    r.next_frame(&mut b).map(|_| ())
                })
                .is_err()
    );
    assert!(std::fs::read(dir.path().join("empty.csv"))
        .unwrap()
        .is_empty());
    let escape = std::fs::read_to_string(dir.path().join("path_escape/campaign.toml")).unwrap();
    assert!(
        toml::from_str::<toml::Value>(&escape).is_ok(),
        "the campaign itself parses; only the path is bad"
    );
}

#[test]
fn more_captures_keep_the_first_locations() {
    let two = run_with(2, 11, None);
    let four = run_with(2, 11, Some(4));
    let locs = |m: &BTreeMap<String, Vec<u8>>| {
        m.keys()
            .filter(|k| k.starts_with("vicon/loc"))
            .cloned()
            .collect::<Vec<_>>()
    };
    assert_eq!(locs(&two), ["vicon/loc01.csv", "vicon/loc02.csv"]);
    assert_eq!(locs(&four).len(), 4);
    for (name, bytes) in &two {
        let per_location = name.starts_with("captures/") || name.starts_with("vicon/loc");
        if per_location {
            assert!(
                four.get(name) == Some(bytes),
                "{name} changed with more captures"
            );
        }
    }
    assert_ne!(
        two["campaign.toml"], four["campaign.toml"],
        "the campaign lists them"
    );
}
