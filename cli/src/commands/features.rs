//! `regolith features detect|repeat`: the detectors and the repeatability metric the
//! certificates use, on a user's own images.

use std::path::Path;

use anyhow::{bail, Context};
use regolith_compiler::ingest::{homography, images};
use regolith_format::limits::Limits;
use regolith_validator::features::{self, contrast, Detector, DetectorParams, GreyF32};
use regolith_validator::metrics::repeatability::{repeatability, EPSILONS};

use super::print_json;
use crate::args::FeaturesAction;
use crate::Outcome;

fn load(path: &Path) -> anyhow::Result<GreyF32> {
    let g = images::read_path(&crate::paths::absolute(path)?, &Limits::default())?;
    let img = GreyF32::new(g.width as usize, g.height as usize, g.data).context("empty image")?;
    Ok(contrast::stretch(&img))
}

pub fn run(action: &FeaturesAction, json: bool) -> anyhow::Result<Outcome> {
    let params = DetectorParams::default();
    match action {
        FeaturesAction::Detect { image, detector } => {
            let d: Detector = detector.parse()?;
            let img = load(image)?;
            let kps = features::detect(&img, d, &params);
            if json {
                print_json(&serde_json::json!({"image": image, "detector": d, "keypoints": kps}))?;
            } else {
                say!(
                    "{}: {} {} keypoints ({}x{})",
                    image.display(),
                    kps.len(),
                    d.name(),
                    img.width,
                    img.height
                );
                for k in kps.iter().take(10) {
                    say!(
                        "  x {:8.2}  y {:8.2}  size {:6.2}  response {:.4}",
                        k.x,
                        k.y,
                        k.size,
                        k.response
                    );
                }
            }
        }
        FeaturesAction::Repeat {
            image_a,
            image_b,
            detector,
            homography: h,
            same_pose,
        } => {
            let d: Detector = detector.parse()?;
            let (a, b) = (load(image_a)?, load(image_b)?);
            let h = match (h, same_pose) {
                (Some(p), _) => {
                    homography::read_path(&crate::paths::absolute(p)?, &Limits::default())?
                }
                (None, true) => [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                (None, false) => bail!(
                    "`features repeat` needs to know how pixels of A map to B: give \
                     --homography FILE (FILE holding {}) or --same-pose (both images taken from \
                     the same pose)",
                    homography::ACCEPTED
                ),
            };
            let pts = |img: &GreyF32| -> Vec<[f64; 2]> {
                features::detect(img, d, &params)
                    .iter()
                    .map(|k| [f64::from(k.x), f64::from(k.y)])
                    .collect()
            };
            let (pa, pb) = (pts(&a), pts(&b));
            let map = |p: [f64; 2]| {
                let w = h[6] * p[0] + h[7] * p[1] + h[8];
                (w.abs() > 1e-12).then(|| {
                    [
                        (h[0] * p[0] + h[1] * p[1] + h[2]) / w,
                        (h[3] * p[0] + h[4] * p[1] + h[5]) / w,
                    ]
                })
            };
            let (bw, bh) = (b.width as f64, b.height as f64);
            let inside =
                |p: [f64; 2]| p[0] >= -0.5 && p[1] >= -0.5 && p[0] < bw - 0.5 && p[1] < bh - 0.5;
            let curve = repeatability(&pa, &pb, map, inside, bw * bh, &EPSILONS);
            if json {
                print_json(
                    &serde_json::json!({"detector": d, "keypoints": [pa.len(), pb.len()], "repeatability": curve}),
                )?;
            } else {
                say!(
                    "{} keypoints: {} in A, {} in B",
                    d.name(),
                    pa.len(),
                    pb.len()
                );
                for r in &curve {
                    say!(
                        "  ε {:>3.1} px: repeatability {:.3} ({} repeated of min({}, {})), one-directional {:.3}, over chance {:.3} (chance {:.3})",
                        r.epsilon_px, r.score, r.repeated, r.n_a, r.n_b, r.one_directional, r.excess, r.chance
                    );
                }
            }
        }
    }
    Ok(Outcome::Ok)
}
