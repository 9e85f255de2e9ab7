//! Survey markers are kept out of the geometric fit.
//!
//! Why: the static Vicon/RIEGL marker balls of a testbed (13 mm radius on the ESTEC yard) are
//! in the captures — the rover is driven to look at them — and each is the brightest, sharpest
//! thing in its image: a white ball on dark soil. A DEM cannot represent it (a 1 cm raster
//! holds a ball as a blunt bump, its far side extrapolated from what the scanner saw), so the
//! render's ball is in the wrong place by construction, and a real ball is an occluding contour
//! whose outline differs between the two cameras, which the stereo pairs' surface model cannot
//! follow. Least squares on band-passed images gives the ball the weight of its contrast. On
//! mini seed 103 with a pose bias hidden (six captures, `laser/0.01`) the 0.7 % of render
//! samples within 4 cm of a marker and the 2.6 % of stereo pairs within 8 cm accounted for all
//! the fit's preference for its solution (0.50° of pitch and 15 mm off) over the truth: every
//! other group of samples preferred the truth. The marker positions are known to a fraction of
//! a millimetre (the Vicon means of the `registration` report), so their discs are removed
//! from the terrain mask the geometric stage band-passes and samples with: both images are
//! filled with the terrain mean there, and no sample or pair lies in them. The alignment
//! residual the gap reports (the figure a geometric effect is judged by, [`super::measure`])
//! samples the same masks, so it measures what the fit lowered.

use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;
use regolith_reader::{ReaderError, ReleaseView};

/// Radius of the ground region kept out around a marker's centre, metres: the ball (13 mm)
/// with the blunt, wider bump the DEM makes of it and the terrain it occludes from a camera
/// 25–40° above the horizon.
pub const KEEP_OUT_M: f64 = 0.05;

/// The ground-frame marker centres of the release's `reports/registration` (`ground_markers[]
/// .mean_m`, the Vicon means); none when the release has no such report or it lists none.
pub fn survey_markers(view: &ReleaseView) -> Result<Vec<[f64; 3]>, ReaderError> {
    if view.entry("reports/registration").is_err() {
        return Ok(Vec::new());
    }
    let report = view.report("reports/registration")?;
    let Some(list) = report["ground_markers"].as_array() else {
        return Ok(Vec::new());
    };
    Ok(list
        .iter()
        .filter_map(|m| {
            let v = m["mean_m"].as_array()?;
            let c: Vec<f64> = v.iter().filter_map(serde_json::Value::as_f64).collect();
            (c.len() == 3 && c.iter().all(|x| x.is_finite())).then(|| [c[0], c[1], c[2]])
        })
        .collect())
}

/// Clears from `mask` (`w` × `h`, row-major) the image of a sphere of radius [`KEEP_OUT_M`]
/// about each of `markers` (ground frame), seen through `camera` at `ground_from_camera`.
pub fn keep_out(
    mask: &mut [bool],
    w: usize,
    h: usize,
    camera: &CameraModel,
    ground_from_camera: &Pose,
    markers: &[[f64; 3]],
) {
    let camera_from_ground = ground_from_camera.inverse();
    for m in markers {
        let c = camera_from_ground.transform_point(*m);
        // A sphere the camera is inside of, or behind the camera, is not in the image.
        if c[2] <= KEEP_OUT_M {
            continue;
        }
        let Some([u, v]) = camera.project(c) else {
            continue;
        };
        // The sphere's angular radius, in pixels at the centre's distance, and one pixel more
        // for the discretisation and the distortion's local scale.
        let dist = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        let r = camera.fx.max(camera.fy) * (KEEP_OUT_M / dist).asin().tan() + 1.0;
        let (x0, x1) = ((u - r).floor().max(0.0), (u + r).ceil().min(w as f64 - 1.0));
        let (y0, y1) = ((v - r).floor().max(0.0), (v + r).ceil().min(h as f64 - 1.0));
        if x0 > x1 || y0 > y1 {
            continue;
        }
        for y in y0 as usize..=y1 as usize {
            for x in x0 as usize..=x1 as usize {
                if (x as f64 - u).powi(2) + (y as f64 - v).powi(2) <= r * r {
                    mask[y * w + x] = false;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use regolith_format::camera_model::Distortion;

    fn camera() -> CameraModel {
        CameraModel {
            model: regolith_format::camera_model::MODEL_ID.into(),
            width: 200,
            height: 100,
            fx: 400.0,
            fy: 400.0,
            cx: 99.5,
            cy: 49.5,
            skew: 0.0,
            distortion: Distortion::default(),
        }
    }

    #[test]
    fn a_marker_clears_a_disc_of_its_keep_out_radius_and_nothing_else() {
        let (w, h) = (200, 100);
        let mut mask = vec![true; w * h];
        // 2 m in front of the camera, 0.1 m to its right: image centre (119.5, 49.5), radius
        // 400 · tan(asin(0.05 / 2.0025)) + 1 ≈ 11.0 px.
        keep_out(
            &mut mask,
            w,
            h,
            &camera(),
            &Pose::IDENTITY,
            &[[0.1, 0.0, 2.0], [0.0, 0.0, -2.0]],
        );
        let cleared: Vec<(usize, usize)> = (0..w * h)
            .filter(|&i| !mask[i])
            .map(|i| (i % w, i / w))
            .collect();
        let r = 400.0 * (0.05f64 / (0.1f64.powi(2) + 4.0).sqrt()).asin().tan() + 1.0;
        assert!(cleared
            .iter()
            .all(|&(x, y)| (x as f64 - 119.5).powi(2) + (y as f64 - 49.5).powi(2) <= r * r));
        let area = std::f64::consts::PI * r * r;
        assert!(
            (cleared.len() as f64 - area).abs() < 0.1 * area,
            "{} px cleared for a disc of {area:.0}",
            cleared.len()
        );
        assert!(mask[49 * w + 99] && !mask[49 * w + 119]);
    }
}
