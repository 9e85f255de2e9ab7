//! Fuzzes the Vicon Nexus `Segments` and `Model Outputs` readers and the all-sections reader:
//! any bytes give typed sections or an error, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::vicon_csv;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_points: 1 << 20,
        ..Limits::default()
    };
    let _ = vicon_csv::parse_export(data, &limits);
    let _ = vicon_csv::parse_segments(data, &limits);
    let _ = vicon_csv::parse_model_outputs(data, &limits);
});
