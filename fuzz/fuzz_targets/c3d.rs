#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::c3d;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = c3d::parse(data, &Limits::default());
});
