//! Fuzzes the Bouguet `.mat` reader (MATLAB Level 5 framing, inflation, `matfile` decoding):
//! any bytes give a pose / cameras or an error, never a panic. Inputs without a MAT header are
//! also tried behind the header of a real little-endian file, so the fuzzer spends its time on
//! the data elements.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::calib_bouguet_mat;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_points: 1 << 20,
        max_object_bytes: 16 << 20,
        ..Limits::default()
    };
    let _ = calib_bouguet_mat::parse_stereo(data, &limits);
    let _ = calib_bouguet_mat::parse_cameras(data, &limits);
    let mut file = b"MATLAB 5.0 MAT-file, fuzz".to_vec();
    file.resize(124, b' ');
    file.extend([0, 1, b'I', b'M']);
    file.extend_from_slice(data);
    let _ = calib_bouguet_mat::variables(&file, &limits);
});
