#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::calib_bouguet;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = calib_bouguet::parse(data, &Limits::default());
    let _ = calib_bouguet::parse_stereo(data, &Limits::default());
});
