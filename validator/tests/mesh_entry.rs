//! GLB mesh entries as render geometry: a hand-built GLB (written from SPEC §5.3 and the glTF
//! 2.0 spec, not by the compiler's encoder) of one quad with a 2 x 2 texture renders the texel
//! values where the axes, the origin translation and the UV convention put them, and the same
//! albedo a heightfield render samples from the same texture; RGB and 16-bit textures decode to
//! the SPEC §5.2 albedo; malformed GLBs are errors naming the entry, never panics.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_format::camera_model::CameraModel;
use regolith_reader::ReaderError;
use regolith_validator::mesh_entry::{decode_glb, png_albedo};
use regolith_validator::render::mesh::sample_texture;
use regolith_validator::render::shading::sample_albedo;
use regolith_validator::render::{
    render, AlbedoGrid, Geometry, Light, MeshTexture, RenderOptions, TriMeshF32, View,
};
use serde_json::{json, Value};

/// Ground coordinates of the quad's south-west corner, the node translation.
const ORIGIN: [f64; 3] = [100.0, 200.0, 5.0];
/// The 2 x 2 texture, row 0 on top (north): NW, NE / SW, SE.
const TEXELS: [u8; 4] = [51, 102, 153, 204];

fn png(
    width: u32,
    height: u32,
    colour: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(colour);
    enc.set_depth(depth);
    enc.write_header().unwrap().write_image_data(data).unwrap();
    out
}

fn pad4(b: &mut Vec<u8>, fill: u8) {
    while !b.len().is_multiple_of(4) {
        b.push(fill);
    }
}

/// A GLB container around `doc` and `bin`.
fn container(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut js = serde_json::to_vec(doc).unwrap();
    pad4(&mut js, b' ');
    let mut bin = bin.to_vec();
    pad4(&mut bin, 0);
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + js.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend((js.len() as u32).to_le_bytes());
    out.extend(0x4E4F_534Au32.to_le_bytes());
    out.extend(js);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(0x004E_4942u32.to_le_bytes());
    out.extend(bin);
    out
}

/// The quad `[0, 1]²` (ground metres, z = 0, relative to `ORIGIN`) as two triangles with UVs
/// `(0, 0)` at its north-west corner, and the texture: the glTF document and its BIN chunk.
fn quad_doc(texture_png: &[u8]) -> (Value, Vec<u8>) {
    // Ground (x, y, z) → glTF (x, z, −y).
    let ground = [
        [0.0f32, 1.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
    ];
    let uv = [[0.0f32, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
    let mut bin = Vec::new();
    for p in ground {
        for c in [p[0], p[2], -p[1]] {
            bin.extend(c.to_le_bytes());
        }
    }
    for t in uv {
        for c in t {
            bin.extend(c.to_le_bytes());
        }
    }
    // NW, SW, SE and NW, SE, NE (the compiler's NW–SE split), u16 indices.
    for i in [0u16, 2, 3, 0, 3, 1] {
        bin.extend(i.to_le_bytes());
    }
    pad4(&mut bin, 0);
    let png_at = bin.len();
    bin.extend(texture_png);
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [ORIGIN[0], ORIGIN[2], -ORIGIN[1]]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"bufferView": 3, "mimeType": "image/png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12},
            {"buffer": 0, "byteOffset": png_at, "byteLength": texture_png.len()}
        ],
        "buffers": [{"byteLength": bin.len() + (4 - bin.len() % 4) % 4}]
    });
    (doc, bin)
}

fn grey_texture() -> Vec<u8> {
    png(
        2,
        2,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &TEXELS,
    )
}

fn quad_glb() -> Vec<u8> {
    let (doc, bin) = quad_doc(&grey_texture());
    container(&doc, &bin)
}

/// A 40 x 40 pinhole view straight down from 10 m above the quad's centre: 40 px per metre
/// on the quad, image up = north, image right = east.
fn top_view() -> View {
    let c = [ORIGIN[0] + 0.5, ORIGIN[1] + 0.5, ORIGIN[2]];
    View::look_at(
        CameraModel::pinhole(40, 40, 400.0, 400.0, 19.5, 19.5),
        [c[0], c[1], c[2] + 10.0],
        c,
    )
}

/// Sun overhead: on the flat quad the radiance is the albedo.
const OVERHEAD: Light = Light {
    azimuth_deg: 0.0,
    elevation_deg: 90.0,
    ambient: 0.3,
};

const PLAIN: RenderOptions = RenderOptions {
    distort: false,
    shadows: false,
    supersample: 1,
    filter_textures: true,
    adaptive: false,
};

#[test]
fn quad_decodes_to_the_ground_frame() {
    let m = decode_glb(&quad_glb(), "t/mesh").unwrap();
    assert_eq!(m.origin_m, ORIGIN);
    assert_eq!(
        m.positions,
        vec![
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0]
        ]
    );
    assert_eq!(m.triangles, vec![[0, 2, 3], [0, 3, 1]]);
    let t = m.texture.as_ref().unwrap();
    assert_eq!((t.width, t.height), (2, 2));
    assert_eq!(t.value, TEXELS.map(|v| f32::from(v) / 255.0).to_vec());
    assert_eq!(t.uvs[0], [0.0, 0.0]);
}

#[test]
fn textured_quad_renders_its_texels_where_the_uvs_put_them() {
    let g = Geometry::Mesh(decode_glb(&quad_glb(), "t/mesh").unwrap());
    let r = render(&g, &OVERHEAD, &top_view(), &PLAIN);
    let at = |c: usize, r_: usize| r.radiance[r_ * 40 + c];
    // Texel centres are at the quarter points; pixels within a quarter of the quad from a
    // corner see only that corner's texel (CLAMP_TO_EDGE).
    let expect = |v: u8| f32::from(v) / 255.0;
    for (c, row, texel, name) in [
        (5, 5, TEXELS[0], "NW = image top-left"),
        (34, 5, TEXELS[1], "NE = image top-right"),
        (5, 34, TEXELS[2], "SW = image bottom-left"),
        (34, 34, TEXELS[3], "SE = image bottom-right"),
    ] {
        assert!(
            (at(c, row) - expect(texel)).abs() < 1e-5,
            "{name}: pixel ({c}, {row}) = {} expected {}",
            at(c, row),
            expect(texel)
        );
    }
    // Pixel (20, 20) looks at texture coordinate (0.5125, 0.5125): texel position 0.525 from
    // the top-left texel centre in both directions, bilinear.
    let (s, t) = (0.525f32, 0.525f32);
    let v = TEXELS.map(|v| f32::from(v) / 255.0);
    let top = v[0] * (1.0 - s) + v[1] * s;
    let bottom = v[2] * (1.0 - s) + v[3] * s;
    let want = top * (1.0 - t) + bottom * t;
    assert!((at(20, 20) - want).abs() < 1e-5, "{} vs {want}", at(20, 20));
    // Every pixel sees the quad 10 m below the camera: the origin translation is applied.
    assert!(r.mask.iter().all(|&m| m == 255));
    assert!(r.depth.iter().all(|d| (d - 10.0).abs() < 1e-4), "depth");
}

#[test]
fn textured_renders_are_the_same_bytes_on_1_or_2_threads() {
    let g = Geometry::Mesh(decode_glb(&quad_glb(), "t/mesh").unwrap());
    let opts = RenderOptions {
        supersample: 3,
        ..PLAIN
    };
    let on = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| render(&g, &OVERHEAD, &top_view(), &opts))
    };
    let (a, b) = (on(1), on(2));
    let bits = |r: &regolith_validator::render::Rendered| {
        r.radiance
            .iter()
            .chain(&r.depth)
            .map(|v| v.to_bits())
            .collect::<Vec<u32>>()
    };
    assert_eq!(bits(&a), bits(&b));
}

#[test]
fn textured_mesh_samples_what_the_heightfield_albedo_lookup_samples() {
    // The 2 x 2 texture as an albedo raster: cell centres at the texel centres of the quad.
    let grid = AlbedoGrid {
        origin_m: [ORIGIN[0] + 0.25, ORIGIN[1] + 0.75],
        cell_m: 0.5,
        width: 2,
        height: 2,
        value: TEXELS.map(|v| f32::from(v) / 255.0).to_vec(),
    };
    let g = Geometry::Mesh(decode_glb(&quad_glb(), "t/mesh").unwrap());
    let r = render(&g, &OVERHEAD, &top_view(), &PLAIN);
    let mut worst = 0.0f32;
    for row in 0..40 {
        for c in 0..40 {
            let x = ORIGIN[0] + (c as f64 + 0.5) / 40.0;
            let y = ORIGIN[1] + 1.0 - (row as f64 + 0.5) / 40.0;
            worst = worst.max((r.radiance[row * 40 + c] - sample_albedo(&grid, x, y)).abs());
        }
    }
    assert!(worst < 1e-5, "largest difference {worst}");
}

#[test]
fn sampler_clamps_and_uses_texel_centres() {
    let t = MeshTexture {
        uvs: Vec::new(),
        width: 2,
        height: 1,
        value: vec![0.0, 1.0],
    };
    assert_eq!(sample_texture(&t, 0.25, 0.5), 0.0);
    assert_eq!(sample_texture(&t, 0.75, 0.5), 1.0);
    assert!((sample_texture(&t, 0.5, 0.5) - 0.5).abs() < 1e-6);
    assert_eq!(sample_texture(&t, -3.0, 9.0), 0.0, "clamped, not repeated");
    assert_eq!(sample_texture(&t, 7.0, -9.0), 1.0, "clamped, not repeated");
    assert_eq!(sample_texture(&t, f64::NAN, 0.5), 0.0);
}

#[test]
fn untextured_triangles_keep_per_vertex_albedo() {
    let mut m = decode_glb(&quad_glb(), "t/mesh").unwrap();
    // A vertex without texture coordinates: both triangles use it, both fall back to the
    // vertex albedo.
    m.texture.as_mut().unwrap().uvs[0] = [f32::NAN, 0.0];
    m.albedo = vec![0.7; 4];
    let r = render(&Geometry::Mesh(m), &OVERHEAD, &top_view(), &PLAIN);
    assert!(r.radiance.iter().all(|v| (v - 0.7).abs() < 1e-5));
    let plain = TriMeshF32 {
        texture: None,
        albedo: vec![0.2, 0.2, 0.6, 0.6],
        ..decode_glb(&quad_glb(), "t/mesh").unwrap()
    };
    let r = render(&Geometry::Mesh(plain), &OVERHEAD, &top_view(), &PLAIN);
    // North edge 0.2, south edge 0.6, linear in between.
    assert!((r.radiance[20] - (0.2 + 0.4 * 0.5 / 40.0)).abs() < 1e-4);
    assert!((r.radiance[39 * 40 + 20] - (0.6 - 0.4 * 0.5 / 40.0)).abs() < 1e-4);
}

#[test]
fn node_matrix_and_vertex_colours() {
    // The same quad placed by a column-major `matrix`, without texture, COLOR_0 as normalised
    // u8 RGBA: albedo = Rec. 601 luma × the material's base colour factor.
    let (mut doc, mut bin) = quad_doc(&grey_texture());
    doc["nodes"][0] = json!({"mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
        ORIGIN[0], ORIGIN[2], -ORIGIN[1], 1]});
    let col_at = bin.len();
    for _ in 0..4 {
        bin.extend([255u8, 0, 0, 255]);
    }
    doc["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 0, "byteOffset": col_at, "byteLength": 16}));
    doc["accessors"].as_array_mut().unwrap().push(
        json!({"bufferView": 4, "componentType": 5121, "normalized": true, "count": 4, "type": "VEC4"}),
    );
    doc["meshes"][0]["primitives"][0]["attributes"] = json!({"POSITION": 0, "COLOR_0": 3});
    doc["materials"][0] = json!({"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}});
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    let m = decode_glb(&container(&doc, &bin), "t/mesh").unwrap();
    assert_eq!(m.origin_m, ORIGIN);
    assert_eq!(m.positions[1], [1.0, 1.0, 0.0]);
    assert!(m.texture.is_none());
    assert!(
        m.albedo.iter().all(|a| (a - 0.299 * 0.5).abs() < 1e-6),
        "{:?}",
        m.albedo
    );
}

#[test]
fn rgb_and_16_bit_textures_decode_to_linear_albedo() {
    let rgb = png(
        1,
        2,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &[255, 0, 0, 0, 0, 255],
    );
    let (w, h, v) = png_albedo(&rgb).unwrap();
    assert_eq!((w, h), (1, 2));
    assert!(
        (v[0] - 0.299).abs() < 1e-6 && (v[1] - 0.114).abs() < 1e-6,
        "{v:?}"
    );
    let grey16 = png(
        2,
        1,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &[0xff, 0xff, 0x80, 0x00],
    );
    let (_, _, v) = png_albedo(&grey16).unwrap();
    assert_eq!(v, vec![1.0, 32768.0 / 65535.0]);
    // An RGBA texture in the quad: only the luma counts.
    let rgba = png(
        2,
        2,
        png::ColorType::Rgba,
        png::BitDepth::Eight,
        &TEXELS
            .iter()
            .flat_map(|&t| [t, t, t, 7])
            .collect::<Vec<u8>>(),
    );
    let (doc, bin) = quad_doc(&rgba);
    let m = decode_glb(&container(&doc, &bin), "t/mesh").unwrap();
    let want = TEXELS.map(|v| f32::from(v) / 255.0);
    for (a, b) in m.texture.unwrap().value.iter().zip(want) {
        assert!((a - b).abs() < 1e-6);
    }
}

fn decode_message(bytes: &[u8]) -> String {
    match decode_glb(bytes, "bad/mesh") {
        Ok(_) => panic!("decoded"),
        Err(e @ ReaderError::Decode { .. }) => {
            let s = e.to_string();
            assert!(s.contains("bad/mesh"), "{s}");
            s
        }
        Err(e) => panic!("not a decode error: {e}"),
    }
}

#[test]
fn bad_glbs_are_errors_naming_the_entry() {
    let good = quad_glb();
    // Truncated anywhere.
    for n in 0..good.len() {
        decode_message(&good[..n]);
    }
    // Truncated with the header's length fixed up: the chunk table itself is short.
    for n in [12, 16, 20, 40, good.len() - 4] {
        let mut b = good[..n].to_vec();
        b[8..12].copy_from_slice(&(n as u32).to_le_bytes());
        decode_message(&b);
    }
    let mut b = good.clone();
    b[0] = b'x';
    assert!(decode_message(&b).contains("magic"));
    b = good.clone();
    b[4] = 1;
    assert!(decode_message(&b).contains("version 2"));

    let edit = |f: &dyn Fn(&mut Value)| {
        let (mut doc, bin) = quad_doc(&grey_texture());
        f(&mut doc);
        decode_message(&container(&doc, &bin))
    };
    // An index past the vertices (the last u16 index: 1 → 9).
    let (doc, mut bin) = quad_doc(&grey_texture());
    bin[90..92].copy_from_slice(&9u16.to_le_bytes());
    let m = decode_message(&container(&doc, &bin));
    assert!(m.contains("index 9 out of range"), "{m}");
    // Counts, offsets and strides past the buffer, including forged huge ones.
    for (what, f) in [
        (
            "run past bufferViews[0]",
            &(|d: &mut Value| d["accessors"][0]["count"] = json!(5)) as &dyn Fn(&mut Value),
        ),
        ("run past bufferViews[2]", &|d: &mut Value| {
            d["accessors"][2]["count"] = json!(u64::MAX / 2)
        }),
        ("runs past the BIN chunk", &|d: &mut Value| {
            d["bufferViews"][0]["byteLength"] = json!(1u64 << 40)
        }),
        ("runs past the BIN chunk", &|d: &mut Value| {
            d["bufferViews"][3]["byteOffset"] = json!(u64::MAX)
        }),
        ("byteStride", &|d: &mut Value| {
            d["bufferViews"][0]["byteStride"] = json!(4)
        }),
        ("elements", &|d: &mut Value| {
            d["bufferViews"][0]["byteStride"] = json!(1u64 << 40)
        }),
        ("componentType", &|d: &mut Value| {
            d["accessors"][0]["componentType"] = json!(5123)
        }),
        ("type", &|d: &mut Value| {
            d["accessors"][1]["type"] = json!("VEC3")
        }),
        ("accessors[7]", &|d: &mut Value| {
            d["meshes"][0]["primitives"][0]["indices"] = json!(7)
        }),
        ("not a non-negative integer", &|d: &mut Value| {
            d["meshes"][0]["primitives"][0]["indices"] = json!(-1)
        }),
        ("no POSITION", &|d: &mut Value| {
            d["meshes"][0]["primitives"][0]["attributes"] = json!({})
        }),
        ("sparse", &|d: &mut Value| {
            d["accessors"][0]["sparse"] = json!({})
        }),
        ("URI", &|d: &mut Value| {
            d["buffers"][0]["uri"] = json!("data.bin")
        }),
        ("mimeType", &|d: &mut Value| {
            d["images"][0]["mimeType"] = json!("image/jpeg")
        }),
        ("images[0]", &|d: &mut Value| {
            d["bufferViews"][3]["byteLength"] = json!(20)
        }),
        ("required extensions", &|d: &mut Value| {
            d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])
        }),
        ("not a tree", &|d: &mut Value| {
            d["nodes"][0]["children"] = json!([0])
        }),
        ("nodes[3]", &|d: &mut Value| {
            d["scenes"][0]["nodes"] = json!([3])
        }),
        ("asset.version", &|d: &mut Value| {
            d["asset"]["version"] = json!("1.0")
        }),
        ("translation", &|d: &mut Value| {
            d["nodes"][0]["translation"] = json!([1, 2])
        }),
    ] {
        let m = edit(f);
        assert!(m.contains(what), "expected {what:?} in {m}");
    }
    // Not JSON at all.
    let mut b = good.clone();
    b[20] = b'#';
    assert!(decode_message(&b).contains("JSON"));
}

#[test]
fn corrupting_any_byte_never_panics() {
    let good = quad_glb();
    let mut ok = 0;
    for i in 0..good.len() {
        for x in [0x01u8, 0xff, 0x40] {
            let mut b = good.clone();
            b[i] ^= x;
            if decode_glb(&b, "fuzz/mesh").is_ok() {
                ok += 1;
            }
        }
    }
    // Many flips land in padding, float mantissas or PNG ancillary bytes and still decode.
    assert!(ok > 0);
}
