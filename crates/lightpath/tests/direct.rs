//! Direct illumination against closed-form answers.

use lightpath::io::{load_scene_str, LoadOptions};
mod common;
use common::render;
use std::path::Path;

/// A diffuse plane (albedo 0.5) at z = 0 under a point light at height h: the radiance
/// is albedo/π · I cosθ / r², pixel by pixel, seen by an orthographic camera from above.
#[test]
fn point_light_over_a_plane_matches_irradiance() {
    let (intensity, h, albedo) = (10.0f32, 2.0f32, 0.5f32);
    let xml = format!(
        r#"<integrator type="direct"><scene>
            <camera type="orthographic"><integer name="width" value="64"/><integer name="height" value="64"/>
                <float name="size" value="3"/><transform><translate z="-5"/></transform></camera>
            <light type="point" position="0.5,0,-{h}" intensity="{intensity}"/>
            <instance><shape type="rectangle"/><bsdf type="diffuse"><texture name="albedo" type="constant" value="{albedo}"/></bsdf>
                <transform><scale value="4"/></transform></instance>
        </scene><sampler type="independent" count="64"/></integrator>"#
    );
    let img = render(&xml);
    let mut worst = 0.0f32;
    let mut bias = 0.0f64;
    for y in 0..64 {
        for x in 0..64 {
            // The pixel's mean radiance by 16x16 quadrature (orthographic, half-width 3).
            let mut expected = 0.0;
            for j in 0..16 {
                for i in 0..16 {
                    let px = ((x as f32 + (i as f32 + 0.5) / 16.0) / 64.0 * 2.0 - 1.0) * 3.0;
                    let py = ((y as f32 + (j as f32 + 0.5) / 16.0) / 64.0 * 2.0 - 1.0) * 3.0;
                    let d = glam::Vec3::new(0.5 - px, -py, -h);
                    let r2 = d.length_squared();
                    let cos = h / r2.sqrt();
                    expected += albedo / std::f32::consts::PI * intensity * cos / r2 / 256.0;
                }
            }
            let got = img.get(x, y).x;
            let rel = (got - expected) / expected;
            worst = worst.max(rel.abs());
            bias += rel as f64 / 4096.0;
        }
    }
    // What is left is the noise of 64 random positions inside each pixel: about 0.25%
    // per pixel where the irradiance changes fastest, so 1.5% is a 6-sigma bound; the
    // mean over all pixels has no such noise and must be unbiased.
    assert!(worst < 0.015, "worst relative error {worst}");
    assert!(bias.abs() < 5e-4, "mean relative error {bias}");
}

/// A white, non-absorbing diffuse sphere in a uniform environment of radiance 1 renders
/// 1 everywhere (the furnace test), with and without sampling the environment directly.
#[test]
fn furnace() {
    for weight in ["0", "1"] {
        let xml = format!(
            r#"<integrator type="direct"><scene>
                <camera type="perspective"><integer name="width" value="32"/><integer name="height" value="32"/>
                    <float name="fov" value="30"/><transform><translate z="-4"/></transform></camera>
                <light type="envmap" weight="{weight}"><texture type="constant" value="1"/></light>
                <instance><shape type="sphere"/><bsdf type="diffuse"><texture name="albedo" type="constant" value="1"/></bsdf></instance>
            </scene><sampler type="independent" count="64"/></integrator>"#
        );
        let img = render(&xml);
        let mean: f32 = img.pixels.iter().map(|p| p.x + p.y + p.z).sum::<f32>()
            / (3.0 * img.pixels.len() as f32);
        assert!((mean - 1.0).abs() < 0.01, "weight {weight}: mean {mean}");
        let worst = img
            .pixels
            .iter()
            .map(|p| (p.x - 1.0).abs())
            .fold(0.0f32, f32::max);
        if weight == "0" {
            // BSDF sampling of a convex object always escapes: exactly 1.
            assert!(worst < 1e-4, "worst {worst}");
        }
    }
}

/// Shadow acne and light leaks: a unit sphere resting on a plane under a directional
/// light at grazing elevations, the whole scene rotated off the axes (so the plane's
/// points are not exactly representable). For every pixel-centre ray the analytic answer (lit or in
/// shadow, from f64 ray/sphere geometry) is compared with the `direct` integrator's value;
/// pixels within a small margin of a shadow boundary or the terminator are left out. A lit
/// pixel must have exactly its closed-form radiance albedo/π · E · cos θ (the estimate is
/// deterministic: one directional light, no environment), a shadowed one must be black.
#[test]
fn no_acne_or_leaks_at_grazing_light() {
    use glam::{DVec3, Vec2};
    use lightpath::accel::RayStats;
    use lightpath::camera::CameraSample;

    let albedo = 0.8f64;
    let (w, h) = (160u32, 120u32);
    let mut checked = 0usize;
    let mut wrong = Vec::new();
    let axis = DVec3::new(1.0, 2.0, 3.0).normalize();
    let angle = 37.0f64;
    let rot = glam::DMat3::from_axis_angle(axis, angle.to_radians());
    let r = |v: DVec3| {
        let v = rot * v;
        format!("{},{},{}", v.x, v.y, v.z)
    };
    for elevation in [1.0f64, 3.0, 10.0, 30.0, 60.0] {
        let e = elevation.to_radians();
        let l = DVec3::new(e.cos() * 0.8, e.cos() * 0.6, e.sin());
        let xml = format!(
            r#"<integrator type="direct"><scene>
                <camera type="perspective"><integer name="width" value="{w}"/><integer name="height" value="{h}"/>
                    <float name="fov" value="50"/>
                    <transform><lookat origin="{}" target="{}" up="{}"/></transform></camera>
                <light type="directional" direction="{}" intensity="1"/>
                <instance><shape type="plane"/><bsdf type="diffuse"><texture name="albedo" type="constant" value="{albedo}"/></bsdf>
                    <transform><rotate axis="{axis_s}" angle="{angle}"/></transform></instance>
                <instance><shape type="sphere"/><bsdf type="diffuse"><texture name="albedo" type="constant" value="{albedo}"/></bsdf>
                    <transform><translate z="1"/><rotate axis="{axis_s}" angle="{angle}"/></transform></instance>
            </scene><sampler type="independent" count="1"/></integrator>"#,
            r(DVec3::new(-5.0, -4.0, 3.5)),
            r(DVec3::new(0.3, 0.2, 0.5)),
            r(DVec3::new(0.0, 0.0, -1.0)),
            r(l),
            axis_s = format!("{},{},{}", axis.x, axis.y, axis.z),
        );
        let loaded = load_scene_str(&xml, Path::new("acne.xml"), &LoadOptions::default()).unwrap();
        let camera = loaded.scene.camera.as_ref().unwrap();
        let mut sampler = loaded.sampler.clone();
        let c = DVec3::new(0.0, 0.0, 1.0);
        for y in 0..h {
            for x in 0..w {
                let film = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let Some(ray) = camera.generate_ray(&CameraSample {
                    film,
                    lens: Vec2::splat(0.5),
                }) else {
                    continue;
                };
                // Back into the unrotated frame of the analytic scene.
                let o = rot.transpose() * ray.origin.as_dvec3();
                let d = (rot.transpose() * ray.direction.as_dvec3()).normalize();
                // Analytic first hit: the sphere, else the plane.
                let oc = o - c;
                let b = oc.dot(d);
                let disc = b * b - (oc.length_squared() - 1.0);
                let sphere_t = if disc > 0.0 { -b - disc.sqrt() } else { -1.0 };
                let plane_t = if d.z != 0.0 { -o.z / d.z } else { -1.0 };
                let (cos, lit) = if sphere_t > 0.0 {
                    let n = (o + d * sphere_t - c).normalize();
                    let cos = n.dot(l);
                    if cos.abs() < 2e-3 || disc < 1e-3 {
                        continue; // the terminator or the silhouette
                    }
                    (cos, cos > 0.0)
                } else if plane_t > 0.0 {
                    let p = o + d * plane_t;
                    // Distance from the sphere's centre to the shadow ray's line.
                    let pc = c - p;
                    let along = pc.dot(l);
                    let dist = (pc - l * along).length();
                    if (dist - 1.0).abs() < 2e-3 || (p - DVec3::ZERO).length() < 0.05 {
                        continue; // a shadow boundary, or the contact point
                    }
                    (l.z, !(along > 0.0 && dist < 1.0))
                } else {
                    continue;
                };
                sampler.start_pixel_sample(glam::UVec2::new(x, y), 0);
                let v = loaded
                    .integrator
                    .li(&loaded.scene, &ray, &mut sampler, &mut RayStats::default())
                    .x as f64;
                let expected = if lit {
                    albedo / std::f64::consts::PI * cos
                } else {
                    0.0
                };
                checked += 1;
                if (v - expected).abs() > 1e-4 + 1e-3 * expected {
                    wrong.push((elevation, x, y, lit, v, expected));
                }
            }
        }
    }
    assert!(checked > 50_000, "only {checked} pixels checked");
    assert!(
        wrong.is_empty(),
        "{} of {checked} pixels wrongly shadowed or lit, e.g. {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(5)]
    );
}
