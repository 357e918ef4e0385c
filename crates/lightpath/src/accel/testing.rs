//! Test helpers shared by the accelerators' tests: triangle soups that stress the
//! structures (random, flat, degenerate, lattice meshes whose edges lie on cell
//! boundaries), rays that start outside, inside and on the geometry, along the axes and
//! in the mesh's plane, and a check of closest and any hits against the brute-force list
//! with the watertight ray/triangle test, so closest-hit ordering is really exercised.

use super::{Accel, ListAccel, RayStats};
use crate::geometry::{intersect_triangle_watertight, WatertightRay};
use crate::math::{Bounds3, Ray};
use crate::sampling::Pcg32;
use glam::Vec3;

pub(crate) type Triangle = [Vec3; 3];

pub(crate) fn boxes(tris: &[Triangle]) -> Vec<Bounds3> {
    tris.iter()
        .map(|t| {
            let mut b = Bounds3::from_point(t[0]);
            b.expand(t[1]);
            b.expand(t[2]);
            b
        })
        .collect()
}

fn point(rng: &mut Pcg32, scale: f32) -> Vec3 {
    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale
}

/// Random small triangles in [0, 10]³, a few of them large.
pub(crate) fn random_soup(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Pcg32::new(seed, 11);
    (0..n)
        .map(|i| {
            let c = point(&mut rng, 10.0);
            let size = if i % 97 == 0 { 6.0 } else { 0.8 };
            let mut v = || c + (point(&mut rng, 1.0) - Vec3::splat(0.5)) * size;
            [v(), v(), v()]
        })
        .collect()
}

/// Every triangle in the plane z = 5 (flat boxes, a flat overall box).
pub(crate) fn flat_soup(n: usize, seed: u64) -> Vec<Triangle> {
    random_soup(n, seed)
        .into_iter()
        .map(|t| t.map(|p| Vec3::new(p.x, p.y, 5.0)))
        .collect()
}

/// Degenerate triangles mixed with normal ones: points (empty-volume boxes), segments
/// (zero area), axis-aligned triangles (flat boxes), exact duplicates, and one triangle
/// spanning the whole scene.
pub(crate) fn degenerate_soup(n: usize, seed: u64) -> Vec<Triangle> {
    let mut tris = random_soup(n, seed);
    for (i, t) in tris.iter_mut().enumerate() {
        match i % 6 {
            0 => *t = [t[0]; 3],
            1 => *t = [t[0], t[1], (t[0] + t[1]) * 0.5],
            2 => {
                let x = t[0].x;
                for p in t.iter_mut() {
                    p.x = x;
                }
            }
            3 if i > 3 => *t = [t[0], t[1], Vec3::new(t[1].x, t[1].y, t[0].z)],
            _ => {}
        }
    }
    let dup = tris[n / 2];
    tris.push(dup);
    tris.push([
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(11.0, 0.0, 10.0),
        Vec3::new(0.0, 11.0, 5.0),
    ]);
    tris
}

/// A height field on the integer lattice [0, k]² (two triangles per square), every
/// vertex at an integer position, so edges fall on the cell boundaries of a grid over
/// it; with `flat` all heights are 0.
pub(crate) fn lattice_mesh(k: usize, flat: bool) -> Vec<Triangle> {
    let h = |x: usize, y: usize| {
        if flat {
            0.0
        } else {
            ((x * 7 + y * 3) % 5) as f32
        }
    };
    let p = |x: usize, y: usize| Vec3::new(x as f32, y as f32, h(x, y));
    let mut tris = Vec::new();
    for y in 0..k {
        for x in 0..k {
            tris.push([p(x, y), p(x + 1, y), p(x + 1, y + 1)]);
            tris.push([p(x, y), p(x + 1, y + 1), p(x, y + 1)]);
        }
    }
    tris
}

/// Rays for a scene inside `bounds`: from outside and inside, towards triangle vertices,
/// edge midpoints and centroids, parallel to the axes, in the plane of a flat scene,
/// with limited ranges and `t_min > 0`.
pub(crate) fn rays_for(tris: &[Triangle], n: usize, seed: u64) -> Vec<Ray> {
    let bounds = boxes(tris).iter().fold(Bounds3::EMPTY, |a, b| a.union(b));
    let (lo, d) = (bounds.min, bounds.diagonal());
    let mut rng = Pcg32::new(seed, 5);
    let mut rays = Vec::with_capacity(n);
    let axes = [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    for i in 0..n {
        // Origins spread over the box grown by 20% on every side.
        let o = lo - d * 0.2 + point(&mut rng, 1.0) * d * 1.4;
        let t = tris[rng.next_u32() as usize % tris.len()];
        let target = match i % 4 {
            0 => t[rng.next_u32() as usize % 3],
            1 => (t[0] + t[1]) * 0.5,
            _ => (t[0] + t[1] + t[2]) / 3.0,
        };
        let mut ray = match i % 8 {
            // Along an axis through the target (hits edges and vertices of lattices).
            0 | 1 => {
                let a = axes[rng.next_u32() as usize % 6];
                Ray::new(target - a * (d.max_element() + 1.0), a)
            }
            // Along an axis from anywhere (origin inside the scene half the time).
            2 => Ray::new(o, axes[i / 8 % 6]),
            // In the plane z = target.z (the plane of a flat scene).
            3 => {
                let dir = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.0);
                Ray::new(Vec3::new(o.x, o.y, target.z), dir)
            }
            // Random direction.
            4 => Ray::new(
                o,
                Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                ),
            ),
            // Aimed at the target from anywhere (unnormalised direction).
            _ => Ray::new(o, target - o),
        };
        if i % 11 == 0 {
            ray.t_min = 0.3 * rng.next_f32();
            ray.t_max = ray.t_min + 2.0 * rng.next_f32();
        }
        if ray.direction != Vec3::ZERO {
            rays.push(ray);
        }
    }
    rays
}

/// The closest hit `(t, prim)` through `accel`, the primitives the closure was handed,
/// and the traversal counters.
pub(crate) fn closest(
    accel: &Accel,
    tris: &[Triangle],
    ray: &Ray,
) -> (Option<(f32, u32)>, Vec<u32>, RayStats) {
    let wr = WatertightRay::new(ray);
    let mut best = None;
    let mut tested = Vec::new();
    let mut stats = RayStats::default();
    accel.intersect(ray, &mut stats, |prim, t_max| {
        tested.push(prim);
        let [a, b, c] = tris[prim as usize];
        match intersect_triangle_watertight(&wr, ray.t_min, *t_max, a, b, c) {
            Some((t, ..)) => {
                *t_max = t;
                best = Some((t, prim));
                true
            }
            None => false,
        }
    });
    assert_eq!(stats.prims_tested as usize, tested.len());
    (best, tested, stats)
}

pub(crate) fn occluded(accel: &Accel, tris: &[Triangle], ray: &Ray) -> bool {
    let wr = WatertightRay::new(ray);
    accel.occluded(ray, &mut RayStats::default(), |prim| {
        let [a, b, c] = tris[prim as usize];
        intersect_triangle_watertight(&wr, ray.t_min, ray.t_max, a, b, c).is_some()
    })
}

/// Checks `accel` against the brute-force list on `rays`: the same closest distance
/// (the primitive may differ only between triangles hit at exactly that distance), and
/// the same occlusion answer. Returns the number of rays that hit.
pub(crate) fn check_against_list(
    accel: &Accel,
    tris: &[Triangle],
    rays: &[Ray],
    what: &str,
) -> usize {
    let list = Accel::List(ListAccel::new(&boxes(tris)));
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let (want, ..) = closest(&list, tris, ray);
        let (got, ..) = closest(accel, tris, ray);
        match (want, got) {
            (Some((tw, pw)), Some((tg, pg))) => {
                if tw != tg {
                    // Coplanar overlapping triangles: their distances may differ in the
                    // last bit, and which of them wins depends on the order they are
                    // tested in (the watertight test rejects against the current t_max
                    // in scaled arithmetic). Both answers are then right: each primitive,
                    // tested on its own, must give the distance reported for it, and the
                    // two distances must agree to within 2 ulps.
                    let wr = WatertightRay::new(ray);
                    let alone = |p: u32| {
                        let [a, b, c] = tris[p as usize];
                        intersect_triangle_watertight(&wr, ray.t_min, ray.t_max, a, b, c)
                            .map(|h| h.0)
                    };
                    let ulps = (tw.to_bits() as i64 - tg.to_bits() as i64).abs();
                    assert!(
                        ulps <= 2 && alone(pw) == Some(tw) && alone(pg) == Some(tg),
                        "{what}: ray {i} {ray:?}: t {tw} (list prim {pw}) vs {tg} (prim {pg})"
                    );
                }
                if pw != pg && tw == tg {
                    let [a, b, c] = tris[pg as usize];
                    let wr = WatertightRay::new(ray);
                    let t = intersect_triangle_watertight(&wr, ray.t_min, ray.t_max, a, b, c);
                    assert_eq!(
                        t.map(|h| h.0),
                        Some(tw),
                        "{what}: ray {i}: prim {pg} vs {pw}"
                    );
                }
                hits += 1;
            }
            (None, None) => {}
            _ => panic!("{what}: ray {i} {ray:?}: list {want:?}, accelerator {got:?}"),
        }
        assert_eq!(
            occluded(accel, tris, ray),
            occluded(&list, tris, ray),
            "{what}: ray {i} {ray:?}: occlusion"
        );
    }
    hits
}

/// Runs [`check_against_list`] for an accelerator kind on every test scene, requiring
/// that a good share of the rays hit (so the check is not vacuous).
pub(crate) fn check_kind_on_all_scenes(kind: super::AccelKind) {
    let scenes: Vec<(&str, Vec<Triangle>)> = vec![
        ("one triangle", random_soup(1, 1)),
        ("three triangles", random_soup(3, 2)),
        ("random 200", random_soup(200, 3)),
        ("random 3000", random_soup(3000, 4)),
        ("flat 500", flat_soup(500, 5)),
        ("degenerate 600", degenerate_soup(600, 6)),
        ("lattice 12", lattice_mesh(12, false)),
        ("flat lattice 12", lattice_mesh(12, true)),
        ("all points", vec![[Vec3::splat(1.0); 3]; 20]),
    ];
    for (name, tris) in &scenes {
        let accel = Accel::build(kind, &boxes(tris));
        let rays = rays_for(tris, 3000, 42);
        let hits = check_against_list(&accel, tris, &rays, &format!("{kind:?} on {name}"));
        if *name != "all points" {
            assert!(
                hits > rays.len() / 20,
                "{kind:?} on {name}: only {hits} hits"
            );
        }
        assert!(accel.memory_bytes() > 0);
        let b = accel.bounds();
        let all = boxes(tris).iter().fold(Bounds3::EMPTY, |a, b| a.union(b));
        assert!(
            b.contains(all.min) && b.contains(all.max),
            "{kind:?} on {name}: bounds"
        );
        // Every primitive box lies inside one of the cover's boxes.
        for max_boxes in [1, 8, 64] {
            let cover = accel.cover(max_boxes);
            assert!(!cover.is_empty() && cover.len() <= max_boxes);
            for (i, b) in boxes(tris).iter().enumerate() {
                assert!(
                    cover.iter().any(|c| c.contains(b.min) && c.contains(b.max)),
                    "{kind:?} on {name}: primitive {i} outside the cover of {max_boxes}"
                );
            }
        }
    }
    // No primitives at all.
    let empty = Accel::build(kind, &[]);
    assert!(!empty.intersect(
        &Ray::new(Vec3::ZERO, Vec3::X),
        &mut RayStats::default(),
        |_, _| true
    ));
    assert!(!empty.occluded(
        &Ray::new(Vec3::ZERO, Vec3::X),
        &mut RayStats::default(),
        |_| true
    ));
}
