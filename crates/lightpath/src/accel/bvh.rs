//! Bounding volume hierarchy: a binned SAH build (parallel with rayon; see
//! `bvh_build.rs`) into compact 32-byte nodes, traversed front to back.
//!
//! Node layout ([`BvhNode`], 32 bytes, two per 64-byte cache line):
//!
//! | bytes  | field            | meaning                                              |
//! |--------|------------------|------------------------------------------------------|
//! | 0..12  | `min`            | box minimum                                          |
//! | 12..16 | `left_or_first`  | inner: index of the left child (right = left + 1); leaf: first entry in `prim_indices` |
//! | 16..28 | `max`            | box maximum                                          |
//! | 28..32 | `count`          | 0 for an inner node, else the number of primitives  |
//!
//! Siblings are stored next to each other, so a node needs a single child index.

use super::RayStats;
use crate::math::{Bounds3, Ray};
use glam::Vec3;
use rayon::prelude::*;
use std::mem::MaybeUninit;
use std::time::Instant;

/// A 32-byte BVH node; see the module docs for the layout.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(32))]
pub struct BvhNode {
    pub min: [f32; 3],
    pub left_or_first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

impl BvhNode {
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    #[inline]
    pub fn bounds(&self) -> Bounds3 {
        Bounds3 {
            min: Vec3::from_array(self.min),
            max: Vec3::from_array(self.max),
        }
    }

    /// Slab test; the entry distance or `None`. With `AXIS_PARALLEL` (a ray with a zero
    /// direction component), a ray lying in the plane of a face (0·∞ = NaN) is inside
    /// that slab; other rays cannot form NaN and skip the check.
    #[inline(always)]
    fn hit<const AXIS_PARALLEL: bool>(
        &self,
        origin: Vec3,
        inv_dir: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<f32> {
        let t0 = (Vec3::from_array(self.min) - origin) * inv_dir;
        let t1 = (Vec3::from_array(self.max) - origin) * inv_dir;
        let (near, far) = if AXIS_PARALLEL {
            let on_face = t0.is_nan_mask() | t1.is_nan_mask();
            (
                Vec3::select(on_face, Vec3::NEG_INFINITY, t0.min(t1)),
                Vec3::select(on_face, Vec3::INFINITY, t0.max(t1)),
            )
        } else {
            (t0.min(t1), t0.max(t1))
        };
        let tnear = near.max_element().max(t_min);
        let tfar = far.min_element().min(t_max) * ROBUST_FAR;
        (tnear <= tfar).then_some(tnear)
    }
}

/// Whether a direction has a zero component: only such rays can form 0·∞ = NaN in a
/// slab test.
#[inline(always)]
pub(crate) fn has_zero_component(d: Vec3) -> bool {
    d.x == 0.0 || d.y == 0.0 || d.z == 0.0
}

/// Widening of the far slab distance, so rounding never lets a ray slip between boxes
/// (pbrt's `1 + 2γ(3)`).
const ROBUST_FAR: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Build parameters. Use the named presets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildSettings {
    /// SAH bins per axis (2 to 256).
    pub bins: usize,
    /// Bin small ranges into fewer bins: a range of n primitives uses 8 + n/8 bins
    /// where that is below `bins` (with 32 bins, ranges under 192 primitives), since
    /// most of 32 bins stay empty under a hundred primitives yet each costs a clear and
    /// a step of both sweeps. Embree's builders scale their bin count with the range
    /// too (4 + n/20). On the 1.1M-triangle bunny the collapsed tree's cost rises by
    /// 0.05 %.
    pub scaled_bins: bool,
    /// Largest leaf.
    pub max_leaf_size: usize,
    /// Cost of a node traversal relative to a primitive test.
    pub traversal_cost: f32,
    /// Make a leaf where splitting costs more than testing every primitive (SAH
    /// termination); without it, nodes split down to `max_leaf_size`.
    pub cost_termination: bool,
    /// Ranges of at most this many primitives are split by a full SAH sweep over their
    /// centroids in sorted order (every split between neighbours, a superset of the
    /// binned candidates) instead of by bins; 0: bins everywhere.
    pub sweep_size: usize,
    /// Passes of reinsertion after the build (every node, largest first, is taken out
    /// and put back where it adds the least SAH cost); 0: none. Needs a positive
    /// `traversal_cost` (it moves inner nodes' boxes).
    pub reinsertion_passes: usize,
    /// Ranges of at most this many primitives always become leaves: the wide BVHs set it
    /// to their SIMD block size, since they merge such subtrees into one block anyway.
    pub always_leaf: usize,
}

impl Default for BuildSettings {
    fn default() -> Self {
        Self::QUALITY
    }
}

impl BuildSettings {
    /// Fewer bins: faster builds, slightly worse trees.
    pub const FAST: BuildSettings = BuildSettings {
        bins: 8,
        scaled_bins: false,
        max_leaf_size: 8,
        traversal_cost: 1.0,
        cost_termination: true,
        sweep_size: 16,
        reinsertion_passes: 0,
        always_leaf: 0,
    };
    /// The default.
    pub const QUALITY: BuildSettings = BuildSettings {
        bins: 32,
        scaled_bins: true,
        max_leaf_size: 8,
        traversal_cost: 1.0,
        cost_termination: true,
        sweep_size: 16,
        reinsertion_passes: 0,
        always_leaf: 0,
    };
    /// A slower build for a better tree: 64 bins, a full SAH sweep over ranges of up to
    /// 64 primitives, then one pass of reinsertion.
    pub const HIGH: BuildSettings = BuildSettings {
        bins: 64,
        scaled_bins: false,
        max_leaf_size: 8,
        traversal_cost: 1.0,
        cost_termination: true,
        sweep_size: 64,
        reinsertion_passes: 1,
        always_leaf: 0,
    };
    /// The lightwave course's textbook build: binned SAH with no cost termination and
    /// leaves of at most two primitives, which reproduces the course's traversal
    /// statistics. 12 bins: on the course's bvh_complex scene (Sibenik) they visit fewer
    /// nodes (9.37 per pixel) and test fewer triangles (1.45) than the course's reference
    /// (9.44, 1.73); 16 bins visit 9.45 nodes, 32 bins 9.41.
    pub const COURSE: BuildSettings = BuildSettings {
        bins: 12,
        scaled_bins: false,
        max_leaf_size: 2,
        traversal_cost: 0.0,
        cost_termination: false,
        sweep_size: 0,
        reinsertion_passes: 0,
        always_leaf: 0,
    };
}

/// Build statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BvhStats {
    pub build_seconds: f64,
    pub nodes: usize,
    pub leaves: usize,
    pub bytes: usize,
    /// SAH cost of the whole tree (traversal cost 1, primitive cost 1, relative to the
    /// root's surface area).
    pub sah_cost: f32,
    pub max_depth: usize,
}

/// A binary BVH over primitive boxes.
#[derive(Debug, Clone)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    pub prim_indices: Vec<u32>,
    pub stats: BvhStats,
}

/// Traversal stack size; no tree is deeper than this.
pub(super) const STACK_SIZE: usize = 128;
/// Depth from which the builder splits at the median: 96 + log2(2^32) = 128.
pub(super) const MEDIAN_DEPTH: usize = 96;

impl Bvh {
    /// Builds a BVH over the given boxes. Boxes must be finite; empty boxes are allowed
    /// (they are never hit).
    pub fn build(boxes: &[Bounds3], settings: &BuildSettings) -> Bvh {
        Bvh::build_from(boxes.len(), |i| boxes[i], settings)
    }

    /// [`Bvh::build`] over `n` boxes that `box_of` gives by index (called once each).
    pub fn build_from(
        n: usize,
        box_of: impl Fn(usize) -> Bounds3 + Sync,
        settings: &BuildSettings,
    ) -> Bvh {
        let start = Instant::now();
        let mut bvh = Bvh::build_unmeasured(n, box_of, settings);
        bvh.stats = bvh.compute_stats(start.elapsed().as_secs_f64(), bvh.stats.max_depth);
        bvh
    }

    /// [`Bvh::build_from`] without the statistics (a pass over the nodes) but the depth:
    /// for the binary trees that the wide BVHs are collapsed from and then drop.
    pub(super) fn build_unmeasured(
        n: usize,
        box_of: impl Fn(usize) -> Bounds3 + Sync,
        settings: &BuildSettings,
    ) -> Bvh {
        let (nodes, prim_indices, max_depth) = if n == 0 {
            let empty = BvhNode {
                min: [f32::INFINITY; 3],
                max: [f32::NEG_INFINITY; 3],
                left_or_first: 0,
                count: 0,
            };
            (vec![empty], Vec::new(), 1)
        } else {
            super::bvh_build::build_from(n, box_of, settings)
        };
        Bvh {
            nodes,
            prim_indices,
            stats: BvhStats {
                max_depth,
                ..BvhStats::default()
            },
        }
    }

    /// Statistics of a built tree of depth `max_depth`, in one pass over the nodes.
    fn compute_stats(&self, build_seconds: f64, max_depth: usize) -> BvhStats {
        let root_area = self.nodes[0].bounds().surface_area().max(f32::MIN_POSITIVE) as f64;
        // Fixed chunks, summed in order: the same total for any thread count.
        let partial: Vec<(f64, usize)> = self
            .nodes
            .par_chunks(1 << 16)
            .map(|chunk| {
                let mut sah = 0.0f64;
                let mut leaves = 0;
                for n in chunk {
                    let a = n.bounds().surface_area() as f64;
                    if n.is_leaf() || self.prim_indices.is_empty() {
                        leaves += 1;
                        sah += a * n.count as f64;
                    } else {
                        sah += a;
                    }
                }
                (sah, leaves)
            })
            .collect();
        let sah: f64 = partial.iter().map(|p| p.0).sum();
        BvhStats {
            build_seconds,
            nodes: self.nodes.len(),
            leaves: partial.iter().map(|p| p.1).sum(),
            bytes: self.memory_bytes(),
            sah_cost: (sah / root_area) as f32,
            max_depth,
        }
    }

    /// The boxes of a breadth-first cut through the top of the tree, about `max_boxes`
    /// of them, covering every primitive.
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        if self.nodes.is_empty() || self.prim_indices.is_empty() {
            return Vec::new();
        }
        let mut cut = vec![0u32];
        loop {
            let mut next = Vec::with_capacity(cut.len() * 2);
            let mut split_any = false;
            for &n in &cut {
                let node = &self.nodes[n as usize];
                if node.is_leaf() {
                    next.push(n);
                } else {
                    next.push(node.left_or_first);
                    next.push(node.left_or_first + 1);
                    split_any = true;
                }
            }
            if !split_any || next.len() > max_boxes {
                break;
            }
            cut = next;
        }
        cut.iter()
            .map(|&n| self.nodes[n as usize].bounds())
            .collect()
    }

    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<BvhNode>() + self.prim_indices.len() * 4
    }

    pub fn bounds(&self) -> Bounds3 {
        self.nodes[0].bounds()
    }

    /// Closest hit, front to back: children are visited nearest first, the far child's
    /// entry distance is kept on the stack and the child is skipped on pop if a closer
    /// hit has been found meanwhile.
    #[inline]
    pub fn intersect<F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        hit: F,
    ) -> bool {
        if has_zero_component(ray.direction) {
            self.intersect_impl::<true, F>(ray, stats, hit)
        } else {
            self.intersect_impl::<false, F>(ray, stats, hit)
        }
    }

    #[inline(always)]
    fn intersect_impl<const AXIS_PARALLEL: bool, F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut hit: F,
    ) -> bool {
        let inv_dir = ray.direction.recip();
        let origin = ray.origin;
        let mut t_max = ray.t_max;
        let mut any = false;
        if self.prim_indices.is_empty() {
            return false;
        }
        let mut stack = [const { MaybeUninit::<(u32, f32)>::uninit() }; STACK_SIZE];
        let mut sp = 0usize;
        let mut current =
            match self.nodes[0].hit::<AXIS_PARALLEL>(origin, inv_dir, ray.t_min, t_max) {
                Some(_) => 0u32,
                None => return false,
            };
        loop {
            // A node counts as visited when it is entered.
            stats.nodes_visited += 1;
            let node = &self.nodes[current as usize];
            if node.is_leaf() {
                let first = node.left_or_first as usize;
                for &prim in &self.prim_indices[first..first + node.count as usize] {
                    stats.prims_tested += 1;
                    any |= hit(prim, &mut t_max);
                }
            } else {
                let l = node.left_or_first;
                let hl =
                    self.nodes[l as usize].hit::<AXIS_PARALLEL>(origin, inv_dir, ray.t_min, t_max);
                let hr = self.nodes[l as usize + 1]
                    .hit::<AXIS_PARALLEL>(origin, inv_dir, ray.t_min, t_max);
                match (hl, hr) {
                    (Some(dl), Some(dr)) => {
                        let (near, far, dfar) = if dl < dr {
                            (l, l + 1, dr)
                        } else {
                            (l + 1, l, dl)
                        };
                        stack[sp].write((far, dfar));
                        sp += 1;
                        current = near;
                        continue;
                    }
                    (Some(_), None) => {
                        current = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        current = l + 1;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node that may still hold a closer hit.
            loop {
                if sp == 0 {
                    return any;
                }
                sp -= 1;
                // SAFETY: every entry below the old `sp` was written.
                let (n, d) = unsafe { stack[sp].assume_init() };
                if d <= t_max {
                    current = n;
                    break;
                }
            }
        }
    }

    /// Any hit: returns at the first primitive that blocks the ray.
    #[inline]
    pub fn occluded<F: FnMut(u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        blocks: F,
    ) -> bool {
        if has_zero_component(ray.direction) {
            self.occluded_impl::<true, F>(ray, stats, blocks)
        } else {
            self.occluded_impl::<false, F>(ray, stats, blocks)
        }
    }

    #[inline(always)]
    fn occluded_impl<const AXIS_PARALLEL: bool, F: FnMut(u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut blocks: F,
    ) -> bool {
        let inv_dir = ray.direction.recip();
        if self.prim_indices.is_empty() {
            return false;
        }
        let mut stack = [const { MaybeUninit::<u32>::uninit() }; STACK_SIZE];
        let mut sp = 0usize;
        if self.nodes[0]
            .hit::<AXIS_PARALLEL>(ray.origin, inv_dir, ray.t_min, ray.t_max)
            .is_none()
        {
            return false;
        }
        let mut current = 0u32;
        loop {
            // A node counts as visited when it is entered.
            stats.nodes_visited += 1;
            let node = &self.nodes[current as usize];
            if node.is_leaf() {
                let first = node.left_or_first as usize;
                for &prim in &self.prim_indices[first..first + node.count as usize] {
                    stats.prims_tested += 1;
                    if blocks(prim) {
                        return true;
                    }
                }
            } else {
                let l = node.left_or_first;
                let hl = self.nodes[l as usize]
                    .hit::<AXIS_PARALLEL>(ray.origin, inv_dir, ray.t_min, ray.t_max)
                    .is_some();
                let hr = self.nodes[l as usize + 1]
                    .hit::<AXIS_PARALLEL>(ray.origin, inv_dir, ray.t_min, ray.t_max)
                    .is_some();
                match (hl, hr) {
                    (true, true) => {
                        stack[sp].write(l + 1);
                        sp += 1;
                        current = l;
                        continue;
                    }
                    (true, false) => {
                        current = l;
                        continue;
                    }
                    (false, true) => {
                        current = l + 1;
                        continue;
                    }
                    (false, false) => {}
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written.
            current = unsafe { stack[sp].assume_init() };
        }
    }

    /// Checks the tree's invariants: every child box inside its parent, every primitive
    /// in exactly one leaf and inside that leaf's box. Returns a description of the first
    /// violation.
    pub fn validate(&self, boxes: &[Bounds3]) -> Result<(), String> {
        let mut seen = vec![false; boxes.len()];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            let nb = n.bounds();
            if n.is_leaf() {
                let first = n.left_or_first as usize;
                for &p in &self.prim_indices[first..first + n.count as usize] {
                    let p = p as usize;
                    if seen[p] {
                        return Err(format!("primitive {p} in two leaves"));
                    }
                    seen[p] = true;
                    let b = boxes[p];
                    if !(b.is_empty() || nb.contains(b.min) && nb.contains(b.max)) {
                        return Err(format!("primitive {p} outside leaf {i}"));
                    }
                }
            } else if !boxes.is_empty() {
                for c in [n.left_or_first as usize, n.left_or_first as usize + 1] {
                    let cb = self.nodes[c].bounds();
                    if !(cb.is_empty() || nb.contains(cb.min) && nb.contains(cb.max)) {
                        return Err(format!("child {c} outside parent {i}"));
                    }
                    stack.push(c);
                }
            }
        }
        if let Some(p) = seen.iter().position(|s| !s) {
            return Err(format!("primitive {p} in no leaf"));
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The shared accelerator property test: closest hits and occlusion equal the
    /// brute-force list's on random, flat, degenerate and lattice meshes, with
    /// axis-parallel rays, rays in the meshes' planes and rays starting inside.
    #[test]
    fn matches_the_list_on_every_test_scene() {
        crate::accel::testing::check_kind_on_all_scenes(crate::accel::AccelKind::Bvh2);
        crate::accel::testing::check_kind_on_all_scenes(crate::accel::AccelKind::BvhCourse);
        crate::accel::testing::check_kind_on_all_scenes(crate::accel::AccelKind::Bvh2High);
        crate::accel::testing::check_kind_on_all_scenes(crate::accel::AccelKind::Bvh4High);
        crate::accel::testing::check_kind_on_all_scenes(crate::accel::AccelKind::Bvh8High);
    }

    /// The high-quality preset: a valid tree, the same for any thread count, and a lower
    /// SAH cost than the default's.
    #[test]
    fn high_quality_preset() {
        let boxes = random_boxes(40_000, 21);
        let build = |threads, settings: &BuildSettings| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| Bvh::build(&boxes, settings))
        };
        let high = build(1, &BuildSettings::HIGH);
        high.validate(&boxes).unwrap();
        let again = build(2, &BuildSettings::HIGH);
        assert_eq!(high.nodes, again.nodes);
        assert_eq!(high.prim_indices, again.prim_indices);
        let default = build(2, &BuildSettings::default());
        assert!(
            high.stats.sah_cost < default.stats.sah_cost,
            "{} {}",
            high.stats.sah_cost,
            default.stats.sah_cost
        );
        assert!(high.stats.max_depth < STACK_SIZE);
    }
    use crate::sampling::Pcg32;

    /// Random small boxes in [0, 10]³ (shared with the wide BVH's tests).
    pub(crate) fn random_boxes(n: usize, seed: u64) -> Vec<Bounds3> {
        let mut rng = Pcg32::new(seed, 1);
        (0..n)
            .map(|_| {
                let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                let e = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.3;
                Bounds3::new(c - e, c + e)
            })
            .collect()
    }

    /// Ray/box "primitives": the hit distance is the box entry.
    fn closest(accel: &crate::accel::Accel, boxes: &[Bounds3], ray: &Ray) -> Option<(u32, f32)> {
        let mut best = None;
        let mut stats = RayStats::default();
        accel.intersect(ray, &mut stats, |i, t_max| {
            match boxes[i as usize].intersect_ray(&Ray {
                t_max: *t_max,
                ..*ray
            }) {
                Some((t, _)) if t < *t_max => {
                    *t_max = t;
                    best = Some((i, t));
                    true
                }
                _ => false,
            }
        });
        best
    }

    #[test]
    fn tree_is_valid_and_matches_brute_force() {
        for &n in &[1usize, 2, 3, 17, 1000, 20000] {
            let boxes = random_boxes(n, n as u64);
            let bvh = Bvh::build(&boxes, &BuildSettings::default());
            bvh.validate(&boxes).unwrap();
            let bvh = crate::accel::Accel::Bvh(bvh);
            let list = crate::accel::Accel::List(crate::accel::ListAccel::new(&boxes));
            let mut rng = Pcg32::new(99, 3);
            for _ in 0..500 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0
                    - Vec3::splat(2.0);
                let d = Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                );
                let ray = Ray::new(o, d);
                let a = closest(&bvh, &boxes, &ray).map(|(_, t)| t);
                let b = closest(&list, &boxes, &ray).map(|(_, t)| t);
                assert_eq!(a, b);
                let mut s = RayStats::default();
                let occ = bvh.occluded(&ray, &mut s, |i| {
                    boxes[i as usize].intersect_ray(&ray).is_some()
                });
                assert_eq!(occ, b.is_some());
            }
        }
    }

    #[test]
    fn degenerate_inputs() {
        // Identical boxes (all centroids equal), flat boxes, empty boxes, no boxes.
        let same = vec![Bounds3::new(Vec3::ZERO, Vec3::ONE); 100];
        Bvh::build(&same, &BuildSettings::default())
            .validate(&same)
            .unwrap();
        let flat: Vec<_> = (0..50)
            .map(|i| {
                Bounds3::new(
                    Vec3::new(i as f32, 0.0, 0.0),
                    Vec3::new(i as f32 + 1.0, 1.0, 0.0),
                )
            })
            .collect();
        Bvh::build(&flat, &BuildSettings::default())
            .validate(&flat)
            .unwrap();
        let mut with_empty = random_boxes(30, 4);
        with_empty[3] = Bounds3::EMPTY;
        Bvh::build(&with_empty, &BuildSettings::default())
            .validate(&with_empty)
            .unwrap();
        let none = Bvh::build(&[], &BuildSettings::default());
        let mut s = RayStats::default();
        assert!(!none.intersect(&Ray::new(Vec3::ZERO, Vec3::X), &mut s, |_, _| true));
    }

    /// The same tree for any thread count, on an input large enough for the parallel
    /// paths (parallel binning, tasks), with empty boxes among the others.
    #[test]
    fn same_tree_for_any_thread_count() {
        let mut boxes = random_boxes(150_000, 11);
        for i in (0..boxes.len()).step_by(9973) {
            boxes[i] = Bounds3::EMPTY;
        }
        for settings in [BuildSettings::default(), BuildSettings::COURSE] {
            let build = |threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| Bvh::build(&boxes, &settings))
            };
            let one = build(1);
            one.validate(&boxes).unwrap();
            for threads in [2, 3] {
                let other = build(threads);
                assert_eq!(one.nodes, other.nodes, "{threads} threads");
                assert_eq!(one.prim_indices, other.prim_indices, "{threads} threads");
                assert_eq!(one.stats.sah_cost, other.stats.sah_cost);
            }
        }
    }

    /// Every primitive index survives the build's packing of indices into the spare
    /// lanes, including ones above 2^16.
    #[test]
    fn leaves_list_every_primitive_once() {
        let boxes = random_boxes(70_000, 5);
        let bvh = Bvh::build(&boxes, &BuildSettings::default());
        let mut seen = bvh.prim_indices.clone();
        seen.sort_unstable();
        assert!(seen.iter().copied().eq(0..boxes.len() as u32));
        bvh.validate(&boxes).unwrap();
    }

    #[test]
    fn sah_beats_a_median_tree_shape() {
        let boxes = random_boxes(5000, 7);
        let bvh = Bvh::build(&boxes, &BuildSettings::default());
        assert!(bvh.stats.sah_cost > 0.0 && bvh.stats.sah_cost < 5000.0 / 4.0);
        assert!(bvh.stats.max_depth < STACK_SIZE);
    }
}
