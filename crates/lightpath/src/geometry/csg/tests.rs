//! CSG against an independent reference: a float64 point classifier and analytic
//! surface crossings (no interval code shared with the implementation).

use super::*;
use crate::accel::AccelKind;
use crate::geometry::MeshData;
use crate::sampling::{warp, Pcg32};
use glam::{DMat4, DVec3};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use std::cell::Cell;

// ---------------------------------------------------------------------------------------
// Test solids

/// The regular octahedron |x| + |y| + |z| <= 1 as an outward-wound mesh.
fn octahedron_data() -> MeshData {
    MeshData {
        positions: vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z],
        normals: vec![],
        uvs: vec![],
        indices: vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ],
        colors: Vec::new(),
        face_colors: Vec::new(),
    }
}

fn mesh(data: MeshData) -> Arc<TriangleMesh> {
    Arc::new(TriangleMesh::new(data, false, AccelKind::Bvh2).unwrap())
}

/// The union of unit voxels `[v, v + 1]` as a closed, outward-wound mesh of their
/// boundary faces (each face with its own four vertices).
fn voxel_data(voxels: &[[i32; 3]]) -> MeshData {
    let mut d = MeshData::default();
    for v in voxels {
        for axis in 0..3 {
            for positive in [false, true] {
                let mut n = [0i32; 3];
                n[axis] = if positive { 1 } else { -1 };
                let neighbour = [v[0] + n[0], v[1] + n[1], v[2] + n[2]];
                if voxels.contains(&neighbour) {
                    continue;
                }
                let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut base = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
                base[axis] += positive as i32 as f32;
                let corner = |i: f32, j: f32| {
                    let mut p = base;
                    p[u] += i;
                    p[w] += j;
                    p
                };
                let b = d.positions.len() as u32;
                d.positions.extend([
                    corner(0.0, 0.0),
                    corner(1.0, 0.0),
                    corner(1.0, 1.0),
                    corner(0.0, 1.0),
                ]);
                // e_u × e_w = e_axis: counter-clockwise seen from +axis.
                if positive {
                    d.indices.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
                } else {
                    d.indices.extend([[b, b + 2, b + 1], [b, b + 3, b + 2]]);
                }
            }
        }
    }
    d
}

fn leaf(solid: Solid, t: Transform) -> CsgNode {
    CsgNode::leaf(solid).transformed(&t)
}

fn scale(s: f32) -> Transform {
    Transform::scale(Vec3::splat(s)).unwrap()
}

fn translate(x: f32, y: f32, z: f32) -> Transform {
    Transform::translate(Vec3::new(x, y, z))
}

fn hit_t(csg: &Csg, ray: &Ray) -> Option<f32> {
    csg.intersect(ray, &mut RayStats::default()).map(|h| h.t)
}

fn normal_at(csg: &Csg, ray: &Ray) -> Vec3 {
    let h = csg.intersect(ray, &mut RayStats::default()).unwrap();
    csg.interaction(ray, &h).n
}

// ---------------------------------------------------------------------------------------
// Hand-checked cases

/// Unit sphere minus the cube [0, 2]³ (a corner bitten out of the +x+y+z octant).
fn sphere_minus_corner() -> Csg {
    Csg::new(CsgNode::op(
        CsgOp::Difference,
        CsgNode::leaf(Solid::Sphere),
        leaf(Solid::Cube, translate(1.0, 1.0, 1.0)),
    ))
    .unwrap()
}

#[test]
fn difference_cut_faces_point_into_the_hole() {
    let csg = sphere_minus_corner();
    // Down the -z axis at x = y = 0.5 from above: the sphere's top is removed, the ray
    // meets the cut face z = 0 (the cube's bottom face, normal -z, flipped to +z).
    let ray = Ray::new(Vec3::new(0.5, 0.5, 5.0), -Vec3::Z);
    assert!((hit_t(&csg, &ray).unwrap() - 5.0).abs() < 1e-5);
    assert!((normal_at(&csg, &ray) - Vec3::Z).length() < 1e-6);
    // At x = y = -0.5 the sphere is whole: the hit is on the sphere.
    let ray = Ray::new(Vec3::new(-0.5, -0.5, 5.0), -Vec3::Z);
    let expected = 5.0 - 0.5f32.sqrt();
    assert!((hit_t(&csg, &ray).unwrap() - expected).abs() < 1e-5);
    // Along +x at y = z = 0.5 from far left: enters the sphere, then leaves the solid
    // through the cut face x = 0. The cube's face there has the outward normal -x;
    // flipped, it points into the hole (x > 0), along the ray.
    let ray = Ray::new(Vec3::new(-5.0, 0.5, 0.5), Vec3::X);
    let h = csg.intersect(&ray, &mut RayStats::default()).unwrap();
    assert!((h.t - (5.0 - 0.5f32.sqrt())).abs() < 1e-5, "{}", h.t);
    let next = Ray::with_range(ray.origin, ray.direction, h.t, f32::INFINITY);
    let h2 = csg.intersect(&next, &mut RayStats::default()).unwrap();
    assert!((h2.t - 5.0).abs() < 1e-5, "{}", h2.t);
    let si = csg.interaction(&next, &h2);
    assert!((si.n - Vec3::X).length() < 1e-6, "{:?}", si.n);
    assert!(Csg::is_flipped(h2.prim));
    assert_eq!(csg.leaf_index(h2.prim), 1);
    // Nothing after the cut face: the rest of the ray is in the hole, then outside.
    let after = Ray::with_range(ray.origin, ray.direction, h2.t, f32::INFINITY);
    assert!(hit_t(&csg, &after).is_none());
}

#[test]
fn rays_starting_inside_leave_through_the_right_surface() {
    let csg = sphere_minus_corner();
    // From the centre region (inside the solid at (-0.2, 0, 0)) towards +x: the cut face.
    let ray = Ray::new(Vec3::new(-0.2, 0.3, 0.3), Vec3::X);
    assert!((hit_t(&csg, &ray).unwrap() - 0.2).abs() < 1e-6);
    assert!((normal_at(&csg, &ray) - Vec3::X).length() < 1e-6);
    // From inside the hole (in the sphere, but cut away) towards -x: enters the solid
    // through the cut face, normal facing the ray.
    let ray = Ray::new(Vec3::new(0.3, 0.3, 0.3), -Vec3::X);
    assert!((hit_t(&csg, &ray).unwrap() - 0.3).abs() < 1e-6);
    assert!((normal_at(&csg, &ray) - Vec3::X).length() < 1e-6);
    // t_min inside the solid skips everything before it.
    let ray = Ray::with_range(Vec3::new(-5.0, -0.3, -0.3), Vec3::X, 5.0, 100.0);
    let expected = 5.0 + (1.0f32 - 0.18).sqrt();
    assert!((hit_t(&csg, &ray).unwrap() - expected).abs() < 1e-5);
    // t_max before the first surface.
    let ray = Ray::with_range(Vec3::new(-5.0, -0.3, -0.3), Vec3::X, 0.0, 3.0);
    assert!(hit_t(&csg, &ray).is_none());
}

#[test]
fn touching_solids_have_no_inner_faces_and_nested_trees_work() {
    // Two unit cubes side by side, [-1, 1] and [1, 3] in x: one box [-1, 3].
    let pair = CsgNode::op(
        CsgOp::Union,
        CsgNode::leaf(Solid::Cube),
        leaf(Solid::Cube, translate(2.0, 0.0, 0.0)),
    );
    let csg = Csg::new(pair.clone()).unwrap();
    let ray = Ray::new(Vec3::new(-5.0, 0.2, 0.1), Vec3::X);
    let h = csg.intersect(&ray, &mut RayStats::default()).unwrap();
    assert!((h.t - 4.0).abs() < 1e-6);
    let next = Ray::with_range(ray.origin, ray.direction, h.t, f32::INFINITY);
    assert!((hit_t(&csg, &next).unwrap() - 8.0).abs() < 1e-6);
    // Intersection of that pair with a sphere of radius 1.5 at x = 1, scaled down by 2
    // and moved: a depth-2 tree under transforms at every level.
    let tree = CsgNode::op(
        CsgOp::Intersection,
        pair,
        leaf(Solid::Sphere, scale(1.5).then(&translate(1.0, 0.0, 0.0))),
    )
    .transformed(&scale(0.5).then(&translate(0.0, 0.0, 3.0)));
    let csg = Csg::new(tree).unwrap();
    // Along z through x = 0.5 (tree space x = 1): enters the sphere at tree z = -1,
    // object z = 3 - 0.5 = 2.5 ... limited by the cube faces z = ±1 → object 2.5 and 3.5.
    let ray = Ray::new(Vec3::new(0.5, 0.0, -5.0), Vec3::Z);
    assert!((hit_t(&csg, &ray).unwrap() - 7.5).abs() < 1e-5);
    assert!((normal_at(&csg, &ray) + Vec3::Z).length() < 1e-5);
}

#[test]
fn bounds_follow_the_operator() {
    let a = || leaf(Solid::Sphere, translate(-1.0, 0.0, 0.0));
    let b = || leaf(Solid::Sphere, translate(1.0, 0.0, 0.0));
    let close = |x: Bounds3, min: Vec3, max: Vec3| {
        (x.min - min).abs().max_element() < 1e-3 && (x.max - max).abs().max_element() < 1e-3
    };
    let u = Csg::new(CsgNode::op(CsgOp::Union, a(), b())).unwrap();
    assert!(close(
        u.bounds(),
        Vec3::new(-2.0, -1.0, -1.0),
        Vec3::new(2.0, 1.0, 1.0)
    ));
    let i = Csg::new(CsgNode::op(CsgOp::Intersection, a(), b())).unwrap();
    assert!(close(
        i.bounds(),
        Vec3::new(0.0, -1.0, -1.0),
        Vec3::new(0.0, 1.0, 1.0)
    ));
    let d = Csg::new(CsgNode::op(CsgOp::Difference, a(), b())).unwrap();
    assert!(close(
        d.bounds(),
        Vec3::new(-2.0, -1.0, -1.0),
        Vec3::new(0.0, 1.0, 1.0)
    ));
    // Disjoint operands of an intersection: empty everywhere.
    let far = leaf(Solid::Sphere, translate(5.0, 0.0, 0.0));
    let e = Csg::new(CsgNode::op(CsgOp::Intersection, a(), far)).unwrap();
    assert!(hit_t(&e, &Ray::new(Vec3::new(-9.0, 0.0, 0.0), Vec3::X)).is_none());
    assert!(!e.bounds().is_empty());
}

#[test]
fn open_or_inside_out_meshes_are_rejected() {
    let mut open = octahedron_data();
    open.indices.pop();
    let e = Csg::new(CsgNode::leaf(Solid::Mesh(mesh(open)))).unwrap_err();
    assert!(e.contains("closed"), "{e}");
    let mut inverted = octahedron_data();
    for t in &mut inverted.indices {
        t.swap(1, 2);
    }
    let e = Csg::new(CsgNode::leaf(Solid::Mesh(mesh(inverted)))).unwrap_err();
    assert!(e.contains("outwards"), "{e}");
    assert!(Csg::new(CsgNode::leaf(Solid::Mesh(mesh(octahedron_data())))).is_ok());
}

/// A non-convex mesh (an L of three voxels) against the union of three cube leaves:
/// the mesh's crossings are paired into several spans per ray, and the union's touching
/// cubes leave no inner faces.
#[test]
fn nonconvex_mesh_matches_the_union_of_its_voxels() {
    let voxels = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]];
    let from_mesh = Csg::new(CsgNode::leaf(Solid::Mesh(mesh(voxel_data(&voxels))))).unwrap();
    let mut cubes: Option<CsgNode> = None;
    for v in voxels {
        let c = leaf(
            Solid::Cube,
            scale(0.5).then(&translate(
                v[0] as f32 + 0.5,
                v[1] as f32 + 0.5,
                v[2] as f32 + 0.5,
            )),
        );
        cubes = Some(match cubes {
            None => c,
            Some(u) => CsgNode::op(CsgOp::Union, u, c),
        });
    }
    let from_cubes = Csg::new(cubes.unwrap()).unwrap();
    let mut rng = Pcg32::new(3, 1);
    let (mut compared, mut multi) = (0, 0);
    let near_edge = |p: Vec3| {
        let f = p.to_array().map(|c| (c - c.round()).abs() < 1e-3);
        f.iter().filter(|&&b| b).count() >= 2
    };
    for _ in 0..20_000 {
        let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 6.0
            + Vec3::splat(1.0);
        // Aimed at the voxels' box, so most rays hit.
        let target = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0;
        let d = (target - o).normalize();
        let mut t = 0.0;
        let mut hits = 0;
        loop {
            let ray = Ray::with_range(o, d, t, f32::INFINITY);
            let (a, b) = (
                from_mesh.intersect(&ray, &mut RayStats::default()),
                from_cubes.intersect(&ray, &mut RayStats::default()),
            );
            match (a, b) {
                (None, None) => break,
                (Some(a), Some(b)) => {
                    let p = ray.at(b.t);
                    if near_edge(p) {
                        break;
                    }
                    assert!((a.t - b.t).abs() < 1e-4, "{o} {d}: {} vs {}", a.t, b.t);
                    let (na, nb) = (
                        from_mesh.interaction(&ray, &a).n,
                        from_cubes.interaction(&ray, &b).n,
                    );
                    assert!((na - nb).length() < 1e-4, "{o} {d}: {na} vs {nb}");
                    assert_eq!(
                        from_mesh.contains(o + d * (a.t + 1e-3)),
                        from_cubes.contains(o + d * (a.t + 1e-3))
                    );
                    compared += 1;
                    hits += 1;
                    t = a.t.max(b.t);
                }
                (a, b) => {
                    let p = ray.at(a.or(b).unwrap().t);
                    assert!(near_edge(p), "{o} {d}: {a:?} vs {b:?}");
                    break;
                }
            }
        }
        if hits > 2 {
            multi += 1;
        }
    }
    assert!(compared > 10_000 && multi > 500, "{compared} {multi}");
}

// ---------------------------------------------------------------------------------------
// Random trees against the float64 reference

#[derive(Debug, Clone, Copy)]
struct Xf {
    scale: [f32; 3],
    mirror: bool,
    axis: [f32; 3],
    angle: f32,
    translate: [f32; 3],
}

impl Xf {
    fn transform(&self) -> Transform {
        let mut s = Vec3::from_array(self.scale);
        if self.mirror {
            s.x = -s.x;
        }
        Transform::scale(s)
            .unwrap()
            .then(&Transform::rotate(Vec3::from_array(self.axis), self.angle).unwrap())
            .then(&Transform::translate(Vec3::from_array(self.translate)))
    }
}

/// A random tree: leaves 0 sphere, 1 cube, 2 cylinder, 3 octahedron mesh; ops 0 union,
/// 1 difference, 2 intersection.
#[derive(Debug, Clone)]
enum Spec {
    Leaf(u8, Xf),
    Op(u8, Xf, Box<Spec>, Box<Spec>),
}

fn xf_strategy() -> impl Strategy<Value = Xf> {
    (
        prop::array::uniform3(0.4f32..1.5),
        prop::bool::weighted(0.2),
        prop::array::uniform3(-1.0f32..1.0)
            .prop_filter("axis", |a| Vec3::from_array(*a).length() > 0.2),
        0.0f32..360.0,
        prop::array::uniform3(-0.7f32..0.7),
    )
        .prop_map(|(scale, mirror, axis, angle, translate)| Xf {
            scale,
            mirror,
            axis,
            angle,
            translate,
        })
}

fn spec_strategy() -> impl Strategy<Value = Spec> {
    let leaf = (0u8..4, xf_strategy()).prop_map(|(k, x)| Spec::Leaf(k, x));
    leaf.prop_recursive(3, 16, 2, |inner| {
        (0u8..3, xf_strategy(), inner.clone(), inner)
            .prop_map(|(op, x, a, b)| Spec::Op(op, x, Box::new(a), Box::new(b)))
    })
}

const OPS: [CsgOp; 3] = [CsgOp::Union, CsgOp::Difference, CsgOp::Intersection];

fn build(spec: &Spec, octahedron: &Arc<TriangleMesh>) -> CsgNode {
    match spec {
        Spec::Leaf(k, x) => {
            let solid = match k {
                0 => Solid::Sphere,
                1 => Solid::Cube,
                2 => Solid::Cylinder,
                _ => Solid::Mesh(octahedron.clone()),
            };
            CsgNode::leaf(solid).transformed(&x.transform())
        }
        Spec::Op(op, x, a, b) => CsgNode::op(
            OPS[*op as usize],
            build(a, octahedron),
            build(b, octahedron),
        )
        .transformed(&x.transform()),
    }
}

/// The reference: leaves with their leaf-from-object matrices in float64.
enum RefTree {
    Leaf(u8, DMat4),
    Op(CsgOp, Box<RefTree>, Box<RefTree>),
}

fn reference(spec: &Spec, object_from_parent: DMat4) -> RefTree {
    match spec {
        Spec::Leaf(k, x) => {
            let m = object_from_parent * x.transform().matrix().as_dmat4();
            RefTree::Leaf(*k, m.inverse())
        }
        Spec::Op(op, x, a, b) => {
            let m = object_from_parent * x.transform().matrix().as_dmat4();
            RefTree::Op(
                OPS[*op as usize],
                Box::new(reference(a, m)),
                Box::new(reference(b, m)),
            )
        }
    }
}

impl RefTree {
    fn contains(&self, p: DVec3) -> bool {
        match self {
            RefTree::Leaf(k, m) => {
                let q = m.transform_point3(p);
                match k {
                    0 => q.length_squared() <= 1.0,
                    1 => q.abs().max_element() <= 1.0,
                    2 => q.x * q.x + q.y * q.y <= 1.0 && (0.0..=1.0).contains(&q.z),
                    _ => q.x.abs() + q.y.abs() + q.z.abs() <= 1.0,
                }
            }
            RefTree::Op(op, a, b) => op.apply(a.contains(p), b.contains(p)),
        }
    }

    /// Whether `q` classifies the same as its neighbours 1e-4 away along each axis:
    /// off every surface by more than float32 rounding of the transforms can move it.
    fn off_surfaces(&self, q: DVec3) -> bool {
        let r = self.contains(q);
        let e = 1e-4;
        [DVec3::X, DVec3::Y, DVec3::Z]
            .iter()
            .all(|&a| self.contains(q + a * e) == r && self.contains(q - a * e) == r)
    }

    /// Every parameter where the ray meets a leaf's surface or its supporting planes
    /// and quadrics (a superset of the surface crossings).
    fn candidates(&self, o: DVec3, d: DVec3, out: &mut Vec<f64>) {
        match self {
            RefTree::Leaf(k, m) => {
                let (o, d) = (m.transform_point3(o), m.transform_vector3(d));
                let mut quadratic = |a: f64, b: f64, c: f64| {
                    let disc = b * b - 4.0 * a * c;
                    if a != 0.0 && disc >= 0.0 {
                        out.push((-b - disc.sqrt()) / (2.0 * a));
                        out.push((-b + disc.sqrt()) / (2.0 * a));
                    }
                };
                match k {
                    0 => quadratic(d.length_squared(), 2.0 * o.dot(d), o.length_squared() - 1.0),
                    1 => {
                        for axis in 0..3 {
                            for s in [-1.0, 1.0] {
                                out.push((s - o[axis]) / d[axis]);
                            }
                        }
                    }
                    2 => {
                        quadratic(
                            d.x * d.x + d.y * d.y,
                            2.0 * (o.x * d.x + o.y * d.y),
                            o.x * o.x + o.y * o.y - 1.0,
                        );
                        out.push(-o.z / d.z);
                        out.push((1.0 - o.z) / d.z);
                    }
                    _ => {
                        for sx in [-1.0, 1.0] {
                            for sy in [-1.0, 1.0] {
                                for sz in [-1.0, 1.0] {
                                    let n = DVec3::new(sx, sy, sz);
                                    out.push((1.0 - n.dot(o)) / n.dot(d));
                                }
                            }
                        }
                    }
                }
            }
            RefTree::Op(_, a, b) => {
                a.candidates(o, d, out);
                b.candidates(o, d, out);
            }
        }
    }

    /// Whether the ray all but touches a sphere or a cylinder side tangentially: its
    /// closest approach to the axis or centre is within `1 ± tol` (squared) of the unit
    /// radius. There the chord it cuts (or just misses) is about `2·sqrt(tol)` long, and
    /// float32 arithmetic on the transformed ray cannot tell such a chord from a miss:
    /// rounding of relative size ε in the ray moves the discriminant by about ε, and
    /// the chord by sqrt(ε), far more than the crossings' own rounding.
    fn grazes(&self, o: DVec3, d: DVec3, tol: f64) -> bool {
        match self {
            RefTree::Leaf(k, m) => {
                let (o, d) = (m.transform_point3(o), m.transform_vector3(d));
                let closest = |o: DVec3, d: DVec3| {
                    let a = d.length_squared();
                    a > 0.0 && ((o - d * (o.dot(d) / a)).length_squared() - 1.0).abs() < tol
                };
                match k {
                    0 => closest(o, d),
                    2 => closest(o.truncate().extend(0.0), d.truncate().extend(0.0)),
                    _ => false,
                }
            }
            RefTree::Op(_, a, b) => a.grazes(o, d, tol) || b.grazes(o, d, tol),
        }
    }

    /// Whether the ray runs within an angle `tol` (its sine) of parallel to a plane that
    /// bounds a leaf: a cube face, a cylinder cap or an octahedron face. Its crossing
    /// `t = (c - n·o) / (n·d)` moves by a relative `ε / sin` when rounding of relative
    /// size ε moves the transformed direction, so at a sine of 1e-4 float32 rounding
    /// alone (ε of a few 1e-7 after nested transforms) can move it by 1e-3 of `t`, the
    /// test's tolerance, while the hit point stays within rounding of the plane.
    fn skims(&self, d: DVec3, tol: f64) -> bool {
        match self {
            RefTree::Leaf(k, m) => {
                let d = m.transform_vector3(d).normalize_or_zero();
                let normals: &[DVec3] = match k {
                    1 => &[DVec3::X, DVec3::Y, DVec3::Z],
                    2 => &[DVec3::Z],
                    3 => &[
                        DVec3::new(1.0, 1.0, 1.0),
                        DVec3::new(1.0, 1.0, -1.0),
                        DVec3::new(1.0, -1.0, 1.0),
                        DVec3::new(-1.0, 1.0, 1.0),
                    ],
                    _ => &[],
                };
                normals.iter().any(|n| n.normalize().dot(d).abs() < tol)
            }
            RefTree::Op(_, a, b) => a.skims(d, tol) || b.skims(d, tol),
        }
    }
}

/// The reference's first boundary in `(t_min, t_max)`, whether the ray enters there,
/// and all the sorted candidates, also those just outside the range that a rounded
/// computation may place inside it (for judging near-degenerate rays).
fn reference_hit(
    tree: &RefTree,
    o: DVec3,
    d: DVec3,
    t_min: f64,
    t_max: f64,
) -> (Option<(f64, bool)>, Vec<f64>) {
    let mut all = Vec::new();
    tree.candidates(o, d, &mut all);
    let mut near: Vec<f64> = all.into_iter().filter(|t| t.is_finite()).collect();
    near.sort_by(f64::total_cmp);
    let ts: Vec<f64> = near
        .iter()
        .copied()
        .filter(|t| *t > t_min && *t < t_max)
        .collect();
    let first_gap_end = ts.first().copied().unwrap_or(t_min + 1.0).min(t_max);
    let mut inside = tree.contains(o + d * (0.5 * (t_min + first_gap_end)));
    for (k, &t) in ts.iter().enumerate() {
        let next = ts.get(k + 1).copied().unwrap_or(t + 1.0).min(t_max);
        let after = tree.contains(o + d * (0.5 * (t + next)));
        if after != inside {
            return (Some((t, after)), near);
        }
        inside = after;
    }
    (None, near)
}

/// Whether a ray is too close to degenerate for the comparison up to `limit`: two
/// candidate crossings (or the range ends) nearly coincide there.
fn ambiguous(ts: &[f64], t_min: f64, t_max: f64, limit: f64) -> bool {
    let mut list: Vec<f64> = vec![t_min];
    let from = t_min - 2e-4 * (1.0 + t_min.abs());
    list.extend(
        ts.iter()
            .copied()
            .filter(|&t| t >= from && t <= limit + 1e-3),
    );
    if t_max.is_finite() {
        list.push(t_max);
    }
    // The crossings may lie on both sides of `t_min`.
    list.sort_by(f64::total_cmp);
    list.windows(2)
        .any(|w| (w[1] - w[0]).abs() < 2e-4 * (1.0 + w[0].abs()))
}

#[test]
fn random_trees_match_the_reference() {
    let octahedron = mesh(octahedron_data());
    let (compared, skipped, hits, inside_starts) = (
        Cell::new(0u32),
        Cell::new(0u32),
        Cell::new(0u32),
        Cell::new(0u32),
    );
    let mut runner = TestRunner::new(Config {
        cases: 3000,
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(
        &(spec_strategy(), any::<u64>()),
        |(spec, seed)| -> Result<(), TestCaseError> {
            let csg = Csg::new(build(&spec, &octahedron)).unwrap();
            let tree = reference(&spec, DMat4::IDENTITY);
            let mut rng = Pcg32::new(seed, 5);
            for _ in 0..64 {
                // Origins anywhere around the tree or in its middle (often inside a
                // solid), aimed at its middle, with directions of any length.
                let spread = if rng.next_f32() < 0.4 { 1.2 } else { 5.0 };
                let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * spread;
                let target =
                    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 1.5;
                let Some(d) = (target - o).try_normalize() else {
                    continue;
                };
                let d = d * (0.5 + 1.5 * rng.next_f32());
                let t_min = if rng.next_f32() < 0.5 {
                    0.0
                } else {
                    2.0 * rng.next_f32()
                };
                let t_max = if rng.next_f32() < 0.7 {
                    f32::INFINITY
                } else {
                    t_min + 0.1 + 5.0 * rng.next_f32()
                };
                let ray = Ray::with_range(o, d, t_min, t_max);
                let (o64, d64) = (o.as_dvec3(), d.as_dvec3());
                let (expected, ts) = reference_hit(&tree, o64, d64, t_min as f64, t_max as f64);
                let got = csg.intersect(&ray, &mut RayStats::default());
                if tree.contains(o64 + d64 * t_min as f64) {
                    inside_starts.set(inside_starts.get() + 1);
                }
                let limit = expected
                    .map(|e| e.0)
                    .unwrap_or(f64::INFINITY)
                    .max(got.map_or(f64::NEG_INFINITY, |h| h.t as f64));
                let agree = match (expected, got) {
                    (None, None) => true,
                    (Some((t, _)), Some(h)) => (h.t as f64 - t).abs() < 1e-3 * (1.0 + t.abs()),
                    _ => false,
                };
                if !agree {
                    if ambiguous(&ts, t_min as f64, t_max as f64, limit.min(1e9))
                        || tree.grazes(o64, d64, 1e-5)
                        || tree.skims(d64, 1e-3)
                    {
                        skipped.set(skipped.get() + 1);
                        continue;
                    }
                    return Err(TestCaseError::fail(format!(
                        "ray {o} {d} [{t_min}, {t_max}]: expected {expected:?}, got {got:?}"
                    )));
                }
                compared.set(compared.get() + 1);
                // The surface's normal faces against the ray where it enters, along it
                // where it leaves.
                if let (Some((_, entering)), Some(h)) = (expected, got) {
                    hits.set(hits.get() + 1);
                    let si = csg.interaction(&ray, &h);
                    let cos = si.n.dot(d.normalize());
                    prop_assert!((si.n.length() - 1.0).abs() < 1e-4, "{:?}", si.n);
                    if cos.abs() > 1e-3 {
                        prop_assert_eq!(
                            cos < 0.0,
                            entering,
                            "normal {} at t {} on ray {} {}",
                            si.n,
                            h.t,
                            o,
                            d
                        );
                    }
                    prop_assert!((si.p - ray.at(h.t)).length() < 1e-3);
                }
            }
            Ok(())
        },
    );
    if let Err(e) = result {
        panic!("{e}");
    }
    let (c, s, h, i) = (
        compared.get(),
        skipped.get(),
        hits.get(),
        inside_starts.get(),
    );
    eprintln!("compared {c} rays ({h} hits, {i} starting inside), skipped {s} near-degenerate");
    assert!(c > 150_000 && s * 100 < c, "compared {c}, skipped {s}");
    assert!(h > 45_000, "{h} hits");
    assert!(i > 9_000, "{i} inside");
}

/// Walking a ray from hit to hit flips inside/outside each time, `contains` agrees with
/// that parity between hits, every walk ends outside, and `contains` agrees with the
/// reference classifier away from surfaces.
#[test]
fn contains_agrees_with_the_parity_of_hits() {
    let octahedron = mesh(octahedron_data());
    let walks = Cell::new(0u32);
    let mut runner = TestRunner::new(Config {
        cases: 1000,
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(
        &(spec_strategy(), any::<u64>()),
        |(spec, seed)| -> Result<(), TestCaseError> {
            let csg = Csg::new(build(&spec, &octahedron)).unwrap();
            let tree = reference(&spec, DMat4::IDENTITY);
            let mut rng = Pcg32::new(seed, 9);
            // Points: the classifier against the reference, off the surfaces.
            for _ in 0..64 {
                let p = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 5.0;
                if tree.off_surfaces(p.as_dvec3()) {
                    prop_assert_eq!(csg.contains(p), tree.contains(p.as_dvec3()), "point {}", p);
                }
            }
            // Walks.
            'rays: for _ in 0..32 {
                let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 5.0;
                let target =
                    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 1.5;
                let Some(d) = (target - o).try_normalize() else {
                    continue;
                };
                // A walk from within rounding error of a surface would skip that
                // surface (hits must be provably ahead) while `contains` may count it.
                if !tree.off_surfaces(o.as_dvec3()) {
                    continue;
                }
                let mut inside = csg.contains(o);
                let mut t = 0.0f32;
                for _ in 0..64 {
                    let ray = Ray::with_range(o, d, t, f32::INFINITY);
                    let Some(h) = csg.intersect(&ray, &mut RayStats::default()) else {
                        prop_assert!(!inside, "the walk along {} {} ends inside", o, d);
                        walks.set(walks.get() + 1);
                        continue 'rays;
                    };
                    if h.t - t < 1e-3 {
                        continue 'rays; // nearly coincident surfaces: classification moot
                    }
                    let mid = ray.at(0.5 * (t + h.t));
                    if !tree.off_surfaces(mid.as_dvec3()) {
                        continue 'rays; // a grazing chord: its middle is all but on the surface
                    }
                    prop_assert_eq!(csg.contains(mid), inside, "between {} and {}", t, h.t);
                    let cos = csg.interaction(&ray, &h).n.dot(d);
                    if cos.abs() > 1e-3 {
                        prop_assert_eq!(cos > 0.0, inside, "normal at {} on {} {}", h.t, o, d);
                    }
                    inside = !inside;
                    t = h.t;
                }
                prop_assert!(false, "more than 64 hits");
            }
            Ok(())
        },
    );
    if let Err(e) = result {
        panic!("{e}");
    }
    eprintln!("{} walks", walks.get());
    assert!(walks.get() > 20_000, "{}", walks.get());
}

// ---------------------------------------------------------------------------------------
// In a scene

/// Rays spawned from CSG hits (cut faces included) never hit the surface they leave at
/// a distance that is only rounding error, under random instance transforms.
#[test]
fn spawned_rays_do_not_self_intersect() {
    use crate::scene::SceneBuilder;
    let csg = Csg::new(
        CsgNode::op(
            CsgOp::Difference,
            CsgNode::op(
                CsgOp::Intersection,
                CsgNode::leaf(Solid::Sphere),
                leaf(Solid::Cube, scale(0.8)),
            ),
            leaf(
                Solid::Cylinder,
                Transform::scale(Vec3::new(0.4, 0.4, 4.0))
                    .unwrap()
                    .then(&translate(0.0, 0.0, -2.0)),
            ),
        )
        .transformed(&Transform::rotate(Vec3::new(1.0, 2.0, 0.5), 33.0).unwrap()),
    )
    .unwrap();
    let shape = crate::geometry::Shape::Csg(Arc::new(csg));
    let mut rng = Pcg32::new(8, 2);
    let (mut acne, mut spawned) = (0, 0);
    for _ in 0..200 {
        let mut b = SceneBuilder::new();
        let id = b.add_shape(shape.clone());
        let s = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0 + 0.2;
        let axis = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
        let to = Transform::scale(s)
            .unwrap()
            .then(&Transform::rotate(axis, rng.next_f32() * 360.0).unwrap())
            .then(&Transform::translate(
                (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 20.0,
            ));
        b.add_instance(id, to);
        let scene = b.build();
        let centre = to.point(Vec3::ZERO);
        for _ in 0..50 {
            let o = centre
                + warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())) * 30.0;
            let target =
                to.point((Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 1.6);
            let Some(si) = scene.intersect(&Ray::new(o, target - o)) else {
                continue;
            };
            for side in [1.0f32, -1.0] {
                let w = crate::math::Frame::from_normal(si.n * side).to_world(
                    warp::square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32())),
                );
                spawned += 1;
                if let Some(h) = scene.intersect(&si.spawn_ray(w)) {
                    let near = (h.p - si.p).length() < 1e-4 * (1.0 + si.p.abs().max_element());
                    if near && h.prim == si.prim {
                        acne += 1;
                    }
                }
            }
        }
    }
    assert!(spawned > 5_000, "{spawned}");
    assert_eq!(
        acne, 0,
        "{acne} of {spawned} spawned rays re-hit their own surface"
    );
}

#[test]
fn scene_files_build_trees_with_leaf_materials() {
    use crate::io::{load_scene_str, LoadOptions};
    let xml = r#"<integrator type="aov" variable="normals"><scene>
        <camera type="perspective"/>
        <instance>
            <shape type="csg" op="difference">
                <shape type="sphere"/>
                <shape type="csg" op="union">
                    <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.1"/></bsdf>
                    <shape type="cube"><transform><scale value="0.5"/><translate x="1"/></transform></shape>
                    <shape type="cylinder">
                        <transform><scale x="0.3" y="0.3" z="4"/><translate z="-2"/></transform>
                        <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.2"/></bsdf>
                    </shape>
                </shape>
            </shape>
            <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.3"/></bsdf>
            <transform><translate z="5"/></transform>
        </instance>
    </scene><sampler type="independent"/></integrator>"#;
    let loaded =
        load_scene_str(xml, std::path::Path::new("t.xml"), &LoadOptions::default()).unwrap();
    let scene = &loaded.scene;
    let albedo = |si: &SurfaceInteraction| match scene.material(si) {
        Some(Material::Diffuse(d)) => d.albedo.eval(Vec2::ZERO).x,
        other => panic!("{other:?}"),
    };
    // The sphere: the instance's material.
    let si = scene
        .intersect(&Ray::new(Vec3::new(-0.5, 0.5, 0.0), Vec3::Z))
        .unwrap();
    assert!((albedo(&si) - 0.3).abs() < 1e-6);
    // Down the drilled hole (x = y = 0): it goes right through, the ray passes.
    assert!(scene.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).is_none());
    // Slightly off the axis, inside the cylinder's radius: nothing either.
    assert!(scene
        .intersect(&Ray::new(Vec3::new(0.2, 0.0, 0.0), Vec3::Z))
        .is_none());
    // The cube's cut face at x = 0.5, seen from the +x side: inherits the union's
    // material; its normal points into the hole (+x).
    let si = scene
        .intersect(&Ray::new(Vec3::new(3.0, 0.1, 4.8), -Vec3::X))
        .unwrap();
    assert!((si.p.x - 0.5).abs() < 1e-5, "{:?}", si.p);
    assert!((si.n - Vec3::X).length() < 1e-5);
    assert!((albedo(&si) - 0.1).abs() < 1e-6);
    // The cylinder's wall, seen from inside the hole: its own material, normal inwards
    // to the axis.
    let si = scene
        .intersect(&Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Y))
        .unwrap();
    assert!((si.p.y - 0.3).abs() < 1e-5, "{:?}", si.p);
    assert!((si.n + Vec3::Y).length() < 1e-5, "{:?}", si.n);
    assert!((albedo(&si) - 0.2).abs() < 1e-6);
}

#[test]
fn scene_file_errors() {
    use crate::io::{load_scene_str, LoadOptions};
    let wrap = |shape: &str, extra: &str| {
        format!(
            r#"<integrator type="aov" variable="normals"><scene><camera type="perspective"/>
            <instance>{shape}{extra}</instance></scene><sampler type="independent"/></integrator>"#
        )
    };
    for (shape, extra, needle) in [
        (
            r#"<shape type="csg"><shape type="sphere"/><shape type="cube"/></shape>"#,
            "",
            "needs an `op`",
        ),
        (
            r#"<shape type="csg" op="minus"><shape type="sphere"/><shape type="cube"/></shape>"#,
            "",
            "unknown csg op",
        ),
        (
            r#"<shape type="csg" op="union"><shape type="sphere"/></shape>"#,
            "",
            "at least two",
        ),
        (
            r#"<shape type="csg" op="union"><shape type="sphere"/><shape type="rectangle"/></shape>"#,
            "",
            "bounds no solid",
        ),
        (
            r#"<shape type="csg" op="union"><shape type="sphere"/><shape type="cylinder" caps="false"/></shape>"#,
            "",
            "closed solid",
        ),
        (
            r#"<shape type="csg" op="union"><shape type="sphere"/><shape type="cube"/></shape>"#,
            r#"<emission type="lambertian"/>"#,
            "cannot emit",
        ),
    ] {
        let e = load_scene_str(
            &wrap(shape, extra),
            std::path::Path::new("t.xml"),
            &LoadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains(needle), "{e}");
    }
}
