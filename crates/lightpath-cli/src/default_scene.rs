//! The scene `lightpath render` draws when given no scene file.

use lightpath::io::{self, LoadOptions, LoadedScene};
use std::path::Path;

/// The built-in scene, in the lightwave dialect.
pub const DEFAULT_SCENE: &str = include_str!("default_scene.xml");

pub fn load(options: &LoadOptions) -> lightpath::Result<LoadedScene> {
    io::load_scene_str(
        DEFAULT_SCENE,
        Path::new("<built-in default scene>.xml"),
        options,
    )
}
