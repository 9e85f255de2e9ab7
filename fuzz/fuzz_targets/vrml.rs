//! Fuzzes the VRML 2.0 reader: any bytes must give a mesh or an error, never a panic; a mesh
//! that parses must survive a write/read round trip.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::vrml;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_points: 1 << 20,
        ..Limits::default()
    };
    if let Ok(mesh) = vrml::read_bytes(data, &limits) {
        let _ = vrml::read_bytes(vrml::write_vrml(&mesh).as_bytes(), &limits);
    }
});
