//! Fuzzes the OpenCV FileStorage JSON reader: the node tree (`opencv_json::parse`) and the
//! calibration built from it must be a value or an error, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::{calib_opencv, opencv_json};
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits::default();
    let _ = opencv_json::parse(data, &limits);
    // Force the JSON path even when the input does not start with `{`.
    let mut doc = b"{".to_vec();
    doc.extend_from_slice(data);
    let _ = calib_opencv::parse(&doc, &limits);
});
