#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::calib_ros;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let _ = calib_ros::parse(data, &Limits::default());
});
