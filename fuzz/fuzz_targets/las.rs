#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::las;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = las::read_las(
        data,
        &Limits {
            max_points: 1 << 20,
            ..Limits::default()
        },
    );
});
