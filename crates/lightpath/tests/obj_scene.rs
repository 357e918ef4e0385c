//! OBJ files as scenes: MTL materials, textures, emitters, the default camera and light,
//! and errors that name the file and line.

use lightpath::camera::CameraSample;
use lightpath::io::{load_scene, LoadOptions, LoadedScene};
use lightpath::light::Light;
use lightpath::material::Material;
use lightpath::math::Vec2;
use lightpath::render::Renderer;
use lightpath::sampling::{IndependentSampler, Sampler};
use lightpath::texture::Texture;
use std::path::{Path, PathBuf};

fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/obj")
        .join(name)
}

/// A scratch folder, removed on drop.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!("lightpath-obj-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    fn write(&self, name: &str, text: &str) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn load(path: &Path) -> lightpath::Result<LoadedScene> {
    load_scene(path, &LoadOptions::default())
}

/// Which instance, and where in uv, the camera sees over the whole of pixel (x, y):
/// `None` if the pixel's corners and centre do not all see the same instance.
fn pixel_sees(loaded: &LoadedScene, x: u32, y: u32) -> Option<(u32, Vec<Vec2>)> {
    let camera = loaded.scene.camera.as_ref().unwrap();
    let mut instance = None;
    let mut uvs = Vec::new();
    for (dx, dy) in [
        (0.0, 0.0),
        (0.999, 0.0),
        (0.0, 0.999),
        (0.999, 0.999),
        (0.5, 0.5),
    ] {
        let film = Vec2::new(x as f32 + dx, y as f32 + dy);
        let ray = camera.generate_ray(&CameraSample {
            film,
            lens: Vec2::splat(0.5),
        })?;
        let si = loaded.scene.intersect(&ray)?;
        if *instance.get_or_insert(si.instance) != si.instance {
            return None;
        }
        uvs.push(si.uv);
    }
    Some((instance?, uvs))
}

/// The shipped OBJ: an emissive material (a panel facing the camera and a strip lighting
/// the other shape) and a textured diffuse quad, red on its left half and blue on its
/// right. Emitting pixels equal `Ke` exactly; the texture's halves show their hues.
#[test]
fn shipped_obj_renders_with_its_materials() {
    let loaded = load(&shipped("two_materials.obj")).expect("load");
    let scene = &loaded.scene;
    // One instance per material, in order of first use.
    assert_eq!(scene.instances.len(), 2);
    let glow = &scene.instances[0];
    let textured = &scene.instances[1];
    assert!(glow.emission.is_some());
    assert!(textured.emission.is_none());
    assert!(matches!(
        textured.material.as_deref(),
        Some(Material::Diffuse(d)) if matches!(*d.albedo, Texture::Image(_))
    ));
    // The emitter is the only light: no environment is added.
    assert!(scene.environment.is_none());
    assert_eq!(scene.lights.len(), 1);
    assert!(matches!(scene.lights[0], Light::Area(_)));

    let sampler = Sampler::Independent(IndependentSampler::new(4, 7));
    let renderer = Renderer {
        scene,
        camera: scene.camera.as_ref().unwrap(),
        integrator: &loaded.integrator,
        sampler: &sampler,
    };
    let (image, _) = renderer.render(&|_| {}).expect("render");

    let (mut glowing, mut red, mut blue) = (0, Vec::new(), Vec::new());
    for y in 0..image.height {
        for x in 0..image.width {
            let Some((instance, uvs)) = pixel_sees(&loaded, x, y) else {
                continue;
            };
            let value = image.get(x, y);
            if instance == 0 {
                assert_eq!(
                    value,
                    lightpath::math::Vec3::new(4.0, 2.0, 1.0),
                    "({x}, {y})"
                );
                glowing += 1;
            } else if uvs.iter().all(|uv| (0.13..0.37).contains(&uv.x)) {
                red.push(value);
            } else if uvs.iter().all(|uv| (0.63..0.87).contains(&uv.x)) {
                blue.push(value);
            }
        }
    }
    assert!(glowing > 5000, "{glowing} emitting pixels");
    assert!(
        red.len() > 2000 && blue.len() > 2000,
        "{} {}",
        red.len(),
        blue.len()
    );
    let mean = |v: &[lightpath::math::Vec3]| {
        v.iter().copied().sum::<lightpath::math::Vec3>() / v.len() as f32
    };
    let (r, b) = (mean(&red), mean(&blue));
    assert!(r.x > 4.0 * r.z && r.x > 0.05, "red half {r}");
    assert!(b.z > 4.0 * b.x && b.z > 0.05, "blue half {b}");
    // The texture's hue, (200, 30, 20) and (20, 40, 210) sRGB, times the light's
    // colour Ke = (4, 2, 1): the only light reaching the quad comes straight from it.
    let srgb = |c: f32| lightpath::io::image::srgb_to_linear(c / 255.0);
    let expect_red = (srgb(20.0) * 1.0) / (srgb(200.0) * 4.0);
    assert!((r.z / r.x / expect_red - 1.0).abs() < 0.05, "{r}");
    let expect_blue = (srgb(20.0) * 4.0) / (srgb(210.0) * 1.0);
    assert!((b.x / b.z / expect_blue - 1.0).abs() < 0.05, "{b}");
    let visible = red
        .iter()
        .chain(&blue)
        .filter(|v| v.max_element() > 0.0)
        .count();
    assert!(
        visible * 10 > (red.len() + blue.len()) * 9,
        "the quad is lit"
    );
}

/// MTL statements map to materials as documented in `io::obj::load_scene`; an OBJ with no
/// emitter gets a constant environment and a camera framing it.
#[test]
fn mtl_mapping_and_default_light() {
    let dir = Scratch::new("mapping");
    dir.write(
        "lib.mtl",
        "newmtl glossy\nKd 0.2 0.4 0.6\nKs 0.5 0.5 0.5\nNs 98\nillum 2\n\
         newmtl glass\nKd 1 1 1\nNi 1.33\nillum 7\n\
         newmtl faded\nKd 0.5 0.5 0.5\nd 0.5\n\
         newmtl matte\nKd 0.3 0.3 0.3\nKs 0.9 0.9 0.9\nillum 1\n",
    );
    let mut obj = String::from("mtllib lib.mtl\n");
    for (i, name) in ["glossy", "glass", "faded", "matte", "unknown"]
        .iter()
        .enumerate()
    {
        let x = i as f32 * 2.0;
        obj += &format!(
            "v {x} 0 0\nv {} 0 0\nv {x} 1 0\nusemtl {name}\nf -3 -2 -1\n",
            x + 1.0
        );
    }
    let loaded = load(&dir.write("m.obj", &obj)).expect("load");
    let kinds: Vec<&Material> = loaded
        .scene
        .instances
        .iter()
        .map(|i| i.material.as_deref().unwrap())
        .collect();
    assert_eq!(kinds.len(), 5);
    let Material::Principled(p) = kinds[0] else {
        panic!("{:?}", kinds[0]);
    };
    let roughness = p.roughness.eval(Vec2::ZERO).x;
    // α = sqrt(2 / (98 + 2)) = sqrt(0.02); roughness = sqrt(α).
    assert!(
        (roughness - 0.02f32.sqrt().sqrt()).abs() < 1e-6,
        "{roughness}"
    );
    assert_eq!(p.specular.eval(Vec2::ZERO).x, 0.5);
    assert_eq!(
        p.base_color.eval(Vec2::ZERO),
        lightpath::math::Vec3::new(0.2, 0.4, 0.6)
    );
    assert!(matches!(kinds[1], Material::Dielectric(d) if d.ior == 1.33));
    assert!(matches!(kinds[2], Material::Dielectric(d) if d.ior == 1.5));
    assert!(matches!(kinds[3], Material::Diffuse(_)), "illum 1 drops Ks");
    assert!(
        matches!(kinds[4], Material::Diffuse(_)),
        "unknown name: grey"
    );
    assert!(loaded.scene.environment.is_some());
    // The camera sees the middle of the bounds.
    let camera = loaded.scene.camera.as_ref().unwrap();
    let res = camera.resolution();
    let ray = camera
        .generate_ray(&CameraSample {
            film: res.as_vec2() * 0.5,
            lens: Vec2::splat(0.5),
        })
        .unwrap();
    assert!(ray.direction.z < -0.999, "{:?}", ray.direction);
    let hit = loaded
        .scene
        .intersect(&ray)
        .expect("the centre sees the model");
    assert!((hit.p.x - 4.5).abs() < 0.6, "{:?}", hit.p);
}

/// Malformed or missing files: errors name the file and the line.
#[test]
fn errors_name_file_and_line() {
    let dir = Scratch::new("errors");
    let message = |obj: &str| -> String {
        let path = dir.write("bad.obj", obj);
        load(&path).expect_err(obj).to_string()
    };
    let bad = dir.0.join("bad.obj").display().to_string();

    let m = message("v 0 0 0\nv 1 0 0\nv 0 1 zz\nf 1 2 3\n");
    assert!(m.starts_with(&format!("{bad}:3:")), "{m}");
    let m = message("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 7\n");
    assert!(m.starts_with(&format!("{bad}:5:")), "{m}");

    let m = message("# lib\nmtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert!(m.starts_with(&format!("{bad}:2:")), "{m}");
    assert!(m.contains("nowhere.mtl"), "{m}");

    let lib = dir.write("lib.mtl", "newmtl a\nKd 0.5 0.5 0.5\n\nKs 1 2\n");
    let m = message("mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n");
    assert!(m.starts_with(&format!("{}:4:", lib.display())), "{m}");

    dir.write("lib.mtl", "newmtl a\nKd 0.5 0.5 0.5\nmap_Kd missing.png\n");
    let m = message("mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n");
    assert!(m.starts_with(&format!("{}:3:", lib.display())), "{m}");
    assert!(m.contains("missing.png"), "{m}");

    let m = message("v 0 0 0\n");
    assert!(m.contains("no faces"), "{m}");
}

/// `map_d` cuts a surface out: a quad whose coverage map is a 2×2 checker of 0 and 1
/// (an RGB PNG: its first channel) lets rays through its lower-right and upper-left
/// quarters to the quad behind it, closest-hit and shadow rays alike; a missing map is
/// an error naming the MTL line.
#[test]
fn map_d_cuts_the_surface_out() {
    let dir = Scratch::new("map-d");
    // Row 0 is the top of the image (v = 1): there at the upper right and lower left.
    let coverage = lightpath::film::Image {
        width: 2,
        height: 2,
        pixels: [0.0, 1.0, 1.0, 0.0].map(glam::Vec3::splat).to_vec(),
    };
    lightpath::io::image::write_image(&dir.0.join("leaf mask.png"), &coverage).unwrap();
    dir.write(
        "lib.mtl",
        "newmtl leaf\nKd 0.2 0.6 0.2\nmap_d leaf mask.png\n",
    );
    let obj = dir.write(
        "leaf.obj",
        "mtllib lib.mtl\n\
         v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
         v -1 -1 -1\nv 2 -1 -1\nv 2 2 -1\nv -1 2 -1\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
         usemtl leaf\nf 1/1 2/2 3/3 4/4\n\
         usemtl back\nf 5 6 7 8\n",
    );
    let loaded = load(&obj).expect("load");
    for (x, y) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
        let there = (x < 0.5) == (y < 0.5);
        let ray = lightpath::math::Ray::new(glam::Vec3::new(x, y, 1.0), -glam::Vec3::Z);
        let si = loaded
            .scene
            .intersect(&ray)
            .expect("the back quad is behind");
        let t = if there { 1.0 } else { 2.0 };
        assert!((si.t - t).abs() < 1e-5, "({x}, {y}): t = {}", si.t);
        let mut shadow = ray;
        shadow.t_max = 1.5;
        assert_eq!(loaded.scene.occluded(&shadow), there, "({x}, {y})");
    }
    let lib = dir.write("lib.mtl", "newmtl leaf\n\nmap_d nowhere.png\n");
    let m = load(&obj).expect_err("missing map_d").to_string();
    assert!(m.starts_with(&format!("{}:3:", lib.display())), "{m}");
    assert!(m.contains("nowhere.png"), "{m}");
}
