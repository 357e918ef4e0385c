//! Round cubic curves: hair and fur as smooth strands. Each curve is a chain of cubic
//! segments (uniform B-spline, Bézier or Catmull-Rom) whose radius is interpolated by
//! the same basis, and its surface is that of the sphere swept along it: the boundary of
//! the union of the spheres `(c(u), r(u))`. Where neighbouring segments meet they share
//! a sphere, so a curve is smooth along its length and ends in round caps. This is
//! Mitsuba 3's `bsplinecurve` (Embree's round B-spline curves), read from the same text
//! files as [`super::LinearCurves`]: one control point per line, `x y z radius`, an empty
//! line before each new curve. Unlike Embree's, the curves' ends are closed by the caps,
//! so a curve is a solid.
//!
//! ```xml
//! <!-- Mitsuba 3: the points are placed by to_world, the radii are not scaled -->
//! <shape type="bsplinecurve">
//!     <string name="filename" value="hair.txt"/>
//!     <bsdf type="hair"/>
//! </shape>
//!
//! <!-- lightwave: basis="linear" (the default), "bspline", "bezier" or "catmullrom";
//!      an instance transform places and scales the curves, radii included -->
//! <instance>
//!     <shape type="curves" filename="hair.txt" basis="bspline"/>
//!     <bsdf type="hair"/>
//! </instance>
//! ```
//!
//! Bases, for the control points `P0 … Pn-1` of one curve:
//! - `bspline`: segments `Pi … Pi+3` for every `i`, `n − 3` in all; the curve passes near,
//!   not through, its control points (Mitsuba's and Embree's convention);
//! - `bezier`: `n = 3k + 1` points, segments `P3i … P3i+3`, each passing through its first
//!   and last point;
//! - `catmullrom`: segments `Pi … Pi+3` from `Pi+1` to `Pi+2`, so the curve passes
//!   through every point but the first and last. Its Bézier radii can undershoot; they
//!   are clamped at zero.
//!
//! Every segment is converted to its Bézier form. A ray is intersected in double
//! precision, in a frame in which it runs along the z axis from the origin: the segment
//! is subdivided (de Casteljau) into pieces, those whose control hull, widened by their
//! largest radius, misses the ray are dropped, and the rest are subdivided until each is
//! within 3% of its radius of the straight round cone between its ends (the depth
//! follows from the control points' second differences). The cone gives a first entry
//! and its sphere `u`; Newton's method then solves the two conditions of the swept
//! surface, `|x − c(u)|² = r(u)²` and `(x − c(u))·c′(u) + r(u)·r′(u) = 0`, for the
//! distance and `u`; the answer is the ray's entry into the sphere at that `u`, so the
//! reported point always lies on a sphere of the union. Only rays entering from outside
//! hit (as with linear curves): a ray starting inside a segment passes through it.

use super::curves::{
    check_control_point, closest_segment, round_cone_entry, swept_sphere_interaction, ConeEntry,
    SegmentHit,
};
use super::{ShapeHit, SurfaceInteraction};
use crate::accel::{Accel, AccelKind, RayStats};
use crate::math::{gamma, Bounds3, Ray};
use glam::{DVec3, DVec4, Vec3, Vec4};

/// How a curve's control points define its cubic segments (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CubicBasis {
    BSpline,
    Bezier,
    CatmullRom,
}

impl CubicBasis {
    /// The basis of a scene's `basis` name, `None` for another name.
    pub fn from_name(name: &str) -> Option<CubicBasis> {
        match name {
            "bspline" => Some(CubicBasis::BSpline),
            "bezier" => Some(CubicBasis::Bezier),
            "catmullrom" => Some(CubicBasis::CatmullRom),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            CubicBasis::BSpline => "B-spline",
            CubicBasis::Bezier => "Bézier",
            CubicBasis::CatmullRom => "Catmull-Rom",
        }
    }

    /// Whether a curve of `n` control points is valid in this basis; otherwise what is
    /// wrong with it.
    pub fn check_count(self, n: usize) -> Result<(), String> {
        match self {
            CubicBasis::Bezier if n < 4 || (n - 1) % 3 != 0 => Err(format!(
                "a Bézier curve needs 3k + 1 control points (4, 7, 10, …); this one has {n}"
            )),
            CubicBasis::BSpline | CubicBasis::CatmullRom if n < 4 => Err(format!(
                "a {} curve needs at least four control points; this one has {n}",
                self.name()
            )),
            _ => Ok(()),
        }
    }

    /// The first control point of each segment of a curve of `n` (valid) points.
    fn segment_starts(self, n: usize) -> impl Iterator<Item = usize> {
        let step = if self == CubicBasis::Bezier { 3 } else { 1 };
        (0..n.saturating_sub(3)).step_by(step)
    }

    /// The Bézier control points (position and radius) of the segment `p`.
    fn to_bezier(self, p: [DVec4; 4]) -> [DVec4; 4] {
        let mut b = match self {
            CubicBasis::Bezier => p,
            CubicBasis::BSpline => [
                (p[0] + 4.0 * p[1] + p[2]) / 6.0,
                (2.0 * p[1] + p[2]) / 3.0,
                (p[1] + 2.0 * p[2]) / 3.0,
                (p[1] + 4.0 * p[2] + p[3]) / 6.0,
            ],
            CubicBasis::CatmullRom => [
                p[1],
                p[1] + (p[2] - p[0]) / 6.0,
                p[2] - (p[3] - p[1]) / 6.0,
                p[2],
            ],
        };
        for q in &mut b {
            q.w = q.w.max(0.0);
        }
        b
    }
}

/// Round cubic curves in object space: per segment its Bézier control points
/// `(x, y, z, radius)`.
#[derive(Debug, Clone)]
pub struct CubicCurves {
    control: Vec<[Vec4; 4]>,
    /// Subdivision depth of each segment's intersection.
    depth: Vec<u8>,
    /// Per segment: bit 0 set when the previous segment continues the same curve, bit 1
    /// when the next one does.
    links: Vec<u8>,
    curves: usize,
    basis: CubicBasis,
    accel: Accel,
}

/// Relative tolerance of a piece's deviation from its straight cone (of its radius).
const FLATNESS: f64 = 0.03;
/// Deepest subdivision of a segment (1024 pieces).
const MAX_DEPTH: u32 = 10;

impl CubicCurves {
    /// Curves from their control points `(position, radius)` in the given basis;
    /// positions and radii must be finite and radii not negative.
    pub fn new(
        curves: &[Vec<(Vec3, f32)>],
        basis: CubicBasis,
        accel: AccelKind,
    ) -> Result<CubicCurves, String> {
        if curves.is_empty() {
            return Err("no curves".into());
        }
        let mut control = Vec::new();
        let mut links: Vec<u8> = Vec::new();
        for (c, curve) in curves.iter().enumerate() {
            basis
                .check_count(curve.len())
                .map_err(|m| format!("curve {}: {m}", c + 1))?;
            for (k, &(p, r)) in curve.iter().enumerate() {
                check_control_point(c, k, p, r)?;
            }
            let first = links.len();
            for i in basis.segment_starts(curve.len()) {
                let p = [0, 1, 2, 3].map(|k| {
                    let (q, r) = curve[i + k];
                    q.as_dvec3().extend(r as f64)
                });
                control.push(basis.to_bezier(p).map(|q| q.as_vec4()));
                links.push(if links.len() > first { 1 } else { 0 });
            }
            for k in first..links.len() - 1 {
                links[k] |= 2;
            }
        }
        if control.len() >= u32::MAX as usize {
            return Err(format!("{} segments: too many", control.len()));
        }
        let depth = control
            .iter()
            .map(|b| subdivision_depth(&widen(b)))
            .collect();
        let boxes: Vec<Bounds3> = control.iter().map(segment_bounds).collect();
        Ok(CubicCurves {
            accel: Accel::build(accel, &boxes),
            control,
            depth,
            links,
            curves: curves.len(),
            basis,
        })
    }

    pub fn basis(&self) -> CubicBasis {
        self.basis
    }

    pub fn curve_count(&self) -> usize {
        self.curves
    }

    pub fn segment_count(&self) -> usize {
        self.control.len()
    }

    pub fn bounds(&self) -> Bounds3 {
        self.accel.bounds()
    }

    /// Seconds the accelerator over the segments took to build.
    pub fn build_seconds(&self) -> f64 {
        self.accel.build_seconds()
    }

    /// Bytes of the control points, depths and accelerator.
    pub fn memory_bytes(&self) -> usize {
        self.control.len() * (64 + 1) + self.accel.memory_bytes()
    }

    /// The closest hit within `[ray.t_min, ray.t_max]`.
    pub fn intersect(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        let query = RayQuery::new(ray)?;
        closest_segment(&self.accel, ray, stats, |segment, t_max| {
            self.entering_hit(&query, ray, segment as usize, t_max as f64)
        })
    }

    /// Whether a segment blocks the ray within its range.
    pub fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        let Some(query) = RayQuery::new(ray) else {
            return false;
        };
        self.accel.occluded(ray, stats, |segment| {
            self.entering_hit(&query, ray, segment as usize, ray.t_max as f64)
                .is_some()
        })
    }

    /// The segment's entering hit, unless it lies inside a neighbouring segment of the
    /// same curve: then the ray has entered the curve's solid before (or started inside
    /// it, and passes through).
    fn entering_hit(
        &self,
        query: &RayQuery,
        ray: &Ray,
        s: usize,
        t_max: f64,
    ) -> Option<SegmentHit> {
        let h = query.hit(&self.control[s], self.depth[s], t_max)?;
        let x = ray.origin.as_dvec3() + ray.direction.as_dvec3() * h.t;
        let links = self.links[s];
        let inside = |n: usize| point_inside(&widen(&self.control[n]), x);
        if (links & 1 != 0 && inside(s - 1)) || (links & 2 != 0 && inside(s + 1)) {
            return None;
        }
        Some(h)
    }

    /// The interaction at a hit: the point projected onto the sphere it lies on (at
    /// `hit.uv.x` along the segment), the outward normal from that sphere's centre, `u`
    /// the angle around the curve's tangent over 2π and `v` the position along all the
    /// segments (`(u + segment) / segments`, as for linear curves), `dpdu` around the
    /// tangent.
    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let b = widen(&self.control[hit.prim as usize]);
        let v = (hit.uv.x as f64).clamp(0.0, 1.0);
        let (c, dc, _) = bezier(&b, v);
        let along = (v + hit.prim as f64) / self.control.len() as f64;
        let sphere = (c.truncate(), c.w.max(0.0));
        swept_sphere_interaction(ray, hit, sphere, dc.truncate(), along)
    }
}

fn widen(b: &[Vec4; 4]) -> [DVec4; 4] {
    b.map(|q| q.as_dvec4())
}

/// The box of a segment's control hull, widened by its largest radius.
fn segment_bounds(b: &[Vec4; 4]) -> Bounds3 {
    let r = b.iter().fold(0.0f32, |m, q| m.max(q.w));
    let mut bounds = Bounds3::EMPTY;
    for q in b {
        bounds.expand(q.truncate());
    }
    // Widened by a few ulps more, for the rounding of the sums.
    let pad = Vec3::splat(r) + (bounds.min.abs().max(bounds.max.abs()) + r) * gamma(4);
    Bounds3::new(bounds.min - pad, bounds.max + pad)
}

/// How often a segment is halved before its pieces are taken as straight cones: a cubic
/// Bézier lies within `¾·max|Δ²P|` of its chord, and halving divides the second
/// differences by 4 (the radius counts as a fourth coordinate).
fn subdivision_depth(b: &[DVec4; 4]) -> u8 {
    let l0 = (b[0] - 2.0 * b[1] + b[2])
        .length()
        .max((b[1] - 2.0 * b[2] + b[3]).length());
    let r = b.iter().fold(0.0f64, |m, q| m.max(q.w));
    let extent = b
        .iter()
        .fold(0.0f64, |m, q| m.max(q.truncate().abs().max_element()));
    let eps = (FLATNESS * r).max(1e-9 * extent).max(f64::MIN_POSITIVE);
    let mut depth = 0;
    let mut deviation = 0.75 * l0;
    while deviation > eps && depth < MAX_DEPTH {
        deviation *= 0.25;
        depth += 1;
    }
    depth as u8
}

/// The point, first and second derivative of a Bézier segment at `u`.
#[inline]
fn bezier(b: &[DVec4; 4], u: f64) -> (DVec4, DVec4, DVec4) {
    let s = 1.0 - u;
    let p = b[0] * (s * s * s)
        + b[1] * (3.0 * u * s * s)
        + b[2] * (3.0 * u * u * s)
        + b[3] * (u * u * u);
    let d1 =
        ((b[1] - b[0]) * (s * s) + (b[2] - b[1]) * (2.0 * u * s) + (b[3] - b[2]) * (u * u)) * 3.0;
    let d2 = ((b[2] - 2.0 * b[1] + b[0]) * s + (b[3] - 2.0 * b[2] + b[1]) * u) * 6.0;
    (p, d1, d2)
}

/// Whether `x` lies inside a sphere of the segment, by more than rounding: the least of
/// `h(u) = |x − c(u)|² − r(u)²` (from the best of nine samples, refined by Newton's
/// method on `h′ = 0`) is below `−10⁻⁷·r²` for the segment's largest radius `r`.
fn point_inside(b: &[DVec4; 4], x: DVec3) -> bool {
    let r = b.iter().fold(0.0f64, |m, q| m.max(q.w));
    let limit = -1e-7 * r * r;
    let (least, start) = (0..=8)
        .map(|k| {
            let u = k as f64 / 8.0;
            (power(b, x, u), u)
        })
        .fold((f64::INFINITY, 0.0), |m, v| if v.0 < m.0 { v } else { m });
    least < limit || power(b, x, least_power(b, x, start, 0.0, 1.0, 16)) < limit
}

/// `h(u) = |x − c(u)|² − r(u)²`: negative where `x` is inside the sphere at `u`.
#[inline]
fn power(b: &[DVec4; 4], x: DVec3, u: f64) -> f64 {
    let (c, _, _) = bezier(b, u);
    (x - c.truncate()).length_squared() - c.w * c.w
}

/// A local minimum of [`power`] over `[u0, u1]`: Newton's method on `h′ = 0` from
/// `start`, at most `steps` steps, stopping where `h″ ≤ 0`.
fn least_power(b: &[DVec4; 4], x: DVec3, start: f64, u0: f64, u1: f64, steps: u32) -> f64 {
    let mut u = start;
    for _ in 0..steps {
        let (c, d1, d2) = bezier(b, u);
        let (p, dp, ddp) = (c.truncate() - x, d1.truncate(), d2.truncate());
        let g = p.dot(dp) - c.w * d1.w;
        let dg = dp.length_squared() + p.dot(ddp) - d1.w * d1.w - c.w * d2.w;
        if dg <= 0.0 || !dg.is_finite() {
            break;
        }
        let next = (u - g / dg).clamp(u0, u1);
        let step = (next - u).abs();
        u = next;
        if step < 1e-12 {
            break;
        }
    }
    u
}

/// The halves of a Bézier segment at `u = ½`.
#[inline]
fn split(b: &[DVec4; 4]) -> ([DVec4; 4], [DVec4; 4]) {
    let ab = (b[0] + b[1]) * 0.5;
    let bc = (b[1] + b[2]) * 0.5;
    let cd = (b[2] + b[3]) * 0.5;
    let abc = (ab + bc) * 0.5;
    let bcd = (bc + cd) * 0.5;
    let m = (abc + bcd) * 0.5;
    ([b[0], ab, abc, m], [m, bcd, cd, b[3]])
}

/// A ray prepared for segment tests: a frame in which it starts at the origin and runs
/// along +z with unit speed, so the distance `s` there is `t·|d|`.
struct RayQuery {
    origin: DVec3,
    /// The frame's axes (rows): two across the ray, then its unit direction.
    axes: [DVec3; 3],
    speed: f64,
    t_min: f64,
}

impl RayQuery {
    fn new(ray: &Ray) -> Option<RayQuery> {
        let d = ray.direction.as_dvec3();
        let speed = d.length();
        if !(speed > 0.0 && speed.is_finite() && ray.origin.is_finite()) {
            return None;
        }
        let n = d / speed;
        let sign = 1.0f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let e1 = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let e2 = DVec3::new(b, sign + n.y * n.y * a, -n.y);
        Some(RayQuery {
            origin: ray.origin.as_dvec3(),
            axes: [e1, e2, n],
            speed,
            t_min: ray.t_min as f64,
        })
    }

    /// A control point in the ray's frame (the radius kept).
    #[inline]
    fn local(&self, q: DVec4) -> DVec4 {
        let v = q.truncate() - self.origin;
        DVec4::new(
            v.dot(self.axes[0]),
            v.dot(self.axes[1]),
            v.dot(self.axes[2]),
            q.w,
        )
    }

    /// The closest entering hit of the segment within `(t_min, t_max)`: `t` and the
    /// position `v` along the segment. (Shadow rays search the whole segment too: a
    /// ray that starts inside it must pass through, wherever the piece that tells so
    /// comes in the search.)
    fn hit(&self, control: &[Vec4; 4], depth: u8, t_max: f64) -> Option<SegmentHit> {
        let b = widen(control).map(|q| self.local(q));
        let mut search = Search {
            segment: b,
            s_lo: self.t_min * self.speed,
            s_hi: t_max * self.speed,
            best: None,
            inside: false,
        };
        search.piece(&b, 0.0, 1.0, depth as u32);
        if search.inside {
            return None;
        }
        search.best.map(|(s, u)| SegmentHit {
            t: s / self.speed,
            v: u,
        })
    }
}

/// One segment's search in the ray's frame (see the module notes).
struct Search {
    /// The whole segment, for evaluation at any `u`.
    segment: [DVec4; 4],
    s_lo: f64,
    s_hi: f64,
    best: Option<(f64, f64)>,
    /// The ray starts inside the segment: it has no entering hit.
    inside: bool,
}

impl Search {
    fn limit(&self) -> f64 {
        self.best.map_or(self.s_hi, |(s, _)| s)
    }

    /// The piece `b` of the segment, from `u0` to `u1`.
    fn piece(&mut self, b: &[DVec4; 4], u0: f64, u1: f64, depth: u32) {
        if self.inside {
            return;
        }
        let r = b.iter().fold(0.0f64, |m, q| m.max(q.w));
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for q in b {
            lo = lo.min(q.truncate());
            hi = hi.max(q.truncate());
        }
        // The ray is the +z axis: the widened hull must contain x = y = 0 and reach the
        // remaining range of distances (or the origin, for the inside test).
        if lo.x > r || hi.x < -r || lo.y > r || hi.y < -r {
            return;
        }
        if lo.z - r > self.limit() || hi.z + r < self.s_lo.min(0.0) {
            return;
        }
        if depth > 0 {
            let (left, right) = split(b);
            let um = 0.5 * (u0 + u1);
            // The nearer half first, so that its hit can cull the other.
            if left[0].z.min(left[3].z) <= right[0].z.min(right[3].z) {
                self.piece(&left, u0, um, depth - 1);
                self.piece(&right, um, u1, depth - 1);
            } else {
                self.piece(&right, um, u1, depth - 1);
                self.piece(&left, u0, um, depth - 1);
            }
            return;
        }
        // The origin within reach of the piece: is it inside?
        if lo.z - r <= 0.0 && hi.z + r >= 0.0 && self.origin_inside(u0, u1) {
            self.inside = true;
            return;
        }
        let (a, b3) = (b[0], b[3]);
        let entry = round_cone_entry(
            DVec3::ZERO,
            DVec3::Z,
            self.s_lo,
            self.limit(),
            a.truncate(),
            a.w,
            b3.truncate(),
            b3.w,
        );
        match entry {
            // Inside the cone but outside the curve (within the flatness tolerance): the
            // ray leaves the surface here.
            ConeEntry::Inside | ConeEntry::Miss => {}
            ConeEntry::Hit(h) => {
                // The least entry over the piece is at one of its ends or where Newton's
                // method goes from the cone's.
                self.take(u0);
                self.take(u1);
                let u_cone = u0 + (u1 - u0) * h.v;
                self.take(u_cone);
                let (u, _) = self.newton(u_cone, h.t);
                self.take(u);
            }
        }
    }

    /// Takes the ray's entry into the sphere at `u`, if it lies in the range and is the
    /// nearest so far.
    fn take(&mut self, u: f64) {
        let u = u.clamp(0.0, 1.0);
        let (c, _, _) = bezier(&self.segment, u);
        let r = c.w.max(0.0);
        let disc = r * r - c.x * c.x - c.y * c.y;
        if disc < 0.0 {
            return;
        }
        let s = c.z - disc.sqrt();
        if s > self.s_lo && s > 0.0 && s < self.limit() {
            self.best = Some((s, u));
        }
    }

    /// Whether the origin lies inside a sphere of the piece from `u0` to `u1`: the least
    /// of `h(u) = |c(u)|² − r(u)²` over the piece (Newton's method on `h′ = 0` from the
    /// piece's middle, and its ends) is negative.
    fn origin_inside(&self, u0: f64, u1: f64) -> bool {
        let h = |u: f64| power(&self.segment, DVec3::ZERO, u);
        h(u0) < 0.0 || h(u1) < 0.0 || {
            let u = least_power(&self.segment, DVec3::ZERO, 0.5 * (u0 + u1), u0, u1, 12);
            h(u) < 0.0
        }
    }

    /// Newton's method on the swept surface's two conditions in `(u, s)`, from a start
    /// on the cone; returns the last iterate (clamped to the segment).
    fn newton(&self, mut u: f64, mut s: f64) -> (f64, f64) {
        for _ in 0..12 {
            let (c, d1, d2) = bezier(&self.segment, u);
            let w = DVec3::new(-c.x, -c.y, s - c.z);
            let (dc, ddc) = (d1.truncate(), d2.truncate());
            let g1 = w.length_squared() - c.w * c.w;
            let g2 = w.dot(dc) + c.w * d1.w;
            // Jacobian of (g1, g2) in (s, u).
            let a11 = 2.0 * w.z;
            let a12 = -2.0 * g2;
            let a21 = dc.z;
            let a22 = -dc.length_squared() + w.dot(ddc) + d1.w * d1.w + c.w * d2.w;
            let det = a11 * a22 - a12 * a21;
            if det == 0.0 || !det.is_finite() {
                break;
            }
            let ds = (-g1 * a22 + g2 * a12) / det;
            let du = (-g2 * a11 + g1 * a21) / det;
            if !(ds.is_finite() && du.is_finite()) {
                break;
            }
            s += ds;
            u = (u + du).clamp(0.0, 1.0);
            if du.abs() < 1e-12 && ds.abs() <= 1e-12 * (1.0 + s.abs()) {
                break;
            }
        }
        (u, s)
    }
}

#[cfg(test)]
mod tests;
