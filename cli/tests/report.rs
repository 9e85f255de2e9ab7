//! `regolith validate --report DIR` on a compiled mini corpus campaign: index.html links only
//! files inside DIR, every linked PNG decodes at the expected size, and a second run writes the
//! same bytes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

use common::regolith;
use regolith_validator::report::{overlay_scale, plot::CHART_SIZE};
use serde_json::Value;

fn ok(out: &Output, codes: &[i32]) {
    assert!(
        out.status.code().is_some_and(|c| codes.contains(&c)),
        "exit {:?}\n{}\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn png_size(path: &Path) -> (u32, u32) {
    let dec = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut r = dec
        .read_info()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r
        .next_frame(&mut buf)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (info.width, info.height)
}

/// Every `src="..."` of the page.
fn image_links(html: &str) -> Vec<String> {
    html.split("src=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap().to_string())
        .collect()
}

fn all_files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(all_files(&p));
        } else {
            out.insert(
                p.strip_prefix(dir).unwrap().to_path_buf(),
                std::fs::read(&p).unwrap(),
            );
        }
    }
    out
}

#[test]
fn validate_writes_a_self_contained_report() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("camp");
    let db = tmp.path().join("db");
    let (camp_s, db_s) = (camp.to_str().unwrap(), db.to_str().unwrap());
    ok(
        &regolith(&[
            "corpus",
            "generate",
            "--renderer",
            "model",
            "--preset",
            "mini",
            "--seed",
            "21",
            "--out",
            camp_s,
        ]),
        &[0],
    );
    ok(&regolith(&["compile", camp_s, "--db", db_s]), &[0]);
    let report = |dir: &Path| {
        let out = regolith(&[
            "validate",
            db_s,
            "--entry",
            "laser/0.02",
            "--detector",
            "harris",
            "--detector",
            "fast",
            "--report",
            dir.to_str().unwrap(),
            "--json",
        ]);
        // The verdict may go either way; the report is written in both cases.
        ok(&out, &[0, 1]);
        serde_json::from_slice::<Value>(&out.stdout).unwrap()
    };
    let rep = tmp.path().join("report");
    let v = report(&rep);
    let index = rep.join("index.html");
    assert_eq!(v["report"], index.to_str().unwrap());
    assert_eq!(
        v["entries"][0]["entry"], "laser/0.02",
        "JSON otherwise as before"
    );
    let html = std::fs::read_to_string(&index).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>") && html.contains("laser/0.02"));
    for failure in v["entries"][0]["failures"].as_array().unwrap() {
        let f = regolith_validator::report::html::escape(failure.as_str().unwrap());
        assert!(html.contains(&f), "failure message in the page: {f}");
    }
    assert!(!html.contains("http://") && !html.contains("https://") && !html.contains("<script"));

    let cam = regolith_reader::Database::open(&db)
        .unwrap()
        .release("latest")
        .unwrap()
        .camera("cameras/navcam_left")
        .unwrap();
    let (w, h) = (cam.width, cam.height);
    let s = overlay_scale(w);
    let links = image_links(&html);
    // 2 captures x 2 cameras: 3 images + 2 overlays + 3 charts each; 4 entry charts.
    assert_eq!(links.len(), 4 * (3 + 2 + 3) + 4, "{links:?}");
    for src in &links {
        assert!(
            !src.contains(':') && !src.starts_with('/') && !src.contains(".."),
            "relative link inside the folder: {src}"
        );
        let path = rep.join(src);
        assert!(path.is_file(), "{src} exists");
        let expected = if src.ends_with("_real.png")
            || src.ends_with("_render.png")
            || src.ends_with("_diff.png")
        {
            (w, h)
        } else if src.contains("_kp_") {
            (w * s, h * s)
        } else {
            CHART_SIZE
        };
        assert_eq!(png_size(&path), expected, "{src}");
    }
    for d in ["harris", "fast"] {
        assert!(
            links.iter().any(|l| l.ends_with(&format!("_kp_{d}.png"))),
            "{d} overlay"
        );
    }

    // Deterministic: the same input gives the same bytes, page and figures.
    let rep2 = tmp.path().join("report2");
    let v2 = report(&rep2);
    assert_eq!(v2["entries"], v["entries"]);
    let (a, b) = (all_files(&rep), all_files(&rep2));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, bytes) in &a {
        assert!(bytes == &b[k], "{} differs between runs", k.display());
    }

    // Without --json a log (stderr not a terminal) gets one line as each entry begins, and
    // stdout the verdict.
    let out = regolith(&[
        "validate",
        db_s,
        "--entry",
        "laser/0.02",
        "--detector",
        "fast",
    ]);
    ok(&out, &[0, 1]);
    let log = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        log.lines()
            .filter(|l| l.starts_with("[  0%] validating laser/0.02 (1/1)"))
            .count(),
        1,
        "{log}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("laser/0.02: "));
}
