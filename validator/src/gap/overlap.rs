//! The vignetting estimate's second witness: the same terrain point seen by two views at two
//! image radii (flat-fielding from overlap, as in Goldman & Chen, "Vignette and exposure
//! calibration and compensation", ICCV 2005).
//!
//! The photometric fit compares real images with renders of the entry, so any error of the
//! entry's radiance that varies over the image is taken for an effect. On a terrain it does
//! vary with the image radius: the far terrain fills the top of the image, the near terrain
//! the bottom, and a laser entry's shading and reflectance are wrong by a range-dependent
//! amount (mini seed 103: a vignetting of 0.173 came out 0.133). A point of a Lambertian
//! terrain under a fixed light has one radiance whoever looks at it, so the radiance two views'
//! real DN invert to must agree there, whatever the entry gets wrong: the log ratio of the two
//! inverted radiances depends only on the response curve, the offset and the falloff at the
//! two radii. Those pairs enter the final fit next to the render's samples
//! ([`super::photometry::refit_with_overlap`]); the render's samples still fix the gain and the
//! response curve (vignetting and the response are only identifiable together from overlap).
//!
//! Correspondences come from the render's depth: a sample of view A is unprojected through
//! A's render camera, moved to view B and kept if B's render sees the same surface there
//! (depth within [`DEPTH_TOLERANCE`]) inside B's eroded terrain mask. Only views of one capture
//! are paired (the stereo head's two cameras): they see the terrain at the same instant, under
//! the same light and exposure, and their relative pose is the calibrated stereo extrinsic
//! rather than two capture poses with their own errors. Pairs across captures pulled the
//! estimate away from the truth (mini seed 103, hidden 0.173: pairs within captures alone
//! gave 0.175, all pairs 0.125).

use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;

use super::geometry::bilinear;
use super::photometry::{rho2_scale, usable, Analysis, STRIDE};
use super::views::{GapView, Prediction};

/// Relative depth difference up to which a point is taken to be visible in the other view.
pub const DEPTH_TOLERANCE: f64 = 0.02;

/// A view as the second of a pair sees the terrain: its render camera, the inverse of the pose
/// the render used, the render's depth and an eroded terrain mask.
pub struct DepthView<'a> {
    /// The render's camera.
    pub camera: &'a CameraModel,
    /// Inverse of the render's `ground_from_camera`.
    pub camera_from_ground: Pose,
    /// The render's camera-frame depth (`NaN` off terrain).
    pub depth: &'a [f32],
    /// Pixels far enough inside the terrain.
    pub inner: &'a [bool],
    /// Width.
    pub w: usize,
    /// Height.
    pub h: usize,
}

impl DepthView<'_> {
    /// Where this view sees the ground point `ground`, at least `margin` px inside its border,
    /// if its render sees that same surface there (depth within [`DEPTH_TOLERANCE`]) inside
    /// `inner`: the point in this camera's frame, its pixel position and the pixel's index.
    pub fn sees(&self, ground: [f64; 3], margin: f64) -> Option<([f64; 3], [f64; 2], usize)> {
        let pc = self.camera_from_ground.transform_point(ground);
        let [u, v] = self.camera.project(pc)?;
        let edge = u
            .min(v)
            .min(self.w as f64 - 1.0 - u)
            .min(self.h as f64 - 1.0 - v);
        if edge.is_nan() || edge < margin {
            return None;
        }
        let j = v.round() as usize * self.w + u.round() as usize;
        let zb = f64::from(self.depth[j]);
        // A NaN or infinite depth (no surface) compares false: not visible.
        let visible = (zb - pc[2]).abs() <= DEPTH_TOLERANCE * pc[2];
        (visible && self.inner[j]).then_some((pc, [u, v], j))
    }
}

/// One terrain point seen by two views.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    /// Fold (capture) of the first view.
    pub fold: usize,
    /// Fold of the second view (the first's for pairs within a capture).
    pub other_fold: usize,
    /// Real mean DN (low-passed like the photometric samples) in each view.
    pub real: [f64; 2],
    /// The render's radiance (after the PSF, low-passed likewise) in each view.
    pub render: [f64; 2],
    /// Normalised squared image radius in each view (as [`super::photometry::Samples::rho2`]).
    pub rho2: [f64; 2],
    /// The point's ground `x`, `y`, metres.
    pub ground: [f64; 2],
}

/// Which views [`pairs`] pairs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pairing {
    /// Views of one capture (the stereo head's cameras): one instant, light and exposure.
    WithinCaptures,
    /// Views of different captures ([`super::capture_exposure`]).
    AcrossCaptures,
}

struct Prepared<'a> {
    analysis: &'a Analysis,
    pred: &'a Prediction,
    pose: Pose,
    seen: DepthView<'a>,
    scale: f64,
    cx: f64,
    cy: f64,
    w: usize,
    h: usize,
}

/// The pairs of every two views of one capture (fold), or of two different captures, as
/// `pairing` says. `analyses` are the views' [`Analysis`] images with `preds`; `poses` are the
/// `ground_from_camera` the renders used.
pub fn pairs(
    views: &[GapView],
    preds: &[Prediction],
    analyses: &[Analysis],
    folds: &[usize],
    poses: &[Pose],
    pairing: Pairing,
) -> Vec<Pair> {
    let across = pairing == Pairing::AcrossCaptures;
    let prepared: Vec<Prepared<'_>> = views
        .iter()
        .zip(preds)
        .zip(analyses)
        .zip(poses)
        .map(|(((v, p), analysis), pose)| {
            let (w, h) = (v.width, v.height);
            Prepared {
                analysis,
                pred: p,
                pose: *pose,
                seen: DepthView {
                    camera: &p.camera,
                    camera_from_ground: pose.inverse(),
                    depth: &p.depth,
                    inner: &analysis.eroded,
                    w,
                    h,
                },
                scale: rho2_scale(&v.camera_model, w, h),
                cx: v.camera_model.cx,
                cy: v.camera_model.cy,
                w,
                h,
            }
        })
        .collect();
    let mut out = Vec::new();
    for (a, va) in prepared.iter().enumerate() {
        for y in (0..va.h).step_by(STRIDE) {
            for x in (0..va.w).step_by(STRIDE) {
                let i = y * va.w + x;
                let z = f64::from(va.pred.depth[i]);
                let ra = f64::from(va.analysis.real[i]);
                let render_a = f64::from(va.analysis.render[i]);
                if !va.analysis.eroded[i] || !z.is_finite() || z <= 0.0 || !usable(ra) {
                    continue;
                }
                let (xn, yn) = va.pred.camera.unproject(x as f64, y as f64);
                let ground = va.pose.transform_point([xn * z, yn * z, z]);
                let rho2_a = ((x as f64 - va.cx).powi(2) + (y as f64 - va.cy).powi(2)) / va.scale;
                let others = prepared.iter().zip(folds).skip(a + 1);
                for (vb, &fold_b) in others.filter(|(_, f)| (**f == folds[a]) != across) {
                    let Some((_, [u, v], _)) = vb.seen.sees(ground, 0.0) else {
                        continue;
                    };
                    let Some(rb) =
                        bilinear(&vb.analysis.real, vb.w, vb.h, u, v).filter(|r| usable(*r))
                    else {
                        continue;
                    };
                    let render_b =
                        bilinear(&vb.analysis.render, vb.w, vb.h, u, v).unwrap_or(f64::NAN);
                    out.push(Pair {
                        fold: folds[a],
                        other_fold: fold_b,
                        real: [ra, rb],
                        render: [render_a, render_b],
                        rho2: [
                            rho2_a,
                            ((u - vb.cx).powi(2) + (v - vb.cy).powi(2)) / vb.scale,
                        ],
                        ground: [ground[0], ground[1]],
                    });
                }
            }
        }
    }
    out
}
