//! The brute-force "accelerator": tests every primitive whose box the ray enters. The
//! correctness oracle for every other structure.

use super::RayStats;
use crate::math::{Bounds3, Ray};

#[derive(Debug, Clone)]
pub struct ListAccel {
    boxes: Vec<Bounds3>,
    bounds: Bounds3,
}

impl ListAccel {
    /// The primitive boxes if there are few, else the overall box.
    pub fn cover(&self, max_boxes: usize) -> Vec<Bounds3> {
        if self.boxes.len() <= max_boxes {
            self.boxes.clone()
        } else {
            vec![self.bounds]
        }
    }

    pub fn new(bounds: &[Bounds3]) -> Self {
        let total = bounds.iter().fold(Bounds3::EMPTY, |acc, b| acc.union(b));
        ListAccel {
            boxes: bounds.to_vec(),
            bounds: total,
        }
    }

    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }

    pub fn memory_bytes(&self) -> usize {
        self.boxes.len() * std::mem::size_of::<Bounds3>()
    }

    #[inline]
    pub fn intersect<F: FnMut(u32, &mut f32) -> bool>(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
        mut hit: F,
    ) -> bool {
        let mut t_max = ray.t_max;
        let mut any = false;
        for i in 0..self.boxes.len() as u32 {
            stats.prims_tested += 1;
            any |= hit(i, &mut t_max);
        }
        any
    }

    #[inline]
    pub fn occluded<F: FnMut(u32) -> bool>(
        &self,
        _ray: &Ray,
        stats: &mut RayStats,
        mut blocks: F,
    ) -> bool {
        for i in 0..self.boxes.len() as u32 {
            stats.prims_tested += 1;
            if blocks(i) {
                return true;
            }
        }
        false
    }
}
