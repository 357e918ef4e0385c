//! Direct illumination against closed-form answers.

use lightpath::io::{load_scene_str, LoadOptions};
use lightpath::render::Renderer;
use std::path::Path;

fn render(xml: &str) -> lightpath::film::Image {
    let loaded = load_scene_str(xml, Path::new("test.xml"), &LoadOptions::default()).unwrap();
    let camera = loaded.scene.camera.as_ref().unwrap();
    let renderer = Renderer {
        scene: &loaded.scene,
        camera,
        integrator: &loaded.integrator,
        sampler: &loaded.sampler,
    };
    renderer.render(&|_| {}).unwrap().0
}

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
