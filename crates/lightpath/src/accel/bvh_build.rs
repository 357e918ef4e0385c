//! The binned SAH builder behind [`Bvh::build`](super::Bvh::build).
//!
//! - **Primitive references.** The build works on a copy of the boxes as 32-byte records
//!   ([`PrimRef`]: `min` and `max` as SIMD `Vec4`, the primitive index in the spare lanes),
//!   so binning and partitioning read memory sequentially instead of gathering boxes and
//!   centroids through an index array. Centroids are kept doubled (`min + max`): that
//!   saves a multiply and bins exactly as the halved centroid would.
//! - **Binning.** One pass over a range puts every primitive into its bin on all three
//!   axes at once (one subtract, multiply and clamp for the three bin indices); a sweep
//!   over the bins from the right and then from the left evaluates every bin boundary,
//!   the three axes at once in the lanes of a `Vec4`. Ranges above [`PAR_BIN_SIZE`] are
//!   binned in parallel, in fixed chunks whose bins are merged (exact: a minimum, a
//!   maximum and a count). With `BuildSettings::scaled_bins` (the default preset),
//!   ranges under a few hundred primitives use fewer bins (8 + n/8).
//! - **Small ranges** (at most `BuildSettings::sweep_size` primitives, most nodes of a
//!   tree) skip the bins: their centroids are sorted along each axis (by counting ranks,
//!   without branches on the data) and every split between neighbours is evaluated, which
//!   costs less than clearing and sweeping the bins and finds splits at least as good.
//! - **Partition.** In place, from both ends, by the same bin computation as the binning
//!   (so the two sides have exactly the counts the SAH evaluated), accumulating both
//!   children's boxes and centroid boxes on the way: no node ever makes a pass of its own
//!   just to find its box. Ranges above [`PAR_PARTITION_SIZE`] (the few at the top of the
//!   tree, which would otherwise be partitioned one after another while other threads
//!   wait) are partitioned in parallel ([`partition_parallel`]).
//! - **Tasks.** Ranges above [`TASK_SIZE`] split into two halves built with `rayon::join`;
//!   a range at or below it is one task that writes its subtree straight into its own
//!   node array, in the final layout (depth first, siblings adjacent). The arrays are
//!   joined once at the end, below the few top-level nodes, in parallel.
//!
//! - **Reinsertion** (`BuildSettings::reinsertion_passes`, the `HIGH` preset): after the
//!   build, every node, largest first, is taken out and put back where it adds the least
//!   SAH cost; then the nodes are laid out depth first again.
//!
//! - **Memory.** The primitive references, the primitive order and the flattened tree
//!   are asked for in huge pages (`accel::memory`): a fresh array's first touch otherwise
//!   costs a page fault per 4 KiB: a build of the 1.1M-triangle bunny in `lightpath
//!   bench` took 9,400 of them, and takes 1,650. The boxes come by index
//!   ([`build_from`]), straight into the references, with no array of their own, and
//!   each thread keeps its task scratch from one task to the next ([`Scratch::take`];
//!   a few hundred KB a thread, kept until the thread ends).
//! - **AVX2.** Where the processor has it, the tasks, the partitions above them and the
//!   parallel binning run in copies of the code compiled for AVX2
//!   ([`Builder::build_task`]); the tree is the same bit for bit.
//!
//! Every decision depends on the data and on fixed sizes only, never on the number of
//! threads or on timing, so the tree is the same for any thread count.

use super::bvh::{BuildSettings, BvhNode, MEDIAN_DEPTH, STACK_SIZE};
use crate::math::Bounds3;
use glam::{BVec4A, Mat4, Vec3, Vec4};
use rayon::prelude::*;
use std::cmp::Reverse;
use std::mem::MaybeUninit;

/// Ranges above this many primitives split into two halves built in parallel; a range
/// at or below it is built by one task.
const TASK_SIZE: usize = 4096;
/// Ranges of at least this many primitives are binned into two sets of bins.
const INTERLEAVE_SIZE: usize = 128;
/// Ranges above this many primitives are binned in parallel ...
const PAR_BIN_SIZE: usize = 1 << 16;
/// ... in chunks of this many.
const BIN_CHUNK: usize = 1 << 14;

/// A primitive's box; the w lanes hold its index, the low 16 bits in `min.w` and the high
/// 16 in `max.w`, as small whole numbers: arithmetic on the spare lane then never meets a
/// subnormal (which costs a microcode assist per instruction) or overflows.
#[derive(Clone, Copy)]
#[repr(C)]
struct PrimRef {
    min: Vec4,
    max: Vec4,
}

impl PrimRef {
    #[inline]
    fn new(b: &Bounds3, index: u32) -> PrimRef {
        PrimRef {
            min: b.min.extend((index & 0xffff) as f32),
            max: b.max.extend((index >> 16) as f32),
        }
    }

    #[inline]
    fn index(&self) -> u32 {
        self.min.w as u32 | (self.max.w as u32) << 16
    }

    /// Half the box's surface area (as `Aabb::half_area`).
    #[inline(always)]
    fn half_area(&self) -> f32 {
        let d = self.max - self.min;
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    /// Whether the box is empty (as [`Bounds3::is_empty`]; the w lanes are ignored).
    #[inline]
    fn is_empty(&self) -> bool {
        self.min.truncate().cmpgt(self.max.truncate()).any()
    }

    /// Twice the centroid (the w lane means nothing).
    #[inline(always)]
    fn centroid2(&self) -> Vec4 {
        self.min + self.max
    }
}

/// A box as two `Vec4` (the w lanes mean nothing).
#[derive(Clone, Copy)]
struct Aabb {
    min: Vec4,
    max: Vec4,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: Vec4::splat(f32::INFINITY),
        max: Vec4::splat(f32::NEG_INFINITY),
    };

    #[inline(always)]
    fn grow(&mut self, p: &PrimRef) {
        self.min = self.min.min(p.min);
        self.max = self.max.max(p.max);
    }

    #[inline(always)]
    fn grow_point(&mut self, c: Vec4) {
        self.min = self.min.min(c);
        self.max = self.max.max(c);
    }

    #[inline(always)]
    fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// Half the surface area (the same expression as `Bounds3::surface_area`).
    #[inline(always)]
    fn half_area(&self) -> f32 {
        let d = self.max - self.min;
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    fn min3(&self) -> [f32; 3] {
        self.min.truncate().to_array()
    }

    fn max3(&self) -> [f32; 3] {
        self.max.truncate().to_array()
    }
}

/// A range's box and the box of its (doubled) centroids.
#[derive(Clone, Copy)]
struct Range {
    bounds: Aabb,
    cbounds: Aabb,
}

impl Range {
    const EMPTY: Range = Range {
        bounds: Aabb::EMPTY,
        cbounds: Aabb::EMPTY,
    };

    #[inline(always)]
    fn grow(&mut self, p: &PrimRef) {
        self.bounds.grow(p);
        self.cbounds.grow_point(p.centroid2());
    }

    /// [`Range::grow`] if `keep`, else no change, without a branch: the primitive is
    /// masked to the empty box (min/max with ±∞ change nothing, so the result is the
    /// same bit for bit).
    #[inline(always)]
    fn grow_if(&mut self, p: &PrimRef, keep: bool) {
        let m = BVec4A::splat(keep);
        let (inf, neg_inf) = (Vec4::INFINITY, Vec4::NEG_INFINITY);
        let c = p.centroid2();
        self.bounds.min = self.bounds.min.min(Vec4::select(m, p.min, inf));
        self.bounds.max = self.bounds.max.max(Vec4::select(m, p.max, neg_inf));
        self.cbounds.min = self.cbounds.min.min(Vec4::select(m, c, inf));
        self.cbounds.max = self.cbounds.max.max(Vec4::select(m, c, neg_inf));
    }

    fn merge(mut self, o: Range) -> Range {
        self.bounds = self.bounds.union(&o.bounds);
        self.cbounds = self.cbounds.union(&o.cbounds);
        self
    }

    #[inline(always)]
    fn of(prims: &[PrimRef]) -> Range {
        let mut r = Range::EMPTY;
        for p in prims {
            r.grow(p);
        }
        r
    }
}

/// Most bins per axis.
pub(super) const MAX_BINS: usize = 256;

/// Adding 1.5·2²³ to a float in [0, 2²²) rounds it to an integer (to nearest, ties to
/// even) that lands in the low bits of the sum's mantissa: a float-to-int conversion
/// without the saturation checks of `as`.
const ROUND_MAGIC: f32 = 12_582_912.0;

/// Maps doubled centroids to bins: bin = round((c − lo)·scale − ½) (which is ⌊(c −
/// lo)·scale⌋ except where that is a whole number), clamped to the bins. An axis along
/// which the centroids do not spread has scale 0 (everything in bin 0) and is not
/// evaluated. Binning and partitioning both go through [`Binner::position`], so a
/// primitive lands on the side of a split that its bin was counted on.
#[derive(Clone, Copy)]
struct Binner {
    lo: Vec4,
    scale: Vec4,
    last: Vec4,
    valid: [bool; 3],
}

impl Binner {
    #[inline(always)]
    fn new(cbounds: &Aabb, bins: usize) -> Binner {
        let extent = cbounds.max - cbounds.min;
        let mut scale = [0.0f32; 4];
        let mut valid = [false; 3];
        for a in 0..3 {
            if extent[a] > 0.0 {
                let s = bins as f32 / extent[a];
                if s.is_finite() {
                    scale[a] = s;
                    valid[a] = true;
                }
            }
        }
        Binner {
            lo: cbounds.min.truncate().extend(0.0),
            scale: Vec4::from_array(scale),
            last: Vec4::splat((bins - 1) as f32),
            valid,
        }
    }

    /// The bins on the three axes, as the bits of the lanes x, y, z (see
    /// [`ROUND_MAGIC`]).
    #[inline(always)]
    fn position(&self, p: &PrimRef) -> Vec4 {
        ((p.centroid2() - self.lo) * self.scale - Vec4::splat(0.5))
            .max(Vec4::ZERO)
            .min(self.last)
            + Vec4::splat(ROUND_MAGIC)
    }

    /// The bins of a primitive on the three axes.
    #[inline(always)]
    fn bins(&self, p: &PrimRef) -> [usize; 3] {
        let v = self.position(p);
        [bin_of(v.x), bin_of(v.y), bin_of(v.z)]
    }

    /// The bin of a primitive on axis `AXIS`.
    #[inline(always)]
    fn bin<const AXIS: usize>(&self, p: &PrimRef) -> usize {
        bin_of(self.position(p)[AXIS])
    }
}

#[inline(always)]
fn bin_of(v: f32) -> usize {
    (v.to_bits() & (MAX_BINS as u32 - 1)) as usize
}

/// Bins: per bin, the boxes and counts of the three axes side by side, so that the sweep
/// evaluates the three axes at once in the lanes of a `Vec4`. Fixed arrays of
/// [`MAX_BINS`] (indices need no bounds checks); only the first `bins` are used.
struct Bins {
    boxes: Box<[[Aabb; 3]; MAX_BINS]>,
    counts: Box<[[u32; 4]; MAX_BINS]>,
    bins: usize,
}

impl Bins {
    fn new(bins: usize) -> Bins {
        Bins {
            boxes: Box::new([[Aabb::EMPTY; 3]; MAX_BINS]),
            counts: Box::new([[0; 4]; MAX_BINS]),
            bins,
        }
    }

    /// Empties the first `bins` bins and uses only those.
    #[inline(always)]
    fn reset(&mut self, bins: usize) {
        self.bins = bins;
        self.boxes[..self.bins].fill([Aabb::EMPTY; 3]);
        self.counts[..self.bins].fill([0; 4]);
    }

    #[inline(always)]
    fn add(&mut self, prims: &[PrimRef], binner: &Binner) {
        for p in prims {
            let b = binner.bins(p);
            for (axis, &bin) in b.iter().enumerate() {
                self.boxes[bin][axis].grow(p);
                self.counts[bin][axis] += 1;
            }
        }
    }

    /// Bins the primitives alternately into `self` and `other`, then merges `other` in:
    /// two independent chains of read-modify-writes where neighbouring primitives
    /// (often in the same bins) would otherwise wait for each other's stores.
    #[inline(always)]
    fn add_interleaved(&mut self, other: &mut Bins, prims: &[PrimRef], binner: &Binner) {
        let pairs = prims.chunks_exact(2);
        let rest = pairs.remainder();
        for pair in pairs {
            let (p, q) = (&pair[0], &pair[1]);
            let (bp, bq) = (binner.bins(p), binner.bins(q));
            for axis in 0..3 {
                self.boxes[bp[axis]][axis].grow(p);
                self.counts[bp[axis]][axis] += 1;
                other.boxes[bq[axis]][axis].grow(q);
                other.counts[bq[axis]][axis] += 1;
            }
        }
        self.add(rest, binner);
        self.merge_from(other);
    }

    #[inline(always)]
    fn merge_from(&mut self, o: &Bins) {
        for (a, b) in self.boxes.iter_mut().zip(o.boxes.iter()).take(self.bins) {
            for axis in 0..3 {
                a[axis] = a[axis].union(&b[axis]);
            }
        }
        for (a, b) in self.counts.iter_mut().zip(o.counts.iter()).take(self.bins) {
            for axis in 0..3 {
                a[axis] += b[axis];
            }
        }
    }

    fn merge(mut self, o: Bins) -> Bins {
        self.merge_from(&o);
        self
    }
}

/// Half the surface areas of three boxes, in lanes x, y, z.
#[inline(always)]
fn half_areas(b: &[Aabb; 3]) -> Vec4 {
    let m = Mat4::from_cols(
        b[0].max - b[0].min,
        b[1].max - b[1].min,
        b[2].max - b[2].min,
        Vec4::ZERO,
    )
    .transpose();
    let (x, y, z) = (m.x_axis, m.y_axis, m.z_axis);
    // Lane by lane the same expression as `Aabb::half_area`.
    x * y + y * z + z * x
}

#[inline(always)]
fn counts4(c: &[u32; 4]) -> Vec4 {
    Vec4::new(c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32)
}

/// Ranges of at most this many keys are sorted by counting ranks (see [`sort_keys`]).
const RANK_SORT_SIZE: usize = 32;

/// Sorts distinct keys. Small sets, the sweep's usual case, are sorted by rank: each
/// key's position is the number of keys below it, n² comparisons without a branch on
/// the data (which the compiler vectorises), where an insertion sort of random keys
/// mispredicts about every other comparison. The order is the same either way.
#[inline(always)]
fn sort_keys(keys: &mut [u64]) {
    let n = keys.len();
    if n > RANK_SORT_SIZE {
        keys.sort_unstable();
        return;
    }
    let mut sorted = [0u64; RANK_SORT_SIZE];
    for &k in keys.iter() {
        let rank = keys.iter().map(|&j| usize::from(j < k)).sum::<usize>();
        sorted[rank] = k;
    }
    keys.copy_from_slice(&sorted[..n]);
}

thread_local! {
    /// A thread's scratch between tasks ([`Scratch::take`]).
    static SCRATCH: std::cell::Cell<Option<Box<Scratch>>> = const { std::cell::Cell::new(None) };
}

/// Reused buffers of one task.
struct Scratch {
    bins: Bins,
    bins2: Bins,
    /// Area-weighted counts and counts of everything right of each bin boundary (lanes:
    /// axes).
    right: Vec<(Vec4, Vec4)>,
    /// The sweep's centroid order per axis: sort keys with the position in the range in
    /// the low 32 bits.
    order: [Vec<u64>; 3],
    /// The sweep's area-weighted counts right of each position (lanes: axes).
    sweep_right: Vec<Vec4>,
    tmp: Vec<PrimRef>,
}

impl Scratch {
    fn new(bins: usize) -> Scratch {
        Scratch {
            bins: Bins::new(bins),
            bins2: Bins::new(bins),
            right: vec![(Vec4::ZERO, Vec4::ZERO); bins],
            order: Default::default(),
            sweep_right: Vec::new(),
            tmp: Vec::new(),
        }
    }

    /// This thread's scratch for `bins` bins, left by an earlier task
    /// ([`Scratch::put_back`]), or a new one: each holds about 60 KB of bins that a new
    /// one fills in, and a build runs dozens of tasks per thread.
    fn take(bins: usize) -> Box<Scratch> {
        SCRATCH
            .take()
            .filter(|s| s.right.len() == bins)
            .unwrap_or_else(|| Box::new(Scratch::new(bins)))
    }

    /// Leaves the scratch for this thread's next task.
    fn put_back(self: Box<Scratch>) {
        SCRATCH.set(Some(self));
    }

    /// Puts a range in the sweep's order along `axis` and splits it after `k`.
    #[inline(always)]
    fn apply_order(&mut self, prims: &mut [PrimRef], axis: usize, k: usize) -> Split {
        self.tmp.clear();
        self.tmp.extend_from_slice(prims);
        for (p, &key) in prims.iter_mut().zip(&self.order[axis]) {
            *p = self.tmp[key as u32 as usize];
        }
        (k, Range::of(&prims[..k]), Range::of(&prims[k..]))
    }
}

/// How to split a range.
enum Plan {
    /// Left: bins up to and including the given one on an axis.
    Binned(Binner, usize, usize),
    /// Left: the first k in centroid order along an axis.
    Sorted(usize, usize),
    /// Two primitives, one on each side; whether to swap them first.
    Pair(bool),
}

/// What one task builds into.
struct Task {
    nodes: Vec<BvhNode>,
    scratch: Box<Scratch>,
}

/// A range still to build: its primitives (`start..end` of the task's), bounds, depth
/// and node.
struct Pending {
    start: usize,
    end: usize,
    range: Range,
    depth: usize,
    at: usize,
}

/// A split: the number of primitives on the left and both sides' ranges.
type Split = (usize, Range, Range);

/// The top of the tree above the tasks.
enum Top {
    Inner(Aabb, Box<[Top; 2]>),
    /// A subtree with its root at index 0 and its nodes' child indices local to it.
    Sub(Vec<BvhNode>),
}

struct Builder {
    settings: BuildSettings,
    bins: usize,
    /// Whether the processor has the AVX2 tier (`crate::cpu`): then the
    /// tasks, the large ranges' partitions and the parallel binning run in copies of
    /// the code compiled for it (see [`Builder::build_task`]). The results are the same
    /// bit for bit: the same IEEE operations in wider encodings, and no fused
    /// multiply-adds (Rust never contracts `a * b + c`).
    avx2: bool,
}

#[inline(always)]
fn leaf(bounds: &Aabb, first: usize, count: usize) -> BvhNode {
    BvhNode {
        min: bounds.min3(),
        left_or_first: first as u32,
        max: bounds.max3(),
        count: count as u32,
    }
}

#[inline(always)]
fn inner(bounds: &Aabb, left: usize) -> BvhNode {
    BvhNode {
        min: bounds.min3(),
        left_or_first: left as u32,
        max: bounds.max3(),
        count: 0,
    }
}

const PLACEHOLDER: BvhNode = BvhNode {
    min: [0.0; 3],
    left_or_first: 0,
    max: [0.0; 3],
    count: 0,
};

/// Partitions a range by `is_left` without a branch on the data (low in the tree a
/// split between bins sends neighbouring primitives either way at random, so a branchy
/// partition mispredicts about every other primitive): from a copy in `tmp`, every
/// primitive is written back both at the next left position and at the next right
/// position (counting down from the end) of `prims`, and only the cursor of its side
/// advances, so the other copy is overwritten later. Returns the size of the left side
/// (kept in order; the right side ends up reversed) and the two ranges.
///
/// Ranges above [`BRANCH_FREE_PARTITION`] primitives are partitioned in place from both
/// ends instead ([`partition_in_place`]).
#[inline(always)]
fn partition(
    prims: &mut [PrimRef],
    tmp: &mut Vec<PrimRef>,
    is_left: impl Fn(&PrimRef) -> bool + Sync,
) -> Split {
    let n = prims.len();
    if n > PAR_PARTITION_SIZE {
        return partition_parallel(prims, is_left);
    }
    if n > BRANCH_FREE_PARTITION {
        return partition_in_place(prims, is_left);
    }
    tmp.clear();
    tmp.extend_from_slice(prims);
    let (mut l, mut r) = (Range::EMPTY, Range::EMPTY);
    let (mut lo, mut hi) = (0usize, n);
    for p in tmp.iter() {
        let left = is_left(p);
        // lo < hi here: one slot is left for each primitive still to place.
        prims[lo] = *p;
        prims[hi - 1] = *p;
        lo += usize::from(left);
        hi -= usize::from(!left);
        l.grow_if(p, left);
        r.grow_if(p, !left);
    }
    (lo, l, r)
}

/// The largest range [`partition`] copies (32 KiB of primitives). Larger ranges sit higher
/// in the tree, where the mesh's own spatial order keeps the sides in long runs that the
/// branchy partition predicts well (1024 measured best against 256, 4096 and 16384 on
/// both benchmark meshes).
const BRANCH_FREE_PARTITION: usize = 1024;

/// Ranges above this many primitives are partitioned in parallel
/// ([`partition_parallel`]), in chunks of [`BIN_CHUNK`].
const PAR_PARTITION_SIZE: usize = PAR_BIN_SIZE;

/// In place and in parallel, for the few large ranges at the top of the tree, whose
/// partitions would otherwise run one after another on one thread while the others
/// wait (on sixteen threads the first four levels' partitions were a sixth of the build
/// of the 1.1M-triangle bunny): fixed chunks of [`BIN_CHUNK`] primitives are each
/// partitioned in place at once, which leaves the range as runs `L₀ R₀ L₁ R₁ …`; then
/// the right-hand primitives that lie in the first `L` positions (`L` the total left
/// count) trade places with the left-hand ones beyond them, in order, the pairs again
/// in parallel. Which primitives go where depends only on the data and the chunk size,
/// never on the threads.
fn partition_parallel(prims: &mut [PrimRef], is_left: impl Fn(&PrimRef) -> bool + Sync) -> Split {
    let n = prims.len();
    let chunks: Vec<(usize, Range, Range)> = prims
        .par_chunks_mut(BIN_CHUNK)
        .map(|c| partition_in_place(c, &is_left))
        .collect();
    let (mut l, mut r) = (Range::EMPTY, Range::EMPTY);
    let mut total_left = 0;
    for (lk, lr, rr) in &chunks {
        l = l.merge(*lr);
        r = r.merge(*rr);
        total_left += lk;
    }
    // The misplaced runs, in position order: each chunk's right run where it lies before
    // `total_left`, its left run where it lies from there on.
    let (mut front, mut back) = (Vec::new(), Vec::new());
    for (k, &(lk, _, _)) in chunks.iter().enumerate() {
        let (start, end) = (k * BIN_CHUNK, ((k + 1) * BIN_CHUNK).min(n));
        let split = start + lk;
        let (misplaced_right, misplaced_left) =
            (split..end.min(total_left), start.max(total_left)..split);
        if !misplaced_right.is_empty() {
            front.push(misplaced_right);
        }
        if !misplaced_left.is_empty() {
            back.push(misplaced_left);
        }
    }
    // Pairs of equal runs, one from each list, cut wherever either list's runs end.
    let mut pairs = Vec::new();
    let (mut fi, mut bi) = (front.into_iter(), back.into_iter());
    let (mut f, mut b) = (fi.next(), bi.next());
    while let (Some(fr), Some(br)) = (f.clone(), b.clone()) {
        let len = fr.len().min(br.len());
        pairs.push((fr.start..fr.start + len, br.start..br.start + len));
        f = if len == fr.len() {
            fi.next()
        } else {
            Some(fr.start + len..fr.end)
        };
        b = if len == br.len() {
            bi.next()
        } else {
            Some(br.start + len..br.end)
        };
    }
    assert!(
        f.is_none() && b.is_none(),
        "as many misplaced on either side"
    );
    /// The parts of `side` (whose first position is `offset`) at the increasing,
    /// disjoint `ranges`.
    fn slices(
        side: &mut [PrimRef],
        offset: usize,
        ranges: Vec<std::ops::Range<usize>>,
    ) -> Vec<&mut [PrimRef]> {
        let mut parts = Vec::with_capacity(ranges.len());
        let (mut rest, mut at) = (side, offset);
        for range in ranges {
            let (_, from) = std::mem::take(&mut rest).split_at_mut(range.start - at);
            let (part, after) = from.split_at_mut(range.len());
            parts.push(part);
            (rest, at) = (after, range.end);
        }
        parts
    }
    let (head, tail) = prims.split_at_mut(total_left);
    let (fronts, backs): (Vec<_>, Vec<_>) = pairs.into_iter().unzip();
    let fronts = slices(head, 0, fronts);
    let backs = slices(tail, total_left, backs);
    fronts
        .into_par_iter()
        .zip(backs)
        .for_each(|(a, b)| a.swap_with_slice(b));
    (total_left, l, r)
}

/// In-place partition from both ends; returns the size of the left side and both sides'
/// ranges.
#[inline(always)]
fn partition_in_place(prims: &mut [PrimRef], is_left: impl Fn(&PrimRef) -> bool) -> Split {
    let mut l = Range::EMPTY;
    let mut r = Range::EMPTY;
    let (mut i, mut j) = (0, prims.len());
    loop {
        while i < j && is_left(&prims[i]) {
            l.grow(&prims[i]);
            i += 1;
        }
        while i < j && !is_left(&prims[j - 1]) {
            r.grow(&prims[j - 1]);
            j -= 1;
        }
        if i == j {
            break;
        }
        // prims[i] belongs right and prims[j - 1] left.
        prims.swap(i, j - 1);
        l.grow(&prims[i]);
        r.grow(&prims[j - 1]);
        i += 1;
        j -= 1;
    }
    (i, l, r)
}

impl Builder {
    /// Leaf (`None`) or split of a range, with the old builder's rules: SAH termination
    /// (when enabled), leaves of at most `max_leaf_size`, a median split where all
    /// centroids coincide or past `MEDIAN_DEPTH`.
    #[inline(always)]
    fn decide(
        &self,
        prims: &mut [PrimRef],
        range: &Range,
        depth: usize,
        scratch: &mut Scratch,
    ) -> Option<Split> {
        let n = prims.len();
        let s = &self.settings;
        if n == 1 || n <= s.always_leaf || (!s.cost_termination && n <= s.max_leaf_size) {
            return None;
        }
        if depth >= MEDIAN_DEPTH {
            if n <= s.max_leaf_size {
                return None;
            }
            let d = range.cbounds.max - range.cbounds.min;
            let axis = if d.x > d.y && d.x > d.z {
                0
            } else if d.y > d.z {
                1
            } else {
                2
            };
            prims.select_nth_unstable_by(n / 2, |a, b| {
                a.centroid2()[axis].total_cmp(&b.centroid2()[axis])
            });
            return Some(median(prims));
        }
        let found = if n <= s.sweep_size {
            self.sweep_split(prims, range, scratch)
        } else {
            self.binned_split(prims, range, scratch)
        };
        match found {
            Some((plan, cost)) if cost < n as f32 || n > s.max_leaf_size || !s.cost_termination => {
                Some(match plan {
                    Plan::Binned(binner, 0, bin) => {
                        partition(prims, &mut scratch.tmp, |p| binner.bin::<0>(p) <= bin)
                    }
                    Plan::Binned(binner, 1, bin) => {
                        partition(prims, &mut scratch.tmp, |p| binner.bin::<1>(p) <= bin)
                    }
                    Plan::Binned(binner, _, bin) => {
                        partition(prims, &mut scratch.tmp, |p| binner.bin::<2>(p) <= bin)
                    }
                    Plan::Sorted(axis, k) => scratch.apply_order(prims, axis, k),
                    Plan::Pair(swap) => {
                        if swap {
                            prims.swap(0, 1);
                        }
                        (1, Range::of(&prims[..1]), Range::of(&prims[1..]))
                    }
                })
            }
            Some(_) => None,
            None if n <= s.max_leaf_size => None,
            // All centroids coincide: any split is as good.
            None => Some(median(prims)),
        }
    }

    /// The best binned SAH split and its cost relative to a leaf (SAH with traversal
    /// cost `traversal_cost` and primitive cost 1).
    #[inline(always)]
    fn binned_split(
        &self,
        prims: &[PrimRef],
        range: &Range,
        scratch: &mut Scratch,
    ) -> Option<(Plan, f32)> {
        let nb = if self.settings.scaled_bins {
            self.bins.min(8 + prims.len() / 8)
        } else {
            self.bins
        };
        let binner = Binner::new(&range.cbounds, nb);
        if binner.valid == [false; 3] {
            return None;
        }
        let par;
        let bins = if prims.len() > PAR_BIN_SIZE {
            par = prims
                .par_chunks(BIN_CHUNK)
                .map(|c| self.bin_chunk(c, &binner, nb))
                .reduce_with(Bins::merge)
                .expect("non-empty");
            &par
        } else {
            scratch.bins.reset(nb);
            if prims.len() >= INTERLEAVE_SIZE {
                scratch.bins2.reset(nb);
                scratch
                    .bins
                    .add_interleaved(&mut scratch.bins2, prims, &binner);
            } else {
                scratch.bins.add(prims, &binner);
            }
            &scratch.bins
        };
        // Minimise area-weighted counts (the parent's area and the traversal cost are
        // the same for every candidate), for the three axes at once.
        let right = &mut scratch.right;
        let (mut acc, mut cnt) = ([Aabb::EMPTY; 3], [0u32; 4]);
        for b in (1..nb).rev() {
            for axis in 0..3 {
                acc[axis] = acc[axis].union(&bins.boxes[b][axis]);
                cnt[axis] += bins.counts[b][axis];
            }
            let c = counts4(&cnt);
            right[b] = (half_areas(&acc) * c, c);
        }
        let valid = Vec4::new(
            f32::from(u8::from(binner.valid[0])),
            f32::from(u8::from(binner.valid[1])),
            f32::from(u8::from(binner.valid[2])),
            0.0,
        )
        .cmpgt(Vec4::ZERO);
        let mut best = Vec4::INFINITY;
        let mut best_bin = Vec4::ZERO;
        let (mut acc, mut cnt) = ([Aabb::EMPTY; 3], [0u32; 4]);
        for b in 0..nb - 1 {
            for axis in 0..3 {
                acc[axis] = acc[axis].union(&bins.boxes[b][axis]);
                cnt[axis] += bins.counts[b][axis];
            }
            let c = counts4(&cnt);
            let (rcost, rc) = right[b + 1];
            let cost = half_areas(&acc) * c + rcost;
            // Strictly lower: the first of equal candidates along an axis wins.
            let better = valid & c.cmpgt(Vec4::ZERO) & rc.cmpgt(Vec4::ZERO) & cost.cmplt(best);
            best = Vec4::select(better, cost, best);
            best_bin = Vec4::select(better, Vec4::splat(b as f32), best_bin);
        }
        let axis = best_axis(best);
        let c = best[axis];
        (c < f32::INFINITY).then(|| {
            (
                Plan::Binned(binner, axis, best_bin[axis] as usize),
                self.cost(c, range),
            )
        })
    }

    /// The SAH cost of a split relative to a leaf, from its area-weighted counts.
    #[inline(always)]
    fn cost(&self, weighted: f32, range: &Range) -> f32 {
        let area = range.bounds.half_area().max(f32::MIN_POSITIVE);
        self.settings.traversal_cost + weighted / area
    }

    /// The best split of a small range between any two neighbours in centroid order (a
    /// full SAH sweep, of which the binned candidates are a subset), the three axes at
    /// once in the lanes of a `Vec4`.
    #[inline(always)]
    fn sweep_split(
        &self,
        prims: &[PrimRef],
        range: &Range,
        scratch: &mut Scratch,
    ) -> Option<(Plan, f32)> {
        let n = prims.len();
        let extent = range.cbounds.max - range.cbounds.min;
        let valid = extent.cmpgt(Vec4::ZERO) & BVec4A::new(true, true, true, false);
        if !valid.any() {
            return None;
        }
        if n == 2 {
            // One candidate, the same on every axis; the sweep would take the first
            // axis along which the centroids spread and order the two along it.
            let axis = valid.bitmask().trailing_zeros() as usize;
            let c = prims[0].half_area() + prims[1].half_area();
            let swap = prims[1].centroid2()[axis] < prims[0].centroid2()[axis];
            return Some((Plan::Pair(swap), self.cost(c, range)));
        }
        // Sort keys: the centroid's bits, made to order as the floats do, then the
        // position in the range (ties in range order, so the sort is deterministic).
        let order = &mut scratch.order;
        for o in order.iter_mut() {
            o.clear();
        }
        for (i, p) in prims.iter().enumerate() {
            let c = p.centroid2();
            for (axis, o) in order.iter_mut().enumerate() {
                let bits = c[axis].to_bits();
                let ordered = if bits >> 31 == 0 {
                    bits | 0x8000_0000
                } else {
                    !bits
                };
                o.push(u64::from(ordered) << 32 | i as u64);
            }
        }
        for (axis, o) in order.iter_mut().enumerate() {
            if valid.test(axis) {
                sort_keys(o);
            }
        }
        let at = |axis: usize, k: usize| &prims[order[axis][k] as u32 as usize];
        let right = &mut scratch.sweep_right;
        right.resize(n, Vec4::ZERO);
        let mut acc = [Aabb::EMPTY; 3];
        for k in (1..n).rev() {
            for (axis, a) in acc.iter_mut().enumerate() {
                a.grow(at(axis, k));
            }
            right[k] = half_areas(&acc) * (n - k) as f32;
        }
        let mut best = Vec4::INFINITY;
        let mut best_k = Vec4::ZERO;
        let mut acc = [Aabb::EMPTY; 3];
        for (k, &r) in right.iter().enumerate().skip(1) {
            for (axis, a) in acc.iter_mut().enumerate() {
                a.grow(at(axis, k - 1));
            }
            let cost = half_areas(&acc) * k as f32 + r;
            let better = valid & cost.cmplt(best);
            best = Vec4::select(better, cost, best);
            best_k = Vec4::select(better, Vec4::splat(k as f32), best_k);
        }
        let axis = best_axis(best);
        let c = best[axis];
        (c < f32::INFINITY).then(|| {
            (
                Plan::Sorted(axis, best_k[axis] as usize),
                self.cost(c, range),
            )
        })
    }

    /// Builds the subtree of a range into the task's nodes, its root at `at`; returns
    /// its depth. A loop over an explicit stack instead of a recursion, so that the
    /// whole task inlines into the copy compiled for AVX2; the left child is taken
    /// first, so nodes are allocated in the recursion's order (depth first, siblings
    /// adjacent).
    #[inline(always)]
    fn build_subtree(
        &self,
        prims: &mut [PrimRef],
        offset: usize,
        range: &Range,
        depth: usize,
        task: &mut Task,
    ) -> usize {
        let mut stack = vec![Pending {
            start: 0,
            end: prims.len(),
            range: *range,
            depth,
            at: 0,
        }];
        let mut max_depth = depth;
        while let Some(p) = stack.pop() {
            let part = &mut prims[p.start..p.end];
            match self.decide(part, &p.range, p.depth, &mut task.scratch) {
                None => {
                    task.nodes[p.at] = leaf(&p.range.bounds, offset + p.start, part.len());
                    max_depth = max_depth.max(p.depth);
                }
                Some((mid, l, r)) => {
                    let left = task.nodes.len();
                    task.nodes.push(PLACEHOLDER);
                    task.nodes.push(PLACEHOLDER);
                    task.nodes[p.at] = inner(&p.range.bounds, left);
                    stack.push(Pending {
                        start: p.start + mid,
                        end: p.end,
                        range: r,
                        depth: p.depth + 1,
                        at: left + 1,
                    });
                    stack.push(Pending {
                        start: p.start,
                        end: p.start + mid,
                        range: l,
                        depth: p.depth + 1,
                        at: left,
                    });
                }
            }
        }
        max_depth
    }

    /// One task: the subtree of a range in its own node array.
    fn build_task(
        &self,
        prims: &mut [PrimRef],
        offset: usize,
        range: &Range,
        depth: usize,
    ) -> (Vec<BvhNode>, usize) {
        // A binary tree over n primitives has at most 2n − 1 nodes.
        let mut task = Task {
            nodes: Vec::with_capacity(2 * prims.len()),
            scratch: Scratch::take(self.bins),
        };
        task.nodes.push(PLACEHOLDER);
        #[cfg(target_arch = "x86_64")]
        let d = if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has these features.
            unsafe { self.build_subtree_avx2(prims, offset, range, depth, &mut task) }
        } else {
            self.build_subtree(prims, offset, range, depth, &mut task)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let d = self.build_subtree(prims, offset, range, depth, &mut task);
        task.scratch.put_back();
        (task.nodes, d)
    }

    /// [`Builder::build_subtree`] compiled for AVX2: the rank sort of the small ranges'
    /// sweep compares 64-bit keys four at a time (SSE2 has no 64-bit compare), and the
    /// box arithmetic needs no register copies (three-operand encodings). 2-4 % off the
    /// whole build of the 1.1M-triangle bunny (medians of 5 and 8 rounds alternated with
    /// the portable code, one and two threads).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn build_subtree_avx2(
        &self,
        prims: &mut [PrimRef],
        offset: usize,
        range: &Range,
        depth: usize,
        task: &mut Task,
    ) -> usize {
        self.build_subtree(prims, offset, range, depth, task)
    }

    /// [`Builder::decide`] for a range above the tasks, in the AVX2 copy where there is
    /// one.
    fn decide_top(
        &self,
        prims: &mut [PrimRef],
        range: &Range,
        depth: usize,
        scratch: &mut Scratch,
    ) -> Option<Split> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has these features.
            return unsafe { self.decide_avx2(prims, range, depth, scratch) };
        }
        self.decide(prims, range, depth, scratch)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn decide_avx2(
        &self,
        prims: &mut [PrimRef],
        range: &Range,
        depth: usize,
        scratch: &mut Scratch,
    ) -> Option<Split> {
        self.decide(prims, range, depth, scratch)
    }

    /// The `bins` bins of one chunk of a range binned in parallel.
    fn bin_chunk(&self, prims: &[PrimRef], binner: &Binner, bins: usize) -> Bins {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has these features.
            return unsafe { bin_chunk_avx2(prims, binner, bins) };
        }
        bin_chunk_body(prims, binner, bins)
    }

    /// The tree of a range, and its primitives' indices in their final order written to
    /// `indices` (as each task ends, while its references are still in cache, rather
    /// than in a pass of its own over all of them).
    fn build_top(
        &self,
        prims: &mut [PrimRef],
        indices: &mut [MaybeUninit<u32>],
        offset: usize,
        range: &Range,
        depth: usize,
    ) -> (Top, usize) {
        if prims.len() <= TASK_SIZE {
            let (nodes, d) = self.build_task(prims, offset, range, depth);
            write_indices(prims, indices);
            return (Top::Sub(nodes), d);
        }
        let mut scratch = Scratch::take(self.bins);
        let decided = self.decide_top(prims, range, depth, &mut scratch);
        scratch.put_back();
        match decided {
            None => {
                write_indices(prims, indices);
                (
                    Top::Sub(vec![leaf(&range.bounds, offset, prims.len())]),
                    depth,
                )
            }
            Some((mid, l, r)) => {
                let (a, b) = prims.split_at_mut(mid);
                let (ia, ib) = indices.split_at_mut(mid);
                let ((lt, dl), (rt, dr)) = rayon::join(
                    || self.build_top(a, ia, offset, &l, depth + 1),
                    || self.build_top(b, ib, offset + mid, &r, depth + 1),
                );
                (Top::Inner(range.bounds, Box::new([lt, rt])), dl.max(dr))
            }
        }
    }
}

/// The primitives' indices, in their order, into `out` (as long).
fn write_indices(prims: &[PrimRef], out: &mut [MaybeUninit<u32>]) {
    assert_eq!(prims.len(), out.len());
    for (o, p) in out.iter_mut().zip(prims) {
        o.write(p.index());
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn bin_chunk_avx2(prims: &[PrimRef], binner: &Binner, bins: usize) -> Bins {
    bin_chunk_body(prims, binner, bins)
}

#[inline(always)]
fn bin_chunk_body(prims: &[PrimRef], binner: &Binner, bins: usize) -> Bins {
    let mut b = Bins::new(bins);
    b.add_interleaved(&mut Bins::new(bins), prims, binner);
    b
}

/// The axis (lane) of the lowest cost; between equal ones the first.
#[inline(always)]
fn best_axis(cost: Vec4) -> usize {
    let mut axis = 0;
    for a in 1..3 {
        if cost[a] < cost[axis] {
            axis = a;
        }
    }
    axis
}

/// Splits at the middle and measures both halves.
#[inline(always)]
fn median(prims: &[PrimRef]) -> Split {
    let mid = prims.len() / 2;
    (mid, Range::of(&prims[..mid]), Range::of(&prims[mid..]))
}

/// A balanced tree over primitives with empty boxes (which no ray can hit), in leaves of
/// at most `max_leaf` primitives; returns its depth.
fn build_empty(
    count: usize,
    offset: usize,
    max_leaf: usize,
    depth: usize,
    nodes: &mut Vec<BvhNode>,
    at: usize,
) -> usize {
    if count <= max_leaf.max(1) {
        nodes[at] = leaf(&Aabb::EMPTY, offset, count);
        return depth;
    }
    let left = nodes.len();
    nodes.push(PLACEHOLDER);
    nodes.push(PLACEHOLDER);
    nodes[at] = inner(&Aabb::EMPTY, left);
    let mid = count / 2;
    let dl = build_empty(mid, offset, max_leaf, depth + 1, nodes, left);
    let dr = build_empty(
        count - mid,
        offset + mid,
        max_leaf,
        depth + 1,
        nodes,
        left + 1,
    );
    dl.max(dr)
}

/// A subtree's node with its local child index k ≥ 1 moved to base + k − 1.
#[inline]
fn relocate(n: &BvhNode, base: usize) -> BvhNode {
    let mut n = *n;
    if n.count == 0 {
        n.left_or_first = (n.left_or_first as usize + base - 1) as u32;
    }
    n
}

/// The array of `top`: the same layout as writing it depth first (an inner node's two
/// children side by side after the current end, a subtree's nodes after its root's
/// slot), laid out first and then written in parallel (a serial copy of the 1.1M-triangle
/// bunny's 2.2M nodes took 5 ms, 3% of the build on two threads and 6% on sixteen).
fn flatten(top: Top) -> Vec<BvhNode> {
    /// Where `top` goes: its root's slot `at` in `singles`, the rest of a subtree as a
    /// block at its base; `len` is the array's length so far.
    fn lay_out<'a>(
        top: &'a Top,
        at: usize,
        len: &mut usize,
        singles: &mut Vec<(usize, BvhNode)>,
        blocks: &mut Vec<(usize, &'a [BvhNode])>,
    ) {
        match top {
            Top::Sub(sub) => {
                // Local index k ≥ 1 goes to base + k − 1; the root goes to `at`.
                let base = *len;
                singles.push((at, relocate(&sub[0], base)));
                // A subtree that is one leaf has no block: an empty one would sort after
                // the single at its base and break the tiling.
                if sub.len() > 1 {
                    blocks.push((base, &sub[1..]));
                }
                *len += sub.len() - 1;
            }
            Top::Inner(bounds, children) => {
                let left = *len;
                *len += 2;
                singles.push((at, inner(bounds, left)));
                lay_out(&children[0], left, len, singles, blocks);
                lay_out(&children[1], left + 1, len, singles, blocks);
            }
        }
    }
    let (mut singles, mut blocks) = (Vec::new(), Vec::new());
    let mut len = 1;
    lay_out(&top, 0, &mut len, &mut singles, &mut blocks);
    // The pieces in the array's order: they tile it, each position once.
    enum Piece<'a> {
        Single(BvhNode),
        /// Relocated to its position in the array.
        Block(&'a [BvhNode]),
    }
    let mut pieces: Vec<(usize, Piece)> = singles
        .into_iter()
        .map(|(at, n)| (at, Piece::Single(n)))
        .chain(blocks.into_iter().map(|(base, b)| (base, Piece::Block(b))))
        .collect();
    pieces.sort_by_key(|&(at, _)| at);
    let piece_len = |p: &Piece| match p {
        Piece::Single(_) => 1,
        Piece::Block(b) => b.len(),
    };
    let mut nodes = super::memory::with_capacity_huge::<BvhNode>(len);
    let parts = super::collapse::split_into(
        &mut nodes.spare_capacity_mut()[..len],
        pieces.iter().map(|(_, p)| piece_len(p)),
    );
    let mut next = 0;
    for (at, p) in &pieces {
        assert_eq!(*at, next, "the pieces tile the array");
        next += piece_len(p);
    }
    assert_eq!(next, len, "the pieces tile the array");
    pieces
        .par_iter()
        .zip(parts)
        .with_min_len(16)
        .for_each(|((at, piece), part)| match piece {
            Piece::Single(n) => {
                part[0].write(*n);
            }
            Piece::Block(block) => {
                for (dst, n) in part.iter_mut().zip(block.iter()) {
                    dst.write(relocate(n, *at));
                }
            }
        });
    // SAFETY: the pieces tile positions 0..len (asserted above), and each part, a piece's
    // positions, was written in full above.
    unsafe { nodes.set_len(len) };
    nodes
}

fn node_box(n: &BvhNode) -> Aabb {
    Aabb {
        min: Vec3::from_array(n.min).extend(0.0),
        max: Vec3::from_array(n.max).extend(0.0),
    }
}

/// Reinsertion (Bittner et al. 2013, sequential): each of the largest nodes in turn is
/// taken out of the tree (its sibling takes its parent's place) and put back beside the
/// node where it adds the least SAH cost (found by branch and bound from the root), which
/// may be where it was. `fraction` of the nodes, largest first, in each of `passes`
/// passes. Deterministic: one fixed order.
fn reinsert(nodes: &mut [BvhNode], passes: usize, fraction: f32) {
    const NONE: u32 = u32::MAX;
    if nodes.len() < 5 {
        return; // nothing below the root's children
    }
    let mut parent = vec![NONE; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if n.count == 0 {
            parent[n.left_or_first as usize] = i as u32;
            parent[n.left_or_first as usize + 1] = i as u32;
        }
    }
    let area = |n: &BvhNode| node_box(n).half_area();
    // Recomputes the boxes of `at` and its ancestors (while they change).
    fn refit(nodes: &mut [BvhNode], parent: &[u32], mut at: u32) {
        while at != u32::MAX {
            let n = &nodes[at as usize];
            let c = n.left_or_first as usize;
            let b = node_box(&nodes[c]).union(&node_box(&nodes[c + 1]));
            let (min, max) = (b.min3(), b.max3());
            let n = &mut nodes[at as usize];
            if n.min == min && n.max == max {
                break;
            }
            n.min = min;
            n.max = max;
            at = parent[at as usize];
        }
    }
    let mut heap = std::collections::BinaryHeap::new();
    for _ in 0..passes {
        let mut order: Vec<(f32, u32)> = (1..nodes.len() as u32)
            .map(|i| (area(&nodes[i as usize]), i))
            .collect();
        let take = ((order.len() as f32 * fraction) as usize).clamp(1, order.len());
        order.select_nth_unstable_by(take - 1, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        order.truncate(take);
        order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for &(_, n) in &order {
            let p = parent[n as usize];
            if p == NONE || parent[p as usize] == NONE {
                continue; // the root or a child of the root
            }
            let pair = nodes[p as usize].left_or_first;
            let s = if n == pair { pair + 1 } else { pair };
            // Take n out: its sibling's record moves into the parent's slot.
            nodes[p as usize] = nodes[s as usize];
            if nodes[p as usize].count == 0 {
                let c = nodes[p as usize].left_or_first as usize;
                parent[c] = p;
                parent[c + 1] = p;
            }
            refit(nodes, &parent, parent[p as usize]);
            // The best node to pair n with.
            let nb = node_box(&nodes[n as usize]);
            let na = nb.half_area();
            let mut best = (f32::INFINITY, 0u32);
            heap.clear();
            // Keyed by the induced cost's bits: it is never negative, and non-negative
            // floats order as their bits do.
            heap.push((Reverse(0.0f32.to_bits()), 0u32));
            while let Some((Reverse(induced), x)) = heap.pop() {
                let induced = f32::from_bits(induced);
                if induced + na >= best.0 {
                    break;
                }
                let xb = node_box(&nodes[x as usize]);
                let joined = xb.union(&nb).half_area();
                if induced + joined < best.0 {
                    best = (induced + joined, x);
                }
                let xn = &nodes[x as usize];
                if xn.count == 0 {
                    let child_induced = induced + joined - xb.half_area();
                    if child_induced + na < best.0 {
                        let c = xn.left_or_first;
                        heap.push((Reverse(child_induced.to_bits()), c));
                        heap.push((Reverse(child_induced.to_bits()), c + 1));
                    }
                }
            }
            // Pair n with x: x's record moves into the free slot s, a new inner node
            // over the pair (n, s) takes x's slot.
            let x = best.1;
            nodes[s as usize] = nodes[x as usize];
            if nodes[s as usize].count == 0 {
                let c = nodes[s as usize].left_or_first as usize;
                parent[c] = s;
                parent[c + 1] = s;
            }
            let b = node_box(&nodes[s as usize]).union(&nb);
            nodes[x as usize] = BvhNode {
                min: b.min3(),
                left_or_first: pair,
                max: b.max3(),
                count: 0,
            };
            parent[n as usize] = x;
            parent[s as usize] = x;
            refit(nodes, &parent, parent[x as usize]);
        }
    }
}

/// The nodes in depth-first order with siblings adjacent (the builder's layout, which
/// reinsertion disturbs); returns them with the tree's depth (the root alone: 1).
fn relayout(nodes: &[BvhNode]) -> (Vec<BvhNode>, usize) {
    let mut out = Vec::with_capacity(nodes.len());
    out.push(PLACEHOLDER);
    let mut stack = vec![(0usize, 0usize, 1usize)];
    let mut max_depth = 1;
    while let Some((old, new, depth)) = stack.pop() {
        max_depth = max_depth.max(depth);
        let mut n = nodes[old];
        if n.count == 0 {
            let left = out.len();
            out.push(PLACEHOLDER);
            out.push(PLACEHOLDER);
            let c = n.left_or_first as usize;
            stack.push((c + 1, left + 1, depth + 1));
            stack.push((c, left, depth + 1));
            n.left_or_first = left as u32;
        }
        out[new] = n;
    }
    (out, max_depth)
}

/// Builds the nodes and primitive order of a BVH over the `n` boxes (`n > 0`) that
/// `box_of` gives by index (called once each); returns them
/// with the tree's depth (the root alone: 1).
pub(super) fn build_from(
    n: usize,
    box_of: impl Fn(usize) -> Bounds3 + Sync,
    settings: &BuildSettings,
) -> (Vec<BvhNode>, Vec<u32>, usize) {
    build_with(n, box_of, settings, crate::cpu::has_avx2())
}

/// The primitive references of `n` boxes, the range of those that are not empty (which
/// come first, in index order, then the empty ones, in index order) and how many are
/// empty. One parallel pass writes the references and finds the range and the empty
/// ones; only where there are empty boxes (rare) a second, serial one moves them last.
fn prim_refs(n: usize, box_of: impl Fn(usize) -> Bounds3 + Sync) -> (Vec<PrimRef>, Range, usize) {
    // In huge pages: 32 bytes a primitive, written once and then binned and partitioned
    // level after level.
    let mut prims: Vec<PrimRef> = super::memory::with_capacity_huge(n);
    let (range, empty) = prims.spare_capacity_mut()[..n]
        .par_chunks_mut(BIN_CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let (mut range, mut empty) = (Range::EMPTY, 0usize);
            for (k, slot) in chunk.iter_mut().enumerate() {
                let i = c * BIN_CHUNK + k;
                let b = box_of(i);
                let p = PrimRef::new(&b, i as u32);
                if b.is_empty() {
                    empty += 1;
                } else {
                    range.grow(&p);
                }
                slot.write(p);
            }
            (range, empty)
        })
        .reduce(|| (Range::EMPTY, 0), |(a, m), (b, k)| (a.merge(b), m + k));
    // SAFETY: the chunks tile positions 0..n, and each position was written above.
    unsafe { prims.set_len(n) };
    if empty > 0 {
        let (mut full, empties): (Vec<PrimRef>, Vec<PrimRef>) =
            prims.into_iter().partition(|p| !p.is_empty());
        full.extend(empties);
        prims = full;
    }
    (prims, range, empty)
}

/// [`build_from`], with the AVX2 copies of the code (where the processor has them) or
/// without.
fn build_with(
    n: usize,
    box_of: impl Fn(usize) -> Bounds3 + Sync,
    settings: &BuildSettings,
    avx2: bool,
) -> (Vec<BvhNode>, Vec<u32>, usize) {
    assert!(
        u32::try_from(n).is_ok(),
        "a BVH takes at most 2^32 primitives"
    );
    let builder = Builder {
        settings: *settings,
        bins: settings.bins.clamp(2, MAX_BINS),
        avx2,
    };
    // Boxes that are empty go last, into a subtree of their own.
    let (mut prims, range, empty) = prim_refs(n, box_of);
    let full = n - empty;
    // Every position is written: the references of each task or leaf of the build's
    // top, and those of the empty boxes.
    let mut prim_indices: Vec<u32> = super::memory::with_capacity_huge(n);
    let (top, depth) = {
        let (full_prims, empty_prims) = prims.split_at_mut(full);
        let (full_indices, empty_indices) =
            prim_indices.spare_capacity_mut()[..n].split_at_mut(full);
        write_indices(empty_prims, empty_indices);
        let empty_tree = || {
            let mut nodes = vec![PLACEHOLDER];
            let d = build_empty(
                empty_prims.len(),
                full,
                settings.max_leaf_size,
                usize::from(full > 0),
                &mut nodes,
                0,
            );
            (Top::Sub(nodes), d)
        };
        if full == 0 {
            empty_tree()
        } else {
            if empty == 0 {
                builder.build_top(full_prims, full_indices, 0, &range, 0)
            } else {
                let (t, d) = builder.build_top(full_prims, full_indices, 0, &range, 1);
                let (e, de) = empty_tree();
                (Top::Inner(range.bounds, Box::new([t, e])), d.max(de))
            }
        }
    };
    let nodes = match top {
        Top::Sub(nodes) => nodes,
        top => flatten(top),
    };
    // SAFETY: every position below `n` was written above.
    unsafe { prim_indices.set_len(n) };
    if settings.reinsertion_passes > 0 && settings.traversal_cost > 0.0 && empty == 0 {
        let mut optimised = nodes.clone();
        reinsert(&mut optimised, settings.reinsertion_passes, 1.0);
        let (optimised, optimised_depth) = relayout(&optimised);
        // Reinsertion deepens some subtrees: keep it only within the traversal stack.
        if optimised_depth <= STACK_SIZE - 8 {
            return (optimised, prim_indices, optimised_depth);
        }
    }
    (nodes, prim_indices, depth + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both partitions put the same primitives left (all that satisfy the predicate, and
    /// only those) and return the same ranges, bit for bit, for sizes on both sides of
    /// the copy limit and the parallel one, and predicates from all-left to all-right.
    #[test]
    fn partitions_agree() {
        let mut rng = crate::sampling::Pcg32::new(5, 9);
        let sizes = [
            0,
            1,
            2,
            3,
            63,
            64,
            65,
            1000,
            BRANCH_FREE_PARTITION,
            5000,
            PAR_PARTITION_SIZE + 1,
            3 * BIN_CHUNK + 1234,
            10 * BIN_CHUNK,
        ];
        for n in sizes {
            for threshold in [0.0f32, 0.1, 0.5, 0.9, 1.01] {
                let prims: Vec<PrimRef> = (0..n as u32)
                    .map(|i| {
                        let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                        let e = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.1;
                        PrimRef::new(&Bounds3::new(c - e, c + e), i)
                    })
                    .collect();
                let is_left = |p: &PrimRef| p.centroid2().x < 2.0 * threshold;
                let check = |v: &[PrimRef], (k, l, r): Split| {
                    assert!(v[..k].iter().all(is_left) && !v[k..].iter().any(is_left));
                    let mut left: Vec<u32> = v[..k].iter().map(PrimRef::index).collect();
                    left.sort_unstable();
                    let bits = |r: &Range| {
                        [r.bounds.min, r.bounds.max, r.cbounds.min, r.cbounds.max]
                            .map(|v| v.to_array().map(f32::to_bits))
                    };
                    (left, bits(&l), bits(&r))
                };
                let mut a = prims.clone();
                let split = partition_in_place(&mut a, is_left);
                let want = check(&a, split);
                let mut b = prims.clone();
                let split = partition(&mut b, &mut Vec::new(), is_left);
                assert_eq!(check(&b, split), want, "{n} {threshold}");
            }
        }
    }

    /// The primitive references of a set of boxes: the non-empty ones first and the
    /// empty ones last, each in index order, with the range of the non-empty ones (bit
    /// for bit that of a serial pass over them) and the number of empty ones, for sizes
    /// on both sides of the parallel chunks and with no, some and only empty boxes.
    #[test]
    fn prim_refs_put_empty_boxes_last() {
        let mut rng = crate::sampling::Pcg32::new(3, 17);
        for n in [
            0usize,
            1,
            6,
            BIN_CHUNK - 1,
            BIN_CHUNK + 5,
            3 * BIN_CHUNK + 777,
        ] {
            for empty_every in [0usize, 1, 7] {
                let boxes: Vec<Bounds3> = (0..n)
                    .map(|i| {
                        if empty_every > 0 && i % empty_every == 0 {
                            return Bounds3::EMPTY;
                        }
                        let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                        let e = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.1;
                        Bounds3::new(c - e, c + e)
                    })
                    .collect();
                let (prims, range, empty) = prim_refs(n, |i| boxes[i]);
                let is_empty = |i: &u32| boxes[*i as usize].is_empty();
                let want: Vec<u32> = (0..n as u32)
                    .filter(|i| !is_empty(i))
                    .chain((0..n as u32).filter(is_empty))
                    .collect();
                let got: Vec<u32> = prims.iter().map(PrimRef::index).collect();
                assert_eq!(got, want, "n = {n}, every {empty_every}");
                assert_eq!(empty, (0..n as u32).filter(is_empty).count());
                let full = Range::of(&prims[..n - empty]);
                let bits = |r: &Range| {
                    [r.bounds.min, r.bounds.max, r.cbounds.min, r.cbounds.max]
                        .map(|v| v.truncate().to_array().map(f32::to_bits))
                };
                assert_eq!(bits(&range), bits(&full), "n = {n}, every {empty_every}");
            }
        }
    }

    /// The AVX2 copy of the build makes the same tree as the portable code, bit for bit
    /// (node boxes, children, leaf ranges and primitive order), with the small ranges'
    /// scaled bins and without, on a mesh-like soup large enough for parallel binning
    /// and many tasks.
    #[test]
    fn avx2_build_equals_the_portable_build() {
        if !crate::cpu::has_avx2() {
            return;
        }
        let mut rng = crate::sampling::Pcg32::new(21, 4);
        let boxes: Vec<Bounds3> = (0..150_000)
            .map(|i| {
                // Clustered centres (runs of nearby boxes, as a mesh's triangles are)
                // and some duplicates, so that every kind of split occurs.
                let k = (i / 64) as f32;
                let base = Vec3::new((k * 0.37).sin(), (k * 0.11).cos(), (k * 0.05).sin());
                let c = if i % 97 == 0 {
                    base
                } else {
                    base + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.02
                };
                let e = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.004;
                Bounds3::new(c - e, c + e)
            })
            .collect();
        for settings in [
            BuildSettings::QUALITY,
            BuildSettings::HIGH,
            BuildSettings::FAST,
        ] {
            let bits = |(nodes, order, depth): (Vec<BvhNode>, Vec<u32>, usize)| {
                let nodes: Vec<[u32; 8]> = nodes
                    .iter()
                    .map(|n| {
                        let (a, b) = (n.min.map(f32::to_bits), n.max.map(f32::to_bits));
                        [a[0], a[1], a[2], n.left_or_first, b[0], b[1], b[2], n.count]
                    })
                    .collect();
                (nodes, order, depth)
            };
            let portable = bits(build_with(boxes.len(), |i| boxes[i], &settings, false));
            let avx2 = bits(build_with(boxes.len(), |i| boxes[i], &settings, true));
            assert!(portable.0.len() > 1000);
            assert!(portable == avx2, "{settings:?}");
        }
    }

    /// A parallel build whose top splits off a few primitives that become one leaf (a
    /// Cornell box's twelve wall triangles merged with a 69k-triangle bunny, the first
    /// case seen) lays its array out whole: such a subtree once left an empty block in the
    /// layout that broke its tiling (a panic).
    #[test]
    fn a_top_level_leaf_lays_out() {
        let mut rng = crate::sampling::Pcg32::new(7, 1);
        let mut boxes: Vec<Bounds3> = (0..3 * TASK_SIZE)
            .map(|_| {
                let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                Bounds3::new(c, c + Vec3::splat(1e-3))
            })
            .collect();
        // Walls, far larger than the cluster, around it.
        for k in 0..12 {
            let (lo, hi) = (Vec3::splat(-400.0), Vec3::splat(400.0));
            let mut b = Bounds3::new(lo, hi);
            let axis = k % 3;
            let side = if k % 2 == 0 { -400.0 } else { 400.0 };
            b.min[axis] = side;
            b.max[axis] = side;
            boxes.push(b);
        }
        for settings in [BuildSettings::default(), BuildSettings::HIGH] {
            let bvh = crate::accel::Bvh::build(&boxes, &settings);
            bvh.validate(&boxes).unwrap();
        }
    }

    #[test]
    fn rank_sort_equals_the_library_sort() {
        let mut rng = crate::sampling::Pcg32::new(11, 3);
        for n in (0..=RANK_SORT_SIZE + 2).chain([40, 64]) {
            for _ in 0..50 {
                // Sweep keys: random high halves (some equal), distinct positions below.
                let mut keys: Vec<u64> = (0..n as u64)
                    .map(|i| u64::from(rng.next_u32() % 8) << 32 | i)
                    .collect();
                let mut expected = keys.clone();
                expected.sort_unstable();
                sort_keys(&mut keys);
                assert_eq!(keys, expected, "n = {n}");
            }
        }
    }
}
