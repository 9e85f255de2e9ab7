#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::sop_dat;

fuzz_target!(|data: &[u8]| {
    let _ = sop_dat::read_sop_dat(data);
});
