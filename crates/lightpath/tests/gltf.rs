//! The glTF loader against the scenes in `tests/gltf/` (written by
//! `tests/gltf/make_scenes.py`): instance placement recomputed here from the file's own
//! node transforms, shared meshes, camera, lights, materials, a render whose emissive
//! pixels equal the emission, the defaults of a file without camera or light, and
//! malformed files that must fail with the file named.

use glam::{Mat4, Quat, UVec2, Vec2, Vec3};
use gltf::json::Value;
use lightpath::camera::{Camera, CameraSample, Perspective};
use lightpath::geometry::Shape;
use lightpath::io::image::srgb_to_linear;
use lightpath::io::{load_scene, LoadOptions, LoadedScene};
use lightpath::light::Light;
use lightpath::material::Material;
use lightpath::render::Renderer;
use lightpath::Error;
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/gltf")
        .join(name)
}

fn load(path: &Path) -> lightpath::Result<LoadedScene> {
    load_scene(path, &LoadOptions::default())
}

/// A node's local matrix composed from the file's numbers (T · R · S or the matrix).
fn local_matrix(node: &gltf::Node) -> Mat4 {
    match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => Mat4::from_cols_array_2d(&matrix),
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            Mat4::from_translation(Vec3::from_array(translation))
                * Mat4::from_quat(Quat::from_array(rotation).normalize())
                * Mat4::from_scale(Vec3::from_array(scale))
        }
    }
}

/// World-space boxes of every mesh node's vertices, depth first, from the file alone.
fn expected_boxes(path: &Path) -> Vec<(String, Vec3, Vec3)> {
    world_matrices(path)
        .into_iter()
        .map(|(name, _, lo, hi)| (name, lo, hi))
        .collect()
}

/// Name, world matrix and world-space box of every mesh primitive's node, depth first,
/// composed here from the file's numbers.
fn world_matrices(path: &Path) -> Vec<(String, Mat4, Vec3, Vec3)> {
    let (doc, buffers, _) = gltf::import(path).unwrap();
    fn visit(
        node: gltf::Node,
        parent: Mat4,
        buffers: &[gltf::buffer::Data],
        out: &mut Vec<(String, Mat4, Vec3, Vec3)>,
    ) {
        let world = parent * local_matrix(&node);
        if let Some(mesh) = node.mesh() {
            for p in mesh.primitives() {
                let reader = p.reader(|b| Some(&buffers[b.index()]));
                let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
                for v in reader.read_positions().unwrap() {
                    let w = world.transform_point3(Vec3::from_array(v));
                    lo = lo.min(w);
                    hi = hi.max(w);
                }
                out.push((node.name().unwrap_or("").to_string(), world, lo, hi));
            }
        }
        for c in node.children() {
            visit(c, world, buffers, out);
        }
    }
    let mut out = Vec::new();
    for node in doc.default_scene().unwrap().nodes() {
        visit(node, Mat4::IDENTITY, &buffers, &mut out);
    }
    out
}

fn check_placement(name: &str) {
    let path = scene_path(name);
    let loaded = load(&path).unwrap();
    let expected = expected_boxes(&path);
    let instances = &loaded.scene.instances;
    assert_eq!(instances.len(), expected.len(), "{name}: instance count");
    assert_eq!(expected.len(), 4);
    for (inst, (node, lo, hi)) in instances.iter().zip(&expected) {
        let err = (inst.bounds.min - *lo)
            .abs()
            .max((inst.bounds.max - *hi).abs())
            .max_element();
        assert!(
            err < 1e-4,
            "{name}: node {node}: box {:?} expected {lo:?}..{hi:?}",
            inst.bounds
        );
    }
    // cubeA and cubeB share the cube mesh: one shape, one BLAS.
    assert!(Arc::ptr_eq(&instances[0].shape, &instances[1].shape));
    let mut distinct: Vec<*const Shape> = instances.iter().map(|i| Arc::as_ptr(&i.shape)).collect();
    distinct.sort();
    distinct.dedup();
    assert_eq!(distinct.len(), 3, "{name}: cube, lamp and floor shapes");
    let Shape::TriangleMesh(cube) = &*instances[0].shape else {
        panic!("not a mesh")
    };
    assert_eq!(cube.triangle_count(), 12);
}

#[test]
fn instances_are_placed_by_the_node_hierarchy() {
    check_placement("hierarchy.gltf");
    check_placement("hierarchy.glb");
}

/// glTF's texture origin is the image's top-left corner: a point in the top-left quarter
/// of the cube's +Z face (glTF uv near (0.25, 0.25)) shows the image's top-left texel.
#[test]
fn texture_coordinates_follow_gltf_orientation() {
    let path = scene_path("hierarchy.gltf");
    let loaded = load(&path).unwrap();
    let (name, world, _, _) = world_matrices(&path).remove(0);
    assert_eq!(name, "cubeA");
    let Some(Material::NormalMap(nm)) = loaded.scene.instances[0].material.as_deref() else {
        panic!("the cube has no normal map")
    };
    let Material::Principled(p) = &*nm.inner else {
        panic!("not principled")
    };
    let texel = |x: f32, y: f32| {
        let target = world.transform_point3(Vec3::new(x, y, 0.5));
        let origin = world.transform_point3(Vec3::new(x, y, 3.0));
        let si = loaded
            .scene
            .intersect(&lightpath::math::Ray::new(origin, target - origin))
            .unwrap();
        assert_eq!(si.instance, 0);
        p.base_color.eval(si.uv)
    };
    let orange = Vec3::new(1.0, srgb_to_linear(128.0 / 255.0), 0.0) * 0.9;
    assert!((texel(-0.25, 0.25) - orange).length() < 1e-5);
    assert!((texel(-0.25, -0.25) - Vec3::new(0.0, 0.0, 0.9)).length() < 1e-5);
    assert!((texel(0.25, 0.25) - Vec3::new(0.0, 0.9, 0.0)).length() < 1e-5);
}

#[test]
fn camera_lights_and_materials() {
    for name in ["hierarchy.gltf", "hierarchy.glb"] {
        let loaded = load(&scene_path(name)).unwrap();
        let scene = &loaded.scene;

        // The camera node: at (0, 1.6, 5), turned −10° about x, looking down its −Z;
        // yfov 0.6 rad, aspect 1.5.
        let camera = scene.camera.as_ref().unwrap();
        assert_eq!(camera.resolution(), UVec2::new(720, 480));
        let ray = |x: f32, y: f32| {
            camera
                .generate_ray(&CameraSample {
                    film: Vec2::new(x, y),
                    lens: Vec2::splat(0.5),
                })
                .unwrap()
        };
        let centre = ray(360.0, 240.0);
        assert!((centre.origin - Vec3::new(0.0, 1.6, 5.0)).length() < 1e-5);
        let forward = Quat::from_axis_angle(Vec3::X, (-10f32).to_radians()) * -Vec3::Z;
        assert!((centre.direction - forward).length() < 1e-5, "{name}");
        let top = ray(360.0, 0.0);
        assert!((top.direction.angle_between(centre.direction) - 0.3).abs() < 1e-4);
        assert!(
            top.direction.y > centre.direction.y,
            "the image's top is +Y"
        );

        // Lights: the point and spot lights, then the lamp's area light; no environment.
        assert_eq!(scene.environment, None);
        assert_eq!(scene.lights.len(), 3);
        let Light::Point(point) = &scene.lights[0] else {
            panic!("{name}: light 0 is not a point light")
        };
        assert!((point.position - Vec3::new(2.0, 4.0, 3.0)).length() < 1e-5);
        assert!((point.intensity - Vec3::splat(30.0)).length() < 1e-4);
        let Light::Spot(spot) = &scene.lights[1] else {
            panic!("{name}: light 1 is not a spot light")
        };
        assert!((spot.position - Vec3::new(-2.0, 3.0, 0.0)).length() < 1e-5);
        assert!((spot.direction - -Vec3::Y).length() < 1e-5);
        assert!((spot.intensity - Vec3::new(20.0, 18.0, 16.0)).length() < 1e-4);
        assert!((spot.cos_falloff_start - 0.3f32.cos()).abs() < 1e-6);
        assert!((spot.cos_cutoff - 0.6f32.cos()).abs() < 1e-6);
        assert!(matches!(scene.lights[2], Light::Area(_)));

        // The cube's material: principled under a normal map; base colour × factor with
        // glTF's v flipped (its top-left texel is (255, 128, 0), sRGB), roughness from G
        // and metallic from B times their factors.
        let Some(Material::NormalMap(nm)) = scene.instances[0].material.as_deref() else {
            panic!("{name}: the cube has no normal map")
        };
        let Material::Principled(p) = &*nm.inner else {
            panic!("{name}: not principled")
        };
        let top_left = p.base_color.eval(Vec2::new(0.25, 1.0 - 0.25));
        let want = Vec3::new(1.0, srgb_to_linear(128.0 / 255.0), 0.0) * 0.9;
        assert!(
            (top_left - want).length() < 1e-5,
            "{top_left:?} vs {want:?}"
        );
        let bottom_left = p.base_color.eval(Vec2::new(0.25, 1.0 - 0.75));
        assert!((bottom_left - Vec3::new(0.0, 0.0, 0.9)).length() < 1e-5);
        let uv = Vec2::splat(0.5);
        assert!((p.roughness.eval(uv).x - 128.0 / 255.0 * 0.6).abs() < 1e-5);
        assert!((p.metallic.eval(uv).x - 64.0 / 255.0 * 0.8).abs() < 1e-5);
        // A flat normal map leaves the shading frame alone.
        assert!((nm.frame(uv.into(), Vec3::Z).n - Vec3::Z).length() < 0.01);

        // Both cubes use material 0: one material, built once.
        let (m0, m1) = (&scene.instances[0].material, &scene.instances[1].material);
        assert!(Arc::ptr_eq(m0.as_ref().unwrap(), m1.as_ref().unwrap()));

        // The lamp: emissive factor × strength.
        let e = scene.instances[2].emission.as_ref().unwrap();
        assert!((e.radiance.eval(uv) - Vec3::new(4.0, 3.2, 2.0)).length() < 1e-5);
        assert!(scene.instances[0].emission.is_none());
    }
}

/// A small render: finite everywhere, black where rays leave the scene, the lit cubes
/// bright, and pixels wholly covered by the emissive quad equal to its emission × strength
/// (within what it reflects, a few per cent).
#[test]
fn renders_the_emission_it_was_given() {
    let loaded = load(&scene_path("hierarchy.glb")).unwrap();
    let scene = &loaded.scene;
    let Some(Camera::Perspective(full)) = &scene.camera else {
        panic!("not perspective")
    };
    let camera = Camera::Perspective(Perspective::new(
        UVec2::new(180, 120),
        0.6f32.to_degrees(),
        lightpath::camera::FovAxis::Y,
        full.render_from_camera,
    ));
    let sampler = loaded.sampler.with_samples_per_pixel(16);
    let renderer = Renderer {
        scene,
        camera: &camera,
        integrator: &loaded.integrator,
        sampler: &sampler,
    };
    let image = renderer.render(&|_| {}).unwrap().0;
    let hit = |x: f32, y: f32| {
        let ray = camera
            .generate_ray(&CameraSample {
                film: Vec2::new(x, y),
                lens: Vec2::splat(0.5),
            })
            .unwrap();
        scene.intersect(&ray).map(|si| si.instance)
    };
    let emission = Vec3::new(4.0, 3.2, 2.0);
    let (mut lamp, mut sky, mut cube) = (0, 0, Vec::new());
    for y in 0..120u32 {
        for x in 0..180u32 {
            let v = image.get(x, y);
            assert!(v.is_finite(), "pixel ({x}, {y}) is {v:?}");
            let (fx, fy) = (x as f32, y as f32);
            let hits: Vec<Option<u32>> =
                [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
                    .iter()
                    .map(|(dx, dy)| hit(fx + dx, fy + dy))
                    .collect();
            if hits.iter().all(|h| *h == Some(2)) {
                lamp += 1;
                let rel = ((v - emission) / emission).abs().max_element();
                assert!(
                    rel < 0.03,
                    "lamp pixel ({x}, {y}) is {v:?}, emission {emission:?}"
                );
            } else if hits.iter().all(|h| h.is_none()) {
                sky += 1;
                assert_eq!(v, Vec3::ZERO, "pixel ({x}, {y}) sees nothing");
            } else if hits.iter().all(|h| *h == Some(0)) {
                cube.push(v);
            }
        }
    }
    assert!(lamp > 50, "only {lamp} pixels wholly on the lamp");
    assert!(sky > 1000, "only {sky} background pixels");
    assert!(cube.len() > 100);
    let mean: Vec3 = cube.iter().copied().sum::<Vec3>() / cube.len() as f32;
    assert!(mean.max_element() > 0.05, "the lit cube is dark: {mean:?}");
}

#[test]
fn defaults_frame_the_scene_and_light_it() {
    let loaded = load(&scene_path("defaults.gltf")).unwrap();
    let scene = &loaded.scene;
    // One quad from (1, 2, 3) to (3, 3, 3), the default material, a uniform environment.
    assert_eq!(scene.instances.len(), 1);
    let b = scene.instances[0].bounds;
    assert!((b.min - Vec3::new(1.0, 2.0, 3.0)).length() < 1e-5);
    assert!((b.max - Vec3::new(3.0, 3.0, 3.0)).length() < 1e-5);
    assert_eq!(scene.lights.len(), 1);
    assert!(matches!(scene.lights[0], Light::Environment(_)));
    assert_eq!(scene.background(Vec3::X), Vec3::ONE);
    let camera = scene.camera.as_ref().unwrap();
    assert_eq!(camera.resolution(), UVec2::new(640, 480));
    let centre = camera
        .generate_ray(&CameraSample {
            film: Vec2::new(320.0, 240.0),
            lens: Vec2::splat(0.5),
        })
        .unwrap();
    let si = scene
        .intersect(&centre)
        .expect("the centre ray hits the quad");
    assert!(
        (si.p - Vec3::new(2.0, 2.5, 3.0)).length() < 1e-3,
        "{:?}",
        si.p
    );
    // The corners of the image see past the quad: it is framed, not cropped.
    for (x, y) in [(0.0, 0.0), (640.0, 0.0), (0.0, 480.0), (640.0, 480.0)] {
        let ray = camera
            .generate_ray(&CameraSample {
                film: Vec2::new(x, y),
                lens: Vec2::splat(0.5),
            })
            .unwrap();
        assert!(scene.intersect(&ray).is_none());
    }
}

/// Alpha modes (`alpha.gltf`): the `MASK` quad over x in [0, 1] is there where its
/// texture's alpha reaches 0.5 (its lower-left and upper-right quarters), the `MASK` quad
/// of constant alpha 0.3 < 0.4 over [1, 2] is not there at all, the `BLEND` quad of alpha
/// 0.3 over [2, 3] is met by 30% of the rays (within four standard deviations), and the
/// quad behind them at z = −1 is reached wherever they are not there: by camera rays and
/// shadow rays alike, through the scene's two-level structure.
#[test]
fn alpha_mask_cuts_the_surface_out() {
    let loaded = load(&scene_path("alpha.gltf")).unwrap();
    let scene = &loaded.scene;
    // The invisible quad is skipped; the other three are instances.
    assert_eq!(scene.instances.len(), 3);
    let mut holes = 0;
    for i in 0..30 {
        for j in 0..10 {
            let (x, y) = (0.05 + 0.1 * i as f32, 0.05 + 0.1 * j as f32);
            if x > 2.0 {
                continue;
            }
            let there = x < 1.0 && (x < 0.5) == (y < 0.5);
            holes += usize::from(!there);
            let ray = lightpath::math::Ray::new(Vec3::new(x, y, 1.0), -Vec3::Z);
            let si = scene
                .intersect(&ray)
                .expect("the back quad is behind everything");
            let t = if there { 1.0 } else { 2.0 };
            assert!((si.t - t).abs() < 1e-5, "({x}, {y}): hit at t = {}", si.t);
            let mut shadow = ray;
            shadow.t_max = 1.5;
            assert_eq!(scene.occluded(&shadow), there, "({x}, {y}): shadow ray");
        }
    }
    assert_eq!(holes, 150);
    let n = 10_000;
    let mut met = 0;
    for i in 0..n {
        // Rays of many origins and directions through the blend quad.
        let (u, v) = ((i % 100) as f32 / 100.0, (i / 100) as f32 / 100.0);
        let (a, b) = ((i as f32 * 0.618).fract(), (i as f32 * 0.414).fract());
        let origin = Vec3::new(2.2 + 0.6 * u, 0.2 + 0.6 * v, 1.0);
        let direction = Vec3::new(0.1 * (a - 0.5), 0.1 * (b - 0.5), -1.0);
        let ray = lightpath::math::Ray::new(origin, direction);
        let si = scene
            .intersect(&ray)
            .expect("the back quad is behind everything");
        let there = (si.t - 1.0).abs() < 1e-4;
        assert!(there || (si.t - 2.0).abs() < 1e-4, "t = {}", si.t);
        met += usize::from(there);
        let mut shadow = ray;
        shadow.t_max = 1.5;
        assert_eq!(scene.occluded(&shadow), there, "ray {i}: the same answer");
    }
    let fraction = met as f64 / n as f64;
    assert!(
        (fraction - 0.3).abs() < 4.0 * (0.21f64 / n as f64).sqrt(),
        "{fraction}"
    );
}

/// A scratch folder for broken copies of the scenes.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightpath-gltf-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn json_of(name: &str) -> Value {
    let text = std::fs::read_to_string(scene_path(name)).unwrap();
    gltf::json::deserialize::from_str(&text).unwrap()
}

/// Writes `doc` as `file` in a scratch folder, with `hierarchy.bin` and `normal.png`
/// beside it unless `without` names one of them.
fn write_scene(dir: &Path, file: &str, doc: &Value, without: &[&str]) -> PathBuf {
    for extra in ["hierarchy.bin", "normal.png"] {
        if !without.contains(&extra) {
            std::fs::copy(scene_path(extra), dir.join(extra)).unwrap();
        }
    }
    let path = dir.join(file);
    std::fs::write(&path, gltf::json::serialize::to_string_pretty(doc).unwrap()).unwrap();
    path
}

/// Loading fails, without panicking, with a message that names the file and contains
/// `needle`.
fn fails(path: &Path, needle: &str) -> Error {
    let result = std::panic::catch_unwind(|| load(path));
    let err = match result {
        Ok(Ok(_)) => panic!("{} loaded", path.display()),
        Ok(Err(e)) => e,
        Err(_) => panic!("{} panicked", path.display()),
    };
    let text = err.to_string();
    let file = path.file_name().unwrap().to_string_lossy().into_owned();
    assert!(text.contains(&file), "`{text}` does not name {file}");
    assert!(text.contains(needle), "`{text}` does not say `{needle}`");
    err
}

#[test]
fn truncated_json_names_file_line_and_column() {
    let dir = scratch("truncated");
    let text = std::fs::read_to_string(scene_path("hierarchy.gltf")).unwrap();
    let path = dir.join("truncated.gltf");
    std::fs::write(&path, &text[..text.len() / 2]).unwrap();
    let err = fails(&path, "malformed glTF JSON");
    let Error::Scene { location, .. } = err else {
        panic!("not a scene error: {err}")
    };
    assert!(location.line > 1, "no line number: {location}");

    // A broken GLB container.
    let glb = std::fs::read(scene_path("hierarchy.glb")).unwrap();
    let path = dir.join("truncated.glb");
    std::fs::write(&path, &glb[..glb.len() / 2]).unwrap();
    fails(&path, "GLB");
}

#[test]
fn missing_buffer_file_is_named() {
    let dir = scratch("missing");
    let path = write_scene(
        &dir,
        "missing.gltf",
        &json_of("hierarchy.gltf"),
        &["hierarchy.bin"],
    );
    fails(&path, "hierarchy.bin");
    let path = write_scene(
        &dir,
        "no-image.gltf",
        &json_of("hierarchy.gltf"),
        &["normal.png"],
    );
    std::fs::remove_file(dir.join("normal.png")).ok();
    fails(&path, "normal.png");
}

#[test]
fn accessor_out_of_range_is_an_error() {
    let dir = scratch("range");
    let mut doc = json_of("hierarchy.gltf");
    doc["accessors"][0]["count"] = 1000.into();
    let path = write_scene(&dir, "range.gltf", &doc, &[]);
    fails(&path, "accessor 0");
    // A buffer view past the end of its buffer.
    let mut doc = json_of("hierarchy.gltf");
    doc["bufferViews"][1]["byteOffset"] = 100_000.into();
    let path = write_scene(&dir, "view.gltf", &doc, &[]);
    fails(&path, "buffer view 1");
    // An index past the last vertex.
    // The floor's POSITION (accessor 4) cut to 2 vertices; its indices reach vertex 3.
    let mut doc = json_of("hierarchy.gltf");
    assert_eq!(
        doc["meshes"][1]["primitives"][0]["attributes"]["POSITION"],
        4
    );
    doc["accessors"][4]["count"] = 2.into();
    let path = write_scene(&dir, "index.gltf", &doc, &[]);
    fails(&path, "out of range");
}

#[test]
fn nan_positions_are_an_error() {
    let dir = scratch("nan");
    let mut bin = std::fs::read(scene_path("hierarchy.bin")).unwrap();
    let doc = json_of("hierarchy.gltf");
    // The cube's POSITION accessor 0 reads buffer view 0 from its start.
    assert_eq!(doc["accessors"][0]["bufferView"], 0);
    assert_eq!(doc["bufferViews"][0]["byteOffset"], 0);
    bin[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    let path = write_scene(&dir, "nan.gltf", &doc, &["hierarchy.bin"]);
    std::fs::write(dir.join("hierarchy.bin"), bin).unwrap();
    fails(&path, "not finite");
}

#[test]
fn unsupported_things_fail_or_are_skipped() {
    let dir = scratch("unsupported");
    let mut doc = json_of("hierarchy.gltf");
    doc["extensionsRequired"] = Value::Array(vec!["KHR_draco_mesh_compression".into()]);
    let path = write_scene(&dir, "draco.gltf", &doc, &[]);
    fails(&path, "KHR_draco_mesh_compression");
    // A primitive of lines is skipped: the floor is gone.
    let mut doc = json_of("hierarchy.gltf");
    doc["meshes"][1]["primitives"][0]["mode"] = 1.into();
    let path = write_scene(&dir, "lines.gltf", &doc, &[]);
    assert_eq!(load(&path).unwrap().scene.instances.len(), 3);
    // A reference to a node that does not exist (the gltf crate's validation).
    let mut doc = json_of("hierarchy.gltf");
    doc["scenes"][0]["nodes"][0] = 99.into();
    let path = write_scene(&dir, "dangling.gltf", &doc, &[]);
    fails(&path, "invalid glTF");
}

/// `COLOR_0` multiplies the base colour: a triangle with normalized 8-bit RGBA vertex
/// colours (linear, alpha not read) and one without them, both of the same material,
/// seen through rays at known barycentrics.
#[test]
fn vertex_colours_multiply_the_base_colour() {
    let dir = scratch("colors");
    let mut bin: Vec<u8> = Vec::new();
    // Two triangles' positions (f32 x 3 each, the second one behind the first at z = -1,
    // shifted right), then the first one's colours (u8 x 4).
    let corners = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    for c in corners {
        bin.extend(c.iter().flat_map(|x| x.to_le_bytes()));
    }
    for c in corners {
        bin.extend(
            [c[0] + 2.0, c[1], -1.0]
                .iter()
                .flat_map(|x| x.to_le_bytes()),
        );
    }
    for rgba in [[255u8, 0, 0, 255], [0, 255, 0, 0], [0, 0, 255, 128]] {
        bin.extend(rgba);
    }
    std::fs::write(dir.join("colors.bin"), &bin).unwrap();
    let doc = parse_json(&format!(
        r#"{{
        "asset": {{"version": "2.0"}},
        "scene": 0,
        "scenes": [{{"nodes": [0]}}],
        "nodes": [{{"mesh": 0}}],
        "meshes": [{{"primitives": [
            {{"attributes": {{"POSITION": 0, "COLOR_0": 2}}, "material": 0}},
            {{"attributes": {{"POSITION": 1}}, "material": 0}}
        ]}}],
        "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.8, 1.0, 1.0]}}}}],
        "buffers": [{{"uri": "colors.bin", "byteLength": {}}}],
        "bufferViews": [
            {{"buffer": 0, "byteOffset": 0, "byteLength": 72}},
            {{"buffer": 0, "byteOffset": 72, "byteLength": 12}}
        ],
        "accessors": [
            {{"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0, 0, 0], "max": [1, 1, 0]}},
            {{"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [2, 0, -1], "max": [3, 1, -1]}},
            {{"bufferView": 1, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC4"}}
        ]
    }}"#,
        bin.len()
    ));
    let path = write_scene(&dir, "colors.gltf", &doc, &["hierarchy.bin", "normal.png"]);
    let loaded = load(&path).unwrap();
    let scene = &loaded.scene;
    let factor = Vec3::new(0.5, 0.8, 1.0);
    let albedo_at = |x: f32, y: f32, z: f32| {
        let ray = lightpath::math::Ray::new(Vec3::new(x, y, z + 5.0), -Vec3::Z);
        let si = scene.intersect(&ray).expect("the ray hits");
        scene.material(&si).unwrap().albedo(si.tex())
    };
    // At barycentrics (0.2, 0.3, 0.5) of the coloured triangle: red 0.2, green 0.3,
    // blue 0.5.
    let got = albedo_at(0.3, 0.5, 0.0);
    let want = factor * Vec3::new(0.2, 0.3, 0.5);
    assert!(
        (got - want).abs().max_element() < 1e-5,
        "{got} against {want}"
    );
    // The uncoloured triangle of the same material: the factor alone.
    let got = albedo_at(2.3, 0.5, -1.0);
    assert!(
        (got - factor).abs().max_element() < 1e-6,
        "{got} against {factor}"
    );
}

fn parse_json(text: &str) -> Value {
    gltf::json::deserialize::from_str(text).unwrap()
}
