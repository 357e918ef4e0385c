//! Round linear curves: hair, fur, fibres and wires as chains of segments, each the
//! surface swept by a sphere whose centre moves along the segment and whose radius
//! varies linearly from one control point to the next (a cone tangent to two spheres).
//! Neighbouring segments share the sphere at their joint, so a curve is smooth at its
//! control points and ends in round caps. This is Mitsuba 3's `linearcurve` (Embree's
//! round linear curves), read from the same text files: one control point per line,
//! `x y z radius`, and an empty line before each new curve.
//!
//! ```xml
//! <!-- Mitsuba 3: the points are placed by to_world, the radii are not scaled -->
//! <shape type="linearcurve">
//!     <string name="filename" value="hair.txt"/>
//!     <transform name="to_world"><scale value="2"/></transform>
//!     <bsdf type="diffuse"/>
//! </shape>
//!
//! <!-- lightwave: an instance transform places and scales the curves, radii included -->
//! <instance>
//!     <shape type="curves" filename="hair.txt"/>
//!     <bsdf type="diffuse"/>
//! </instance>
//! ```
//!
//! As in Mitsuba, only rays that enter a curve from outside hit it: a ray that starts
//! inside (or leaves the surface inwards) passes through, so curves are for opaque
//! materials. The segments are the primitives of their own accelerator (the scene's
//! `--accel` kind), and each segment is intersected in double precision (the cone's
//! quadratic cancels badly in single precision for thin fibres seen from afar); the hit
//! point is projected back onto the exact surface.

use super::{ShapeHit, SurfaceInteraction};
use crate::accel::{Accel, AccelKind, RayStats};
use crate::math::{gamma, Bounds3, Frame, Ray, PI};
use glam::{DVec3, Vec2, Vec3};

/// Curves of linear segments with a radius per control point, in object space.
#[derive(Debug, Clone)]
pub struct LinearCurves {
    points: Vec<Vec3>,
    radii: Vec<f32>,
    /// The first control point of each segment (which joins it to the next).
    segments: Vec<u32>,
    curves: usize,
    accel: Accel,
}

/// The closest entering hit of a segment: the ray parameter and the position along the
/// segment (0 at its first control point, 1 at its second) of the sphere whose surface
/// the hit lies on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SegmentHit {
    pub t: f64,
    pub v: f64,
}

impl LinearCurves {
    /// Curves from their control points `(position, radius)`, each curve at least two
    /// points; positions and radii must be finite and radii not negative.
    pub fn new(curves: &[Vec<(Vec3, f32)>], accel: AccelKind) -> Result<LinearCurves, String> {
        if curves.is_empty() {
            return Err("no curves".into());
        }
        let total: usize = curves.iter().map(Vec::len).sum();
        if total >= u32::MAX as usize {
            return Err(format!("{total} control points: too many"));
        }
        let mut points = Vec::with_capacity(total);
        let mut radii = Vec::with_capacity(total);
        let mut segments = Vec::with_capacity(total);
        for (c, curve) in curves.iter().enumerate() {
            if curve.len() < 2 {
                return Err(format!(
                    "curve {} has {} control point(s); a curve needs at least two",
                    c + 1,
                    curve.len()
                ));
            }
            for (k, &(p, r)) in curve.iter().enumerate() {
                check_control_point(c, k, p, r)?;
                if k + 1 < curve.len() {
                    segments.push(points.len() as u32);
                }
                points.push(p);
                radii.push(r);
            }
        }
        let boxes: Vec<Bounds3> = segments
            .iter()
            .map(|&i| {
                let i = i as usize;
                let sphere = |k: usize| {
                    let r = Vec3::splat(radii[k]);
                    Bounds3::new(points[k] - r, points[k] + r)
                };
                sphere(i).union(&sphere(i + 1))
            })
            .collect();
        Ok(LinearCurves {
            accel: Accel::build(accel, &boxes),
            points,
            radii,
            segments,
            curves: curves.len(),
        })
    }

    pub fn curve_count(&self) -> usize {
        self.curves
    }

    pub fn segment_count(&self) -> usize {
        self.segments.len()
    }

    pub fn bounds(&self) -> Bounds3 {
        self.accel.bounds()
    }

    /// Seconds the accelerator over the segments took to build.
    pub fn build_seconds(&self) -> f64 {
        self.accel.build_seconds()
    }

    /// Bytes of the control points, segments and accelerator.
    pub fn memory_bytes(&self) -> usize {
        self.points.len() * 16 + self.segments.len() * 4 + self.accel.memory_bytes()
    }

    /// The segment's end spheres: centres and radii in double precision.
    #[inline]
    fn ends(&self, segment: u32) -> (DVec3, f64, DVec3, f64) {
        let i = self.segments[segment as usize] as usize;
        (
            self.points[i].as_dvec3(),
            self.radii[i] as f64,
            self.points[i + 1].as_dvec3(),
            self.radii[i + 1] as f64,
        )
    }

    /// The closest hit within `[ray.t_min, ray.t_max]`.
    pub fn intersect(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        closest_segment(&self.accel, ray, stats, |segment, t_max| {
            self.entering_hit(ray, segment, t_max)
        })
    }

    /// Whether a segment blocks the ray within its range.
    pub fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        self.accel.occluded(ray, stats, |segment| {
            self.entering_hit(ray, segment, ray.t_max).is_some()
        })
    }

    /// The segment's entering hit, unless it lies inside a neighbouring segment of the
    /// same curve: then the ray has entered the curve's solid before (or started inside
    /// it, and passes through).
    fn entering_hit(&self, ray: &Ray, segment: u32, t_max: f32) -> Option<SegmentHit> {
        let (a, ra, b, rb) = self.ends(segment);
        let h = segment_hit(ray, t_max, a, ra, b, rb)?;
        let x = ray.origin.as_dvec3() + ray.direction.as_dvec3() * h.t;
        let s = segment as usize;
        let first = self.segments[s];
        let inside = |n: usize| {
            let (a, ra, b, rb) = self.ends(n as u32);
            point_inside_round_cone(x, a, ra, b, rb)
        };
        if (s > 0 && self.segments[s - 1] + 1 == first && inside(s - 1))
            || (s + 1 < self.segments.len() && self.segments[s + 1] == first + 1 && inside(s + 1))
        {
            return None;
        }
        Some(h)
    }

    /// The interaction at a hit: the point projected onto the sphere it lies on (centre
    /// and radius interpolated at `hit.uv.x` along the segment), the outward normal from
    /// that centre, `u` the angle around the segment's axis over 2π and `v` the position
    /// along all the segments (as Mitsuba's: `(v + segment) / segments`), `dpdu` around
    /// the axis.
    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let (a, ra, b, rb) = self.ends(hit.prim);
        let v = (hit.uv.x as f64).clamp(0.0, 1.0);
        let along = (v + hit.prim as f64) / self.segments.len() as f64;
        let sphere = (a + (b - a) * v, ra + (rb - ra) * v);
        swept_sphere_interaction(ray, hit, sphere, b - a, along)
    }
}

/// Refuses the `k`-th control point of curve `c` (both from 0) unless its position and
/// radius are finite and the radius is not negative.
pub(crate) fn check_control_point(c: usize, k: usize, p: Vec3, r: f32) -> Result<(), String> {
    if !p.is_finite() || !r.is_finite() || r < 0.0 {
        return Err(format!(
            "curve {}, control point {}: position {p} and radius {r} must be finite, the \
             radius not negative",
            c + 1,
            k + 1
        ));
    }
    Ok(())
}

/// The closest of the segments' hits that `hit(segment, t_max)` finds through `accel`,
/// as a shape hit with the position along its segment in `uv.x`.
pub(crate) fn closest_segment(
    accel: &Accel,
    ray: &Ray,
    stats: &mut RayStats,
    mut hit: impl FnMut(u32, f32) -> Option<SegmentHit>,
) -> Option<ShapeHit> {
    let mut found = None;
    accel.intersect(ray, stats, |segment, t_max| match hit(segment, *t_max) {
        Some(h) => {
            *t_max = h.t as f32;
            found = Some(ShapeHit {
                t: h.t as f32,
                prim: segment,
                uv: Vec2::new(h.v as f32, 0.0),
            });
            true
        }
        None => false,
    });
    found
}

/// The interaction at a hit on a curve's swept surface, on the sphere `(centre, radius)`
/// of the curve whose tangent there is `tangent`: the hit point projected onto the
/// sphere, the outward normal from its centre, `u` the angle around the tangent over 2π,
/// `v` = `along` (the position along the curve set), `dpdu` around the tangent.
pub(crate) fn swept_sphere_interaction(
    ray: &Ray,
    hit: &ShapeHit,
    (centre, radius): (DVec3, f64),
    tangent: DVec3,
    along: f64,
) -> SurfaceInteraction {
    let x = ray.origin.as_dvec3() + ray.direction.as_dvec3() * hit.t as f64;
    let axis = tangent.normalize_or_zero();
    let out = x - centre;
    let n = if out.length_squared() > 0.0 {
        out.normalize()
    } else {
        // The hit is at the centre (a sphere of radius 0): face the ray.
        -ray.direction.as_dvec3().normalize()
    };
    let p = centre + n * radius;
    let (nf, pf) = (n.as_vec3(), p.as_vec3());
    // Rounding p to single precision is the only error left (half an ulp per axis).
    let p_error = gamma(4) * pf.abs();
    let frame = if axis == DVec3::ZERO {
        Frame::from_normal(nf)
    } else {
        Frame::from_normal(axis.as_vec3())
    };
    let mut u = nf.dot(frame.t).atan2(nf.dot(frame.s));
    if u < 0.0 {
        u += 2.0 * PI;
    }
    let mut dpdu = frame.n.cross(nf) * (2.0 * PI * radius as f32);
    if dpdu.length_squared() == 0.0 || !dpdu.is_finite() {
        dpdu = Frame::from_normal(nf).s;
    }
    SurfaceInteraction {
        p: pf,
        p_error,
        t: hit.t,
        n: nf,
        shading_n: nf,
        dpdu,
        // Along the curve (v runs along the curve set; its rate per unit of v is not
        // known here, so this has dp/du's length).
        dpdv: nf.cross(dpdu),
        uv: Vec2::new(u / (2.0 * PI), along as f32),
        color: Vec3::ONE,
        wo: -ray.direction.normalize(),
        instance: 0,
        prim: hit.prim,
    }
}

/// The entering hit closest to the ray's origin, within `(ray.t_min, t_max)`, of the
/// round segment from the sphere `(a, ra)` to the sphere `(b, rb)`: the solid is the
/// union of the two spheres and the cone tangent to both (their convex hull), so a ray
/// that starts outside it enters it once, where it first enters either sphere or the
/// cone's side between its two circles of contact; a ray that starts inside has no
/// entering hit.
///
/// The cone's side: a point `x` with `s = (x − a)·(b − a)` lies on it when
/// `F(x) = d²|x − a|² − s² + 2·ra·δ·s − L²·ra² = 0`, where `L = |b − a|`, `δ = ra − rb`
/// and `d² = L² − δ²` (the envelope of the spheres: its normal makes the angle
/// `sin α = δ / L` with the axis), and its sphere of contact is at `v = y / d²` along the
/// segment with `y = s − ra·δ`, which must lie in `[0, d²]`. `F` is positive outside, so
/// along the ray (a quadratic in `t`) the entering root is the one where `F` falls.
pub(crate) fn segment_hit(
    ray: &Ray,
    t_max: f32,
    a: DVec3,
    ra: f64,
    b: DVec3,
    rb: f64,
) -> Option<SegmentHit> {
    let o = ray.origin.as_dvec3();
    let d = ray.direction.as_dvec3();
    match round_cone_entry(o, d, ray.t_min as f64, t_max as f64, a, ra, b, rb) {
        ConeEntry::Hit(h) => Some(h),
        ConeEntry::Miss | ConeEntry::Inside => None,
    }
}

/// What a ray meets of a round segment ([`round_cone_entry`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum ConeEntry {
    /// It enters the solid within the range.
    Hit(SegmentHit),
    /// It does not enter it within the range.
    Miss,
    /// Its origin is inside the solid.
    Inside,
}

/// [`segment_hit`] for the ray `o + t·d` in double precision, within `(t_lo, t_hi)`,
/// telling a ray that starts inside the solid from one that misses it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn round_cone_entry(
    o: DVec3,
    d: DVec3,
    t_lo: f64,
    t_hi: f64,
    a: DVec3,
    ra: f64,
    b: DVec3,
    rb: f64,
) -> ConeEntry {
    let dd = d.length_squared();
    if dd == 0.0 || !dd.is_finite() {
        return ConeEntry::Miss;
    }
    let ba = b - a;
    let l2 = ba.length_squared();
    let delta = ra - rb;
    let d2 = l2 - delta * delta;
    let oa = o - a;
    let m1 = ba.dot(oa);
    let m5 = oa.length_squared();
    let k0 = d2 * m5 - m1 * m1 + 2.0 * ra * delta * m1 - l2 * ra * ra;
    // A ray that starts inside the (convex) solid never enters it.
    let inside = m5 < ra * ra
        || (o - b).length_squared() < rb * rb
        || (l2 > 0.0 && d2 > 0.0 && k0 < 0.0 && (0.0..=d2).contains(&(m1 - ra * delta)));
    if inside {
        return ConeEntry::Inside;
    }
    let mut best: Option<SegmentHit> = None;
    let mut take = |t: f64, v: f64| {
        if t > t_lo && t < t_hi && t > 0.0 && best.is_none_or(|h| t < h.t) {
            best = Some(SegmentHit { t, v });
        }
    };
    for (c, r, v) in [(a, ra, 0.0), (b, rb, 1.0)] {
        if let Some(t) = sphere_entry(o, d, dd, c, r) {
            take(t, v);
        }
    }
    if l2 > 0.0 && d2 > 0.0 {
        let m2 = ba.dot(d);
        let m3 = d.dot(oa);
        let k2 = d2 * dd - m2 * m2;
        let k1 = d2 * m3 - m1 * m2 + ra * delta * m2;
        let h = k1 * k1 - k0 * k2;
        if h >= 0.0 && k2 != 0.0 {
            let t = (-k1 - h.sqrt()) / k2;
            let y = m1 + t * m2 - ra * delta;
            if (0.0..=d2).contains(&y) {
                take(t, y / d2);
            }
        }
    }
    match best {
        Some(h) => ConeEntry::Hit(h),
        None => ConeEntry::Miss,
    }
}

/// Whether `x` lies inside the round segment from `(a, ra)` to `(b, rb)` by more than
/// rounding (a relative 10⁻⁷ of the squared radii; see [`round_cone_entry`] for the
/// cone's side).
pub(crate) fn point_inside_round_cone(x: DVec3, a: DVec3, ra: f64, b: DVec3, rb: f64) -> bool {
    const REL: f64 = 1e-7;
    let (xa, ba) = (x - a, b - a);
    if xa.length_squared() - ra * ra < -REL * ra * ra
        || (x - b).length_squared() - rb * rb < -REL * rb * rb
    {
        return true;
    }
    let l2 = ba.length_squared();
    let delta = ra - rb;
    let d2 = l2 - delta * delta;
    if !(l2 > 0.0 && d2 > 0.0) {
        return false;
    }
    let m1 = ba.dot(xa);
    let k0 = d2 * xa.length_squared() - m1 * m1 + 2.0 * ra * delta * m1 - l2 * ra * ra;
    let r = ra.max(rb);
    k0 < -REL * d2 * r * r && (0.0..=d2).contains(&(m1 - ra * delta))
}

/// The entering root of the sphere `(c, r)` along `o + t·d` (`dd = d·d`), in the stable
/// form: the discriminant from the distance of the centre to the ray's line, and the
/// smaller root from the product of the roots.
#[inline]
fn sphere_entry(o: DVec3, d: DVec3, dd: f64, c: DVec3, r: f64) -> Option<f64> {
    if r <= 0.0 {
        return None;
    }
    let oc = o - c;
    let b_half = oc.dot(d);
    let closest = oc - d * (b_half / dd);
    let disc = dd * (r * r - closest.length_squared());
    if disc < 0.0 {
        return None;
    }
    let q = -(b_half + b_half.signum() * disc.sqrt());
    if q == 0.0 {
        return None;
    }
    let c0 = oc.length_squared() - r * r;
    Some((q / dd).min(c0 / q))
}

#[cfg(test)]
mod tests;
