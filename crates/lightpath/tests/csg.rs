//! CSG in whole renders: normals against an analytic image, the silhouette against
//! POV-Ray, and furnace tests of the path tracer through CSG glass and diffuse solids.

use glam::{DMat3, DVec3, Vec2, Vec3};
use lightpath::camera::CameraSample;
use lightpath::film::Image;
use lightpath::io::image::{read_image, Transfer};
use lightpath::io::{load_scene, load_scene_str, LoadOptions, LoadedScene};
use lightpath::render::Renderer;
use std::path::{Path, PathBuf};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn render(loaded: &LoadedScene) -> Image {
    let renderer = Renderer {
        scene: &loaded.scene,
        camera: loaded.scene.camera.as_ref().unwrap(),
        integrator: &loaded.integrator,
        sampler: &loaded.sampler,
    };
    renderer.render(&|_| {}).unwrap().0
}

fn render_str(xml: &str) -> Image {
    render(&load_scene_str(xml, Path::new("test.xml"), &LoadOptions::default()).unwrap())
}

// ---------------------------------------------------------------------------------------
// tests/csg/sphere_minus_cube.xml, analytically (float64, independent of lightpath)

/// Right-handed rotation about a unit axis (Rodrigues).
fn rotation(axis: DVec3, degrees: f64) -> DMat3 {
    let (s, c) = degrees.to_radians().sin_cos();
    let k = DMat3::from_cols(
        DVec3::new(0.0, axis.z, -axis.y),
        DVec3::new(-axis.z, 0.0, axis.x),
        DVec3::new(axis.y, -axis.x, 0.0),
    );
    DMat3::IDENTITY * c
        + k * s
        + DMat3::from_cols(axis * axis.x, axis * axis.y, axis * axis.z) * (1.0 - c)
}

/// What a camera ray through raster point `film` sees in sphere_minus_cube.xml: the
/// surface (0 the sphere, 1 + face for the cube's faces, -1 nothing) and its normal.
fn sphere_minus_cube(film: (f64, f64)) -> (i32, DVec3) {
    const W: f64 = 320.0;
    const H: f64 = 240.0;
    let t = 20f64.to_radians().tan();
    let (nx, ny) = (2.0 * film.0 / W - 1.0, 2.0 * film.1 / H - 1.0);
    let d = DVec3::new(nx * t, ny * t * H / W, 1.0).normalize();
    // The instance: rotate y 25°, then x -20°, then translate z 4.
    let r = rotation(DVec3::X, -20.0) * rotation(DVec3::Y, 25.0);
    let (o, d) = (
        r.transpose() * -DVec3::new(0.0, 0.0, 4.0),
        r.transpose() * d,
    );
    // The sphere's chord.
    let (b, c) = (o.dot(d), o.length_squared() - 1.0);
    let disc = b * b - c;
    if disc < 0.0 {
        return (-1, DVec3::ZERO);
    }
    let (s0, s1) = (-b - disc.sqrt(), -b + disc.sqrt());
    // The cube's: [-1, 1]³ scaled 0.6 around (0.7, -0.7, -0.3).
    let centre = DVec3::new(0.7, -0.7, -0.3);
    let (co, cd) = ((o - centre) / 0.6, d / 0.6);
    let (mut c0, mut c1, mut exit_face) = (f64::NEG_INFINITY, f64::INFINITY, 0);
    for axis in 0..3 {
        let (ta, tb) = ((-1.0 - co[axis]) / cd[axis], (1.0 - co[axis]) / cd[axis]);
        c0 = c0.max(ta.min(tb));
        if ta.max(tb) < c1 {
            c1 = ta.max(tb);
            exit_face = axis as i32 * 2 + (cd[axis] > 0.0) as i32;
        }
    }
    let sphere = |t: f64| (0, r * (o + d * t));
    if c0 >= c1 || c1 <= s0 || c0 >= s1 || c0 > s0 {
        return sphere(s0); // the cube misses the sphere's chord or starts inside it
    }
    if c1 >= s1 {
        return (-1, DVec3::ZERO); // the cube covers the whole chord
    }
    // The cube's exit face, seen from inside the hole: its normal flipped.
    let mut n = DVec3::ZERO;
    n[(exit_face / 2) as usize] = if exit_face % 2 == 1 { 1.0 } else { -1.0 };
    (1 + exit_face, r * -n)
}

fn scene_file() -> PathBuf {
    repo_root().join("tests/csg/sphere_minus_cube.xml")
}

/// The `normals` AOV of sphere_minus_cube.xml (16 random samples per pixel) against the
/// analytic image: per pixel, the mean of (n + 1) / 2 over a 4×4 grid, compared where a
/// 6×6 grid over the pixel widened by half a pixel on every side sees one surface only
/// (so pixels within half a pixel of a silhouette or an edge are skipped). Tolerance:
/// 0.01 per channel and pixel (the normal changes by about 0.005 across a pixel), mean
/// absolute error 1e-3.
#[test]
fn normals_match_the_analytic_image() {
    let loaded = load_scene(&scene_file(), &LoadOptions::default()).unwrap();
    let img = render(&loaded);
    assert_eq!((img.width, img.height), (320, 240));
    let (mut compared, mut skipped, mut sum, mut worst) = (0usize, 0usize, 0.0f64, 0.0f64);
    let mut per_surface = [0usize; 8];
    for y in 0..img.height {
        for x in 0..img.width {
            let (px, py) = (x as f64, y as f64);
            let id = sphere_minus_cube((px + 0.5, py + 0.5)).0;
            let clean = (0..36).all(|k| {
                let (i, j) = ((k % 6) as f64, (k / 6) as f64);
                let film = (
                    px - 0.5 + 2.0 * (i + 0.5) / 6.0,
                    py - 0.5 + 2.0 * (j + 0.5) / 6.0,
                );
                sphere_minus_cube(film).0 == id
            });
            if !clean {
                skipped += 1;
                continue;
            }
            let mut expected = DVec3::ZERO;
            for k in 0..16 {
                let (i, j) = ((k % 4) as f64, (k / 4) as f64);
                let (s, n) = sphere_minus_cube((px + (i + 0.5) / 4.0, py + (j + 0.5) / 4.0));
                expected += if s < 0 {
                    DVec3::splat(0.5)
                } else {
                    (n + DVec3::ONE) * 0.5
                } / 16.0;
            }
            let got = img.get(x, y).as_dvec3();
            let err = (got - expected).abs().max_element();
            worst = worst.max(err);
            sum += (got - expected).abs().element_sum() / 3.0;
            compared += 1;
            per_surface[(id + 1) as usize] += 1;
            assert!(
                err < 0.01,
                "pixel ({x}, {y}) on surface {id}: {got} vs {expected}"
            );
        }
    }
    let mae = sum / compared as f64;
    eprintln!("compared {compared} pixels, skipped {skipped} near edges; MAE {mae:.2e}, worst {worst:.2e}; per surface {per_surface:?}");
    assert!(mae < 1e-3, "MAE {mae}");
    assert!(compared > 70_000, "only {compared} pixels compared");
    // The sphere and at least two cut faces are in view and were compared.
    assert!(per_surface[1] > 20_000, "{per_surface:?}");
    assert!(
        per_surface[2..].iter().filter(|&&n| n > 300).count() >= 2,
        "{per_surface:?}"
    );
}

fn mask_of(loaded: &LoadedScene) -> Vec<bool> {
    let camera = loaded.scene.camera.as_ref().unwrap();
    let res = camera.resolution();
    let mut mask = Vec::new();
    for y in 0..res.y {
        for x in 0..res.x {
            let ray = camera
                .generate_ray(&CameraSample {
                    film: Vec2::new(x as f32 + 0.5, y as f32 + 0.5),
                    lens: Vec2::splat(0.5),
                })
                .unwrap();
            mask.push(loaded.scene.intersect(&ray).is_some());
        }
    }
    mask
}

/// Our silhouette of sphere_minus_cube.xml (one ray through each pixel centre: object or
/// background) against POV-Ray 3.7's render of the same scene
/// (tests/csg/sphere_minus_cube.pov; the command and the coordinate conventions are in
/// that file; the PNG was made with `povray` from Debian). At least 99.5% of the pixels
/// must agree. The same scene with a union in place of the difference agrees on clearly
/// fewer, so the limit can tell a wrong operator.
#[test]
fn silhouette_matches_povray() {
    let reference = read_image(
        &repo_root().join("tests/csg/sphere_minus_cube_mask.png"),
        Some(Transfer::Linear),
    )
    .unwrap();
    let pov: Vec<bool> = reference.pixels.iter().map(|p| p.x > 0.5).collect();
    let agreement = |mask: &[bool]| {
        assert_eq!(mask.len(), pov.len());
        mask.iter().zip(&pov).filter(|(a, b)| a == b).count() as f64 / mask.len() as f64
    };
    let text = std::fs::read_to_string(scene_file()).unwrap();
    let loaded = load_scene_str(&text, &scene_file(), &LoadOptions::default()).unwrap();
    let ours = agreement(&mask_of(&loaded));
    let covered = pov.iter().filter(|&&b| b).count();
    let union = text.replace(
        r#"<shape type="csg" op="difference">"#,
        r#"<shape type="csg" op="union">"#,
    );
    let loaded = load_scene_str(&union, &scene_file(), &LoadOptions::default()).unwrap();
    let with_union = agreement(&mask_of(&loaded));
    eprintln!(
        "POV-Ray mask ({covered} object pixels): {:.3}% of pixels agree; a union instead: {:.3}%",
        100.0 * ours,
        100.0 * with_union
    );
    assert!(ours >= 0.995, "only {:.3}% agree", 100.0 * ours);
    assert!(
        with_union < 0.98,
        "the test cannot tell: {:.3}%",
        100.0 * with_union
    );
}

// ---------------------------------------------------------------------------------------
// Light transport

fn mean_and_worst(img: &Image, expected: f32) -> (f64, f32) {
    let mut sum = 0.0f64;
    let mut worst = 0.0f32;
    for p in &img.pixels {
        for c in 0..3 {
            sum += p[c] as f64;
            worst = worst.max((p[c] - expected).abs());
        }
    }
    (sum / (3 * img.pixels.len()) as f64, worst)
}

const GLASS: &str = r#"<bsdf type="dielectric"><float name="ior" value="1.5"/></bsdf>"#;

/// Three CSG glass objects: a lens (two spheres intersected), a sphere with a cube cut
/// out, and the lens with a cylindrical hole drilled along the view (a depth-2 tree).
fn glass_objects(bsdf: &str) -> String {
    format!(
        r#"
        <instance>
            <shape type="csg" op="intersection">
                <shape type="sphere"><transform><scale value="1.6"/><translate z="1.3"/></transform></shape>
                <shape type="sphere"><transform><scale value="1.6"/><translate z="-1.3"/></transform></shape>
            </shape>
            {bsdf}
            <transform><rotate axis="0,1,0" angle="30"/><translate x="-1.3" y="-0.5" z="6"/></transform>
        </instance>
        <instance>
            <shape type="csg" op="difference">
                <shape type="sphere"/>
                <shape type="cube"><transform><scale value="0.6"/><translate x="0.6" y="-0.5" z="-0.5"/></transform></shape>
            </shape>
            {bsdf}
            <transform><scale value="0.9"/><translate x="1.2" y="-0.4" z="5"/></transform>
        </instance>
        <instance>
            <shape type="csg" op="difference">
                <shape type="csg" op="intersection">
                    <shape type="sphere"><transform><scale value="1.6"/><translate z="1.3"/></transform></shape>
                    <shape type="sphere"><transform><scale value="1.6"/><translate z="-1.3"/></transform></shape>
                </shape>
                <shape type="cylinder"><transform><scale x="0.3" y="0.3" z="4"/><translate z="-2"/></transform></shape>
            </shape>
            {bsdf}
            <transform><rotate axis="1,0,0" angle="20"/><translate x="0.2" y="1.1" z="6"/></transform>
        </instance>"#
    )
}

/// White furnace through glass: a dielectric (index 1.5, no absorption) under a uniform
/// environment of 1. Every refraction into the glass weighs a path by 1/η² and the
/// refraction out by η², so a path that leaves every solid it enters carries exactly 1,
/// and the image is 1 up to Russian roulette. Light leaking through a missing cut face,
/// or a cut face whose normal points the wrong way (the dielectric then takes an exit
/// for an entry), weighs paths by 2.25 or 0.44 and shows at once. Russian roulette
/// (from vertex 64 on, weights 1/0.95 per vertex) only ends paths trapped by total
/// internal reflection, which the sphere with a cube corner cut out can hold for long:
/// a handful of pixels. So: mean within 2e-4 of 1, at most 1% of the pixels off by more
/// than 1e-3, none by 0.2.
#[test]
fn glass_furnace_leaks_no_light() {
    let xml = format!(
        r#"<integrator type="pathtracer" depth="-1" rrDepth="64"><scene>
        <camera type="perspective"><integer name="width" value="64"/><integer name="height" value="48"/>
            <float name="fov" value="45"/></camera>
        <light type="envmap"><texture type="constant" value="1"/></light>
        {}
    </scene><sampler type="independent" count="64"/></integrator>"#,
        glass_objects(GLASS)
    );
    let img = render_str(&xml);
    let (mean, worst) = mean_and_worst(&img, 1.0);
    let off = img
        .pixels
        .iter()
        .filter(|p| (**p - Vec3::ONE).abs().max_element() > 1e-3)
        .count();
    eprintln!("glass furnace: mean {mean}, worst pixel off by {worst}, {off} pixels off by more than 1e-3");
    assert!((mean - 1.0).abs() < 2e-4, "mean {mean}");
    assert!(
        off * 100 <= img.pixels.len(),
        "{off} pixels off by more than 1e-3"
    );
    assert!(worst < 0.2, "worst pixel off by {worst}");
}

/// A dielectric of index 1 bends nothing and reflects nothing: the CSG glass objects are
/// invisible in front of a checkered environment, pixel for pixel (same samples, same
/// camera rays, with and without them). Paths through them must never be lost (stuck on
/// their own surface, or absorbed).
#[test]
fn index_one_glass_shows_the_environment_exactly() {
    let scene = |objects: &str| {
        format!(
            r#"<integrator type="pathtracer" depth="-1" rrDepth="64"><scene>
            <camera type="perspective"><integer name="width" value="64"/><integer name="height" value="48"/>
                <float name="fov" value="45"/></camera>
            <light type="envmap"><texture type="checkerboard" scale="24,12" color0="0.1,0.2,0.3" color1="1,0.8,0.5"/></light>
            {objects}
        </scene><sampler type="independent" count="16"/></integrator>"#
        )
    };
    let index_one = r#"<bsdf type="dielectric"><float name="ior" value="1"/></bsdf>"#;
    let with = render_str(&scene(&glass_objects(index_one)));
    let without = render_str(&scene(""));
    let mut worst = 0.0f32;
    for (a, b) in with.pixels.iter().zip(&without.pixels) {
        worst = worst.max((*a - *b).abs().max_element());
    }
    eprintln!("index-1 glass: worst pixel off by {worst}");
    assert!(worst < 1e-4, "worst pixel off by {worst}");
}

/// White furnace with diffuse CSG solids (albedo 1, each operand with its own `<bsdf>`,
/// the instance with none, so every hit must find its leaf's material): a sphere with a
/// cube cut out, united with a cylinder, under a uniform environment of 1, renders 1.
#[test]
fn diffuse_furnace() {
    let white = r#"<bsdf type="diffuse"><texture name="albedo" type="constant" value="1"/></bsdf>"#;
    let xml = format!(
        r#"<integrator type="pathtracer" depth="-1"><scene>
        <camera type="perspective"><integer name="width" value="32"/><integer name="height" value="32"/>
            <float name="fov" value="40"/></camera>
        <light type="envmap"><texture type="constant" value="1"/></light>
        <instance>
            <shape type="csg" op="union">
                <shape type="csg" op="difference">
                    <shape type="sphere">{white}</shape>
                    <shape type="cube">{white}<transform><scale value="0.6"/><translate x="0.5" y="-0.5" z="-0.5"/></transform></shape>
                </shape>
                <shape type="cylinder">{white}<transform><scale x="0.3" y="0.3" z="3"/><rotate axis="0,1,0" angle="90"/><translate x="-1.5" y="0.4"/></transform></shape>
            </shape>
            <transform><rotate axis="0,1,0" angle="20"/><translate z="4"/></transform>
        </instance>
    </scene><sampler type="sobol" count="1024"/></integrator>"#
    );
    let img = render_str(&xml);
    let (mean, worst) = mean_and_worst(&img, 1.0);
    eprintln!("diffuse furnace: mean {mean}, worst pixel off by {worst}");
    assert!((mean - 1.0).abs() < 2e-3, "mean {mean}");
    assert!(worst < 0.03, "worst pixel off by {worst}");
}

/// A closed shell made by CSG (a box united with a sphere, minus a smaller sphere united
/// with a cylinder: every inner wall is a cut face) around the camera, under a bright
/// environment and a point light outside: no light gets in, the image is black. Light
/// through a missing cut face, or a shadow ray slipping through the shell, shows.
#[test]
fn closed_shell_lets_no_light_in() {
    let xml = r#"<integrator type="pathtracer" depth="6"><scene>
        <camera type="perspective"><integer name="width" value="32"/><integer name="height" value="32"/>
            <float name="fov" value="100"/><transform><rotate axis="1,1,0" angle="30"/></transform></camera>
        <light type="envmap"><texture type="constant" value="5"/></light>
        <light type="point" position="0.5,9,0.2" intensity="1000"/>
        <instance>
            <shape type="csg" op="difference">
                <shape type="csg" op="union">
                    <shape type="cube"><transform><scale value="3"/></transform></shape>
                    <shape type="sphere"><transform><scale value="3.6"/><translate y="1"/></transform></shape>
                </shape>
                <shape type="csg" op="union">
                    <shape type="sphere"><transform><scale value="2.5"/></transform></shape>
                    <shape type="cylinder"><transform><scale x="1" y="1" z="5.4"/><translate z="-2.7"/></transform></shape>
                </shape>
            </shape>
            <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.9"/></bsdf>
        </instance>
    </scene><sampler type="independent" count="64"/></integrator>"#;
    let img = render_str(xml);
    let brightest = img
        .pixels
        .iter()
        .fold(0.0f32, |m, p: &Vec3| m.max(p.max_element()));
    assert_eq!(
        brightest, 0.0,
        "light leaked in: brightest pixel {brightest}"
    );
    // The same shell with a window cut through it lets light in: the test can see leaks.
    let window = xml.replace(
        r#"<transform><scale x="1" y="1" z="5.4"/><translate z="-2.7"/></transform>"#,
        r#"<transform><scale x="1" y="1" z="9"/><translate z="-2.7"/></transform>"#,
    );
    let img = render_str(&window);
    let (mean, _) = mean_and_worst(&img, 0.0);
    assert!(mean > 0.1, "the window lets in only {mean}");
}
