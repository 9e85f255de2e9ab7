//! All the objects of one terrain raster: the heightfield's PNG, mask and EXR (SPEC §5.1), the
//! mesh levels of detail as GLB (§5.3) with the raster's texture embedded, and their metadata.
//!
//! Why a module of its own: encoding is a pure function of the raster, and it is most of what
//! `encode.terrain` costs (quadric simplification, PNG/EXR compression). Kept apart from the
//! database writes, the rasters of a terrain encode in parallel and are stored afterwards in a
//! fixed order, so entries and bytes are those of a sequential run on any thread count.

use rayon::prelude::*;
use regolith_format::kinds::LodMeta;

use super::heightfield::{self, EncodedHeightfield, GridInput};
use super::{glb, mesh_lod, EncodeError};

/// The encoded objects of one raster.
#[derive(Debug, Clone)]
pub struct EncodedTerrain {
    /// Heightfield objects and metadata.
    pub heightfield: EncodedHeightfield,
    /// The texture PNG, when the raster has one (also embedded in every level's GLB).
    pub texture: Option<Vec<u8>>,
    /// GLB bytes and metadata per level of detail, lod0 first.
    pub lods: Vec<(Vec<u8>, LodMeta)>,
    /// Ground position of the meshes' local origin.
    pub local_origin_m: [f64; 3],
}

/// Encodes a grid, its optional texture and up to `lods` mesh levels (at least one). Levels
/// stop early when the simplifier can go no further (the locked border bounds it): a level
/// with fewer than 4 vertices or no fewer triangles than the one before is not kept.
pub fn encode(
    g: &GridInput<'_>,
    texture: Option<Vec<u8>>,
    lods: u32,
) -> Result<EncodedTerrain, EncodeError> {
    let (w, h) = (g.width as usize, g.height as usize);
    let filled = heightfield::fill_holes(g.heights, w, h);
    let (hf, levels) = rayon::join(
        || heightfield::encode_filled(g, &filled),
        || mesh_lod::LodBuilder::new(&filled, w, h, g.origin_m, g.cell_m).lods(lods.max(1)),
    );
    let mut kept: Vec<(glb::GlbMesh, LodMeta)> = Vec::new();
    for (m, err) in levels {
        let triangles = (m.indices.len() / 3) as u64;
        if m.positions.len() < 4 || kept.last().is_some_and(|l| triangles >= l.1.triangles) {
            break;
        }
        let meta = LodMeta {
            vertices: m.positions.len() as u64,
            triangles,
            max_height_error_m: err,
        };
        kept.push((m, meta));
    }
    let local_origin_m = kept.last().map_or([0.0; 3], |(m, _)| m.local_origin_m);
    let lods = kept
        .into_par_iter()
        .map(|(mut m, meta)| {
            m.texture_png.clone_from(&texture);
            Ok((glb::encode(&m)?, meta))
        })
        .collect::<Result<Vec<_>, EncodeError>>()?;
    Ok(EncodedTerrain {
        heightfield: hf?,
        texture,
        lods,
        local_origin_m,
    })
}
