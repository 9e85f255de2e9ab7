#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::homography;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = homography::parse(data, &Limits::default());
});
