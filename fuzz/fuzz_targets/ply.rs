#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::ply;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_points: 1 << 20,
        ..Limits::default()
    };
    let _ = ply::read_ply(data, &limits);
    let _ = ply::read_ply_mesh(data, &limits);
});
