#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::calib_opencv;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = calib_opencv::parse(data, &Limits::default());
});
