//! Fuzzes undistortion: the first 48 bytes become camera parameters (any finite or non-finite
//! values), the rest a raw image; building the map and applying it must never panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::images::GreyImage;
use regolith_compiler::ingest::undistort::UndistortMap;
use regolith_format::camera_model::{CameraModel, Distortion};
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let mut p = [0.0f32; 12];
    for (v, c) in p.iter_mut().zip(data.chunks_exact(4)) {
        *v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    }
    let (w, h) = (
        1 + data.first().copied().unwrap_or(0) as u32 % 32,
        1 + data.get(1).copied().unwrap_or(0) as u32 % 32,
    );
    let f = |i: usize| f64::from(p[i]);
    let mut cam = CameraModel::pinhole(w, h, f(0), f(1), f(2), f(3));
    cam.skew = f(4);
    cam.distortion = Distortion {
        k1: f(5),
        k2: f(6),
        p1: f(7),
        p2: f(8),
        k3: f(9),
    };
    let limits = Limits::default();
    let Ok(map) = UndistortMap::new(&cam, &limits) else {
        return;
    };
    let Ok(mut raw) = GreyImage::new(w, h, 8, &limits) else {
        return;
    };
    for (v, b) in raw.data.iter_mut().zip(data.iter().skip(48)) {
        *v = f32::from(*b) / 255.0;
    }
    if let Ok(out) = map.apply(&raw) {
        assert_eq!(out.valid.len(), out.image.data.len());
    }
});
