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
