//! Acceleration structures over boxes and primitive indices.
//!
//! An accelerator never knows what a primitive is: it is built from one bounding box per
//! primitive, and its queries take a closure that intersects primitive `i`. For the
//! closest hit, the closure gets the current `t_max` by reference and shrinks it when it
//! finds a closer hit; for the any-hit (shadow) query it answers whether primitive `i`
//! blocks the ray, and traversal stops at the first `true`.

pub mod bsp;
pub mod bvh;
mod bvh8;
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
mod bvh8_packet;
mod bvh_build;
mod collapse;
mod cover;
pub mod grid;
pub mod kdtree;
mod list;
mod memory;
pub mod octree;
#[cfg(test)]
pub(crate) mod testing;
mod wide_bvh;

pub use bsp::{Bsp, BspNode};
pub use bvh::{Bvh, BvhNode, BvhStats};
pub use bvh8::{Bvh8, Bvh8Node, STREAM_GROUP};
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
pub use bvh8_packet::{PacketLanes, PACKET};
pub use grid::Grid;
pub use kdtree::{KdNode, KdTree};
pub use list::ListAccel;
pub(crate) use memory::collect_huge;
pub use octree::{Octree, OctreeNode};
pub use wide_bvh::{Bvh4, Bvh4Node};

use crate::math::{Bounds3, Ray};

/// Per-ray traversal counters, drawn by the `bvh` AOV.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RayStats {
    /// Nodes entered (their box was hit within the ray's current range).
    pub nodes_visited: u32,
    /// Primitives handed to the intersection closure.
    pub prims_tested: u32,
    /// Rays traced through the scene (closest-hit and shadow rays).
    pub rays: u32,
    /// Of those, shadow (any-hit) rays.
    pub shadow_rays: u32,
}

/// Which accelerator to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AccelKind {
    /// Brute force over all primitives: the correctness oracle.
    List,
    /// Binary BVH with a binned SAH build.
    Bvh2,
    /// The lightwave course's binary BVH (binned SAH, leaves of at most two primitives, no
    /// SAH termination): the tree whose statistics the course's `bvh` views show.
    BvhCourse,
    /// The binary SAH tree collapsed into 4-wide nodes tested with SIMD.
    Bvh4,
    /// `Bvh2` built with `BuildSettings::HIGH` (slower build, lower SAH cost).
    Bvh2High,
    /// `Bvh4` collapsed from a `BuildSettings::HIGH` tree.
    Bvh4High,
    /// The binary SAH tree collapsed into 8-wide nodes tested with AVX2: the fastest,
    /// and the default.
    #[default]
    Bvh8,
    /// `Bvh8` collapsed from a `BuildSettings::HIGH` tree.
    Bvh8High,
    /// Uniform grid traversed by 3D-DDA, with per-ray mailboxing.
    Grid,
    /// Octree split at node centres, traversed front to back.
    Octree,
    /// kd-tree with pbrt-v3's SAH build.
    KdTree,
    /// BSP tree whose split planes may have any orientation.
    Bsp,
}

impl AccelKind {
    pub const NAMES: &'static [&'static str] = &[
        "list",
        "bvh2",
        "bvh",
        "bvh4",
        "bvh8",
        "bvh2-hq",
        "bvh4-hq",
        "bvh8-hq",
        "bvh-course",
        "grid",
        "octree",
        "kdtree",
        "bsp",
    ];

    pub fn from_name(name: &str) -> Option<AccelKind> {
        match name {
            "list" => Some(AccelKind::List),
            "bvh" | "bvh2" => Some(AccelKind::Bvh2),
            "bvh-course" => Some(AccelKind::BvhCourse),
            "bvh4" => Some(AccelKind::Bvh4),
            "bvh8" => Some(AccelKind::Bvh8),
            "bvh2-hq" => Some(AccelKind::Bvh2High),
            "bvh4-hq" => Some(AccelKind::Bvh4High),
            "bvh8-hq" => Some(AccelKind::Bvh8High),
            "grid" => Some(AccelKind::Grid),
            "octree" => Some(AccelKind::Octree),
            "kdtree" => Some(AccelKind::KdTree),
            "bsp" => Some(AccelKind::Bsp),
            _ => None,
        }
    }
}

/// An accelerator of any kind.
#[derive(Debug, Clone)]
pub enum Accel {
    List(ListAccel),
    Bvh(Bvh),
    Bvh4(Bvh4),
    Bvh8(Bvh8),
    Grid(Grid),
    Octree(Octree),
    KdTree(KdTree),
    Bsp(Bsp),
}

/// Runs `f` on a thread of rayon's pool (at once where the caller is one) and waits for
/// it. A build makes dozens of parallel calls (the boxes, the binning and partitioning
/// at the top of the tree, the collapse, the leaves' blocks); each made from a thread
/// outside the pool hands its work to the pool and sleeps until it is done, and on a
/// virtual machine the wake-ups on both sides cost tens of microseconds each. Made from
/// inside the pool they cost nothing: the Stanford bunny's mesh and BVH build 21.3 -> 18.9
/// ms on one thread and 11.0 -> 10.3 ms on two (`lightpath bench`, medians of 40).
pub(crate) fn in_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

impl Accel {
    /// Builds an accelerator of `kind` over the primitive boxes, on rayon's pool: even
    /// a serial build is started from inside the pool, where the parallel builders'
    /// tasks are handed out without waking threads from outside it.
    pub fn build(kind: AccelKind, bounds: &[Bounds3]) -> Accel {
        in_pool(|| match kind {
            AccelKind::List => Accel::List(ListAccel::new(bounds)),
            AccelKind::Grid => Accel::Grid(Grid::build(bounds)),
            AccelKind::Octree => Accel::Octree(Octree::build(bounds)),
            AccelKind::KdTree => Accel::KdTree(KdTree::build(bounds)),
            AccelKind::Bsp => Accel::Bsp(Bsp::build(bounds)),
            _ => Accel::build_from(kind, bounds.len(), |i| bounds[i]),
        })
    }

    /// [`Accel::build`] over `n` boxes that `box_of` gives by index: the BVHs make their
    /// primitive references straight from it, in the pass that finds their range, with
    /// no array of boxes in between (24 bytes a primitive, which a 1.1M-triangle mesh
    /// otherwise writes, faults in and reads back once); the others collect the boxes.
    pub fn build_from(
        kind: AccelKind,
        n: usize,
        box_of: impl Fn(usize) -> Bounds3 + Sync + Send,
    ) -> Accel {
        use bvh::BuildSettings as S;
        in_pool(|| match kind {
            AccelKind::Bvh2 => Accel::Bvh(Bvh::build_from(n, box_of, &S::default())),
            AccelKind::BvhCourse => Accel::Bvh(Bvh::build_from(n, box_of, &S::COURSE)),
            AccelKind::Bvh4 => Accel::Bvh4(Bvh4::build_from(n, box_of, &S::default())),
            AccelKind::Bvh8 => Accel::Bvh8(Bvh8::build_from(n, box_of, &S::default())),
            AccelKind::Bvh2High => Accel::Bvh(Bvh::build_from(n, box_of, &S::HIGH)),
            AccelKind::Bvh4High => Accel::Bvh4(Bvh4::build_from(n, box_of, &S::HIGH)),
            AccelKind::Bvh8High => Accel::Bvh8(Bvh8::build_from(n, box_of, &S::HIGH)),
            other => {
                use rayon::prelude::*;
                let boxes: Vec<Bounds3> = (0..n).into_par_iter().map(box_of).collect();
                Accel::build(other, &boxes)
            }
        })
    }

    /// Bounds of everything.
    pub fn bounds(&self) -> Bounds3 {
        match self {
            Accel::List(a) => a.bounds(),
            Accel::Bvh(a) => a.bounds(),
            Accel::Bvh4(a) => a.bounds(),
            Accel::Bvh8(a) => a.bounds(),
            Accel::Grid(a) => a.bounds(),
            Accel::Octree(a) => a.bounds(),
            Accel::KdTree(a) => a.bounds(),
            Accel::Bsp(a) => a.bounds(),
        }
    }

    /// Closest hit: `hit(prim, &mut t_max)` returns true when it found a closer hit and
    /// lowered `t_max`. Returns whether anything was hit.
    #[inline]
    pub fn intersect<F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        hit: F,
    ) -> bool {
        match self {
            Accel::List(a) => a.intersect(ray, stats, hit),
            Accel::Bvh(a) => a.intersect(ray, stats, hit),
            Accel::Bvh4(a) => a.intersect(ray, stats, hit),
            Accel::Bvh8(a) => a.intersect(ray, stats, hit),
            Accel::Grid(a) => a.intersect(ray, stats, hit),
            Accel::Octree(a) => a.walk_intersect(ray, stats, hit),
            Accel::KdTree(a) => a.walk_intersect(ray, stats, hit),
            Accel::Bsp(a) => a.walk_intersect(ray, stats, hit),
        }
    }

    /// Any hit: stops at the first primitive for which `blocks(prim)` is true.
    #[inline]
    pub fn occluded<F: FnMut(u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        blocks: F,
    ) -> bool {
        match self {
            Accel::List(a) => a.occluded(ray, stats, blocks),
            Accel::Bvh(a) => a.occluded(ray, stats, blocks),
            Accel::Bvh4(a) => a.occluded(ray, stats, blocks),
            Accel::Bvh8(a) => a.occluded(ray, stats, blocks),
            Accel::Grid(a) => a.occluded(ray, stats, blocks),
            Accel::Octree(a) => a.walk_occluded(ray, stats, blocks),
            Accel::KdTree(a) => a.walk_occluded(ray, stats, blocks),
            Accel::Bsp(a) => a.walk_occluded(ray, stats, blocks),
        }
    }

    /// For accelerators that hand out whole leaves (the wide BVHs), the primitive at
    /// every leaf position: leaves start at multiples of 4 and are padded to a multiple
    /// of 4 by repeating their last primitive. See [`Bvh4::intersect_leaves`].
    pub fn leaf_order(&self) -> Option<&[u32]> {
        match self {
            Accel::Bvh4(a) => Some(a.prim_order()),
            Accel::Bvh8(a) => Some(a.prim_order()),
            _ => None,
        }
    }

    /// Closest hit by whole leaves (`leaf(first, count, &mut t_max)` over positions of
    /// [`Accel::leaf_order`]); only for accelerators that have a leaf order.
    #[inline]
    /// `prefetch_leaf(first)` may be called for leaves that will be visited later, so
    /// that their primitive data can start loading.
    pub fn intersect_leaves<P: Fn(u32), F: FnMut(u32, u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        prefetch_leaf: P,
        leaf: F,
    ) -> bool {
        match self {
            Accel::Bvh4(a) => a.intersect_leaves(ray, stats, leaf),
            Accel::Bvh8(a) => a.intersect_leaves(ray, stats, prefetch_leaf, leaf),
            _ => unreachable!("intersect_leaves on an accelerator without a leaf order"),
        }
    }

    /// Any hit by whole leaves; only for accelerators that have a leaf order.
    #[inline]
    pub fn occluded_leaves<P: Fn(u32), F: FnMut(u32, u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        prefetch_leaf: P,
        blocks: F,
    ) -> bool {
        match self {
            Accel::Bvh4(a) => a.occluded_leaves(ray, stats, blocks),
            Accel::Bvh8(a) => a.occluded_leaves(ray, stats, prefetch_leaf, blocks),
            _ => unreachable!("occluded_leaves on an accelerator without a leaf order"),
        }
    }

    /// Bytes used by the structure (nodes and index arrays).
    pub fn memory_bytes(&self) -> usize {
        match self {
            Accel::List(a) => a.memory_bytes(),
            Accel::Bvh(a) => a.memory_bytes(),
            Accel::Bvh4(a) => a.memory_bytes(),
            Accel::Bvh8(a) => a.memory_bytes(),
            Accel::Grid(a) => a.memory_bytes(),
            Accel::Octree(a) => a.memory_bytes(),
            Accel::KdTree(a) => a.memory_bytes(),
            Accel::Bsp(a) => a.memory_bytes(),
        }
    }

    /// The cost that the wide BVHs' collapse minimises (node and leaf tests weighted by
    /// the surface areas of their boxes, relative to the root's); `None` for the rest.
    pub fn collapse_cost(&self) -> Option<f32> {
        match self {
            Accel::Bvh4(a) => Some(a.collapse_cost),
            Accel::Bvh8(a) => Some(a.collapse_cost),
            _ => None,
        }
    }

    /// Seconds the build took (0 for the list, which has no build).
    pub fn build_seconds(&self) -> f64 {
        match self {
            Accel::List(_) => 0.0,
            Accel::Bvh(a) => a.stats.build_seconds,
            Accel::Bvh4(a) => a.build_seconds,
            Accel::Bvh8(a) => a.build_seconds,
            Accel::Grid(a) => a.build_seconds,
            Accel::Octree(a) => a.build_seconds,
            Accel::KdTree(a) => a.build_seconds,
            Accel::Bsp(a) => a.build_seconds,
        }
    }

    /// A few boxes (at most about `max_boxes`) whose union covers everything, each much
    /// tighter than the overall box: the top of the tree. Transforming these and taking
    /// their union gives a tight box for a rotated instance.
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        match self {
            Accel::List(a) => a.cover(max_boxes),
            Accel::Bvh(a) => a.cover(max_boxes),
            Accel::Bvh4(a) => a.cover(max_boxes),
            Accel::Bvh8(a) => a.cover(max_boxes),
            Accel::Grid(a) => a.cover(max_boxes),
            Accel::Octree(a) => a.cover(max_boxes),
            Accel::KdTree(a) => a.cover(max_boxes),
            Accel::Bsp(a) => a.cover(max_boxes),
        }
    }
}

/// A structure traversed as a walk over cells in ray order (kd-tree, BSP, octree):
/// `walk` hands each cell's primitives to `leaf`, which returns the distance past which
/// the walk may stop.
pub(crate) trait CellWalk {
    fn walk(&self, ray: &Ray, stats: &mut RayStats, leaf: impl FnMut(&[u32], &mut RayStats) -> f32);

    /// Closest hit: every cell's primitives until a hit lies before the next cell.
    #[inline]
    fn walk_intersect<F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut hit: F,
    ) -> bool {
        let mut t_max = ray.t_max;
        let mut any = false;
        self.walk(ray, stats, |prims, stats| {
            for &p in prims {
                stats.prims_tested += 1;
                any |= hit(p, &mut t_max);
            }
            widen(t_max)
        });
        any
    }

    /// Any hit: stops at the first blocking primitive.
    #[inline]
    fn walk_occluded<F: FnMut(u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut blocks: F,
    ) -> bool {
        let mut blocked = false;
        self.walk(ray, stats, |prims, stats| {
            for &p in prims {
                stats.prims_tested += 1;
                if blocks(p) {
                    blocked = true;
                    return f32::NEG_INFINITY;
                }
            }
            f32::INFINITY
        });
        blocked
    }
}

/// Widens a ray distance by a relative 1e-5 (and a tiny absolute amount), so that
/// rounding in the distances to cell boundaries and split planes never ends a traversal
/// before a hit that lies just beyond a boundary: the grid, octree, kd-tree and BSP
/// tree still enter a cell whose entry distance is at most `widen(t_max)`.
#[inline(always)]
pub(crate) fn widen(t: f32) -> f32 {
    t + t.abs() * 1e-5 + f32::MIN_POSITIVE
}

/// The ray's segment inside `b`: `[entry, exit]` clipped to `[t_min, t_max]`, the exit
/// widened by `1 + 2γ(3)` against rounding (pbrt's rule). Unlike a plain slab test, a
/// zero direction component is decided by whether the origin lies in that slab, faces
/// included, rather than by `0 · ∞`, so a ray running exactly along a face of the box
/// still enters it.
#[inline(always)]
pub(crate) fn clip_ray(b: &Bounds3, ray: &Ray, inv_dir: glam::Vec3) -> Option<(f32, f32)> {
    if b.is_empty() {
        return None;
    }
    let (mut t0, mut t1) = (ray.t_min, ray.t_max);
    for a in 0..3 {
        let o = ray.origin[a];
        if ray.direction[a] == 0.0 {
            if o < b.min[a] || o > b.max[a] {
                return None;
            }
            continue;
        }
        let near = (b.min[a] - o) * inv_dir[a];
        let far = (b.max[a] - o) * inv_dir[a];
        let (near, far) = if near <= far {
            (near, far)
        } else {
            (far, near)
        };
        t0 = t0.max(near);
        t1 = t1.min(far * (1.0 + 2.0 * crate::math::gamma(3)));
    }
    (t0 <= t1).then_some((t0, t1))
}
