//! Fuzzes the per-corner texture-coordinate path of the PLY mesh reader: the input is the body
//! of a MeshLab-style textured mesh (`texcoord` and `texnumber` face properties), ascii and
//! binary little endian; any body gives a mesh or an error, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use regolith_compiler::ingest::ply;
use regolith_format::limits::Limits;

fuzz_target!(|data: &[u8]| {
    let limits = Limits {
        max_points: 1 << 20,
        ..Limits::default()
    };
    for format in ["ascii", "binary_little_endian"] {
        let mut file = format!(
            "ply\nformat {format} 1.0\ncomment TextureFile a.png\ncomment TextureFile b.png\n\
             element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 2\n\
             property list uchar int vertex_indices\nproperty list uchar float texcoord\n\
             property int texnumber\nend_header\n"
        )
        .into_bytes();
        file.extend_from_slice(data);
        let _ = ply::read_ply_mesh(&file, &limits);
    }
});
