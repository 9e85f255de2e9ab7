//! What a real lab's data carry that no campaign records: the laser sees the surface at another
//! wavelength than the NavCams, and the SfM photographs come from another camera with its own
//! exposure and response.
//!
//! A lab that textures its DEM with laser reflectance, or with the colours of an SfM mesh, gets
//! a texture whose radiometry is not the NavCam's; a validator that reads texture values as the
//! NavCam's albedo meets exactly this. The campaigns rendered physically (`--renderer mitsuba`)
//! carry [`World::LAB`]; the validator-model campaigns keep [`World::IDEAL`] (texture sources
//! in the camera's radiometry), which their unit tests were calibrated on. The parameters are
//! written to `truth/lab.json`.

use regolith_format::grid::AlbedoGrid;
use serde::Serialize;

use crate::terrain::synth::material;
use crate::terrain::Terrain;

/// How the laser sees the surface.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LaserRadiometry {
    /// Reflectance at the laser's wavelength over albedo at the camera's, per material id
    /// (soil, gypsum, pebble, marker).
    pub ratio_by_material: [f64; 4],
    /// The return falls as `cos(incidence)^exponent` (1 = Lambertian).
    pub incidence_exponent: f64,
}

/// How the SfM photographs' camera recorded the surface: `DN = 255 · (gain · albedo)^(1/gamma)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PhotoCamera {
    /// Exposure gain relative to the NavCam's.
    pub gain: f64,
    /// Response curve exponent.
    pub gamma: f64,
}

/// The nuisances of a campaign's world.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct World {
    /// `ideal` or `lab`.
    pub name: &'static str,
    /// The laser.
    pub laser: LaserRadiometry,
    /// The SfM photographs' camera.
    pub sfm_camera: PhotoCamera,
}

impl World {
    /// Texture sources in the NavCam's radiometry (the corpus's first world).
    pub const IDEAL: World = World {
        name: "ideal",
        laser: LaserRadiometry {
            ratio_by_material: [1.0; 4],
            incidence_exponent: 1.0,
        },
        sfm_camera: PhotoCamera {
            gain: 1.0,
            gamma: 1.0,
        },
    };

    /// A lab: a near-infrared (1550 nm) scanner, under which the iron-poor gypsum is darker
    /// and the basaltic pebbles and iron-bearing soil brighter than in the visible (ratios of
    /// the order of laboratory spectra of such materials), with a return falling faster than
    /// Lambert's law at grazing incidence; and SfM photographs from a consumer camera, exposed
    /// brighter and stored with an sRGB-like response.
    pub const LAB: World = World {
        name: "lab",
        laser: LaserRadiometry {
            ratio_by_material: [1.25, 0.85, 1.15, 1.0],
            incidence_exponent: 1.4,
        },
        sfm_camera: PhotoCamera {
            gain: 1.2,
            gamma: 2.2,
        },
    };

    /// The albedo the laser sees: the camera's albedo times the material's ratio.
    pub fn laser_albedo(&self, terrain: &Terrain, albedo: &AlbedoGrid) -> AlbedoGrid {
        let mut out = albedo.clone();
        if self.laser.ratio_by_material == [1.0; 4] || out.value.len() != terrain.material.len() {
            return out;
        }
        for (v, &m) in out.value.iter_mut().zip(&terrain.material) {
            let k = match m {
                material::GYPSUM => 1,
                material::PEBBLE => 2,
                material::MARKER => 3,
                _ => 0,
            };
            *v = (f64::from(*v) * self.laser.ratio_by_material[k]).min(1.0) as f32;
        }
        out
    }

    /// An SfM photograph's grey value of albedo `a`.
    pub fn photo_dn(&self, a: f64) -> u8 {
        let c = self.sfm_camera;
        let v = if c.gain == 1.0 && c.gamma == 1.0 {
            a
        } else {
            (c.gain * a).clamp(0.0, 1.0).powf(1.0 / c.gamma)
        };
        (255.0 * v).round().clamp(0.0, 255.0) as u8
    }
}
