#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::markers;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = markers::parse_rig_markers(data, &Limits::default());
});
