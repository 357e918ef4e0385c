//! Warps from the unit square to other domains, each with its density.

use crate::math::{INV_PI, PI};
use glam::{Vec2, Vec3};

/// Shirley–Chiu concentric map to the unit disk (area-preserving, low distortion).
#[inline]
pub fn square_to_uniform_disk_concentric(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    // θ = φ in the wedges around ±x, θ = π/2 − φ around ±y, with |φ| ≤ π/4.
    if o.x.abs() > o.y.abs() {
        let (sin, cos) = sin_cos_quarter((PI / 4.0) * (o.y / o.x));
        o.x * Vec2::new(cos, sin)
    } else {
        let (sin, cos) = sin_cos_quarter((PI / 4.0) * (o.x / o.y));
        o.y * Vec2::new(sin, cos)
    }
}

/// `(sin x, cos x)` for `|x| ≤ π/4` by their Taylor polynomials (truncation below 4e-7
/// there, about f32's rounding), in place of a library call at every diffuse bounce.
#[inline]
fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let sin = x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0))));
    let cos = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0))));
    (sin, cos)
}

/// Uniform density on the unit disk.
pub const UNIFORM_DISK_PDF: f32 = INV_PI;

/// A uniform point in the regular polygon with `blades` corners inscribed in the unit
/// circle, first corner at angle `rotation` (radians). The polygon is split into
/// `blades` equal triangles; `u.x` picks one and is reused, `u` then warps uniformly into
/// the triangle.
pub fn square_to_uniform_polygon(u: Vec2, blades: u32, rotation: f32) -> Vec2 {
    let n = blades.max(3) as f32;
    let scaled = u.x * n;
    let k = (scaled as u32).min(blades.max(3) - 1);
    let ux = scaled - k as f32;
    let a0 = rotation + 2.0 * PI * k as f32 / n;
    let a1 = rotation + 2.0 * PI * (k + 1) as f32 / n;
    let p0 = Vec2::new(a0.cos(), a0.sin());
    let p1 = Vec2::new(a1.cos(), a1.sin());
    // Uniform barycentrics on the triangle (centre, p0, p1).
    let su = ux.sqrt();
    let b0 = su * (1.0 - u.y);
    let b1 = su * u.y;
    p0 * b0 + p1 * b1
}

/// Uniform direction on the unit sphere.
#[inline]
pub fn square_to_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

pub const UNIFORM_SPHERE_PDF: f32 = 0.25 * INV_PI;

/// Cosine-weighted direction on the +z hemisphere.
#[inline]
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = square_to_uniform_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

#[inline]
pub fn cosine_hemisphere_pdf(v: Vec3) -> f32 {
    v.z.max(0.0) * INV_PI
}

/// Uniform barycentrics on a triangle (Heitz 2019's low-distortion map).
#[inline]
pub fn square_to_uniform_triangle(u: Vec2) -> Vec2 {
    if u.x < u.y {
        let b0 = u.x / 2.0;
        Vec2::new(b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        Vec2::new(u.x - b1, b1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_sin_cos_matches_the_library() {
        let mut worst = 0.0f64;
        for k in -10_000..=10_000 {
            let x = (PI / 4.0) * k as f32 / 10_000.0;
            let (s, c) = sin_cos_quarter(x);
            let (s64, c64) = (x as f64).sin_cos();
            worst = worst
                .max((s as f64 - s64).abs())
                .max((c as f64 - c64).abs());
        }
        assert!(worst < 5e-7, "{worst}");
    }

    #[test]
    fn concentric_map_stays_on_the_disk_and_keeps_its_wedges() {
        for i in 0..=64 {
            for j in 0..=64 {
                let u = Vec2::new(i as f32 / 64.0, j as f32 / 64.0);
                let d = square_to_uniform_disk_concentric(u);
                let o = 2.0 * u - Vec2::ONE;
                // The square's ring at radius max(|ox|, |oy|) maps to the circle of it.
                let r = o.x.abs().max(o.y.abs());
                assert!((d.length() - r).abs() < 1e-6, "{u:?} {d:?}");
                // Each point stays in its square's quadrant.
                assert!(d.x * o.x >= -1e-7 && d.y * o.y >= -1e-7, "{u:?} {d:?}");
            }
        }
    }
    use crate::sampling::Pcg32;

    fn uniform_in(n: usize, f: impl Fn(Vec2) -> Vec2, region: impl Fn(Vec2) -> bool) -> f32 {
        let mut rng = Pcg32::new(5, 5);
        let mut inside = 0;
        for _ in 0..n {
            let p = f(Vec2::new(rng.next_f32(), rng.next_f32()));
            if region(p) {
                inside += 1;
            }
        }
        inside as f32 / n as f32
    }

    #[test]
    fn disk_is_uniform() {
        // The inner disk of radius 1/2 holds a quarter of the area.
        let frac = uniform_in(200_000, square_to_uniform_disk_concentric, |p| {
            p.length() < 0.5
        });
        assert!((frac - 0.25).abs() < 0.005, "{frac}");
        let frac = uniform_in(200_000, square_to_uniform_disk_concentric, |p| {
            p.x > 0.0 && p.y > 0.0
        });
        assert!((frac - 0.25).abs() < 0.005, "{frac}");
    }

    #[test]
    fn polygon_is_uniform_and_inside() {
        // A square (4 blades, rotated 45°) is [-s, s]^2 with s = 1/sqrt 2.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let f = |u| square_to_uniform_polygon(u, 4, PI / 4.0);
        let frac = uniform_in(200_000, f, |p| {
            p.x.abs() <= s + 1e-5 && p.y.abs() <= s + 1e-5
        });
        assert_eq!(frac, 1.0);
        let frac = uniform_in(200_000, f, |p| p.x > 0.0 && p.y > 0.0);
        assert!((frac - 0.25).abs() < 0.005, "{frac}");
        let frac = uniform_in(200_000, f, |p| p.x.abs() < s / 2.0 && p.y.abs() < s / 2.0);
        assert!((frac - 0.25).abs() < 0.005, "{frac}");
    }

    #[test]
    fn sphere_and_hemisphere_are_unit() {
        let mut rng = Pcg32::new(2, 2);
        let mut mean_z = 0.0;
        for _ in 0..10_000 {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            assert!((square_to_uniform_sphere(u).length() - 1.0).abs() < 1e-5);
            let h = square_to_cosine_hemisphere(u);
            assert!((h.length() - 1.0).abs() < 1e-4 && h.z >= 0.0);
            mean_z += h.z;
        }
        // E[cos θ] under the cosine density is 2/3.
        assert!((mean_z / 10_000.0 - 2.0 / 3.0).abs() < 0.01);
    }
}
