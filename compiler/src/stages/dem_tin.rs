//! Stage `dem.tin`: the Delaunay triangulation (TIN) of the merged ground points in (x, y).
//!
//! Design decisions:
//! - Points that share exactly the same (x, y) are merged *before* triangulating into one vertex
//!   whose z (and albedo) is the **mean** of the group: a TIN can hold only one height per
//!   position, the mean is the least-squares height of the group, and merging ourselves (sorted
//!   by x, y, then input index) makes the result independent of spade's internal dedup order.
//! - The triangulation (`delaunay`) is spade's `bulk_load` (O(n log n)), run on vertical strips in
//!   parallel for big clouds. The TIN holds the Delaunay triangles whose longest horizontal edge
//!   is at most `max_edge_m` (the `dem.raster` hole limit; longer triangles span missing data and
//!   no raster uses them), which is what lets strips give exactly those triangles. Deterministic:
//!   the vertex/triangle lists are bit-identical run to run and for any thread count. Triangles
//!   index our vertex array, are counter-clockwise seen from +z, start at their lowest vertex
//!   index and are sorted (`canonical_order`: west to east, for cache-friendly passes).
//! - Non-finite coordinates are an error naming the first bad point, never a spade panic.

use rayon::prelude::*;
use serde::Serialize;

use super::delaunay::triangulate;
use super::merge_clean::MergedCloud;
use crate::stage::{Stage, StageCx, StageError};

/// A triangulated irregular network.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tin {
    /// Vertices (x, y unique), ground frame, metres.
    pub vertices: Vec<[f64; 3]>,
    /// Per-vertex linear albedo estimate (the texture value: `merge.clean`'s incidence-corrected
    /// albedo, or SfM vertex grey / 255), when the source had it.
    pub albedo: Option<Vec<f32>>,
    /// Counter-clockwise triangles (indices into `vertices`).
    pub triangles: Vec<[u32; 3]>,
    /// Input points merged into another one because they shared (x, y).
    pub duplicates_merged: usize,
    /// A bound every triangle's longest horizontal edge is known to respect (`dem.tin`'s limit,
    /// measured as `dem.raster` measures it), so a raster with a limit at least as long need not
    /// check each triangle again; `None`: unknown.
    pub max_edge_m: Option<f64>,
}

/// Statistics of a TIN.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TinStats {
    /// Number of vertices.
    pub points: usize,
    /// Number of triangles.
    pub triangles: usize,
    /// Input points merged as (x, y) duplicates.
    pub duplicates_merged: usize,
}

impl Tin {
    /// Point and triangle counts.
    pub fn stats(&self) -> TinStats {
        TinStats {
            points: self.vertices.len(),
            triangles: self.triangles.len(),
            duplicates_merged: self.duplicates_merged,
        }
    }
}

/// Triangulates `points` (x, y) carrying z and the optional per-point `albedo`, keeping the
/// triangles whose longest horizontal edge is at most `max_edge_m` (`f64::INFINITY`: all).
///
/// Errors (as text; the stage adds its name) on non-finite points, an albedo list of the wrong
/// length, more than `u32::MAX` vertices, or a spade insertion error.
pub fn build_tin(
    points: &[[f64; 3]],
    albedo: Option<&[f32]>,
    max_edge_m: f64,
) -> Result<Tin, String> {
    let recs = sorted_records(points, albedo)?;
    from_records(recs, albedo.is_some(), points.len(), max_edge_m)
}

/// [`build_tin`] of points it frees once they are sorted, so a survey's points and albedo are
/// not held beside the sorted records and the vertices (the stage's largest arrays; on an
/// 18 M-point survey 0.5 GB of its peak).
pub fn build_tin_owned(
    points: Vec<[f64; 3]>,
    albedo: Option<Vec<f32>>,
    max_edge_m: f64,
) -> Result<Tin, String> {
    let (n, has_albedo) = (points.len(), albedo.is_some());
    let recs = sorted_records(&points, albedo.as_deref())?;
    drop(points);
    drop(albedo);
    from_records(recs, has_albedo, n, max_edge_m)
}

/// A point as `build_tin` sorts it: by (x, y, index) records carrying z and albedo, not as
/// indices compared through the points, so the sort and the merge read memory in order
/// instead of jumping to a random point for every comparison and every value.
struct Rec {
    x: f64,
    y: f64,
    z: f64,
    albedo: f32,
    index: u32,
}

/// The checked points as records sorted by x, y, then input index.
fn sorted_records(points: &[[f64; 3]], albedo: Option<&[f32]>) -> Result<Vec<Rec>, String> {
    if let Some(i) = points.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(format!(
            "point {i} has non-finite coordinates, expected finite x, y, z"
        ));
    }
    if let Some(r) = albedo {
        if r.len() != points.len() {
            return Err(format!(
                "{} albedo values for {} points, expected one per point",
                r.len(),
                points.len()
            ));
        }
    }
    u32::try_from(points.len())
        .map_err(|_| format!("{} points, expected at most {}", points.len(), u32::MAX))?;
    let mut recs: Vec<Rec> = points
        .par_iter()
        .zip(0u32..u32::MAX)
        .map(|(p, index)| Rec {
            x: p[0],
            y: p[1],
            z: p[2],
            albedo: albedo
                .and_then(|r| r.get(index as usize))
                .copied()
                .unwrap_or(0.0),
            index,
        })
        .collect();
    recs.par_sort_unstable_by(|a, b| {
        a.x.total_cmp(&b.x)
            .then(a.y.total_cmp(&b.y))
            .then(a.index.cmp(&b.index))
    });
    Ok(recs)
}

/// The TIN of `n_points` points given as their sorted records: (x, y) duplicates merged into
/// their mean, then triangulated. The records are freed once merged: they are the largest
/// array of the stage (40 bytes a point, 0.75 GB on an 18 M-point survey) and the
/// triangulation needs only the vertices.
fn from_records(
    recs: Vec<Rec>,
    has_albedo: bool,
    n_points: usize,
    max_edge_m: f64,
) -> Result<Tin, String> {
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut refl: Vec<f32> = Vec::new();
    for group in recs.chunk_by(|a, b| a.x == b.x && a.y == b.y) {
        let Some(first) = group.first() else { continue };
        let n = group.len() as f64;
        let z = group.iter().map(|r| r.z).sum::<f64>() / n;
        vertices.push([first.x, first.y, z]);
        if has_albedo {
            let m = group.iter().map(|r| f64::from(r.albedo)).sum::<f64>() / n;
            refl.push(m as f32);
        }
    }
    drop(recs);
    let duplicates_merged = n_points - vertices.len();
    u32::try_from(vertices.len())
        .map_err(|_| format!("{} vertices, expected at most {}", vertices.len(), u32::MAX))?;
    let mut triangles = triangulate(&vertices, max_edge_m)?;
    canonical_order(&mut triangles);
    Ok(Tin {
        vertices,
        albedo: has_albedo.then_some(refl),
        triangles,
        duplicates_merged,
        max_edge_m: max_edge_m.is_finite().then_some(max_edge_m),
    })
}

/// Puts every triangle's lowest vertex index first (a rotation, so still counter-clockwise) and
/// sorts the triangles: one order whatever way the triangulation was built, and, the vertices
/// being x-sorted, a west-to-east one, so that a pass over the triangles reads the vertex array
/// almost sequentially (`dem.raster`).
fn canonical_order(triangles: &mut [[u32; 3]]) {
    triangles.par_iter_mut().for_each(|t| {
        let lowest = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
        t.rotate_left(lowest);
    });
    triangles.par_sort_unstable();
}

/// Stage `dem.tin` (the duplicate rule is fixed, see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DemTin {
    /// Longest horizontal triangle edge kept, metres (`f64::INFINITY`: the whole triangulation).
    pub max_edge_m: f64,
}

impl Stage for DemTin {
    const NAME: &'static str = "dem.tin";
    const VERSION: u32 = 4;
    const DESCRIPTION: &'static str =
        "Delaunay TIN of the merged ground points in (x, y); (x, y) duplicates keep the mean z";
    type Input = MergedCloud;
    type Output = Tin;

    fn params(&self) -> serde_json::Value {
        serde_json::json!({ "duplicates": "mean", "max_edge_m": self.max_edge_m })
    }

    fn run(&self, _cx: &StageCx, input: &MergedCloud) -> Result<Tin, StageError> {
        build_tin(&input.points, input.albedo.as_deref(), self.max_edge_m)
            .map_err(|e| StageError::new(Self::NAME, e))
    }
}

impl DemTin {
    /// [`Stage::run`] taking the cloud's points and albedo out of `input` and freeing them as
    /// soon as they are sorted ([`build_tin_owned`]); the same TIN.
    pub fn run_owned(&self, input: &mut MergedCloud) -> Result<Tin, StageError> {
        build_tin_owned(
            std::mem::take(&mut input.points),
            input.albedo.take(),
            self.max_edge_m,
        )
        .map_err(|e| StageError::new(Self::NAME, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_with_duplicate_and_centre() {
        let pts = [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
            [0.5, 0.5, 2.0],
            [0.5, 0.5, 4.0],
        ];
        let tin = build_tin(&pts, None, f64::INFINITY).unwrap();
        assert_eq!(tin.vertices.len(), 5);
        assert_eq!(tin.duplicates_merged, 1);
        assert_eq!(tin.triangles.len(), 4);
        assert!(tin.vertices.contains(&[0.5, 0.5, 3.0]));
        assert!(build_tin(&[[f64::NAN, 0.0, 0.0]], None, 1.0).is_err());
        let albedo: Vec<f32> = (0..pts.len()).map(|i| i as f32 / 10.0).collect();
        assert_eq!(
            build_tin_owned(pts.to_vec(), Some(albedo.clone()), f64::INFINITY).unwrap(),
            build_tin(&pts, Some(&albedo), f64::INFINITY).unwrap()
        );
    }
}
