use super::*;
use crate::math::offset_ray_origin;
use crate::sampling::Pcg32;

/// The signed distance of `x` to the round segment, by definition: the least distance
/// to the swept spheres' surfaces, `min over s of |x − c(s)| − r(s)`, which is convex in
/// `s`, so a ternary search finds it.
fn distance(x: DVec3, a: DVec3, ra: f64, b: DVec3, rb: f64) -> f64 {
    let g = |s: f64| (x - (a + (b - a) * s)).length() - (ra + (rb - ra) * s);
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..200 {
        let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if g(m1) < g(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    g(0.5 * (lo + hi)).min(g(0.0)).min(g(1.0))
}

/// The first entry of the ray into the solid by marching the distance function (sphere
/// tracing: a step of the distance never crosses the surface), `None` when the origin
/// is inside or the ray leaves `t_max`. Also the least distance met along the way, to
/// skip grazing rays that either answer may call a hit.
fn marched(ray: &Ray, a: DVec3, ra: f64, b: DVec3, rb: f64) -> (Option<f64>, f64) {
    let (o, d) = (ray.origin.as_dvec3(), ray.direction.as_dvec3());
    let len = d.length();
    let mut t = ray.t_min as f64;
    let mut least = f64::INFINITY;
    if distance(o + d * t, a, ra, b, rb) <= 0.0 {
        return (None, 0.0);
    }
    for _ in 0..100_000 {
        let dist = distance(o + d * t, a, ra, b, rb);
        least = least.min(dist);
        if dist < 1e-10 {
            return (Some(t), least);
        }
        t += dist / len;
        if t > ray.t_max as f64 || t > 1e3 {
            return (None, least);
        }
    }
    (None, least)
}

fn random_vec(rng: &mut Pcg32, scale: f32) -> Vec3 {
    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE) * scale
}

/// Random segments (equal, growing and shrinking radii, one sphere almost containing
/// the other, zero radius at one end) against random rays: the same first entry as
/// marching the definition, and interactions on the surface with the outward normal.
#[test]
fn segments_match_the_swept_sphere_definition() {
    let mut rng = Pcg32::new(7, 11);
    let mut hits = 0;
    for case in 0..3000 {
        let a = random_vec(&mut rng, 1.0);
        let b = random_vec(&mut rng, 1.0);
        let ra = 0.05 + 0.4 * rng.next_f32();
        let rb = match case % 4 {
            0 => ra,
            1 => 0.05 + 0.4 * rng.next_f32(),
            2 => 0.0,
            _ => ra + 0.9 * (b - a).length(),
        };
        let origin = random_vec(&mut rng, 3.0);
        // Aim near the segment, so that most rays hit it.
        let target = a.lerp(b, rng.next_f32()) + random_vec(&mut rng, ra.max(rb) * 1.2);
        let dir = (target - origin) * (0.5 + rng.next_f32());
        let ray = Ray::new(origin, dir);
        let (a64, b64) = (a.as_dvec3(), b.as_dvec3());
        let (ra64, rb64) = (ra as f64, rb as f64);
        let (expected, least) = marched(&ray, a64, ra64, b64, rb64);
        let got = segment_hit(&ray, f32::INFINITY, a64, ra64, b64, rb64);
        if expected.is_none() && least.abs() < 1e-5 {
            continue; // a near miss (or a start on the surface): either answer may hold
        }
        match (expected, got) {
            (None, None) => {}
            (Some(t), Some(h)) => {
                hits += 1;
                // Sphere tracing creeps up on a grazing hit: compare where it is steep.
                let x = ray.origin.as_dvec3() + ray.direction.as_dvec3() * t;
                let e = 1e-6;
                let along = (distance(x - ray.direction.as_dvec3() * e, a64, ra64, b64, rb64)
                    - distance(x, a64, ra64, b64, rb64))
                    / (e * ray.direction.as_dvec3().length());
                let tolerance = if along > 0.05 { 1e-6 } else { 1e-3 };
                assert!(
                    (h.t - t).abs() < tolerance * (1.0 + t),
                    "case {case}: t {} against {t}",
                    h.t
                );
                let curves = LinearCurves::new(&[vec![(a, ra), (b, rb)]], AccelKind::List).unwrap();
                let shape_hit = ShapeHit {
                    t: h.t as f32,
                    prim: 0,
                    uv: Vec2::new(h.v as f32, 0.0),
                };
                let si = curves.interaction(&ray, &shape_hit);
                let p = si.p.as_dvec3();
                assert!(
                    distance(p, a64, ra64, b64, rb64).abs() < 1e-5,
                    "case {case}: the point is off the surface"
                );
                // The normal is the distance's gradient.
                let e = 1e-5;
                let grad = DVec3::new(
                    distance(p + DVec3::X * e, a64, ra64, b64, rb64)
                        - distance(p - DVec3::X * e, a64, ra64, b64, rb64),
                    distance(p + DVec3::Y * e, a64, ra64, b64, rb64)
                        - distance(p - DVec3::Y * e, a64, ra64, b64, rb64),
                    distance(p + DVec3::Z * e, a64, ra64, b64, rb64)
                        - distance(p - DVec3::Z * e, a64, ra64, b64, rb64),
                )
                .normalize();
                assert!(
                    (grad - si.n.as_dvec3()).length() < 1e-3,
                    "case {case}: normal {} against the gradient {grad}",
                    si.n
                );
                assert!((si.n.length() - 1.0).abs() < 1e-5);
                assert!(
                    si.n.dot(ray.direction) < 0.0,
                    "an entering hit faces the ray"
                );
            }
            (e, g) => panic!("case {case}: marching {e:?}, segment_hit {g:?}"),
        }
    }
    assert!(hits > 500, "only {hits} hits: the test rays miss too often");
}

/// Rays that start inside a segment pass through it, as in Mitsuba (only entering hits).
#[test]
fn rays_from_inside_pass_through() {
    let c = LinearCurves::new(
        &[vec![(Vec3::ZERO, 0.5), (Vec3::X * 2.0, 0.25)]],
        AccelKind::Bvh8,
    )
    .unwrap();
    let stats = &mut RayStats::default();
    for d in [Vec3::X, -Vec3::X, Vec3::Y, Vec3::new(0.3, -0.2, 0.9)] {
        assert!(c
            .intersect(&Ray::new(Vec3::new(0.5, 0.0, 0.0), d), stats)
            .is_none());
        assert!(!c.occluded(&Ray::new(Vec3::new(0.5, 0.0, 0.0), d), stats));
    }
    // Along a curve of several segments: a ray from inside passes the joints too.
    let chain: Vec<(Vec3, f32)> = (0..6).map(|i| (Vec3::X * i as f32, 0.3)).collect();
    let chain = LinearCurves::new(&[chain], AccelKind::Bvh8).unwrap();
    for d in [Vec3::X, -Vec3::X, Vec3::new(1.0, 0.05, -0.02)] {
        let ray = Ray::new(Vec3::new(1.5, 0.0, 0.0), d);
        assert!(chain.intersect(&ray, stats).is_none(), "{d}");
        assert!(!chain.occluded(&ray, stats), "{d}");
    }
    // From outside, a ray straight at a joint hits it.
    let h = chain
        .intersect(&Ray::new(Vec3::new(2.0, 0.0, -1.0), Vec3::Z), stats)
        .unwrap();
    assert!((h.t - 0.7).abs() < 1e-6, "{}", h.t);
    // From outside: the cap at x = −0.5 and, past the end, nothing behind.
    let h = c
        .intersect(&Ray::new(Vec3::new(-3.0, 0.0, 0.0), Vec3::X), stats)
        .unwrap();
    assert!((h.t - 2.5).abs() < 1e-6, "{}", h.t);
    assert!(c
        .intersect(&Ray::new(Vec3::new(3.0, 0.0, 0.0), Vec3::X), stats)
        .is_none());
    // The side of a capsule (equal radii) at exactly its radius, and t_max honoured.
    let capsule = LinearCurves::new(
        &[vec![(Vec3::ZERO, 0.25), (Vec3::X * 2.0, 0.25)]],
        AccelKind::Bvh8,
    )
    .unwrap();
    let ray = Ray::new(Vec3::new(1.0, 0.0, -2.0), Vec3::Z);
    let h = capsule.intersect(&ray, stats).unwrap();
    assert!((h.t - 1.75).abs() < 1e-6, "{}", h.t);
    let si = capsule.interaction(&ray, &h);
    assert!((si.n - -Vec3::Z).length() < 1e-6);
    assert!(
        (si.uv.y - 0.5).abs() < 1e-6,
        "v along the curve {}",
        si.uv.y
    );
    let short = Ray::with_range(ray.origin, ray.direction, 0.0, 1.7);
    assert!(capsule.intersect(&short, stats).is_none());
    assert!(!capsule.occluded(&short, stats));
}

/// Many curves through every accelerator: the closest hit equals the brute-force list's,
/// and rays spawned off a hit away from the surface do not hit it again.
#[test]
fn accelerators_agree_and_spawned_rays_leave() {
    let mut rng = Pcg32::new(3, 5);
    let mut curves = Vec::new();
    for _ in 0..40 {
        let mut p = random_vec(&mut rng, 2.0);
        let mut curve = Vec::new();
        for _ in 0..6 {
            curve.push((p, 0.02 + 0.08 * rng.next_f32()));
            p += random_vec(&mut rng, 0.3);
        }
        curves.push(curve);
    }
    let list = LinearCurves::new(&curves, AccelKind::List).unwrap();
    assert_eq!((list.curve_count(), list.segment_count()), (40, 200));
    let kinds = [
        AccelKind::Bvh2,
        AccelKind::Bvh4,
        AccelKind::Bvh8,
        AccelKind::Grid,
        AccelKind::KdTree,
        AccelKind::Octree,
        AccelKind::Bsp,
    ];
    let built: Vec<LinearCurves> = kinds
        .iter()
        .map(|&k| LinearCurves::new(&curves, k).unwrap())
        .collect();
    let stats = &mut RayStats::default();
    let mut hits = 0;
    for _ in 0..2000 {
        let origin = random_vec(&mut rng, 4.0);
        // Aim near a random control point.
        let curve = &curves[(rng.next_f32() * 40.0) as usize % 40];
        let (p, r) = curve[(rng.next_f32() * 6.0) as usize % 6];
        let ray = Ray::new(origin, p + random_vec(&mut rng, 2.0 * r) - origin);
        let expected = list.intersect(&ray, stats);
        for (k, c) in kinds.iter().zip(&built) {
            let got = c.intersect(&ray, stats);
            assert_eq!(got.map(|h| h.t), expected.map(|h| h.t), "{k:?}");
            assert_eq!(c.occluded(&ray, stats), expected.is_some(), "{k:?}");
        }
        let Some(h) = expected else { continue };
        hits += 1;
        let si = list.interaction(&ray, &h);
        // Leave the surface on its outer side in a few directions.
        for _ in 0..4 {
            let mut w = random_vec(&mut rng, 1.0);
            if w.dot(si.n) < 0.0 {
                w = -w;
            }
            if w.dot(si.n) < 1e-3 {
                continue;
            }
            let o = offset_ray_origin(si.p, si.p_error, si.n, w);
            let again = list.intersect(&Ray::new(o, w), stats);
            if let Some(g) = again {
                assert!(
                    g.prim != h.prim || g.t > 1e-3,
                    "the ray spawned off segment {} hit it again at t = {}",
                    h.prim,
                    g.t
                );
            }
        }
    }
    assert!(hits > 200, "only {hits} hits");
}

#[test]
fn bad_curves_are_refused() {
    let one = vec![(Vec3::ZERO, 0.1)];
    assert!(LinearCurves::new(&[one], AccelKind::Bvh8)
        .unwrap_err()
        .contains("at least two"));
    let nan = vec![(Vec3::ZERO, 0.1), (Vec3::new(f32::NAN, 0.0, 0.0), 0.1)];
    assert!(LinearCurves::new(&[nan], AccelKind::Bvh8)
        .unwrap_err()
        .contains("control point 2"));
    let negative = vec![(Vec3::ZERO, 0.1), (Vec3::X, -0.1)];
    assert!(LinearCurves::new(&[negative], AccelKind::Bvh8).is_err());
    assert!(LinearCurves::new(&[], AccelKind::Bvh8).is_err());
}
