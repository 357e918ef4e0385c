//! `lightpath render`: render a scene file (or the built-in scene) to an image.

use crate::{default_scene, progress, RenderOptions};
use anyhow::{Context, Result};
use lightpath::io::{self, LoadedScene};
use lightpath::render::{RenderStats, Renderer};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Scene file (lightwave XML). Without it, renders the built-in default scene.
    pub scene: Option<PathBuf>,
    /// Output image; the extension picks the format (.png or .exr).
    #[arg(short, long, default_value = "render.png")]
    pub output: PathBuf,
    #[command(flatten)]
    pub options: RenderOptions,
}

pub fn run(args: RenderArgs) -> Result<()> {
    args.options.init_threads()?;
    let ext = io::extension(&args.output);
    if ext != "png" && ext != "exr" {
        anyhow::bail!(
            "{}: unsupported output format `.{ext}` (use .png or .exr)",
            args.output.display()
        );
    }
    let load = args.options.load_options()?;
    let loaded = match &args.scene {
        Some(path) => io::load_scene(path, &load)?,
        None => default_scene::load(&load)?,
    };
    let stats = render_to(&loaded, &args.output, &args.options)?;
    if !args.options.quiet {
        eprintln!(
            "wrote {} ({:.2} s, {:.2} M samples/s, {:.2} M rays/s)",
            args.output.display(),
            stats.seconds,
            stats.samples as f64 / stats.seconds.max(1e-9) / 1e6,
            stats.rays as f64 / stats.seconds.max(1e-9) / 1e6
        );
        if stats.non_finite_samples > 0 {
            eprintln!(
                "warning: {} NaN/infinite samples were discarded",
                stats.non_finite_samples
            );
        }
    }
    Ok(())
}

/// Renders a loaded scene and writes it to `output` (atomically).
pub fn render_to(
    loaded: &LoadedScene,
    output: &Path,
    options: &RenderOptions,
) -> Result<RenderStats> {
    let (image, stats) = render_image(loaded, options)?;
    io::image::write_image(output, &image)
        .with_context(|| format!("writing {}", output.display()))?;
    Ok(stats)
}

pub fn render_image(
    loaded: &LoadedScene,
    options: &RenderOptions,
) -> Result<(lightpath::film::Image, RenderStats)> {
    let camera = loaded
        .scene
        .camera
        .as_ref()
        .context("the scene has no camera")?;
    let sampler = options.sampler(&loaded.sampler)?;
    let integrator = options.integrator(&loaded.integrator)?;
    let name = loaded
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let bar = progress::bar(&name, options.quiet);
    let renderer = Renderer {
        scene: &loaded.scene,
        camera,
        integrator: &integrator,
        sampler: &sampler,
    };
    let result = renderer.render(&progress::callback(&bar));
    bar.finish_and_clear();
    Ok(result?)
}
