#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::opencv_storage;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    if let Ok(root) = opencv_storage::parse(data, &Limits::default()) {
        let _ = opencv_storage::matrices(&root);
    }
});
