//! Covers for the tree accelerators: the boxes of breadth-first cuts through the top of
//! a build tree, recorded while the build tree still exists, so that `cover` can answer
//! without keeping per-node boxes in the traversal layout.

use crate::math::Bounds3;

/// The largest cut recorded (`shape.rs` asks for 64 boxes).
const MAX_CUT: usize = 256;

/// A build-tree node as the cover sees it: the box of everything below it and its
/// children (none for a leaf).
pub(crate) trait CoverNode {
    fn cover_bounds(&self) -> Bounds3;
    fn cover_children(&self) -> Vec<&Self>;
}

/// Successive cuts: `cuts[k]` holds the boxes `k` levels below the root (leaves carried
/// down), empty subtrees dropped.
#[derive(Debug, Clone, Default)]
pub(crate) struct CoverCuts {
    cuts: Vec<Vec<Bounds3>>,
}

impl CoverCuts {
    pub(crate) fn record<N: CoverNode>(root: &N) -> CoverCuts {
        let mut cuts = Vec::new();
        let mut cut = vec![root];
        loop {
            cuts.push(
                cut.iter()
                    .map(|n| n.cover_bounds())
                    .filter(|b| !b.is_empty())
                    .collect(),
            );
            let mut next = Vec::new();
            let mut opened = false;
            for n in &cut {
                let children = n.cover_children();
                if children.is_empty() {
                    next.push(*n);
                } else {
                    opened = true;
                    next.extend(
                        children
                            .into_iter()
                            .filter(|c| !c.cover_bounds().is_empty()),
                    );
                }
            }
            if !opened || next.len() > MAX_CUT {
                return CoverCuts { cuts };
            }
            cut = next;
        }
    }

    /// The deepest recorded cut of at most `max_boxes` boxes (the root's box if none).
    pub(crate) fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        self.cuts
            .iter()
            .rev()
            .find(|c| c.len() <= max_boxes.max(1))
            .cloned()
            .unwrap_or_else(|| self.cuts.first().cloned().unwrap_or_default())
    }
}
