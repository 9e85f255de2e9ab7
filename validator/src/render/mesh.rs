//! Ray/triangle-mesh intersection through a bounding-volume hierarchy.
//!
//! Design decisions:
//! * The BVH is built by recursive median splits of triangle centroids along the longest axis
//!   (`select_nth_unstable_by` with a total order, so the tree is a pure function of the
//!   input), down to leaves of at most `LEAF` triangles. Median splits are not SAH-optimal,
//!   but they build ~1M-triangle SfM meshes in well under a second and trace fast enough for
//!   re-rendering; the tree depth is bounded by `log2(n)`.
//! * Triangles are stored in BVH order with their vertices relative to the mesh origin in
//!   `f64` and intersected with Möller–Trumbore. What the intersection reads (72 bytes a
//!   triangle) is kept apart from what only the nearest hit's shading reads, and both are put
//!   in BVH order in place: an estec 5 mm mesh has six million triangles, and a reordered copy
//!   of them was most of the 1.1 GB by which a whole-release validation's peak exceeded 2.5 GB.
//! * Shading uses **per-face normals** (flat shading): SfM meshes often have inconsistent
//!   vertex normals and winding, so the normal is recomputed from the face and turned toward
//!   the incoming ray. Albedo is interpolated barycentrically from the vertices, or, for a
//!   triangle with texture coordinates, sampled from the texture ([`sample_texture`]) at the
//!   barycentrically interpolated coordinates. A ray caster interpolates at the true 3-D hit,
//!   so this is the perspective-correct coordinate (a rasteriser needs the `1/w` division for
//!   the same result).
//! * Invalid input is skipped, not fatal: triangles with an out-of-range index, a non-finite
//!   vertex or zero area are left out of the tree.

use rayon::prelude::*;

use super::{Hit, MeshTexture, TriMeshF32};

/// Maximum number of triangles in a leaf.
const LEAF: usize = 4;
/// The reciprocal of a zero ray component in the slab test: finite, and past any
/// `1 / component` a ray meeting the scene can have.
const INV_ZERO: f64 = 1e300;
/// Traversal stack size (the median-split tree depth is at most ~log2(n) + 1).
const STACK: usize = 96;

/// A triangle as the intersection test reads it.
#[derive(Clone, Copy)]
struct Tri {
    v0: [f64; 3],
    e1: [f64; 3],
    e2: [f64; 3],
}

/// What shading a triangle's hit reads.
#[derive(Clone, Copy)]
struct TriShade {
    albedo: [f32; 3],
    /// Texture coordinates of the three vertices (as the mesh stores them), when the mesh has a
    /// texture and all three are finite.
    uv: Option<[[f32; 2]; 3]>,
    /// Ground size of one texel on this triangle, metres (`sqrt(area / texel area)`; 0 when
    /// the triangle has no texture coordinates or a degenerate mapping).
    texel_m: f64,
    normal: [f64; 3],
}

/// The texture image a tracer samples (the coordinates live in the triangles).
struct Image {
    width: usize,
    height: usize,
    value: Vec<f32>,
    mips: super::shading::MipChain,
}

/// A BVH node: its box in `f32`, rounded outwards (a ray that meets the exact box meets this
/// one), so two siblings fill one cache line ([`Pair`]).
#[derive(Clone, Copy)]
#[repr(C)]
struct Node {
    lo: [f32; 3],
    /// Leaf: first triangle; inner: index of the [`Pair`] holding its two children.
    start: u32,
    hi: [f32; 3],
    /// Number of triangles in a leaf, 0 for an inner node.
    count: u32,
}

impl Node {
    const EMPTY: Node = Node {
        lo: [f32::INFINITY; 3],
        start: 0,
        hi: [f32::NEG_INFINITY; 3],
        count: 0,
    };

    /// The node of the box `[lo, hi]` (rounded outwards to `f32`).
    fn new(lo: [f64; 3], hi: [f64; 3], start: u32, count: u32) -> Node {
        let down = |v: f64| {
            let f = v as f32;
            if f64::from(f) > v {
                f.next_down()
            } else {
                f
            }
        };
        let up = |v: f64| {
            let f = v as f32;
            if f64::from(f) < v {
                f.next_up()
            } else {
                f
            }
        };
        Node {
            lo: lo.map(down),
            start,
            hi: hi.map(up),
            count,
        }
    }
}

/// Two sibling nodes, aligned to a cache line: a traversal step reads both children's boxes,
/// and on a six-million-triangle mesh the nodes (192 MB) are far from cache, so one line per
/// step instead of two (or three with 64-byte `f64` nodes) is most of the walk's time.
/// `pairs[0]` holds the root (and an empty slot).
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Pair([Node; 2]);

/// Traces rays against a [`TriMeshF32`]; build once, share across threads.
pub struct MeshTracer {
    origin: [f64; 3],
    tris: Vec<Tri>,
    /// Per triangle of `tris`, same order.
    shade: Vec<TriShade>,
    pairs: Vec<Pair>,
    extent: f64,
    texture: Option<Image>,
}

impl MeshTracer {
    /// Builds the BVH of `mesh`.
    pub fn new(mesh: &TriMeshF32) -> MeshTracer {
        let vert = |i: u32| -> Option<[f64; 3]> {
            let p = mesh.positions.get(i as usize)?;
            let p = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
            p.iter().all(|c| c.is_finite()).then_some(p)
        };
        let albedo = |i: u32| mesh.albedo.get(i as usize).copied().unwrap_or(0.0);
        let uv = |i: u32| -> Option<[f32; 2]> {
            let t = *mesh.texture.as_ref()?.uvs.get(i as usize)?;
            t.iter().all(|c| c.is_finite()).then_some(t)
        };
        let prepared = mesh.triangles.par_iter().filter_map(|t| {
            let (Some(a), Some(b), Some(c)) = (vert(t[0]), vert(t[1]), vert(t[2])) else {
                return None;
            };
            let (e1, e2) = (sub(b, a), sub(c, a));
            let n = cross(e1, e2);
            let len = dot(n, n).sqrt();
            if len <= 0.0 || !len.is_finite() {
                return None;
            }
            let normal = [n[0] / len, n[1] / len, n[2] / len];
            let uv = match (uv(t[0]), uv(t[1]), uv(t[2])) {
                (Some(p), Some(q), Some(r)) => Some([p, q, r]),
                _ => None,
            };
            // Texel area of the triangle: its uv area times the image's texel count.
            let texels = uv.zip(mesh.texture.as_ref()).map_or(0.0, |(uv, tex)| {
                let uv = uv_f64(uv);
                let (du1, dv1) = (uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]);
                let (du2, dv2) = (uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]);
                0.5 * (du1 * dv2 - du2 * dv1).abs() * (tex.width * tex.height) as f64
            });
            let shade = TriShade {
                albedo: [albedo(t[0]), albedo(t[1]), albedo(t[2])],
                uv,
                texel_m: if texels > 0.0 {
                    (0.5 * len / texels).sqrt()
                } else {
                    0.0
                },
                normal,
            };
            Some((Tri { v0: a, e1, e2 }, shade))
        });
        let (tris, shade): (Vec<Tri>, Vec<TriShade>) = prepared.unzip();
        let mut tracer = MeshTracer {
            origin: mesh.origin_m,
            tris: Vec::new(),
            shade: Vec::new(),
            pairs: Vec::new(),
            extent: 1.0,
            texture: mesh.texture.as_ref().map(|t| Image {
                width: t.width,
                height: t.height,
                value: t.value.clone(),
                mips: super::shading::MipChain::new(t.width, t.height, &t.value),
            }),
        };
        tracer.build(tris, shade);
        tracer
    }

    fn build(&mut self, mut tris: Vec<Tri>, mut shade: Vec<TriShade>) {
        let centroid =
            |t: &Tri| -> [f64; 3] { std::array::from_fn(|k| t.v0[k] + (t.e1[k] + t.e2[k]) / 3.0) };
        let mut order: Vec<(usize, [f64; 3])> = tris
            .par_iter()
            .enumerate()
            .map(|(i, t)| (i, centroid(t)))
            .collect();
        if order.is_empty() {
            return;
        }
        self.pairs = subtree(&tris, &mut order, 0);
        if let Some(root) = self.root() {
            let d: [f64; 3] =
                std::array::from_fn(|k| f64::from(root.hi[k]) - f64::from(root.lo[k]));
            self.extent = dot(d, d).sqrt().max(1e-9);
        }
        let from: Vec<usize> = order.into_iter().map(|(i, _)| i).collect();
        permute(&mut tris, &from);
        permute(&mut shade, &from);
        self.tris = tris;
        self.shade = shade;
    }

    /// Diagonal of the mesh's bounding box in metres (1 for an empty mesh).
    pub fn extent(&self) -> f64 {
        self.extent
    }

    /// The nearest intersection with `0 <= t <= t_max`, if any.
    pub fn trace(&self, origin: [f64; 3], dir: [f64; 3], t_max: f64) -> Option<Hit> {
        self.trace_albedo(origin, dir, t_max, 0.0).map(|h| h.0)
    }

    /// Whether anything is hit with `0 <= t <= t_max`.
    pub fn occluded(&self, origin: [f64; 3], dir: [f64; 3], t_max: f64) -> bool {
        self.walk(sub(origin, self.origin), dir, t_max, true)
            .is_some()
    }

    /// The nearest intersection and the albedo there: the texture sample at the interpolated
    /// texture coordinates for a textured triangle (filtered over the footprint of a ray sample
    /// `spread` wide in normalised image coordinates, see [`super::shading::MipChain`]), else the
    /// interpolated vertex albedo.
    pub(crate) fn trace_albedo(
        &self,
        origin: [f64; 3],
        dir: [f64; 3],
        t_max: f64,
        spread: f64,
    ) -> Option<(Hit, f32)> {
        let (t, ti, bu, bv) = self.walk(sub(origin, self.origin), dir, t_max, false)?;
        let tri = self.shade.get(ti)?;
        let point = [
            origin[0] + t * dir[0],
            origin[1] + t * dir[1],
            origin[2] + t * dir[2],
        ];
        let n = if dot(tri.normal, dir) > 0.0 {
            tri.normal.map(|c| -c)
        } else {
            tri.normal
        };
        let albedo = match (tri.uv, &self.texture) {
            (Some(uv), Some(img)) => {
                let uv = uv_f64(uv);
                let w0 = 1.0 - bu - bv;
                let (u, v) = (
                    w0 * uv[0][0] + bu * uv[1][0] + bv * uv[2][0],
                    w0 * uv[0][1] + bu * uv[1][1] + bv * uv[2][1],
                );
                let texels = if tri.texel_m > 0.0 {
                    super::shading::footprint_m(t, dir, tri.normal, spread) / tri.texel_m
                } else {
                    0.0
                };
                img.mips.sample(
                    img.width,
                    img.height,
                    &img.value,
                    u * img.width as f64 - 0.5,
                    v * img.height as f64 - 0.5,
                    texels,
                )
            }
            _ => {
                let a = tri.albedo;
                (1.0 - bu - bv) as f32 * a[0] + bu as f32 * a[1] + bv as f32 * a[2]
            }
        };
        Some((
            Hit {
                t,
                point,
                normal: n,
            },
            albedo,
        ))
    }

    /// The root node, if the tree has one.
    fn root(&self) -> Option<&Node> {
        self.pairs.first().map(|p| &p.0[0])
    }

    /// Returns `(t, triangle, u, v)` of the nearest (or with `any` the first found) hit.
    fn walk(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        t_max: f64,
        any: bool,
    ) -> Option<(f64, usize, f64, f64)> {
        // Finite reciprocals (a ray parallel to an axis gets ±1e300), so no slab product is
        // `0 · ∞ = NaN` and the slab test needs plain comparisons, not NaN-aware `min`/`max`.
        let inv = d.map(|v| {
            if v == 0.0 {
                INV_ZERO
            } else {
                (1.0 / v).clamp(-INV_ZERO, INV_ZERO)
            }
        });
        let span = |n: &Node, t1: f64| -> Option<f64> {
            let (mut lo, mut hi) = (0.0f64, t1);
            for k in 0..3 {
                let ta = (f64::from(n.lo[k]) - o[k]) * inv[k];
                let tb = (f64::from(n.hi[k]) - o[k]) * inv[k];
                let (near, far) = if ta < tb { (ta, tb) } else { (tb, ta) };
                lo = if near > lo { near } else { lo };
                hi = if far < hi { far } else { hi };
            }
            (lo <= hi).then_some(lo)
        };
        let root = self.root()?;
        let mut stack = [(root, 0.0f64); STACK];
        stack[0] = (root, span(root, t_max)?);
        let mut sp = 1;
        let mut best: Option<(f64, usize, f64, f64)> = None;
        let mut t_best = t_max;
        while sp > 0 {
            sp -= 1;
            let (node, t_enter) = stack[sp];
            if t_enter > t_best {
                continue;
            }
            if node.count > 0 {
                let first = node.start as usize;
                for ti in first..first + node.count as usize {
                    let Some(tri) = self.tris.get(ti) else {
                        continue;
                    };
                    if let Some((t, u, v)) = intersect(tri, o, d, t_best) {
                        t_best = t;
                        best = Some((t, ti, u, v));
                        if any {
                            return best;
                        }
                    }
                }
                continue;
            }
            let Some(Pair([l, r])) = self.pairs.get(node.start as usize) else {
                continue;
            };
            let push_order = match (
                span(l, t_best).map(|t| (l, t)),
                span(r, t_best).map(|t| (r, t)),
            ) {
                (Some(a), Some(b)) if a.1 <= b.1 => [Some(b), Some(a)],
                (Some(a), Some(b)) => [Some(a), Some(b)],
                (a, b) => [a.or(b), None],
            };
            // The farther child is pushed first so the nearer one is popped first.
            for p in push_order.into_iter().flatten() {
                debug_assert!(sp < STACK);
                if let Some(slot) = stack.get_mut(sp) {
                    *slot = p;
                    sp += 1;
                }
            }
        }
        best
    }
}

/// Triangles from which [`subtree`] builds the two halves of a node in parallel; below it a
/// subtree is built in one task ([`subtree_serial`]).
const PARALLEL_MIN: usize = 1 << 16;

/// The box of the triangles `order` lists (`(triangle, centroid)`) and, unless they fit in a
/// leaf, the position at which `order` is now split at its median along the centroids'
/// longest axis (ties by triangle index, so the tree is a pure function of the input).
fn split(tris: &[Tri], order: &mut [(usize, [f64; 3])]) -> ([f64; 3], [f64; 3], Option<usize>) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let (mut clo, mut chi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for (idx, c) in order.iter() {
        if let Some(t) = tris.get(*idx) {
            for p in [t.v0, add(t.v0, t.e1), add(t.v0, t.e2)] {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        for k in 0..3 {
            clo[k] = clo[k].min(c[k]);
            chi[k] = chi[k].max(c[k]);
        }
    }
    if order.len() <= LEAF {
        return (lo, hi, None);
    }
    let ext = [chi[0] - clo[0], chi[1] - clo[1], chi[2] - clo[2]];
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |a, b| {
        a.1[axis].total_cmp(&b.1[axis]).then(a.0.cmp(&b.0))
    });
    (lo, hi, Some(mid))
}

/// The BVH over the triangles `order` lists, whose first entry is at position `first` of the
/// whole order (leaves name triangles by that position): pairs whose `[0]` holds the root
/// (and an empty slot), children indices local to the returned list. Big subtrees build their
/// halves in parallel and splice them: the same tree as one task builds, laid out otherwise,
/// and a ray's walk depends on the tree only.
fn subtree(tris: &[Tri], order: &mut [(usize, [f64; 3])], first: usize) -> Vec<Pair> {
    if order.len() < PARALLEL_MIN {
        return subtree_serial(tris, order, first);
    }
    let (lo, hi, Some(mid)) = split(tris, order) else {
        return subtree_serial(tris, order, first);
    };
    let (left, right) = order.split_at_mut(mid);
    let (l, r) = rayon::join(
        || subtree(tris, left, first),
        || subtree(tris, right, first + mid),
    );
    // [root, children, l's pairs but its root holder, r's likewise]: l's index i ≥ 1 moves to
    // i + 1, r's to i + l.len().
    let moved = |n: Node, by: usize| {
        if n.count == 0 {
            Node {
                start: n.start + by as u32,
                ..n
            }
        } else {
            n
        }
    };
    let (lr, rr) = (l[0].0[0], r[0].0[0]);
    let mut pairs = Vec::with_capacity(l.len() + r.len());
    pairs.push(Pair([Node::new(lo, hi, 1, 0), Node::EMPTY]));
    pairs.push(Pair([moved(lr, 1), moved(rr, l.len())]));
    pairs.extend(l.iter().skip(1).map(|p| Pair(p.0.map(|n| moved(n, 1)))));
    pairs.extend(
        r.iter()
            .skip(1)
            .map(|p| Pair(p.0.map(|n| moved(n, l.len())))),
    );
    pairs
}

/// [`subtree`] in one task, node by node from a work list.
fn subtree_serial(tris: &[Tri], order: &mut [(usize, [f64; 3])], first: usize) -> Vec<Pair> {
    let mut pairs = vec![Pair([Node::EMPTY; 2])];
    // (pair, slot, first, end) of the nodes still to fill.
    let mut work = vec![(0usize, 0usize, 0usize, order.len())];
    while let Some((pair, slot, s, e)) = work.pop() {
        let Some(part) = order.get_mut(s..e) else {
            continue;
        };
        let (lo, hi, split_at) = split(tris, part);
        let (start, count) = match split_at {
            None => (first + s, e - s),
            Some(mid) => {
                let children = pairs.len();
                pairs.push(Pair([Node::EMPTY; 2]));
                work.push((children, 0, s, s + mid));
                work.push((children, 1, s + mid, e));
                (children, 0)
            }
        };
        if let Some(n) = pairs.get_mut(pair).and_then(|p| p.0.get_mut(slot)) {
            *n = Node::new(lo, hi, start as u32, count as u32);
        }
    }
    pairs
}

/// The texture's albedo at texture coordinates `(u, v)` with the sampler of [`MeshTexture`]:
/// `(0, 0)` is the image's top-left corner, texel centres at `((i + 0.5) / width, (j + 0.5) /
/// height)`, bilinear between texel centres and clamped to the edge texels. The arithmetic is
/// that of [`super::shading::sample_albedo`], so a mesh whose vertex coordinates sit on texel
/// centres samples what the heightfield render of the same texture samples. An empty texture
/// gives 0, non-finite coordinates or values count as 0.
pub fn sample_texture(texture: &MeshTexture, u: f64, v: f64) -> f32 {
    sample_image(texture.width, texture.height, &texture.value, u, v)
}

fn sample_image(width: usize, height: usize, value: &[f32], u: f64, v: f64) -> f32 {
    super::shading::bilinear(
        width,
        height,
        value,
        u * width as f64 - 0.5,
        v * height as f64 - 0.5,
    )
}

/// Möller–Trumbore; returns `(t, u, v)` with `0 <= t <= t_max`.
fn intersect(tri: &Tri, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<(f64, f64, f64)> {
    let p = cross(d, tri.e2);
    let det = dot(tri.e1, p);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(o, tri.v0);
    let u = dot(s, p) * inv;
    if !(-1e-12..=1.0 + 1e-12).contains(&u) {
        return None;
    }
    let q = cross(s, tri.e1);
    let v = dot(d, q) * inv;
    if v < -1e-12 || u + v > 1.0 + 1e-12 {
        return None;
    }
    let t = dot(tri.e2, q) * inv;
    (t >= 0.0 && t <= t_max).then_some((t, u, v))
}

/// Texture coordinates in the `f64` the arithmetic uses (exact).
fn uv_f64(uv: [[f32; 2]; 3]) -> [[f64; 2]; 3] {
    uv.map(|p| p.map(f64::from))
}

/// Reorders `items` in place so that the new `items[k]` is the old `items[from[k]]` (`from` a
/// permutation of the indices), following each cycle once.
fn permute<T>(items: &mut [T], from: &[usize]) {
    let mut placed = vec![false; items.len()];
    for start in 0..items.len().min(from.len()) {
        let mut k = start;
        while !placed.get(k).copied().unwrap_or(true) {
            if let Some(p) = placed.get_mut(k) {
                *p = true;
            }
            let src = from.get(k).copied().unwrap_or(start);
            if src == start || src >= items.len() {
                break;
            }
            items.swap(k, src);
            k = src;
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::{permute, subtree, subtree_serial, Node, Pair, Tri, PARALLEL_MIN};

    /// The tree below `node` in pre-order: boxes, and leaves' triangle ranges.
    fn preorder(pairs: &[Pair], node: &Node, out: &mut Vec<([f32; 3], [f32; 3], u32, u32)>) {
        if node.count > 0 {
            out.push((node.lo, node.hi, node.start, node.count));
            return;
        }
        out.push((node.lo, node.hi, 0, 0));
        let [l, r] = pairs[node.start as usize].0;
        preorder(pairs, &l, out);
        preorder(pairs, &r, out);
    }

    #[test]
    fn the_parallel_build_makes_the_serial_tree() {
        // A wavy 200 x 200 grid of quads: 80 000 triangles, past the parallel threshold.
        let n = 200usize;
        let z = |i: usize, j: usize| ((i * 7 + j * 13) % 17) as f64 * 0.01;
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let p = |a: usize, b: usize| [a as f64 * 0.01, b as f64 * 0.01, z(a, b)];
                let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
                let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i, j + 1), p(i + 1, j + 1));
                tris.push(Tri {
                    v0: a,
                    e1: sub(b, a),
                    e2: sub(d, a),
                });
                tris.push(Tri {
                    v0: a,
                    e1: sub(d, a),
                    e2: sub(c, a),
                });
            }
        }
        assert!(tris.len() > PARALLEL_MIN);
        let order: Vec<(usize, [f64; 3])> = tris
            .iter()
            .enumerate()
            .map(|(i, t)| {
                (
                    i,
                    std::array::from_fn(|k| t.v0[k] + (t.e1[k] + t.e2[k]) / 3.0),
                )
            })
            .collect();
        let (mut o1, mut o2) = (order.clone(), order);
        let (par, ser) = (
            subtree(&tris, &mut o1, 0),
            subtree_serial(&tris, &mut o2, 0),
        );
        assert_eq!(o1, o2);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        preorder(&par, &par[0].0[0], &mut a);
        preorder(&ser, &ser[0].0[0], &mut b);
        let leaves: u32 = a.iter().map(|n| n.3).sum();
        assert_eq!(leaves as usize, tris.len());
        assert_eq!(a, b);
        assert_eq!(par.len(), ser.len());
    }

    #[test]
    fn permute_puts_every_item_where_the_permutation_says() {
        // Cycles of lengths 1, 2 and 4, against a reordered copy.
        let from = [0usize, 2, 1, 6, 3, 4, 5];
        let old: Vec<char> = "abcdefg".chars().collect();
        let mut items = old.clone();
        permute(&mut items, &from);
        let copy: Vec<char> = from.iter().map(|&i| old[i]).collect();
        assert_eq!(items, copy);
        assert_eq!(items.iter().collect::<String>(), "acbgdef");
    }
}
