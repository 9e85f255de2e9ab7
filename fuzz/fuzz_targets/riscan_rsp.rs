#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::riscan_rsp;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = riscan_rsp::read_rsp(
        data,
        &Limits {
            max_points: 1 << 20,
            ..Limits::default()
        },
    );
});
