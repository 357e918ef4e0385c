//! Collapsing a binary BVH into a tree of `W`-wide nodes (shared by the 4- and 8-wide
//! BVHs), with leaves laid out for SIMD primitive blocks.
//!
//! Each wide node takes the up-to-`W` descendants found by repeatedly opening its
//! largest inner child. A subtree of at most two blocks of [`LEAF_ALIGN`] primitives
//! becomes one leaf, whose primitives are tested together as SIMD blocks: that costs
//! less than visiting its nodes, and saves the memory of nodes with two small leaves.
//! Where a node still has free slots once no inner child is left, such leaves of more
//! than one block are opened into their halves. Leaves are then moved to positions that
//! are multiples of [`LEAF_ALIGN`] and padded to a multiple of it by repeating their last
//! primitive, so that a primitive owner can keep its data in blocks that match the leaves
//! ([`crate::geometry::TriangleBlock`]); leaves keep their true counts.
//!
//! Whether a subtree can become a leaf is read from a table filled in one parallel pass
//! from the leaves up ([`leaf_spans`]); the top levels of the wide tree are built in
//! parallel and concatenated once, and the leaves are placed in parallel.

use super::bvh::Bvh;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// Leaves start at multiples of this and are padded to it.
pub const LEAF_ALIGN: usize = 4;

/// A subtree of at most this many primitives (two blocks) becomes a leaf, unless its
/// node has room to open it.
const MERGE_LIMIT: usize = 2 * LEAF_ALIGN;

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
}

/// Builds the binary tree a wide BVH is collapsed from, and returns it with the moment
/// the build started: subtrees of one block become leaves in the collapse, so the
/// binary build stops there (`BuildSettings::always_leaf`).
pub fn build_binary(
    boxes: &[crate::math::Bounds3],
    settings: &super::bvh::BuildSettings,
) -> (Bvh, std::time::Instant) {
    let start = std::time::Instant::now();
    let settings = super::bvh::BuildSettings {
        always_leaf: LEAF_ALIGN,
        ..*settings
    };
    (Bvh::build(boxes, &settings), start)
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
    };
    if bvh.nodes.is_empty() || bvh.prim_indices.is_empty() {
        return out;
    }
    let spans = leaf_spans(bvh);
    out.root = match as_leaf(bvh, &spans, 0) {
        Some(leaf) => leaf,
        None => {
            out.nodes = concatenate(collapse_parallel(bvh, &spans, 0, 0));
            (0, 0)
        }
    };
    align_leaves(&mut out, &bvh.prim_indices);
    out
}

/// A binary node as a candidate slot: its index, its leaf range if it is taken as a
/// leaf, and its surface area.
#[derive(Clone, Copy)]
struct Candidate {
    node: u32,
    leaf: Option<(u32, u32)>,
    area: f32,
}

/// Binary node `s`'s leaf range if it becomes a leaf, from [`leaf_spans`]: a binary
/// leaf, or a subtree of at most [`MERGE_LIMIT`] primitives that are contiguous.
fn as_leaf(bvh: &Bvh, spans: &[AtomicU64], s: u32) -> Option<(u32, u32)> {
    let n = &bvh.nodes[s as usize];
    if n.is_leaf() {
        return Some((n.left_or_first, n.count));
    }
    let span = spans[s as usize].load(Relaxed);
    (span != NOT_A_LEAF && span >> 8 & 0xff == span & 0xff)
        .then_some(((span >> 16) as u32, (span & 0xff) as u32))
}

/// A span for a subtree that cannot become a leaf.
const NOT_A_LEAF: u64 = u64::MAX;

/// Subtrees this high are summarised by parallel tasks.
const SPAN_TASK_LEVELS: usize = 4;

/// For every binary node, what [`as_leaf`] needs, in one pass from the leaves up: the
/// lowest primitive position `lo` of its subtree, the extent `hi − lo` of its positions
/// and its primitive count, packed as `lo << 16 | extent << 8 | count` (it is a leaf
/// range when the extent equals the count), or [`NOT_A_LEAF`] once either passes
/// [`MERGE_LIMIT`] (neither shrinks towards the root). A binary leaf always has its
/// range, whatever its size.
fn leaf_spans(bvh: &Bvh) -> Vec<AtomicU64> {
    let spans: Vec<AtomicU64> = (0..bvh.nodes.len()).map(|_| AtomicU64::new(0)).collect();
    fill_spans(bvh, &spans, 0, 0);
    spans
}

fn fill_spans(bvh: &Bvh, spans: &[AtomicU64], s: u32, level: usize) -> u64 {
    let n = &bvh.nodes[s as usize];
    let span = if n.is_leaf() {
        let count = u64::from(n.count);
        u64::from(n.left_or_first) << 16 | count.min(0xff) << 8 | count.min(0xff)
    } else {
        let (l, r) = (n.left_or_first, n.left_or_first + 1);
        let (a, b) = if level < SPAN_TASK_LEVELS {
            rayon::join(
                || fill_spans(bvh, spans, l, level + 1),
                || fill_spans(bvh, spans, r, level + 1),
            )
        } else {
            (
                fill_spans(bvh, spans, l, level + 1),
                fill_spans(bvh, spans, r, level + 1),
            )
        };
        merge_spans(a, b)
    };
    spans[s as usize].store(span, Relaxed);
    span
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

fn candidate(bvh: &Bvh, spans: &[AtomicU64], s: u32) -> Candidate {
    Candidate {
        node: s,
        leaf: as_leaf(bvh, spans, s),
        area: bvh.nodes[s as usize].bounds().surface_area(),
    }
}

/// The up-to-`W` descendants of binary inner node `node` that become the slots of its
/// wide node.
fn choose<const W: usize>(bvh: &Bvh, spans: &[AtomicU64], node: u32) -> ([Candidate; W], usize) {
    let first = bvh.nodes[node as usize].left_or_first;
    let mut slots = [candidate(bvh, spans, first); W];
    slots[1] = candidate(bvh, spans, first + 1);
    let mut len = 2;
    while len < W {
        // Open the inner child with the largest surface area; when every child is a
        // leaf, split a leaf of more than one block that still has a binary subtree.
        let pick = |open: &dyn Fn(&Candidate) -> bool| {
            (0..len)
                .filter(|&i| open(&slots[i]))
                .max_by(|&a, &b| slots[a].area.total_cmp(&slots[b].area))
        };
        let best = pick(&|c| c.leaf.is_none()).or_else(|| {
            pick(&|c| {
                !bvh.nodes[c.node as usize].is_leaf()
                    && c.leaf.is_some_and(|(_, count)| count as usize > LEAF_ALIGN)
            })
        });
        let Some(i) = best else { break };
        let c = bvh.nodes[slots[i].node as usize].left_or_first;
        slots[i] = candidate(bvh, spans, c);
        slots[len] = candidate(bvh, spans, c + 1);
        len += 1;
    }
    (slots, len)
}

/// The wide node for binary inner node `node`, with its inner children still to be
/// placed: their slots get `child` = the binary node and `count` 0.
fn wide_node<const W: usize>(bvh: &Bvh, spans: &[AtomicU64], node: u32) -> ([Slot; W], usize) {
    let (slots, len) = choose::<W>(bvh, spans, node);
    let mut wide = [UNUSED; W];
    for (k, c) in slots[..len].iter().enumerate() {
        let b = &bvh.nodes[c.node as usize];
        let (child, count) = c.leaf.unwrap_or((c.node, 0));
        wide[k] = Slot {
            min: b.min,
            max: b.max,
            child,
            count,
        };
    }
    (wide, len)
}

/// The wide subtree under binary inner node `node`, its root first, as consecutive
/// pieces: the top levels are collapsed in parallel. Each piece's inner child indices
/// are relative to its `shift`, a position in the subtree (see [`concatenate`]).
fn collapse_parallel<const W: usize>(
    bvh: &Bvh,
    spans: &[AtomicU64],
    node: u32,
    level: usize,
) -> Vec<Piece<W>> {
    if level >= PARALLEL_LEVELS {
        let mut nodes = vec![[UNUSED; W]];
        fill(bvh, spans, &mut nodes, node, 0);
        return vec![Piece { nodes, shift: 0 }];
    }
    let (mut wide, len) = wide_node::<W>(bvh, spans, node);
    let inner: Vec<usize> = (0..len).filter(|&k| wide[k].count == 0).collect();
    let subtrees: Vec<Vec<Piece<W>>> = inner
        .par_iter()
        .map(|&k| collapse_parallel::<W>(bvh, spans, wide[k].child, level + 1))
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
    let mut out = vec![[UNUSED; W]; pieces.iter().map(|p| p.nodes.len()).sum()];
    let parts = split_into(&mut out, pieces.iter().map(|p| p.nodes.len()));
    pieces.par_iter().zip(parts).for_each(|(piece, part)| {
        for (dst, src) in part.iter_mut().zip(&piece.nodes) {
            *dst = *src;
            for slot in dst.iter_mut().filter(|s| s.count == 0) {
                slot.child += piece.shift;
            }
        }
    });
    out
}

/// Fills wide node `at` from the binary inner node `node`, appending its descendants.
fn fill<const W: usize>(
    bvh: &Bvh,
    spans: &[AtomicU64],
    nodes: &mut Vec<[Slot; W]>,
    node: u32,
    at: usize,
) {
    let (mut wide, len) = wide_node::<W>(bvh, spans, node);
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
        fill(bvh, spans, nodes, s, index);
    }
}

/// `slice` cut into consecutive parts of the given lengths (which must not exceed it).
fn split_into<T>(mut slice: &mut [T], lens: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
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
                let spans = leaf_spans(&bvh);
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
