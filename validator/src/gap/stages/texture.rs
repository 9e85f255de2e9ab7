//! The texture stage: `texture-lowpass` from the texture's effective blur against the real
//! albedo gathered on the ground ([`crate::gap::texture`]); heightfield entries only.

use std::collections::BTreeMap;

use regolith_format::frames::Pose;

use crate::gap::context::{has, jackknife, named, upsert, Ctx};
use crate::gap::one_sample::Shading;
use crate::gap::views::{predict, Prediction};
use crate::gap::{texture, Named, TextureFigures};
use crate::render::{AlbedoGrid, Geometry, HeightGrid, Scene};
use crate::sensor::{Effect, SensorModel};

/// What [`texture`] reads of every view under one model: the render with a uniform albedo
/// (the shading the real image is divided by) and the real frame mean, both on radiance.
pub(crate) struct TextureInputs {
    pub(crate) flat: Vec<Prediction>,
    pub(crate) real: Vec<Vec<f32>>,
    pub(crate) flat_radiance: Vec<Vec<f32>>,
    pub(crate) poses: Vec<Pose>,
}

/// The uniform albedo of the texture measure's flat renders: the texture's mean.
pub(crate) fn flat_albedo(albedo: &AlbedoGrid) -> f32 {
    let mean =
        albedo.value.iter().map(|&v| f64::from(v)).sum::<f64>() / albedo.value.len().max(1) as f64;
    mean as f32
}

impl TextureInputs {
    /// The inputs of `model` on the entry's `grid` and `albedo`, its flat renders made here.
    pub(crate) fn new(
        ctx: &Ctx<'_>,
        grid: &HeightGrid,
        albedo: &AlbedoGrid,
        model: &SensorModel,
    ) -> Self {
        let mut uniform = albedo.clone();
        uniform.value.fill(flat_albedo(albedo));
        let flat_geometry = Geometry::Heightfield {
            grid: grid.clone(),
            albedo: uniform,
        };
        let flat_scene = Scene::new(&flat_geometry);
        let flat: Vec<Prediction> = ctx
            .views
            .iter()
            .map(|v| predict(&flat_scene, &ctx.light, v, model, 1))
            .collect();
        Self::with_flat(ctx, model, flat)
    }

    /// [`TextureInputs::new`], the flat renders taken from the first step's kept ones
    /// ([`Ctx::one_sample`]) while `model`'s rays and light are its: shaded from the traced
    /// rays under exactly the uniform albedo, where a render of the uniform grid interpolates
    /// it to within a rounding.
    pub(crate) fn kept_or_new(
        ctx: &Ctx<'_>,
        grid: &HeightGrid,
        albedo: &AlbedoGrid,
        model: &SensorModel,
    ) -> Self {
        let kept = ctx
            .one_sample(model, Shading::Flat)
            .filter(|_| ctx.one_sample_flat_albedo() == Some(flat_albedo(albedo)));
        match kept {
            Some(flat) => Self::with_flat(ctx, model, flat),
            None => Self::new(ctx, grid, albedo, model),
        }
    }

    /// The inputs of `model` given its `flat` renders (the views under [`flat_albedo`]).
    pub(crate) fn with_flat(ctx: &Ctx<'_>, model: &SensorModel, flat: Vec<Prediction>) -> Self {
        // Ratios are taken on radiance: the response curve and black level undone (a curve
        // left in bends the ratios and reads a faithful texture blurrier).
        let linear = |dn: &[f32]| crate::sensor::image::undo_response(&model.effects, dn);
        TextureInputs {
            real: ctx.views.iter().map(|v| linear(&v.mean())).collect(),
            flat_radiance: flat.iter().map(|p| linear(&p.dn)).collect(),
            poses: ctx.views.iter().map(|v| model.pose(&v.at)).collect(),
            flat,
        }
    }

    pub(crate) fn views(&self, ctx: &Ctx<'_>) -> Vec<texture::TextureView<'_>> {
        ctx.views
            .iter()
            .enumerate()
            .map(|(i, v)| texture::TextureView {
                real: &self.real[i],
                flat: &self.flat_radiance[i],
                mask: &self.flat[i].mask,
                depth: &self.flat[i].depth,
                camera: &self.flat[i].camera,
                ground_from_camera: &self.poses[i],
                w: v.width,
                h: v.height,
                fold: ctx.folds[i],
            })
            .collect()
    }
}

/// `texture-lowpass` from the texture's effective blur ([`texture`]); heightfield entries only.
/// Updates `model` and returns the figures.
pub(crate) fn texture_stage(
    ctx: &Ctx<'_>,
    model: &mut SensorModel,
    out: &mut Vec<Named>,
) -> Option<TextureFigures> {
    let Geometry::Heightfield { grid, albedo } = ctx.geometry else {
        return None;
    };
    let inputs = TextureInputs::kept_or_new(ctx, grid, albedo, model);
    let views = inputs.views(ctx);
    let m = texture::TextureMeasure::new(&views, albedo)?;
    let (blur, correlation) = m.blur_m(&|_| true)?;
    let cell = albedo.cell_m;
    let excess = texture::excess_m(blur, cell);
    let figures = TextureFigures {
        effective_blur_m: blur,
        own_blur_m: texture::own_blur_m(cell),
        excess_m: excess,
        correlation,
        cell_m: cell,
    };
    // Per capture the blur is rough (docs/gap-findings.md, "The texture's effective blur"), so
    // the pooled figure decides; the per-capture ones are shown.
    let per_fold: Vec<String> = m
        .folds()
        .iter()
        .filter_map(|&f| m.blur_m(&|g| g == f))
        .map(|(b, _)| format!("{:.1}", b * 1e3))
        .collect();
    if excess < texture::MIN_EXCESS_M || has(model, "texture-lowpass") {
        return Some(figures);
    }
    let folds = m.folds();
    let jack = jackknife(folds.len(), &|hold| {
        let f = folds[hold];
        vec![m
            .blur_m(&|g| g != f)
            .map_or(excess, |(b, _)| texture::excess_m(b, cell))]
    });
    let e = Effect::TextureLowpass { sigma_m: excess };
    upsert(model, e);
    // The captures' spread and the calibration's (texture::EXCESS_PER_SIGMA) in quadrature.
    let calibration = texture::EXCESS_SPREAD * excess;
    let spread = jack.map_or(0.0, |j| j[0]);
    let mut std_err = BTreeMap::new();
    std_err.insert("sigma_m".to_string(), spread.hypot(calibration));
    out.push(named(
        &e,
        std_err,
        1.0 - (figures.own_blur_m / blur).powi(2),
        "texture",
        format!(
            "the entry's texture matches the real albedo blurred by {:.1} mm (per capture {} mm; band-pass correlation {:.2}); a faithful texture of {:.3} m cells shows {:.1} mm",
            blur * 1e3,
            per_fold.join(", "),
            correlation,
            cell,
            figures.own_blur_m * 1e3
        ),
    ));
    Some(figures)
}
