//! Collapsing a binary BVH into a tree of `W`-wide nodes (shared by the 4- and 8-wide
//! BVHs), with leaves laid out for SIMD primitive blocks.
//!
//! The collapse is SAH-optimal ([`plan`]): which descendants of a binary node become the
//! up-to-`W` slots of its wide node, and which subtrees become leaves, is the choice of
//! least expected cost under a model of node and leaf tests, found by dynamic
//! programming over the binary tree. A subtree of at most four blocks of [`LEAF_ALIGN`]
//! primitives may become one leaf, whose primitives are tested together as SIMD blocks.
//! Leaves are then moved to positions that
//! are multiples of [`LEAF_ALIGN`] and padded to a multiple of it by repeating their last
//! primitive, so that a primitive owner can keep its data in blocks that match the leaves
//! ([`crate::geometry::TriangleBlock`]); leaves keep their true counts.
//!
//! Whether a subtree can become a leaf and its plan are read from tables filled in one
//! parallel pass from the leaves up ([`plan`]); the top levels of the wide tree are built in
//! parallel and concatenated once, and the leaves are placed in parallel.

use super::bvh::Bvh;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};

/// Leaves start at multiples of this and are padded to it.
pub const LEAF_ALIGN: usize = 4;

/// A subtree of at most this many primitives (four blocks) may become a leaf.
const MERGE_LIMIT: usize = 4 * LEAF_ALIGN;

/// Marks an unused slot.
pub const EMPTY: u32 = u32::MAX;

/// One child of a wide node: its box, and an inner node's index (count 0) or a leaf's
/// first position and primitive count (`EMPTY` for an unused slot).
#[derive(Debug, Clone, Copy)]
pub struct Slot {
    pub min: [f32; 3],
    pub max: [f32; 3],
    pub child: u32,
    pub count: u32,
}

const UNUSED: Slot = Slot {
    min: [f32::INFINITY; 3],
    max: [f32::INFINITY; 3],
    child: 0,
    count: EMPTY,
};

/// A collapsed tree: nodes of `W` slots, the root slot and the padded leaf order.
pub struct Collapsed<const W: usize> {
    pub nodes: Vec<[Slot; W]>,
    pub root: (u32, u32),
    pub prim_order: Vec<u32>,
    /// The tree's cost under the collapse's model (`COST_NODE` per wide node,
    /// [`leaf_cost`] per leaf, each times its box's surface area), relative to the
    /// root's surface area: the statistic the collapse minimises.
    pub cost: f32,
}

/// Builds the binary tree a wide BVH is collapsed from, and returns it with the moment
/// the build started: subtrees of one block become leaves in the collapse, so the
/// binary build stops there (`BuildSettings::always_leaf`).
pub fn build_binary(
    n: usize,
    box_of: impl Fn(usize) -> crate::math::Bounds3 + Sync,
    settings: &super::bvh::BuildSettings,
) -> (Bvh, std::time::Instant) {
    let start = std::time::Instant::now();
    let settings = super::bvh::BuildSettings {
        always_leaf: LEAF_ALIGN,
        ..*settings
    };
    (Bvh::build_unmeasured(n, box_of, &settings), start)
}

/// A closest-hit leaf callback that hands each primitive of the leaf to `hit`.
#[inline(always)]
pub fn each_prim<'a, F: FnMut(u32, &mut f32) -> bool + 'a>(
    prims: &'a [u32],
    mut hit: F,
) -> impl FnMut(u32, u32, &mut f32) -> bool + 'a {
    move |first, count, t_max| {
        let mut any = false;
        for &prim in &prims[first as usize..(first + count) as usize] {
            any |= hit(prim, t_max);
        }
        any
    }
}

/// An any-hit leaf callback that asks `blocks` for each primitive of the leaf.
#[inline(always)]
pub fn any_prim<'a, F: FnMut(u32) -> bool + 'a>(
    prims: &'a [u32],
    mut blocks: F,
) -> impl FnMut(u32, u32) -> bool + 'a {
    move |first, count| {
        prims[first as usize..(first + count) as usize]
            .iter()
            .any(|&prim| blocks(prim))
    }
}

/// Levels of wide nodes whose subtrees are collapsed in parallel.
const PARALLEL_LEVELS: usize = 2;

/// Collapses `bvh` into `W`-wide nodes (see the module docs). The result does not
/// depend on the number of threads.
pub fn collapse<const W: usize>(bvh: &Bvh) -> Collapsed<W> {
    let mut out = Collapsed {
        nodes: Vec::new(),
        root: (0, 0),
        prim_order: Vec::new(),
        cost: 0.0,
    };
    if bvh.nodes.is_empty() || bvh.prim_indices.is_empty() {
        return out;
    }
    let (spans, plans) = plan::<W>(bvh);
    let tree = Tree {
        bvh,
        spans: &spans,
        plans: &plans,
    };
    out.root = match tree.leaf(0) {
        Some(leaf) => leaf,
        None => {
            out.nodes = concatenate(collapse_parallel::<W>(&tree, 0, 0));
            (0, 0)
        }
    };
    align_leaves(&mut out, &bvh.prim_indices);
    let root_area = f64::from(bvh.nodes[0].bounds().surface_area());
    if root_area > 0.0 {
        out.cost = (model_cost(root_area, &out) / root_area) as f32;
    }
    out
}

/// The cost of a collapsed tree whose root box has surface area `root_area` under the
/// collapse's model (not normalised), summed over its nodes.
fn model_cost<const W: usize>(root_area: f64, tree: &Collapsed<W>) -> f64 {
    if tree.nodes.is_empty() {
        return root_area * f64::from(leaf_cost(u64::from(tree.root.1)));
    }
    let slot_cost = |slot: &Slot| {
        let b = crate::math::Bounds3 {
            min: glam::Vec3::from_array(slot.min),
            max: glam::Vec3::from_array(slot.max),
        };
        let unit = match slot.count {
            0 => COST_NODE,
            c => leaf_cost(u64::from(c)),
        };
        f64::from(b.surface_area()) * f64::from(unit)
    };
    // Summed in fixed chunks, in parallel, and the chunks' sums in order: the same
    // rounding for any number of threads.
    let sums: Vec<f64> = tree
        .nodes
        .par_chunks(1 << 12)
        .map(|chunk| {
            chunk
                .iter()
                .flatten()
                .filter(|s| s.count != EMPTY)
                .map(slot_cost)
                .sum()
        })
        .collect();
    let children: f64 = sums.iter().sum();
    root_area * f64::from(COST_NODE) + children
}

/// The collapse's cost model: a ray that enters a box pays `COST_NODE` to test a wide
/// node's children there, or, for a leaf, `COST_LEAF` to reach it and `COST_TEST` for
/// each SIMD test of its blocks: a pair of blocks where the leaf test takes two as one
/// 8-lane test (AVX2 with full-width units), else each block
/// ([`crate::cpu::leaf_blocks_per_test`]; see [`leaf_cost`]). The constants and
/// [`MERGE_LIMIT`] were measured rather than derived (with pairs, on a Zen 4).
/// On both bunnies' four ray sets, costs per block from 0.15 to 0.6 of a node's, with
/// leaves of up to two, three or four blocks, all beat the greedy collapse this
/// replaced ("open the largest child"): cheap leaves make a small tree, whose fewer
/// cache misses the single-ray traversal rewards more than it pays for the extra
/// triangle tests. A cost per block lost 1.5 % on a small mesh (the Cornell box), where
/// nothing misses the cache and a leaf's fixed cost shows; costs per pair plus that fixed
/// cost kept the bunnies' gains and lost least there. Where 256-bit operations run as
/// two halves (a Zen 1 EPYC), a pair costs two blocks: pricing each block, with lone
/// blocks tested at 4 lanes rather than paired with themselves, traced the Stanford
/// bunny's rays 2-11% faster on one thread than pairs did (the median of five
/// alternated rounds; 57.9 bytes per triangle rather than 54.8). On an Intel Xeon with
/// AVX-512 (2 MB of L2 per core, a slow shared L3), a pair priced at 0.5 rather than 0.3
/// (slightly smaller leaves: the bunny's 54.8 bytes per triangle become 56.6) traced the
/// Stanford bunny's diffuse rays 2.4% faster and its shadow rays 2.9%, its primary and
/// random rays the same (within 0.3%; the medians of six paired runs, both builds at once
/// on the two CPUs), and bunny_loop2's sets within 2% either way (diffuse +1.8%, random
/// -1.1%); 0.2 and 0.8 were no better than 0.3, and the Cornell box render took the same
/// time at 0.3 and 0.6.
const COST_NODE: f32 = 1.0;
const COST_LEAF: f32 = 0.5;
const COST_TEST: f32 = 0.5;

/// The cost of a leaf of `count` primitives per unit of its box's surface area.
fn leaf_cost(count: u64) -> f32 {
    let blocks = count.div_ceil(LEAF_ALIGN as u64);
    // Blocks per test is 1 or 2: a shift, not a division (whose latency the planning of
    // every binary node waited on).
    let per_test = crate::cpu::leaf_blocks_per_test();
    debug_assert!(per_test.is_power_of_two());
    let shift = per_test.trailing_zeros();
    let tests = (blocks + (1 << shift) - 1) >> shift;
    COST_LEAF + COST_TEST * tests as f32
}

/// Binary node `s`'s leaf range if it can become a leaf, from its span (see
/// [`plan`]): a binary leaf, or a subtree of at most [`MERGE_LIMIT`] primitives that are
/// contiguous.
fn as_leaf(bvh: &Bvh, spans: &[AtomicU64], s: u32) -> Option<(u32, u32)> {
    let n = &bvh.nodes[s as usize];
    if n.is_leaf() {
        return Some((n.left_or_first, n.count));
    }
    span_range(spans[s as usize].load(Relaxed))
}

/// The leaf range `(first, count)` a span packs, when its positions are contiguous.
fn span_range(span: u64) -> Option<(u32, u32)> {
    (span != NOT_A_LEAF && span >> 8 & 0xff == span & 0xff)
        .then_some(((span >> 16) as u32, (span & 0xff) as u32))
}

/// A span for a subtree that cannot become a leaf.
const NOT_A_LEAF: u64 = u64::MAX;

/// Subtrees this high are planned by parallel tasks.
const SPAN_TASK_LEVELS: usize = 4;

/// The plan of a binary node's subtree, packed in 32 bits. For `i` = 2..=W slots: bits
/// `3(i-2)..3(i-1)` hold how many of the least-cost `i` slots come from the left child
/// (0: the node itself takes one slot); bits `3(W-1)..3W` the same for the node's own
/// wide node (its `W` slots, always split); bit 31: the node itself becomes a leaf
/// rather than a wide node.
type Plan = u32;
const PLAN_LEAF: Plan = 1 << 31;

/// Field `field` of `plan` (see [`Plan`]): a left child's share of slots.
fn plan_split(plan: Plan, field: usize) -> usize {
    (plan >> (3 * field) & 7) as usize
}

/// For every binary node, in one parallel pass from the leaves up, what the collapse
/// needs: its span, packed as `lo << 16 | extent << 8 | count` (the lowest primitive
/// position `lo` of its subtree, the extent `hi − lo` of its positions and its
/// primitive count; it is a leaf range when the extent equals the count), or
/// [`NOT_A_LEAF`] once either passes [`MERGE_LIMIT`] (neither shrinks towards the root);
/// and its [`Plan`].
///
/// The plans make the collapse SAH-optimal for the cost model above (after Ylitie,
/// Karras and Laine, "Efficient incoherent ray traversal on GPUs through compressed wide
/// BVHs", 2017): `C(n, i)`, the least cost of representing subtree `n` by at most `i`
/// slots of its parent, is the cheaper of `n` itself in one slot (a leaf of
/// `area · leaf_cost(count)`, when it can be one, or a wide node of
/// `area · COST_NODE + D(n, W)`) and `D(n, i)`, the least of `C(left, k) + C(right, i − k)`
/// over `k`. Which slots a node opens, and which subtrees stay leaves, follows from the
/// costs rather than from a rule such as "open the largest child".
fn plan<const W: usize>(bvh: &Bvh) -> (Vec<AtomicU64>, Vec<AtomicU32>) {
    const { assert!(W >= 2 && W <= 8) };
    let n = bvh.nodes.len();
    let spans: Vec<AtomicU64> =
        super::memory::collect_huge((0..n).into_par_iter().map(|_| AtomicU64::new(0)));
    let plans: Vec<AtomicU32> =
        super::memory::collect_huge((0..n).into_par_iter().map(|_| AtomicU32::new(0)));
    fill_plans::<W>(bvh, &spans, &plans, 0, 0);
    (spans, plans)
}

/// Plans binary node `s`'s subtree; returns its span and its costs `C(s, i)` for `i` =
/// 1..=W (at index `i − 1`).
fn fill_plans<const W: usize>(
    bvh: &Bvh,
    spans: &[AtomicU64],
    plans: &[AtomicU32],
    s: u32,
    level: usize,
) -> (u64, [f32; W]) {
    let n = &bvh.nodes[s as usize];
    let area = n.bounds().surface_area();
    let (span, cost, plan) = if n.is_leaf() {
        let count = u64::from(n.count);
        let span = u64::from(n.left_or_first) << 16 | count.min(0xff) << 8 | count.min(0xff);
        let leaf = area * leaf_cost(count);
        (span, [leaf; W], PLAN_LEAF)
    } else {
        let (l, r) = (n.left_or_first, n.left_or_first + 1);
        let ((a, ca), (b, cb)) = if level < SPAN_TASK_LEVELS {
            rayon::join(
                || fill_plans::<W>(bvh, spans, plans, l, level + 1),
                || fill_plans::<W>(bvh, spans, plans, r, level + 1),
            )
        } else {
            (
                fill_plans::<W>(bvh, spans, plans, l, level + 1),
                fill_plans::<W>(bvh, spans, plans, r, level + 1),
            )
        };
        let span = merge_spans(a, b);
        // D(s, i) for i = 2..=W and the left share that reaches it: for each share k in
        // increasing order, the sums for every i at once (independent lanes, selects
        // rather than branches), a lower sum replacing the best so far, so the first k
        // of equal sums wins.
        let mut cost_i = [f32::INFINITY; W];
        let mut share_i = [0u32; W];
        for k in 1..W {
            let a = ca[k - 1];
            for i in k..W {
                let c = a + cb[i - k];
                let lower = c < cost_i[i];
                share_i[i] = if lower { k as u32 } else { share_i[i] };
                cost_i[i] = if lower { c } else { cost_i[i] };
            }
        }
        let node = area * COST_NODE + cost_i[W - 1];
        let leaf = span_range(span).map_or(f32::INFINITY, |(_, count)| {
            area * leaf_cost(u64::from(count))
        });
        let mut plan = share_i[W - 1] << (3 * (W - 1));
        if leaf <= node {
            plan |= PLAN_LEAF;
        }
        let mut cost = [leaf.min(node); W];
        for i in 1..W {
            if cost_i[i] < cost[0] {
                cost[i] = cost_i[i];
                plan |= share_i[i] << (3 * (i - 1));
            }
        }
        (span, cost, plan)
    };
    spans[s as usize].store(span, Relaxed);
    plans[s as usize].store(plan, Relaxed);
    (span, cost)
}

/// The span of a subtree from its two children's.
fn merge_spans(a: u64, b: u64) -> u64 {
    if a == NOT_A_LEAF || b == NOT_A_LEAF {
        return NOT_A_LEAF;
    }
    let unpack = |x: u64| (x >> 16, (x >> 16) + (x >> 8 & 0xff), x & 0xff);
    let ((alo, ahi, ac), (blo, bhi, bc)) = (unpack(a), unpack(b));
    let (lo, hi, count) = (alo.min(blo), ahi.max(bhi), ac + bc);
    if count > MERGE_LIMIT as u64 || hi - lo > MERGE_LIMIT as u64 {
        return NOT_A_LEAF;
    }
    lo << 16 | (hi - lo) << 8 | count
}

/// A binary tree with its spans and plans.
struct Tree<'a> {
    bvh: &'a Bvh,
    spans: &'a [AtomicU64],
    plans: &'a [AtomicU32],
}

impl Tree<'_> {
    /// Binary node `s`'s leaf range when its plan makes it a leaf.
    fn leaf(&self, s: u32) -> Option<(u32, u32)> {
        if self.plans[s as usize].load(Relaxed) & PLAN_LEAF == 0 {
            return None;
        }
        as_leaf(self.bvh, self.spans, s)
    }

    /// Appends to `out` the binary nodes that take the at most `i` slots planned for
    /// subtree `s` in its parent's wide node ([`Tree::wide_node`] reads `s`'s own).
    fn slots<const W: usize>(&self, s: u32, i: usize, out: &mut [u32; W], len: &mut usize) {
        let k = match i {
            1 => 0,
            _ => plan_split(self.plans[s as usize].load(Relaxed), i - 2),
        };
        if k == 0 {
            out[*len] = s;
            *len += 1;
            return;
        }
        let l = self.bvh.nodes[s as usize].left_or_first;
        self.slots::<W>(l, k, out, len);
        self.slots::<W>(l + 1, i - k, out, len);
    }

    /// The wide node for binary inner node `node`, with its inner children still to be
    /// placed: their slots get `child` = the binary node and `count` 0.
    fn wide_node<const W: usize>(&self, node: u32) -> ([Slot; W], usize) {
        let k = plan_split(self.plans[node as usize].load(Relaxed), W - 1);
        debug_assert!(k > 0, "an inner node's own wide node is split");
        let mut chosen = [0u32; W];
        let mut len = 0;
        let l = self.bvh.nodes[node as usize].left_or_first;
        self.slots::<W>(l, k, &mut chosen, &mut len);
        self.slots::<W>(l + 1, W - k, &mut chosen, &mut len);
        let mut wide = [UNUSED; W];
        for (slot, &c) in wide.iter_mut().zip(&chosen[..len]) {
            let b = &self.bvh.nodes[c as usize];
            let (child, count) = self.leaf(c).unwrap_or((c, 0));
            *slot = Slot {
                min: b.min,
                max: b.max,
                child,
                count,
            };
        }
        (wide, len)
    }
}

/// The wide subtree under binary inner node `node`, its root first, as consecutive
/// pieces: the top levels are collapsed in parallel. Each piece's inner child indices
/// are relative to its `shift`, a position in the subtree (see [`concatenate`]).
fn collapse_parallel<const W: usize>(tree: &Tree, node: u32, level: usize) -> Vec<Piece<W>> {
    if level >= PARALLEL_LEVELS {
        let mut nodes = vec![[UNUSED; W]];
        fill(tree, &mut nodes, node, 0);
        return vec![Piece { nodes, shift: 0 }];
    }
    let (mut wide, len) = tree.wide_node::<W>(node);
    let inner: Vec<usize> = (0..len).filter(|&k| wide[k].count == 0).collect();
    let subtrees: Vec<Vec<Piece<W>>> = inner
        .par_iter()
        .map(|&k| collapse_parallel::<W>(tree, wide[k].child, level + 1))
        .collect();
    // The root here, then each child's subtree, its pieces shifted to where it starts.
    let mut pieces = Vec::with_capacity(1 + subtrees.iter().map(Vec::len).sum::<usize>());
    let mut at = 1u32;
    for (&k, sub) in inner.iter().zip(subtrees) {
        let start = at;
        wide[k].child = start;
        for mut piece in sub {
            piece.shift += start;
            at += piece.nodes.len() as u32;
            pieces.push(piece);
        }
    }
    pieces.insert(
        0,
        Piece {
            nodes: vec![wide],
            shift: 0,
        },
    );
    pieces
}

/// Consecutive wide nodes of a collapsed tree whose inner child indices are relative to
/// `shift`.
struct Piece<const W: usize> {
    nodes: Vec<[Slot; W]>,
    shift: u32,
}

/// The pieces as one array, copied in parallel, with their indices made absolute.
fn concatenate<const W: usize>(pieces: Vec<Piece<W>>) -> Vec<[Slot; W]> {
    let total = pieces.iter().map(|p| p.nodes.len()).sum();
    let mut out = Vec::with_capacity(total);
    let parts = split_into(
        &mut out.spare_capacity_mut()[..total],
        pieces.iter().map(|p| p.nodes.len()),
    );
    pieces.par_iter().zip(parts).for_each(|(piece, part)| {
        for (dst, src) in part.iter_mut().zip(&piece.nodes) {
            let mut node = *src;
            for slot in node.iter_mut().filter(|s| s.count == 0) {
                slot.child += piece.shift;
            }
            dst.write(node);
        }
    });
    // SAFETY: the parts tile positions 0..total (`split_into` cut them from it in order,
    // with the pieces' lengths, which sum to it), and each was written in full above.
    unsafe { out.set_len(total) };
    out
}

/// Fills wide node `at` from the binary inner node `node`, appending its descendants.
fn fill<const W: usize>(tree: &Tree, nodes: &mut Vec<[Slot; W]>, node: u32, at: usize) {
    let (mut wide, len) = tree.wide_node::<W>(node);
    let mut inner = [(0u32, 0usize); W];
    let mut n_inner = 0;
    for slot in wide[..len].iter_mut() {
        if slot.count == 0 {
            let index = nodes.len();
            nodes.push([UNUSED; W]);
            inner[n_inner] = (slot.child, index);
            n_inner += 1;
            slot.child = index as u32;
        }
    }
    nodes[at] = wide;
    for &(s, index) in &inner[..n_inner] {
        fill(tree, nodes, s, index);
    }
}

/// `slice` cut into consecutive parts of the given lengths (which must not exceed it).
pub(super) fn split_into<T>(
    mut slice: &mut [T],
    lens: impl Iterator<Item = usize>,
) -> Vec<&mut [T]> {
    let mut parts = Vec::with_capacity(lens.size_hint().0);
    for len in lens {
        let (part, rest) = std::mem::take(&mut slice).split_at_mut(len);
        parts.push(part);
        slice = rest;
    }
    parts
}

/// Moves every leaf to an aligned, padded position (see the module docs): the leaves in
/// node and slot order, each node's share of the order found first so that the nodes
/// are filled in parallel.
fn align_leaves<const W: usize>(tree: &mut Collapsed<W>, prims: &[u32]) {
    let padded = |count: u32| (count as usize).div_ceil(LEAF_ALIGN) * LEAF_ALIGN;
    let is_leaf = |slot: &Slot| slot.count != EMPTY && slot.count > 0;
    // Writes a leaf's primitives and its padding (the last primitive repeated) to `out`.
    let place = |first: u32, count: u32, out: &mut [u32]| {
        let leaf = &prims[first as usize..(first + count) as usize];
        out[..leaf.len()].copy_from_slice(leaf);
        let last = *leaf.last().expect("leaves are not empty");
        out[leaf.len()..].fill(last);
    };
    if tree.nodes.is_empty() {
        let (first, count) = tree.root;
        let mut order = vec![0; padded(count)];
        place(first, count, &mut order);
        tree.root.0 = 0;
        tree.prim_order = order;
        return;
    }
    let sizes: Vec<usize> = tree
        .nodes
        .par_iter()
        .map(|node| {
            node.iter()
                .filter(|s| is_leaf(s))
                .map(|s| padded(s.count))
                .sum()
        })
        .collect();
    let mut order = vec![0u32; sizes.iter().sum()];
    let bases = sizes.iter().scan(0, |at, &size| {
        *at += size;
        Some(*at - size)
    });
    let parts: Vec<(usize, &mut [u32])> = bases
        .zip(split_into(&mut order, sizes.iter().copied()))
        .collect();
    tree.nodes
        .par_iter_mut()
        .zip(parts)
        .for_each(|(node, (base, part))| {
            let mut at = 0;
            for slot in node.iter_mut().filter(|s| is_leaf(s)) {
                let size = padded(slot.count);
                place(slot.child, slot.count, &mut part[at..at + size]);
                slot.child = (base + at) as u32;
                at += size;
            }
        });
    tree.prim_order = order;
}

/// The boxes of the deepest cut through the top of a wide tree with at most
/// `max_boxes` boxes, leaves carried down (see [`crate::accel::Accel::cover`]).
/// `slot(node, k)` gives slot `k` of a node: its box, child and count, or `None` when
/// unused.
pub fn wide_cover(
    width: usize,
    max_boxes: usize,
    slot: impl Fn(usize, usize) -> Option<(crate::math::Bounds3, u32, u32)>,
) -> Option<Vec<crate::math::Bounds3>> {
    // (node, slot) pairs of the current cut.
    let mut cut: Vec<(usize, usize)> = (0..width)
        .filter(|&k| slot(0, k).is_some())
        .map(|k| (0, k))
        .collect();
    if cut.len() > max_boxes {
        return None;
    }
    loop {
        let mut next = Vec::new();
        let mut opened = false;
        for &(n, k) in &cut {
            match slot(n, k) {
                Some((_, c, 0)) => {
                    next.extend(
                        (0..width)
                            .filter(|&j| slot(c as usize, j).is_some())
                            .map(|j| (c as usize, j)),
                    );
                    opened = true;
                }
                _ => next.push((n, k)),
            }
        }
        if !opened || next.len() > max_boxes {
            break;
        }
        cut = next;
    }
    Some(
        cut.iter()
            .filter_map(|&(n, k)| slot(n, k).map(|s| s.0))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh::BuildSettings;
    use crate::accel::testing::{boxes, degenerate_soup, lattice_mesh, random_soup};

    /// The leaf range of a subtree found by walking all of it.
    fn as_leaf_by_walking(bvh: &Bvh, s: u32) -> Option<(u32, u32)> {
        let n = &bvh.nodes[s as usize];
        if n.is_leaf() {
            return Some((n.left_or_first, n.count));
        }
        let (mut stack, mut total, mut lo, mut hi) = (vec![s], 0u32, u32::MAX, 0u32);
        while let Some(i) = stack.pop() {
            let n = &bvh.nodes[i as usize];
            if n.is_leaf() {
                total += n.count;
                lo = lo.min(n.left_or_first);
                hi = hi.max(n.left_or_first + n.count);
            } else {
                stack.extend([n.left_or_first, n.left_or_first + 1]);
            }
        }
        (total as usize <= MERGE_LIMIT && hi - lo == total).then_some((lo, total))
    }

    /// Every cut of subtree `s` into at most `max` subtrees (`s` itself included).
    fn cuts(bvh: &Bvh, s: u32, max: usize) -> Vec<Vec<u32>> {
        let mut out = vec![vec![s]];
        let n = &bvh.nodes[s as usize];
        if max >= 2 && !n.is_leaf() {
            let l = n.left_or_first;
            for a in cuts(bvh, l, max - 1) {
                for b in cuts(bvh, l + 1, max - a.len()) {
                    out.push([a.clone(), b].concat());
                }
            }
        }
        out
    }

    /// The least cost of subtree `s` in one slot, found by trying every leaf and every
    /// wide node (each set of at most `W` descendants) there is.
    fn brute_slot<const W: usize>(
        bvh: &Bvh,
        spans: &[AtomicU64],
        s: u32,
        memo: &mut std::collections::HashMap<u32, f64>,
    ) -> f64 {
        if let Some(&c) = memo.get(&s) {
            return c;
        }
        let n = &bvh.nodes[s as usize];
        let area = f64::from(n.bounds().surface_area());
        let leaf =
            as_leaf(bvh, spans, s).map(|(_, count)| area * f64::from(leaf_cost(u64::from(count))));
        let mut best = leaf.unwrap_or(f64::INFINITY);
        if !n.is_leaf() {
            let l = n.left_or_first;
            for a in cuts(bvh, l, W - 1) {
                for b in cuts(bvh, l + 1, W - a.len()) {
                    let children: f64 = a
                        .iter()
                        .chain(&b)
                        .map(|&c| brute_slot::<W>(bvh, spans, c, memo))
                        .sum();
                    best = best.min(area * f64::from(COST_NODE) + children);
                }
            }
        }
        memo.insert(s, best);
        best
    }

    fn check_optimal<const W: usize>(bvh: &Bvh) {
        let tree = collapse::<W>(bvh);
        let (spans, _) = plan::<W>(bvh);
        let mut memo = std::collections::HashMap::new();
        let root = &bvh.nodes[0];
        // The root is a wide node unless the whole tree is one leaf.
        let best = if root.is_leaf() {
            brute_slot::<W>(bvh, &spans, 0, &mut memo)
        } else {
            let area = f64::from(root.bounds().surface_area());
            let node = cuts(bvh, root.left_or_first, W - 1)
                .into_iter()
                .flat_map(|a| {
                    cuts(bvh, root.left_or_first + 1, W - a.len())
                        .into_iter()
                        .map(move |b| [a.clone(), b].concat())
                })
                .map(|slots| {
                    slots
                        .iter()
                        .map(|&c| brute_slot::<W>(bvh, &spans, c, &mut memo))
                        .sum::<f64>()
                })
                .fold(f64::INFINITY, f64::min);
            let leaf = as_leaf(bvh, &spans, 0).map_or(f64::INFINITY, |(_, count)| {
                area * f64::from(leaf_cost(u64::from(count)))
            });
            (area * f64::from(COST_NODE) + node).min(leaf)
        };
        let root_area = f64::from(root.bounds().surface_area());
        let got = model_cost(root_area, &tree);
        assert!((f64::from(tree.cost) - got / root_area).abs() <= 1e-5 * got / root_area);
        assert!(
            (got - best).abs() <= 1e-4 * best,
            "W = {W}: the collapsed tree costs {got}, the best collapse {best}"
        );
    }

    /// The collapse reaches the least cost of its model, which a search through every
    /// possible collapse of small trees finds independently.
    #[test]
    fn collapse_is_sah_optimal() {
        for seed in 0..6 {
            let n = [9, 24, 40, 64][seed as usize % 4];
            let tris = if seed == 5 {
                degenerate_soup(48, seed)
            } else {
                random_soup(n, seed)
            };
            let settings = BuildSettings {
                always_leaf: LEAF_ALIGN,
                ..BuildSettings::QUALITY
            };
            let bvh = Bvh::build(&boxes(&tris), &settings);
            check_optimal::<4>(&bvh);
            check_optimal::<8>(&bvh);
        }
    }

    /// Every binary node's span gives what walking its subtree gives, for trees from the
    /// wide builds and from the other presets (whose leaves and, after reinsertion,
    /// primitive ranges are arranged differently).
    #[test]
    fn spans_equal_walking_the_subtree() {
        let meshes = [
            random_soup(3000, 1),
            degenerate_soup(500, 2),
            lattice_mesh(20, true),
        ];
        for tris in &meshes {
            let b = boxes(tris);
            for settings in [
                BuildSettings {
                    always_leaf: LEAF_ALIGN,
                    ..BuildSettings::QUALITY
                },
                BuildSettings::HIGH,
                BuildSettings::COURSE,
            ] {
                let bvh = Bvh::build(&b, &settings);
                let (spans, _) = plan::<8>(&bvh);
                let mut leaves = 0;
                let mut reachable = vec![0u32];
                while let Some(s) = reachable.pop() {
                    let expected = as_leaf_by_walking(&bvh, s);
                    assert_eq!(as_leaf(&bvh, &spans, s), expected, "node {s}");
                    leaves += usize::from(expected.is_some());
                    let n = &bvh.nodes[s as usize];
                    if !n.is_leaf() {
                        reachable.extend([n.left_or_first, n.left_or_first + 1]);
                    }
                }
                assert!(leaves > 0);
            }
        }
    }
}
