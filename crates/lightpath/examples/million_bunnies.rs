//! A million Stanford bunnies (about 70 billion triangles) on a ground plane, each with its
//! own rotation, scale and colour: one bottom-level BVH for the bunny, a top-level BVH
//! over a million instance boxes.
//!
//! ```sh
//! cargo run --release -p lightpath --example million_bunnies -- \
//!     ../shared/models/stanford-bunny/bunny.ply bunnies.png [side=1000] [width=1280] [spp=16]
//! /usr/bin/time -v target/release/examples/million_bunnies BUNNY.ply out.png   # peak memory
//! ```

use lightpath::camera::{Camera, FovAxis, Perspective};
use lightpath::geometry::{Plane, Shape, TriangleMesh};
use lightpath::integrator::{Direct, Integrator};
use lightpath::light::{DirectionalLight, Environment, Light};
use lightpath::material::{Diffuse, Material};
use lightpath::math::{Transform, Vec3};
use lightpath::render::Renderer;
use lightpath::sampling::{Pcg32, Sampler, SobolSampler};
use lightpath::scene::SceneBuilder;
use lightpath::texture::Texture;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

fn hsv(h: f32, s: f32, v: f32) -> Vec3 {
    let k = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        v - v * s * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    Vec3::new(k(5.0), k(3.0), k(1.0))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: million_bunnies BUNNY.ply OUT.png [side=1000] [width=1280] [spp=16]");
        std::process::exit(2);
    }
    let bunny_path = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    let side: u32 = args.get(3).map_or(Ok(1000), |s| s.parse())?;
    let width: u32 = args.get(4).map_or(Ok(1280), |s| s.parse())?;
    let spp: u32 = args.get(5).map_or(Ok(16), |s| s.parse())?;
    let height = width * 9 / 16;

    let t0 = Instant::now();
    let data = lightpath::io::load_mesh(&bunny_path)?;
    let bunny = TriangleMesh::new(data, true, lightpath::accel::AccelKind::Bvh2)?;
    let triangles = bunny.triangle_count();
    // The bunny stands on z = 0 (it is modelled y-up), about one unit tall.
    let b = bunny.bounds();
    let to_unit = Transform::translate(Vec3::new(
        -(b.min.x + b.max.x) * 0.5,
        -b.min.y,
        -(b.min.z + b.max.z) * 0.5,
    ))
    .then(&Transform::scale(Vec3::splat(1.0 / (b.max.y - b.min.y))).unwrap())
    .then(&Transform::rotate(Vec3::X, 90.0).unwrap());
    let load_s = t0.elapsed().as_secs_f64();

    let mut builder = SceneBuilder::new();
    let bunny_id = builder.add_shape(Shape::TriangleMesh(Arc::new(bunny)));
    let ground = builder.add_shape(Shape::Plane(Plane));
    let g = builder.add_instance(ground, Transform::IDENTITY);
    builder.set_material(
        g,
        Arc::new(Material::Diffuse(Diffuse {
            albedo: Arc::new(Texture::Constant(Vec3::splat(0.45))),
        })),
    );
    let mut rng = Pcg32::new(2026, 11);
    let spacing = 1.4f32;
    for j in 0..side {
        for i in 0..side {
            let jitter = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.0) * 0.5;
            let pos = Vec3::new(i as f32 * spacing, j as f32 * spacing, 0.0) + jitter;
            let scale = 0.6 + 0.8 * rng.next_f32();
            let t = to_unit
                .then(&Transform::scale(Vec3::splat(scale)).unwrap())
                .then(&Transform::rotate(Vec3::Z, rng.next_f32() * 360.0).unwrap())
                .then(&Transform::translate(pos));
            let id = builder.add_instance(bunny_id, t);
            let colour = hsv(rng.next_f32(), 0.55 + 0.35 * rng.next_f32(), 0.85);
            builder.set_material(
                id,
                Arc::new(Material::Diffuse(Diffuse {
                    albedo: Arc::new(Texture::Constant(colour)),
                })),
            );
        }
    }
    // Looking over the field from a corner, low, towards its far side (world z up; the
    // camera's +y is image down, so `up` points down).
    let extent = side as f32 * spacing;
    let eye = Vec3::new(-6.0, -6.0, 5.0);
    let target = Vec3::new(extent * 0.35, extent * 0.3, 0.0);
    let camera = Camera::Perspective(Perspective::new(
        glam::UVec2::new(width, height),
        55.0,
        FovAxis::X,
        Transform::look_at(eye, target, Vec3::new(0.0, 0.0, -1.0)).ok_or("bad camera")?,
    ));
    builder.set_camera(camera);
    let t1 = Instant::now();
    let mut scene = builder.build();
    let build_s = t1.elapsed().as_secs_f64();
    scene.set_lights(
        vec![
            Light::Directional(DirectionalLight {
                direction: Vec3::new(-0.5, -0.3, 0.6).normalize(),
                intensity: Vec3::new(2.6, 2.4, 2.1),
            }),
            Light::Environment(Environment::new(
                Arc::new(Texture::Constant(Vec3::new(0.35, 0.45, 0.65))),
                Transform::IDENTITY,
            )),
        ],
        &[1.0, 1.0],
    )?;
    let integrator = Integrator::Direct(Direct);
    let sampler = Sampler::Sobol(Box::new(SobolSampler::new(spp, 0)));
    let t2 = Instant::now();
    let (image, stats) = Renderer {
        scene: &scene,
        camera: scene.camera.as_ref().unwrap(),
        integrator: &integrator,
        sampler: &sampler,
    }
    .render(&|_| {})?;
    let render_s = t2.elapsed().as_secs_f64();
    lightpath::io::image::write_image(&out, &image)?;
    let instances = side as u64 * side as u64;
    eprintln!(
        "{instances} bunnies x {triangles} triangles = {:.1e} triangles; load {load_s:.2} s, \
         scene build (TLAS) {build_s:.2} s, render {width}x{height} {spp} spp {render_s:.2} s \
         ({:.2} M rays/s); accel memory {:.1} MiB",
        instances as f64 * triangles as f64,
        stats.rays as f64 / render_s / 1e6,
        scene.accel_memory_bytes() as f64 / (1u64 << 20) as f64
    );
    Ok(())
}
