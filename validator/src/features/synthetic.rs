//! Deterministic synthetic test scenes with analytic warps, for detector tests and benches.
//!
//! A [`BlobScene`] is a continuous image: a smooth background plus opaque ellipses painted in
//! order, each with a one-pixel anti-aliased edge. Because the scene is a function of continuous
//! coordinates, an image warped by a known map is rendered exactly (`render` samples the scene
//! at the inverse-mapped pixel centre) instead of by resampling, so repeatability under a known
//! homography measures the detector and nothing else. Blob lookup uses a 32-px bucket grid.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::image::GreyF32;

/// One opaque ellipse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipse {
    /// Centre column, px.
    pub x: f64,
    /// Centre row, px.
    pub y: f64,
    /// Semi-axis along the rotated x axis, px.
    pub a: f64,
    /// Semi-axis along the rotated y axis, px.
    pub b: f64,
    /// Rotation, radians.
    pub theta: f64,
    /// Grey value in `[0, 1]`.
    pub value: f64,
}

impl Ellipse {
    /// Coverage in `[0, 1]` of the point `(x, y)` (1 inside, a ~1 px linear edge).
    pub fn coverage(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.x, y - self.y);
        let (c, s) = (self.theta.cos(), self.theta.sin());
        let (u, v) = (c * dx + s * dy, -s * dx + c * dy);
        let d = ((u / self.a).powi(2) + (v / self.b).powi(2)).sqrt();
        (0.5 - (d - 1.0) * self.a.min(self.b)).clamp(0.0, 1.0)
    }
}

/// A background plus ellipses painted in order.
#[derive(Debug, Clone)]
pub struct BlobScene {
    /// The ellipses, painted first to last.
    pub blobs: Vec<Ellipse>,
    width: f64,
    height: f64,
    cell: f64,
    grid_w: usize,
    grid: Vec<Vec<usize>>,
}

impl BlobScene {
    /// A scene of the given extent from explicit ellipses.
    pub fn new(width: f64, height: f64, blobs: Vec<Ellipse>) -> BlobScene {
        let cell = 32.0;
        let grid_w = (width / cell).ceil().max(1.0) as usize + 1;
        let grid_h = (height / cell).ceil().max(1.0) as usize + 1;
        let mut grid = vec![Vec::new(); grid_w * grid_h];
        for (i, e) in blobs.iter().enumerate() {
            let r = e.a.max(e.b) + 1.0;
            let cx0 = ((e.x - r) / cell).floor().max(0.0) as usize;
            let cy0 = ((e.y - r) / cell).floor().max(0.0) as usize;
            let cx1 = (((e.x + r) / cell).floor().max(0.0) as usize).min(grid_w - 1);
            let cy1 = (((e.y + r) / cell).floor().max(0.0) as usize).min(grid_h - 1);
            for gy in cy0..=cy1 {
                for gx in cx0..=cx1 {
                    if let Some(c) = grid.get_mut(gy * grid_w + gx) {
                        c.push(i);
                    }
                }
            }
        }
        BlobScene {
            blobs,
            width,
            height,
            cell,
            grid_w,
            grid,
        }
    }

    /// `n` random ellipses with semi-axes in `radius` (px), seeded.
    pub fn random(
        width: usize,
        height: usize,
        n: usize,
        radius: (f64, f64),
        seed: u64,
    ) -> BlobScene {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (w, h) = (width as f64, height as f64);
        let blobs = (0..n)
            .map(|_| {
                let a = rng.gen_range(radius.0..radius.1);
                Ellipse {
                    x: rng.gen_range(0.0..w),
                    y: rng.gen_range(0.0..h),
                    a,
                    b: a * rng.gen_range(0.4..1.0),
                    theta: rng.gen_range(0.0..std::f64::consts::PI),
                    value: rng.gen_range(0.05..0.95),
                }
            })
            .collect();
        BlobScene::new(w, h, blobs)
    }

    /// Scene value at `(x, y)`.
    pub fn sample(&self, x: f64, y: f64) -> f64 {
        let mut v = 0.35 + 0.3 * (x / self.width.max(1.0)) * (1.0 - 0.5 * y / self.height.max(1.0));
        if x < 0.0 || y < 0.0 {
            return v;
        }
        let (gx, gy) = ((x / self.cell) as usize, (y / self.cell) as usize);
        if gx >= self.grid_w {
            return v;
        }
        for &i in self
            .grid
            .get(gy * self.grid_w + gx)
            .map(Vec::as_slice)
            .unwrap_or(&[])
        {
            if let Some(e) = self.blobs.get(i) {
                let c = e.coverage(x, y);
                v = v * (1.0 - c) + e.value * c;
            }
        }
        v
    }

    /// Renders `width × height` pixels; pixel `(u, v)` shows the scene at `source(u, v)`
    /// (the inverse of the warp; identity for the plain scene).
    pub fn render<F>(&self, width: usize, height: usize, source: F) -> GreyF32
    where
        F: Fn(f64, f64) -> (f64, f64) + Sync,
    {
        let mut data = vec![0.0f32; width * height];
        data.par_chunks_mut(width.max(1))
            .enumerate()
            .for_each(|(v, row)| {
                for (u, o) in row.iter_mut().enumerate() {
                    let (x, y) = source(u as f64, v as f64);
                    *o = self.sample(x, y) as f32;
                }
            });
        GreyF32 {
            width,
            height,
            data,
        }
    }
}

/// The bench and peer scene: 1280×1024 with 2500 blobs of 2–24 px, seed 7, quantised to
/// 8-bit levels.
pub fn bench_scene() -> GreyF32 {
    let scene = BlobScene::random(1280, 1024, 2500, (2.0, 24.0), 7);
    let img = scene.render(1280, 1024, |x, y| (x, y));
    let levels = img.to_u8();
    GreyF32::from_u8(1280, 1024, &levels).unwrap_or(img)
}
