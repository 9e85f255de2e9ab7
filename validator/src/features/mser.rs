//! MSER (Matas et al. 2002): maximally stable extremal regions, the variant in OpenCV ≥ 3.
//!
//! Each polarity is one pass over the 8-bit levels: pixels are added in increasing level
//! (counting sort) to a 4-connected union-find, and every component that changes at a level
//! becomes a node of the component tree `(level, area, moments)`. The variation of a node at
//! level `g` is `(|R(g + Δ)| − |R(g − Δ)|) / |R(g)|`, where `R(g − Δ)` follows the largest-child
//! chain down and `R(g + Δ)` the parents up (OpenCV's `CompHistory::updateTree`). A node is
//! stable when `min_area ≤ |R| ≤ max_area`, its variation is `≤ max_variation`, not above any
//! child's, and (if positive) below its parent's. Dark regions come from the levels as they
//! are, bright ones from `255 − level`. The two passes run in parallel (`rayon::join`).
//!
//! `min_diversity` follows the original MSER (and OpenCV before 3.0, and VLFeat): a stable
//! region is dropped when it is less than `min_diversity` larger (relative area) than a stable
//! region nested in it. OpenCV 5.0 behaves differently (measured: with 0.2 it drops even a
//! single sharp disc on a flat background), so the peer check runs both sides with 0, where
//! the algorithms agree. Unlike OpenCV, pixels on the image's outer ring take part.
//! Regions are summarised by centroid and second moments ([`Region`]), exact in integers.

use serde::{Deserialize, Serialize};

use super::image::GreyF32;
use super::keypoint::{sort_keypoints, Keypoint, Region};

/// MSER parameters; defaults are OpenCV's `MSER::create()`. The thesis (Table 6.2) used
/// Δ = 2–4 and areas 25–100 px on contrast-stretched 640×512 images.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MserParams {
    /// Level step Δ of the stability test (5).
    pub delta: u8,
    /// Minimum region area, px (60).
    pub min_area: usize,
    /// Maximum region area, px (14400).
    pub max_area: usize,
    /// Maximum variation (0.25).
    pub max_variation: f32,
    /// Minimum relative area difference to a nested stable region (0.2; 0 = off).
    pub min_diversity: f32,
    /// Detect dark regions (default true).
    pub dark: bool,
    /// Detect bright regions (default true).
    pub bright: bool,
}

impl Default for MserParams {
    fn default() -> Self {
        MserParams {
            delta: 5,
            min_area: 60,
            max_area: 14400,
            max_variation: 0.25,
            min_diversity: 0.2,
            dark: true,
            bright: true,
        }
    }
}

const NONE: u32 = u32::MAX;

/// A component-tree node: what the stability test walks, and a pixel of the component.
#[derive(Debug, Clone, Copy)]
struct Node {
    size: u32,
    parent: u32,
    /// A pixel of the component (its union-find root when the node was made), from which
    /// [`moments`] floods the region of the few nodes that are kept.
    seed: u32,
    level: u8,
}

/// The component tree of one polarity: nodes in creation order (children before parents).
struct Tree {
    nodes: Vec<Node>,
}

/// Union-find state of one pixel: `parent` is `NONE` until the pixel is added; `size` and
/// `node` (its latest tree node) are meaningful at roots. One record per pixel, so a neighbour
/// test, a find step and a union read one cache line each.
#[derive(Debug, Clone, Copy)]
struct Cell {
    parent: u32,
    size: u32,
    node: u32,
}

/// Per-pixel union-find state. Moments are not carried along the unions: of the component
/// tree's ~10⁶ nodes only a few hundred regions are kept, and flooding those afterwards
/// ([`moments`]) costs less than updating 40 bytes of moments at every pixel and union.
struct Forest {
    cells: Vec<Cell>,
}

impl Forest {
    fn parent(&self, i: u32) -> u32 {
        self.cells.get(i as usize).map_or(i, |c| c.parent)
    }

    fn added(&self, i: usize) -> bool {
        self.cells.get(i).is_some_and(|c| c.parent != NONE)
    }

    fn size(&self, r: u32) -> u32 {
        self.cells.get(r as usize).map_or(0, |c| c.size)
    }

    /// Root of `i` with path halving.
    fn find(&mut self, mut i: u32) -> u32 {
        loop {
            let p = self.parent(i);
            if p == i {
                return i;
            }
            let gp = self.parent(p);
            if let Some(c) = self.cells.get_mut(i as usize) {
                c.parent = gp;
            }
            i = gp;
        }
    }

    /// Adds pixel `i` as a component of its own.
    fn add(&mut self, i: usize) {
        if let Some(c) = self.cells.get_mut(i) {
            *c = Cell {
                parent: i as u32,
                size: 1,
                node: NONE,
            };
        }
    }

    /// Unites the roots `a` and `b` (by size); returns the new root.
    fn union(&mut self, a: u32, b: u32) -> u32 {
        let (big, small) = if self.size(a) >= self.size(b) {
            (a, b)
        } else {
            (b, a)
        };
        let ss = self.size(small);
        if let Some(c) = self.cells.get_mut(small as usize) {
            c.parent = big;
        }
        if let Some(c) = self.cells.get_mut(big as usize) {
            c.size += ss;
        }
        big
    }

    /// Takes the latest node of root `r` (if any), leaving none.
    fn take_node(&mut self, r: u32) -> Option<u32> {
        let c = self.cells.get_mut(r as usize)?;
        let n = std::mem::replace(&mut c.node, NONE);
        (n != NONE).then_some(n)
    }
}

/// The 4-neighbours of pixel `i` in a `w`-wide, `h`-high image (`None` past its border): the
/// connectivity of the component tree and of the regions' floods alike.
fn neighbours4(i: usize, w: usize, h: usize) -> [Option<usize>; 4] {
    let (x, y) = (i % w, i / w);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < w).then(|| i + 1),
        (y > 0).then(|| i - w),
        (y + 1 < h).then(|| i + w),
    ]
}

/// Builds the component tree of `levels` (pixels join in increasing level).
fn component_tree(levels: &[u8], w: usize, h: usize) -> Tree {
    let n = w * h;
    let mut start = [0usize; 257];
    for &v in levels {
        if let Some(s) = start.get_mut(usize::from(v) + 1) {
            *s += 1;
        }
    }
    for g in 1..257 {
        let prev = start.get(g - 1).copied().unwrap_or(0);
        if let Some(s) = start.get_mut(g) {
            *s += prev;
        }
    }
    let mut order = vec![0u32; n];
    let mut fill = start;
    for (i, &v) in levels.iter().enumerate() {
        if let Some(f) = fill.get_mut(usize::from(v)) {
            if let Some(o) = order.get_mut(*f) {
                *o = i as u32;
            }
            *f += 1;
        }
    }
    let mut f = Forest {
        cells: vec![
            Cell {
                parent: NONE,
                size: 0,
                node: NONE,
            };
            n
        ],
    };
    let mut tree = Tree { nodes: Vec::new() };
    let mut orphans: Vec<(u32, u32)> = Vec::new();
    for (g, bounds) in start.windows(2).enumerate() {
        let pixels = match bounds {
            [a, b] => order.get(*a..*b).unwrap_or(&[]),
            _ => &[],
        };
        orphans.clear();
        for &pix in pixels {
            let i = pix as usize;
            f.add(i);
            let neighbours = neighbours4(i, w, h);
            // The root of `pix`'s component, kept across its neighbours (a union returns it).
            let mut a = pix;
            for q in neighbours.into_iter().flatten() {
                if !f.added(q) {
                    continue;
                }
                let b = f.find(q as u32);
                if a == b {
                    continue;
                }
                for r in [a, b] {
                    if let Some(nd) = f.take_node(r) {
                        orphans.push((nd, pix));
                    }
                }
                a = f.union(a, b);
            }
        }
        for &pix in pixels {
            let r = f.find(pix);
            let size = f.size(r);
            if let Some(c) = f.cells.get_mut(r as usize) {
                if c.node == NONE {
                    c.node = tree.nodes.len() as u32;
                    tree.nodes.push(Node {
                        size,
                        parent: NONE,
                        seed: r,
                        level: g as u8,
                    });
                }
            }
        }
        for &(child, pix) in &orphans {
            let r = f.find(pix);
            let p = f.cells.get(r as usize).map_or(NONE, |c| c.node);
            if let Some(c) = tree.nodes.get_mut(child as usize) {
                c.parent = p;
            }
        }
    }
    tree
}

/// Stable regions of one polarity.
fn pass(levels: &[u8], w: usize, h: usize, bright: bool, p: &MserParams) -> Vec<Region> {
    let tree = component_tree(levels, w, h);
    let nodes = &tree.nodes;
    let get = |i: u32| nodes.get(i as usize);
    let mut largest = vec![NONE; nodes.len()];
    for (i, nd) in nodes.iter().enumerate() {
        if let Some(slot) = largest.get_mut(nd.parent as usize) {
            if *slot == NONE || get(*slot).is_some_and(|c| c.size < nd.size) {
                *slot = i as u32;
            }
        }
    }
    let delta = i32::from(p.delta);
    let var: Vec<f32> = nodes
        .iter()
        .enumerate()
        .map(|(i, nd)| {
            if (nd.size as usize) < p.min_area {
                return f32::INFINITY;
            }
            let g = i32::from(nd.level);
            let mut h1 = *nd;
            while let Some(up) = get(h1.parent).filter(|u| i32::from(u.level) <= g + delta) {
                h1 = *up;
            }
            let mut h0 = i as u32;
            while let Some(&c) = largest.get(h0 as usize) {
                match get(c) {
                    Some(cn) if i32::from(cn.level) >= g - delta => h0 = c,
                    _ => break,
                }
            }
            let s0 = get(h0).map_or(nd.size, |x| x.size);
            (h1.size - s0) as f32 / nd.size as f32
        })
        .collect();
    let mut min_child = vec![f32::INFINITY; nodes.len()];
    for (i, nd) in nodes.iter().enumerate() {
        if let (Some(m), Some(&v)) = (min_child.get_mut(nd.parent as usize), var.get(i)) {
            *m = m.min(v);
        }
    }
    let mut stable: Vec<bool> = nodes
        .iter()
        .enumerate()
        .map(|(i, nd)| {
            let v = var.get(i).copied().unwrap_or(f32::INFINITY);
            let pv = var.get(nd.parent as usize).copied();
            (nd.size as usize) >= p.min_area
                && (nd.size as usize) <= p.max_area
                && v <= p.max_variation
                && v <= min_child.get(i).copied().unwrap_or(f32::INFINITY)
                && !(v > 0.0 && pv.is_some_and(|pv| pv.is_finite() && v >= pv))
        })
        .collect();
    if p.min_diversity > 0.0 {
        let kept = stable.clone();
        for (i, nd) in nodes.iter().enumerate() {
            if !kept.get(i).copied().unwrap_or(false) {
                continue;
            }
            let mut a = nd.parent;
            while let Some(an) = get(a) {
                if kept.get(a as usize).copied().unwrap_or(false) {
                    let div = (an.size - nd.size) as f32 / an.size as f32;
                    if div < p.min_diversity {
                        if let Some(s) = stable.get_mut(a as usize) {
                            *s = false;
                        }
                    }
                    break;
                }
                a = an.parent;
            }
        }
    }
    let mut flood = Flood::new(levels.len());
    nodes
        .iter()
        .zip(stable.iter().zip(&var))
        .filter(|(_, (&s, _))| s)
        .map(|(nd, (_, &v))| region(nd, &flood.moments(levels, w, h, nd), bright, v))
        .collect()
}

/// Scratch of [`Flood::moments`]: a visit stamp per pixel (a new stamp per region, so
/// nothing is cleared between regions) and the queue.
struct Flood {
    stamp: Vec<u32>,
    current: u32,
    queue: Vec<u32>,
}

impl Flood {
    fn new(n: usize) -> Flood {
        Flood {
            stamp: vec![0; n],
            current: 0,
            queue: Vec::new(),
        }
    }

    /// `Σx, Σy, Σx², Σxy, Σy²` of node `nd`'s region: the 4-connected pixels of level at most
    /// `nd.level` around its seed (the component the union-find built), exact in integers.
    fn moments(&mut self, levels: &[u8], w: usize, h: usize, nd: &Node) -> [u64; 5] {
        self.current += 1;
        let stamp = self.current;
        let mut mom = [0u64; 5];
        self.queue.clear();
        if let Some(s) = self.stamp.get_mut(nd.seed as usize) {
            *s = stamp;
            self.queue.push(nd.seed);
        }
        let mut head = 0;
        while let Some(&p) = self.queue.get(head) {
            head += 1;
            let i = p as usize;
            let (x, y) = (i % w, i / w);
            let (xu, yu) = (x as u64, y as u64);
            for (m, v) in mom.iter_mut().zip([xu, yu, xu * xu, xu * yu, yu * yu]) {
                *m += v;
            }
            let neighbours = neighbours4(i, w, h);
            for q in neighbours.into_iter().flatten() {
                let inside = levels.get(q).is_some_and(|&l| l <= nd.level);
                if let Some(s) = self.stamp.get_mut(q).filter(|s| inside && **s != stamp) {
                    *s = stamp;
                    self.queue.push(q as u32);
                }
            }
        }
        debug_assert_eq!(self.queue.len(), nd.size as usize);
        mom
    }
}

fn region(nd: &Node, mom: &[u64; 5], bright: bool, variation: f32) -> Region {
    let n = f64::from(nd.size);
    let [sx, sy, sxx, sxy, syy] = mom.map(|m| m as f64);
    let (mx, my) = (sx / n, sy / n);
    Region {
        x: mx,
        y: my,
        area: nd.size as usize,
        cov: [
            [sxx / n - mx * mx, sxy / n - mx * my],
            [sxy / n - mx * my, syy / n - my * my],
        ],
        bright,
        level: nd.level,
        variation,
    }
}

/// MSER regions of both requested polarities, sorted by `(y, x, area, bright)`.
pub fn mser_regions(img: &GreyF32, p: &MserParams) -> Vec<Region> {
    if img.is_degenerate() || img.width.saturating_mul(img.height) >= NONE as usize {
        return Vec::new();
    }
    let (w, h) = (img.width, img.height);
    let dark_levels = img.to_u8();
    let (dark, bright) = rayon::join(
        || {
            if p.dark {
                pass(&dark_levels, w, h, false, p)
            } else {
                Vec::new()
            }
        },
        || {
            if p.bright {
                let inv: Vec<u8> = dark_levels.iter().map(|v| 255 - v).collect();
                pass(&inv, w, h, true, p)
            } else {
                Vec::new()
            }
        },
    );
    let mut all: Vec<Region> = dark.into_iter().chain(bright).collect();
    all.sort_by(|a, b| {
        a.y.total_cmp(&b.y)
            .then(a.x.total_cmp(&b.x))
            .then(a.area.cmp(&b.area))
            .then(a.bright.cmp(&b.bright))
    });
    all
}

/// MSER keypoints: one per region (centroid; response `1 − variation`).
pub fn detect_mser(img: &GreyF32, p: &MserParams) -> Vec<Keypoint> {
    mser_keypoints(&mser_regions(img, p))
}

/// The keypoints of `regions` in canonical order (what [`detect_mser`] returns for them).
pub fn mser_keypoints(regions: &[Region]) -> Vec<Keypoint> {
    let mut kps: Vec<Keypoint> = regions.iter().map(Region::keypoint).collect();
    sort_keypoints(&mut kps);
    kps
}
