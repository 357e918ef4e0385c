//! Collapsing a binary BVH into a tree of `W`-wide nodes (shared by the 4- and 8-wide
//! BVHs), with leaves laid out for SIMD primitive blocks.
//!
//! Each wide node takes the up-to-`W` descendants found by repeatedly opening its
//! largest inner child. A subtree of at most two blocks of [`LEAF_ALIGN`] primitives
//! becomes one leaf, whose primitives are tested together as SIMD blocks: that costs
//! less than visiting its nodes, and saves the memory of nodes with two small leaves.
//! Where a node still has free slots once no inner child is left, such leaves of more
//! than one block are opened into their halves. Leaves are then moved to positions that are multiples of [`LEAF_ALIGN`]
//! and padded to a multiple of it by repeating their last primitive, so that a
//! primitive owner can keep its data in blocks that match the leaves
//! ([`crate::geometry::TriangleBlock`]); leaves keep their true counts.

use super::bvh::Bvh;

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

/// Collapses `bvh` into `W`-wide nodes (see the module docs).
pub fn collapse<const W: usize>(bvh: &Bvh) -> Collapsed<W> {
    let mut out = Collapsed {
        nodes: Vec::new(),
        root: (0, 0),
        prim_order: Vec::new(),
    };
    if bvh.nodes.is_empty() || bvh.prim_indices.is_empty() {
        return out;
    }
    let ranges = subtree_ranges(bvh);
    let as_leaf = |s: u32| -> Option<(u32, u32)> {
        let n = &bvh.nodes[s as usize];
        if n.is_leaf() {
            return Some((n.left_or_first, n.count));
        }
        ranges[s as usize].filter(|r| r.1 as usize <= MERGE_LIMIT)
    };
    out.root = match as_leaf(0) {
        Some(leaf) => leaf,
        None => {
            out.nodes.push([UNUSED; W]);
            fill(bvh, &as_leaf, &mut out.nodes, 0, 0);
            (0, 0)
        }
    };
    align_leaves(&mut out, &bvh.prim_indices);
    out
}

/// Fills wide node `at` from the binary inner node `node`.
fn fill<const W: usize>(
    bvh: &Bvh,
    as_leaf: &impl Fn(u32) -> Option<(u32, u32)>,
    nodes: &mut Vec<[Slot; W]>,
    node: u32,
    at: usize,
) {
    let n = &bvh.nodes[node as usize];
    let mut slots = vec![n.left_or_first, n.left_or_first + 1];
    while slots.len() < W {
        // Open the inner child with the largest surface area; when every child is a
        // leaf, split a leaf of more than one block that still has a binary subtree.
        let area = |s: u32| bvh.nodes[s as usize].bounds().surface_area();
        let largest = |open: &dyn Fn(u32) -> bool| {
            slots
                .iter()
                .enumerate()
                .filter(|(_, &s)| open(s))
                .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
                .map(|(i, _)| i)
        };
        let best = largest(&|s| as_leaf(s).is_none()).or_else(|| {
            largest(&|s| {
                !bvh.nodes[s as usize].is_leaf()
                    && as_leaf(s).is_some_and(|(_, count)| count as usize > LEAF_ALIGN)
            })
        });
        let Some(i) = best else { break };
        let s = slots.swap_remove(i);
        let c = bvh.nodes[s as usize].left_or_first;
        slots.push(c);
        slots.push(c + 1);
    }
    let mut wide = [UNUSED; W];
    let mut inner = Vec::new();
    for (k, &s) in slots.iter().enumerate() {
        let b = &bvh.nodes[s as usize];
        let (child, count) = match as_leaf(s) {
            Some(leaf) => leaf,
            None => {
                let index = nodes.len();
                nodes.push([UNUSED; W]);
                inner.push((s, index));
                (index as u32, 0)
            }
        };
        wide[k] = Slot {
            min: b.min,
            max: b.max,
            child,
            count,
        };
    }
    nodes[at] = wide;
    for (s, index) in inner {
        fill(bvh, as_leaf, nodes, s, index);
    }
}

/// The contiguous range `(first, count)` of `prim_indices` under every binary node, or
/// `None` where a subtree's primitives are not contiguous.
fn subtree_ranges(bvh: &Bvh) -> Vec<Option<(u32, u32)>> {
    fn visit(bvh: &Bvh, i: usize, ranges: &mut [Option<(u32, u32)>]) -> Option<(u32, u32)> {
        let n = &bvh.nodes[i];
        let r = if n.is_leaf() {
            Some((n.left_or_first, n.count))
        } else {
            let l = n.left_or_first as usize;
            match (visit(bvh, l, ranges), visit(bvh, l + 1, ranges)) {
                (Some(a), Some(b)) if a.0 + a.1 == b.0 => Some((a.0, a.1 + b.1)),
                (Some(a), Some(b)) if b.0 + b.1 == a.0 => Some((b.0, a.1 + b.1)),
                _ => None,
            }
        };
        ranges[i] = r;
        r
    }
    let mut ranges = vec![None; bvh.nodes.len()];
    visit(bvh, 0, &mut ranges);
    ranges
}

/// Moves every leaf to an aligned, padded position (see the module docs).
fn align_leaves<const W: usize>(tree: &mut Collapsed<W>, prims: &[u32]) {
    let mut order = Vec::with_capacity(prims.len() + prims.len() / 2);
    let place = |first: u32, count: u32, order: &mut Vec<u32>| -> u32 {
        let at = order.len() as u32;
        let leaf = &prims[first as usize..(first + count) as usize];
        order.extend_from_slice(leaf);
        let last = *leaf.last().expect("leaves are not empty");
        while order.len() % LEAF_ALIGN != 0 {
            order.push(last);
        }
        at
    };
    if tree.nodes.is_empty() {
        tree.root.0 = place(tree.root.0, tree.root.1, &mut order);
    }
    for node in &mut tree.nodes {
        for slot in node.iter_mut() {
            if slot.count != EMPTY && slot.count > 0 {
                slot.child = place(slot.child, slot.count, &mut order);
            }
        }
    }
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
