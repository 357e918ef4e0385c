//! kd-tree: axis-aligned split planes chosen by the surface area heuristic, after
//! pbrt-v3's `KdTreeAccel`, in compact 8-byte nodes.
//!
//! Selected with `--accel kdtree` on `lightpath render`, `rays` and `bench`
//! (`lightpath render scene.xml --accel kdtree`), or in code with
//! `Accel::build(AccelKind::KdTree, &boxes)`.
//!
//! **Build.** At each node the candidate planes lie along the node's longest axis (the
//! other two axes are tried if none is inside the node): the primitive box edges and
//! the positions just outside them (see below). The boxes' starts and ends are sorted;
//! the candidates come from them in order by a four-way merge (the starts, the floats
//! just below them, the ends, the floats just above them), each once, and are swept
//! together with the starts and ends, counting the primitives below and above each
//! position (merging instead of sorting the candidates again builds the same trees,
//! bunny_loop2's about 14% faster). Each candidate costs `C_trav + C_isect · (1 − b) ·
//! (p_below · n_below + p_above · n_above)`, with `p` the children's surface areas
//! relative to the node's and `b` = [`EMPTY_BONUS`] when a side is empty. A primitive
//! whose box touches the plane goes to both sides (the sweep counts it on both, so the
//! costs match the split), which also keeps hits exactly on a plane and rays lying in a
//! plane correct.
//! A node becomes a leaf at [`MAX_PRIMS`] primitives, at depth `8 + 1.3 · log2 N`, or
//! where its best split costs more than the leaf. Subtrees of large nodes build in
//! parallel.
//!
//! **Costs and candidates.** pbrt-v3 prices a primitive test at 80 node steps and lets
//! a path of nodes split up to three times at a loss ("bad refines"). Its candidate
//! planes are the box edges only. This tree knows only the primitives' boxes, so a
//! plane at a box's edge duplicates that box into both children. With pbrt-v3's
//! settings the splitting went on far past the point of paying: 462 bytes per triangle
//! on the Stanford bunny. So:
//! - the costs here are 1 : 2. With the candidates below, 1 : 1.5 to 1 : 4 traced the
//!   bunny's rays within noise of each other, and memory grew with the cost (61 to 84
//!   bytes per triangle);
//! - no split is made at a loss;
//! - the candidates also include the positions just outside each box (the next float
//!   below its start and above its end), where the box lies on one side only. A plane
//!   there can cut empty space away without duplicating the primitive that bounds it.
//!
//! Stanford bunny, one thread, against pbrt-v3's settings (2 alternated rounds of
//! `lightpath bench bunny.ply --rays DIR --accel kdtree`):
//! - 69.6 bytes per triangle instead of 461.8;
//! - built in 250 ms instead of 590;
//! - about 2× the rays per second on all four ray sets.
//!
//! **Node layout** ([`KdNode`], 8 bytes): `split_or_first` is an inner node's split
//! position (f32 bits) or a leaf's first entry in `prim_indices`; `flags` holds the axis
//! (0–2, or 3 for a leaf) in its two low bits and, above them, the index of the above
//! child (the below child follows its parent) or the leaf's primitive count.
//!
//! **Traversal.** pbrt's: the ray is clipped to the scene box; at an inner node the
//! distance to the plane splits the node's `[t_min, t_max]`; the child on the origin's
//! side is visited first and the other pushed with its own segment, unless the segment
//! lies on one side only. A leaf's primitives are tested; a hit inside the leaf's
//! segment ends the query (the next cell on the stack starts beyond it; the comparison
//! is widened by a relative 1e-5 against rounding).

use super::cover::{CoverCuts, CoverNode};
use super::{widen, CellWalk, RayStats};
use crate::math::{next_float_down, next_float_up, Bounds3, Ray};
use std::time::Instant;

/// Cost of a primitive test, relative to [`TRAVERSAL_COST`] (see the module notes).
pub const INTERSECT_COST: f32 = 2.0;
pub const TRAVERSAL_COST: f32 = 1.0;
/// Fraction of the cost saved by a split with an empty side.
pub const EMPTY_BONUS: f32 = 0.5;
/// A node with this many primitives or fewer is a leaf.
pub const MAX_PRIMS: usize = 1;
/// Nodes with more primitives build their subtrees in parallel.
const PARALLEL_THRESHOLD: usize = 4096;
/// Traversal stack size (the depth is at most 8 + 1.3 · 32 < 64).
const STACK_SIZE: usize = 64;

/// An 8-byte kd-tree node; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct KdNode {
    pub split_or_first: u32,
    pub flags: u32,
}

const LEAF: u32 = 3;

impl KdNode {
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.flags & 3 == LEAF
    }
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.flags & 3) as usize
    }
    #[inline(always)]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.split_or_first)
    }
    /// The above child of an inner node, the primitive count of a leaf.
    #[inline(always)]
    pub fn above_or_count(&self) -> u32 {
        self.flags >> 2
    }
}

#[derive(Debug, Clone)]
pub struct KdTree {
    pub nodes: Vec<KdNode>,
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
        axis: usize,
        split: f32,
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

struct Builder<'a> {
    boxes: &'a [Bounds3],
}

impl Builder<'_> {
    fn build(&self, node: Bounds3, prims: Vec<u32>, depth_left: usize) -> BuildNode {
        let bounds = prims
            .iter()
            .fold(Bounds3::EMPTY, |a, &p| a.union(&self.boxes[p as usize]));
        let n = prims.len();
        let total_area = node.surface_area();
        if n <= MAX_PRIMS || depth_left == 0 || total_area <= 0.0 {
            return BuildNode::Leaf { prims, bounds };
        }
        // The best plane along the longest axis, else along the others.
        let d = node.diagonal();
        let mut axis = node.max_extent();
        let mut best: Option<(usize, f32, f32)> = None;
        for _ in 0..3 {
            best = self.best_split(&node, &prims, axis, total_area);
            if best.is_some() {
                break;
            }
            axis = (axis + 1) % 3;
        }
        let leaf_cost = INTERSECT_COST * n as f32;
        let Some((axis, split, cost)) = best else {
            return BuildNode::Leaf { prims, bounds };
        };
        if cost > leaf_cost {
            return BuildNode::Leaf { prims, bounds };
        }
        let below: Vec<u32> = prims
            .iter()
            .copied()
            .filter(|&p| self.boxes[p as usize].min[axis] <= split)
            .collect();
        let above: Vec<u32> = prims
            .iter()
            .copied()
            .filter(|&p| self.boxes[p as usize].max[axis] >= split)
            .collect();
        drop(prims);
        let (mut below_box, mut above_box) = (node, node);
        below_box.max[axis] = split;
        above_box.min[axis] = split;
        debug_assert!(d[axis] > 0.0);
        let (l, r) = if n > PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(below_box, below, depth_left - 1),
                || self.build(above_box, above, depth_left - 1),
            )
        } else {
            (
                self.build(below_box, below, depth_left - 1),
                self.build(above_box, above, depth_left - 1),
            )
        };
        BuildNode::Inner {
            axis,
            split,
            children: Box::new([l, r]),
            bounds,
        }
    }

    /// The cheapest plane strictly inside the node along `axis`: (axis, position, cost).
    ///
    /// The candidates are the primitives' box edges, where a box that touches the plane
    /// counts on both sides, and the positions just outside each box (the next float
    /// below its start and above its end), where the box lies on one side only: without
    /// these, a primitive at the edge of empty space would be duplicated by every plane
    /// that could cut the empty space off.
    fn best_split(
        &self,
        node: &Bounds3,
        prims: &[u32],
        axis: usize,
        total_area: f32,
    ) -> Option<(usize, f32, f32)> {
        let mut starts: Vec<f32> = Vec::with_capacity(prims.len());
        let mut ends: Vec<f32> = Vec::with_capacity(prims.len());
        for &p in prims {
            let b = &self.boxes[p as usize];
            starts.push(b.min[axis]);
            ends.push(b.max[axis]);
        }
        starts.sort_unstable_by(f32::total_cmp);
        ends.sort_unstable_by(f32::total_cmp);
        let d = node.diagonal();
        let (o1, o2) = ((axis + 1) % 3, (axis + 2) % 3);
        let inv_area = 1.0 / total_area;
        let n = prims.len();
        // Sweep the candidates in order: below = boxes starting at or before the
        // position, above = boxes ending at or after it.
        let (mut started, mut ended) = (0usize, 0usize);
        let mut best: Option<(usize, f32, f32)> = None;
        for_each_candidate(&starts, &ends, |t| {
            while started < n && starts[started] <= t {
                started += 1;
            }
            while ended < n && ends[ended] < t {
                ended += 1;
            }
            if t > node.min[axis] && t < node.max[axis] {
                let (n_below, n_above) = (started, n - ended);
                let below_area = 2.0 * (d[o1] * d[o2] + (t - node.min[axis]) * (d[o1] + d[o2]));
                let above_area = 2.0 * (d[o1] * d[o2] + (node.max[axis] - t) * (d[o1] + d[o2]));
                let bonus = if n_below == 0 || n_above == 0 {
                    EMPTY_BONUS
                } else {
                    0.0
                };
                let cost = TRAVERSAL_COST
                    + INTERSECT_COST
                        * (1.0 - bonus)
                        * (below_area * inv_area * n_below as f32
                            + above_area * inv_area * n_above as f32);
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((axis, t, cost));
                }
            }
        });
        best
    }
}

/// Calls `f` with the candidate planes of sorted `starts` and `ends` in ascending order
/// (`f32::total_cmp`), each value once (as sorting and `Vec::dedup` would give them):
/// the starts, the floats just below them, the ends and the floats just above them. The
/// four sequences are each sorted already, so a merge gives the order without sorting.
fn for_each_candidate(starts: &[f32], ends: &[f32], mut f: impl FnMut(f32)) {
    let n = starts.len();
    assert_eq!(ends.len(), n, "one end per start");
    let value = |k: usize, i: usize| match k {
        0 => starts[i],
        1 => next_float_down(starts[i]),
        2 => ends[i],
        _ => next_float_up(ends[i]),
    };
    let mut at = [0usize; 4];
    if n == 0 {
        return;
    }
    let mut heads = [0, 1, 2, 3].map(|k| value(k, 0));
    let mut last: Option<f32> = None;
    while let Some(k) = (0..4)
        .filter(|&k| at[k] < n)
        .min_by(|&a, &b| heads[a].total_cmp(&heads[b]))
    {
        let t = heads[k];
        at[k] += 1;
        if at[k] < n {
            heads[k] = value(k, at[k]);
        }
        if last != Some(t) {
            last = Some(t);
            f(t);
        }
    }
}

/// Writes `node` at the end of `nodes` (pre-order: the below child follows its parent).
fn flatten(node: BuildNode, nodes: &mut Vec<KdNode>, prim_indices: &mut Vec<u32>) {
    match node {
        BuildNode::Leaf { prims, .. } => {
            nodes.push(KdNode {
                split_or_first: prim_indices.len() as u32,
                flags: (prims.len() as u32) << 2 | LEAF,
            });
            prim_indices.extend_from_slice(&prims);
        }
        BuildNode::Inner {
            axis,
            split,
            children,
            ..
        } => {
            let index = nodes.len();
            nodes.push(KdNode {
                split_or_first: split.to_bits(),
                flags: axis as u32,
            });
            let [below, above] = *children;
            flatten(below, nodes, prim_indices);
            nodes[index].flags |= (nodes.len() as u32) << 2;
            flatten(above, nodes, prim_indices);
        }
    }
}

impl KdTree {
    pub fn build(boxes: &[Bounds3]) -> KdTree {
        let start = Instant::now();
        let bounds = boxes.iter().fold(Bounds3::EMPTY, |a, b| a.union(b));
        let prims: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| !boxes[i as usize].is_empty())
            .collect();
        let max_depth = (8.0 + 1.3 * (prims.len().max(1) as f32).log2()).round() as usize;
        let root = Builder { boxes }.build(bounds, prims, max_depth.min(STACK_SIZE - 2));
        let covers = CoverCuts::record(&root);
        let mut nodes = Vec::new();
        let mut prim_indices = Vec::new();
        flatten(root, &mut nodes, &mut prim_indices);
        KdTree {
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
        self.nodes.len() * std::mem::size_of::<KdNode>() + self.prim_indices.len() * 4
    }

    /// The primitive boxes of a breadth-first cut through the top levels.
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        self.covers.cover(max_boxes)
    }
}

impl CellWalk for KdTree {
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
        let inv_dir = ray.direction.recip();
        let Some((mut t0, mut t1)) = super::clip_ray(&self.bounds, ray, inv_dir) else {
            return;
        };
        let mut stack = [(0u32, 0.0f32, 0.0f32); STACK_SIZE];
        let mut sp = 0;
        let mut current = 0u32;
        loop {
            stats.nodes_visited += 1;
            let node = self.nodes[current as usize];
            if !node.is_leaf() {
                let axis = node.axis();
                let split = node.split();
                let (o, d) = (ray.origin[axis], ray.direction[axis]);
                let t_plane = if d != 0.0 {
                    (split - o) * inv_dir[axis]
                } else {
                    f32::INFINITY
                };
                let below_first = o < split || (o == split && d <= 0.0);
                let (first, second) = if below_first {
                    (current + 1, node.above_or_count())
                } else {
                    (node.above_or_count(), current + 1)
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
            let first = node.split_or_first as usize;
            let limit = leaf(
                &self.prim_indices[first..first + node.above_or_count() as usize],
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
    use crate::accel::{Accel, AccelKind};

    #[test]
    fn matches_the_list_on_every_test_scene() {
        testing::check_kind_on_all_scenes(AccelKind::KdTree);
    }

    /// The merged candidates are those of sorting all four sequences together and
    /// dropping repeats, in the same order (ties, signed zeros and adjacent floats
    /// included).
    #[test]
    fn merged_candidates_equal_sorted_ones() {
        let mut rng = crate::sampling::Pcg32::new(5, 11);
        for case in 0..200 {
            let n = case % 23;
            // Few distinct values, so that starts, ends and their neighbours collide.
            let pick = |rng: &mut crate::sampling::Pcg32| match rng.next_u32() % 6 {
                0 => 0.0,
                1 => -0.0,
                2 => 1.0,
                3 => next_float_up(1.0),
                4 => -2.5,
                _ => rng.next_f32() * 4.0 - 2.0,
            };
            let mut starts: Vec<f32> = (0..n).map(|_| pick(&mut rng)).collect();
            let mut ends: Vec<f32> = starts.iter().map(|&s| s + pick(&mut rng).abs()).collect();
            starts.sort_unstable_by(f32::total_cmp);
            ends.sort_unstable_by(f32::total_cmp);
            let mut expected: Vec<f32> = Vec::new();
            for (&s, &e) in starts.iter().zip(&ends) {
                expected.extend([s, next_float_down(s), e, next_float_up(e)]);
            }
            expected.sort_unstable_by(f32::total_cmp);
            expected.dedup();
            let mut got = Vec::new();
            for_each_candidate(&starts, &ends, |t| got.push(t));
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&got),
                bits(&expected),
                "case {case}: {starts:?} {ends:?}"
            );
        }
    }

    #[test]
    fn node_layout_round_trips() {
        assert_eq!(std::mem::size_of::<KdNode>(), 8);
        let tris = testing::random_soup(3000, 13);
        let b = boxes(&tris);
        let tree = KdTree::build(&b);
        // Every primitive is in some leaf; every inner node's children are in range.
        let mut seen = vec![false; b.len()];
        let mut stack = vec![(0usize, 0usize)];
        let mut max_depth = 0;
        while let Some((i, depth)) = stack.pop() {
            max_depth = max_depth.max(depth);
            let n = tree.nodes[i];
            if n.is_leaf() {
                let first = n.split_or_first as usize;
                for &p in &tree.prim_indices[first..first + n.above_or_count() as usize] {
                    seen[p as usize] = true;
                }
            } else {
                assert!((n.above_or_count() as usize) < tree.nodes.len());
                stack.push((i + 1, depth + 1));
                stack.push((n.above_or_count() as usize, depth + 1));
            }
        }
        assert!(seen.iter().all(|&s| s));
        assert!(max_depth as f32 <= 8.0 + 1.3 * 3000f32.log2() + 1.0);
        assert!(max_depth > 8, "{max_depth}");
    }

    /// The SAH cuts off empty space: a ray through the empty two thirds of the scene
    /// visits few nodes and tests next to nothing.
    #[test]
    fn sah_cuts_empty_space() {
        let mut tris: Vec<_> = testing::random_soup(2000, 14)
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % 97 != 0) // no large triangles
            .map(|(_, t)| t)
            .collect();
        for t in &mut tris {
            for p in t.iter_mut() {
                p.x *= 0.3; // everything in x < 3.3, the box reaching x = 10 by one triangle
            }
        }
        tris.push([
            glam::Vec3::new(10.0, 0.0, 0.0),
            glam::Vec3::new(10.0, 0.1, 0.0),
            glam::Vec3::new(10.0, 0.0, 0.1),
        ]);
        let tree = Accel::KdTree(KdTree::build(&boxes(&tris)));
        let ray = Ray::new(glam::Vec3::new(7.0, 5.0, -1.0), glam::Vec3::Z);
        let (hit, _, stats) = testing::closest(&tree, &tris, &ray);
        assert!(hit.is_none());
        assert!(
            stats.prims_tested <= 2 && stats.nodes_visited < 12,
            "{stats:?}"
        );
    }
}
