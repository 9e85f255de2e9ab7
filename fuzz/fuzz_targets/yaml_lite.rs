#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::yaml_lite;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = yaml_lite::parse(data, &Limits::default());
});
