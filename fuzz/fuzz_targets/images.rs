//! Fuzzes image decoding (PNG, TIFF, JPEG) into a grey image, with small limits.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::images;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_image_side: 4096,
        max_alloc_bytes: 1 << 28,
        ..Limits::default()
    };
    if let Ok(img) = images::decode(data, &limits) {
        assert_eq!(img.data.len(), img.width as usize * img.height as usize);
        assert!(img.data.iter().all(|v| (0.0..=1.0).contains(v)));
    }
});
