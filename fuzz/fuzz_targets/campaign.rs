#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::campaign;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = campaign::parse_str(text);
    }
});
