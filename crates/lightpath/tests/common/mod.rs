//! Helpers shared by the integration tests.

use lightpath::io::{load_scene_str, LoadOptions, LoadedScene};
use lightpath::render::Renderer;
use std::path::Path;

/// Renders a lightwave scene given as text with its own integrator and sampler.
#[allow(dead_code)] // not every test file renders from text
pub fn render(xml: &str) -> lightpath::film::Image {
    let loaded = load_scene_str(xml, Path::new("test.xml"), &LoadOptions::default()).unwrap();
    render_loaded(&loaded)
}

/// Renders a loaded scene with its own camera, integrator and sampler.
pub fn render_loaded(loaded: &LoadedScene) -> lightpath::film::Image {
    let camera = loaded.scene.camera.as_ref().unwrap();
    let renderer = Renderer {
        scene: &loaded.scene,
        camera,
        integrator: &loaded.integrator,
        sampler: &loaded.sampler,
    };
    renderer.render(&|_| {}).unwrap().0
}
