//! Instancing against flattening: a mesh placed many times through one shared BLAS gives
//! the same hits and the same image as the same triangles transformed into world space.

use lightpath::geometry::MeshData;
use lightpath::integrator::{Aov, AovVariable, Integrator};
use lightpath::prelude::*;
use lightpath::sampling::{warp, IndependentSampler, Pcg32, Sampler};
use std::sync::Arc;

fn lumpy_mesh(rng: &mut Pcg32) -> MeshData {
    // A closed, lumpy octahedron-like blob: a sphere tessellation with radial noise.
    let (nu, nv) = (24u32, 12u32);
    let mut data = MeshData::default();
    for j in 0..=nv {
        for i in 0..nu {
            let (theta, phi) = (
                std::f32::consts::PI * j as f32 / nv as f32,
                2.0 * std::f32::consts::PI * i as f32 / nu as f32,
            );
            let r = 1.0 + 0.15 * rng.next_f32();
            data.positions.push(
                Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ) * r,
            );
        }
    }
    for j in 0..nv {
        for i in 0..nu {
            let a = j * nu + i;
            let b = j * nu + (i + 1) % nu;
            let (c, d) = (a + nu, b + nu);
            data.indices.push([a, c, b]);
            data.indices.push([b, c, d]);
        }
    }
    data
}

/// Random placements with rotation, non-uniform scale and mirroring.
fn placements(rng: &mut Pcg32, n: usize) -> Vec<Transform> {
    (0..n)
        .map(|k| {
            let mirror = if k % 3 == 0 { -1.0 } else { 1.0 };
            let s = Vec3::new(
                mirror * (0.3 + 0.5 * rng.next_f32()),
                0.3 + 0.5 * rng.next_f32(),
                0.3 + 0.5 * rng.next_f32(),
            );
            let axis = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let t = Vec3::new(
                (k % 5) as f32 * 2.0 - 4.0,
                (k / 5) as f32 * 2.0 - 4.0,
                rng.next_f32() * 2.0,
            );
            Transform::scale(s)
                .unwrap()
                .then(&Transform::rotate(axis, rng.next_f32() * 360.0).unwrap())
                .then(&Transform::translate(t))
        })
        .collect()
}

fn scenes() -> (Scene, Scene) {
    let mut rng = Pcg32::new(21, 3);
    let data = lumpy_mesh(&mut rng);
    let places = placements(&mut rng, 25);
    // Instanced: one mesh, one BLAS, 25 instances.
    let mut a = SceneBuilder::new();
    let shared = a.add_shape(Shape::TriangleMesh(Arc::new(
        TriangleMesh::new(data.clone(), false, AccelKind::Bvh2).unwrap(),
    )));
    for t in &places {
        a.add_instance(shared, *t);
    }
    // Flattened: 25 meshes already in world space (winding flipped where mirrored).
    let mut b = SceneBuilder::new();
    for t in &places {
        let mut d = data.clone();
        for p in &mut d.positions {
            *p = t.point(*p);
        }
        if t.swaps_handedness() {
            for tri in &mut d.indices {
                tri.swap(1, 2);
            }
        }
        let s = b.add_shape(Shape::TriangleMesh(Arc::new(
            TriangleMesh::new(d, false, AccelKind::Bvh2).unwrap(),
        )));
        b.add_instance(s, Transform::IDENTITY);
    }
    let camera = Camera::Perspective(Perspective::new(
        glam::UVec2::new(96, 96),
        60.0,
        FovAxis::X,
        Transform::translate(Vec3::new(0.0, 0.0, -9.0)),
    ));
    a.set_camera(camera.clone());
    b.set_camera(camera);
    (a.build(), b.build())
}

#[test]
fn instanced_hits_equal_flattened_hits() {
    let (inst, flat) = scenes();
    let mut rng = Pcg32::new(5, 5);
    let (mut hits, mut compared) = (0, 0);
    for _ in 0..50_000 {
        let o = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())) * 15.0;
        let target = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 10.0;
        let ray = Ray::new(o, target - o);
        match (inst.intersect(&ray), flat.intersect(&ray)) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                hits += 1;
                assert!((a.t - b.t).abs() <= 2e-4 * a.t, "t {} vs {}", a.t, b.t);
                // Away from silhouettes and shared edges the same triangle is hit.
                if (a.instance, a.prim) == (b.instance, b.prim) {
                    compared += 1;
                    assert!(a.n.dot(b.n) > 0.9999, "normal {:?} vs {:?}", a.n, b.n);
                    assert!((a.p - b.p).length() < 1e-3, "{:?} vs {:?}", a.p, b.p);
                }
            }
            (a, b) => {
                // Only grazing rays along an edge may differ.
                let t = a.or(b).unwrap().t;
                panic!("one scene hit at t = {t}, the other missed: {:?}", ray);
            }
        }
    }
    assert!(
        hits > 5_000 && compared > hits * 9 / 10,
        "{hits} hits, {compared} compared"
    );
}

#[test]
fn instanced_image_equals_flattened_image() {
    let (inst, flat) = scenes();
    let integrator = Integrator::Aov(Aov {
        variable: AovVariable::Normals,
        scale: 1.0,
    });
    let sampler = Sampler::Independent(IndependentSampler::new(4, 1));
    let render = |scene: &Scene| {
        Renderer {
            scene,
            camera: scene.camera.as_ref().unwrap(),
            integrator: &integrator,
            sampler: &sampler,
        }
        .render(&|_| {})
        .unwrap()
        .0
    };
    let (a, b) = (render(&inst), render(&flat));
    let errors = lightpath::film::ImageErrors::compute(&a, &b).unwrap();
    assert!(errors.mae < 1e-4, "mean absolute difference {}", errors.mae);
}
