//! The LAS fast path (`las::read_las`, `las::read_path`) against the `las` crate's decoding:
//! files written by the `las` crate in point formats 0–3 and 6–8, LAS 1.0–1.4, with and
//! without extra bytes; files written by laspy (tools/fixtures/laspy_las.py); the real files
//! of ../shared/realdata; identical output on 1 and N threads; truncated and corrupt inputs
//! give errors naming the place, never panics.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::Cursor;

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use regolith_compiler::ingest::las;
use regolith_compiler::ingest::types::PointCloud;
use regolith_format::limits::Limits;

fn lim() -> Limits {
    Limits::default()
}

mod common;
use common::{realdata, scan_data as data};

/// The `las` crate's decoding of the same bytes (the reference).
fn reference(bytes: &[u8]) -> Result<PointCloud, String> {
    las::read_las_from(Cursor::new(bytes.to_vec()), &lim()).map_err(|e| e.to_string())
}

#[derive(Debug, Clone, Copy)]
struct Spec {
    version: (u8, u8),
    format: u8,
    extra: u16,
    n: usize,
    eight_bit: bool,
    seed: u64,
}

/// Writes `spec.n` random points with the `las` crate's writer.
fn write(spec: Spec) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let mut builder = ::las::Builder::from(spec.version);
    builder.point_format = ::las::point::Format::new(spec.format).unwrap();
    builder.point_format.extra_bytes = spec.extra;
    let scale = [0.001, 0.0025, 0.01];
    let offset = [512_000.0, -4_200_000.0, 37.5];
    let t = |k: usize| ::las::Transform {
        scale: scale[k],
        offset: offset[k],
    };
    builder.transforms = ::las::Vector {
        x: t(0),
        y: t(1),
        z: t(2),
    };
    let header = builder.into_header().unwrap();
    let f = *header.point_format();
    let mut w = ::las::Writer::new(Cursor::new(Vec::new()), header).unwrap();
    for _ in 0..spec.n {
        let mut c = || {
            if spec.eight_bit {
                rng.gen_range(0..=255u16)
            } else {
                rng.gen()
            }
        };
        let color = f.has_color.then(|| ::las::Color::new(c(), c(), c()));
        let coord = |rng: &mut ChaCha8Rng, k: usize| {
            f64::from(rng.gen_range(-2_000_000_000..=2_000_000_000i32)) * scale[k] + offset[k]
        };
        let p = ::las::Point {
            x: coord(&mut rng, 0),
            y: coord(&mut rng, 1),
            z: coord(&mut rng, 2),
            intensity: rng.gen(),
            gps_time: f.has_gps_time.then(|| rng.gen_range(0.0..1e6)),
            color,
            nir: f.has_nir.then(|| rng.gen_range(1..=u16::MAX)),
            extra_bytes: (0..spec.extra).map(|_| rng.gen()).collect(),
            ..Default::default()
        };
        w.write_point(p).unwrap();
    }
    w.into_inner().unwrap().into_inner()
}

fn specs() -> Vec<Spec> {
    let mut v = Vec::new();
    let mut seed = 0;
    let mut add = |version, format, extra, eight_bit| {
        seed += 1;
        v.push(Spec {
            version,
            format,
            extra,
            n: 3_000 + seed as usize * 17,
            eight_bit,
            seed,
        });
    };
    for extra in [0, 5] {
        add((1, 0), 0, extra, false);
        add((1, 1), 1, extra, false);
        for f in 0..=3 {
            add((1, 2), f, extra, false);
        }
        add((1, 2), 2, extra, true);
        for f in [0, 1, 2, 3, 6, 7, 8] {
            add((1, 4), f, extra, false);
        }
        add((1, 4), 7, extra, true);
    }
    v
}

fn one_thread<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn fast_path_equals_the_las_crate_for_every_format() {
    let dir = tempfile::tempdir().unwrap();
    for spec in specs() {
        let bytes = write(spec);
        let want = reference(&bytes).unwrap();
        let got = las::read_las(&bytes, &lim()).unwrap();
        assert_eq!(got, want, "{spec:?}");
        assert_eq!(got.points.len(), spec.n);
        let f = ::las::point::Format::new(spec.format).unwrap();
        assert_eq!(got.rgb.is_some(), f.has_color, "{spec:?}");
        if f.has_color && !spec.eight_bit {
            assert!(got.rgb.as_ref().unwrap().iter().flatten().any(|&c| c > 0));
        }
        // Directly against the crate's points, not only our wrapper of it.
        let mut r = ::las::Reader::new(Cursor::new(bytes.clone())).unwrap();
        let pd = r.read_all().unwrap();
        for (i, p) in pd.points().enumerate() {
            let p = p.unwrap();
            assert_eq!(got.points[i], [p.x, p.y, p.z], "{spec:?} point {i}");
            assert_eq!(got.intensity.as_ref().unwrap()[i], f32::from(p.intensity));
            if spec.eight_bit {
                let c = p.color.unwrap();
                let want = [c.red, c.green, c.blue].map(|v| v as u8);
                assert_eq!(got.rgb.as_ref().unwrap()[i], want);
            }
        }
        // From a file, in blocks.
        let path = dir
            .path()
            .join(format!("f{}_{}.las", spec.format, spec.seed));
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(las::read_path(&path, &lim()).unwrap(), want, "{spec:?}");
        // One thread gives the same as all threads.
        assert_eq!(
            one_thread(|| las::read_las(&bytes, &lim()).unwrap()),
            want,
            "{spec:?}"
        );
    }
}

#[test]
fn many_blocks_and_threads_give_identical_output() {
    // More than one read block, and more threads than cores.
    let n = las::BLOCK_BYTES / 25 + 12_345;
    let bytes = write(Spec {
        version: (1, 2),
        format: 0,
        extra: 5,
        n,
        eight_bit: false,
        seed: 99,
    });
    assert!(bytes.len() > las::BLOCK_BYTES + 100_000);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.las");
    std::fs::write(&path, &bytes).unwrap();
    let want = reference(&bytes).unwrap();
    assert_eq!(want.points.len(), n);
    assert_eq!(one_thread(|| las::read_path(&path, &lim()).unwrap()), want);
    let four = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap();
    assert_eq!(
        four.install(|| las::read_path(&path, &lim()).unwrap()),
        want
    );
    assert_eq!(
        four.install(|| las::read_las(&bytes, &lim()).unwrap()),
        want
    );
}

#[test]
fn laspy_files_read_as_written() {
    // tools/fixtures/laspy_las.py: the record values are a formula of the point index.
    let rec = |i: i64| {
        [
            (i * 7919) % 100_000 - 50_000,
            (i * 104_729) % 200_000 - 100_000,
            i * 13 - 1000,
        ]
    };
    for (name, scale, offset, rgb) in [
        (
            "laspy_f3_v12.las",
            0.01,
            [500_000.0, 4_000_000.0, 100.0],
            (|i: i64| [(i * 3) % 256, (i * 5) % 256, (i * 7) % 256]) as fn(i64) -> [i64; 3],
        ),
        ("laspy_f7_v14_extra.las", 0.001, [-12.5, 7.25, 0.0], |i| {
            [
                ((i * 1031) % 65_536) >> 8,
                ((i * 2053) % 65_536) >> 8,
                ((i * 4099) % 65_536) >> 8,
            ]
        }),
    ] {
        let bytes = std::fs::read(data(name)).unwrap();
        let c = las::read_las(&bytes, &lim()).unwrap();
        assert_eq!(c, las::read_path(&data(name), &lim()).unwrap());
        assert_eq!(c, reference(&bytes).unwrap(), "{name}");
        assert_eq!(c.points.len(), 300);
        let intensity = c.intensity.as_ref().unwrap();
        let colours = c.rgb.as_ref().unwrap();
        for (i, p) in c.points.iter().enumerate() {
            let i = i as i64;
            let r = rec(i);
            for k in 0..3 {
                assert_eq!(p[k], scale * r[k] as f64 + offset[k], "{name} point {i}");
            }
            assert_eq!(intensity[i as usize], ((i * 257) % 65_536) as f32);
            assert_eq!(colours[i as usize], rgb(i).map(|v| v as u8), "{name} {i}");
        }
    }
}

#[test]
fn real_files_match_the_las_crate() {
    for name in ["scans/simple.las", "scans/vegetation_1_3.las"] {
        let bytes = std::fs::read(realdata(name)).unwrap();
        let want = reference(&bytes).unwrap();
        assert_eq!(las::read_las(&bytes, &lim()).unwrap(), want, "{name}");
        assert_eq!(las::read_path(&realdata(name), &lim()).unwrap(), want);
    }
    // LAZ stays on the las crate.
    let laz = realdata("scans/autzen_trim.laz");
    let bytes = std::fs::read(&laz).unwrap();
    assert_eq!(
        las::read_las(&bytes, &lim()).unwrap(),
        las::read_path(&laz, &lim()).unwrap()
    );
}

fn small() -> Vec<u8> {
    write(Spec {
        version: (1, 2),
        format: 3,
        extra: 2,
        n: 40,
        eight_bit: false,
        seed: 7,
    })
}

fn put(bytes: &mut [u8], at: usize, v: &[u8]) {
    bytes[at..at + v.len()].copy_from_slice(v);
}

#[test]
fn every_truncation_is_an_error_naming_the_offset() {
    let b = small();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.las");
    for n in 0..b.len() {
        let e = las::read_las(&b[..n], &lim()).unwrap_err().to_string();
        if n >= 227 {
            assert!(e.contains("byte offset"), "cut at {n}: {e}");
        }
        std::fs::write(&path, &b[..n]).unwrap();
        let e = las::read_path(&path, &lim()).unwrap_err().to_string();
        assert!(e.contains("cut.las"), "{e}");
    }
    assert!(las::read_las(&b, &lim()).is_ok());
    // A point cut in two: the error names where that point starts.
    let e = las::read_las(&b[..b.len() - 3], &lim())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(&format!("byte offset {}:", b.len() - 36)),
        "{e}"
    );
    assert!(e.contains("truncated in point 40 of 40"), "{e}");
}

#[test]
fn header_counts_beyond_the_data_or_limits_are_errors() {
    let b = small();
    // Legacy count (byte 107) one more than written.
    let mut c = b.clone();
    put(&mut c, 107, &41u32.to_le_bytes());
    let e = las::read_las(&c, &lim()).unwrap_err().to_string();
    assert!(e.contains("truncated in point 41 of 41"), "{e}");
    // A count beyond the limits is refused before anything is allocated.
    put(&mut c, 107, &u32::MAX.to_le_bytes());
    let e = las::read_las(&c, &lim()).unwrap_err().to_string();
    assert!(e.contains("points"), "{e}");
    let tight = Limits {
        max_points: 39,
        ..lim()
    };
    assert!(las::read_las(&b, &tight).is_err());
    // LAS 1.4: the 64-bit count (byte 247) with a zero legacy count.
    let mut d = write(Spec {
        version: (1, 4),
        format: 6,
        extra: 0,
        n: 10,
        eight_bit: false,
        seed: 3,
    });
    put(&mut d, 107, &0u32.to_le_bytes());
    assert_eq!(las::read_las(&d, &lim()).unwrap().points.len(), 10);
    put(&mut d, 247, &(1u64 << 40).to_le_bytes());
    assert!(las::read_las(&d, &lim()).is_err());
    put(&mut d, 247, &11u64.to_le_bytes());
    let e = las::read_las(&d, &lim()).unwrap_err().to_string();
    assert!(e.contains("truncated in point 11 of 11"), "{e}");
}

#[test]
fn non_finite_coordinates_are_errors() {
    let b = small();
    // X scale (byte 131) so large that scale * X overflows.
    let mut c = b.clone();
    put(&mut c, 131, &1e308f64.to_le_bytes());
    let e = las::read_las(&c, &lim()).unwrap_err().to_string();
    assert!(e.contains("non-finite coordinate"), "{e}");
    assert!(reference(&c).is_err());
    // Z offset (byte 171) NaN: the first point is named, at its offset.
    let mut c = b.clone();
    put(&mut c, 171, &f64::NAN.to_le_bytes());
    let e = las::read_las(&c, &lim()).unwrap_err().to_string();
    let start = u32::from_le_bytes(c[96..100].try_into().unwrap());
    assert!(
        e.starts_with(&format!("byte offset {start}: point 1 has")),
        "{e}"
    );
}

#[test]
fn corrupt_headers_are_errors() {
    let b = small();
    let cases: [(usize, &[u8]); 6] = [
        (0, b"LASG"),                  // signature
        (104, &[11]),                  // point format 11
        (105, &20u16.to_le_bytes()),   // record shorter than format 3
        (100, &1000u32.to_le_bytes()), // VLRs that are not there
        (96, &100u32.to_le_bytes()),   // point data inside the header
        (24, &[2, 0]),                 // version 2.0
    ];
    for (at, v) in cases {
        let mut c = b.clone();
        put(&mut c, at, v);
        assert!(las::read_las(&c, &lim()).is_err(), "byte {at} = {v:?}");
    }
    // A record longer than the format (more extra bytes) is fine if the data is there.
    let mut c = b.clone();
    put(&mut c, 105, &38u16.to_le_bytes());
    put(&mut c, 107, &36u32.to_le_bytes());
    assert_eq!(las::read_las(&c, &lim()).unwrap(), reference(&c).unwrap());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Random byte writes (mostly in the header) and a random cut: never a panic; when the cut
    /// removes point data the result is an error; when both readers accept the bytes they agree.
    #[test]
    fn corruption_never_panics(
        which in 0usize..2,
        writes in prop::collection::vec((0usize..420, any::<u8>()), 0..5),
        tail in prop::collection::vec((0usize..4000, any::<u8>()), 0..3),
        cut in prop::option::of(0usize..4000),
    ) {
        let mut b = if which == 0 {
            small()
        } else {
            write(Spec { version: (1, 4), format: 7, extra: 3, n: 40, eight_bit: false, seed: 11 })
        };
        let original = b.clone();
        for (at, v) in writes.into_iter().chain(tail) {
            if let Some(x) = b.get_mut(at) {
                *x = v;
            }
        }
        if let Some(n) = cut {
            b.truncate(n);
        }
        let got = las::read_las(&b, &lim());
        if b.len() < original.len() && original.starts_with(&b) {
            prop_assert!(got.is_err());
        }
        if let Ok(got) = got {
            // Only now is the las crate asked: it reads EVLRs whose length it trusts.
            if let Ok(want) = reference(&b) {
                prop_assert_eq!(got, want);
            }
        }
    }
}

/// A LAZ file whose extended VLR claims more bytes than the file has is an error naming the
/// record and its offset; the `las` crate alone would try to allocate the claimed length.
#[test]
fn a_laz_evlr_longer_than_the_file_is_an_error() {
    let mut builder = ::las::Builder::from((1, 4));
    builder.point_format = ::las::point::Format::new(6).unwrap();
    builder.point_format.is_compressed = true;
    builder.evlrs.push(::las::Vlr {
        user_id: "regolith".into(),
        record_id: 7,
        description: "test".into(),
        data: vec![1, 2, 3, 4],
    });
    let header = builder.into_header().unwrap();
    let mut w = ::las::Writer::new(Cursor::new(Vec::new()), header).unwrap();
    for i in 0..50 {
        w.write_point(::las::Point {
            x: f64::from(i),
            y: 2.0 * f64::from(i),
            z: 0.5,
            gps_time: Some(f64::from(i)),
            ..Default::default()
        })
        .unwrap();
    }
    let good = w.into_inner().unwrap().into_inner();
    let read = las::read_las(&good, &lim()).unwrap();
    assert_eq!(read.points.len(), 50);
    // LAS 1.4 header: start_of_first_evlr (u64) at byte 235, number_of_evlrs (u32) at 243.
    let start = u64::from_le_bytes(good[235..243].try_into().unwrap()) as usize;
    assert_eq!(u32::from_le_bytes(good[243..247].try_into().unwrap()), 1);
    assert_eq!(&good[start + 2..start + 10], b"regolith");
    let mut bad = good.clone();
    bad[start + 20..start + 28].copy_from_slice(&(u64::MAX / 4).to_le_bytes());
    let err = las::read_las(&bad, &lim()).unwrap_err().to_string();
    assert!(
        err.contains("extended VLR 1 of 1") && err.contains(&start.to_string()),
        "{err}"
    );
}
