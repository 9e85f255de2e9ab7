#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::ptx;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = ptx::read_ptx(
        data,
        &Limits {
            max_points: 1 << 20,
            ..Limits::default()
        },
    );
});
