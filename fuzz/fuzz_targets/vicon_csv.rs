#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::vicon_csv;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = vicon_csv::parse(data, &Limits::default());
});
