//! End-to-end tests of the interactive side of `lightpath`: progress output, time
//! budgets, previews, statistics, tone mapping, scene info, helpful errors, shell
//! completions and the man page.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_lightpath")
}

fn lightpath(args: &[&str], dir: &Path) -> Output {
    Command::new(exe())
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run lightpath")
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lightpath-ux-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// An ambient-occlusion scene of `w`×`h` pixels with `spp` samples per pixel.
fn ao_scene(w: u32, h: u32, spp: u64) -> String {
    format!(
        r#"<integrator type="ao" distance="2">
    <scene>
        <camera type="perspective">
            <integer name="width" value="{w}"/>
            <integer name="height" value="{h}"/>
            <transform><lookat origin="0,-1,-5" target="0,0,0" up="0,-1,0"/></transform>
        </camera>
        <instance><shape type="sphere"/></instance>
        <instance>
            <shape type="plane"/>
            <transform><rotate axis="1,0,0" angle="-90"/><translate y="1"/></transform>
        </instance>
    </scene>
    <sampler type="independent" count="{spp}"/>
</integrator>
"#
    )
}

/// Signs of a drawn progress bar: carriage returns, escape sequences, bar characters.
fn has_bar(stderr: &str) -> bool {
    stderr.contains('\r')
        || stderr.contains('\x1b')
        || stderr.contains("ETA")
        || stderr.contains("[=")
        || stderr.contains("spp, ")
}

/// With stderr captured (a pipe, not a terminal) no bar is drawn, only the summary
/// line; with --quiet nothing at all; stdout stays empty either way.
#[test]
fn no_progress_bar_when_not_a_terminal_or_quiet() {
    let dir = temp_dir("bar");
    std::fs::write(dir.join("s.xml"), ao_scene(64, 48, 64)).unwrap();
    let out = lightpath(&["render", "s.xml", "-o", "a.png"], &dir);
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!has_bar(&stderr), "bar drawn into a pipe: {stderr:?}");
    assert!(stderr.starts_with("wrote a.png"), "{stderr:?}");
    assert!(out.stdout.is_empty());
    let out = lightpath(&["render", "s.xml", "-o", "b.png", "--quiet"], &dir);
    assert!(out.status.success());
    assert!(out.stderr.is_empty(), "{:?}", text(&out.stderr));
    assert!(out.stdout.is_empty());
}

/// In a terminal (a pseudo-terminal made by util-linux `script`, stdout redirected to a
/// file) the bar is drawn on stderr with the rates, and stdout gets none of it.
#[test]
fn progress_bar_on_stderr_in_a_terminal() {
    if Command::new("script")
        .arg("--version")
        .output()
        .map(|o| !o.status.success())
        .unwrap_or(true)
    {
        eprintln!("skipped: util-linux `script` is not available");
        return;
    }
    let dir = temp_dir("tty");
    std::fs::write(dir.join("s.xml"), ao_scene(64, 48, 1_000_000)).unwrap();
    let command = format!(
        "{} render s.xml -o a.png --time 1s --stats > stdout.txt",
        exe()
    );
    let out = Command::new("script")
        .args(["-qec", &command, "/dev/null"])
        .current_dir(&dir)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let terminal = text(&out.stdout);
    assert!(out.status.success(), "{terminal}");
    assert!(terminal.contains("ETA"), "{terminal:?}");
    assert!(terminal.contains(" spp, "), "{terminal:?}");
    assert!(terminal.contains("samples/s, "), "{terminal:?}");
    assert!(terminal.contains("rays/s"), "{terminal:?}");
    assert!(terminal.contains('\r') || terminal.contains('\x1b'));
    let stdout = std::fs::read_to_string(dir.join("stdout.txt")).unwrap();
    assert!(!has_bar(&stdout), "{stdout:?}");
    assert!(
        stdout.contains("samples"),
        "--stats goes to stdout: {stdout:?}"
    );
    let stderr = lightpath(&["render", "s.xml", "-q", "--time", "1s"], &dir);
    assert!(stderr.stderr.is_empty());
}

/// `--time 2s` on a scene that would take hours: the process ends within a second of
/// the budget, the image is written, and every pixel has the same (whole) number of
/// samples.
#[test]
fn time_budget_ends_the_render() {
    let dir = temp_dir("time");
    std::fs::write(dir.join("slow.xml"), ao_scene(64, 48, 10_000_000)).unwrap();
    let start = Instant::now();
    let out = lightpath(
        &[
            "render",
            "slow.xml",
            "--time",
            "2s",
            "-o",
            "out.exr",
            "--stats-json",
            "stats.json",
        ],
        &dir,
    );
    let wall = start.elapsed();
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(wall < Duration::from_secs(3), "took {wall:?}");
    assert!(dir.join("out.exr").exists());
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).unwrap()).unwrap();
    let render = stats["seconds"]["render"].as_f64().unwrap();
    let spp = stats["spp"].as_u64().unwrap();
    eprintln!(
        "--time 2s: wall {:.3} s, render {render:.3} s ({:+.3} s), {spp} spp in {} passes",
        wall.as_secs_f64(),
        render - 2.0,
        stats["passes"]
    );
    assert!(render > 1.5 && render < 2.5, "render {render} s");
    assert!(spp > 4, "{spp}");
    assert_eq!(stats["samples"].as_u64().unwrap(), spp * 64 * 48);
    // With --spp as well, whichever comes first: here the sample count.
    let out = lightpath(
        &[
            "render",
            "slow.xml",
            "--time",
            "1m",
            "--spp",
            "3",
            "-o",
            "x.png",
            "--stats-json",
            "s.json",
        ],
        &dir,
    );
    assert!(out.status.success());
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("s.json")).unwrap()).unwrap();
    assert_eq!(stats["spp"], 3);
    // Bad durations are rejected.
    let out = lightpath(&["render", "slow.xml", "--time", "2 parsecs"], &dir);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("unknown unit"),
        "{}",
        text(&out.stderr)
    );
}

/// `--preview P.png --every 0.2s` writes a valid PNG while the render is still running,
/// atomically (no temporary files left), and leaves it showing the final image.
#[test]
fn preview_appears_during_the_render() {
    let dir = temp_dir("preview");
    std::fs::write(dir.join("s.xml"), ao_scene(48, 32, 10_000_000)).unwrap();
    let start = Instant::now();
    let mut child = Command::new(exe())
        .args([
            "render",
            "s.xml",
            "--time",
            "1.5s",
            "--preview",
            "p.png",
            "--every",
            "0.2s",
            "-o",
            "final.png",
            "-q",
        ])
        .current_dir(&dir)
        .spawn()
        .unwrap();
    let mut appeared = None;
    let status = loop {
        if appeared.is_none() && dir.join("p.png").exists() {
            appeared = Some(start.elapsed());
        }
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let finished = start.elapsed();
    assert!(status.success());
    let appeared = appeared.expect("no preview while rendering");
    eprintln!("preview appeared after {appeared:?}; the render ended after {finished:?}");
    assert!(appeared + Duration::from_millis(300) < finished);
    let preview = lightpath::io::image::read_image(&dir.join("p.png"), None).unwrap();
    assert_eq!((preview.width, preview.height), (48, 32));
    assert_eq!(
        std::fs::read(dir.join("p.png")).unwrap(),
        std::fs::read(dir.join("final.png")).unwrap(),
        "the last preview is the final image"
    );
    assert_eq!(files(&dir), vec!["final.png", "p.png", "s.xml"]);
    // A preview must be a display image.
    let out = lightpath(
        &["render", "s.xml", "--preview", "p.exr", "--spp", "1"],
        &dir,
    );
    assert!(!out.status.success());
}

/// `--stats-json` writes valid JSON with every documented key; `--stats` prints a
/// table to stdout.
#[test]
fn stats_json_has_the_documented_keys() {
    let dir = temp_dir("stats");
    std::fs::write(dir.join("s.xml"), ao_scene(40, 30, 4)).unwrap();
    let out = lightpath(
        &[
            "render",
            "s.xml",
            "-q",
            "--stats",
            "--stats-json",
            "stats.json",
            "-o",
            "o.exr",
        ],
        &dir,
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(
        table.contains("render") && table.contains("rays"),
        "{table}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).unwrap())
            .expect("valid JSON");
    for phase in ["load", "render", "write", "total"] {
        assert!(
            json["seconds"][phase].as_f64().is_some_and(|s| s >= 0.0),
            "seconds.{phase} in {json}"
        );
    }
    for key in [
        "samples",
        "rays",
        "nodes_visited",
        "prims_tested",
        "non_finite_samples",
        "accel_bytes",
        "width",
        "height",
        "spp",
        "passes",
    ] {
        assert!(json[key].as_u64().is_some(), "{key} in {json}");
    }
    for kind in ["camera", "bounce", "shadow"] {
        assert!(
            json["rays_by_kind"][kind].as_u64().is_some(),
            "rays_by_kind.{kind} in {json}"
        );
    }
    for (level, keys) in [
        ("tlas", &["instances", "bytes"][..]),
        ("blas", &["count", "triangles", "bytes"][..]),
    ] {
        for key in keys {
            assert!(
                json[level][key].as_u64().is_some(),
                "{level}.{key} in {json}"
            );
        }
        assert!(
            json[level]["build_seconds"].as_f64().is_some(),
            "{level} in {json}"
        );
    }
    for key in ["samples_per_second", "rays_per_second"] {
        assert!(
            json[key].as_f64().is_some_and(|v| v > 0.0),
            "{key} in {json}"
        );
    }
    assert_eq!(json["width"], 40);
    assert_eq!(json["height"], 30);
    assert_eq!(json["spp"], 4);
    assert_eq!(json["samples"], 40 * 30 * 4);
    assert!(json["rays"].as_u64().unwrap() >= 40 * 30 * 4);
    assert_eq!(files(&dir), vec!["o.exr", "s.xml", "stats.json"]);
}

/// `lightpath tonemap IN.exr -o OUT.png` makes a PNG; the operators differ; EXR
/// output of `render` stays linear whatever --tonemap says.
#[test]
fn tonemap_command_writes_a_png() {
    let dir = temp_dir("tonemap");
    // A linear ramp from 0 to 8.
    let mut ramp = lightpath::film::Image::new(64, 4);
    for y in 0..4 {
        for x in 0..64 {
            ramp.set(x, y, lightpath::math::Vec3::splat(x as f32 / 8.0));
        }
    }
    lightpath::io::image::write_image(&dir.join("in.exr"), &ramp).unwrap();
    let mut outputs = Vec::new();
    for op in ["clamp", "reinhard", "aces", "agx"] {
        let name = format!("{op}.png");
        let out = lightpath(
            &[
                "tonemap",
                "in.exr",
                "-o",
                &name,
                "--tonemap",
                op,
                "--exposure",
                "0.5",
            ],
            &dir,
        );
        assert!(out.status.success(), "{op}: {}", text(&out.stderr));
        let png = lightpath::io::image::read_image(&dir.join(&name), None).unwrap();
        assert_eq!((png.width, png.height), (64, 4));
        // 0 stays black; the ramp never gets darker.
        assert_eq!(png.get(0, 0).x, 0.0, "{op}");
        for x in 1..64 {
            assert!(png.get(x, 2).x >= png.get(x - 1, 2).x, "{op} at {x}");
        }
        outputs.push(std::fs::read(dir.join(&name)).unwrap());
    }
    for i in 0..outputs.len() {
        for j in i + 1..outputs.len() {
            assert_ne!(outputs[i], outputs[j], "operators {i} and {j} agree");
        }
    }
    // Negative exposure is a number, not an option.
    let out = lightpath(
        &["tonemap", "in.exr", "-o", "dark.png", "--exposure", "-2"],
        &dir,
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    // The output must be a display format.
    let out = lightpath(&["tonemap", "in.exr", "-o", "out.exr"], &dir);
    assert!(!out.status.success());
    // render: EXR stays linear.
    std::fs::write(dir.join("s.xml"), ao_scene(16, 16, 2)).unwrap();
    for (name, op) in [("lin.exr", "clamp"), ("agx.exr", "agx")] {
        let out = lightpath(
            &["render", "s.xml", "-q", "-o", name, "--tonemap", op],
            &dir,
        );
        assert!(out.status.success());
    }
    assert_eq!(
        std::fs::read(dir.join("lin.exr")).unwrap(),
        std::fs::read(dir.join("agx.exr")).unwrap()
    );
}

/// Typos of --accel, --sampler and --tonemap name the nearest valid value.
#[test]
fn typos_suggest_the_nearest_name() {
    let dir = temp_dir("typos");
    for (args, hint) in [
        (
            vec!["render", "--accel", "bvh-corse"],
            "did you mean `bvh-course`?",
        ),
        (vec!["render", "--sampler", "sobl"], "did you mean `sobol`?"),
        (
            vec!["render", "--tonemap", "reinhart"],
            "did you mean `reinhard`?",
        ),
        (
            vec!["tonemap", "a.exr", "-o", "b.png", "--tonemap", "agz"],
            "did you mean `agx`?",
        ),
        (
            vec!["test", "x.xml", "--accel", "lst"],
            "did you mean `list`?",
        ),
    ] {
        let out = lightpath(&args, &dir);
        let stderr = text(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains(hint), "{args:?}: {stderr}");
        assert!(stderr.contains("known:"), "{args:?}: {stderr}");
    }
    assert!(files(&dir).is_empty());
}

/// A scene that needs light and has none gets a warning (but renders); one that shows
/// geometry does not.
#[test]
fn dark_scene_warning() {
    let dir = temp_dir("dark");
    let dark = ao_scene(8, 8, 1).replace(r#"type="ao" distance="2""#, r#"type="direct""#);
    std::fs::write(dir.join("dark.xml"), dark).unwrap();
    let out = lightpath(&["render", "dark.xml", "-o", "d.png"], &dir);
    assert!(out.status.success());
    assert!(
        text(&out.stderr).contains("warning: the scene has no lights"),
        "{}",
        text(&out.stderr)
    );
    let out = lightpath(&["render", "dark.xml", "-o", "d.png", "-q"], &dir);
    assert!(out.stderr.is_empty());
    std::fs::write(dir.join("ao.xml"), ao_scene(8, 8, 1)).unwrap();
    let out = lightpath(&["render", "ao.xml", "-o", "a.png"], &dir);
    assert!(!text(&out.stderr).contains("warning"));
}

/// `lightpath info` describes a scene without rendering it; `--verbose` logs the same
/// counts before rendering.
#[test]
fn info_and_verbose_describe_the_scene() {
    let dir = temp_dir("info");
    let scene = r#"<integrator type="pathtracer">
    <scene>
        <camera type="perspective">
            <integer name="width" value="20"/><integer name="height" value="10"/>
            <transform><lookat origin="0,-1,-5" target="0,0,0" up="0,-1,0"/></transform>
        </camera>
        <light type="point" position="0,-3,0" power="10"/>
        <instance>
            <shape type="sphere"/>
            <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.5"/></bsdf>
        </instance>
        <instance>
            <shape type="rectangle"/>
            <emission type="lambertian"><texture name="emission" type="constant" value="1"/></emission>
            <transform><translate y="-2"/></transform>
        </instance>
    </scene>
    <sampler type="sobol" count="16"/>
</integrator>
"#;
    std::fs::write(dir.join("s.xml"), scene).unwrap();
    let out = lightpath(&["info", "s.xml"], &dir);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    for needle in [
        "camera              perspective, 20x10",
        "integrator          path-tracer",
        "sampler             sobol, 16 spp",
        "instances           2 (rectangle 1, sphere 1)",
        "lights              2 (area 1, point 1)",
        "emitting instances  1",
        "materials           1 (diffuse 1); 1 instances without a material",
        "accelerator memory",
        "bounds",
        "simd tier           ",
    ] {
        assert!(stdout.contains(needle), "`{needle}` missing in\n{stdout}");
    }
    assert_eq!(files(&dir), vec!["s.xml"], "info renders nothing");
    let out = lightpath(
        &["render", "s.xml", "-v", "--spp", "1", "-o", "o.png"],
        &dir,
    );
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("instances   2 (rectangle 1, sphere 1)"),
        "{stderr}"
    );
    assert!(
        stderr.contains("lights      2 (area 1, point 1)"),
        "{stderr}"
    );
    assert!(stderr.contains("triangles"), "{stderr}");
    assert!(stderr.contains("accelerator "), "{stderr}");
}

/// Completion scripts for every shell and the man page are generated from the clap
/// definition.
#[test]
fn completions_and_man_page() {
    let dir = temp_dir("completions");
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let out = lightpath(&["completions", shell], &dir);
        assert!(out.status.success(), "{shell}");
        let script = text(&out.stdout);
        assert!(script.len() > 500, "{shell}: {script}");
        assert!(script.contains("tonemap"), "{shell}");
        assert!(script.contains("stats-json"), "{shell}");
    }
    // The value lists reach the completions.
    let bash = text(&lightpath(&["completions", "bash"], &dir).stdout);
    assert!(bash.contains("reinhard"), "tone maps in bash completions");
    let out = lightpath(&["man"], &dir);
    assert!(out.status.success());
    let man = text(&out.stdout);
    assert!(man.starts_with(".ie") || man.contains(".TH"), "{man}");
    assert!(man.contains("lightpath"));
    assert!(man.contains("render"));
    let out = lightpath(&["completions", "tcsh"], &dir);
    assert!(!out.status.success());
}

/// A camera that sees no surface and no environment is warned about; one that sees the
/// scene is not.
#[test]
fn camera_seeing_nothing_is_a_warning() {
    let dir = temp_dir("blind");
    let away = ao_scene(8, 8, 1)
        .replace(r#"target="0,0,0""#, r#"target="0,-1,-10""#)
        .replace(
            r#"<instance>
            <shape type="plane"/>
            <transform><rotate axis="1,0,0" angle="-90"/><translate y="1"/></transform>
        </instance>"#,
            "",
        );
    std::fs::write(dir.join("away.xml"), away).unwrap();
    let out = lightpath(&["render", "away.xml", "-o", "a.png"], &dir);
    assert!(out.status.success());
    assert!(
        text(&out.stderr).contains("warning: the camera sees nothing"),
        "{}",
        text(&out.stderr)
    );
    std::fs::write(dir.join("ao.xml"), ao_scene(8, 8, 1)).unwrap();
    let out = lightpath(&["render", "ao.xml", "-o", "b.png"], &dir);
    assert!(!text(&out.stderr).contains("sees nothing"));
}

/// A misspelt property name in a scene is answered with the nearest valid one.
#[test]
fn misspelt_property_suggests_the_valid_name() {
    let dir = temp_dir("typo-prop");
    let scene = ao_scene(8, 8, 1).replace(
        r#"<integer name="height" value="8"/>"#,
        r#"<integer name="height" value="8"/><float name="fvo" value="40"/>"#,
    );
    std::fs::write(dir.join("typo.xml"), scene).unwrap();
    let out = lightpath(&["render", "typo.xml", "-o", "t.png"], &dir);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(
        err.contains("unknown property `fvo`") && err.contains("did you mean `fov`?"),
        "{err}"
    );
    assert!(err.contains("typo.xml:"), "the error names the file: {err}");
}
