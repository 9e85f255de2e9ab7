#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::e57;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = e57::read_e57(
        data,
        &Limits {
            max_points: 1 << 20,
            ..Limits::default()
        },
    );
});
