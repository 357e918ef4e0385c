//! End-to-end tests of the `lightpath` binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn lightpath(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightpath"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run lightpath")
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .unwrap()
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lightpath-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const CAMERA: &str = r#"<camera type="perspective"><integer name="width" value="8"/><integer name="height" value="8"/></camera>"#;

fn scene_with(body: &str) -> String {
    format!(
        "<integrator type=\"aov\" variable=\"normals\">\n<scene>\n{CAMERA}\n{body}\n</scene>\n<sampler type=\"independent\" count=\"1\"/>\n</integrator>\n"
    )
}

/// A malformed scene: non-zero exit, a one-line error naming `scene.xml:LINE:COL` and
/// the problem, no panic, and no output file.
fn assert_rejected(name: &str, text: &str, line: u32, needle: &str) {
    let dir = temp_dir(name);
    std::fs::write(dir.join("scene.xml"), text).unwrap();
    let out = lightpath(&["render", "scene.xml", "-o", "out.png"], &dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{name}: should fail");
    assert_eq!(
        stderr.trim().lines().count(),
        1,
        "{name}: one line, got {stderr}"
    );
    assert!(
        stderr.contains(&format!("scene.xml:{line}:")),
        "{name}: location missing in {stderr}"
    );
    assert!(
        stderr.contains(needle),
        "{name}: `{needle}` missing in {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{name}: {stderr}");
    // The reader wraps a file's text in an element of its own; errors never name it.
    assert!(!stderr.contains("lightpath-document"), "{name}: {stderr}");
    assert!(!dir.join("out.png").exists(), "{name}: output written");
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "{name}: stray files {leftovers:?}");
}

#[test]
fn malformed_scenes_are_reported_with_location() {
    assert_rejected(
        "bad-xml",
        "<integrator type=\"aov\">\n<scene>\n</integrator>\n",
        3,
        "malformed XML",
    );
    assert_rejected(
        "unclosed-element",
        "<integrator type=\"aov\">\n<scene>\n<shape type=\"sphere\">\n",
        3,
        "the file ends before <shape> is closed",
    );
    assert_rejected(
        "stray-closing-tag",
        "<integrator type=\"aov\"/>\n</scene>\n",
        2,
        "closing tag </scene> without an opening tag",
    );
    assert_rejected(
        "unknown-shape",
        &scene_with("<instance>\n<shape type=\"spehre\"/>\n</instance>"),
        5,
        "did you mean `sphere`",
    );
    assert_rejected(
        "missing-mesh",
        &scene_with("<instance>\n<shape type=\"mesh\" filename=\"nope.ply\"/>\n</instance>"),
        5,
        "nope.ply",
    );
    assert_rejected(
        "matrix-15",
        &scene_with(
            "<instance>\n<shape type=\"sphere\"/>\n<transform>\n<matrix value=\"1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0\"/>\n</transform>\n</instance>",
        ),
        7,
        "16 numbers, got 15",
    );
    assert_rejected(
        "negative-width",
        "<integrator type=\"aov\" variable=\"normals\">\n<scene>\n<camera type=\"perspective\">\n<integer name=\"width\" value=\"-4\"/>\n</camera>\n</scene>\n<sampler type=\"independent\" count=\"1\"/>\n</integrator>\n",
        3,
        "width must be between 1",
    );
    assert_rejected(
        "unknown-property",
        &scene_with("<instance>\n<shape type=\"sphere\" radius=\"2\"/>\n</instance>"),
        5,
        "unknown property `radius`",
    );
    assert_rejected(
        "nan-value",
        &scene_with("<instance>\n<shape type=\"sphere\"/>\n<transform>\n<translate x=\"nan\"/>\n</transform>\n</instance>"),
        7,
        "expected a number",
    );
}

#[test]
fn missing_scene_file_is_an_error() {
    let dir = temp_dir("missing");
    let out = lightpath(&["render", "absent.xml", "-o", "out.png"], &dir);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("absent.xml"));
    assert!(!dir.join("out.png").exists());
}

/// An output that cannot be written is one line naming the file and the reason once
/// (the library's I/O error already carries both).
#[test]
fn unwritable_output_names_the_file_once() {
    let dir = temp_dir("unwritable");
    for name in ["missing/out.png", "missing/out.exr"] {
        let out = lightpath(&["render", "--spp", "1", "-o", name], &dir);
        assert!(!out.status.success(), "{name}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert_eq!(stderr.matches(name).count(), 1, "{stderr}");
        assert_eq!(stderr.matches("os error").count(), 1, "{stderr}");
    }
}

#[test]
fn own_test_scenes_pass() {
    let root = repo_root();
    let out_dir = temp_dir("own");
    let out = lightpath(
        &[
            "test",
            root.join("tests/scenes").to_str().unwrap(),
            "--out-dir",
            out_dir.to_str().unwrap(),
        ],
        &out_dir,
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("4 passed, 0 failed"), "{stdout}");
}

#[test]
fn test_command_fails_on_a_wrong_image() {
    // A copy of a scene whose reference is another scene's image must fail.
    let root = repo_root();
    let dir = temp_dir("wrong");
    let text = std::fs::read_to_string(root.join("tests/scenes/sphere_ellipsoid.xml")).unwrap();
    std::fs::write(
        dir.join("sphere_ellipsoid.xml"),
        text.replace("angle=\"30\"", "angle=\"60\""),
    )
    .unwrap();
    std::fs::copy(
        root.join("tests/scenes/sphere_ellipsoid_ref.exr"),
        dir.join("sphere_ellipsoid_ref.exr"),
    )
    .unwrap();
    let out = lightpath(&["test", "sphere_ellipsoid.xml", "--out-dir", "out"], &dir);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success());
    assert!(stdout.contains("0 passed, 1 failed"), "{stdout}");
}

#[test]
fn gltf_scenes_render() {
    let dir = temp_dir("gltf");
    for scene in ["hierarchy.gltf", "hierarchy.glb", "defaults.gltf"] {
        let path = repo_root().join("tests/gltf").join(scene);
        let out = lightpath(
            &[
                "render",
                path.to_str().unwrap(),
                "-o",
                "x.png",
                "--spp",
                "1",
                "-q",
            ],
            &dir,
        );
        assert!(
            out.status.success(),
            "{scene}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let png = std::fs::read(dir.join("x.png")).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        std::fs::remove_file(dir.join("x.png")).unwrap();
    }
    // A broken file: an error naming it and its line, no image.
    std::fs::write(
        dir.join("broken.gltf"),
        "{\n  \"asset\": {\"version\": \"2.0\"},\n  oops\n}",
    )
    .unwrap();
    let out = lightpath(&["render", "broken.gltf", "-o", "x.png"], &dir);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("broken.gltf:3:"), "{err}");
    assert!(!dir.join("x.png").exists());
}

#[test]
fn default_scene_renders_png_and_exr() {
    let dir = temp_dir("default");
    let out = lightpath(&["render", "--spp", "1", "--quiet"], &dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stderr.is_empty(), "--quiet prints nothing");
    let png = std::fs::read(dir.join("render.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let out = lightpath(&["render", "--spp", "1", "-q", "-o", "x.exr"], &dir);
    assert!(out.status.success());
    let exr = std::fs::read(dir.join("x.exr")).unwrap();
    assert_eq!(&exr[..4], &[0x76, 0x2f, 0x31, 0x01]);
}

#[test]
fn compare_prints_metrics() {
    let root = repo_root();
    let r = root.join("tests/scenes/sphere_ellipsoid_ref.exr");
    let out = lightpath(
        &["compare", r.to_str().unwrap(), r.to_str().unwrap()],
        &root,
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(stdout.contains("mae    0.000000e0"), "{stdout}");
}

#[test]
fn threads_do_not_change_the_image() {
    let dir = temp_dir("threads");
    let scene = repo_root().join("tests/scenes/shapes_normals.xml");
    for (t, name) in [("1", "a.exr"), ("2", "b.exr")] {
        let out = lightpath(
            &[
                "render",
                scene.to_str().unwrap(),
                "-q",
                "--threads",
                t,
                "-o",
                name,
            ],
            &dir,
        );
        assert!(out.status.success());
    }
    assert_eq!(
        std::fs::read(dir.join("a.exr")).unwrap(),
        std::fs::read(dir.join("b.exr")).unwrap()
    );
}

/// `lightpath rays` writes embree-bench's hit and occlusion formats: every accelerator
/// gives the brute-force list's answers, a known ray hits the known triangle at the known
/// distance (in units of its unnormalised direction), and a bad ray file is an error.
#[test]
fn rays_command_traces_ray_files() {
    let dir = temp_dir("rays");
    // Two quads (four triangles): z = 0 and z = 2, over [0,1]², fan-triangulated.
    std::fs::write(
        dir.join("m.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 2\nv 1 0 2\nv 1 1 2\nv 0 1 2\nf 1 2 3 4\nf 5 6 7 8\n",
    )
    .unwrap();
    let mut rays = Vec::new();
    let mut push = |o: [f32; 3], tmin: f32, d: [f32; 3], tmax: f32| {
        for v in [o[0], o[1], o[2], tmin, d[0], d[1], d[2], tmax] {
            rays.extend_from_slice(&v.to_le_bytes());
        }
    };
    push([0.25, 0.75, -1.0], 0.0, [0.0, 0.0, 2.0], f32::INFINITY); // hits z=0 at t=0.5, tri 1
    push([0.25, 0.75, 3.0], 0.0, [0.0, 0.0, -1.0], f32::INFINITY); // hits z=2 at t=1
    push([0.25, 0.75, -1.0], 0.0, [0.0, 0.0, 1.0], 0.5); // stops short
    push([5.0, 5.0, -1.0], 0.0, [0.0, 0.0, 1.0], f32::INFINITY); // misses
    for k in 0..200 {
        let a = k as f32 * 0.1;
        push(
            [0.5, 0.5, 1.0],
            0.0,
            [a.cos(), a.sin(), (a * 0.7).cos()],
            f32::INFINITY,
        );
    }
    std::fs::write(dir.join("r.rays"), &rays).unwrap();
    let mut outputs = Vec::new();
    for accel in [
        "list",
        "bvh2",
        "bvh4",
        "bvh-course",
        "grid",
        "octree",
        "kdtree",
        "bsp",
    ] {
        let hits = format!("{accel}.hits");
        let out = lightpath(
            &["rays", "m.obj", "r.rays", &hits, "--accel", accel, "-q"],
            &dir,
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        outputs.push(std::fs::read(dir.join(&hits)).unwrap());
        let occ = format!("{accel}.occ");
        let out = lightpath(
            &[
                "rays",
                "m.obj",
                "r.rays",
                &occ,
                "--occluded",
                "--accel",
                accel,
                "-q",
            ],
            &dir,
        );
        assert!(out.status.success());
        let occ = std::fs::read(dir.join(&occ)).unwrap();
        assert_eq!(&occ[..4], &[1, 1, 0, 0]);
    }
    for o in &outputs[1..] {
        assert_eq!(o, &outputs[0]);
    }
    // The wide trees' traversals and leaf tests under every vector instruction tier
    // (a tier the processor lacks runs as its highest).
    for tier in ["baseline", "avx2", "avx512"] {
        for accel in ["bvh4", "bvh8"] {
            let hits = format!("{accel}-{tier}.hits");
            let out = lightpath(
                &[
                    "rays", "m.obj", "r.rays", &hits, "--accel", accel, "--simd", tier, "-q",
                ],
                &dir,
            );
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let got = std::fs::read(dir.join(&hits)).unwrap();
            assert_eq!(got, outputs[0], "{accel} --simd {tier}");
        }
    }
    let rec = |i: usize| {
        let r = &outputs[0][8 * i..8 * i + 8];
        (
            f32::from_le_bytes(r[..4].try_into().unwrap()),
            u32::from_le_bytes(r[4..].try_into().unwrap()),
        )
    };
    assert_eq!(outputs[0].len(), 8 * 204);
    let (t, prim) = rec(0);
    assert!((t - 0.5).abs() < 1e-6 && prim == 1, "{t} {prim}");
    let (t, prim) = rec(1);
    assert!(
        (t - 1.0).abs() < 1e-6 && (prim == 2 || prim == 3),
        "{t} {prim}"
    );
    assert_eq!(rec(2), (f32::INFINITY, u32::MAX));
    assert_eq!(rec(3), (f32::INFINITY, u32::MAX));
    std::fs::write(dir.join("bad.rays"), [0u8; 33]).unwrap();
    let out = lightpath(&["rays", "m.obj", "bad.rays", "x.hits"], &dir);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("32-byte"));
    assert!(!dir.join("x.hits").exists());
}

/// `lightpath bench` times every accelerator on the ray sets found in a folder and
/// writes embree-bench's key layout as JSON, with each set's hit count the same for
/// every accelerator, ray by ray and (`--stream`) through the stream queries.
#[test]
fn bench_command_times_ray_sets() {
    let dir = temp_dir("bench");
    std::fs::write(
        dir.join("m.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         f 1 2 3 4\nf 5 6 7 8\nf 1 2 6 5\nf 4 3 7 8\n",
    )
    .unwrap();
    // More rays than the two-thread passes hand out at a time (1,024), with a partial
    // last chunk, so that those passes must count every chunk's hits.
    let mut rays = Vec::new();
    for k in 0..2500 {
        let a = k as f32 * 0.37;
        for v in [
            0.5f32,
            0.5,
            0.5,
            0.0,
            a.cos(),
            a.sin(),
            (a * 1.3).sin(),
            f32::INFINITY,
        ] {
            rays.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(dir.join("random.rays"), &rays).unwrap();
    std::fs::write(dir.join("shadow.rays"), &rays).unwrap();
    let out = lightpath(
        &[
            "bench", "m.obj", "--rays", ".", "--accel", "list", "--accel", "bvh2", "--accel",
            "bvh4", "--accel", "bvh8", "--reps", "2", "--stream", "--packet", "--json", "b.json",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("b.json")).unwrap()).unwrap();
    let hits = |accel: &str, v: &str, set: &str| {
        json["accels"][accel]["traversal"][v][set]["hits"]
            .as_u64()
            .unwrap()
    };
    // The binary tree reports its SAH cost, the wide trees the cost their collapse
    // minimises.
    let build = |accel: &str, key: &str| json["accels"][accel]["build"][key].as_f64();
    assert!(build("bvh2", "sah_cost").is_some_and(|c| c > 0.0));
    assert!(build("bvh2", "collapse_cost").is_none());
    for accel in ["bvh4", "bvh8"] {
        assert!(build(accel, "collapse_cost").is_some_and(|c| c > 0.0));
    }
    for accel in ["list", "bvh2", "bvh4", "bvh8"] {
        assert!(json["accels"][accel]["build"]["ms_median"]
            .as_f64()
            .is_some());
        for v in ["st", "mt"] {
            for set in ["random", "shadow"] {
                assert!(
                    json["accels"][accel]["traversal"][v][set]["mrays_per_s_median"]
                        .as_f64()
                        .is_some_and(|m| m > 0.0)
                );
                assert_eq!(hits(accel, v, set), hits("list", "st", set));
                for mode in ["stream", "packet"] {
                    let entry = &json["accels"][accel]["traversal"][v][mode][set];
                    assert!(entry["mrays_per_s_median"]
                        .as_f64()
                        .is_some_and(|m| m > 0.0));
                    assert_eq!(entry["hits"].as_u64(), Some(hits("list", "st", set)));
                }
            }
        }
    }
    // From inside the box every ray hits one of the four walls or leaves through an
    // open side.
    let h = hits("list", "st", "random");
    assert!(h > 0 && h < 2500, "{h}");
}

/// `lightpath bench --heatmap` draws the primary rays' traversal cost: a PNG of the
/// camera image (square by default) plus its colour bar, one file per accelerator.
#[test]
fn bench_heatmap_is_written() {
    let dir = temp_dir("heatmap");
    std::fs::write(
        dir.join("m.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         f 1 2 3 4\nf 5 6 7 8\nf 1 2 6 5\nf 4 3 7 8\n",
    )
    .unwrap();
    // A 24×24 camera looking down -z at the box from above.
    let mut rays = Vec::new();
    for k in 0..24 * 24 {
        let (x, y) = (k % 24, k / 24);
        let (u, v) = (x as f32 / 24.0 * 2.0 - 0.5, y as f32 / 24.0 * 2.0 - 0.5);
        for f in [u, v, 3.0, 0.0, 0.0, 0.0, -1.0, f32::INFINITY] {
            rays.extend_from_slice(&f.to_le_bytes());
        }
    }
    std::fs::write(dir.join("primary.rays"), &rays).unwrap();
    let png_size = |name: &str| {
        let bytes = std::fs::read(dir.join(name)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
        (be(16), be(20))
    };
    let out = lightpath(
        &[
            "bench",
            "m.obj",
            "--rays",
            ".",
            "--accel",
            "grid",
            "--reps",
            "1",
            "--heatmap",
            "h.png",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("heat map"));
    assert_eq!(png_size("h.png"), (24, 24 + 12));
    let out = lightpath(
        &[
            "bench",
            "m.obj",
            "--rays",
            ".",
            "--accel",
            "kdtree",
            "--accel",
            "bsp",
            "--reps",
            "1",
            "--heatmap",
            "h.png",
            "--heatmap-width",
            "32",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(png_size("h-kdtree.png"), (32, 18 + 12));
    assert_eq!(png_size("h-bsp.png"), (32, 18 + 12));
    // A width that does not divide the ray count is an error, and nothing is written.
    let out = lightpath(
        &[
            "bench",
            "m.obj",
            "--rays",
            ".",
            "--accel",
            "octree",
            "--reps",
            "1",
            "--heatmap",
            "bad.png",
            "--heatmap-width",
            "25",
        ],
        &dir,
    );
    assert!(!out.status.success());
    assert!(!dir.join("bad.png").exists());
}

/// Channel name → values of the first part of an EXR file.
fn exr_channels(path: &Path) -> std::collections::HashMap<String, Vec<f32>> {
    let image = exr::prelude::read_all_flat_layers_from_file(path).expect("read EXR");
    let layer = &image.layer_data[0];
    layer
        .channel_data
        .list
        .iter()
        .map(|c| {
            let values = match &c.sample_data {
                exr::prelude::FlatSamples::F32(v) => v.clone(),
                exr::prelude::FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
                exr::prelude::FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
            };
            (c.name.to_string(), values)
        })
        .collect()
}

/// `--aov albedo,normal,depth` writes the three layers beside R, G, B: an orthographic
/// camera 3 units in front of a square facing it sees depth 3, the normal towards the
/// camera and the square's diffuse colour; pixels that miss have depth +inf, albedo 0.
#[test]
fn render_writes_aov_layers_into_the_exr() {
    let dir = temp_dir("aov");
    let scene = r#"<integrator type="aov" variable="normals">
<scene>
  <camera type="orthographic">
    <integer name="width" value="8"/><integer name="height" value="8"/>
    <float name="size" value="2"/>
    <transform><translate z="-3"/></transform>
  </camera>
  <instance>
    <shape type="rectangle"/>
    <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.2,0.4,0.6"/></bsdf>
    <transform><scale value="0.5"/><rotate axis="0,1,0" angle="180"/></transform>
  </instance>
</scene>
<sampler type="independent" count="4"/>
</integrator>
"#;
    std::fs::write(dir.join("scene.xml"), scene).unwrap();
    let out = lightpath(
        &[
            "render",
            "scene.xml",
            "-o",
            "out.exr",
            "--aov",
            "albedo,normal,depth",
            "-q",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let channels = exr_channels(&dir.join("out.exr"));
    let mut names: Vec<&str> = channels.keys().map(|k| k.as_str()).collect();
    names.sort();
    assert_eq!(
        names,
        [
            "B", "G", "R", "albedo.B", "albedo.G", "albedo.R", "depth.Z", "normal.X", "normal.Y",
            "normal.Z"
        ]
    );
    let at = |name: &str, x: usize, y: usize| channels[name][y * 8 + x];
    for (x, y) in [(3, 3), (3, 4), (4, 4)] {
        assert!(
            (at("depth.Z", x, y) - 3.0).abs() < 1e-5,
            "({x}, {y}): {:?}",
            channels["depth.Z"]
        );
        assert!((at("normal.Z", x, y) + 1.0).abs() < 1e-5);
        assert!(at("normal.X", x, y).abs() < 1e-5 && at("normal.Y", x, y).abs() < 1e-5);
        assert!((at("albedo.R", x, y) - 0.2).abs() < 1e-6);
        assert!((at("albedo.G", x, y) - 0.4).abs() < 1e-6);
        assert!((at("albedo.B", x, y) - 0.6).abs() < 1e-6);
        // The image itself is the scene's normals AOV, (n + 1) / 2.
        assert!((at("B", x, y) - 0.0).abs() < 1e-5 && (at("R", x, y) - 0.5).abs() < 1e-5);
    }
    for (x, y) in [(0, 0), (7, 3), (4, 7)] {
        assert_eq!(at("depth.Z", x, y), f32::INFINITY, "({x}, {y})");
        assert_eq!(at("albedo.R", x, y), 0.0);
        assert_eq!(at("normal.Z", x, y), 0.0);
    }
    // The image reads back as usual.
    let out = lightpath(&["compare", "out.exr", "out.exr"], &dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // AOVs need an EXR; unknown layers get a suggestion; nothing is written.
    let out = lightpath(
        &["render", "scene.xml", "-o", "out.png", "--aov", "depth"],
        &dir,
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains(".exr"));
    assert!(!dir.join("out.png").exists());
    let out = lightpath(
        &["render", "scene.xml", "-o", "b.exr", "--aov", "albdo"],
        &dir,
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("albedo"));
    assert!(!dir.join("b.exr").exists());
}

/// `.hdr` output, and an OBJ rendered directly as a scene.
#[test]
fn render_writes_hdr_and_renders_obj_scenes() {
    let dir = temp_dir("hdr-obj");
    let obj = repo_root().join("tests/obj/two_materials.obj");
    let out = lightpath(
        &[
            "render",
            obj.to_str().unwrap(),
            "-o",
            "obj.hdr",
            "--spp",
            "1",
            "-q",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(dir.join("obj.hdr")).unwrap();
    assert!(bytes.starts_with(b"#?RADIANCE"));
    assert!(String::from_utf8_lossy(&bytes).contains("-Y 480 +X 640"));
    let out = lightpath(&["compare", "obj.hdr", "obj.hdr"], &dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A broken OBJ: one line naming file and line, nothing written.
    std::fs::write(dir.join("bad.obj"), "v 0 0 0\nv 1 0 0\nv 0 x 0\nf 1 2 3\n").unwrap();
    let out = lightpath(&["render", "bad.obj", "-o", "bad.png"], &dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("bad.obj:3:"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!dir.join("bad.png").exists());
}

/// `--crop X,Y,W,H` writes the rectangle alone, its pixels those of the whole image (the
/// image and an AOV layer); a rectangle outside the image, or a malformed one, is an
/// error that writes nothing.
#[test]
fn render_crop_writes_that_part_of_the_image() {
    let dir = temp_dir("crop");
    let scene = repo_root().join("tests/scenes/shapes_normals.xml");
    let scene = scene.to_str().unwrap();
    let render = |extra: &[&str], name: &str| {
        let mut args = vec!["render", scene, "-q", "--spp", "3", "--aov", "depth"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", name]);
        lightpath(&args, &dir)
    };
    assert!(render(&[], "full.exr").status.success());
    assert!(render(&["--crop", "7,5,20,13"], "part.exr")
        .status
        .success());
    let (full, part) = (
        exr_channels(&dir.join("full.exr")),
        exr_channels(&dir.join("part.exr")),
    );
    let header = exr::prelude::read_all_flat_layers_from_file(dir.join("full.exr")).unwrap();
    let width = header.layer_data[0].size.0;
    for channel in ["R", "G", "B", "depth.Z"] {
        let want: Vec<u32> = (5..18)
            .flat_map(|y| (7..27).map(move |x| (x, y)))
            .map(|(x, y)| full[channel][y * width + x].to_bits())
            .collect();
        let got: Vec<u32> = part[channel].iter().map(|v| v.to_bits()).collect();
        assert_eq!(got, want, "{channel}");
    }
    for (bad, needle) in [
        ("7,5,2000,13", "reaches outside"),
        ("7,5,0,13", "empty"),
        ("1,2,3", "X,Y,W,H"),
    ] {
        let out = render(&["--crop", bad], "bad.exr");
        assert!(!out.status.success(), "{bad}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{bad}: {err}");
        assert!(!dir.join("bad.exr").exists(), "{bad}");
    }
}

/// A Cornell-style box of separate triangles (each shrunk by 2% about its centroid, so
/// that no two share an edge and no ray can hit two at the same distance), diffuse
/// walls, a tilted diffuse block and an emitting quad, in Mitsuba's format.
fn tie_free_box(dir: &Path) -> PathBuf {
    type Tri = [[f32; 3]; 3];
    // A quad's two triangles, wound so that their normal is `n` (the winding of
    // `a, b, c, d` may be either).
    let quad = |q: [[f32; 3]; 4], n: [f32; 3]| -> Vec<Tri> {
        let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let (e1, e2) = (sub(q[1], q[0]), sub(q[2], q[0]));
        let c = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let tris = [[q[0], q[1], q[2]], [q[0], q[2], q[3]]];
        if c[0] * n[0] + c[1] * n[1] + c[2] * n[2] >= 0.0 {
            tris.to_vec()
        } else {
            tris.iter().map(|t| [t[0], t[2], t[1]]).collect()
        }
    };
    let obj = |name: &str, tris: &[Tri]| {
        let mut text = String::new();
        for (k, t) in tris.iter().enumerate() {
            let c: Vec<f32> = (0..3)
                .map(|a| (t[0][a] + t[1][a] + t[2][a]) / 3.0)
                .collect();
            for v in t {
                let s: Vec<String> = (0..3)
                    .map(|a| (c[a] + 0.98 * (v[a] - c[a])).to_string())
                    .collect();
                text += &format!("v {}\n", s.join(" "));
            }
            text += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
        }
        std::fs::write(dir.join(name), text).unwrap();
    };
    let mut walls = Vec::new();
    walls.extend(quad(
        [
            [-1., -1., -1.],
            [1., -1., -1.],
            [1., -1., 1.],
            [-1., -1., 1.],
        ],
        [0., 1., 0.],
    ));
    walls.extend(quad(
        [[-1., 1., -1.], [1., 1., -1.], [1., 1., 1.], [-1., 1., 1.]],
        [0., -1., 0.],
    ));
    walls.extend(quad(
        [
            [-1., -1., -1.],
            [1., -1., -1.],
            [1., 1., -1.],
            [-1., 1., -1.],
        ],
        [0., 0., 1.],
    ));
    obj("walls.obj", &walls);
    obj(
        "red.obj",
        &quad(
            [
                [-1., -1., -1.],
                [-1., 1., -1.],
                [-1., 1., 1.],
                [-1., -1., 1.],
            ],
            [1., 0., 0.],
        ),
    );
    obj(
        "green.obj",
        &quad(
            [[1., -1., -1.], [1., 1., -1.], [1., 1., 1.], [1., -1., 1.]],
            [-1., 0., 0.],
        ),
    );
    obj(
        "light.obj",
        &quad(
            [
                [-0.3, 0.99, -0.3],
                [0.3, 0.99, -0.3],
                [0.3, 0.99, 0.3],
                [-0.3, 0.99, 0.3],
            ],
            [0., -1., 0.],
        ),
    );
    // A block turned 30 degrees about y, its faces outward.
    let (s, c) = (0.5f32, 0.866_025_4f32);
    let corner = |x: f32, y: f32, z: f32| {
        [
            0.1 + 0.35 * (c * x + s * z),
            -1.0 + 0.6 * (y + 1.0) / 2.0,
            -0.2 + 0.35 * (c * z - s * x),
        ]
    };
    let mut block = Vec::new();
    for axis in 0..3 {
        for side in [-1.0f32, 1.0] {
            let p = |u: f32, v: f32| match axis {
                0 => corner(side, u, v),
                1 => corner(u, side, v),
                _ => corner(u, v, side),
            };
            let q = [p(-1., -1.), p(1., -1.), p(1., 1.), p(-1., 1.)];
            // Outward: away from the block's centre.
            let centre = corner(0., 0., 0.);
            let outward: [f32; 3] = std::array::from_fn(|a| (q[0][a] + q[2][a]) / 2.0 - centre[a]);
            block.extend(quad(q, outward));
        }
    }
    obj("block.obj", &block);
    let scene = r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="6"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="0, 0, 3.4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
        <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="32"/></film>
    </sensor>
    <shape type="obj" filename="walls.obj"><bsdf type="diffuse"><rgb name="reflectance" value="0.75, 0.75, 0.72"/></bsdf></shape>
    <shape type="obj" filename="red.obj"><bsdf type="diffuse"><rgb name="reflectance" value="0.65, 0.08, 0.06"/></bsdf></shape>
    <shape type="obj" filename="green.obj"><bsdf type="diffuse"><rgb name="reflectance" value="0.12, 0.5, 0.1"/></bsdf></shape>
    <shape type="obj" filename="block.obj"><bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.5, 0.8"/></bsdf></bsdf></shape>
    <shape type="obj" filename="light.obj"><emitter type="area"><rgb name="radiance" value="12, 10, 8"/></emitter></shape>
</scene>
"#;
    let path = dir.join("box.xml");
    std::fs::write(&path, scene).unwrap();
    path
}

/// `--simd` caps the vector instruction tier, and every tier the processor has renders
/// the same image, bit for bit, with each sampler: the baseline code (paths one by one),
/// the AVX2 tile (paths advanced together, diffuse vertices in lanes) and the AVX-512
/// one (rays in packets too). The scene has no ties between triangles, the one place
/// where the tiers may report different (equally close) hits.
#[test]
fn every_simd_tier_renders_the_same_image() {
    let dir = temp_dir("simd");
    let scene = tie_free_box(&dir);
    for sampler in ["independent", "sobol"] {
        let mut images: Vec<(String, Vec<u8>)> = Vec::new();
        for tier in ["baseline", "avx2", "avx512"] {
            let out = lightpath(
                &[
                    "render",
                    scene.to_str().unwrap(),
                    "-q",
                    "--simd",
                    tier,
                    "--sampler",
                    sampler,
                    "-o",
                    "out.exr",
                    "--stats-json",
                    "stats.json",
                ],
                &dir,
            );
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let stats = std::fs::read_to_string(dir.join("stats.json")).unwrap();
            let used = serde_json::from_str::<serde_json::Value>(&stats).unwrap()["simd"]
                .as_str()
                .unwrap()
                .to_string();
            // A tier the processor lacks runs as the highest it has: nothing new to see.
            if used != tier {
                assert_ne!(tier, "baseline", "the baseline always runs");
                continue;
            }
            let image = std::fs::read(dir.join("out.exr")).unwrap();
            images.push((used, image));
        }
        let pixels = exr_channels(&dir.join("out.exr"));
        assert!(
            pixels["R"].iter().filter(|&&r| r > 0.0).count() > pixels["R"].len() / 2,
            "the box is lit"
        );
        for (tier, image) in &images[1..] {
            assert!(
                *image == images[0].1,
                "{sampler}: {tier} differs from the baseline"
            );
        }
    }
}

fn read_ray_file(path: &Path) -> Vec<[f32; 8]> {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(
        bytes.len() % 32,
        0,
        "{}: whole 32-byte records",
        path.display()
    );
    bytes
        .chunks_exact(32)
        .map(|r| {
            std::array::from_fn(|i| f32::from_le_bytes(r[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

/// `--record-rays` writes every ray the path tracer traces, as the render's statistics
/// count them (camera and bounce rays in paths.rays, shadow rays in shadow.rays), with
/// the scene's triangles; on a processor without AVX2, or capped to the baseline, the
/// render traces no batches and says so.
#[test]
fn record_rays_writes_every_traced_ray() {
    let dir = temp_dir("record");
    let scene = tie_free_box(&dir);
    let out = lightpath(
        &[
            "render",
            scene.to_str().unwrap(),
            "-q",
            "--spp",
            "2",
            "--threads",
            "1",
            "-o",
            "out.exr",
            "--record-rays",
            "rec",
            "--stats-json",
            "stats.json",
        ],
        &dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stats = std::fs::read_to_string(dir.join("stats.json"));
    let simd = stats.as_ref().map_or(String::new(), |s| {
        serde_json::from_str::<serde_json::Value>(s).unwrap()["simd"]
            .as_str()
            .unwrap()
            .to_string()
    });
    if !out.status.success() && stderr.contains("AVX2") {
        // Only a processor without AVX2 may refuse (then no statistics were written).
        let info = lightpath(&["info", scene.to_str().unwrap()], &dir);
        assert!(
            String::from_utf8_lossy(&info.stdout).contains("baseline"),
            "{stderr}"
        );
        return;
    }
    assert!(out.status.success(), "{stderr}");
    assert_ne!(simd, "baseline");
    let stats: serde_json::Value = serde_json::from_str(&stats.unwrap()).unwrap();
    let kinds = &stats["rays_by_kind"];
    let count = |k: &str| kinds[k].as_u64().unwrap() as usize;
    let paths = read_ray_file(&dir.join("rec/paths.rays"));
    let shadow = read_ray_file(&dir.join("rec/shadow.rays"));
    assert_eq!(paths.len(), count("camera") + count("bounce"));
    assert_eq!(shadow.len(), count("shadow"));
    assert_eq!(
        count("camera"),
        40 * 32 * 2,
        "every pixel's two camera rays"
    );
    assert!(
        shadow.len() > 1000,
        "the light is sampled: {}",
        shadow.len()
    );
    // The pinhole's rays leave its eye; every ray's direction and range are usable.
    let eye = [0.0, 0.0, 3.4];
    let from_eye = paths
        .iter()
        .filter(|r| (0..3).all(|a| (r[a] - eye[a]).abs() < 1e-5));
    assert!(from_eye.count() >= count("camera"));
    for r in paths.iter().chain(&shadow) {
        assert!(
            r.iter().all(|v| !v.is_nan()) && r[3] >= 0.0 && r[7] > r[3],
            "{r:?}"
        );
        assert!(r[4] != 0.0 || r[5] != 0.0 || r[6] != 0.0, "{r:?}");
    }
    assert!(
        shadow.iter().all(|r| r[7].is_finite()),
        "shadow rays end at the light"
    );
    // The triangles: the scene's five meshes, merged, as the mesh loader reads them.
    let faces = |name: &str| {
        std::fs::read_to_string(dir.join(name))
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("f "))
            .count()
    };
    let all = [
        "walls.obj",
        "red.obj",
        "green.obj",
        "block.obj",
        "light.obj",
    ]
    .iter()
    .map(|n| faces(n))
    .sum::<usize>();
    assert_eq!(faces("rec/scene.obj"), all);
    // And Embree's formats: `lightpath rays` traces them against those triangles, every
    // camera ray and bounce meeting the closed box but where it looks out of its open side.
    let traced = lightpath(
        &["rays", "rec/scene.obj", "rec/paths.rays", "hits.bin", "-q"],
        &dir,
    );
    assert!(
        traced.status.success(),
        "{}",
        String::from_utf8_lossy(&traced.stderr)
    );
    let hits = std::fs::read(dir.join("hits.bin")).unwrap();
    assert_eq!(hits.len(), 8 * paths.len());
    let hit = hits
        .chunks_exact(8)
        .filter(|h| f32::from_le_bytes(h[..4].try_into().unwrap()).is_finite())
        .count();
    assert!(hit > paths.len() / 2, "{hit} of {} rays hit", paths.len());
    let names: Vec<String> = std::fs::read_dir(dir.join("rec"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names.len(), 3, "no temporary files left: {names:?}");
}

/// A render that traces its rays inside the integrator (here: an analytic sphere, which
/// does not merge into one mesh) cannot record them: a clear error before rendering, and
/// no output.
#[test]
fn record_rays_refuses_renders_without_batches() {
    let dir = temp_dir("record-refused");
    let scene = r#"<scene version="3.0.0">
    <integrator type="path"/>
    <sensor type="perspective">
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
    <shape type="sphere"><emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape>
</scene>
"#;
    std::fs::write(dir.join("sphere.xml"), scene).unwrap();
    let out = lightpath(
        &[
            "render",
            "sphere.xml",
            "-q",
            "-o",
            "out.exr",
            "--record-rays",
            "rec",
        ],
        &dir,
    );
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--record-rays") && stderr.contains("one triangle mesh"),
        "{stderr}"
    );
    assert!(!dir.join("rec").exists() && !dir.join("out.exr").exists());
}
