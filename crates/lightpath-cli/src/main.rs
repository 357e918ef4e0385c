//! `lightpath`: render scenes, run the course's test scenes, compare images.

mod bench;
mod compare;
mod completions;
mod default_scene;
mod duration;
mod fsutil;
mod heatmap;
mod info;
mod logger;
mod names;
mod progress;
mod rays;
mod record;
mod render;
mod stats;
mod summary;
mod test;
mod tev;
mod tonemap;

use anyhow::Result;
use clap::{CommandFactory, Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "lightpath",
    version,
    about = "A physically based ray tracer",
    propagate_version = true
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Highest vector instruction tier to use: baseline (SSE2), avx2 or avx512 (default:
    /// the processor's highest). Every tier gives the same images and hits bit for bit,
    /// except where a ray hits two triangles at exactly the same distance; a lower one
    /// is for comparing tiers' speeds, or for tools such as valgrind that do not decode
    /// the higher tiers' instructions.
    #[arg(long, global = true, value_parser = names::SIMD_TIERS, value_name = "TIER")]
    simd: Option<String>,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image (with no SCENE, a built-in default scene).
    Render(Box<render::RenderArgs>),
    /// Render lightwave test scenes and compare them with their reference images.
    Test(test::TestArgs),
    /// Print error metrics between two images.
    Compare(compare::CompareArgs),
    /// Describe a scene (instances, shapes, triangles, lights, materials, camera,
    /// integrator, sampler, bounds, accelerator memory) without rendering it.
    Info(info::InfoArgs),
    /// Tone map a linear image (EXR) to a display image (PNG).
    Tonemap(tonemap::TonemapArgs),
    /// Trace a ray file against a mesh and write the hits (embree-bench's formats).
    Rays(rays::RaysArgs),
    /// Time the acceleration structures on embree-bench's ray sets.
    Bench(bench::BenchArgs),
    /// Print a shell completion script to stdout.
    Completions(completions::CompletionsArgs),
    /// Print the man page (roff) to stdout.
    Man,
}

fn main() {
    logger::init(false, false);
    let cli = Cli::parse();
    if let Some(tier) = cli.simd.as_deref().and_then(lightpath::SimdTier::from_name) {
        lightpath::limit_simd_tier(tier);
    }
    let result: Result<bool> = match cli.command {
        Command::Render(args) => render::run(*args).map(|_| true),
        Command::Test(args) => test::run(args),
        Command::Compare(args) => compare::run(args).map(|_| true),
        Command::Info(args) => info::run(args).map(|_| true),
        Command::Tonemap(args) => tonemap::run(args).map(|_| true),
        Command::Rays(args) => rays::run(args).map(|_| true),
        Command::Bench(args) => bench::run(args).map(|_| true),
        Command::Completions(args) => completions::completions(args, Cli::command()).map(|_| true),
        Command::Man => completions::man(Cli::command()).map(|_| true),
    };
    match result {
        Ok(true) => {}
        Ok(false) => std::process::exit(1),
        Err(e) => {
            // One line: the library's errors already carry file:line:col.
            let mut msg = format!("error: {e}");
            for cause in e.chain().skip(1) {
                // Errors that show their source in their own message (the library's
                // I/O errors) would otherwise print it twice.
                let cause = cause.to_string();
                if !msg.contains(&cause) {
                    msg.push_str(&format!(": {cause}"));
                }
            }
            eprintln!("{msg}");
            std::process::exit(1);
        }
    }
}

/// Shared options of commands that render.
#[derive(clap::Args, Clone)]
pub struct RenderOptions {
    /// Samples per pixel (overrides the scene's sampler).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Acceleration structure: list, bvh2, bvh4, bvh8, bvh2-hq, bvh4-hq, bvh8-hq (their
    /// high-quality builds: slower, lower SAH cost), bvh-course, grid, octree, kdtree, bsp
    /// (default: bvh8; lightwave scenes with the `bvh` statistics view use bvh-course,
    /// the course's BVH).
    #[arg(long, value_parser = names::ACCELS, value_name = "KIND")]
    pub accel: Option<String>,
    /// Sampler: independent, sobol or halton (default: the scene's).
    #[arg(long, value_parser = names::SAMPLERS, value_name = "KIND")]
    pub sampler: Option<String>,
    /// Clamp each path's contribution to this value per channel (biased; off by default).
    #[arg(long)]
    pub clamp: Option<f32>,
    /// Seed of the random sequences.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Scene parameter substitution `$name` -> value (repeatable).
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub defines: Vec<String>,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
    /// Mitsuba scenes: turn unsupported plugins and parameters into warnings and render
    /// with the documented fallbacks (unknown BSDFs as diffuse 0.5, unknown textures as
    /// 0.5 grey, unknown emitters and shapes left out, ...) instead of failing.
    #[arg(long)]
    pub lenient: bool,
}

impl RenderOptions {
    pub fn load_options(&self) -> Result<lightpath::io::LoadOptions> {
        let accel = match &self.accel {
            None => None,
            Some(name) => Some(lightpath::accel::AccelKind::from_name(name).ok_or_else(|| {
                anyhow::anyhow!(names::unknown(
                    "--accel",
                    name,
                    lightpath::accel::AccelKind::NAMES
                ))
            })?),
        };
        let mut defines = Vec::new();
        for d in &self.defines {
            let (k, v) = d
                .split_once('=')
                .ok_or_else(|| anyhow::anyhow!("-D expects NAME=VALUE, got `{d}`"))?;
            defines.push((k.to_string(), v.to_string()));
        }
        Ok(lightpath::io::LoadOptions {
            accel,
            defines,
            lenient: self.lenient,
        })
    }

    /// Sets up the global thread pool.
    pub fn init_threads(&self) -> Result<()> {
        if let Some(n) = self.threads {
            if n == 0 {
                anyhow::bail!("--threads must be at least 1");
            }
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build_global()?;
        }
        Ok(())
    }

    /// The sampler after command-line overrides.
    pub fn sampler(
        &self,
        s: &lightpath::sampling::Sampler,
    ) -> Result<lightpath::sampling::Sampler> {
        let mut s = s.clone();
        if let Some(spp) = self.spp {
            if spp == 0 {
                anyhow::bail!("--spp must be at least 1");
            }
            s = s.with_samples_per_pixel(spp);
        }
        if let Some(seed) = self.seed {
            s = s.with_seed(seed);
        }
        if let Some(kind) = &self.sampler {
            s = s.with_kind(kind).ok_or_else(|| {
                anyhow::anyhow!(names::unknown("--sampler", kind, names::SAMPLERS.names))
            })?;
        }
        Ok(s)
    }

    /// The integrator after command-line overrides (`--clamp`).
    pub fn integrator(
        &self,
        i: &lightpath::integrator::Integrator,
    ) -> Result<lightpath::integrator::Integrator> {
        use lightpath::integrator::Integrator;
        let mut i = i.clone();
        if let Some(c) = self.clamp {
            if c.is_nan() || c <= 0.0 {
                anyhow::bail!("--clamp must be positive, got {c}");
            }
            match &mut i {
                Integrator::PathTracer(p) => p.clamp = Some(c),
                _ => anyhow::bail!("--clamp applies to the pathtracer integrator only"),
            }
        }
        Ok(i)
    }
}
