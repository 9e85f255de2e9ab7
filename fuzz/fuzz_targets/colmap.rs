//! Fuzzes the three COLMAP text parsers with the same bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::colmap;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_points: 1 << 20,
        ..Limits::default()
    };
    let _ = colmap::parse_cameras(data);
    let _ = colmap::parse_images(data, &limits);
    let _ = colmap::parse_points3d(data, &limits);
});
