//! Uniform grid: the scene box cut into equal cells, each listing the primitives whose
//! box overlaps it, traversed cell by cell along the ray with a 3D-DDA.
//!
//! Selected with `--accel grid` on `lightpath render`, `rays` and `bench`
//! (`lightpath render scene.xml --accel grid`), or in code with
//! `LoadOptions { accel: Some(AccelKind::Grid), .. }` / `Accel::build(AccelKind::Grid, &boxes)`.
//!
//! **Build.** The resolution follows the primitive count: about `λ·N` cells
//! ([`CELLS_PER_PRIM`] = λ), as near to cubes as the box allows (the cube-root rule
//! `res_i = d_i · ∛(λN / V)` over the axes of non-zero extent; an axis of zero extent
//! gets one cell), each axis capped at [`MAX_RES`] and the total at [`MAX_CELLS`].
//! A primitive is registered in every cell its box overlaps, its box grown by
//! `CELL_EPS` (1e-4) of a cell so that rounding in the walk never misses it. The cells are a
//! compressed sparse row layout: `offsets[c]..offsets[c + 1]` is cell `c`'s range in
//! `indices` (cell `c = (z · ry + y) · rx + x`), built by a counting pass, a prefix sum
//! and a filling pass: 4 bytes a cell plus 4 bytes a reference, no per-cell vectors.
//!
//! **Traversal.** Amanatides and Woo's 3D-DDA: the ray is clipped to the grid box (a ray
//! starting inside starts in its own cell), and at each step it moves into the neighbour
//! across the nearest cell boundary; the boundary distances are recomputed from the
//! cell index rather than accumulated, so long walks do not drift. An axis along which
//! the ray does not move (a zero direction component) or the grid has no extent is never
//! stepped. A closest hit found in a cell is accepted only once the walk has passed it:
//! the walk continues while the next cell's entry distance is below the hit distance,
//! since a primitive spanning cells may be hit beyond the current cell, behind a closer
//! primitive in the next one. Each ray carries a mailbox: a small hash set of the ids
//! tested (open addressing with linear probing, on the stack, so queries stay `&self`
//! and thread-safe), so a primitive spanning several cells is tested once per ray; a
//! ray that tests more than [`MAILBOX_LOAD`] distinct primitives empties its set and
//! starts over, which can only cost a repeated test, never a missed one.

use super::{widen, RayStats};
use crate::math::{Bounds3, Ray};
use glam::Vec3;
use std::time::Instant;

/// Target number of cells per primitive (λ).
pub const CELLS_PER_PRIM: f32 = 4.0;
/// Most cells along one axis.
pub const MAX_RES: usize = 1024;
/// Most cells in all (the offsets alone take 4 bytes a cell: 64 MiB).
pub const MAX_CELLS: usize = 1 << 24;
/// Primitive boxes are grown by this fraction of a cell when registered.
const CELL_EPS: f32 = 1e-4;
/// Mailbox slots per ray (a power of two).
const MAILBOX: usize = 128;
/// Most ids a mailbox holds before it starts over (half its slots, so probes stay short).
pub const MAILBOX_LOAD: usize = MAILBOX / 2;

/// A per-ray set of the primitive ids tested; see the module docs.
struct Mailbox {
    slots: [u32; MAILBOX],
    len: usize,
}

impl Mailbox {
    #[inline(always)]
    fn new() -> Self {
        Mailbox {
            slots: [u32::MAX; MAILBOX],
            len: 0,
        }
    }

    /// Adds `id`; false if it was already there (tested before on this ray).
    #[inline(always)]
    fn insert(&mut self, id: u32) -> bool {
        let mut i = (id.wrapping_mul(0x9E37_79B1) >> 25) as usize;
        loop {
            let s = self.slots[i];
            if s == id {
                return false;
            }
            if s == u32::MAX {
                break;
            }
            i = (i + 1) & (MAILBOX - 1);
        }
        if self.len == MAILBOX_LOAD {
            self.slots = [u32::MAX; MAILBOX];
            self.len = 0;
            return self.insert(id);
        }
        self.slots[i] = id;
        self.len += 1;
        true
    }
}

/// A uniform grid over primitive boxes; see the module docs.
#[derive(Debug, Clone)]
pub struct Grid {
    bounds: Bounds3,
    res: [i32; 3],
    /// Cell widths (0 along an axis of zero extent).
    cell_size: Vec3,
    /// Cells per unit length (0 along an axis of zero extent).
    inv_cell_size: Vec3,
    /// `offsets[c]..offsets[c + 1]` is cell `c`'s range in `indices`.
    offsets: Vec<u32>,
    indices: Vec<u32>,
    /// Covers for 1, 2³, 3³, 4³ blocks: see [`Grid::cover`].
    covers: Vec<Vec<Bounds3>>,
    pub build_seconds: f64,
}

impl Grid {
    pub fn build(boxes: &[Bounds3]) -> Grid {
        let start = Instant::now();
        let bounds = boxes.iter().fold(Bounds3::EMPTY, |a, b| a.union(b));
        let n = boxes.iter().filter(|b| !b.is_empty()).count();
        let mut grid = Grid {
            bounds,
            res: [1; 3],
            cell_size: Vec3::ZERO,
            inv_cell_size: Vec3::ZERO,
            offsets: vec![0, 0],
            indices: Vec::new(),
            covers: Vec::new(),
            build_seconds: 0.0,
        };
        if n == 0 {
            grid.build_seconds = start.elapsed().as_secs_f64();
            return grid;
        }
        // Resolution: about λN near-cubic cells over the axes of non-zero extent.
        let d = bounds.diagonal();
        let max_d = d.max_element();
        let axes: Vec<usize> = (0..3).filter(|&a| d[a] > max_d * 1e-4).collect();
        let mut res = [1usize; 3];
        if !axes.is_empty() {
            let measure: f64 = axes.iter().map(|&a| d[a] as f64).product();
            let k = (CELLS_PER_PRIM as f64 * n as f64 / measure).powf(1.0 / axes.len() as f64);
            for &a in &axes {
                res[a] = ((d[a] as f64 * k).round() as usize).clamp(1, MAX_RES);
            }
            while res.iter().product::<usize>() > MAX_CELLS {
                for r in &mut res {
                    *r = (*r * 7 / 8).max(1);
                }
            }
        }
        for a in 0..3 {
            grid.res[a] = res[a] as i32;
            if d[a] > 0.0 {
                grid.cell_size[a] = d[a] / res[a] as f32;
                grid.inv_cell_size[a] = res[a] as f32 / d[a];
            }
        }
        let cells = res.iter().product::<usize>();

        // Counting pass, prefix sum, filling pass.
        let mut counts = vec![0u32; cells + 1];
        for b in boxes.iter().filter(|b| !b.is_empty()) {
            let (lo, hi) = grid.cell_range(b);
            grid.for_each_cell(lo, hi, |c| counts[c] += 1);
        }
        let mut sum = 0u32;
        for c in counts.iter_mut() {
            let k = *c;
            *c = sum;
            sum += k;
        }
        let mut cursor = counts.clone();
        let mut indices = vec![0u32; sum as usize];
        for (i, b) in boxes.iter().enumerate() {
            if b.is_empty() {
                continue;
            }
            let (lo, hi) = grid.cell_range(b);
            grid.for_each_cell(lo, hi, |c| {
                indices[cursor[c] as usize] = i as u32;
                cursor[c] += 1;
            });
        }
        grid.offsets = counts;
        grid.indices = indices;
        grid.covers = (1..=4).map(|k| block_cover(boxes, &bounds, k)).collect();
        grid.build_seconds = start.elapsed().as_secs_f64();
        grid
    }

    /// The cells (inclusive ranges) overlapped by `b` grown by [`CELL_EPS`] of a cell.
    fn cell_range(&self, b: &Bounds3) -> ([i32; 3], [i32; 3]) {
        let mut lo = [0; 3];
        let mut hi = [0; 3];
        for a in 0..3 {
            let to_cell = |x: f32, eps: f32| {
                let c = ((x - self.bounds.min[a]) * self.inv_cell_size[a] + eps).floor();
                (c.max(0.0) as i32).min(self.res[a] - 1)
            };
            lo[a] = to_cell(b.min[a], -CELL_EPS);
            hi[a] = to_cell(b.max[a], CELL_EPS);
        }
        (lo, hi)
    }

    fn for_each_cell(&self, lo: [i32; 3], hi: [i32; 3], mut f: impl FnMut(usize)) {
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    f(self.cell_index([x, y, z]));
                }
            }
        }
    }

    #[inline(always)]
    fn cell_index(&self, c: [i32; 3]) -> usize {
        ((c[2] * self.res[1] + c[1]) * self.res[0] + c[0]) as usize
    }

    /// Cells along each axis.
    pub fn resolution(&self) -> [usize; 3] {
        self.res.map(|r| r as usize)
    }

    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }

    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Grid>() + (self.offsets.len() + self.indices.len()) * 4
    }

    /// Boxes of the primitives grouped into `k³` blocks by their centres, for the
    /// largest `k ≤ 4` with at most `max_boxes` non-empty blocks: each primitive box
    /// lies inside its block's box.
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        self.covers
            .iter()
            .rev()
            .find(|c| c.len() <= max_boxes)
            .or(self.covers.first())
            .cloned()
            .unwrap_or_default()
    }

    /// The walk's starting state, or `None` if the ray misses the grid.
    #[inline(always)]
    fn start(&self, ray: &Ray) -> Option<Dda> {
        if self.indices.is_empty() {
            return None;
        }
        let inv_dir = ray.direction.recip();
        let (t0, t1) = super::clip_ray(&self.bounds, ray, inv_dir)?;
        let p = ray.at(t0);
        let mut dda = Dda {
            cell: [0; 3],
            step: [0; 3],
            next: [f32::INFINITY; 3],
            t_end: t1,
            inv_dir,
        };
        for a in 0..3 {
            let c = ((p[a] - self.bounds.min[a]) * self.inv_cell_size[a]).floor();
            dda.cell[a] = (c.max(0.0) as i32).min(self.res[a] - 1);
            if self.cell_size[a] > 0.0 && ray.direction[a] != 0.0 {
                dda.step[a] = if ray.direction[a] > 0.0 { 1 } else { -1 };
                dda.next[a] = self.boundary(ray, &dda, a);
            }
        }
        Some(dda)
    }

    /// Distance to the boundary the ray crosses next along axis `a`.
    #[inline(always)]
    fn boundary(&self, ray: &Ray, dda: &Dda, a: usize) -> f32 {
        let face = dda.cell[a] + i32::from(dda.step[a] > 0);
        (self.bounds.min[a] + face as f32 * self.cell_size[a] - ray.origin[a]) * dda.inv_dir[a]
    }

    /// Moves into the next cell; false when the ray leaves the grid or ends first.
    #[inline(always)]
    fn advance(&self, ray: &Ray, dda: &mut Dda) -> bool {
        let n = dda.next;
        let a = if n[0] <= n[1] && n[0] <= n[2] {
            0
        } else if n[1] <= n[2] {
            1
        } else {
            2
        };
        // Stop where the ray leaves the grid or ends, or if it never steps at all.
        let inside = n[a] <= dda.t_end && n[a] < f32::INFINITY;
        if !inside {
            return false;
        }
        dda.cell[a] += dda.step[a];
        if dda.cell[a] < 0 || dda.cell[a] >= self.res[a] {
            return false;
        }
        dda.next[a] = self.boundary(ray, dda, a);
        true
    }

    #[inline(always)]
    fn cell_prims(&self, dda: &Dda) -> &[u32] {
        let c = self.cell_index(dda.cell);
        &self.indices[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }

    /// Closest hit by the DDA walk; see the module docs.
    #[inline]
    pub fn intersect<F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut hit: F,
    ) -> bool {
        let Some(mut dda) = self.start(ray) else {
            return false;
        };
        let mut mailbox = Mailbox::new();
        let mut t_max = ray.t_max;
        let mut any = false;
        loop {
            stats.nodes_visited += 1;
            for &prim in self.cell_prims(&dda) {
                if !mailbox.insert(prim) {
                    continue;
                }
                stats.prims_tested += 1;
                any |= hit(prim, &mut t_max);
            }
            // Accept the hit only once the walk has passed it.
            let t_exit = dda.next[0].min(dda.next[1]).min(dda.next[2]);
            if t_exit > widen(t_max) || !self.advance(ray, &mut dda) {
                return any;
            }
        }
    }

    /// Any hit by the DDA walk, stopping at the first blocking primitive.
    #[inline]
    pub fn occluded<F: FnMut(u32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut blocks: F,
    ) -> bool {
        let Some(mut dda) = self.start(ray) else {
            return false;
        };
        let mut mailbox = Mailbox::new();
        loop {
            stats.nodes_visited += 1;
            for &prim in self.cell_prims(&dda) {
                if !mailbox.insert(prim) {
                    continue;
                }
                stats.prims_tested += 1;
                if blocks(prim) {
                    return true;
                }
            }
            if !self.advance(ray, &mut dda) {
                return false;
            }
        }
    }
}

/// The state of the walk: the current cell, the step direction per axis, the distance
/// to the next boundary per axis (∞ where the ray never steps), and where the ray leaves
/// the grid.
struct Dda {
    cell: [i32; 3],
    step: [i32; 3],
    next: [f32; 3],
    t_end: f32,
    inv_dir: Vec3,
}

/// Primitive boxes unioned into `k³` blocks by their centres; empty blocks dropped.
fn block_cover(boxes: &[Bounds3], bounds: &Bounds3, k: usize) -> Vec<Bounds3> {
    let mut blocks = vec![Bounds3::EMPTY; k * k * k];
    let d = bounds.diagonal();
    for b in boxes.iter().filter(|b| !b.is_empty()) {
        let c = b.center();
        let mut idx = [0usize; 3];
        for a in 0..3 {
            if d[a] > 0.0 {
                idx[a] = (((c[a] - bounds.min[a]) / d[a] * k as f32) as usize).min(k - 1);
            }
        }
        let i = (idx[2] * k + idx[1]) * k + idx[0];
        blocks[i] = blocks[i].union(b);
    }
    blocks.retain(|b| !b.is_empty());
    blocks
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::{self, boxes};
    use crate::accel::{Accel, AccelKind};

    #[test]
    fn matches_the_list_on_every_test_scene() {
        testing::check_kind_on_all_scenes(AccelKind::Grid);
    }

    #[test]
    fn resolution_follows_the_primitive_count() {
        let tris = testing::random_soup(4000, 9);
        let grid = Grid::build(&boxes(&tris));
        let cells: usize = grid.resolution().iter().product();
        assert!(
            (2 * 4000..8 * 4000).contains(&cells),
            "{:?}",
            grid.resolution()
        );
        // A flat scene gets one cell across its zero extent.
        let flat = Grid::build(&boxes(&testing::flat_soup(4000, 9)));
        assert_eq!(flat.resolution()[2], 1);
        assert!(flat.resolution()[0] > 50, "{:?}", flat.resolution());
    }

    /// A primitive spanning every cell along the ray is tested once, and the walk stops
    /// in the cell of the hit rather than at the grid's end.
    #[test]
    fn mailbox_and_early_exit() {
        let mut tris = testing::random_soup(2000, 10);
        // A big triangle in the plane x = 5 and a wall behind it at x = 9.
        tris.push([
            Vec3::new(5.0, -1.0, -1.0),
            Vec3::new(5.0, 21.0, -1.0),
            Vec3::new(5.0, -1.0, 21.0),
        ]);
        let big = tris.len() as u32 - 1;
        let grid = Accel::Grid(Grid::build(&boxes(&tris)));
        // Along the plane of the big triangle it spans every cell the ray enters.
        let ray = Ray::new(Vec3::new(5.0, 0.5, -3.0), Vec3::Z);
        let (_, tested, _) = testing::closest(&grid, &tris, &ray);
        assert_eq!(tested.iter().filter(|&&p| p == big).count(), 1);
        let mut seen = tested.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), tested.len(), "a primitive tested twice");
        // Through it: the walk ends in the cell of the first hit, not at the grid's end.
        let ray = Ray::new(Vec3::new(-1.0, 0.2, 0.3), Vec3::X);
        let (hit, _, stats) = testing::closest(&grid, &tris, &ray);
        assert!(hit.is_some_and(|(t, _)| t <= 6.0), "{hit:?}");
        let Accel::Grid(g) = &grid else {
            unreachable!()
        };
        assert!(
            (stats.nodes_visited as i32) < g.res[0] * 3 / 4,
            "{} cells visited of {}",
            stats.nodes_visited,
            g.res[0]
        );
    }
}
