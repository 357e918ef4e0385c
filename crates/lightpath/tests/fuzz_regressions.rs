//! Inputs the fuzzers (`fuzz/`, cargo-fuzz) found to crash, hang or exhaust memory in a
//! loader, kept as regression tests: each file under `tests/fuzz/<target>/` is run
//! through the same entry points as its fuzz target and must give `Ok` or an `Err`
//! naming the file, never a panic.
//!
//! Targets: `scene_xml` (lightwave and Mitsuba XML scenes), `mesh_ply`, `mesh_obj` (OBJ
//! meshes and OBJ scenes with MTL materials; a line `@@MTL@@` splits an input into the
//! OBJ and its `.mtl`) and `scene_gltf` (`.gltf`, or `.glb` when the input starts with
//! the GLB magic).

use lightpath::io::{load_mesh, load_scene, LoadOptions};
use std::path::{Path, PathBuf};

const SEPARATOR: &[u8] = b"\n@@MTL@@\n";

fn corpus(target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../tests/fuzz/{target}"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.is_file());
    files.sort();
    files
}

/// A fresh folder per input, so inputs cannot see each other's files.
fn workdir(target: &str, input: &Path) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "lightpath-fuzz-regression-{}-{target}-{}",
        std::process::id(),
        input.file_name().unwrap().to_string_lossy()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The error of a failed load must name the file it read.
fn check_error<T>(result: lightpath::Result<T>, input: &Path) {
    if let Err(e) = result {
        let message = e.to_string();
        assert!(
            message.contains("input."),
            "{}: the error does not name the file: {message}",
            input.display()
        );
    }
}

fn run(target: &str, input: &Path) {
    let data = std::fs::read(input).unwrap();
    let dir = workdir(target, input);
    match target {
        "scene_xml" => {
            let path = dir.join("input.xml");
            std::fs::write(&path, &data).unwrap();
            check_error(load_scene(&path, &LoadOptions::default()), input);
        }
        "mesh_ply" => {
            let path = dir.join("input.ply");
            std::fs::write(&path, &data).unwrap();
            check_error(load_mesh(&path), input);
        }
        "mesh_obj" => {
            let (obj, mtl) = match data.windows(SEPARATOR.len()).position(|w| w == SEPARATOR) {
                Some(i) => (&data[..i], &data[i + SEPARATOR.len()..]),
                None => (&data[..], &[][..]),
            };
            std::fs::write(dir.join("input.mtl"), mtl).unwrap();
            let path = dir.join("input.obj");
            std::fs::write(&path, obj).unwrap();
            check_error(load_mesh(&path), input);
            check_error(load_scene(&path, &LoadOptions::default()), input);
        }
        "scene_gltf" => {
            let ext = if data.starts_with(b"glTF") {
                "glb"
            } else {
                "gltf"
            };
            let path = dir.join(format!("input.{ext}"));
            std::fs::write(&path, &data).unwrap();
            check_error(load_scene(&path, &LoadOptions::default()), input);
        }
        other => panic!("unknown fuzz target {other}"),
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn run_target(target: &str) {
    let inputs = corpus(target);
    for input in &inputs {
        run(target, input);
    }
    eprintln!("{target}: {} regression inputs", inputs.len());
}

#[test]
fn scene_xml_regressions() {
    run_target("scene_xml");
}

#[test]
fn mesh_ply_regressions() {
    run_target("mesh_ply");
}

#[test]
fn mesh_obj_regressions() {
    run_target("mesh_obj");
}

#[test]
fn scene_gltf_regressions() {
    run_target("scene_gltf");
}
