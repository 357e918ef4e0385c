//! BSP tree: binary space partitioning by planes of any orientation, `n · x = d`, chosen
//! among the thirteen k-DOP directions and the principal axis of the primitives'
//! centres, by a surface-area cost.
//!
//! Selected with `--accel bsp` on `lightpath render`, `rays` and `bench`
//! (`lightpath render scene.xml --accel bsp`), or in code with
//! `Accel::build(AccelKind::Bsp, &boxes)`.
//!
//! **Build.** A primitive's box with centre `c` and half-extent `e` covers
//! `[c · n − e · |n|, c · n + e · |n|]` along a unit normal `n` (`|n|` component-wise).
//! At each node, for each candidate normal (the 3 axes, the 6 face diagonals and the 4
//! body diagonals of the 26-DOP, and the principal axis of the node's primitive centres
//! by power iteration on their covariance), the projected intervals are binned into
//! [`BINS`] bins and every bin boundary `d` is scored by a SAH-like cost:
//! `C_trav + C_isect · (A(below) · n_below + A(above) · n_above) / A(node)`, where
//! `below` holds the primitives whose interval starts at or before `d`, `above` those
//! that end at or after it (a primitive straddling the plane goes to both sides), `A` of
//! a side is the surface area of the union of their boxes, and `A(node)` that of a box
//! around the node's region (the scene box clipped by each ancestor's plane in turn).
//! Two more candidates per normal cut empty space away: the planes just outside the
//! primitives' extent on either side, where the region reaches beyond it and the cut
//! takes at least a tenth off the region's box, cost `C_trav + C_isect · (1 − b) · n ·
//! A(kept) / A(node)` with `b` = [`EMPTY_BONUS`]. The cheapest plane is taken
//! unless a leaf is cheaper for the third time on a path (bad refines, as in the
//! kd-tree); leaves hold at most [`MAX_LEAF`] primitives unless the depth limit
//! `8 + 1.3 · log2 N` stops the split. Primitive intervals are widened by a relative
//! 1e-6 when sorted to a side, so rounding in the projection never loses one.
//!
//! Child regions stay conservative: a node's region is the scene box cut by the planes
//! of its ancestors, a primitive is stored on every side its box reaches, and traversal
//! clips the ray by exactly those planes: the ray segment of a leaf contains every hit
//! on its primitives within that region.
//!
//! **Node layout** ([`BspNode`], 24 bytes): the unit normal (12 bytes), the plane offset
//! `d` (4), then `above_or_first` (the above child of an inner node, whose below child
//! follows it; a leaf's first entry in `prim_indices`) and `count` (a leaf's primitive
//! count, or [`INNER`]).
//!
//! **Traversal.** As the kd-tree's, with the plane distance `t = (d − n · o) / (n · dir)`
//! and the near side given by the sign of `n · o − d` (on the plane: by the sign of
//! `n · dir`); a hit inside a leaf's segment ends the query.

use super::cover::{CoverCuts, CoverNode};
use super::{widen, CellWalk, RayStats};
use crate::math::{Bounds3, Ray};
use glam::Vec3;
use std::time::Instant;

/// Bins per candidate direction.
pub const BINS: usize = 32;
/// Cost of a primitive test relative to [`TRAVERSAL_COST`].
pub const INTERSECT_COST: f32 = 2.0;
pub const TRAVERSAL_COST: f32 = 1.0;
/// Fraction of the cost saved by a plane with nothing on one side (it cuts empty space
/// away).
pub const EMPTY_BONUS: f32 = 0.5;
/// Largest leaf (unless the depth limit stops the split first).
pub const MAX_LEAF: usize = 2;
/// `count` of an inner node.
pub const INNER: u32 = u32::MAX;
/// Nodes with more primitives build their subtrees in parallel.
const PARALLEL_THRESHOLD: usize = 4096;
/// Traversal stack size (the depth is at most 8 + 1.3 · 32 < 64).
const STACK_SIZE: usize = 64;

/// A 24-byte BSP node; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct BspNode {
    pub normal: [f32; 3],
    pub offset: f32,
    pub above_or_first: u32,
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<BspNode>() == 24);

/// The 13 directions of the 26-DOP (axes, face diagonals, body diagonals), unnormalised.
const KDOP: [[f32; 3]; 13] = [
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 1.0, 0.0],
    [1.0, -1.0, 0.0],
    [1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
    [0.0, 1.0, 1.0],
    [0.0, 1.0, -1.0],
    [1.0, 1.0, 1.0],
    [1.0, 1.0, -1.0],
    [1.0, -1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

#[derive(Debug, Clone)]
pub struct Bsp {
    pub nodes: Vec<BspNode>,
    pub prim_indices: Vec<u32>,
    bounds: Bounds3,
    covers: CoverCuts,
    pub build_seconds: f64,
}

enum BuildNode {
    Leaf {
        prims: Vec<u32>,
        bounds: Bounds3,
    },
    Inner {
        normal: Vec3,
        offset: f32,
        children: Box<[BuildNode; 2]>,
        bounds: Bounds3,
    },
}

impl CoverNode for BuildNode {
    fn cover_bounds(&self) -> Bounds3 {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Inner { bounds, .. } => *bounds,
        }
    }
    fn cover_children(&self) -> Vec<&Self> {
        match self {
            BuildNode::Leaf { .. } => Vec::new(),
            BuildNode::Inner { children, .. } => children.iter().collect(),
        }
    }
}

/// The interval a box covers along the unit normal `n`.
#[inline(always)]
fn project(b: &Bounds3, n: Vec3) -> (f32, f32) {
    let c = b.center().dot(n);
    let e = (b.diagonal() * 0.5).dot(n.abs());
    (c - e, c + e)
}

/// The box around the part of `b` on one side of the plane `n · x = d` (`below`: where
/// `n · x <= d`): the corners on that side and the edges' crossings of the plane; empty
/// if none. A conservative stand-in for a node's region (the scene box cut by the planes
/// above it) in the split cost; traversal never uses it.
fn clip_box(b: &Bounds3, n: Vec3, d: f32, below: bool) -> Bounds3 {
    if b.is_empty() {
        return Bounds3::EMPTY;
    }
    let corners = b.corners();
    let side = corners.map(|c| {
        let v = n.dot(c) - d;
        if below {
            -v
        } else {
            v
        }
    });
    let mut out = Bounds3::EMPTY;
    for k in 0..8 {
        if side[k] >= 0.0 {
            out = out.union(&Bounds3::from_point(corners[k]));
        }
        for bit in [1, 2, 4] {
            let j = k | bit;
            if j != k && (side[k] >= 0.0) != (side[j] >= 0.0) {
                let t = side[k] / (side[k] - side[j]);
                let p = corners[k] + (corners[j] - corners[k]) * t;
                out = out.union(&Bounds3::from_point(p.clamp(b.min, b.max)));
            }
        }
    }
    out
}

/// The principal axis of the centres (unit), or `None` if they hardly spread.
fn principal_axis(centres: impl Iterator<Item = Vec3> + Clone) -> Option<Vec3> {
    let n = centres.clone().count() as f64;
    if n < 3.0 {
        return None;
    }
    let mean = centres.clone().fold([0.0f64; 3], |m, c| {
        [m[0] + c.x as f64, m[1] + c.y as f64, m[2] + c.z as f64]
    });
    let mean = mean.map(|m| m / n);
    let mut cov = [[0.0f64; 3]; 3];
    for c in centres {
        let v = [
            c.x as f64 - mean[0],
            c.y as f64 - mean[1],
            c.z as f64 - mean[2],
        ];
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += v[i] * v[j];
            }
        }
    }
    let mut v = [0.577f64, 0.579, 0.575];
    for _ in 0..24 {
        let w: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| cov[i][j] * v[j]).sum())
            .collect();
        let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        if len.is_nan() || len <= 1e-30 {
            return None;
        }
        v = [w[0] / len, w[1] / len, w[2] / len];
    }
    let axis = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32).normalize_or_zero();
    (axis != Vec3::ZERO && axis.is_finite()).then_some(axis)
}

#[derive(Clone, Copy)]
struct Bin {
    starts: usize,
    start_box: Bounds3,
    ends: usize,
    end_box: Bounds3,
}

const EMPTY_BIN: Bin = Bin {
    starts: 0,
    start_box: Bounds3::EMPTY,
    ends: 0,
    end_box: Bounds3::EMPTY,
};

struct Builder<'a> {
    boxes: &'a [Bounds3],
}

impl Builder<'_> {
    /// The subtree of `prims` in `region` (a box around the node's region).
    fn build(
        &self,
        prims: Vec<u32>,
        region: Bounds3,
        depth_left: usize,
        bad_refines: usize,
    ) -> BuildNode {
        let bounds = prims
            .iter()
            .fold(Bounds3::EMPTY, |a, &p| a.union(&self.boxes[p as usize]));
        let n = prims.len();
        let area = region.surface_area();
        if n <= MAX_LEAF || depth_left == 0 || area.is_nan() || area <= 0.0 {
            return BuildNode::Leaf { prims, bounds };
        }
        let pca = principal_axis(prims.iter().map(|&p| self.boxes[p as usize].center()));
        let normals = KDOP
            .iter()
            .map(|&v| Vec3::from_array(v).normalize())
            .chain(pca);
        let mut best: Option<(Vec3, f32, f32)> = None;
        for normal in normals {
            if let Some((offset, cost)) = self.best_plane(&prims, normal, &region, area) {
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((normal, offset, cost));
                }
            }
        }
        let leaf_cost = INTERSECT_COST * n as f32;
        let Some((normal, offset, cost)) = best else {
            return BuildNode::Leaf { prims, bounds };
        };
        let bad_refines = bad_refines + usize::from(cost >= leaf_cost);
        if bad_refines == 3 {
            return BuildNode::Leaf { prims, bounds };
        }
        // Sort to the sides, the intervals widened against rounding.
        let (mut below, mut above) = (Vec::new(), Vec::new());
        for &p in &prims {
            let (lo, hi) = project(&self.boxes[p as usize], normal);
            let eps = (lo.abs() + hi.abs() + offset.abs()) * 1e-6;
            if lo - eps <= offset {
                below.push(p);
            }
            if hi + eps >= offset {
                above.push(p);
            }
        }
        if below.len() == n && above.len() == n {
            return BuildNode::Leaf { prims, bounds };
        }
        drop(prims);
        let region_below = clip_box(&region, normal, offset, true);
        let region_above = clip_box(&region, normal, offset, false);
        let (l, r) = if n > PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(below, region_below, depth_left - 1, bad_refines),
                || self.build(above, region_above, depth_left - 1, bad_refines),
            )
        } else {
            (
                self.build(below, region_below, depth_left - 1, bad_refines),
                self.build(above, region_above, depth_left - 1, bad_refines),
            )
        };
        BuildNode::Inner {
            normal,
            offset,
            children: Box::new([l, r]),
            bounds,
        }
    }

    /// The cheapest plane along `normal`, a bin boundary or a plane just outside the
    /// primitives on either side (cutting empty space away): (offset, cost).
    fn best_plane(
        &self,
        prims: &[u32],
        normal: Vec3,
        region: &Bounds3,
        area: f32,
    ) -> Option<(f32, f32)> {
        let intervals: Vec<(f32, f32)> = prims
            .iter()
            .map(|&p| project(&self.boxes[p as usize], normal))
            .collect();
        let lo = intervals.iter().fold(f32::INFINITY, |m, i| m.min(i.0));
        let hi = intervals.iter().fold(f32::NEG_INFINITY, |m, i| m.max(i.1));
        let spread = hi - lo;
        if spread.is_nan() || spread <= (lo.abs() + hi.abs()) * 1e-6 {
            return None;
        }
        let scale = BINS as f32 / (hi - lo);
        let bin = |x: f32| (((x - lo) * scale) as usize).min(BINS - 1);
        let mut bins = [EMPTY_BIN; BINS];
        for (&p, &(s, e)) in prims.iter().zip(&intervals) {
            let b = &self.boxes[p as usize];
            let (i, j) = (bin(s), bin(e));
            bins[i].starts += 1;
            bins[i].start_box = bins[i].start_box.union(b);
            bins[j].ends += 1;
            bins[j].end_box = bins[j].end_box.union(b);
        }
        // A bin boundary costs what its two sides' primitives' boxes cover, relative to
        // the node's region; a cut just outside the primitives (below) what is left of
        // the region, with a bonus for the empty side.
        let n = prims.len();
        let mut best: Option<(f32, f32)> = None;
        let mut consider = |d: f32, c: f32| {
            if best.is_none_or(|(_, b)| c < b) {
                best = Some((d, c));
            }
        };
        // Above the boundary k: the boxes ending in bins k and up.
        let mut above = [(0usize, 0.0f32); BINS];
        let (mut count, mut acc) = (0, Bounds3::EMPTY);
        for k in (1..BINS).rev() {
            count += bins[k].ends;
            acc = acc.union(&bins[k].end_box);
            above[k] = (count, acc.surface_area());
        }
        let (mut count, mut acc) = (0, Bounds3::EMPTY);
        for k in 1..BINS {
            count += bins[k - 1].starts;
            acc = acc.union(&bins[k - 1].start_box);
            let (n_above, above_area) = above[k];
            let cost = TRAVERSAL_COST
                + INTERSECT_COST
                    * (acc.surface_area() * count as f32 + above_area * n_above as f32)
                    / area;
            consider(lo + k as f32 / scale, cost);
        }
        // Just outside the primitives (a margin well clear of the widening that sorts
        // primitives to the sides), where that cuts at least a tenth off the region's
        // box: a cut that leaves the box as it was (an oblique plane past a corner the
        // box still holds) would otherwise look as good every time and use up the depth.
        let margin = spread * 1e-3 + (lo.abs() + hi.abs()) * 1e-5;
        let (r_lo, r_hi) = project(region, normal);
        for (d, below) in [(lo - margin, false), (hi + margin, true)] {
            if (below && r_hi <= d) || (!below && r_lo >= d) {
                continue; // The region ends before the plane: nothing to cut.
            }
            let kept = clip_box(region, normal, d, below).surface_area();
            if kept < 0.9 * area {
                let cost =
                    TRAVERSAL_COST + INTERSECT_COST * (1.0 - EMPTY_BONUS) * kept * n as f32 / area;
                consider(d, cost);
            }
        }
        best
    }
}

/// Writes `node` at the end of `nodes` (pre-order: the below child follows its parent).
fn flatten(node: BuildNode, nodes: &mut Vec<BspNode>, prim_indices: &mut Vec<u32>) {
    match node {
        BuildNode::Leaf { prims, .. } => {
            nodes.push(BspNode {
                normal: [0.0; 3],
                offset: 0.0,
                above_or_first: prim_indices.len() as u32,
                count: prims.len() as u32,
            });
            prim_indices.extend_from_slice(&prims);
        }
        BuildNode::Inner {
            normal,
            offset,
            children,
            ..
        } => {
            let index = nodes.len();
            nodes.push(BspNode {
                normal: normal.to_array(),
                offset,
                above_or_first: 0,
                count: INNER,
            });
            let [below, above] = *children;
            flatten(below, nodes, prim_indices);
            nodes[index].above_or_first = nodes.len() as u32;
            flatten(above, nodes, prim_indices);
        }
    }
}

impl Bsp {
    pub fn build(boxes: &[Bounds3]) -> Bsp {
        let start = Instant::now();
        let bounds = boxes.iter().fold(Bounds3::EMPTY, |a, b| a.union(b));
        let prims: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| !boxes[i as usize].is_empty())
            .collect();
        let max_depth = (8.0 + 1.3 * (prims.len().max(1) as f32).log2()).round() as usize;
        let root = Builder { boxes }.build(prims, bounds, max_depth.min(STACK_SIZE - 2), 0);
        let covers = CoverCuts::record(&root);
        let mut nodes = Vec::new();
        let mut prim_indices = Vec::new();
        flatten(root, &mut nodes, &mut prim_indices);
        Bsp {
            nodes,
            prim_indices,
            bounds,
            covers,
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }

    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<BspNode>() + self.prim_indices.len() * 4
    }

    /// The primitive boxes of a breadth-first cut through the top levels.
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        self.covers.cover(max_boxes)
    }
}

impl CellWalk for Bsp {
    /// Visits the leaves along the ray front to back; `leaf` tests a leaf's primitives
    /// and returns the distance beyond which no leaf needs visiting (`-∞` to stop).
    #[inline(always)]
    fn walk(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut leaf: impl FnMut(&[u32], &mut RayStats) -> f32,
    ) {
        if self.prim_indices.is_empty() {
            return;
        }
        let Some((mut t0, mut t1)) = super::clip_ray(&self.bounds, ray, ray.direction.recip())
        else {
            return;
        };
        let mut stack = [(0u32, 0.0f32, 0.0f32); STACK_SIZE];
        let mut sp = 0;
        let mut current = 0u32;
        loop {
            stats.nodes_visited += 1;
            let node = self.nodes[current as usize];
            if node.count == INNER {
                let normal = Vec3::from_array(node.normal);
                let side = normal.dot(ray.origin) - node.offset;
                let denom = normal.dot(ray.direction);
                let t_plane = if denom != 0.0 {
                    -side / denom
                } else {
                    f32::INFINITY
                };
                let below_first = side < 0.0 || (side == 0.0 && denom <= 0.0);
                let (first, second) = if below_first {
                    (current + 1, node.above_or_first)
                } else {
                    (node.above_or_first, current + 1)
                };
                if t_plane > widen(t1) || t_plane <= 0.0 {
                    current = first;
                } else if widen(t_plane) < t0 {
                    current = second;
                } else {
                    stack[sp] = (second, t_plane, t1);
                    sp += 1;
                    current = first;
                    t1 = t_plane;
                }
                continue;
            }
            let first = node.above_or_first as usize;
            let limit = leaf(
                &self.prim_indices[first..first + node.count as usize],
                stats,
            );
            // The next cell, unless the hit lies before it.
            if sp == 0 {
                return;
            }
            sp -= 1;
            (current, t0, t1) = stack[sp];
            if t0 > limit {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::{self, boxes};
    use crate::accel::AccelKind;

    #[test]
    fn matches_the_list_on_every_test_scene() {
        testing::check_kind_on_all_scenes(AccelKind::Bsp);
    }

    /// Empty space is cut away: a cluster of small triangles in one corner of a big
    /// scene box gets empty leaves around it, and a ray that passes the cluster by
    /// crosses few regions (with only planes between primitives, every region held
    /// primitives and such a ray crossed the cluster's regions one after another).
    #[test]
    fn cuts_empty_space_away() {
        let mut rng = crate::sampling::Pcg32::new(9, 2);
        let mut tris: Vec<testing::Triangle> = (0..500)
            .map(|_| {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                [
                    o,
                    o + Vec3::new(0.05, 0.0, 0.0),
                    o + Vec3::new(0.0, 0.05, 0.02),
                ]
            })
            .collect();
        // A far corner makes the scene box 10 wide.
        let far = Vec3::splat(10.0);
        tris.push([far, far - Vec3::X * 0.01, far - Vec3::Y * 0.01]);
        let tree = Bsp::build(&boxes(&tris));
        assert!(tree.nodes.iter().any(|n| n.count == 0));
        let accel = crate::accel::Accel::Bsp(tree);
        // Rays along z through the empty part of the box, beside the cluster.
        let mut visited = 0;
        for i in 0..100 {
            let x = 1.5 + 8.0 * i as f32 / 100.0;
            let ray = Ray::new(Vec3::new(x, 0.5, -1.0), Vec3::Z);
            let (hit, _, stats) = testing::closest(&accel, &tris, &ray);
            assert!(hit.is_none());
            visited += stats.nodes_visited;
        }
        assert!(visited <= 100 * 8, "{visited} nodes for 100 rays");
        testing::check_against_list(&accel, &tris, &testing::rays_for(&tris, 2000, 4), "cluster");
    }

    /// A scene of thin slabs along a diagonal is split by diagonal planes, which no
    /// axis-aligned tree can use.
    #[test]
    fn uses_oblique_planes_on_oblique_scenes() {
        let mut tris = Vec::new();
        for i in 0..400 {
            let s = i as f32 * 0.05;
            // Small triangles on the plane x + y = s... spread along (1, -1, 0) and z.
            for j in 0..2 {
                let o = Vec3::new(s * 0.5 + j as f32, s * 0.5 - j as f32, (i % 7) as f32);
                tris.push([
                    o,
                    o + Vec3::new(0.1, -0.1, 0.0),
                    o + Vec3::new(0.0, 0.0, 0.1),
                ]);
            }
        }
        let tree = Bsp::build(&boxes(&tris));
        let oblique = tree
            .nodes
            .iter()
            .filter(|n| n.count == INNER)
            .filter(|n| n.normal.iter().filter(|&&c| c != 0.0).count() > 1)
            .count();
        assert!(oblique > 0);
        testing::check_against_list(
            &crate::accel::Accel::Bsp(tree),
            &tris,
            &testing::rays_for(&tris, 2000, 3),
            "oblique",
        );
    }

    #[test]
    fn principal_axis_of_a_line() {
        let pts = (0..10).map(|i| Vec3::new(i as f32, 2.0 * i as f32, 0.5));
        let a = principal_axis(pts).unwrap();
        assert!(
            (a.abs() - Vec3::new(1.0, 2.0, 0.0).normalize()).length() < 1e-4,
            "{a}"
        );
    }
}
