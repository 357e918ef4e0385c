//! Triangles packed four to a block in the order of the mesh's BVH leaves, so that a leaf
//! is tested against a ray with one 4-lane SIMD watertight test per block instead of
//! four scalar tests behind three indirections each (BVH slot -> triangle -> vertices).
//!
//! The wide BVHs lay out their leaves at positions that are multiples of four and pad
//! each leaf to a whole number of blocks by repeating its last triangle, so a leaf at
//! `(first, count)` is exactly the blocks `first / 4 .. (first + count).div_ceil(4)`;
//! a repeated triangle can only find the same hit again.
//!
//! The lanes compute exactly what [`intersect_triangle_watertight`] computes, operation
//! for operation in the same order (no fused multiply-adds), so the packed path and the
//! scalar path agree bit for bit; a lane whose edge function is exactly zero falls back
//! to the scalar test, which redoes that case in double precision.

use super::mesh::{intersect_triangle_watertight, WatertightRay};
use crate::math::gamma;
use glam::{BVec4A, Vec3, Vec4};

/// Four triangles' vertices as structure of arrays: `p[vertex][axis]` holds that
/// coordinate of the four triangles (144 bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(16))]
pub struct TriangleBlock {
    pub p: [[Vec4; 3]; 3],
}

/// Triangles a block holds.
pub const BLOCK: usize = 4;

impl TriangleBlock {
    /// Packs four triangles given as vertex triples.
    pub fn new(tris: [[Vec3; 3]; 4]) -> TriangleBlock {
        let mut p = [[Vec4::ZERO; 3]; 3];
        for (lane, tri) in tris.iter().enumerate() {
            for (v, vertex) in tri.iter().enumerate() {
                for axis in 0..3 {
                    p[v][axis][lane] = vertex[axis];
                }
            }
        }
        TriangleBlock { p }
    }

    /// The vertices of triangle `lane`.
    #[inline]
    pub fn triangle(&self, lane: usize) -> (Vec3, Vec3, Vec3) {
        let v = |i: usize| Vec3::new(self.p[i][0][lane], self.p[i][1][lane], self.p[i][2][lane]);
        (v(0), v(1), v(2))
    }

    /// The watertight test for the four triangles at once. Returns the mask of lanes hit
    /// with `t_min < t <= t_max` (provably in front of the origin), their distances and
    /// their barycentrics `b1`, `b2`.
    #[inline(always)]
    pub fn intersect(&self, wr: &WatertightRay, t_min: f32, t_max: f32) -> (u32, Vec4, Vec4, Vec4) {
        let (kx, ky, kz) = wr.axes();
        let o = wr.origin;
        let (ox, oy, oz) = (Vec4::splat(o[kx]), Vec4::splat(o[ky]), Vec4::splat(o[kz]));
        let s = wr.shear();
        let (sx, sy, sz) = (Vec4::splat(s.x), Vec4::splat(s.y), Vec4::splat(s.z));
        let p = &self.p;
        // Translate to the ray origin, permute and shear.
        let (az, bz, cz) = (p[0][kz] - oz, p[1][kz] - oz, p[2][kz] - oz);
        let ax = (p[0][kx] - ox) + sx * az;
        let ay = (p[0][ky] - oy) + sy * az;
        let bx = (p[1][kx] - ox) + sx * bz;
        let by = (p[1][ky] - oy) + sy * bz;
        let cx = (p[2][kx] - ox) + sx * cz;
        let cy = (p[2][ky] - oy) + sy * cz;
        let e0 = bx * cy - by * cx;
        let e1 = cx * ay - cy * ax;
        let e2 = ax * by - ay * bx;
        let zero = Vec4::ZERO;
        if (e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero)).any() {
            return self.intersect_scalar(wr, t_min, t_max);
        }
        let negative = e0.cmplt(zero) | e1.cmplt(zero) | e2.cmplt(zero);
        let positive = e0.cmpgt(zero) | e1.cmpgt(zero) | e2.cmpgt(zero);
        let det = e0 + e1 + e2;
        let mut valid = !(negative & positive) & det.cmpne(zero);
        if !valid.any() {
            return (0, zero, zero, zero);
        }
        let (az, bz, cz) = (az * sz, bz * sz, cz * sz);
        let t_scaled = e0 * az + e1 * bz + e2 * cz;
        let (lo, hi) = (Vec4::splat(t_min) * det, Vec4::splat(t_max) * det);
        let det_negative = det.cmplt(zero);
        let reject_negative = det_negative & (t_scaled.cmpge(lo) | t_scaled.cmplt(hi));
        let reject_positive = !det_negative & (t_scaled.cmple(lo) | t_scaled.cmpgt(hi));
        valid &= !(reject_negative | reject_positive);
        if !valid.any() {
            return (0, zero, zero, zero);
        }
        let inv_det = Vec4::ONE / det;
        let t = t_scaled * inv_det;
        // Reject t that is not provably positive (pbrt-v4, section 6.8.4).
        let max_zt = az.abs().max(bz.abs()).max(cz.abs());
        let delta_z = Vec4::splat(gamma(3)) * max_zt;
        let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
        let max_yt = ay.abs().max(by.abs()).max(cy.abs());
        let g5 = Vec4::splat(gamma(5));
        let delta_x = g5 * (max_xt + max_zt);
        let delta_y = g5 * (max_yt + max_zt);
        let delta_e = Vec4::splat(2.0)
            * (Vec4::splat(gamma(2)) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = Vec4::splat(3.0)
            * (Vec4::splat(gamma(3)) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
            * inv_det.abs();
        valid &= t.cmpgt(delta_t);
        (mask(valid), t, e1 * inv_det, e2 * inv_det)
    }

    /// The same test one lane at a time (for lanes with an edge function of exactly 0).
    #[cold]
    fn intersect_scalar(
        &self,
        wr: &WatertightRay,
        t_min: f32,
        t_max: f32,
    ) -> (u32, Vec4, Vec4, Vec4) {
        let (mut bits, mut t, mut b1, mut b2) = (0, Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
        for lane in 0..BLOCK {
            let (p0, p1, p2) = self.triangle(lane);
            if let Some((tl, _, u, v)) = intersect_triangle_watertight(wr, t_min, t_max, p0, p1, p2)
            {
                bits |= 1 << lane;
                t[lane] = tl;
                b1[lane] = u;
                b2[lane] = v;
            }
        }
        (bits, t, b1, b2)
    }
}

#[inline(always)]
fn mask(b: BVec4A) -> u32 {
    b.bitmask()
}

/// The nearest of the lanes in `bits` (the lowest lane among equal distances).
#[inline(always)]
pub fn nearest_lane(bits: u32, t: Vec4) -> usize {
    let mut best = bits.trailing_zeros() as usize;
    let mut rest = bits & (bits - 1);
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        if t[lane] < t[best] {
            best = lane;
        }
        rest &= rest - 1;
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Ray;
    use crate::sampling::Pcg32;

    /// Every lane equals the scalar watertight test bit for bit, on random triangles,
    /// triangles sharing edges with the ray's axis, degenerate triangles and random rays
    /// with limited ranges.
    #[test]
    fn lanes_equal_the_scalar_test() {
        let mut rng = Pcg32::new(5, 11);
        let v = |rng: &mut Pcg32| {
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE
        };
        let mut hits = 0;
        for i in 0..20000 {
            let mut tris = [[Vec3::ZERO; 3]; 4];
            for tri in tris.iter_mut() {
                *tri = [v(&mut rng), v(&mut rng), v(&mut rng)];
            }
            if i % 7 == 0 {
                tris[1][2] = tris[1][1]; // degenerate: a segment
            }
            if i % 11 == 0 {
                tris[2] = [Vec3::ZERO, Vec3::X, Vec3::Y]; // edges on the axes
            }
            let block = TriangleBlock::new(tris);
            let o = v(&mut rng) * 2.0;
            // Mostly aimed at one of the triangles, so that many lanes hit.
            let aim = tris[i % 4];
            let mut d = (aim[0] + aim[1] + aim[2]) / 3.0 + v(&mut rng) * 0.2 - o;
            if i % 5 == 0 {
                d = [Vec3::Z, Vec3::NEG_X, Vec3::Y][i % 3];
            }
            let ray = Ray::with_range(o, d, rng.next_f32() * 0.2, 0.5 + rng.next_f32() * 3.0);
            let wr = WatertightRay::new(&ray);
            let (bits, t, b1, b2) = block.intersect(&wr, ray.t_min, ray.t_max);
            for (lane, tri) in tris.iter().enumerate() {
                let scalar = intersect_triangle_watertight(
                    &wr, ray.t_min, ray.t_max, tri[0], tri[1], tri[2],
                );
                match scalar {
                    Some((ts, _, u, w)) => {
                        hits += 1;
                        assert!(bits & (1 << lane) != 0, "ray {i} lane {lane}: missed");
                        assert_eq!(
                            (t[lane].to_bits(), b1[lane].to_bits(), b2[lane].to_bits()),
                            (ts.to_bits(), u.to_bits(), w.to_bits()),
                            "ray {i} lane {lane}"
                        );
                    }
                    None => assert!(bits & (1 << lane) == 0, "ray {i} lane {lane}: false hit"),
                }
            }
        }
        assert!(hits > 10000, "only {hits} hits: the test is too weak");
    }

    #[test]
    fn nearest_lane_takes_the_smallest_distance() {
        let t = Vec4::new(3.0, 1.0, 2.0, 1.0);
        assert_eq!(nearest_lane(0b1111, t), 1);
        assert_eq!(nearest_lane(0b0101, t), 2);
        assert_eq!(nearest_lane(0b1000, t), 3);
    }
}
