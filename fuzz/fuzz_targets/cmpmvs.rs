//! Fuzzes the CMPMVS DEM reader: `DEM.txt` parsing, and the DEM image decoded against a fixed box.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::cmpmvs;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_image_side: 4096,
        max_alloc_bytes: 1 << 28,
        ..Limits::default()
    };
    if let Ok(dem) = cmpmvs::parse_dem_txt(data) {
        let _ = cmpmvs::height_grid(&dem, data, &limits);
    }
    let dem = cmpmvs::DemBox {
        origin: [0.0; 3],
        x: [4.0, 0.0, 0.0],
        y: [0.0, 3.0, 0.0],
        z: [0.0, 0.0, 1.0],
        width: 4,
        height: 3,
    };
    let _ = cmpmvs::height_grid(&dem, data, &limits);
});
