//! A 4-wide BVH: the binary SAH tree collapsed so that every node holds up to four
//! children whose boxes are stored as structure-of-arrays and tested against a ray at
//! once with 4-lane SIMD (glam's `Vec4`, SSE on x86-64, a portable fallback elsewhere).
//! The nearest hit child is visited first, the others go on the stack with their entry
//! distances and are culled on pop. Selected with `--accel bvh4`.
//!
//! Leaves are laid out for blocks of four primitives (the `collapse` module), so a triangle
//! mesh tests each leaf with SIMD. The 8-wide [`super::Bvh8`] is faster on processors
//! with AVX2 and is the default; this one stays selectable for comparison.
//!
//! Node layout ([`Bvh4Node`], 128 bytes, two cache lines): the six box planes of the four
//! children as `[f32; 4]` each (96 bytes), then per child a `u32` reference (an inner
//! node's index, or a leaf's first entry in `prim_indices`) and a `u32` count (0 for an
//! inner node, else the number of primitives; `u32::MAX` for an unused slot).

use super::bvh::{has_zero_component, BuildSettings, Bvh};
use super::collapse::{any_prim, build_binary, collapse, each_prim, wide_cover, EMPTY};
use super::RayStats;
use crate::math::{Bounds3, Ray};
use glam::{Vec3, Vec4};
use std::mem::MaybeUninit;

/// Four children's boxes and references; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub struct Bvh4Node {
    pub min_x: [f32; 4],
    pub min_y: [f32; 4],
    pub min_z: [f32; 4],
    pub max_x: [f32; 4],
    pub max_y: [f32; 4],
    pub max_z: [f32; 4],
    pub child: [u32; 4],
    pub count: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);

/// Unused slots hold a box at +∞ and the count `EMPTY`; traversal skips them by the
/// count, since a box at infinity still passes the slab test of a ray with t_max = ∞.
const EMPTY_NODE: Bvh4Node = Bvh4Node {
    min_x: [f32::INFINITY; 4],
    min_y: [f32::INFINITY; 4],
    min_z: [f32::INFINITY; 4],
    max_x: [f32::INFINITY; 4],
    max_y: [f32::INFINITY; 4],
    max_z: [f32::INFINITY; 4],
    child: [0; 4],
    count: [EMPTY; 4],
};

/// Widening of the far slab distance (as in the binary BVH, pbrt's `1 + 2γ(3)`).
const ROBUST_FAR: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Stack depth: each level pushes at most three siblings.
const STACK_SIZE: usize = 3 * 128 + 4;

/// A stack entry: a child slot (inner node or leaf range) and its entry distance.
#[derive(Clone, Copy, Default)]
struct Entry {
    child: u32,
    count: u32,
    dist: f32,
}

#[derive(Debug, Clone)]
pub struct Bvh4 {
    pub nodes: Vec<Bvh4Node>,
    pub prim_indices: Vec<u32>,
    bounds: Bounds3,
    /// The root slot: an inner node (count 0) or, for tiny inputs, a leaf.
    root: (u32, u32),
    pub build_seconds: f64,
    /// The collapse's cost of the tree: node tests and leaf tests weighted by the
    /// surface areas of their boxes, relative to the root's (the `collapse` module).
    pub collapse_cost: f32,
}

impl Bvh4 {
    /// Builds the binary SAH tree, then collapses it.
    pub fn build(boxes: &[Bounds3], settings: &BuildSettings) -> Bvh4 {
        Bvh4::build_from(boxes.len(), |i| boxes[i], settings)
    }

    /// [`Bvh4::build`] over `n` boxes that `box_of` gives by index (called once each).
    pub fn build_from(
        n: usize,
        box_of: impl Fn(usize) -> Bounds3 + Sync,
        settings: &BuildSettings,
    ) -> Bvh4 {
        let (bvh, start) = build_binary(n, box_of, settings);
        let mut wide = Bvh4::collapse(&bvh);
        wide.build_seconds = start.elapsed().as_secs_f64();
        wide
    }

    /// Collapses a binary BVH into 4-wide nodes (the `collapse` module).
    pub fn collapse(bvh: &Bvh) -> Bvh4 {
        let tree = collapse::<4>(bvh);
        use rayon::prelude::*;
        let nodes = tree
            .nodes
            .par_iter()
            .map(|slots| {
                let mut n = EMPTY_NODE;
                for (k, s) in slots.iter().enumerate() {
                    n.min_x[k] = s.min[0];
                    n.min_y[k] = s.min[1];
                    n.min_z[k] = s.min[2];
                    n.max_x[k] = s.max[0];
                    n.max_y[k] = s.max[1];
                    n.max_z[k] = s.max[2];
                    n.child[k] = s.child;
                    n.count[k] = s.count;
                }
                n
            })
            .collect();
        Bvh4 {
            nodes,
            prim_indices: tree.prim_order,
            bounds: bvh.bounds(),
            root: tree.root,
            build_seconds: 0.0,
            collapse_cost: tree.cost,
        }
    }

    /// The primitive at every leaf position (leaves padded as the `collapse` module
    /// describes); the positions that [`Bvh4::intersect_leaves`] hands out index it.
    pub fn prim_order(&self) -> &[u32] {
        &self.prim_indices
    }

    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }

    /// Starts loading an inner child's node, whose cache lines are otherwise fetched
    /// one miss at a time when it is popped.
    #[inline(always)]
    fn prefetch(&self, child: u32, count: u32) {
        #[cfg(target_arch = "x86_64")]
        if count == 0 {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let p = self.nodes.as_ptr().wrapping_add(child as usize) as *const i8;
            // SAFETY: prefetching is a hint and never faults, whatever the address.
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(p);
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (child, count);
    }

    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Bvh4Node>() + self.prim_indices.len() * 4
    }

    /// The boxes of the root's children (and theirs, while under `max_boxes`).
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        if self.prim_indices.is_empty() {
            return Vec::new();
        }
        if self.nodes.is_empty() {
            return vec![self.bounds];
        }
        wide_cover(4, max_boxes, |n, k| {
            let node = &self.nodes[n];
            (node.count[k] != EMPTY).then(|| {
                let b = Bounds3::new(
                    Vec3::new(node.min_x[k], node.min_y[k], node.min_z[k]),
                    Vec3::new(node.max_x[k], node.max_y[k], node.max_z[k]),
                );
                (b, node.child[k], node.count[k])
            })
        })
        .unwrap_or_else(|| vec![self.bounds])
    }

    /// Entry distances of the four children, and a bit mask of those hit. With
    /// `AXIS_PARALLEL` (a ray with a zero direction component), a ray lying in a slab's
    /// plane (0·∞ = NaN) is inside that slab; other rays cannot form NaN and skip the
    /// check.
    #[inline(always)]
    fn hit4<const AXIS_PARALLEL: bool>(
        node: &Bvh4Node,
        o: [Vec4; 3],
        inv: [Vec4; 3],
        t_min: f32,
        t_max: f32,
    ) -> (Vec4, u32) {
        let tx0 = (Vec4::from_array(node.min_x) - o[0]) * inv[0];
        let tx1 = (Vec4::from_array(node.max_x) - o[0]) * inv[0];
        let ty0 = (Vec4::from_array(node.min_y) - o[1]) * inv[1];
        let ty1 = (Vec4::from_array(node.max_y) - o[1]) * inv[1];
        let tz0 = (Vec4::from_array(node.min_z) - o[2]) * inv[2];
        let tz1 = (Vec4::from_array(node.max_z) - o[2]) * inv[2];
        let slab = |t0: Vec4, t1: Vec4| {
            if AXIS_PARALLEL {
                let on_face = t0.is_nan_mask() | t1.is_nan_mask();
                (
                    Vec4::select(on_face, Vec4::NEG_INFINITY, t0.min(t1)),
                    Vec4::select(on_face, Vec4::INFINITY, t0.max(t1)),
                )
            } else {
                (t0.min(t1), t0.max(t1))
            }
        };
        let (x0, x1) = slab(tx0, tx1);
        let (y0, y1) = slab(ty0, ty1);
        let (z0, z1) = slab(tz0, tz1);
        let near = x0.max(y0).max(z0).max(Vec4::splat(t_min));
        let far = x1.min(y1).min(z1).min(Vec4::splat(t_max)) * ROBUST_FAR;
        (near, near.cmple(far).bitmask())
    }

    #[inline(always)]
    fn ray_lanes(ray: &Ray) -> ([Vec4; 3], [Vec4; 3]) {
        let inv = ray.direction.recip();
        (
            [
                Vec4::splat(ray.origin.x),
                Vec4::splat(ray.origin.y),
                Vec4::splat(ray.origin.z),
            ],
            [Vec4::splat(inv.x), Vec4::splat(inv.y), Vec4::splat(inv.z)],
        )
    }

    /// Whether the whole tree's box is hit at all.
    #[inline(always)]
    fn root_hit(&self, ray: &Ray, t_max: f32) -> bool {
        self.bounds.intersect_ray(&Ray { t_max, ..*ray }).is_some()
    }

    /// Closest hit, front to back (see [`crate::accel::Accel::intersect`]).
    #[inline]
    pub fn intersect<F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        hit: F,
    ) -> bool {
        self.intersect_leaves(ray, stats, each_prim(&self.prim_indices, hit))
    }

    /// Closest hit by whole leaves: `leaf(first, count, &mut t_max)` tests the
    /// primitives at positions `first..first + count` of [`Bvh4::prim_order`] (`first`
    /// is a multiple of `LEAF_ALIGN` (4), and the padding up to the next multiple repeats
    /// the leaf's last primitive), lowers `t_max` for a closer hit and returns whether
    /// it found one.
    #[inline]
    pub fn intersect_leaves<F: FnMut(u32, u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        leaf: F,
    ) -> bool {
        if has_zero_component(ray.direction) {
            self.intersect_impl::<true, F>(ray, stats, leaf)
        } else {
            self.intersect_impl::<false, F>(ray, stats, leaf)
        }
    }

    #[inline(always)]
    fn intersect_impl<const AXIS_PARALLEL: bool, F: FnMut(u32, u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut leaf: F,
    ) -> bool {
        if self.prim_indices.is_empty() || !self.root_hit(ray, ray.t_max) {
            return false;
        }
        let (o, inv) = Self::ray_lanes(ray);
        let mut t_max = ray.t_max;
        let mut any = false;
        // Uninitialised: zeroing its 4.6 KB cost every ray a memset.
        let mut stack = [const { MaybeUninit::<Entry>::uninit() }; STACK_SIZE];
        stack[0].write(Entry {
            child: self.root.0,
            count: self.root.1,
            dist: ray.t_min,
        });
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written.
            let e = unsafe { stack[sp].assume_init() };
            if e.dist > t_max {
                continue;
            }
            stats.nodes_visited += 1;
            if e.count > 0 {
                stats.prims_tested += e.count;
                any |= leaf(e.child, e.count, &mut t_max);
                continue;
            }
            let node = &self.nodes[e.child as usize];
            let (near, mask) = Self::hit4::<AXIS_PARALLEL>(node, o, inv, ray.t_min, t_max);
            if mask == 0 {
                continue;
            }
            // Push the hit children, the nearest last so that it is popped next.
            let mut nearest: Option<Entry> = None;
            for k in 0..4 {
                if mask & (1 << k) != 0 && node.count[k] != EMPTY {
                    self.prefetch(node.child[k], node.count[k]);
                    let entry = Entry {
                        child: node.child[k],
                        count: node.count[k],
                        dist: near[k],
                    };
                    match nearest {
                        Some(best) if best.dist <= entry.dist => {
                            stack[sp].write(entry);
                            sp += 1;
                        }
                        Some(best) => {
                            stack[sp].write(best);
                            sp += 1;
                            nearest = Some(entry);
                        }
                        None => nearest = Some(entry),
                    }
                }
            }
            if let Some(best) = nearest {
                stack[sp].write(best);
                sp += 1;
            }
        }
        any
    }

    /// Any hit: returns at the first primitive that blocks the ray.
    #[inline]
    pub fn occluded<F: FnMut(u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        blocks: F,
    ) -> bool {
        self.occluded_leaves(ray, stats, any_prim(&self.prim_indices, blocks))
    }

    /// Any hit by whole leaves: `blocks(first, count)` says whether a primitive at the
    /// positions `first..first + count` of [`Bvh4::prim_order`] blocks the ray (see
    /// [`Bvh4::intersect_leaves`] for the layout).
    #[inline]
    pub fn occluded_leaves<F: FnMut(u32, u32) -> bool>(
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
    fn occluded_impl<const AXIS_PARALLEL: bool, F: FnMut(u32, u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut blocks: F,
    ) -> bool {
        if self.prim_indices.is_empty() || !self.root_hit(ray, ray.t_max) {
            return false;
        }
        let (o, inv) = Self::ray_lanes(ray);
        // Uninitialised: zeroing its 4.6 KB cost every ray a memset.
        let mut stack = [const { MaybeUninit::<Entry>::uninit() }; STACK_SIZE];
        stack[0].write(Entry {
            child: self.root.0,
            count: self.root.1,
            dist: 0.0,
        });
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written.
            let e = unsafe { stack[sp].assume_init() };
            stats.nodes_visited += 1;
            if e.count > 0 {
                stats.prims_tested += e.count;
                if blocks(e.child, e.count) {
                    return true;
                }
                continue;
            }
            let node = &self.nodes[e.child as usize];
            let (_, mask) = Self::hit4::<AXIS_PARALLEL>(node, o, inv, ray.t_min, ray.t_max);
            for k in 0..4 {
                if mask & (1 << k) != 0 && node.count[k] != EMPTY {
                    stack[sp].write(Entry {
                        child: node.child[k],
                        count: node.count[k],
                        dist: 0.0,
                    });
                    sp += 1;
                }
            }
        }
        false
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
        crate::accel::testing::check_kind_on_all_scenes(crate::accel::AccelKind::Bvh4);
    }
    use crate::accel::bvh::tests::random_boxes;
    use crate::accel::{Accel, ListAccel};
    use crate::sampling::Pcg32;

    /// The exact entry distance of a ray into a box (inclusive faces), in f64, with a
    /// zero direction component handled as "inside the slab or not".
    pub(crate) fn exact_entry(b: &Bounds3, ray: &Ray) -> Option<f32> {
        if b.is_empty() {
            return None;
        }
        let (mut near, mut far) = (ray.t_min as f64, ray.t_max as f64);
        for i in 0..3 {
            let (o, d) = (ray.origin[i] as f64, ray.direction[i] as f64);
            let (lo, hi) = (b.min[i] as f64, b.max[i] as f64);
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((lo - o) / d, (hi - o) / d);
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        (near <= far).then_some(near as f32)
    }

    fn closest(accel: &Accel, boxes: &[Bounds3], ray: &Ray) -> Option<f32> {
        let mut best = None;
        accel.intersect(ray, &mut RayStats::default(), |i, t_max| match exact_entry(
            &boxes[i as usize],
            &Ray {
                t_max: *t_max,
                ..*ray
            },
        ) {
            Some(t) if t < *t_max => {
                *t_max = t;
                best = Some(t);
                true
            }
            _ => false,
        });
        best
    }

    /// Closest and any hits equal the brute-force list's, for random boxes including
    /// empty and flat ones, rays from inside and outside, and rays along the axes.
    #[test]
    fn matches_brute_force() {
        for &n in &[1usize, 2, 3, 5, 17, 1000, 20000] {
            let mut boxes = random_boxes(n, n as u64 + 7);
            if n > 5 {
                boxes[1] = Bounds3::EMPTY;
                boxes[2].max.y = boxes[2].min.y; // flat
            }
            let wide = Accel::Bvh4(Bvh4::build(&boxes, &BuildSettings::default()));
            let list = Accel::List(ListAccel::new(&boxes));
            let mut rng = Pcg32::new(99, 3);
            for i in 0..2000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0
                    - Vec3::splat(2.0);
                let mut d = Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                );
                if i % 5 == 0 {
                    // Parallel to two axes.
                    d = [Vec3::X, Vec3::NEG_Y, Vec3::Z][i % 3];
                }
                let ray = Ray::new(o, d);
                let a = closest(&wide, &boxes, &ray);
                let b = closest(&list, &boxes, &ray);
                assert_eq!(a, b, "n = {n}, ray {i}");
                let occ = wide.occluded(&ray, &mut RayStats::default(), |k| {
                    exact_entry(&boxes[k as usize], &ray).is_some()
                });
                assert_eq!(occ, b.is_some(), "n = {n}, ray {i}");
            }
        }
    }

    #[test]
    fn every_primitive_is_reachable_once() {
        let boxes = random_boxes(5000, 3);
        let wide = Bvh4::build(&boxes, &BuildSettings::default());
        let mut seen = vec![0u32; boxes.len()];
        let mut stack = vec![(wide.root.0, wide.root.1)];
        while let Some((child, count)) = stack.pop() {
            if count > 0 {
                for &p in &wide.prim_indices[child as usize..(child + count) as usize] {
                    seen[p as usize] += 1;
                }
                continue;
            }
            let node = &wide.nodes[child as usize];
            for k in 0..4 {
                if node.count[k] != EMPTY {
                    stack.push((node.child[k], node.count[k]));
                }
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
        // Wide nodes are well filled: far fewer nodes than the binary tree's inner nodes.
        let binary = Bvh::build(&boxes, &BuildSettings::default());
        let inner = binary.nodes.iter().filter(|n| !n.is_leaf()).count();
        assert!(
            wide.nodes.len() * 2 < inner,
            "{} vs {inner}",
            wide.nodes.len()
        );
    }
}
