#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::riscan_ascii;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_points: 1 << 20,
        ..Limits::default()
    };
    let _ = riscan_ascii::read_ascii(data, None, &limits);
    let _ = riscan_ascii::read_ascii(data, Some("x y z reflectance"), &limits);
});
