//! The path tracer against closed-form answers.

mod common;
use common::render;

fn mean_and_worst(img: &lightpath::film::Image, expected: f32) -> (f64, f32) {
    let (w, h) = (img.width, img.height);
    let mut sum = 0.0f64;
    let mut worst = 0.0f32;
    for y in 0..h {
        for x in 0..w {
            let v = img.get(x, y);
            for c in 0..3 {
                sum += v[c] as f64;
                worst = worst.max((v[c] - expected).abs());
            }
        }
    }
    (sum / (3 * w * h) as f64, worst)
}

/// A point light of intensity I at the centre of a closed diffuse sphere of radius R and
/// albedo ρ: by symmetry the wall's radiance is uniform, L = ρ/π · (I/R² + π L), so
/// L = ρ I / (π R² (1 − ρ)). With ρ = 0.5, I = π, R = 2: L = 0.25. Every bounce matters
/// (depth 1, 2, 3 give 0, 0.125, 0.1875, …), so this checks the whole light transport.
#[test]
fn point_light_inside_a_diffuse_sphere_matches_the_closed_form() {
    let xml = r#"<integrator type="pathtracer" depth="-1"><scene>
        <camera type="perspective"><integer name="width" value="32"/><integer name="height" value="32"/>
            <float name="fov" value="90"/><transform><translate x="0.3"/></transform></camera>
        <light type="point" position="0,0,0" intensity="3.14159265"/>
        <instance><shape type="sphere"/><bsdf type="diffuse"><texture name="albedo" type="constant" value="0.5"/></bsdf>
            <transform><scale value="2"/></transform></instance>
    </scene><sampler type="sobol" count="256"/></integrator>"#;
    let img = render(xml);
    let (mean, worst) = mean_and_worst(&img, 0.25);
    assert!((mean - 0.25).abs() < 0.0025, "mean {mean}, expected 0.25");
    assert!(worst < 0.05, "worst pixel off by {worst}");

    // A limited depth stops the series: depth 3 sees the direct term and one bounce,
    // ρ I/(π R²) · (1 + ρ) = 0.1875.
    let img = render(&xml.replace(r#"depth="-1""#, r#"depth="3""#));
    let (mean, _) = mean_and_worst(&img, 0.1875);
    assert!(
        (mean - 0.1875).abs() < 0.002,
        "depth 3: mean {mean}, expected 0.1875"
    );
}

/// White furnace: a non-absorbing sphere under a uniform environment of radiance 1
/// renders 1 everywhere. Exact for the diffuse BSDF of albedo 1 and the rough dielectric
/// of index 1 (it lets light through unchanged); the single-scattering GGX conductor
/// (reflectance 1, no Fresnel) loses some energy at grazing angles, so it is held to 1%
/// on average and 10% per pixel at roughness 0.2.
#[test]
fn white_furnace() {
    for (bsdf, mean_tol, pixel_tol) in [
        (
            r#"<bsdf type="diffuse"><texture name="albedo" type="constant" value="1"/></bsdf>"#,
            2e-3,
            0.03,
        ),
        (
            r#"<bsdf type="roughdielectric"><float name="ior" value="1"/><float name="roughness" value="0.3"/></bsdf>"#,
            1e-4,
            1e-3,
        ),
        (
            r#"<bsdf type="roughconductor"><texture name="reflectance" type="constant" value="1"/><float name="roughness" value="0.2"/></bsdf>"#,
            0.01,
            0.1,
        ),
    ] {
        let xml = format!(
            r#"<integrator type="pathtracer" depth="-1"><scene>
            <camera type="perspective"><integer name="width" value="32"/><integer name="height" value="32"/>
                <float name="fov" value="30"/><transform><translate z="-4"/></transform></camera>
            <light type="envmap"><texture type="constant" value="1"/></light>
            <instance><shape type="sphere"/>{bsdf}</instance>
        </scene><sampler type="sobol" count="256"/></integrator>"#
        );
        let img = render(&xml);
        let (mean, worst) = mean_and_worst(&img, 1.0);
        assert!(
            (mean - 1.0).abs() < mean_tol,
            "{bsdf}: mean {mean}, expected 1"
        );
        assert!(worst < pixel_tol, "{bsdf}: worst pixel off by {worst}");
    }
}
