//! Mitsuba 3 scenes of our own, rendered unchanged by lightpath and compared with
//! references that Mitsuba 3.9.1 (`scalar_rgb`, 16384 spp) rendered from the same files:
//! `tests/mitsuba/<scene>_mitsuba.exr`, made by `tests/mitsuba/make_references.py`.
//!
//! The metric is the relative mean squared error of `../shared/tools/mitsuba-ref/
//! compare.py`, mean over pixels and channels of (t − r)² / (r² + 0.01); a scene passes
//! when it is below 1e-3 and the mean brightness is within 1% of the reference's.
//!
//! The scenes cover: `shapegroup` + `instance`, analytic shapes (rectangle, cube, sphere, open cylinder, disk), area,
//! point, spot, directional and constant emitters, perspective (horizontal and vertical
//! fov, 4:3 and 9:5 films) and orthographic sensors, Gaussian (Mitsuba's default), tent,
//! box, Mitchell–Netravali and Lanczos reconstruction filters, `path` (with `max_depth` and `rr_depth`) and `direct`
//! integrators, and the BSDFs diffuse, conductor, roughconductor (Beckmann and GGX,
//! isotropic and anisotropic), plastic, roughplastic (Beckmann and GGX, nonlinear),
//! one-sided diffuse seen from behind, dielectric, roughdielectric, thindielectric,
//! blendbsdf, twosided, normalmap and mask (a bitmap and a constant opacity, shadow rays
//! through them), with checkerboard and bitmap textures, `serialized` meshes (three from
//! one file: computed smooth normals, double precision with normals and texture
//! coordinates, `face_normals`), `bumpmap` (a bitmap height field on a rectangle, a
//! sphere with `to_uv`, a mesh with texture coordinates and a negative scale, and inside
//! a `twosided` seen from behind), `principled` (every lobe: a plain base, a tinted
//! anisotropic metal, a clearcoat, a transmissive sphere, sheen with flatness, and a
//! textured mix) and `principledthin` (a sheet lit from behind), float parameters given
//! colour textures (a bitmap as a roughconductor's and a roughdielectric's `alpha`, a
//! principled `metallic` and a mask's `opacity`, an `rgb` blend weight), and round
//! linear curves (`linearcurve`: tapering strands, a wire with sharp joints placed by a
//! scaling `to_world`) and cubic B-spline curves (`bsplinecurve`: wavy tapering strands
//! and a thick arch), and `flip_normals` on analytic shapes (a rectangle area light, a
//! dielectric sphere that becomes a bubble, an open cylinder with a one-sided diffuse),
//! a film's crop window, and vertex and face colours (`mesh_attribute` `vertex_color`
//! and `face_color` from PLY files, as diffuse reflectances and a principled base colour).

use lightpath::film::{Image, ImageErrors};
use lightpath::io::{load_scene, load_scene_str, LoadOptions, LoadedScene};
use lightpath::render::Renderer;
use std::path::{Path, PathBuf};

const MAX_REL_MSE: f64 = 1e-3;
const MAX_MEAN_DEVIATION: f64 = 0.01;

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../tests/mitsuba/{name}.xml"))
}

fn render(loaded: &LoadedScene, spp: u32) -> Image {
    let sampler = loaded
        .sampler
        .with_kind("sobol")
        .unwrap()
        .with_samples_per_pixel(spp);
    let renderer = Renderer {
        scene: &loaded.scene,
        camera: loaded.scene.camera.as_ref().unwrap(),
        integrator: &loaded.integrator,
        sampler: &sampler,
    };
    renderer.render(&|_| {}).unwrap().0
}

fn reference(name: &str) -> Image {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(format!("../../tests/mitsuba/{name}_mitsuba.exr"));
    lightpath::io::image::read_image(&path, None).unwrap()
}

fn mean(image: &Image) -> f64 {
    image
        .pixels
        .iter()
        .map(|p| (p.x + p.y + p.z) as f64)
        .sum::<f64>()
        / (3 * image.pixels.len()) as f64
}

/// (relMSE, mean ratio) of an image against a scene's Mitsuba reference.
fn compare(image: &Image, name: &str) -> (f64, f64) {
    let reference = reference(name);
    let errors = ImageErrors::compute(image, &reference).expect("sizes match");
    assert_eq!(errors.non_finite, 0);
    (errors.rel_mse, mean(image) / mean(&reference))
}

fn check(name: &str, spp: u32) {
    let loaded = load_scene(&scene_path(name), &LoadOptions::default()).unwrap();
    assert_matches(&render(&loaded, spp), name);
}

/// Asserts that `image` passes the comparison with reference `name`.
fn assert_matches(image: &Image, name: &str) {
    let (rel_mse, ratio) = compare(image, name);
    eprintln!("{name}: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}");
    assert!(
        rel_mse < MAX_REL_MSE,
        "{name}: relMSE {rel_mse:.3e} against Mitsuba (limit {MAX_REL_MSE:e})"
    );
    assert!(
        (ratio - 1.0).abs() < MAX_MEAN_DEVIATION,
        "{name}: mean brightness {ratio:.4} of Mitsuba's"
    );
}

#[test]
fn box_matches_mitsuba() {
    check("box", 1024);
}

#[test]
fn materials_match_mitsuba() {
    check("materials", 2048);
}

#[test]
fn plastics_match_mitsuba() {
    check("plastics", 512);
}

#[test]
fn lights_match_mitsuba() {
    check("lights", 512);
}

#[test]
fn curves_match_mitsuba() {
    check("curves", 1024);
}

#[test]
fn masks_match_mitsuba() {
    check("mask", 1024);
}

/// The mask comparison can fail: the constant mask made opaque (opacity 0.3 → 1) is
/// caught.
#[test]
fn the_mask_comparison_catches_an_opaque_surface() {
    check_caught(
        "mask",
        r#"<float name="opacity" value="0.3"/>"#,
        r#"<float name="opacity" value="1"/>"#,
        "an opaque mask",
    );
}

/// Asserts that scene `name` with `from` replaced by `to` (a deliberate mistake, `what`)
/// fails the comparison with its Mitsuba reference.
fn check_caught(name: &str, from: &str, to: &str, what: &str) {
    let path = scene_path(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let changed = text.replace(from, to);
    assert_ne!(changed, text);
    let loaded = load_scene_str(&changed, &path, &LoadOptions::default()).unwrap();
    let (rel_mse, ratio) = compare(&render(&loaded, 1024), name);
    eprintln!("{what}: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}");
    assert!(
        rel_mse >= MAX_REL_MSE || (ratio - 1.0).abs() >= MAX_MEAN_DEVIATION,
        "{what} passed: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}"
    );
}

#[test]
fn flipped_normals_match_mitsuba() {
    check("flip", 4096);
}

#[test]
fn vertex_colors_match_mitsuba() {
    check("colors", 1024);
}

/// The vertex-colour comparison can fail: the floor's vertex colours, or the
/// icosahedron's face colours, replaced by a grey of about their mean are caught.
#[test]
fn the_vertex_color_comparison_catches_a_uniform_colour() {
    for (attribute, what) in [
        ("vertex_color", "a grey floor"),
        ("face_color", "a grey icosahedron"),
    ] {
        let texture = format!(
            r#"<texture type="mesh_attribute" name="reflectance">
                <string name="name" value="{attribute}"/>
            </texture>"#
        );
        check_caught(
            "colors",
            &texture,
            r#"<rgb name="reflectance" value="0.5"/>"#,
            what,
        );
    }
}

/// The flip comparison can fail: the light left unflipped (facing away), the sphere
/// (glass rather than a bubble) and the cylinder (lit outside, black inside) are caught.
#[test]
fn the_flip_comparison_catches_unflipped_shapes() {
    for (shape, what) in [
        ("rectangle", "an unflipped light"),
        ("sphere", "an unflipped sphere"),
        ("cylinder", "an unflipped cylinder"),
    ] {
        check_caught(
            "flip",
            &format!(
                "<shape type=\"{shape}\">\n        <boolean name=\"flip_normals\" value=\"true\"/>"
            ),
            &format!("<shape type=\"{shape}\">"),
            what,
        );
    }
}

/// The film's crop window (`crop_offset_x`, ..., as Mitsuba reads them): the flip scene
/// cropped to 30x25 pixels at (20, 10) matches that part of its Mitsuba reference
/// (Mitsuba's own crop of the scene is that part too: relMSE 2.2e-4 against it at 4096
/// spp).
#[test]
fn a_cropped_film_matches_that_part_of_mitsuba() {
    let path = scene_path("flip");
    let text = std::fs::read_to_string(&path).unwrap();
    let film = r#"<integer name="height" value="48"/>"#;
    assert!(text.contains(film));
    let cropped = text.replace(
        film,
        &format!(
            r#"{film}<integer name="crop_offset_x" value="20"/>
            <integer name="crop_offset_y" value="10"/><integer name="crop_width" value="30"/>
            <integer name="crop_height" value="25"/>"#
        ),
    );
    let loaded = load_scene_str(&cropped, &path, &LoadOptions::default()).unwrap();
    let image = render(&loaded, 4096);
    assert_eq!((image.width, image.height), (30, 25));
    let full = reference("flip");
    let part = Image {
        width: 30,
        height: 25,
        pixels: (10..35)
            .flat_map(|y| (20..50).map(move |x| (x, y)))
            .map(|(x, y)| full.pixels[(y * full.width + x) as usize])
            .collect(),
    };
    let errors = ImageErrors::compute(&image, &part).expect("sizes match");
    let ratio = mean(&image) / mean(&part);
    eprintln!(
        "flip, cropped: relMSE {:.3e}, mean ratio {ratio:.4}",
        errors.rel_mse
    );
    assert!(
        errors.rel_mse < MAX_REL_MSE,
        "relMSE {:.3e}",
        errors.rel_mse
    );
    assert!(
        (ratio - 1.0).abs() < MAX_MEAN_DEVIATION,
        "mean ratio {ratio:.4}"
    );
}

#[test]
fn serialized_meshes_match_mitsuba() {
    check("serialized", 1024);
}

/// The serialized comparison can fail: the UV sphere shaded faceted (its computed smooth
/// normals left out), and the tent shaded with the file's normals (all straight up)
/// instead of its faces', are both caught.
#[test]
fn the_serialized_comparison_catches_wrong_normals() {
    check_caught(
        "serialized",
        r#"<string name="filename" value="meshes.serialized"/>
        <transform"#,
        r#"<string name="filename" value="meshes.serialized"/>
        <boolean name="face_normals" value="true"/>
        <transform"#,
        "a faceted sphere",
    );
    check_caught(
        "serialized",
        r#"<boolean name="face_normals" value="true"/>"#,
        r#"<boolean name="face_normals" value="false"/>"#,
        "the tent's file normals",
    );
}

#[test]
fn bump_maps_match_mitsuba() {
    check("bump", 1024);
}

/// The bump comparison can fail: the floor's bumps with the opposite sign (dents) and
/// the mesh's bumps left out (scale 0) are each caught. (Mitsuba's terminator shadowing
/// is checked value by value in the material tests.)
#[test]
fn the_bump_comparison_catches_wrong_bumps() {
    check_caught(
        "bump",
        r#"<float name="scale" value="0.4"/>"#,
        r#"<float name="scale" value="-0.4"/>"#,
        "dents for bumps",
    );
    check_caught(
        "bump",
        r#"<float name="scale" value="-0.1"/>"#,
        r#"<float name="scale" value="0"/>"#,
        "a flat mesh",
    );
}

/// The back of a two-sided bump map sees the bumps mirrored through the surface, as
/// Mitsuba's `twosided` mirrors the directions before its nested `bumpmap` sees them;
/// the nesting the other way round (the bump map outside, its normal negated from
/// behind) is caught.
#[test]
fn the_bump_comparison_catches_the_back_of_an_outer_bump_map() {
    let path = scene_path("bump");
    let text = std::fs::read_to_string(&path).unwrap();
    let from = r#"<bsdf type="twosided">
            <bsdf type="bumpmap">
                <ref id="heights"/>
                <float name="scale" value="0.15"/>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.45, 0.2"/></bsdf>
            </bsdf>
        </bsdf>"#;
    let to = r#"<bsdf type="bumpmap">
            <ref id="heights"/>
            <float name="scale" value="0.15"/>
            <bsdf type="twosided">
                <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.45, 0.2"/></bsdf>
            </bsdf>
        </bsdf>"#;
    let changed = text.replace(from, to);
    assert_ne!(changed, text);
    let loaded = load_scene_str(&changed, &path, &LoadOptions::default()).unwrap();
    let (rel_mse, ratio) = compare(&render(&loaded, 1024), "bump");
    eprintln!("bumpmap outside twosided: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}");
    assert!(
        rel_mse >= MAX_REL_MSE || (ratio - 1.0).abs() >= MAX_MEAN_DEVIATION,
        "bumpmap outside twosided passed: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}"
    );
}

#[test]
fn bspline_curves_match_mitsuba() {
    check("bspline", 1024);
}

/// The B-spline comparison can fail: the same control points read as linear curves
/// (the control polygon instead of the smooth curve) are caught.
#[test]
fn the_bspline_comparison_catches_the_control_polygon() {
    check_caught(
        "bspline",
        r#"<shape type="bsplinecurve">"#,
        r#"<shape type="linearcurve">"#,
        "B-splines as polygons",
    );
}

/// The curve comparison can fail: the wire's radii scaled by its `to_world` (1.6, as an
/// instance transform would scale them; Mitsuba keeps them) is caught.
#[test]
fn the_curve_comparison_catches_scaled_radii() {
    let dir = std::env::temp_dir().join(format!("lightpath-curves-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let wire = scene_path("curves").with_file_name("curves_wire.txt");
    let scaled: String = std::fs::read_to_string(&wire)
        .unwrap()
        .lines()
        .map(|l| {
            let mut v: Vec<f32> = l.split_whitespace().map(|f| f.parse().unwrap()).collect();
            if let Some(r) = v.get_mut(3) {
                *r *= 1.6;
            }
            v.iter().map(f32::to_string).collect::<Vec<_>>().join(" ") + "\n"
        })
        .collect();
    let scaled_path = dir.join("wire.txt");
    std::fs::write(&scaled_path, scaled).unwrap();
    let path = scene_path("curves");
    let text = std::fs::read_to_string(&path).unwrap();
    let changed = text.replace(
        r#"value="curves_wire.txt""#,
        &format!(r#"value="{}""#, scaled_path.display()),
    );
    assert_ne!(changed, text);
    let loaded = load_scene_str(&changed, &path, &LoadOptions::default()).unwrap();
    let (rel_mse, ratio) = compare(&render(&loaded, 1024), "curves");
    std::fs::remove_dir_all(&dir).unwrap();
    eprintln!("curves with scaled radii: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}");
    assert!(
        rel_mse >= MAX_REL_MSE || (ratio - 1.0).abs() >= MAX_MEAN_DEVIATION,
        "curves with scaled radii passed: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}"
    );
}

/// The comparison can fail: the box rendered with a box filter instead of Mitsuba's
/// default Gaussian, the plastics with a one-sided panel made two-sided, and the lights
/// scene with its bitmap read upside down (Mitsuba's v convention undone by a `to_uv`
/// mirror) are all caught.
#[test]
fn the_comparison_catches_a_wrong_convention() {
    for (name, what, from, to, spp) in [
        (
            "box",
            "a box filter",
            r#"<integer name="height" value="$res_y"/>"#,
            r#"<integer name="height" value="$res_y"/><rfilter type="box"/>"#,
            1024,
        ),
        (
            "plastics",
            "the panel seen from behind made two-sided",
            r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.9, 0.9, 0.2"/></bsdf>"#,
            r#"<bsdf type="twosided"><bsdf type="diffuse">
               <rgb name="reflectance" value="0.9, 0.9, 0.2"/></bsdf></bsdf>"#,
            512,
        ),
        (
            "lights",
            "the bitmap mirrored in v",
            r#"<string name="filename" value="stripes.png"/>"#,
            r#"<string name="filename" value="stripes.png"/>
               <transform name="to_uv"><scale y="-1"/></transform>"#,
            512,
        ),
    ] {
        let path = scene_path(name);
        let text = std::fs::read_to_string(&path).unwrap();
        let changed = text.replace(from, to);
        assert_ne!(
            changed, text,
            "{name} with {what}: the scene text did not change"
        );
        let loaded = load_scene_str(&changed, &path, &LoadOptions::default()).unwrap();
        let (rel_mse, ratio) = compare(&render(&loaded, spp), name);
        eprintln!("{name} with {what}: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}");
        assert!(
            rel_mse >= MAX_REL_MSE || (ratio - 1.0).abs() >= MAX_MEAN_DEVIATION,
            "{name} with {what} passed: relMSE {rel_mse:.3e}, mean ratio {ratio:.4}"
        );
    }
}

#[test]
fn principled_matches_mitsuba() {
    check("principled", 2048);
}

/// The principled comparison can fail: the transmissive sphere made opaque, and the
/// thin sheet without its diffuse transmission (dark where the sun shines through), are
/// caught.
/// (The lobes one by one, and the parameters' mapping, are checked value by value in the
/// material and Mitsuba reader tests; each sphere is too small a part of this image for
/// the metric to see, say, its sheen alone.)
#[test]
fn the_principled_comparison_catches_missing_transmission() {
    check_caught(
        "principled",
        r#"<float name="spec_trans" value="0.9"/>"#,
        r#"<float name="spec_trans" value="0"/>"#,
        "an opaque glass",
    );
    check_caught(
        "principled",
        r#"<float name="diff_trans" value="1.2"/>"#,
        r#"<float name="diff_trans" value="0"/>"#,
        "a sheet without diffuse transmission",
    );
}

#[test]
fn float_parameters_from_colour_textures_match_mitsuba() {
    check("scalars", 2048);
}

/// The comparison can fail: the colour stripes read by their red channel rather than
/// their luminance (what a reader taking a texture's first channel sees) are caught.
#[test]
fn the_scalar_comparison_catches_the_first_channel() {
    check_caught(
        "scalars",
        "stripes.png",
        "stripes_red.png",
        "float parameters from the red channel",
    );
}

/// `hide_emitters` (on `path` and `direct`) blacks out what camera rays see of emitters
/// and the environment, and keeps their light in reflections. Pixel values as Mitsuba
/// 3.9.1 renders this scene (box filter): an area light (4) in the centre, the
/// environment (0.5) at the top, and a mirror sphere reflecting the environment (0.5)
/// at the top right.
#[test]
fn hide_emitters_hides_only_what_the_camera_sees_directly() {
    let scene = |integrator: &str, hide: bool| {
        format!(
            r#"<scene version="3.0.0">
            <integrator type="{integrator}"><boolean name="hide_emitters" value="{hide}"/></integrator>
            <sensor type="perspective"><float name="fov" value="60"/>
                <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/>
                    <rfilter type="box"/></film>
            </sensor>
            <emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>
            <shape type="rectangle"><transform name="to_world"><scale x="0.5" y="0.5" z="1"/></transform>
                <emitter type="area"><rgb name="radiance" value="4"/></emitter></shape>
            <shape type="sphere"><point name="center" x="1.3" y="1.3" z="0"/><float name="radius" value="0.4"/>
                <bsdf type="conductor"/></shape>
            </scene>"#
        )
    };
    for integrator in ["path", "direct"] {
        for hide in [false, true] {
            let xml = scene(integrator, hide);
            let loaded =
                load_scene_str(&xml, Path::new("hide.xml"), &LoadOptions::default()).unwrap();
            let image = render(&loaded, 16);
            let at = |x: u32, y: u32| image.get(x, y);
            let (light, env) = if hide { (0.0, 0.0) } else { (4.0, 0.5) };
            for (what, value, expected) in [
                ("light", at(8, 8), light),
                ("environment", at(8, 0), env),
                ("mirror", at(12, 3), 0.5),
            ] {
                assert!(
                    (value - glam::Vec3::splat(expected)).abs().max_element() < 1e-4,
                    "{integrator}, hide_emitters {hide}: {what} {value}, expected {expected}"
                );
            }
        }
    }
}

/// The `filters` scene with its `filter` default set to `filter`.
fn filters_scene(filter: &str) -> LoadedScene {
    let path = scene_path("filters");
    let text = std::fs::read_to_string(&path).unwrap();
    let from = r#"<default name="filter" value="lanczos"/>"#;
    assert!(text.contains(from));
    let text = text.replace(
        from,
        &format!(r#"<default name="filter" value="{filter}"/>"#),
    );
    load_scene_str(&text, &path, &LoadOptions::default()).unwrap()
}

/// The reconstruction filters with negative lobes, each against its own reference
/// (`filters_mitchell`, `filters_lanczos`): weighted samples whose sign follows the lobe,
/// through the steps in which Mitsuba's film applies its filters. Lanczos's weights vary
/// the most (its lobes hold the most negative mass), hence its sample count.
#[test]
fn negative_lobed_filters_match_mitsuba() {
    for (filter, spp) in [("mitchell", 1024), ("lanczos", 4096)] {
        assert_matches(
            &render(&filters_scene(filter), spp),
            &format!("filters_{filter}"),
        );
    }
}

/// The filter comparison can fail: Mitsuba's default Gaussian in place of either filter
/// is caught against both references.
#[test]
fn the_filter_comparison_catches_a_gaussian() {
    let image = render(&filters_scene("gaussian"), 1024);
    for filter in ["mitchell", "lanczos"] {
        let (rel_mse, _) = compare(&image, &format!("filters_{filter}"));
        eprintln!("gaussian against {filter}: relMSE {rel_mse:.3e}");
        assert!(
            rel_mse >= MAX_REL_MSE,
            "a Gaussian passed for {filter}: {rel_mse:.3e}"
        );
    }
}
