use super::*;
use crate::geometry::curves::segment_hit;
use crate::geometry::LinearCurves;
use crate::math::offset_ray_origin;
use crate::sampling::Pcg32;

fn random_vec(rng: &mut Pcg32, scale: f32) -> Vec3 {
    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE) * scale
}

/// The definition, brute force: in the ray's frame, the entry into the sphere at `u` is
/// `s(u) = cz − √(r² − cx² − cy²)`; the first entry into the union of the spheres is the
/// least `s(u) > 0` over `u`, found by sampling `u` densely and refining the best
/// samples by golden-section search. Also the margin `min over u of √(cx² + cy²) − r`,
/// the ray's clearance of the spheres (negative when it meets one), to skip grazing rays.
fn brute_force(ray: &Ray, b: &[DVec4; 4]) -> (Option<(f64, f64)>, f64) {
    let q = RayQuery::new(ray).unwrap();
    let local = b.map(|p| q.local(p));
    let entry = |u: f64| {
        let (c, _, _) = bezier(&local, u);
        let disc = c.w * c.w - c.x * c.x - c.y * c.y;
        let s = c.z - disc.max(0.0).sqrt();
        if disc >= 0.0 && s > 0.0 {
            s
        } else {
            f64::INFINITY
        }
    };
    let clearance = |u: f64| {
        let (c, _, _) = bezier(&local, u);
        (c.x * c.x + c.y * c.y).sqrt() - c.w
    };
    const N: usize = 4000;
    let mut best: Option<(f64, f64)> = None;
    let mut margin = f64::INFINITY;
    for i in 0..=N {
        let u = i as f64 / N as f64;
        margin = margin.min(clearance(u));
        let s = entry(u);
        if s.is_finite() {
            // Refine within the neighbouring samples.
            let (mut lo, mut hi) = ((u - 1.0 / N as f64).max(0.0), (u + 1.0 / N as f64).min(1.0));
            for _ in 0..80 {
                let (m1, m2) = (lo + (hi - lo) * 0.382, hi - (hi - lo) * 0.382);
                if entry(m1) < entry(m2) {
                    hi = m2;
                } else {
                    lo = m1;
                }
            }
            for v in [u, 0.5 * (lo + hi)] {
                let s = entry(v);
                if best.is_none_or(|(b, _)| s < b) {
                    best = Some((s, v));
                }
            }
        }
    }
    (best.map(|(s, u)| (s / q.speed, u)), margin)
}

fn random_segment(rng: &mut Pcg32) -> [Vec4; 4] {
    let p = [0, 1, 2, 3].map(|_| {
        random_vec(rng, 1.0)
            .as_dvec3()
            .extend(0.05 + 0.35 * rng.next_f32() as f64)
    });
    let basis = [
        CubicBasis::BSpline,
        CubicBasis::Bezier,
        CubicBasis::CatmullRom,
    ][rng.next_u32() as usize % 3];
    basis.to_bezier(p).map(|q| q.as_vec4())
}

/// Random segments of every basis against rays from outside aimed near them: hit or
/// miss, distance and position along the curve as the brute-force definition gives
/// them, for all but grazing rays (within 4% of the radius of a silhouette, where the
/// pieces' flatness tolerance decides).
#[test]
fn segments_match_the_union_of_spheres() {
    let mut rng = Pcg32::new(3, 5);
    let (mut hits, mut misses, mut compared) = (0, 0, 0);
    for case in 0..1500 {
        let control = random_segment(&mut rng);
        let b = widen(&control);
        let r_min = b.iter().fold(f64::INFINITY, |m, q| m.min(q.w));
        let target =
            bezier(&b, rng.next_f32() as f64).0.truncate().as_vec3() + random_vec(&mut rng, 0.4);
        let dir = random_vec(&mut rng, 1.0).normalize_or(Vec3::X);
        let origin = target - dir * 4.0;
        let ray = Ray::new(origin, dir * (0.5 + rng.next_f32() * 2.0));
        let (expected, margin) = brute_force(&ray, &b);
        if margin.abs() < 0.04 * r_min {
            continue;
        }
        compared += 1;
        let got = RayQuery::new(&ray)
            .unwrap()
            .hit(&control, subdivision_depth(&b), f64::INFINITY);
        match (expected, got) {
            (None, None) => misses += 1,
            (Some((t, u)), Some(h)) => {
                hits += 1;
                assert!(
                    (h.t - t).abs() <= 1e-7 * t.max(1.0),
                    "case {case}: t {} against {t}",
                    h.t
                );
                // The same sphere, unless the entry is flat in u (a tangent hit).
                let moved = (h.v - u).abs();
                assert!(moved < 1e-3, "case {case}: u {} against {u}", h.v);
            }
            (e, g) => panic!("case {case}: brute force {e:?}, segment {g:?} (margin {margin})"),
        }
    }
    assert!(
        compared > 1300 && hits > 300 && misses > 300,
        "{compared} {hits} {misses}"
    );
}

/// The curve's surface at its hits: the point lies on the sphere at its `u`, the normal
/// points from that sphere's centre to it (against the ray), and away from the ends
/// the point is on the envelope: `(x − c)·c′ + r·r′ = 0`.
#[test]
fn interactions_lie_on_the_swept_surface() {
    let mut rng = Pcg32::new(9, 1);
    let mut checked = 0;
    for _ in 0..400 {
        let control = random_segment(&mut rng);
        let curves = CubicCurves {
            accel: Accel::build(AccelKind::default(), &[segment_bounds(&control)]),
            depth: vec![subdivision_depth(&widen(&control))],
            links: vec![0],
            control: vec![control],
            curves: 1,
            basis: CubicBasis::Bezier,
        };
        let b = widen(&control);
        let target = bezier(&b, rng.next_f32() as f64).0.truncate().as_vec3();
        let dir = random_vec(&mut rng, 1.0).normalize_or(Vec3::X);
        let ray = Ray::new(target - dir * 3.0, dir);
        let Some(hit) = curves.intersect(&ray, &mut RayStats::default()) else {
            continue;
        };
        let si = curves.interaction(&ray, &hit);
        let u = hit.uv.x as f64;
        let (c, d1, _) = bezier(&b, u);
        let x = si.p.as_dvec3() - c.truncate();
        assert!(
            (x.length() - c.w).abs() < 1e-5,
            "{} against {}",
            x.length(),
            c.w
        );
        assert!(si.n.dot(ray.direction) < 0.0);
        assert!((si.n.as_dvec3() - x / x.length()).length() < 1e-5);
        if u > 1e-6 && u < 1.0 - 1e-6 {
            let g = x.dot(d1.truncate()) + c.w * d1.w;
            let (bf, _) = brute_force(&ray, &b);
            assert!(
                g.abs() < 1e-4 * d1.length(),
                "envelope condition {g}: u {u} t {} brute {bf:?} ctrl {control:?}",
                hit.t
            );
        }
        checked += 1;
    }
    assert!(checked > 100, "{checked}");
}

/// A B-spline of evenly spaced collinear points and one radius is a capsule (a straight
/// round segment with equal end spheres): the same hits as the linear curve's exact test.
#[test]
fn a_straight_bspline_is_a_capsule() {
    let (a, b) = (Vec3::new(-1.0, 0.2, 0.1), Vec3::new(1.5, -0.3, 0.4));
    let r = 0.3;
    // Points a − Δ, a, …: the B-spline runs from a to b exactly.
    let delta = (b - a) / 3.0;
    let points: Vec<(Vec3, f32)> = (0..6).map(|i| (a + delta * (i as f32 - 1.0), r)).collect();
    let curves = CubicCurves::new(&[points], CubicBasis::BSpline, AccelKind::default()).unwrap();
    assert_eq!(curves.segment_count(), 3);
    let mut rng = Pcg32::new(4, 4);
    let mut hits = 0;
    for _ in 0..2000 {
        let target = a + (b - a) * rng.next_f32() + random_vec(&mut rng, 0.5);
        let dir = random_vec(&mut rng, 1.0).normalize_or(Vec3::Y);
        let ray = Ray::new(target - dir * 3.0, dir);
        let exact = segment_hit(
            &ray,
            f32::INFINITY,
            a.as_dvec3(),
            r as f64,
            b.as_dvec3(),
            r as f64,
        );
        let got = curves.intersect(&ray, &mut RayStats::default());
        match (exact, got) {
            (None, None) => {}
            (Some(e), Some(g)) => {
                hits += 1;
                assert!((e.t - g.t as f64).abs() < 1e-5, "{} against {}", g.t, e.t);
            }
            (e, g) => {
                // Only grazing rays may disagree: the ray's clearance of the axis.
                let o = ray.origin.as_dvec3() - a.as_dvec3();
                let axis = (b - a).as_dvec3().normalize();
                let d = ray.direction.as_dvec3();
                let n = d.cross(axis);
                let clearance = if n.length() > 1e-9 {
                    o.dot(n).abs() / n.length()
                } else {
                    0.0
                };
                assert!(
                    (clearance - r as f64).abs() < 1e-3,
                    "exact {e:?}, cubic {g:?}"
                );
            }
        }
    }
    assert!(hits > 500, "{hits}");
}

/// Rays that start inside a curve pass through it, and rays leaving a hit point
/// outwards do not hit the same spot again (a straight capsule, which is convex).
#[test]
fn rays_from_inside_pass_and_leaving_rays_do_not_return() {
    let points: Vec<(Vec3, f32)> = (0..7)
        .map(|i| (Vec3::new(i as f32 * 0.5, 0.0, 0.0), 0.2))
        .collect();
    let curves = CubicCurves::new(&[points], CubicBasis::BSpline, AccelKind::default()).unwrap();
    let mut rng = Pcg32::new(8, 2);
    let mut leaving = 0;
    for _ in 0..500 {
        let inside = Vec3::new(0.6 + rng.next_f32() * 1.8, 0.0, 0.0) + random_vec(&mut rng, 0.1);
        let dir = random_vec(&mut rng, 1.0).normalize_or(Vec3::Z);
        assert!(curves
            .intersect(&Ray::new(inside, dir), &mut RayStats::default())
            .is_none());
        assert!(!curves.occluded(&Ray::new(inside, dir), &mut RayStats::default()));
        // From outside: hit, then continue inwards (through) and bounce outwards.
        let ray = Ray::new(inside - dir * 2.0, dir);
        let Some(hit) = curves.intersect(&ray, &mut RayStats::default()) else {
            continue;
        };
        let si = curves.interaction(&ray, &hit);
        let through = Ray::new(offset_ray_origin(si.p, si.p_error, si.n, dir), dir);
        assert!(curves
            .intersect(&through, &mut RayStats::default())
            .is_none());
        let out = dir - 2.0 * dir.dot(si.n) * si.n;
        let bounce = Ray::new(offset_ray_origin(si.p, si.p_error, si.n, out), out);
        assert!(curves
            .intersect(&bounce, &mut RayStats::default())
            .is_none());
        leaving += 1;
    }
    assert!(leaving > 100, "{leaving}");
}

/// Each basis's Bézier form traces the curve its own definition gives.
#[test]
fn bases_convert_to_their_bezier_forms() {
    let mut rng = Pcg32::new(1, 1);
    let p = [0, 1, 2, 3].map(|_| {
        random_vec(&mut rng, 1.0)
            .as_dvec3()
            .extend(rng.next_f32() as f64)
    });
    for (basis, weights) in [
        (
            CubicBasis::BSpline,
            (|u: f64| {
                let s = 1.0 - u;
                [
                    s * s * s / 6.0,
                    (3.0 * u * u * u - 6.0 * u * u + 4.0) / 6.0,
                    (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) / 6.0,
                    u * u * u / 6.0,
                ]
            }) as fn(f64) -> [f64; 4],
        ),
        (CubicBasis::CatmullRom, |u: f64| {
            [
                0.5 * (-u * u * u + 2.0 * u * u - u),
                0.5 * (3.0 * u * u * u - 5.0 * u * u + 2.0),
                0.5 * (-3.0 * u * u * u + 4.0 * u * u + u),
                0.5 * (u * u * u - u * u),
            ]
        }),
    ] {
        let b = basis.to_bezier(p);
        for k in 0..=10 {
            let u = k as f64 / 10.0;
            let w = weights(u);
            let expected = p[0] * w[0] + p[1] * w[1] + p[2] * w[2] + p[3] * w[3];
            let got = bezier(&b, u).0;
            // (Clamped radii aside: the random ones here stay positive.)
            if b.iter().all(|q| q.w > 0.0) || basis == CubicBasis::BSpline {
                assert!(
                    (got - expected).length() < 1e-12,
                    "{basis:?} at {u}: {got} vs {expected}"
                );
            }
        }
    }
    assert_eq!(
        CubicBasis::Bezier.segment_starts(10).collect::<Vec<_>>(),
        [0, 3, 6]
    );
    assert_eq!(
        CubicBasis::BSpline.segment_starts(6).collect::<Vec<_>>(),
        [0, 1, 2]
    );
}

/// Rendered as the image the finest linear curves give: a B-spline strand against its
/// polyline of 64 points per segment (which lies within 1e-4 of its radius), by rays on
/// a grid over the strand, nearly every one answered alike.
#[test]
fn a_bspline_strand_agrees_with_a_fine_polyline() {
    let control: Vec<(Vec3, f32)> = vec![
        (Vec3::new(-1.5, -0.5, 0.0), 0.05),
        (Vec3::new(-1.0, 0.8, 0.3), 0.12),
        (Vec3::new(0.0, -0.6, -0.2), 0.2),
        (Vec3::new(0.7, 0.9, 0.1), 0.08),
        (Vec3::new(1.5, 0.0, 0.4), 0.15),
        (Vec3::new(1.8, -0.9, 0.0), 0.1),
    ];
    let cubic = CubicCurves::new(
        std::slice::from_ref(&control),
        CubicBasis::BSpline,
        AccelKind::default(),
    )
    .unwrap();
    let mut polyline = Vec::new();
    for s in 0..cubic.segment_count() {
        let b = widen(&cubic.control[s]);
        for k in 0..64 {
            let c = bezier(&b, k as f64 / 64.0).0;
            polyline.push((c.truncate().as_vec3(), c.w as f32));
        }
    }
    let last = widen(&cubic.control[cubic.segment_count() - 1]);
    polyline.push((last[3].truncate().as_vec3(), last[3].w as f32));
    let linear = LinearCurves::new(&[polyline], AccelKind::default()).unwrap();
    let (mut both, mut differ, mut total) = (0, 0, 0);
    for i in 0..120 {
        for j in 0..80 {
            let o = Vec3::new(
                -2.2 + 4.4 * i as f32 / 120.0,
                -1.4 + 2.8 * j as f32 / 80.0,
                5.0,
            );
            let ray = Ray::new(o, Vec3::new(0.05, 0.02, -1.0));
            let a = cubic.intersect(&ray, &mut RayStats::default());
            let b = linear.intersect(&ray, &mut RayStats::default());
            total += 1;
            match (a, b) {
                (Some(a), Some(b)) => {
                    both += 1;
                    assert!((a.t - b.t).abs() < 2e-3, "{} against {}", a.t, b.t);
                    let na = cubic.interaction(&ray, &a).n;
                    let nb = linear.interaction(&ray, &b).n;
                    assert!(na.dot(nb) > 0.99, "normals {na} and {nb}");
                }
                (None, None) => {}
                _ => differ += 1,
            }
        }
    }
    assert!(both > 500, "{both} of {total}");
    assert!(differ * 100 < both, "{differ} of {both} rays disagree");
}

/// Many curves of each basis through every accelerator: the closest hit equals the
/// brute-force list's, shadow queries agree, and rays spawned off a hit away from the
/// surface do not hit it again nearby.
#[test]
fn accelerators_agree_and_spawned_rays_leave() {
    let mut rng = Pcg32::new(6, 7);
    let mut curves = Vec::new();
    for _ in 0..30 {
        let mut p = random_vec(&mut rng, 2.0);
        let mut curve = Vec::new();
        for _ in 0..7 {
            curve.push((p, 0.03 + 0.08 * rng.next_f32()));
            p += random_vec(&mut rng, 0.4);
        }
        curves.push(curve);
    }
    let kinds = [
        AccelKind::Bvh2,
        AccelKind::Bvh4,
        AccelKind::Bvh8,
        AccelKind::Grid,
        AccelKind::KdTree,
        AccelKind::Octree,
        AccelKind::Bsp,
    ];
    let stats = &mut RayStats::default();
    let mut hits = 0;
    for basis in [
        CubicBasis::BSpline,
        CubicBasis::Bezier,
        CubicBasis::CatmullRom,
    ] {
        let list = CubicCurves::new(&curves, basis, AccelKind::List).unwrap();
        let segments = if basis == CubicBasis::Bezier { 2 } else { 4 };
        assert_eq!(
            (list.curve_count(), list.segment_count()),
            (30, 30 * segments)
        );
        let built: Vec<CubicCurves> = kinds
            .iter()
            .map(|&k| CubicCurves::new(&curves, basis, k).unwrap())
            .collect();
        for _ in 0..700 {
            let origin = random_vec(&mut rng, 4.0);
            let curve = &curves[rng.next_u32() as usize % 30];
            let (p, r) = curve[rng.next_u32() as usize % 7];
            let ray = Ray::new(origin, p + random_vec(&mut rng, 2.0 * r) - origin);
            let expected = list.intersect(&ray, stats);
            for (k, c) in kinds.iter().zip(&built) {
                let got = c.intersect(&ray, stats);
                assert_eq!(got.map(|h| h.t), expected.map(|h| h.t), "{basis:?} {k:?}");
                assert_eq!(
                    c.occluded(&ray, stats),
                    expected.is_some(),
                    "{basis:?} {k:?}"
                );
            }
            let Some(h) = expected else { continue };
            hits += 1;
            let si = list.interaction(&ray, &h);
            for _ in 0..4 {
                let mut w = random_vec(&mut rng, 1.0);
                if w.dot(si.n) < 0.0 {
                    w = -w;
                }
                if w.dot(si.n) < 1e-2 {
                    continue;
                }
                let o = offset_ray_origin(si.p, si.p_error, si.n, w);
                if let Some(g) = list.intersect(&Ray::new(o, w), stats) {
                    assert!(
                        g.prim != h.prim || g.t > 1e-3,
                        "{basis:?}: the ray spawned off segment {} hit it again at t = {}",
                        h.prim,
                        g.t
                    );
                }
            }
        }
    }
    assert!(hits > 500, "only {hits} hits");
}

#[test]
fn bad_curves_are_refused() {
    let ok = |n: usize| -> Vec<(Vec3, f32)> { (0..n).map(|i| (Vec3::X * i as f32, 0.1)).collect() };
    for (curves, basis, expected) in [
        (
            vec![ok(3)],
            CubicBasis::BSpline,
            "curve 1: a B-spline curve needs at least four",
        ),
        (
            vec![ok(4), ok(5)],
            CubicBasis::Bezier,
            "curve 2: a Bézier curve needs 3k + 1",
        ),
        (vec![ok(2)], CubicBasis::CatmullRom, "needs at least four"),
        (
            vec![vec![
                (Vec3::ZERO, 0.1),
                (Vec3::X, -0.1),
                (Vec3::Y, 0.1),
                (Vec3::Z, 0.1),
            ]],
            CubicBasis::BSpline,
            "control point 2",
        ),
        (
            vec![vec![
                (Vec3::ZERO, 0.1),
                (Vec3::X, 0.1),
                (Vec3::NAN, 0.1),
                (Vec3::Z, 0.1),
            ]],
            CubicBasis::BSpline,
            "control point 3",
        ),
        (vec![], CubicBasis::BSpline, "no curves"),
    ] {
        let e = CubicCurves::new(&curves, basis, AccelKind::default()).unwrap_err();
        assert!(e.contains(expected), "{e}");
    }
}
