//! An 8-wide BVH: the binary SAH tree collapsed so that every node holds up to eight
//! children whose boxes are tested against a ray at once, with AVX2 (detected at run
//! time) or, elsewhere, as two 4-lane halves. Selected with `--accel bvh8`; the default.
//!
//! ```xml
//! <instance>
//!     <shape type="mesh" filename="bunny.ply"/>   <!-- lightpath render --accel bvh8 -->
//! </instance>
//! ```
//!
//! Node layout ([`Bvh8Node`], 256 bytes, four cache lines): the six box planes of the
//! eight children (`planes[0..3]` the minima in x, y, z, `planes[3..6]` the maxima),
//! then per child a `u32` reference (an inner node's index, or a leaf's first position)
//! and a `u32` count (0 for an inner node, else the number of primitives; `u32::MAX` for
//! an unused slot). Leaves are laid out for blocks of four primitives
//! (the `collapse` module), so a triangle mesh tests each leaf with SIMD.
//!
//! Traversal, per ray: the near and far plane of each axis are chosen once from the
//! signs of the direction, so a node test is a subtraction and a multiplication per
//! plane, then maxima and minima reduced as two-level trees, on the distances' bits as
//! integers, which takes a cycle per step where float operations take four (see
//! [`NodeTest`]); unused
//! slots hold empty boxes that no ray enters. The nearest hit child is visited next without
//! touching the stack; with two hits the farther one is pushed; with more, they are
//! pushed sorted, nearest on top. Entry distances stay on the stack and entries farther
//! than the current hit are culled when popped. Pushed inner nodes are prefetched.
//! The any-hit traversal (shadow rays) visits the hit children in slot order, depth
//! first, with no distances: the lowest slot next, the others pushed by one permuted
//! eight-lane store ([`NodeTest::push_hits`]) rather than a loop over the mask's bits,
//! and each entry it pops prefetches the one below it, the next to be visited.
//! Rays with a zero (or subnormal) direction component, a negative `t_min` or a
//! non-finite origin take a general variant of the node test, in floats, in which a ray
//! lying in a slab's plane (0·∞ = NaN) is inside that slab. There is no separate test
//! of the root's own box: a ray that misses it misses all the root's children, which
//! costs one node test.
//!
//! Streams ([`Bvh8::intersect_stream`], [`Bvh8::occluded_stream`]): a ray that wanders
//! over a mesh larger than the caches waits at almost every node for memory, and the
//! next node's address depends on the data it waits for, so one ray cannot overlap its
//! own misses. The stream traversals keep [`STREAM_GROUP`] rays in flight: each takes
//! one step (a node test or a leaf), prefetches the node or leaf it goes to next and
//! hands over to the next ray, so that the misses of the group overlap. Each ray visits
//! the same nodes and leaves in the same order as it would alone, so the answers are
//! the single-ray ones; the price is the state saved and restored at every step, which
//! makes streams slower where the data is in cache (coherent rays, small meshes).

use super::bvh::{BuildSettings, Bvh};
use super::collapse::{any_prim, build_binary, collapse, each_prim, wide_cover, EMPTY};
use super::RayStats;
use crate::math::{Bounds3, Ray};
use glam::{Vec3, Vec4};
use std::mem::MaybeUninit;

/// Eight children's boxes and references; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub struct Bvh8Node {
    pub planes: [[f32; 8]; 6],
    pub child: [u32; 8],
    pub count: [u32; 8],
}

const _: () = assert!(std::mem::size_of::<Bvh8Node>() == 256);

/// Unused slots keep an empty box (see [`NodeTest`]).
const EMPTY_NODE: Bvh8Node = Bvh8Node {
    planes: [
        [f32::INFINITY; 8],
        [f32::INFINITY; 8],
        [f32::INFINITY; 8],
        [f32::NEG_INFINITY; 8],
        [f32::NEG_INFINITY; 8],
        [f32::NEG_INFINITY; 8],
    ],
    child: [0; 8],
    count: [EMPTY; 8],
};

/// Widening of the far slab distance (as in the binary BVH, pbrt's `1 + 2γ(3)`).
pub(super) const ROBUST_FAR: f32 =
    1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Stack depth: each level pushes at most seven siblings.
const STACK_SIZE: usize = 7 * 128 + 8;

/// A stack entry: a child slot (inner node or leaf range) and its entry distance.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    count: u32,
    dist: f32,
}

/// A node test's eight entry distances, aligned to 32 bytes so that the test's one
/// vector store of them never spans two cache lines: the descent reads them back one at
/// a time, and a load from a store split over two lines waits for the store to complete
/// instead of taking its data forwarded. As a plain array its place on the stack was
/// left to chance, and a build that happened to put it across a line ran the bunny's
/// closest-hit sets 1-4% slower.
#[derive(Clone, Copy)]
#[repr(C, align(32))]
struct Near([f32; 8]);

impl std::ops::Deref for Near {
    type Target = [f32; 8];
    #[inline(always)]
    fn deref(&self) -> &[f32; 8] {
        &self.0
    }
}

impl std::ops::DerefMut for Near {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut [f32; 8] {
        &mut self.0
    }
}

/// What a node test needs of a ray.
struct RayLanes {
    origin: [f32; 3],
    inv: [f32; 3],
    /// `inv` widened by [`ROBUST_FAR`], for the far planes: scaling the reciprocal once
    /// per ray keeps the widening off each node test's dependency chain. The extra
    /// rounding of the product is covered: `(1 - 3u)(1 - u)(1 + 6u) > 1` for the unit
    /// roundoff `u`, so the far distance still bounds the exact one.
    inv_far: [f32; 3],
    /// Index into `planes` of the near and far plane of each axis.
    near: [usize; 3],
    far: [usize; 3],
}

impl RayLanes {
    #[inline(always)]
    fn new(ray: &Ray) -> RayLanes {
        let inv = ray.direction.recip();
        let near = [0, 1, 2].map(|a| if inv[a] >= 0.0 { a } else { a + 3 });
        RayLanes {
            origin: ray.origin.to_array(),
            inv: inv.to_array(),
            inv_far: (inv * ROBUST_FAR).to_array(),
            near,
            far: near.map(|p| if p < 3 { p + 3 } else { p - 3 }),
        }
    }
}

/// Whether `ray` takes the general node test (see [`NodeTest`]): unless every direction
/// component is finite and at least the smallest normal float (so that its reciprocal
/// is finite and not zero, and no plane distance is NaN: a zero component gives `0·∞`
/// for a ray in a slab's plane), `t_min` is a non-negative float other than `-0` and
/// the origin is finite.
///
/// Each condition is a range of the float's bits, and all seven are combined without a
/// branch: every ray pays for this test before its first node, and most rays that miss
/// the mesh pay for little else.
#[inline(always)]
fn needs_general_test(ray: &Ray) -> bool {
    let abs = |x: f32| x.to_bits() & 0x7fff_ffff;
    // Finite and at least `MIN_POSITIVE` in magnitude (NaN fails).
    let normal = |x: f32| abs(x).wrapping_sub(0x0080_0000) < 0x7f80_0000 - 0x0080_0000;
    // Finite (NaN fails).
    let finite = |x: f32| abs(x) < 0x7f80_0000;
    let (d, o) = (ray.direction, ray.origin);
    // `+0` up to `+∞`: neither negative, `-0` nor NaN.
    let t_min_ok = ray.t_min.to_bits() <= 0x7f80_0000;
    let ok = normal(d.x)
        & normal(d.y)
        & normal(d.z)
        & finite(o.x)
        & finite(o.y)
        & finite(o.z)
        & t_min_ok;
    !ok
}

/// A node test: writes the entry distances of the eight children and returns the bit
/// mask of those whose box the ray enters within `[t_min, t_max]`.
///
/// The entry distance is the maximum of the three near-plane distances and `t_min`, the
/// exit distance the minimum of the three (widened) far-plane distances and the widened
/// `t_max`, each reduced as a tree of two levels rather than a chain of three, which
/// shortens the latency of a node test. Unused slots have empty boxes (minima `+∞`,
/// maxima `-∞`), whose entry is `+∞` and exit `-∞` for any ray with a finite, non-zero
/// direction component, so the plain test needs no separate mask for them; the
/// general variant (`GENERAL`), which orders each axis's two distances, masks them by
/// count.
///
/// The plain test reduces and compares the distances as the integers their bits are (a
/// cycle per operation where float minima and maxima take four, on the chain of
/// dependent operations that a ray's traversal waits on), as Embree does: for floats
/// that are not NaN, the integer order of the bits is the float order among
/// non-negative floats, puts every negative float below every non-negative one, and
/// reverses the order among negative ones. So where `t_min` is a non-negative float (not
/// `-0`), the integer maximum is exactly the float maximum whenever the float one is
/// non-negative, and is `t_min` itself otherwise (where the float maximum would be
/// `t_min` too); the entry is then non-negative and the comparison with the exit exact,
/// whatever the exit's sign (a negative exit, exact or not, is below it either way). The
/// general test takes the rays for which this does not hold, or whose distances can be
/// NaN, with float operations; see [`needs_general_test`].
trait NodeTest {
    /// The hit mask and the eight entry distances.
    fn test<const GENERAL: bool>(
        node: &Bvh8Node,
        ray: &RayLanes,
        t_min: f32,
        t_max: f32,
    ) -> (u32, Near);

    /// Pushes the children of `node` in `mask` onto the any-hit traversal's stacks at
    /// `sp`, the highest slot first, so that the lowest is on top (children are visited
    /// in slot order); returns the new `sp`. The stacks have room for eight entries past
    /// any `sp` a traversal reaches.
    #[inline(always)]
    fn push_hits(
        node: &Bvh8Node,
        mask: u32,
        children: &mut [MaybeUninit<u32>; ANY_STACK],
        counts: &mut [MaybeUninit<u32>; ANY_STACK],
        mut sp: usize,
    ) -> usize {
        let mut bits = mask;
        while bits != 0 {
            let j = 31 - bits.leading_zeros() as usize;
            bits &= !(1 << j);
            children[sp].write(node.child[j]);
            counts[sp].write(node.count[j]);
            sp += 1;
        }
        sp
    }
}

/// The any-hit stacks' size: [`STACK_SIZE`] and room for an eight-wide store at the top.
const ANY_STACK: usize = STACK_SIZE + 8;

/// For each hit mask of a node, its set slots from the highest down (then zeros): the
/// permutation that packs the hit children of [`NodeTest::push_hits`].
#[cfg(target_arch = "x86_64")]
static PUSH_ORDER: [[u8; 8]; 256] = {
    let mut table = [[0u8; 8]; 256];
    let mut mask = 0;
    while mask < 256 {
        let mut n = 0;
        let mut slot = 8;
        while slot > 0 {
            slot -= 1;
            if mask & (1 << slot) != 0 {
                table[mask][n] = slot as u8;
                n += 1;
            }
        }
        mask += 1;
    }
    table
};

/// Two 4-lane halves (SSE on x86-64, a portable fallback elsewhere).
struct Portable;

impl NodeTest for Portable {
    #[inline(always)]
    fn test<const GENERAL: bool>(
        node: &Bvh8Node,
        ray: &RayLanes,
        t_min: f32,
        t_max: f32,
    ) -> (u32, Near) {
        let mut near = Near([0.0; 8]);
        let mut mask = 0;
        for half in 0..2 {
            let lanes = |p: usize| Vec4::from_slice(&node.planes[p][4 * half..4 * half + 4]);
            let (mut t0, mut t1) = ([Vec4::ZERO; 3], [Vec4::ZERO; 3]);
            for a in 0..3 {
                let o = Vec4::splat(ray.origin[a]);
                let n = (lanes(ray.near[a]) - o) * Vec4::splat(ray.inv[a]);
                let f = (lanes(ray.far[a]) - o) * Vec4::splat(ray.inv_far[a]);
                if GENERAL {
                    let on_face = n.is_nan_mask() | f.is_nan_mask();
                    t0[a] = Vec4::select(on_face, Vec4::NEG_INFINITY, n.min(f));
                    t1[a] = Vec4::select(on_face, Vec4::INFINITY, n.max(f));
                } else {
                    (t0[a], t1[a]) = (n, f);
                }
            }
            let t_far = t_max * ROBUST_FAR;
            if !GENERAL {
                // On the floats' bits as integers, as the AVX2 test.
                let bits = |v: Vec4| v.to_array().map(|x| x.to_bits() as i32);
                let (n, f) = (t0.map(bits), t1.map(bits));
                for k in 0..4 {
                    let lo = n[0][k]
                        .max(n[1][k])
                        .max(n[2][k].max(t_min.to_bits() as i32));
                    let hi = f[0][k]
                        .min(f[1][k])
                        .min(f[2][k].min(t_far.to_bits() as i32));
                    near[4 * half + k] = f32::from_bits(lo as u32);
                    mask |= u32::from(lo <= hi) << (4 * half + k);
                }
                continue;
            }
            let lo = t0[0].max(t0[1]).max(t0[2].max(Vec4::splat(t_min)));
            let hi = t1[0].min(t1[1]).min(t1[2].min(Vec4::splat(t_far)));
            let hit = lo.cmple(hi).bitmask();
            lo.write_to_slice(&mut near[4 * half..4 * half + 4]);
            mask |= hit << (4 * half);
        }
        if GENERAL {
            for (k, &c) in node.count.iter().enumerate() {
                if c == EMPTY {
                    mask &= !(1 << k);
                }
            }
        }
        (mask, near)
    }
}

/// AVX2, when the processor has it.
#[cfg(target_arch = "x86_64")]
struct Avx2;

#[cfg(target_arch = "x86_64")]
impl NodeTest for Avx2 {
    #[inline(always)]
    fn test<const GENERAL: bool>(
        node: &Bvh8Node,
        ray: &RayLanes,
        t_min: f32,
        t_max: f32,
    ) -> (u32, Near) {
        // SAFETY: `Avx2` is only used by traversals entered after detecting the AVX2
        // tier (`crate::cpu`).
        unsafe { avx2_test::<GENERAL>(node, ray, t_min, t_max) }
    }

    /// One permutation ([`PUSH_ORDER`]) and one eight-lane store per array, however
    /// many children there are: a loop over the mask's bits runs a number of turns
    /// that a branch predictor cannot guess for incoherent rays.
    #[inline(always)]
    fn push_hits(
        node: &Bvh8Node,
        mask: u32,
        children: &mut [MaybeUninit<u32>; ANY_STACK],
        counts: &mut [MaybeUninit<u32>; ANY_STACK],
        sp: usize,
    ) -> usize {
        assert!(sp + 8 <= ANY_STACK, "any-hit stack overflow");
        // SAFETY: `Avx2` is only used by traversals entered after detecting the AVX2
        // tier (`crate::cpu`), and the stores at `sp` are in bounds (asserted above).
        unsafe { avx2_push(node, mask, children, counts, sp) };
        sp + mask.count_ones() as usize
    }
}

/// [`Avx2`]'s `push_hits`: the permuted stores.
///
/// # Safety
/// The processor must have the AVX2 tier (`crate::cpu`), and `sp + 8 <= ANY_STACK`.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn avx2_push(
    node: &Bvh8Node,
    mask: u32,
    children: &mut [MaybeUninit<u32>; ANY_STACK],
    counts: &mut [MaybeUninit<u32>; ANY_STACK],
    sp: usize,
) {
    use std::arch::x86_64::*;
    let order = &PUSH_ORDER[mask as usize & 0xff];
    // SAFETY: the loads read the table's eight bytes and a node's eight-lane arrays; the
    // caller guarantees room for the eight-lane stores at `sp`.
    unsafe {
        let perm = _mm256_cvtepu8_epi32(_mm_loadl_epi64(order.as_ptr() as *const __m128i));
        let child = _mm256_loadu_si256(node.child.as_ptr() as *const __m256i);
        let count = _mm256_loadu_si256(node.count.as_ptr() as *const __m256i);
        _mm256_storeu_si256(
            children.as_mut_ptr().add(sp) as *mut __m256i,
            _mm256_permutevar8x32_epi32(child, perm),
        );
        _mm256_storeu_si256(
            counts.as_mut_ptr().add(sp) as *mut __m256i,
            _mm256_permutevar8x32_epi32(count, perm),
        );
    }
}

#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn avx2_test<const GENERAL: bool>(
    node: &Bvh8Node,
    ray: &RayLanes,
    t_min: f32,
    t_max: f32,
) -> (u32, Near) {
    use std::arch::x86_64::*;
    let planes = node.planes.as_ptr() as *const f32;
    let mut t0 = [_mm256_setzero_ps(); 3];
    let mut t1 = [_mm256_setzero_ps(); 3];
    for a in 0..3 {
        let o = _mm256_set1_ps(ray.origin[a]);
        // SAFETY: the plane indices are below 6, and nodes are 64-byte aligned, so
        // each plane is an aligned 32-byte load inside the node.
        let (pn, pf) = unsafe {
            (
                _mm256_load_ps(planes.add(8 * ray.near[a])),
                _mm256_load_ps(planes.add(8 * ray.far[a])),
            )
        };
        let n = _mm256_mul_ps(_mm256_sub_ps(pn, o), _mm256_set1_ps(ray.inv[a]));
        let f = _mm256_mul_ps(_mm256_sub_ps(pf, o), _mm256_set1_ps(ray.inv_far[a]));
        if GENERAL {
            let on_face = _mm256_or_ps(
                _mm256_cmp_ps::<_CMP_UNORD_Q>(n, n),
                _mm256_cmp_ps::<_CMP_UNORD_Q>(f, f),
            );
            t0[a] = _mm256_blendv_ps(
                _mm256_min_ps(n, f),
                _mm256_set1_ps(f32::NEG_INFINITY),
                on_face,
            );
            t1[a] = _mm256_blendv_ps(_mm256_max_ps(n, f), _mm256_set1_ps(f32::INFINITY), on_face);
        } else {
            (t0[a], t1[a]) = (n, f);
        }
    }
    if GENERAL {
        let lo = _mm256_max_ps(
            _mm256_max_ps(t0[0], t0[1]),
            _mm256_max_ps(t0[2], _mm256_set1_ps(t_min)),
        );
        let hi = _mm256_min_ps(
            _mm256_min_ps(t1[0], t1[1]),
            _mm256_min_ps(t1[2], _mm256_set1_ps(t_max * ROBUST_FAR)),
        );
        let mut near = Near([0.0; 8]);
        // SAFETY: `near` holds eight floats.
        unsafe { _mm256_storeu_ps(near.as_mut_ptr(), lo) };
        let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(lo, hi)) as u32;
        // SAFETY: `count` is 32 bytes at offset 224 of a 64-byte aligned node.
        let count = unsafe { _mm256_load_si256(node.count.as_ptr() as *const __m256i) };
        let unused = _mm256_cmpeq_epi32(count, _mm256_set1_epi32(-1));
        return (
            hit & !(_mm256_movemask_ps(_mm256_castsi256_ps(unused)) as u32),
            near,
        );
    }
    // The reductions and the comparison on the floats' bits as integers (see
    // `NodeTest`): one cycle each where the float operations take four.
    let bits = _mm256_castps_si256;
    let lo = _mm256_max_epi32(
        _mm256_max_epi32(bits(t0[0]), bits(t0[1])),
        _mm256_max_epi32(bits(t0[2]), _mm256_set1_epi32(t_min.to_bits() as i32)),
    );
    let hi = _mm256_min_epi32(
        _mm256_min_epi32(bits(t1[0]), bits(t1[1])),
        _mm256_min_epi32(
            bits(t1[2]),
            _mm256_set1_epi32((t_max * ROBUST_FAR).to_bits() as i32),
        ),
    );
    let mut near = Near([0.0; 8]);
    // SAFETY: `near` holds eight floats.
    unsafe { _mm256_storeu_ps(near.as_mut_ptr(), _mm256_castsi256_ps(lo)) };
    let miss = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(lo, hi))) as u32;
    (!miss & 0xff, near)
}

#[derive(Debug, Clone)]
pub struct Bvh8 {
    pub nodes: Vec<Bvh8Node>,
    prim_order: Vec<u32>,
    bounds: Bounds3,
    /// The root slot: an inner node (count 0) or, for tiny inputs, a leaf.
    pub(super) root: (u32, u32),
    /// Whether the processor has the AVX2 tier (`crate::cpu`; detected at build).
    avx2: bool,
    pub build_seconds: f64,
    /// The collapse's cost of the tree: node tests and leaf tests weighted by the
    /// surface areas of their boxes, relative to the root's (the `collapse` module).
    pub collapse_cost: f32,
}

impl Bvh8 {
    /// Builds the binary SAH tree, then collapses it.
    pub fn build(boxes: &[Bounds3], settings: &BuildSettings) -> Bvh8 {
        Bvh8::build_from(boxes.len(), |i| boxes[i], settings)
    }

    /// [`Bvh8::build`] over `n` boxes that `box_of` gives by index (called once each).
    pub fn build_from(
        n: usize,
        box_of: impl Fn(usize) -> Bounds3 + Sync,
        settings: &BuildSettings,
    ) -> Bvh8 {
        let (bvh, start) = build_binary(n, box_of, settings);
        let mut wide = Bvh8::collapse(&bvh);
        wide.build_seconds = start.elapsed().as_secs_f64();
        wide
    }

    /// Collapses a binary BVH into 8-wide nodes (the `collapse` module).
    pub fn collapse(bvh: &Bvh) -> Bvh8 {
        let tree = collapse::<8>(bvh);
        use rayon::prelude::*;
        let nodes = super::memory::collect_huge(tree.nodes.par_iter().map(|slots| {
            let mut n = EMPTY_NODE;
            for (k, s) in slots.iter().enumerate().filter(|(_, s)| s.count != EMPTY) {
                for a in 0..3 {
                    n.planes[a][k] = s.min[a];
                    n.planes[a + 3][k] = s.max[a];
                }
                n.child[k] = s.child;
                n.count[k] = s.count;
            }
            n
        }));
        Bvh8 {
            nodes,
            prim_order: tree.prim_order,
            bounds: bvh.bounds(),
            root: tree.root,
            avx2: crate::cpu::has_avx2(),
            build_seconds: 0.0,
            collapse_cost: tree.cost,
        }
    }

    /// Uses the portable node test even where AVX2 is available (for tests).
    #[cfg(test)]
    fn without_avx2(mut self) -> Bvh8 {
        self.avx2 = false;
        self
    }

    /// The primitive at every leaf position (see the `collapse` module); the positions
    /// that [`Bvh8::intersect_leaves`] hands out index it.
    pub fn prim_order(&self) -> &[u32] {
        &self.prim_order
    }

    /// Every leaf's `(first, count)`: its positions in [`Bvh8::prim_order`].
    #[cfg_attr(not(all(target_arch = "x86_64", lightpath_avx512)), allow(dead_code))]
    pub(crate) fn leaves(&self) -> Vec<(u32, u32)> {
        if self.prim_order.is_empty() {
            return Vec::new();
        }
        if self.root.1 > 0 {
            return vec![self.root];
        }
        let mut leaves = Vec::new();
        for node in &self.nodes {
            for (&child, &count) in node.child.iter().zip(&node.count) {
                if count != EMPTY && count > 0 {
                    leaves.push((child, count));
                }
            }
        }
        leaves
    }

    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }

    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice()) + self.prim_order.len() * 4
    }

    /// The boxes of the root's children (and theirs, while under `max_boxes`).
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        if self.prim_order.is_empty() {
            return Vec::new();
        }
        if self.nodes.is_empty() {
            return vec![self.bounds];
        }
        wide_cover(8, max_boxes, |n, k| {
            let node = &self.nodes[n];
            (node.count[k] != EMPTY).then(|| {
                let p = &node.planes;
                let b = Bounds3::new(
                    Vec3::new(p[0][k], p[1][k], p[2][k]),
                    Vec3::new(p[3][k], p[4][k], p[5][k]),
                );
                (b, node.child[k], node.count[k])
            })
        })
        .unwrap_or_else(|| vec![self.bounds])
    }

    /// Starts loading a pushed child: an inner node's cache lines, or through
    /// `prefetch_leaf` a leaf's primitive data, so that the misses of all the hit
    /// children overlap instead of coming one at a time when each is popped.
    #[inline(always)]
    fn prefetch(&self, child: u32, count: u32, prefetch_leaf: &impl Fn(u32)) {
        if count > 0 {
            prefetch_leaf(child);
            return;
        }
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let p = self.nodes.as_ptr().wrapping_add(child as usize) as *const i8;
            // SAFETY: prefetching is a hint and never faults, whatever the address.
            unsafe {
                for line in 0..4 {
                    _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line));
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = child;
    }

    /// Starts loading the cache line of `node`'s child references (its fourth) at the
    /// start of its test, so that a miss on it overlaps with the misses on the box
    /// planes. Without it, the line is requested only once the test has chosen a child,
    /// a second wait for memory, in series, at every node that was not prefetched when
    /// pushed (the nearest hit child, visited next without the stack, never is).
    #[inline(always)]
    fn prefetch_refs(node: &Bvh8Node) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: prefetching is a hint and never faults, whatever the address.
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(node.child.as_ptr() as *const i8);
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = node;
    }

    /// The closest-hit descent from a node whose children in `mask` (at least one) the
    /// ray enters at distances `near`: returns the nearest child and pushes the others
    /// sorted by decreasing distance, so that the next nearest is on top. Ties go to the
    /// lower slot. Of two children the nearer is selected by one comparison; three or
    /// four are sorted by a network of compare-exchanges on keys (a distance's
    /// [`order_bits`] above its slot); both compile to conditional moves: the order of
    /// the children of an incoherent ray is a coin toss that a branch predictor loses.
    /// Unless `GENERAL` (the plain node test's distances, never negative nor `-0`), the
    /// distances' bits order like them as they are.
    #[inline(always)]
    fn descend<const GENERAL: bool, P: Fn(u32)>(
        &self,
        node: &Bvh8Node,
        mask: u32,
        near: &Near,
        stack: &mut [MaybeUninit<Entry>],
        sp: &mut usize,
        prefetch_leaf: &P,
    ) -> Entry {
        // The entry of slot `k`.
        let entry = |k: u32| {
            let k = k as usize;
            Entry {
                child: node.child[k],
                count: node.count[k],
                dist: near[k],
            }
        };
        // The distance of slot `k` as an integer that orders like it.
        let ord = |k: u32| {
            let bits = near[k as usize].to_bits();
            if GENERAL {
                order_bits(bits)
            } else {
                bits
            }
        };
        let key = |k: u32| (u64::from(ord(k)) << 32) | u64::from(k);
        // The slot a key holds.
        let slot = |key: u64| key as u32 & 7;
        let a = key(mask.trailing_zeros());
        let rest = mask & (mask - 1);
        if rest == 0 {
            // One child: descend without the stack.
            return entry(slot(a));
        }
        // Two children (the most common case after one): the nearer (the next node,
        // which the traversal waits for) is selected by one comparison from both slots'
        // references, loaded while their distances are compared, as Embree does, rather
        // than loaded after the comparison by the winning slot, which would put a load
        // on that chain (2-5% faster on the bunny's closest-hit sets). The lower slot
        // wins a tie. With three or four, the same selection lost 1-2%.
        let kb = rest.trailing_zeros();
        let rest = rest & (rest - 1);
        if rest == 0 {
            let ka = mask.trailing_zeros();
            let (ea, eb) = (entry(ka), entry(kb));
            let (first, second) = nearer(ea, ord(ka), eb, ord(kb));
            push_entry(self, second, stack, sp, prefetch_leaf);
            return first;
        }
        let mut push = |key: u64| push_entry(self, entry(slot(key)), stack, sp, prefetch_leaf);
        let b = key(kb);
        let c = key(rest.trailing_zeros());
        let rest = rest & (rest - 1);
        if rest == 0 {
            let (a, b) = sort2(a, b);
            let (b, c) = sort2(b, c);
            let (a, b) = sort2(a, b);
            push(c);
            push(b);
            return entry(slot(a));
        }
        let d = key(rest.trailing_zeros());
        let rest = rest & (rest - 1);
        if rest == 0 {
            let (a, b) = sort2(a, b);
            let (c, d) = sort2(c, d);
            let (a, c) = sort2(a, c);
            let (b, d) = sort2(b, d);
            let (b, c) = sort2(b, c);
            push(d);
            push(c);
            push(b);
            return entry(slot(a));
        }
        // Five or more (rare): the keys sorted in a small array.
        let mut keys = [u64::MAX; 8];
        keys[..4].copy_from_slice(&[a, b, c, d]);
        let mut n = 4;
        let mut bits = rest;
        while bits != 0 {
            keys[n] = key(bits.trailing_zeros());
            bits &= bits - 1;
            n += 1;
        }
        keys[..n].sort_unstable();
        for &k in keys[1..n].iter().rev() {
            push(k);
        }
        entry(slot(keys[0]))
    }

    /// Closest hit, front to back (see [`crate::accel::Accel::intersect`]).
    #[inline]
    pub fn intersect<F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        hit: F,
    ) -> bool {
        self.intersect_leaves(ray, stats, |_| {}, each_prim(&self.prim_order, hit))
    }

    /// Any hit: returns at the first primitive that blocks the ray.
    #[inline]
    pub fn occluded<F: FnMut(u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        blocks: F,
    ) -> bool {
        self.occluded_leaves(ray, stats, |_| {}, any_prim(&self.prim_order, blocks))
    }

    /// Closest hit by whole leaves: `leaf(first, count, &mut t_max)` tests the
    /// primitives at positions `first..first + count` of [`Bvh8::prim_order`] (`first`
    /// is a multiple of 4, and the padding up to the next multiple repeats the leaf's
    /// last primitive), lowers `t_max` for a closer hit and returns whether it found
    /// one.
    #[inline]
    pub fn intersect_leaves<P: Fn(u32), F: FnMut(u32, u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        prefetch_leaf: P,
        leaf: F,
    ) -> bool {
        if self.prim_order.is_empty() {
            return false;
        }
        self.intersect_leaves_from(ray, self.root, stats, prefetch_leaf, leaf)
    }

    /// [`Bvh8::intersect_leaves`] in the subtree of slot `start` (an inner node's index
    /// and count 0, or a leaf) only.
    #[inline]
    pub(crate) fn intersect_leaves_from<P: Fn(u32), F: FnMut(u32, u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        start: (u32, u32),
        stats: &mut RayStats,
        prefetch_leaf: P,
        leaf: F,
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the AVX2 tier was detected when the tree was built.
            return unsafe { self.intersect_avx2(ray, start, stats, prefetch_leaf, leaf) };
        }
        if needs_general_test(ray) {
            self.intersect_impl::<Portable, true, P, F>(ray, start, stats, prefetch_leaf, leaf)
        } else {
            self.intersect_impl::<Portable, false, P, F>(ray, start, stats, prefetch_leaf, leaf)
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn intersect_avx2<P: Fn(u32), F: FnMut(u32, u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        start: (u32, u32),
        stats: &mut RayStats,
        prefetch_leaf: P,
        leaf: F,
    ) -> bool {
        if needs_general_test(ray) {
            self.intersect_impl::<Avx2, true, P, F>(ray, start, stats, prefetch_leaf, leaf)
        } else {
            self.intersect_impl::<Avx2, false, P, F>(ray, start, stats, prefetch_leaf, leaf)
        }
    }

    /// Any hit by whole leaves: `blocks(first, count)` says whether a primitive at the
    /// positions `first..first + count` of [`Bvh8::prim_order`] blocks the ray.
    #[inline]
    pub fn occluded_leaves<P: Fn(u32), F: FnMut(u32, u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        prefetch_leaf: P,
        blocks: F,
    ) -> bool {
        if self.prim_order.is_empty() {
            return false;
        }
        self.occluded_leaves_from(ray, self.root, stats, prefetch_leaf, blocks)
    }

    /// [`Bvh8::occluded_leaves`] in the subtree of slot `start` only.
    #[inline]
    pub(crate) fn occluded_leaves_from<P: Fn(u32), F: FnMut(u32, u32) -> bool>(
        &self,
        ray: &Ray,
        start: (u32, u32),
        stats: &mut RayStats,
        prefetch_leaf: P,
        blocks: F,
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the AVX2 tier was detected when the tree was built.
            return unsafe { self.occluded_avx2(ray, start, stats, prefetch_leaf, blocks) };
        }
        if needs_general_test(ray) {
            self.occluded_impl::<Portable, true, P, F>(ray, start, stats, prefetch_leaf, blocks)
        } else {
            self.occluded_impl::<Portable, false, P, F>(ray, start, stats, prefetch_leaf, blocks)
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn occluded_avx2<P: Fn(u32), F: FnMut(u32, u32) -> bool>(
        &self,
        ray: &Ray,
        start: (u32, u32),
        stats: &mut RayStats,
        prefetch_leaf: P,
        blocks: F,
    ) -> bool {
        if needs_general_test(ray) {
            self.occluded_impl::<Avx2, true, P, F>(ray, start, stats, prefetch_leaf, blocks)
        } else {
            self.occluded_impl::<Avx2, false, P, F>(ray, start, stats, prefetch_leaf, blocks)
        }
    }

    #[inline(always)]
    fn intersect_impl<T: NodeTest, const GENERAL: bool, P, F>(
        &self,
        ray: &Ray,
        start: (u32, u32),
        stats: &mut RayStats,
        prefetch_leaf: P,
        mut leaf: F,
    ) -> bool
    where
        P: Fn(u32),
        F: FnMut(u32, u32, &mut f32) -> bool,
    {
        let lanes = RayLanes::new(ray);
        let mut t_max = ray.t_max;
        let mut any = false;
        let mut stack = [const { MaybeUninit::<Entry>::uninit() }; STACK_SIZE];
        let mut sp = 0usize;
        let mut cur = Entry {
            child: start.0,
            count: start.1,
            dist: ray.t_min,
        };
        // Counted here and added to `stats` at the end: stores through `stats` in the
        // loop cannot be kept in registers across the calls to `leaf`.
        let (mut visited, mut tested) = (0u32, 0u32);
        loop {
            visited += 1;
            if cur.count > 0 {
                tested += cur.count;
                any |= leaf(cur.child, cur.count, &mut t_max);
            } else {
                let node = &self.nodes[cur.child as usize];
                Self::prefetch_refs(node);
                let (mask, near) = T::test::<GENERAL>(node, &lanes, ray.t_min, t_max);
                if mask != 0 {
                    cur = self.descend::<GENERAL, P>(
                        node,
                        mask,
                        &near,
                        &mut stack,
                        &mut sp,
                        &prefetch_leaf,
                    );
                    continue;
                }
            }
            // Pop the next entry that can still hold a closer hit.
            loop {
                if sp == 0 {
                    stats.nodes_visited += visited;
                    stats.prims_tested += tested;
                    return any;
                }
                sp -= 1;
                // SAFETY: every entry below `sp` was written before `sp` passed it.
                cur = unsafe { stack[sp].assume_init() };
                if cur.dist <= t_max {
                    break;
                }
            }
        }
    }

    #[inline(always)]
    fn occluded_impl<T: NodeTest, const GENERAL: bool, P, F>(
        &self,
        ray: &Ray,
        start: (u32, u32),
        stats: &mut RayStats,
        prefetch_leaf: P,
        mut blocks: F,
    ) -> bool
    where
        P: Fn(u32),
        F: FnMut(u32, u32) -> bool,
    {
        let lanes = RayLanes::new(ray);
        // The stack as two arrays of child references (see `NodeTest::push_hits`).
        let mut children = [const { MaybeUninit::<u32>::uninit() }; ANY_STACK];
        let mut counts = [const { MaybeUninit::<u32>::uninit() }; ANY_STACK];
        let mut sp = 0usize;
        let (mut child, mut count) = start;
        let (mut visited, mut tested) = (0u32, 0u32);
        loop {
            visited += 1;
            if count > 0 {
                tested += count;
                if blocks(child, count) {
                    stats.nodes_visited += visited;
                    stats.prims_tested += tested;
                    return true;
                }
            } else {
                let node = &self.nodes[child as usize];
                Self::prefetch_refs(node);
                let (mask, _) = T::test::<GENERAL>(node, &lanes, ray.t_min, ray.t_max);
                if mask != 0 {
                    // The lowest slot next, the others on the stack, the next lowest on top.
                    let k = mask.trailing_zeros() as usize;
                    sp = T::push_hits(node, mask & (mask - 1), &mut children, &mut counts, sp);
                    (child, count) = (node.child[k], node.count[k]);
                    continue;
                }
            }
            if sp == 0 {
                stats.nodes_visited += visited;
                stats.prims_tested += tested;
                return false;
            }
            sp -= 1;
            // SAFETY: every entry below `sp` was written before `sp` passed it.
            (child, count) = unsafe { (children[sp].assume_init(), counts[sp].assume_init()) };
            // Start loading the entry below, the next to be visited unless this one
            // pushes children. One prefetch per entry visited, rather than one per entry
            // pushed (most of which a shadow ray that is blocked never visits): 2-5%
            // faster on coherent shadow rays and 5-9% on incoherent any-hit rays of the
            // 1.1M-triangle bunny (Zen 4), with the pushes above.
            if sp > 0 {
                // SAFETY: as above.
                let (c, n) =
                    unsafe { (children[sp - 1].assume_init(), counts[sp - 1].assume_init()) };
                self.prefetch(c, n, &prefetch_leaf);
            }
        }
    }
}

/// Pushes `e` on a closest-hit stack, prefetching what it refers to.
#[inline(always)]
fn push_entry<P: Fn(u32)>(
    tree: &Bvh8,
    e: Entry,
    stack: &mut [MaybeUninit<Entry>],
    sp: &mut usize,
    prefetch_leaf: &P,
) {
    tree.prefetch(e.child, e.count, prefetch_leaf);
    stack[*sp].write(e);
    *sp += 1;
}

/// Two entries and their distances' [`order_bits`]: the nearer first, `x` on a tie,
/// chosen by selects (conditional moves) rather than a branch.
#[inline(always)]
fn nearer(x: Entry, x_ord: u32, y: Entry, y_ord: u32) -> (Entry, Entry) {
    let x_first = x_ord <= y_ord;
    let pick = |p: u32, q: u32| if x_first { (p, q) } else { (q, p) };
    let (c1, c2) = pick(x.child, y.child);
    let (n1, n2) = pick(x.count, y.count);
    let (d1, d2) = pick(x.dist.to_bits(), y.dist.to_bits());
    let entry = |child, count, dist| Entry {
        child,
        count,
        dist: f32::from_bits(dist),
    };
    (entry(c1, n1, d1), entry(c2, n2, d2))
}

/// A float's bits (not NaN) made monotonic as an unsigned integer.
#[inline(always)]
fn order_bits(bits: u32) -> u32 {
    let flip = ((bits as i32 >> 31) as u32) | 0x8000_0000;
    bits ^ flip
}

/// The two keys in order (compiled to conditional moves, not branches).
#[inline(always)]
fn sort2(a: u64, b: u64) -> (u64, u64) {
    (a.min(b), a.max(b))
}

/// Rays in flight at once in a stream traversal (see [`Bvh8::intersect_stream`]).
pub const STREAM_GROUP: usize = 8;

/// One ray of a stream traversal in flight: the state that the single-ray loop keeps in
/// registers, kept here between its steps, and the caller's per-ray state `user`.
struct Flight<X> {
    lanes: RayLanes,
    t_max: f32,
    /// Whether the ray takes the general node test ([`needs_general_test`]).
    general: bool,
    any: bool,
    ray: usize,
    cur: Entry,
    /// The top of this ray's stack (its slot's `STACK_SIZE` entries of the stream's
    /// stack buffer).
    sp: usize,
    user: X,
}

impl<X> Flight<X> {
    fn new(ray: &Ray, index: usize, root: (u32, u32), user: X) -> Flight<X> {
        Flight {
            lanes: RayLanes::new(ray),
            t_max: ray.t_max,
            general: needs_general_test(ray),
            any: false,
            ray: index,
            cur: Entry {
                child: root.0,
                count: root.1,
                dist: ray.t_min,
            },
            sp: 0,
            user,
        }
    }

    /// Takes the next ray into this slot and returns the previous ray's state.
    fn restart(&mut self, ray: &Ray, index: usize, root: (u32, u32), user: X) -> X {
        std::mem::replace(self, Flight::new(ray, index, root, user)).user
    }
}

impl Bvh8 {
    /// Closest hits of many rays, [`STREAM_GROUP`] of them in flight at a time: each
    /// ray takes one step (a node or a leaf), starts loading the node or leaf it goes to
    /// next, and hands over to the next ray, so that the cache misses of several rays
    /// overlap instead of each ray waiting for its own. Visits, for each ray, the same
    /// nodes and leaves in the same order as [`Bvh8::intersect_leaves`], so it finds the
    /// same hits.
    ///
    /// Per ray, `init(ray)` makes the caller's state, `leaf(&mut state, ray, first,
    /// count, &mut t_max)` is the leaf test (as in [`Bvh8::intersect_leaves`]), and
    /// `done(ray, state, any)` receives the state when the ray's traversal ends.
    pub fn intersect_stream<X, P, I, F, D>(
        &self,
        rays: &[Ray],
        stats: &mut RayStats,
        prefetch_leaf: P,
        init: I,
        leaf: F,
        done: D,
    ) where
        P: Fn(u32),
        I: FnMut(usize) -> X,
        F: FnMut(&mut X, &Ray, u32, u32, &mut f32) -> bool,
        D: FnMut(usize, X, bool),
    {
        self.stream::<false, X, P, I, F, D>(rays, stats, prefetch_leaf, init, leaf, done)
    }

    /// Any hits of many rays, several in flight at a time (see
    /// [`Bvh8::intersect_stream`]); `blocks(&mut state, ray, first, count)` says whether
    /// a primitive of the leaf blocks the ray, and `done(ray, state, occluded)` receives
    /// the answer.
    pub fn occluded_stream<X, P, I, F, D>(
        &self,
        rays: &[Ray],
        stats: &mut RayStats,
        prefetch_leaf: P,
        init: I,
        mut blocks: F,
        done: D,
    ) where
        P: Fn(u32),
        I: FnMut(usize) -> X,
        F: FnMut(&mut X, &Ray, u32, u32) -> bool,
        D: FnMut(usize, X, bool),
    {
        let leaf = |x: &mut X, ray: &Ray, first, count, _: &mut f32| blocks(x, ray, first, count);
        self.stream::<true, X, P, I, _, D>(rays, stats, prefetch_leaf, init, leaf, done)
    }

    fn stream<const ANY_HIT: bool, X, P, I, F, D>(
        &self,
        rays: &[Ray],
        stats: &mut RayStats,
        prefetch_leaf: P,
        mut init: I,
        leaf: F,
        mut done: D,
    ) where
        P: Fn(u32),
        I: FnMut(usize) -> X,
        F: FnMut(&mut X, &Ray, u32, u32, &mut f32) -> bool,
        D: FnMut(usize, X, bool),
    {
        if self.prim_order.is_empty() {
            for i in 0..rays.len() {
                done(i, init(i), false);
            }
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the AVX2 tier was detected when the tree was built.
            return unsafe {
                self.stream_avx2::<ANY_HIT, X, P, I, F, D>(
                    rays,
                    stats,
                    prefetch_leaf,
                    init,
                    leaf,
                    done,
                )
            };
        }
        self.stream_impl::<Portable, ANY_HIT, X, P, I, F, D>(
            rays,
            stats,
            prefetch_leaf,
            init,
            leaf,
            done,
        )
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn stream_avx2<const ANY_HIT: bool, X, P, I, F, D>(
        &self,
        rays: &[Ray],
        stats: &mut RayStats,
        prefetch_leaf: P,
        init: I,
        leaf: F,
        done: D,
    ) where
        P: Fn(u32),
        I: FnMut(usize) -> X,
        F: FnMut(&mut X, &Ray, u32, u32, &mut f32) -> bool,
        D: FnMut(usize, X, bool),
    {
        self.stream_impl::<Avx2, ANY_HIT, X, P, I, F, D>(
            rays,
            stats,
            prefetch_leaf,
            init,
            leaf,
            done,
        )
    }

    #[inline(always)]
    fn stream_impl<T: NodeTest, const ANY_HIT: bool, X, P, I, F, D>(
        &self,
        rays: &[Ray],
        stats: &mut RayStats,
        prefetch_leaf: P,
        mut init: I,
        mut leaf: F,
        mut done: D,
    ) where
        P: Fn(u32),
        I: FnMut(usize) -> X,
        F: FnMut(&mut X, &Ray, u32, u32, &mut f32) -> bool,
        D: FnMut(usize, X, bool),
    {
        let group = STREAM_GROUP.min(rays.len());
        // One stack per slot, uninitialised (entries are written before they are read).
        let mut stack: Vec<MaybeUninit<Entry>> = Vec::with_capacity(group * STACK_SIZE);
        // SAFETY: `MaybeUninit` entries need no initialisation.
        unsafe { stack.set_len(group * STACK_SIZE) };
        let mut flights: Vec<(Flight<X>, usize)> = (0..group)
            .map(|i| (Flight::new(&rays[i], i, self.root, init(i)), i * STACK_SIZE))
            .collect();
        let mut next = flights.len();
        // Counted here and added to `stats` at the end (see `intersect_impl`).
        let mut counts = (0u32, 0u32);
        while !flights.is_empty() {
            let mut s = 0;
            while s < flights.len() {
                let (f, base) = &mut flights[s];
                let base = *base;
                if self.stream_step::<T, ANY_HIT, X, P, F>(
                    f,
                    &mut stack[base..base + STACK_SIZE],
                    &rays[f.ray],
                    &prefetch_leaf,
                    &mut leaf,
                    &mut counts,
                ) {
                    s += 1;
                    continue;
                }
                let (ray, any) = (f.ray, f.any);
                if next < rays.len() {
                    let user = f.restart(&rays[next], next, self.root, init(next));
                    next += 1;
                    done(ray, user, any);
                    s += 1;
                } else {
                    let (f, _) = flights.swap_remove(s);
                    done(ray, f.user, any);
                }
            }
        }
        stats.nodes_visited += counts.0;
        stats.prims_tested += counts.1;
    }

    /// One step of a ray in flight: visits its current node or leaf and moves on to the
    /// next one, which it starts loading; returns false when the ray's traversal is over.
    /// The order of visits is the single-ray loops' (`intersect_impl`, `occluded_impl`).
    #[inline(always)]
    fn stream_step<T: NodeTest, const ANY_HIT: bool, X, P, F>(
        &self,
        f: &mut Flight<X>,
        stack: &mut [MaybeUninit<Entry>],
        ray: &Ray,
        prefetch_leaf: &P,
        leaf: &mut F,
        counts: &mut (u32, u32),
    ) -> bool
    where
        P: Fn(u32),
        F: FnMut(&mut X, &Ray, u32, u32, &mut f32) -> bool,
    {
        counts.0 += 1;
        let cur = f.cur;
        if cur.count > 0 {
            counts.1 += cur.count;
            if leaf(&mut f.user, ray, cur.child, cur.count, &mut f.t_max) {
                f.any = true;
                if ANY_HIT {
                    return false;
                }
            }
        } else {
            let node = &self.nodes[cur.child as usize];
            let (mask, near) = if f.general {
                T::test::<true>(node, &f.lanes, ray.t_min, f.t_max)
            } else {
                T::test::<false>(node, &f.lanes, ray.t_min, f.t_max)
            };
            if mask != 0 {
                let next = if ANY_HIT {
                    // Any hit: children in slot order (as `occluded_impl`): the first
                    // next, the others pushed from the highest slot down.
                    let entry = |k: u32| Entry {
                        child: node.child[k as usize],
                        count: node.count[k as usize],
                        dist: 0.0,
                    };
                    let mut bits = mask & (mask - 1);
                    while bits != 0 {
                        let k = 31 - bits.leading_zeros();
                        let e = entry(k);
                        bits &= !(1 << k);
                        self.prefetch(e.child, e.count, prefetch_leaf);
                        stack[f.sp].write(e);
                        f.sp += 1;
                    }
                    entry(mask.trailing_zeros())
                } else {
                    self.descend::<true, P>(node, mask, &near, stack, &mut f.sp, prefetch_leaf)
                };
                self.prefetch(next.child, next.count, prefetch_leaf);
                f.cur = next;
                return true;
            }
        }
        // Pop the next entry that can still hold a closer hit.
        while f.sp > 0 {
            f.sp -= 1;
            // SAFETY: every entry below `sp` was written before `sp` passed it.
            let e = unsafe { stack[f.sp].assume_init() };
            if ANY_HIT || e.dist <= f.t_max {
                f.cur = e;
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::check_kind_on_all_scenes;
    use crate::accel::{Accel, AccelKind};

    /// The descent returns the nearest child and leaves the others on the stack in the
    /// order a sort by (distance, slot) gives, for every mask and for distances with
    /// ties, signed zeros, negatives and infinities (the general node test's), and with
    /// their magnitudes for the plain test's keys.
    #[test]
    fn descent_sorts_children_by_distance_then_slot() {
        let mut node = EMPTY_NODE;
        for k in 0..8 {
            node.child[k] = 100 + k as u32;
            node.count[k] = (k as u32 % 3) * 4;
        }
        let tree = Bvh8::build(
            &crate::accel::bvh::tests::random_boxes(10, 1),
            &BuildSettings::default(),
        );
        let values = [0.0, -0.0, 1.0, 1.0, 2.5, -3.0, f32::INFINITY, 1e-30];
        let mut rng = crate::sampling::Pcg32::new(3, 4);
        for round in 0..8000 {
            let general = round % 4 < 2;
            let mut near = [0.0f32; 8];
            for d in near.iter_mut() {
                *d = if round % 2 == 0 {
                    values[(rng.next_u32() % 8) as usize]
                } else {
                    rng.next_f32() * 4.0 - 1.0
                };
                if !general {
                    *d = d.abs();
                }
            }
            let mask = 1 + (round / 4) as u32 % 255;
            let mut expected: Vec<usize> = (0..8).filter(|k| mask & (1 << k) != 0).collect();
            expected.sort_by(|&a, &b| near[a].total_cmp(&near[b]).then(a.cmp(&b)));
            // `total_cmp` orders -0 before +0, as the keys do.
            let mut stack = [const { MaybeUninit::<Entry>::uninit() }; 16];
            let mut sp = 3;
            let first = if general {
                tree.descend::<true, _>(&node, mask, &Near(near), &mut stack, &mut sp, &|_| {})
            } else {
                tree.descend::<false, _>(&node, mask, &Near(near), &mut stack, &mut sp, &|_| {})
            };
            let mut got = vec![first];
            while sp > 3 {
                sp -= 1;
                got.push(unsafe { stack[sp].assume_init() });
            }
            assert_eq!(got.len(), expected.len(), "mask {mask:#b}");
            for (e, &k) in got.iter().zip(&expected) {
                assert_eq!(
                    (e.child, e.count),
                    (node.child[k], node.count[k]),
                    "mask {mask:#b} near {near:?}"
                );
                assert_eq!(e.dist.to_bits(), near[k].to_bits());
            }
        }
    }

    /// The shared accelerator property test (closest and any hits equal the brute-force
    /// list's on random, flat, degenerate and lattice meshes, with axis-parallel rays,
    /// rays in the meshes' planes and rays starting inside), with whatever node test
    /// this processor uses.
    #[test]
    fn matches_the_list_on_every_test_scene() {
        check_kind_on_all_scenes(AccelKind::Bvh8);
    }

    /// The bit-range form of `needs_general_test` against its definition in float
    /// comparisons, for each field of the ray at every edge of its range.
    #[test]
    fn general_test_choice_matches_its_definition() {
        let reference = |ray: &Ray| {
            let d = ray.direction.abs();
            let direction_ok = d.cmpge(Vec3::splat(f32::MIN_POSITIVE)).all() && d.is_finite();
            !(direction_ok
                && ray.t_min >= 0.0
                && ray.t_min.is_sign_positive()
                && ray.origin.is_finite())
        };
        let edges = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::MIN_POSITIVE / 2.0,
            -f32::from_bits(1),
            f32::from_bits(1),
            1.0,
            -1.0,
            f32::MAX,
            -f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7f80_0001),
        ];
        let base = Ray {
            origin: Vec3::new(0.5, -2.0, 3.0),
            direction: Vec3::new(0.3, -0.4, 0.5),
            t_min: 0.0,
            t_max: f32::INFINITY,
        };
        let mut general = 0;
        for field in 0..7 {
            for &v in &edges {
                let mut ray = base;
                match field {
                    0..=2 => ray.origin[field] = v,
                    3..=5 => ray.direction[field - 3] = v,
                    _ => ray.t_min = v,
                }
                assert_eq!(
                    needs_general_test(&ray),
                    reference(&ray),
                    "field {field}, {v:?}"
                );
                general += usize::from(reference(&ray));
            }
        }
        // Every field has values on both sides.
        assert!(general > 7 * 3 && general < 7 * edges.len() - 7 * 3);
    }

    /// Both node tests (the plain one on integer bits and the general one) visit every
    /// leaf whose box the ray enters within `[t_min, t_max]`, by an exact slab test in
    /// f64, for rays of every kind: `t_min` positive, `+0`, `-0` and negative, finite
    /// ranges, direction components zero, subnormal or huge, origins inside the boxes.
    #[test]
    fn visits_every_box_the_ray_enters() {
        let boxes = crate::accel::bvh::tests::random_boxes(3000, 23);
        let fast = Bvh8::build(&boxes, &BuildSettings::default());
        let portable = fast.clone().without_avx2();
        let enters =
            |b: &Bounds3, ray: &Ray| crate::accel::wide_bvh::tests::exact_entry(b, ray).is_some();
        let mut rng = crate::sampling::Pcg32::new(8, 3);
        let mut entered = 0;
        for i in 0..4000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - 2.0;
            // Towards a point among the boxes.
            let aim = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
            let mut d = (aim - o) * (0.1 + rng.next_f32());
            match i % 6 {
                1 => d.x = 0.0,
                2 => d.y = 1e-40,
                3 => d.z = -3e38,
                _ => {}
            }
            let t_min = [0.0, -0.0, -1.5, 0.7, 2.0][i % 5];
            let t_max = if i % 3 == 0 { 3.0 } else { f32::INFINITY };
            let ray = Ray::with_range(o, d, t_min, t_max);
            let want: Vec<u32> = (0..boxes.len() as u32)
                .filter(|&p| enters(&boxes[p as usize], &ray))
                .collect();
            entered += want.len();
            for tree in [&fast, &portable] {
                let mut seen = Vec::new();
                tree.intersect(&ray, &mut RayStats::default(), |p, _| {
                    seen.push(p);
                    false
                });
                seen.sort_unstable();
                let missed: Vec<_> = want
                    .iter()
                    .filter(|p| seen.binary_search(p).is_err())
                    .collect();
                assert!(missed.is_empty(), "ray {i} {ray:?} skips boxes {missed:?}");
                let any = tree.occluded(&ray, &mut RayStats::default(), |p| want.contains(&p));
                assert_eq!(any, !want.is_empty(), "ray {i} {ray:?}");
            }
        }
        assert!(
            entered > 5000,
            "only {entered} boxes entered: the test is too weak"
        );
    }

    /// The portable and the AVX2 node tests give the same hits, distances and traversal
    /// counts.
    #[test]
    fn portable_and_avx2_agree() {
        let boxes = crate::accel::bvh::tests::random_boxes(5000, 17);
        let fast = Bvh8::build(&boxes, &BuildSettings::default());
        let portable = fast.clone().without_avx2();
        let mut rng = crate::sampling::Pcg32::new(3, 9);
        for i in 0..3000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - 2.0;
            let mut d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
            if i % 4 == 0 {
                d.y = 0.0;
            }
            let ray = Ray::new(o, d);
            let run = |t: &Bvh8| {
                let mut stats = RayStats::default();
                let mut seen = Vec::new();
                t.intersect(&ray, &mut stats, |p, t_max| {
                    seen.push(p);
                    let c = boxes[p as usize].center();
                    let t = (c - ray.origin).length();
                    if t < *t_max && (p % 3 == 0) {
                        *t_max = t;
                        true
                    } else {
                        false
                    }
                });
                let occ = t.occluded(&ray, &mut RayStats::default(), |p| p % 5 == 0);
                (seen, stats, occ)
            };
            assert_eq!(run(&fast), run(&portable), "ray {i}");
        }
        // The accelerator enum reaches the same tree.
        let accel = Accel::Bvh8(fast);
        assert!(accel.leaf_order().is_some());
    }

    /// The stream traversals visit, for every ray, the same leaves in the same order as
    /// the single-ray ones and end with the same answers and counters, with either node
    /// test, for streams shorter and longer than the group in flight.
    #[test]
    fn streams_match_single_rays() {
        let boxes = crate::accel::bvh::tests::random_boxes(3000, 5);
        let fast = Bvh8::build(&boxes, &BuildSettings::default());
        let portable = fast.clone().without_avx2();
        let mut rng = crate::sampling::Pcg32::new(8, 1);
        let rays: Vec<Ray> = (0..700)
            .map(|i| {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - 2.0;
                let mut d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
                if i % 5 == 0 {
                    d.x = 0.0;
                }
                let mut ray = Ray::new(o, d);
                if i % 7 == 0 {
                    ray.t_min = 0.5;
                    ray.t_max = 4.0;
                }
                ray
            })
            .collect();
        // A leaf "hits" its primitives whose index is a multiple of 3, at the distance
        // of their box centre, and blocks rays when one is a multiple of 5.
        let leaf_hit = |ray: &Ray, first: u32, count: u32, t_max: &mut f32, t: &Bvh8| {
            let mut found = false;
            for &p in &t.prim_order[first as usize..(first + count) as usize] {
                let d = (boxes[p as usize].center() - ray.origin).length();
                if p % 3 == 0 && d < *t_max && d >= ray.t_min {
                    *t_max = d;
                    found = true;
                }
            }
            found
        };
        let blocks = |first: u32, count: u32, t: &Bvh8| {
            t.prim_order[first as usize..(first + count) as usize]
                .iter()
                .any(|&p| p % 5 == 0)
        };
        for tree in [&fast, &portable] {
            for n in [0, 1, 3, STREAM_GROUP, STREAM_GROUP + 1, rays.len()] {
                let all = n == rays.len();
                let rays = &rays[..n];
                let mut single = Vec::new();
                let mut single_stats = RayStats::default();
                for ray in rays {
                    let mut seen = Vec::new();
                    let mut t_max = ray.t_max;
                    let any = tree.intersect_leaves(
                        ray,
                        &mut single_stats,
                        |_| {},
                        |f, c, t| {
                            seen.push((f, c));
                            let hit = leaf_hit(ray, f, c, t, tree);
                            t_max = *t;
                            hit
                        },
                    );
                    let mut occ_seen = Vec::new();
                    let occ = tree.occluded_leaves(
                        ray,
                        &mut single_stats,
                        |_| {},
                        |f, c| {
                            occ_seen.push((f, c));
                            blocks(f, c, tree)
                        },
                    );
                    single.push((seen, any, t_max.to_bits(), occ_seen, occ));
                }
                let mut stream = vec![(Vec::new(), false, 0u32, Vec::new(), false); n];
                let mut stream_stats = RayStats::default();
                tree.intersect_stream(
                    rays,
                    &mut stream_stats,
                    |_| {},
                    |i| (Vec::new(), rays[i].t_max),
                    |(seen, t_max): &mut (Vec<(u32, u32)>, f32), ray, f, c, t| {
                        seen.push((f, c));
                        let hit = leaf_hit(ray, f, c, t, tree);
                        *t_max = *t;
                        hit
                    },
                    |i, (seen, t_max), any| {
                        stream[i].0 = seen;
                        stream[i].1 = any;
                        stream[i].2 = t_max.to_bits();
                    },
                );
                tree.occluded_stream(
                    rays,
                    &mut stream_stats,
                    |_| {},
                    |_| Vec::new(),
                    |seen: &mut Vec<(u32, u32)>, _, f, c| {
                        seen.push((f, c));
                        blocks(f, c, tree)
                    },
                    |i, seen, occ| {
                        stream[i].3 = seen;
                        stream[i].4 = occ;
                    },
                );
                assert_eq!(single, stream, "{n} rays");
                assert_eq!(
                    (single_stats.nodes_visited, single_stats.prims_tested),
                    (stream_stats.nodes_visited, stream_stats.prims_tested)
                );
                if all {
                    assert!(single.iter().filter(|s| s.1).count() > 50);
                    assert!(single.iter().filter(|s| s.4).count() > 50);
                }
            }
        }
    }

    #[test]
    fn every_primitive_is_reachable_once() {
        let boxes = crate::accel::bvh::tests::random_boxes(5000, 3);
        let wide = Bvh8::build(&boxes, &BuildSettings::default());
        let mut seen = vec![0u32; boxes.len()];
        let mut stack = vec![wide.root];
        while let Some((child, count)) = stack.pop() {
            if count > 0 {
                assert_eq!(child % 4, 0, "leaves start at multiples of 4");
                for &p in &wide.prim_order[child as usize..(child + count) as usize] {
                    seen[p as usize] += 1;
                }
                continue;
            }
            let node = &wide.nodes[child as usize];
            for k in 0..8 {
                if node.count[k] != EMPTY {
                    stack.push((node.child[k], node.count[k]));
                }
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
        assert_eq!(wide.prim_order.len() % 4, 0);
    }
}
