#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::gcp;
use regolith_compiler::ingest::types::NamedPoint;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    if let Ok(rows) = gcp::read_gcp(data, &Limits::default()) {
        let markers = [NamedPoint {
            name: "Marker1".into(),
            xyz: [0.45, 0.5, 0.09],
        }];
        let _ = gcp::match_markers(&rows, &markers);
    }
});
