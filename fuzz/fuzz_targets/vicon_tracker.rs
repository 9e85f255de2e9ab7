#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::vicon_tracker;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = vicon_tracker::parse(data, 100.0, &Limits::default());
});
