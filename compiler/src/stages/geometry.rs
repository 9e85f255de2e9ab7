//! Geometry shared by the registration, merge and DEM stages: rigid/similarity fits, plane fits,
//! kd-tree neighbourhoods, 4x4 matrix helpers and robust statistics.
//!
//! Design decisions:
//! - Transforms are fitted with Umeyama's closed form (the SVD solution of Horn's absolute
//!   orientation problem, with the reflection guard), so tie-point registration and SfM alignment
//!   share one audited implementation; `with_scale = false` gives the rigid fit.
//! - Neighbourhoods use kiddo's `ImmutableKdTree` (balanced, no panic on coincident points,
//!   unlike the mutable tree whose buckets overflow when many points share one coordinate).
//! - Every reduction is sequential over a `Vec` collected from an indexed parallel map, so sums do
//!   not depend on the rayon thread count (house style practice 11).

use std::num::NonZero;

use kiddo::SquaredEuclidean;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::ingest::types::Matrix4;

/// The kd-tree used by the stages (items are indices into the slice it was built from).
pub type Tree3 = kiddo::ImmutableKdTree<f64, 3>;

/// `p' = scale * rotation * p + translation`.
#[derive(Debug, Clone, PartialEq)]
pub struct Similarity {
    /// Isotropic scale (1 for a rigid transform).
    pub scale: f64,
    /// Proper rotation (det = +1).
    pub rotation: Matrix3<f64>,
    /// Translation, metres.
    pub translation: Vector3<f64>,
}

impl Similarity {
    /// The transform as a row-major, column-vector [`Matrix4`].
    pub fn to_matrix4(&self) -> Matrix4 {
        let m = self.rotation * self.scale;
        let t = self.translation;
        [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)], t.x],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)], t.y],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)], t.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }
}

/// The upper-left 3x3 block of a [`Matrix4`].
pub fn linear_part(m: &Matrix4) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| m[r][c])
}

/// The translation column of a [`Matrix4`].
pub fn translation_part(m: &Matrix4) -> Vector3<f64> {
    Vector3::new(m[0][3], m[1][3], m[2][3])
}

/// Builds a [`Matrix4`] from a 3x3 linear part and a translation.
pub fn compose(linear: &Matrix3<f64>, t: &Vector3<f64>) -> Matrix4 {
    Similarity {
        scale: 1.0,
        rotation: *linear,
        translation: *t,
    }
    .to_matrix4()
}

/// `a * b` for [`Matrix4`]s.
pub fn mat4_mul(a: &Matrix4, b: &Matrix4) -> Matrix4 {
    let mut out = [[0.0; 4]; 4];
    for (r, row) in out.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = (0..4).map(|k| a[r][k] * b[k][c]).sum();
        }
    }
    out
}

/// Inverse of a rigid [`Matrix4`] (rotation transposed).
pub fn invert_rigid(m: &Matrix4) -> Matrix4 {
    let rt = linear_part(m).transpose();
    compose(&rt, &(-(rt * translation_part(m))))
}

/// Translation distance (m) and rotation angle (degrees) between two rigid transforms.
pub fn pose_difference(a: &Matrix4, b: &Matrix4) -> (f64, f64) {
    let dt = (translation_part(a) - translation_part(b)).norm();
    let r = linear_part(a).transpose() * linear_part(b);
    let cos = ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    (dt, cos.acos().to_degrees())
}

/// Umeyama's least-squares fit of `dst ≈ s·R·src + t` (`s = 1` unless `with_scale`).
///
/// Returns `None` for fewer than 3 pairs, mismatched lengths, non-finite input or a degenerate
/// (collinear or coincident) configuration, where the rotation is not determined.
pub fn fit_transform(src: &[[f64; 3]], dst: &[[f64; 3]], with_scale: bool) -> Option<Similarity> {
    if src.len() != dst.len() || src.len() < 3 {
        return None;
    }
    let n = src.len() as f64;
    let vs: Vec<Vector3<f64>> = src.iter().map(|p| Vector3::from(*p)).collect();
    let vd: Vec<Vector3<f64>> = dst.iter().map(|p| Vector3::from(*p)).collect();
    let mu_s = vs.iter().sum::<Vector3<f64>>() / n;
    let mu_d = vd.iter().sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    let mut var_s = 0.0;
    for (s, d) in vs.iter().zip(&vd) {
        cov += (d - mu_d) * (s - mu_s).transpose();
        var_s += (s - mu_s).norm_squared();
    }
    cov /= n;
    var_s /= n;
    if !cov.iter().all(|v| v.is_finite()) || var_s <= 0.0 {
        return None;
    }
    let svd = cov.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let sv = svd.singular_values; // descending
    if sv[1] <= 1e-12 * sv[0].max(f64::MIN_POSITIVE) {
        return None;
    }
    let mut d = Vector3::new(1.0, 1.0, 1.0);
    if u.determinant() * v_t.determinant() < 0.0 {
        d.z = -1.0;
    }
    let rotation = u * Matrix3::from_diagonal(&d) * v_t;
    let scale = if with_scale {
        sv.component_mul(&d).sum() / var_s
    } else {
        1.0
    };
    let translation = mu_d - rotation * mu_s * scale;
    Some(Similarity {
        scale,
        rotation,
        translation,
    })
}

/// A plane fitted to a neighbourhood.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalPlane {
    /// Centroid of the neighbourhood.
    pub centroid: Vector3<f64>,
    /// Unit normal (sign arbitrary).
    pub normal: Vector3<f64>,
    /// Surface variation λ_min / (λ0 + λ1 + λ2): 0 for a perfect plane, 1/3 for isotropic noise.
    pub variation: f64,
}

/// Least-squares plane through `points` (smallest eigenvector of the covariance).
pub fn fit_plane(points: &[Vector3<f64>]) -> Option<LocalPlane> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let centroid = points.iter().sum::<Vector3<f64>>() / n;
    let cov = points.iter().fold(Matrix3::zeros(), |acc, p| {
        acc + (p - centroid) * (p - centroid).transpose()
    }) / n;
    let eig = SymmetricEigen::new(cov);
    let (imin, lmin) = eig.eigenvalues.argmin();
    let total = eig.eigenvalues.sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let normal = eig.eigenvectors.column(imin).into_owned();
    Some(LocalPlane {
        centroid,
        normal,
        variation: lmin.max(0.0) / total,
    })
}

/// Builds a kd-tree over `points` (`None` when empty).
pub fn build_tree(points: &[[f64; 3]]) -> Option<Tree3> {
    if points.is_empty() {
        return None;
    }
    Some(Tree3::new_from_slice(points))
}

/// The `k` nearest neighbours of `query` as (index, distance in metres), nearest first.
pub fn knn(tree: &Tree3, query: &[f64; 3], k: usize) -> Vec<(usize, f64)> {
    let Some(k) = NonZero::new(k) else {
        return Vec::new();
    };
    tree.nearest_n::<SquaredEuclidean>(query, k)
        .into_iter()
        .filter_map(|nn| {
            usize::try_from(nn.item)
                .ok()
                .map(|i| (i, nn.distance.sqrt()))
        })
        .collect()
}

/// Plane through the `k` neighbours of `query` in `points` (indexed by `tree`), together with
/// the distance to the nearest neighbour.
pub fn local_plane(
    tree: &Tree3,
    points: &[[f64; 3]],
    query: &[f64; 3],
    k: usize,
) -> Option<(LocalPlane, f64)> {
    let nn = knn(tree, query, k);
    let nearest = nn.first()?.1;
    let nb: Vec<Vector3<f64>> = nn
        .iter()
        .filter_map(|(i, _)| points.get(*i))
        .map(|p| Vector3::from(*p))
        .collect();
    fit_plane(&nb).map(|p| (p, nearest))
}

/// Median of `values` (reorders them); `None` when empty.
pub fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// Mean and population standard deviation (sequential sums: deterministic).
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    (mean, var.sqrt())
}

/// Root mean square; 0 for an empty slice.
pub fn rms(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

/// True when every coordinate is finite.
pub fn all_finite(points: &[[f64; 3]]) -> bool {
    points.iter().all(|p| p.iter().all(|v| v.is_finite()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn umeyama_recovers_a_similarity() {
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1).into_inner();
        let t = Vector3::new(1.0, -2.0, 0.5);
        let src = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.2],
            [0.0, 2.0, 0.0],
            [0.5, 0.5, 1.0],
        ];
        let dst: Vec<[f64; 3]> = src
            .iter()
            .map(|p| (r * Vector3::from(*p) * 2.5 + t).into())
            .collect();
        let s = fit_transform(&src, &dst, true).unwrap();
        assert!((s.scale - 2.5).abs() < 1e-12);
        assert!((s.rotation - r).norm() < 1e-12);
        assert!((s.translation - t).norm() < 1e-12);
        assert!(fit_transform(&src[..2], &dst[..2], false).is_none());
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!(fit_transform(&line, &line, false).is_none());
    }

    #[test]
    fn rigid_inverse_and_difference() {
        let m = compose(
            &nalgebra::Rotation3::from_euler_angles(0.1, 0.2, 0.3).into_inner(),
            &Vector3::new(1.0, 2.0, 3.0),
        );
        let id = mat4_mul(&m, &invert_rigid(&m));
        let (dt, da) = pose_difference(&id, &crate::ingest::types::IDENTITY4);
        assert!(dt < 1e-12 && da < 1e-6);
    }
}
