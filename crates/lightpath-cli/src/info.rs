//! `lightpath info SCENE`: what a scene holds, without rendering it.

use crate::summary::{by_kind, bytes, SceneSummary};
use crate::{default_scene, RenderOptions};
use anyhow::Result;
use lightpath::io::{self, LoadedScene};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct InfoArgs {
    /// Scene file: lightwave or Mitsuba 3 XML, or glTF 2.0 (.gltf, .glb).
    /// Without it, the built-in default scene.
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub options: RenderOptions,
}

/// The report, one `name  value` line each.
pub fn report(loaded: &LoadedScene, options: &RenderOptions, load_seconds: f64) -> Result<String> {
    let s = SceneSummary::of(loaded);
    let sampler = options.sampler(&loaded.sampler)?;
    let mut lines = vec![("scene", loaded.path.display().to_string())];
    lines.push((
        "camera",
        match &s.camera {
            Some((kind, w, h)) => format!("{kind}, {w}x{h}"),
            None => "none (the scene cannot be rendered)".to_string(),
        },
    ));
    lines.push(("integrator", s.integrator.clone()));
    lines.push((
        "sampler",
        format!(
            "{}, {} spp",
            crate::summary::variant_name(&sampler),
            sampler.samples_per_pixel()
        ),
    ));
    lines.push(("instances", by_kind(&s.shapes)));
    lines.push((
        "meshes",
        format!(
            "{} distinct, {} triangles ({} counting instances)",
            s.meshes, s.triangles, s.instanced_triangles
        ),
    ));
    let lights = if s.is_dark() {
        "0 (no lights and no emitters)".to_string()
    } else {
        by_kind(&s.lights)
    };
    lines.push(("lights", lights));
    lines.push(("emitting instances", s.emitters.to_string()));
    let mut materials = by_kind(&s.materials);
    if s.without_material > 0 {
        materials.push_str(&format!(
            "; {} instances without a material",
            s.without_material
        ));
    }
    lines.push(("materials", materials));
    let unbounded = loaded
        .scene
        .instances
        .iter()
        .filter(|i| !(i.bounds.min.is_finite() && i.bounds.max.is_finite()))
        .count();
    let b = s.bounds;
    let mut bounds = if b.min.cmple(b.max).all() {
        format!(
            "({:.4}, {:.4}, {:.4}) to ({:.4}, {:.4}, {:.4})",
            b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
        )
    } else {
        "empty".to_string()
    };
    if unbounded > 0 {
        bounds.push_str(&format!(", and {unbounded} unbounded instances (planes)"));
    }
    lines.push(("bounds", bounds));
    lines.push(("accelerator memory", bytes(s.accel_bytes)));
    lines.push(("simd tier", lightpath::simd_tier().name().to_string()));
    lines.push((
        "load time",
        format!("{load_seconds:.3} s (incl. accelerator build)"),
    ));
    let width = lines.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
    Ok(lines
        .iter()
        .map(|(k, v)| format!("{k:<width$}  {v}"))
        .collect::<Vec<_>>()
        .join("\n"))
}

pub fn run(args: InfoArgs) -> Result<()> {
    args.options.init_threads()?;
    let load = args.options.load_options()?;
    let start = Instant::now();
    let loaded = match &args.scene {
        Some(path) => io::load_scene(path, &load)?,
        None => default_scene::load(&load)?,
    };
    let seconds = start.elapsed().as_secs_f64();
    println!("{}", report(&loaded, &args.options, seconds)?);
    Ok(())
}
