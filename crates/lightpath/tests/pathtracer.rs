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

/// A blend is linear in its weight: with direct light only (maximum depth 2), the image
/// of a blend of a diffuse and a perfect mirror at weight 0.5 is the mean of the images at
/// weights 0 and 1. This checks that a delta sample of one child, the mixture pdf of the
/// other and next-event estimation combine without missing or doubled light. (Mitsuba
/// 3.9.1's `blendbsdf` fails it: at 1024 samples per pixel it renders this scene 5.8%
/// darker than the mean of its own weight-0 and weight-1 images, the deficit all in the
/// mirror image of the lamp: that is why lightpath and Mitsuba disagree on blends with a
/// delta child.)
#[test]
fn a_blend_with_a_delta_child_is_linear_in_its_weight() {
    let scene = |w: f32| {
        format!(
            r#"<scene version="3.0.0">
            <integrator type="path"><integer name="max_depth" value="2"/></integrator>
            <sensor type="perspective"><float name="fov" value="40"/>
                <transform name="to_world"><lookat origin="0, 2, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
                <sampler type="ldsampler"><integer name="sample_count" value="256"/></sampler>
                <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/>
                    <rfilter type="box"/></film></sensor>
            <shape type="rectangle">
                <transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
                <bsdf type="blendbsdf"><float name="weight" value="{w}"/>
                    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
                    <bsdf type="conductor"/></bsdf></shape>
            <shape type="rectangle">
                <transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate value="0, 1.5, -0.5"/></transform>
                <emitter type="area"><rgb name="radiance" value="10"/></emitter></shape>
            </scene>"#
        )
    };
    // The scene is grey, so the mean over the channels is the mean of each.
    let mean = |w: f32| mean_and_worst(&render(&scene(w)), 0.0).0;
    let (diffuse, mirror, half) = (mean(0.0), mean(1.0), mean(0.5));
    let expected = 0.5 * (diffuse + mirror);
    // Both ends see the lamp (the mirror directly, the diffuse plane lit by it).
    assert!(diffuse > 0.05 && mirror > 0.2, "{diffuse} {mirror}");
    let rel = (half - expected) / expected;
    assert!(
        rel.abs() < 0.015,
        "blend at 0.5: mean {half}, mean of the ends {expected} ({:+.2}%)",
        100.0 * rel
    );
}
