//! A tiny release with every kind of entry, built from closed-form data so its bytes (and its
//! release id) are fixed: a 17x13 heightfield with a hole, its texture, a two-LOD mesh, two
//! cameras, a rig, one capture with two frames per camera, and a report.

use std::collections::BTreeMap;

use regolith_compiler::encode::{glb, heightfield, mcap, png, EncodeError};
use regolith_format::camera_model::{CameraModel, Distortion};
use regolith_format::frames::{quat_from_axis_angle, Pose};
use regolith_format::kinds::{
    self, media, roles, CameraMeta, LodMeta, MeshMeta, RigMeta, TextureMeta,
};
use regolith_format::manifest::{new_release, CampaignRef, InputFile, PlanStep, Producer};
use regolith_format::{Entry, FileRef, ObjectId, Release, Tile};
use regolith_reader::{ReaderError, Writer};
use serde_json::json;

/// Errors while building the sample.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    /// Encoding failed.
    #[error(transparent)]
    Encode(#[from] EncodeError),
    /// Writing failed.
    #[error(transparent)]
    Write(#[from] ReaderError),
    /// JSON conversion failed.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// Grid size of the sample heightfield.
pub const W: u32 = 17;
/// Grid rows.
pub const H: u32 = 13;
/// Cell size.
pub const CELL_M: f64 = 0.05;
/// The cell left as nodata.
pub const HOLE: (u32, u32) = (5, 4);

/// The sample heights: a smooth hill plus a ramp, one nodata cell.
pub fn heights() -> Vec<f32> {
    let mut z = Vec::new();
    for r in 0..H {
        for c in 0..W {
            let (x, y) = (f64::from(c) * CELL_M, f64::from(r) * CELL_M);
            let v = 0.3 * (-((x - 0.4).powi(2) + (y - 0.3).powi(2)) / 0.05).exp() + 0.02 * x - 0.01;
            z.push(if (c, r) == HOLE { f32::NAN } else { v as f32 });
        }
    }
    z
}

/// The sample left camera.
pub fn camera_left() -> CameraModel {
    CameraModel {
        distortion: Distortion {
            k1: -0.21,
            k2: 0.09,
            p1: 4e-4,
            p2: -2e-4,
            k3: 0.0,
        },
        ..CameraModel::pinhole(16, 12, 13.0, 13.0, 7.5, 5.5)
    }
}

fn tile(files: BTreeMap<String, FileRef>, bounds_m: [f64; 4]) -> Vec<Tile> {
    vec![Tile {
        level: 0,
        x: 0,
        y: 0,
        bounds_m,
        files,
    }]
}

fn tiny_image(seed: u8) -> Result<Vec<u8>, EncodeError> {
    let px: Vec<u8> = (0..16u32 * 12)
        .map(|i| ((i * 37 + u32::from(seed) * 11) % 256) as u8)
        .collect();
    png::grey8(16, 12, &px)
}

/// Builds the sample release into `writer`, returning its id. `version` lets tests make a second,
/// different release.
pub fn build(writer: &Writer, version: &str) -> Result<ObjectId, SampleError> {
    let mut rel: Release = new_release(
        "sample",
        version,
        Producer {
            name: "regolith-tests".into(),
            version: "1".into(),
        },
    );
    let z = heights();
    let hf = heightfield::encode(&heightfield::GridInput {
        origin_m: [0.025, 0.625],
        cell_m: CELL_M,
        width: W,
        height: H,
        heights: &z,
        site_origin_m: [1000.0, 2000.0, 0.0],
        source: "laser",
    })?;
    let bounds = hf.meta.bounds();
    let files: BTreeMap<String, FileRef> = [
        (
            roles::HEIGHT.to_string(),
            writer.put(&hf.height_png, media::PNG)?,
        ),
        (
            roles::HEIGHT_F32.to_string(),
            writer.put(&hf.height_exr, media::EXR)?,
        ),
        (
            roles::MASK.to_string(),
            writer.put(&hf.mask_png, media::PNG)?,
        ),
    ]
    .into();
    rel.entries.push(Entry {
        name: "laser/0.05".into(),
        kind: kinds::HEIGHTFIELD.into(),
        meta: serde_json::to_value(&hf.meta)?,
        files: BTreeMap::new(),
        tiles: tile(files, bounds),
    });
    let tex: Vec<[u8; 3]> = (0..W * H)
        .map(|i| [(i % 251) as u8, (i * 3 % 251) as u8, 128])
        .collect();
    let tex_png = png::rgb8(W, H, &tex)?;
    rel.entries.push(Entry {
        name: "laser/0.05/texture".into(),
        kind: kinds::TEXTURE.into(),
        meta: serde_json::to_value(TextureMeta {
            grid_of: "laser/0.05".into(),
            content: "albedo".into(),
            pixels_per_cell: 1,
            bit_depth: 8,
        })?,
        files: BTreeMap::new(),
        tiles: tile(
            [(roles::IMAGE.to_string(), writer.put(&tex_png, media::PNG)?)].into(),
            bounds,
        ),
    });
    let filled = heightfield::fill_holes(&z, W as usize, H as usize);
    let mut lods = Vec::new();
    let mut lod_files = BTreeMap::new();
    let mut origin = [0.0; 3];
    for (n, step) in [1usize, 2].into_iter().enumerate() {
        let (mut m, err) = glb::grid_mesh(
            &filled,
            W as usize,
            H as usize,
            hf.meta.origin_m,
            CELL_M,
            step,
        );
        m.texture_png = Some(tex_png.clone());
        origin = m.local_origin_m;
        lods.push(LodMeta {
            vertices: m.positions.len() as u64,
            triangles: (m.indices.len() / 3) as u64,
            max_height_error_m: err,
        });
        lod_files.insert(
            roles::lod(n as u32),
            writer.put(&glb::encode(&m)?, media::GLB)?,
        );
    }
    rel.entries.push(Entry {
        name: "laser/0.05/mesh".into(),
        kind: kinds::MESH.into(),
        meta: serde_json::to_value(MeshMeta {
            frame: "ground".into(),
            local_origin_m: origin,
            lods,
            texture: Some("laser/0.05/texture".into()),
        })?,
        files: BTreeMap::new(),
        tiles: tile(lod_files, bounds),
    });
    let left = camera_left();
    let right = CameraModel {
        cx: 7.6,
        ..left.clone()
    };
    for (name, cam) in [
        ("cameras/navcam_left", &left),
        ("cameras/navcam_right", &right),
    ] {
        rel.entries.push(Entry {
            name: name.into(),
            kind: kinds::CAMERA.into(),
            meta: serde_json::to_value(CameraMeta { model: cam.clone() })?,
            files: [(roles::CALIBRATION.to_string(), writer.put_json(cam)?)].into(),
            tiles: Vec::new(),
        });
    }
    let rig = RigMeta {
        left: "cameras/navcam_left".into(),
        right: "cameras/navcam_right".into(),
        right_from_left: Pose {
            translation_m: [-0.1, 0.0, 0.0],
            rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
        },
        rig_from_left: Pose::IDENTITY,
    };
    rel.entries.push(Entry {
        name: "rig".into(),
        kind: kinds::RIG.into(),
        meta: serde_json::to_value(&rig)?,
        files: [(roles::CALIBRATION.to_string(), writer.put_json(&rig)?)].into(),
        tiles: Vec::new(),
    });
    let gfl = Pose {
        translation_m: [0.4, -0.5, 0.9],
        rotation_xyzw: quat_from_axis_angle([1.0, 0.0, 0.0], -2.0),
    };
    let gfr = gfl.compose(&rig.right_from_left.inverse());
    let cams = [
        ("navcam_left", &left, gfl, 1u8),
        ("navcam_right", &right, gfr, 5u8),
    ];
    let mut capture = mcap::CaptureFrames {
        name: "loc01".into(),
        cameras: Vec::new(),
        pose_spread: (0.0002, 0.01),
    };
    for (name, model, pose, seed) in cams {
        capture.cameras.push(mcap::CameraFrames {
            camera: name.into(),
            model: model.clone(),
            ground_from_camera: pose,
            raw_png: vec![tiny_image(seed)?, tiny_image(seed + 1)?],
            rect_png: vec![tiny_image(seed + 2)?, tiny_image(seed + 3)?],
        });
    }
    let (mcap_bytes, index) = mcap::encode(&[capture])?;
    rel.entries.push(Entry {
        name: "captures".into(),
        kind: kinds::CAPTURES.into(),
        meta: json!({"captures": 1}),
        files: [
            (
                roles::MCAP.to_string(),
                writer.put(&mcap_bytes, media::MCAP)?,
            ),
            (roles::INDEX.to_string(), writer.put_json(&index)?),
        ]
        .into(),
        tiles: Vec::new(),
    });
    let report = json!({"report": "dem", "cells": W * H, "valid_cells": hf.meta.valid_cells});
    rel.entries.push(Entry {
        name: "reports/dem".into(),
        kind: kinds::REPORT.into(),
        meta: json!({"report": "dem"}),
        files: [(roles::REPORT.to_string(), writer.put_json(&report)?)].into(),
        tiles: Vec::new(),
    });
    rel.campaign = CampaignRef {
        name: "sample".into(),
        inputs: vec![InputFile {
            path: "campaign.toml".into(),
            sha256: ObjectId::of_bytes(b"sample"),
            size: 6,
        }],
    };
    rel.plan = vec![PlanStep {
        stage: "sample.build".into(),
        version: 1,
        params: json!({"cell_m": CELL_M}),
    }];
    Ok(writer.commit(rel, true)?)
}
