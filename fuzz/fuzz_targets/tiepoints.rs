#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::tiepoints;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = tiepoints::read_tiepoints(data, &Limits::default());
});
