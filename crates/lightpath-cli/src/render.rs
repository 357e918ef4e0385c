//! `lightpath render`: render a scene file (or the built-in scene) to an image,
//! progressively: `--time` stops at a time budget, `--preview` rewrites a preview image
//! as passes finish, `--tev` streams the passes to the tev viewer.

use crate::record::RayRecorder;
use crate::stats::Report;
use crate::summary::{by_kind, bytes, SceneSummary};
use crate::tev::Tev;
use crate::tonemap::{self, ToneArgs};
use crate::{default_scene, duration, names, progress, RenderOptions};
use anyhow::{Context, Result};
use lightpath::film::Image;
use lightpath::integrator::{AovLayer, Integrator};
use lightpath::io::image::ExrChannel;
use lightpath::io::{self, LoadedScene};
use lightpath::render::{RayBatch, RenderControl, RenderStats, Rendered, Renderer};
use lightpath::scene::CropWindow;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Scene file: lightwave or Mitsuba 3 XML, or glTF 2.0 (.gltf, .glb).
    /// Without it, renders the built-in default scene.
    pub scene: Option<PathBuf>,
    /// Output image; the extension picks the format (.png, tone mapped; .exr or .hdr,
    /// linear).
    #[arg(short, long, default_value = "render.png")]
    pub output: PathBuf,
    /// Extra layers to write into the EXR output beside the image, from the first hit of
    /// each camera sample, averaged like the image: albedo (albedo.R/G/B: the material's
    /// colour), normal (normal.X/Y/Z: shading normal in render space), depth (depth.Z:
    /// distance along the camera ray, averaged over the samples that hit, +inf where none
    /// does). Comma-separated; needs an .exr output.
    #[arg(long, value_parser = names::AOVS, value_delimiter = ',', value_name = "LAYERS")]
    pub aov: Vec<String>,
    /// Stop after this much rendering time (e.g. 500ms, 2s, 1.5m), at the end of a pass
    /// so every pixel has the same number of samples. Without --spp, samples are
    /// unlimited.
    #[arg(long, value_parser = duration::parse, value_name = "DURATION")]
    pub time: Option<Duration>,
    /// Rewrite this PNG (atomically, tone mapped) with the image so far as passes finish.
    #[arg(long, value_name = "FILE.png")]
    pub preview: Option<PathBuf>,
    /// Minimum time between preview updates.
    #[arg(long, value_parser = duration::parse, default_value = "5s", value_name = "DURATION")]
    pub every: Duration,
    /// Stream the image to the tev viewer at HOST:PORT as it renders (tev listens on
    /// 127.0.0.1:14158 by default). A missing viewer is a warning.
    #[arg(long, value_name = "HOST:PORT")]
    pub tev: Option<String>,
    /// Render only this rectangle of the image (X and Y of its top-left pixel, its width
    /// and height), its pixels exactly as in the whole image; the output is the
    /// rectangle alone. Replaces a crop window the scene sets.
    #[arg(long, value_parser = parse_crop, value_name = "X,Y,W,H")]
    pub crop: Option<CropWindow>,
    /// Print render statistics (times, samples, rays, traversal work) to stdout.
    #[arg(long)]
    pub stats: bool,
    /// Write render statistics as JSON to FILE (atomically).
    #[arg(long, value_name = "FILE")]
    pub stats_json: Option<PathBuf>,
    /// Log what was loaded: instances, meshes, triangles, lights, accelerator memory.
    #[arg(short, long)]
    pub verbose: bool,
    /// Write the path tracer's rays into DIR as it traces them (paths.rays: closest-hit
    /// queries; shadow.rays: occlusion queries; embree-bench's ray format) with the
    /// scene's triangles (scene.obj), for timing a tracer on a real workload:
    /// `lightpath bench DIR/scene.obj --rays DIR --packet`. Needs the path tracer, a
    /// scene whose geometry merges into one triangle mesh, and the AVX2 tier.
    #[arg(long, value_name = "DIR")]
    pub record_rays: Option<PathBuf>,
    #[command(flatten)]
    pub tone: ToneArgs,
    #[command(flatten)]
    pub options: RenderOptions,
}

/// `--crop X,Y,W,H`: four whole numbers, the size not zero (whether the rectangle fits
/// the image is checked when it renders).
fn parse_crop(text: &str) -> std::result::Result<CropWindow, String> {
    let v: Vec<u32> = text
        .split(',')
        .map(|t| t.trim().parse::<u32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("expected X,Y,W,H (four whole numbers), got `{text}`"))?;
    let [x, y, w, h] = v[..] else {
        return Err(format!(
            "expected X,Y,W,H (four whole numbers), got `{text}`"
        ));
    };
    if w == 0 || h == 0 {
        return Err(format!("the crop window `{text}` is empty"));
    }
    Ok(CropWindow {
        offset: lightpath::math::UVec2::new(x, y),
        size: lightpath::math::UVec2::new(w, h),
    })
}

/// Time between passes when streaming to tev without a preview.
const TEV_INTERVAL: Duration = Duration::from_secs(1);

pub fn run(args: RenderArgs) -> Result<()> {
    args.options.init_threads()?;
    args.tone.check()?;
    let ext = io::extension(&args.output);
    if !matches!(ext.as_str(), "png" | "exr" | "hdr") {
        anyhow::bail!(
            "{}: unsupported output format `.{ext}` (use .png, .exr or .hdr)",
            args.output.display()
        );
    }
    if !args.aov.is_empty() && ext != "exr" {
        anyhow::bail!(
            "{}: --aov writes layers into an EXR; use an .exr output",
            args.output.display()
        );
    }
    let layers = aov_layers(&args.aov);
    if let Some(p) = &args.preview {
        if !tonemap::is_display(p) {
            anyhow::bail!("{}: the preview is a display image; use .png", p.display());
        }
    }
    let quiet = args.options.quiet;
    crate::logger::init(quiet, args.verbose);
    let load = args.options.load_options()?;
    let start = Instant::now();
    let spinner = progress::spinner("loading scene and building accelerators", quiet);
    let loaded = match &args.scene {
        Some(path) => io::load_scene(path, &load),
        None => default_scene::load(&load),
    };
    spinner.finish_and_clear();
    let mut loaded = loaded?;
    if args.crop.is_some() {
        loaded.scene.crop = args.crop;
    }
    let load_seconds = start.elapsed().as_secs_f64();
    let summary = SceneSummary::of(&loaded);
    if args.verbose && !quiet {
        eprintln!("{}", loaded_log(&loaded, &summary, load_seconds));
    }
    if !quiet && camera_sees_nothing(&loaded) {
        eprintln!(
            "warning: the camera sees nothing: no ray through a 16x16 grid of the image hits \
             a surface and there is no environment light"
        );
    }
    if !quiet && summary.is_dark() && needs_light(&loaded.integrator) {
        eprintln!(
            "warning: the scene has no lights and no emitting surfaces; the image will be black"
        );
    }

    let mut tev = None;
    if let Some(address) = &args.tev {
        let name = args
            .output
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "lightpath".into());
        let (client, warning) = Tev::connect(address, &name);
        if let (Some(w), false) = (warning, quiet) {
            eprintln!("warning: {w}");
        }
        tev = Some(client).filter(Tev::connected);
    }
    let interval = match (&args.preview, &tev) {
        (Some(_), Some(_)) => Some(args.every.min(TEV_INTERVAL)),
        (Some(_), None) => Some(args.every),
        (None, Some(_)) => Some(TEV_INTERVAL),
        (None, None) => None,
    };
    let mut live = Live::new(
        args.preview.as_deref().map(|p| (p, args.every)),
        &args.tone,
        tev.as_mut(),
        quiet,
    );
    let recorder = match &args.record_rays {
        Some(dir) => Some(start_recording(&loaded, &args.options, dir)?),
        None => None,
    };
    let rendered = match render_loaded(
        &loaded,
        &args.options,
        args.time,
        interval,
        recorder.as_ref(),
        &mut live,
    ) {
        Ok(rendered) => rendered,
        Err(e) => {
            if let Some(recorder) = recorder {
                recorder.discard();
            }
            return Err(e);
        }
    };
    if let (Some(recorder), Some(dir)) = (recorder, &args.record_rays) {
        let recorded = recorder.finish()?;
        if !quiet {
            eprintln!(
                "recorded {} path rays and {} shadow rays in {}",
                recorded.path_rays,
                recorded.shadow_rays,
                dir.display()
            );
        }
    }

    let write_start = Instant::now();
    if layers.is_empty() {
        tonemap::write(&args.output, &rendered.image, &args.tone)?;
    } else {
        let channels = render_aovs(&loaded, &args.options, rendered.spp, &layers)?;
        io::image::write_exr_channels(&args.output, &rendered.image, &channels)
            .context("writing the image")?;
    }
    let write_seconds = write_start.elapsed().as_secs_f64();

    let stats = rendered.stats;
    if !quiet {
        eprintln!(
            "wrote {} ({} spp in {} passes, {:.2} s, {}samples/s, {}rays/s)",
            args.output.display(),
            rendered.spp,
            rendered.passes,
            stats.seconds,
            rate(stats.samples, stats.seconds),
            rate(stats.rays, stats.seconds),
        );
        if stats.non_finite_samples > 0 {
            eprintln!(
                "warning: {} NaN/infinite samples were discarded",
                stats.non_finite_samples
            );
        }
    }
    if args.stats || args.stats_json.is_some() {
        let report = Report {
            load_seconds,
            render_seconds: stats.seconds,
            write_seconds,
            stats,
            accel_bytes: summary.accel_bytes,
            accel: loaded.scene.accel_report(),
            width: rendered.image.width,
            height: rendered.image.height,
            spp: rendered.spp,
            passes: rendered.passes,
        };
        if args.stats {
            println!("{}", report.table());
        }
        if let Some(path) = &args.stats_json {
            report.write_json(path)?;
        }
    }
    Ok(())
}

/// The requested layers, each once, in the order `AovLayer::NAMES` lists them.
fn aov_layers(names: &[String]) -> Vec<AovLayer> {
    AovLayer::NAMES
        .iter()
        .filter(|n| names.iter().any(|m| m == *n))
        .filter_map(|n| AovLayer::from_name(n))
        .collect()
}

/// The AOV channels of `layers` at `spp` samples per pixel (the image's own camera rays).
fn render_aovs(
    loaded: &LoadedScene,
    options: &RenderOptions,
    spp: u32,
    layers: &[AovLayer],
) -> Result<Vec<ExrChannel>> {
    let camera = loaded
        .scene
        .camera
        .as_ref()
        .context("the scene has no camera")?;
    let sampler = options.sampler(&loaded.sampler)?;
    let integrator = options.integrator(&loaded.integrator)?;
    let renderer = Renderer {
        scene: &loaded.scene,
        camera,
        integrator: &integrator,
        sampler: &sampler,
    };
    let aovs = renderer.render_aovs(spp)?;
    let mut channels = Vec::new();
    for layer in layers {
        let names = layer.channels();
        match layer {
            AovLayer::Albedo | AovLayer::Normal => {
                let image = if *layer == AovLayer::Albedo {
                    &aovs.albedo
                } else {
                    &aovs.normal
                };
                for (c, name) in names.iter().enumerate() {
                    channels.push(ExrChannel {
                        name: name.to_string(),
                        values: image.pixels.iter().map(|p| p[c]).collect(),
                    });
                }
            }
            AovLayer::Depth => channels.push(ExrChannel {
                name: names[0].to_string(),
                values: aovs.depth.clone(),
            }),
        }
    }
    Ok(channels)
}

/// `1.23 M` per second, for the summary line.
fn rate(n: u64, seconds: f64) -> String {
    format!("{} ", progress::si(n as f64 / seconds.max(1e-9)))
}

/// Integrators whose images come from light (the others show geometry).
fn needs_light(integrator: &Integrator) -> bool {
    matches!(
        integrator,
        Integrator::Direct(_) | Integrator::PathTracer(_)
    )
}

/// The `--verbose` log of what was loaded.
fn loaded_log(loaded: &LoadedScene, s: &SceneSummary, seconds: f64) -> String {
    let mut lines = vec![format!(
        "loaded {} in {seconds:.3} s (incl. accelerator build)",
        loaded.path.display()
    )];
    lines.push(format!("  instances   {}", by_kind(&s.shapes)));
    lines.push(format!(
        "  meshes      {} distinct, {} triangles ({} counting instances)",
        s.meshes, s.triangles, s.instanced_triangles
    ));
    lines.push(format!("  lights      {}", by_kind(&s.lights)));
    lines.push(format!("  materials   {}", s.material_count()));
    lines.push(format!("  accelerator {}", bytes(s.accel_bytes)));
    if let Some((kind, w, h)) = &s.camera {
        lines.push(format!("  camera      {kind}, {w}x{h}"));
    }
    lines.push(format!(
        "  integrator  {}, sampler {} ({} spp in the scene)",
        s.integrator, s.sampler, s.spp
    ));
    lines.join("\n")
}

/// What happens between passes: previews and tev updates.
pub struct Live<'a> {
    pub preview: Option<(&'a Path, Duration)>,
    pub tone: &'a ToneArgs,
    pub tev: Option<&'a mut Tev>,
    pub last_preview: Instant,
    pub quiet: bool,
    /// Samples per pixel of the image last shown in the preview and in tev.
    preview_spp: u32,
    tev_spp: u32,
}

impl<'a> Live<'a> {
    pub fn new(
        preview: Option<(&'a Path, Duration)>,
        tone: &'a ToneArgs,
        tev: Option<&'a mut Tev>,
        quiet: bool,
    ) -> Live<'a> {
        Live {
            preview,
            tone,
            tev,
            last_preview: Instant::now(),
            quiet,
            preview_spp: 0,
            tev_spp: 0,
        }
    }

    /// After a pass: warnings to print, if any. `force`: show this image even if the
    /// preview is not due (the final image).
    fn show(&mut self, image: &Image, spp: u32, force: bool) -> Vec<String> {
        let mut warnings = Vec::new();
        if let Some(tev) = self.tev.as_deref_mut() {
            if self.tev_spp != spp {
                self.tev_spp = spp;
                warnings.extend(tev.send(image));
            }
            if !tev.connected() {
                self.tev = None;
            }
        }
        if let Some((path, every)) = self.preview {
            let due = self.last_preview.elapsed() >= every || force;
            if due && self.preview_spp != spp {
                self.last_preview = Instant::now();
                self.preview_spp = spp;
                if let Err(e) = tonemap::write(path, image, self.tone) {
                    warnings.push(format!("preview not written: {e:#}; no more previews"));
                    self.preview = None;
                }
            }
        }
        if self.quiet {
            warnings.clear();
        }
        warnings
    }
}

/// Renders a loaded scene progressively: to `--spp` (or the scene's count), or, with a
/// time budget, until it is spent (unlimited samples without `--spp`).
pub fn render_loaded(
    loaded: &LoadedScene,
    options: &RenderOptions,
    time: Option<Duration>,
    pass_interval: Option<Duration>,
    record: Option<&RayRecorder>,
    live: &mut Live,
) -> Result<Rendered> {
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
    let report = progress::callback(&bar);
    let record_batch = record.map(|r| move |batch: RayBatch<'_>| r.record(batch));
    let control = RenderControl {
        max_spp: match (options.spp, time) {
            (Some(n), _) => Some(n),
            (None, Some(_)) => None,
            (None, None) => Some(sampler.samples_per_pixel().max(1)),
        },
        time_budget: time,
        pass_interval,
        // Passes only serve previews, tev and time budgets.
        single_pass: time.is_none() && pass_interval.is_none(),
        progress: Some(&report),
        ray_batches: record_batch.as_ref().map(|f| f as _),
    };
    let result = renderer.render_progressive(&control, &mut |pass| {
        for w in live.show(pass.image, pass.spp, pass.last) {
            bar.suspend(|| eprintln!("warning: {w}"));
        }
        ControlFlow::Continue(())
    });
    bar.finish_and_clear();
    let rendered = result?;
    // The final image, if the last pass was not shown (a pass abandoned at the time
    // budget, or a preview that was not due).
    for w in live.show(&rendered.image, rendered.spp, true) {
        eprintln!("warning: {w}");
    }
    Ok(rendered)
}

/// The recorder of `--record-rays DIR`, once the render is known to trace its rays in
/// batches ([`Renderer::batches_rays`]), with the scene's triangles written to DIR.
fn start_recording(
    loaded: &LoadedScene,
    options: &RenderOptions,
    dir: &Path,
) -> Result<RayRecorder> {
    let integrator = options.integrator(&loaded.integrator)?;
    let sampler = options.sampler(&loaded.sampler)?;
    let camera = loaded
        .scene
        .camera
        .as_ref()
        .context("the scene has no camera")?;
    let renderer = Renderer {
        scene: &loaded.scene,
        camera,
        integrator: &integrator,
        sampler: &sampler,
    };
    let triangles = loaded.scene.merged_triangles();
    let (Some((positions, indices)), true) = (triangles, renderer.batches_rays()) else {
        anyhow::bail!(
            "--record-rays: this render traces its rays one by one inside the integrator, \
             not in batches; recording needs the path tracer, a scene whose geometry merges \
             into one triangle mesh (no analytic shapes, curves or separately instanced \
             meshes) and a processor with AVX2 (not capped by --simd baseline)"
        );
    };
    RayRecorder::new(dir, positions, indices)
}

/// Renders a loaded scene to the requested samples per pixel.
pub fn render_image(loaded: &LoadedScene, options: &RenderOptions) -> Result<(Image, RenderStats)> {
    let tone = ToneArgs {
        tonemap: "clamp".into(),
        exposure: 0.0,
    };
    let out = render_loaded(
        loaded,
        options,
        None,
        None,
        None,
        &mut Live::new(None, &tone, None, true),
    )?;
    Ok((out.image, out.stats))
}

/// Whether no camera ray through a grid over the image hits anything, with no environment
/// to see either (a camera pointing away from the scene, or a scene with no objects).
pub fn camera_sees_nothing(loaded: &LoadedScene) -> bool {
    let Some(camera) = loaded.scene.camera.as_ref() else {
        return false;
    };
    if loaded.scene.environment.is_some() {
        return false;
    }
    let res = camera.resolution();
    let n = 16;
    for j in 0..n {
        for i in 0..n {
            let film = lightpath::math::Vec2::new(
                (i as f32 + 0.5) / n as f32 * res.x as f32,
                (j as f32 + 0.5) / n as f32 * res.y as f32,
            );
            let sample = lightpath::camera::CameraSample {
                film,
                lens: lightpath::math::Vec2::splat(0.5),
            };
            if let Some(ray) = camera.generate_ray(&sample) {
                if loaded.scene.intersect(&ray).is_some() {
                    return false;
                }
            }
        }
    }
    true
}
