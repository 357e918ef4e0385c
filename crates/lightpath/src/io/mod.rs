//! Input and output: scene dialects, mesh formats and image formats.

pub mod curves;
pub mod gltf;
pub mod image;
pub mod lens;
pub mod lightwave;
pub mod mitsuba;
pub mod mtl;
pub mod obj;
pub mod ply;
pub mod props;
pub mod serialized;
pub mod xml;

use crate::accel::AccelKind;
use crate::error::{Error, Result};
use crate::geometry::MeshData;
use crate::integrator::Integrator;
use crate::sampling::Sampler;
use crate::scene::Scene;
use std::path::{Path, PathBuf};

/// A scene file's test limits (lightwave `<test>`): the rendered image passes when its
/// mean absolute error is at most `mae` and its absolute mean error at most `me`.
#[derive(Debug, Clone, PartialEq)]
pub struct TestSpec {
    pub id: String,
    pub mae: f64,
    pub me: f64,
}

/// Everything a scene file describes.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    pub scene: Scene,
    pub integrator: Integrator,
    pub sampler: Sampler,
    pub test: Option<TestSpec>,
    pub path: PathBuf,
}

impl LoadedScene {
    /// A renderer for the scene as loaded: its camera, integrator and sampler. `None`
    /// when the scene has no camera.
    pub fn renderer(&self) -> Option<crate::render::Renderer<'_>> {
        Some(crate::render::Renderer {
            scene: &self.scene,
            camera: self.scene.camera.as_ref()?,
            integrator: &self.integrator,
            sampler: &self.sampler,
        })
    }
}

/// How to load a scene.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Accelerator for meshes and the top level; `None`: the dialect's default (the
    /// lightwave dialect builds the course's BVH so its statistics views match).
    pub accel: Option<AccelKind>,
    /// `$name` substitutions (`-D name=value`).
    pub defines: Vec<(String, String)>,
    /// Mitsuba scenes: an unsupported plugin or parameter is a warning (logged with the
    /// file and line) and gets the documented fallback, instead of an error.
    pub lenient: bool,
}

/// Loads a scene file. `.gltf` and `.glb` files are glTF 2.0 ([`gltf`]); a `.obj` file
/// is a scene of its own, with its MTL materials ([`obj::load_scene`]); otherwise the XML
/// dialect is recognised from the root element: a root `<scene version="3...">` is a
/// Mitsuba 3 scene, anything else is lightwave.
pub fn load_scene(path: &Path, options: &LoadOptions) -> Result<LoadedScene> {
    if self::gltf::is_gltf(path) {
        return self::gltf::load(path, options);
    }
    if extension(path) == "obj" {
        return obj::load_scene(path, options);
    }
    if let Ok(text) = std::fs::read_to_string(path) {
        if mitsuba::is_mitsuba(&text) {
            return mitsuba::load_str(&text, path, options);
        }
    }
    let root = xml::read_file(path, &options.defines)?;
    lightwave::build(&root, path, options)
}

/// Loads a scene from XML text; relative paths resolve from `path`'s folder.
pub fn load_scene_str(text: &str, path: &Path, options: &LoadOptions) -> Result<LoadedScene> {
    if mitsuba::is_mitsuba(text) {
        return mitsuba::load_str(text, path, options);
    }
    let root = xml::read_str(text, path, &options.defines)?;
    lightwave::build(&root, path, options)
}

/// Loads a triangle mesh, choosing the format by extension (`.ply`, `.obj`, and
/// `.serialized`, whose first mesh it reads).
pub fn load_mesh(path: &Path) -> Result<MeshData> {
    match extension(path).as_str() {
        "ply" => ply::load_ply(path),
        "obj" => obj::load_obj(path),
        "serialized" => serialized::load_serialized(path, 0),
        other => Err(Error::mesh(
            path,
            format!("unsupported mesh format `.{other}` (supported: .ply, .obj, .serialized)"),
        )),
    }
}

/// The lower-case extension of a path.
pub fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

/// The known name closest to `name` (edit distance at most 2), for "did you mean".
pub fn suggest<'a>(name: &str, known: &[&'a str]) -> Option<&'a str> {
    known
        .iter()
        .map(|k| (edit_distance(name, k), *k))
        .filter(|(d, _)| *d <= 2)
        .min_by_key(|(d, _)| *d)
        .map(|(_, k)| k)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + (ca != *cb) as usize)
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions() {
        assert_eq!(suggest("spehre", &["sphere", "mesh"]), Some("sphere"));
        assert_eq!(suggest("xyzzy", &["sphere", "mesh"]), None);
    }
}
