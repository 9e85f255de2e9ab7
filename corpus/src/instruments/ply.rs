//! PLY writers: a scan as a binary point cloud, the SfM mesh as a coloured triangle mesh.
//!
//! Both are `binary_little_endian 1.0` (what scanner and SfM tools write for large data) with
//! float coordinates, `uchar` colours and a `list uchar int vertex_indices` face list, the
//! form formats.md §9 recommends (MeshLab rejects a `uint` count). The scan's reflectance goes
//! into a `float scalar_Reflectance` property (CloudCompare's name for scalar fields).

/// A binary PLY point cloud: x y z (float) + reflectance (float).
pub fn points(points: &[[f64; 3]], reflectance_db: &[f32], comment: &str) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment {comment}\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nproperty float scalar_Reflectance\nend_header\n",
        points.len()
    );
    let mut out = header.into_bytes();
    out.reserve(points.len() * 16);
    for (p, r) in points.iter().zip(reflectance_db) {
        for v in p {
            out.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        out.extend_from_slice(&r.to_le_bytes());
    }
    out
}

/// A binary PLY triangle mesh with per-vertex RGB.
pub fn mesh(
    positions: &[[f64; 3]],
    colors: &[[u8; 3]],
    triangles: &[[u32; 3]],
    comment: &str,
) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment {comment}\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        positions.len(),
        triangles.len()
    );
    let mut out = header.into_bytes();
    out.reserve(positions.len() * 15 + triangles.len() * 13);
    for (p, c) in positions.iter().zip(colors) {
        for v in p {
            out.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        out.extend_from_slice(c);
    }
    for t in triangles {
        out.push(3);
        for i in t {
            out.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mesh_body_length_matches_header_counts() {
        let m = mesh(
            &[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            &[[1, 2, 3]; 3],
            &[[0, 1, 2]],
            "t",
        );
        let text = String::from_utf8_lossy(&m);
        let end = text.find("end_header\n").unwrap() + "end_header\n".len();
        assert_eq!(m.len() - end, 3 * 15 + 13);
        let p = points(&[[1.5, 2.0, -3.0]], &[-4.5], "t");
        let end = String::from_utf8_lossy(&p).find("end_header\n").unwrap() + 11;
        assert_eq!(f32::from_le_bytes(p[end..end + 4].try_into().unwrap()), 1.5);
        assert_eq!(
            f32::from_le_bytes(p[end + 12..end + 16].try_into().unwrap()),
            -4.5
        );
    }
}
