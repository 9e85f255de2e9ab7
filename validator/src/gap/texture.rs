//! The `texture-lowpass` effect: how much smoother the entry's texture is than the albedo the
//! camera sees.
//!
//! Dividing an image by the render of the same view with a uniform albedo (shading only)
//! leaves the true albedo (times the shading the render does not reproduce, which is not
//! correlated with the texture). The comparison is made **on the ground, in the texture's own
//! cells**: every terrain pixel is back-projected through the render's depth and the pose and
//! lens the render used, and the ratios of the pixels that land in a cell are averaged (a cell
//! counts once it receives three). A view's real albedo is then the texture's grid
//! seen by the camera, so a blur of σ metres is the same Gaussian everywhere in it, whatever
//! the view's depth and obliquity. (An earlier version compared images: a ground blur became
//! σ / GSD pixels at the view's median depth, which is wrong along the view direction of an
//! oblique camera and wrong away from the median depth, so the reading depended on the
//! campaign's geometry — faithful 1.5 cm textures read 6.0 mm on estec, 10.5 mm at 1 cm on
//! mini — and a hidden 20 mm low-pass on estec was not detected.)
//!
//! The real albedo is blurred by a Gaussian of σ on a 2 mm ladder and correlated with the
//! texture, both band-passed (difference of Gaussians of 0.5 and 5 cells: from the cell to the
//! decimetre patches every texture holds) by normalised convolution over the cells the view
//! sees. If the texture is the real albedo blurred by σ_t, the correlation peaks near σ = σ_t:
//! blurring the real albedo less leaves detail the texture lacks, more removes detail it holds.
//! The peak (parabola through the best step, pooled over views) is the texture's **effective
//! blur**.
//!
//! A faithful texture has an effective blur of its own: its cells (the compile's Gaussian
//! average of the points within a cell), what the instrument adds (range noise moves a point's
//! reflectance, registration) and what the measure adds (shading detail of relief finer than
//! the DEM is in the real albedo only, and the peak blurs it away). [`own_blur_m`] models it
//! as `sqrt(A² + (b·c)²)`, fitted on faithful textures of both presets at 1–3 cm cells. The
//! excess `sqrt(σ_fit² − σ_own²)` over [`EXCESS_PER_SIGMA`] is the low-pass the texture has
//! on top; `texture-lowpass` is named when it is at least [`MIN_EXCESS_M`]. The spread of
//! faithful textures' effective blurs makes low-passes under ~10 mm undetectable; the corpus
//! draws them from 15–30 mm (figures: docs/gap-findings.md, "The texture's effective blur").
//!
//! Sharpening the texture (an inverse of the fitted Gaussian, or Van Cittert iterations) does
//! not bring the detail back: it made every measure worse, because it amplifies the texture's
//! own noise (figures: the same section). So the model adds detail with
//! the missing *spectrum* to sample renders instead ([`crate::sensor::detail`]); the real
//! pattern needs a sharper texture source.

use rayon::prelude::*;
use regolith_format::camera_model::CameraModel;
use regolith_format::frames::Pose;

use crate::render::unproject;
use crate::render::AlbedoGrid;
use crate::sensor::gaussian_blur;

pub use crate::sensor::detail::{own_blur_m, OWN_BLUR_BASE_M, OWN_BLUR_PER_CELL};

/// One view for the texture measure (`w x h` images).
#[derive(Debug, Clone, Copy)]
pub struct TextureView<'a> {
    /// Real frame mean, on radiance (response curve undone).
    pub real: &'a [f32],
    /// Prediction of the same view with a uniform albedo, on radiance.
    pub flat: &'a [f32],
    /// The render sees terrain.
    pub mask: &'a [bool],
    /// Render depth along the optical axis at each pixel centre, metres.
    pub depth: &'a [f32],
    /// The camera the render used.
    pub camera: &'a CameraModel,
    /// The pose the render used.
    pub ground_from_camera: &'a Pose,
    /// Width.
    pub w: usize,
    /// Height.
    pub h: usize,
    /// Cross-validation fold (capture).
    pub fold: usize,
}

/// Ground blurs tried, metres: 0, 2, …, 50 mm.
fn ladder() -> Vec<f64> {
    (0..=25).map(|i| 0.002 * f64::from(i)).collect()
}

/// Band-pass of the correlation, in texture cells (difference of these two Gaussians): from
/// the cell itself to the decimetre patches every texture holds.
const BAND_CELLS: (f64, f64) = (0.5, 5.0);

/// Fewest image pixels a cell must receive for its real albedo to count (a cell seen by fewer
/// is blurred by the pixel footprint rather than averaged over it).
const MIN_PIXELS: u32 = 3;

/// A cell counts where at least this share of the coarse band's neighbourhood is seen.
const MIN_COVERAGE: f32 = 0.5;

/// Lowest radiance of the uniform-albedo render at which a pixel's albedo is used (DN scale).
const MIN_FLAT_DN: f32 = 5.0;

/// The sums of one view at every step of the ladder.
#[derive(Debug, Clone)]
struct ViewSums {
    fold: usize,
    /// Σ real·texture, per ladder step.
    cov: Vec<f64>,
    /// Σ real², per ladder step.
    var_real: Vec<f64>,
    /// Σ texture².
    var_texture: f64,
}

/// The real albedo of one view on a window of the texture grid.
struct Ortho {
    /// First column and row of the window in the texture grid.
    col0: usize,
    row0: usize,
    /// Window size, cells.
    w: usize,
    h: usize,
    /// Mean real/flat ratio of the pixels in each cell (0 where not seen).
    value: Vec<f32>,
    /// 1 where the cell received at least [`MIN_PIXELS`] pixels, else 0.
    weight: Vec<f32>,
}

/// Excess effective blur per metre of hidden low-pass: the measure reads a low-pass about
/// 1.3 times too wide (13 hidden low-passes of 13–20 mm on both presets and 1–3 cm cells:
/// 0.87–1.60, mean 1.29), because the real albedo image also holds shading detail the
/// uniform-albedo render lacks (relief finer than the DEM), which the blur that maximises the
/// correlation also removes; the weaker the campaign's ambient light, the more.
pub const EXCESS_PER_SIGMA: f64 = 1.3;

/// Relative standard deviation of [`EXCESS_PER_SIGMA`] over those 13 low-passes (0.23 / 1.29):
/// part of a fitted low-pass's standard error.
pub const EXCESS_SPREAD: f64 = 0.17;

/// Smallest low-pass named, metres: 13 mm of excess effective blur, twice the widest excess a
/// faithful texture read (6.5 mm); the corpus draws hidden low-passes of 15–30 mm.
pub const MIN_EXCESS_M: f64 = 0.010;

/// The low-pass, metres, that an effective blur `sigma_fit_m` shows on top of the texture's
/// own (0 when the texture is not blurrier than a faithful one).
pub fn excess_m(sigma_fit_m: f64, cell_m: f64) -> f64 {
    (sigma_fit_m.powi(2) - own_blur_m(cell_m).powi(2))
        .max(0.0)
        .sqrt()
        / EXCESS_PER_SIGMA
}

/// The measured texture blur.
#[derive(Debug, Clone)]
pub struct TextureMeasure {
    sums: Vec<ViewSums>,
    ladder: Vec<f64>,
}

impl TextureMeasure {
    /// Band-passed correlations of every view with the entry's `texture` at every ladder step.
    /// `None` when no view has enough terrain.
    pub fn new(views: &[TextureView<'_>], texture: &AlbedoGrid) -> Option<TextureMeasure> {
        let ladder = ladder();
        let sums: Vec<ViewSums> = views
            .iter()
            .filter_map(|v| view_sums(&ortho(v, texture, &ladder)?, texture, v.fold, &ladder))
            .collect();
        (!sums.is_empty()).then_some(TextureMeasure { sums, ladder })
    }

    /// Pooled correlation at each ladder step over the views whose fold passes `keep`.
    fn profile(&self, keep: &dyn Fn(usize) -> bool) -> Vec<f64> {
        (0..self.ladder.len())
            .map(|k| {
                let (mut c, mut a, mut t) = (0.0, 0.0, 0.0);
                for s in self.sums.iter().filter(|s| keep(s.fold)) {
                    c += s.cov[k];
                    a += s.var_real[k];
                    t += s.var_texture;
                }
                if a > 0.0 && t > 0.0 {
                    c / (a * t).sqrt()
                } else {
                    f64::NAN
                }
            })
            .collect()
    }

    /// Effective blur, metres, over the views whose fold passes `keep`, with the correlation
    /// there; `None` when no view passes.
    pub fn blur_m(&self, keep: &dyn Fn(usize) -> bool) -> Option<(f64, f64)> {
        let p = self.profile(keep);
        let best = (0..p.len())
            .filter(|&k| p[k].is_finite())
            .max_by(|&a, &b| p[a].total_cmp(&p[b]))?;
        if best == 0 || best + 1 == p.len() {
            return Some((self.ladder[best], p[best]));
        }
        let (l, c, r) = (p[best - 1], p[best], p[best + 1]);
        let curvature = l - 2.0 * c + r;
        let offset = if curvature < 0.0 {
            (0.5 * (l - r) / curvature).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        let step = self.ladder[1] - self.ladder[0];
        Some((self.ladder[best] + offset * step, c))
    }

    /// The folds present.
    pub fn folds(&self) -> Vec<usize> {
        let mut f: Vec<usize> = self.sums.iter().map(|s| s.fold).collect();
        f.sort_unstable();
        f.dedup();
        f
    }
}

/// log10 of the band power (the correlation's band: a difference of Gaussians of 0.5 and 5
/// cells) of `texture` over that of
/// the real albedo, on the cells the views see: how much of the real surface's fine texture
/// the entry's texture holds. A faithful texture holds less than all of it (its own blur),
/// a low-passed one less again; the procedural detail of a `texture-lowpass`
/// ([`crate::sensor::detail`]) gives the power back. `None` without enough terrain.
pub fn band_power_log_ratio(views: &[TextureView<'_>], texture: &AlbedoGrid) -> Option<f64> {
    let ladder = [0.0];
    let (t, r) = views
        .iter()
        .filter_map(|v| view_sums(&ortho(v, texture, &ladder)?, texture, v.fold, &ladder))
        .fold((0.0, 0.0), |(t, r), s| {
            (t + s.var_texture, r + s.var_real[0])
        });
    (t > 0.0 && r > 0.0).then(|| (t / r).log10())
}

/// The real albedo of view `v` gathered on the cells of `texture` it sees (each pixel centre
/// back-projected through the render's depth); `None` without enough cells. The window has a
/// margin for the widest blur.
fn ortho(v: &TextureView<'_>, texture: &AlbedoGrid, ladder: &[f64]) -> Option<Ortho> {
    let n = v.w * v.h;
    if [v.real.len(), v.flat.len(), v.mask.len(), v.depth.len()]
        .iter()
        .any(|&l| l < n)
        || texture.cell_m <= 0.0
        || texture.width == 0
        || texture.height == 0
    {
        return None;
    }
    let c = texture.cell_m;
    let hits: Vec<(usize, f32)> = (0..v.h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..v.w).filter_map(move |x| {
                let i = y * v.w + x;
                let d = f64::from(v.depth[i]);
                if !v.mask[i] || v.flat[i] <= MIN_FLAT_DN || !(d > 0.0 && d.is_finite()) {
                    return None;
                }
                let (xn, yn) = unproject(v.camera, x as f64, y as f64);
                let p = v.ground_from_camera.transform_point([xn * d, yn * d, d]);
                let col = ((p[0] - texture.origin_m[0]) / c).round();
                let row = ((texture.origin_m[1] - p[1]) / c).round();
                let inside = (0.0..texture.width as f64).contains(&col)
                    && (0.0..texture.height as f64).contains(&row);
                let ratio = v.real[i] / v.flat[i];
                (inside && ratio.is_finite())
                    .then(|| (row as usize * texture.width + col as usize, ratio))
            })
        })
        .collect();
    if hits.is_empty() {
        return None;
    }
    let widest = ladder.last().copied().unwrap_or(0.0) / c + BAND_CELLS.1;
    let margin = (3.0 * widest).ceil() as usize;
    let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
    for &(k, _) in &hits {
        let (r, col) = (k / texture.width, k % texture.width);
        (c0, c1, r0, r1) = (c0.min(col), c1.max(col), r0.min(r), r1.max(r));
    }
    let (col0, row0) = (c0.saturating_sub(margin), r0.saturating_sub(margin));
    let w = (c1 + margin + 1).min(texture.width) - col0;
    let h = (r1 + margin + 1).min(texture.height) - row0;
    let mut sum = vec![0.0f64; w * h];
    let mut count = vec![0u32; w * h];
    for &(k, ratio) in &hits {
        let j = (k / texture.width - row0) * w + (k % texture.width - col0);
        sum[j] += f64::from(ratio);
        count[j] += 1;
    }
    let seen = count.iter().filter(|&&k| k >= MIN_PIXELS).count();
    (seen >= 200).then(|| Ortho {
        col0,
        row0,
        w,
        h,
        value: sum
            .iter()
            .zip(&count)
            .map(|(s, &k)| {
                if k >= MIN_PIXELS {
                    (s / f64::from(k)) as f32
                } else {
                    0.0
                }
            })
            .collect(),
        weight: count
            .iter()
            .map(|&k| if k >= MIN_PIXELS { 1.0 } else { 0.0 })
            .collect(),
    })
}

/// Correlation sums of one view's real albedo `o` with `texture` at every ladder step, both
/// band-passed by normalised convolution over the cells the view sees; `None` without enough
/// cells.
fn view_sums(o: &Ortho, texture: &AlbedoGrid, fold: usize, ladder: &[f64]) -> Option<ViewSums> {
    let (w, h) = (o.w, o.h);
    let tex: Vec<f32> = (0..h)
        .flat_map(|r| {
            let start = (o.row0 + r) * texture.width + o.col0;
            texture.value[start..start + w].iter().copied()
        })
        .zip(&o.weight)
        .map(|(t, wt)| if t.is_finite() { t * wt } else { 0.0 })
        .collect();
    let real: Vec<f32> = o
        .value
        .iter()
        .zip(&o.weight)
        .map(|(v, wt)| v * wt)
        .collect();
    // Normalised convolution: the blur of the seen cells over the blur of the coverage.
    let norm = |img: &[f32], sigma: f64| -> Vec<f32> {
        let num = gaussian_blur(img, w, h, sigma);
        let den = gaussian_blur(&o.weight, w, h, sigma);
        num.iter()
            .zip(&den)
            .map(|(a, b)| if *b > 1e-6 { a / b } else { 0.0 })
            .collect()
    };
    let band = |img: &[f32], extra: f64| -> Vec<f32> {
        let fine = norm(img, (BAND_CELLS.0.powi(2) + extra.powi(2)).sqrt());
        let coarse = norm(img, (BAND_CELLS.1.powi(2) + extra.powi(2)).sqrt());
        fine.iter().zip(&coarse).map(|(a, b)| a - b).collect()
    };
    let coverage = gaussian_blur(&o.weight, w, h, BAND_CELLS.1);
    let keep: Vec<usize> = (0..w * h)
        .filter(|&i| o.weight[i] > 0.5 && coverage[i] >= MIN_COVERAGE)
        .collect();
    if keep.len() < 200 {
        return None;
    }
    let bt = band(&tex, 0.0);
    let var_texture: f64 = keep.iter().map(|&i| f64::from(bt[i]).powi(2)).sum();
    let (cov, var_real): (Vec<f64>, Vec<f64>) = ladder
        .par_iter()
        .map(|sigma_m| {
            let br = band(&real, sigma_m / texture.cell_m);
            keep.iter().fold((0.0, 0.0), |(c, a), &i| {
                let r = f64::from(br[i]);
                (c + r * f64::from(bt[i]), a + r * r)
            })
        })
        .unzip();
    Some(ViewSums {
        fold,
        cov,
        var_real,
        var_texture,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic white-noise albedo field on a fine ground grid.
    fn noise(w: usize, h: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        (0..w * h)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                0.3 + 0.1 * ((s >> 33) as f32 / (1u64 << 31) as f32 - 0.5)
            })
            .collect()
    }

    /// A camera 1 m above the ground looking straight down with fx 500 px: pixel (u, v) sees
    /// ground (2u, −2v) mm. The real albedo is white noise at the pixels; the texture has
    /// 6 mm cells (3 x 3 pixels each, centred on a pixel) holding the albedo blurred by
    /// `texture_sigma_m`.
    fn measure(texture_sigma_m: f64, seed: u64) -> f64 {
        let (w, h) = (360, 360);
        // The fields are made with a margin, so the blur sees no image border.
        let pad = 100;
        let (wp, hp) = (w + 2 * pad, h + 2 * pad);
        let field = noise(wp, hp, seed);
        let field_blurred = gaussian_blur(&field, wp, hp, texture_sigma_m / 0.002);
        let crop = |f: &[f32]| -> Vec<f32> {
            (0..w * h)
                .map(|i| f[(i / w + pad) * wp + i % w + pad])
                .collect()
        };
        let (albedo, blurred) = (crop(&field), crop(&field_blurred));
        let cells = w / 3;
        let texture = AlbedoGrid {
            origin_m: [0.0, 0.0],
            cell_m: 0.006,
            width: cells,
            height: cells,
            value: (0..cells * cells)
                .map(|k| blurred[(k / cells) * 3 * w + (k % cells) * 3])
                .collect(),
        };
        let real: Vec<f32> = albedo.iter().map(|v| v * 200.0).collect();
        // Sky along the top rows: outside the terrain.
        let mask: Vec<bool> = (0..w * h).map(|i| i / w >= 10).collect();
        let depth = vec![1.0f32; w * h];
        let camera = CameraModel::pinhole(w as u32, h as u32, 500.0, 500.0, 0.0, 0.0);
        let down = Pose::from_matrix(
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            [0.0, 0.0, 1.0],
        );
        blur_of(&real, &mask, &depth, &camera, &down, &texture)
    }

    /// The effective blur of one view of `texture` (a uniform shading of 200 DN).
    fn blur_of(
        real: &[f32],
        mask: &[bool],
        depth: &[f32],
        camera: &CameraModel,
        pose: &Pose,
        texture: &AlbedoGrid,
    ) -> f64 {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let flat = vec![200.0f32; w * h];
        let v = TextureView {
            real,
            flat: &flat,
            mask,
            depth,
            camera,
            ground_from_camera: pose,
            w,
            h,
            fold: 0,
        };
        let m = TextureMeasure::new(&[v], texture).expect("enough terrain");
        m.blur_m(&|_| true).expect("one view").0
    }

    #[test]
    fn the_effective_blur_is_the_texture_blur() {
        // Noise-free: the peak sits at the blur that made the texture (less the real side's
        // 6 mm cell average, σ 1.7 mm in quadrature).
        for (sigma, seed) in [(0.006, 1), (0.012, 2), (0.02, 3), (0.03, 5)] {
            let got = measure(sigma, seed);
            assert!((got - sigma).abs() < 0.0015, "{sigma} → {got}");
        }
        // A texture as sharp as the real albedo peaks at no blur.
        assert!(measure(0.0, 4) < 0.002);
    }

    /// A camera 0.9 m above flat ground looking 37° down at it (ground sample distance 2.5 mm
    /// across the view, 4 mm along it, both growing with depth), the real image sampling a
    /// 2 mm albedo field; the texture has 6 mm cells holding the field blurred by
    /// `texture_sigma_m`.
    fn measure_oblique(texture_sigma_m: f64, seed: u64) -> f64 {
        let n = 1000;
        let field = noise(n, n, seed);
        let blurred = gaussian_blur(&field, n, n, texture_sigma_m / 0.002);
        let fine = AlbedoGrid {
            origin_m: [0.0, 2.0],
            cell_m: 0.002,
            width: n,
            height: n,
            value: field,
        };
        let cells = n / 3;
        let texture = AlbedoGrid {
            origin_m: [0.0, 2.0],
            cell_m: 0.006,
            width: cells,
            height: cells,
            value: (0..cells * cells)
                .map(|k| blurred[(k / cells) * 3 * n + (k % cells) * 3])
                .collect(),
        };
        let (w, h) = (480, 360);
        let camera = CameraModel::pinhole(w as u32, h as u32, 600.0, 600.0, 239.5, 179.5);
        let view = crate::render::View::look_at(camera.clone(), [1.0, 0.0, 0.9], [1.0, 1.2, 0.0]);
        let pose = view.ground_from_camera;
        let (mut real, mut depth, mut mask) = (
            vec![0.0f32; w * h],
            vec![f32::NAN; w * h],
            vec![false; w * h],
        );
        for y in 0..h {
            for x in 0..w {
                let (xn, yn) = camera.unproject(x as f64, y as f64);
                let d = pose.rotate([xn, yn, 1.0]);
                if d[2] >= 0.0 {
                    continue;
                }
                let t = -0.9 / d[2];
                let (gx, gy) = (1.0 + t * d[0], t * d[1]);
                if !(0.05..1.95).contains(&gx) || !(0.05..1.95).contains(&gy) {
                    continue;
                }
                let i = y * w + x;
                real[i] = 200.0 * crate::render::shading::sample_albedo(&fine, gx, gy);
                depth[i] = t as f32;
                mask[i] = true;
            }
        }
        blur_of(&real, &mask, &depth, &camera, &pose, &texture)
    }

    #[test]
    fn an_oblique_view_reads_the_ground_blur() {
        // The same Gaussian on the ground whatever the depth and the foreshortening; the real
        // side's pixels (4 mm along the view at the near edge) and bilinear sampling blur it a
        // little, so the reading is a little below the truth.
        for (sigma, seed) in [(0.012, 6), (0.02, 7)] {
            let got = measure_oblique(sigma, seed);
            assert!((got - sigma).abs() < 0.002, "{sigma} → {got}");
        }
    }

    #[test]
    fn the_excess_is_zero_for_a_faithful_texture_and_adds_in_quadrature() {
        let own = own_blur_m(0.01);
        assert!((own - (0.0123f64.powi(2) + 0.0064f64.powi(2)).sqrt()).abs() < 1e-12);
        assert!(own_blur_m(0.03) > own);
        assert_eq!(excess_m(own * 0.9, 0.01), 0.0);
        let with = (own * own + (EXCESS_PER_SIGMA * 0.008).powi(2)).sqrt();
        assert!((excess_m(with, 0.01) - 0.008).abs() < 1e-12);
    }

    #[test]
    fn views_without_terrain_give_no_measure() {
        let (w, h) = (40, 30);
        let z = vec![0.0f32; w * h];
        let camera = CameraModel::pinhole(w as u32, h as u32, 500.0, 500.0, 0.0, 0.0);
        let pose = Pose::from_matrix(
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            [0.0, 0.0, 1.0],
        );
        let texture = AlbedoGrid {
            origin_m: [0.0, 0.0],
            cell_m: 0.01,
            width: 10,
            height: 10,
            value: vec![0.5; 100],
        };
        let v = TextureView {
            real: &z,
            flat: &z,
            mask: &vec![false; w * h],
            depth: &z,
            camera: &camera,
            ground_from_camera: &pose,
            w,
            h,
            fold: 0,
        };
        assert!(TextureMeasure::new(&[v], &texture).is_none());
        // Short buffers are refused, not indexed.
        let short = TextureView {
            real: &z[..10],
            ..v
        };
        assert!(TextureMeasure::new(&[short], &texture).is_none());
    }
}
