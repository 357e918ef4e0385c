//! `lightpath test`: renders lightwave `<test>` scenes and checks them against their
//! `<id>_ref.exr` with the scene's own limits on mean absolute error and mean error.

use crate::{render, RenderOptions};
use anyhow::{Context, Result};
use lightpath::film::ImageErrors;
use lightpath::io::{self, image::read_image};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct TestArgs {
    /// Test scene files or folders of them.
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    /// Where to write the rendered images (`<id>.exr`).
    #[arg(long, default_value = "test-output")]
    pub out_dir: PathBuf,
    #[command(flatten)]
    pub options: RenderOptions,
}

fn collect(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut entries: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("reading {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|e| io::extension(e) == "xml")
                .collect();
            entries.sort();
            files.extend(entries);
        } else if p.exists() {
            files.push(p.clone());
        } else {
            anyhow::bail!("{}: no such file or folder", p.display());
        }
    }
    Ok(files)
}

/// Runs one test; `Ok(Err(reason))` is a failed test, `Err` a broken one.
fn run_one(file: &Path, args: &TestArgs) -> Result<std::result::Result<String, String>> {
    let loaded = io::load_scene(file, &args.options.load_options()?)?;
    let spec = loaded.test.clone().context("not a <test> scene")?;
    let (image, stats) = render::render_image(&loaded, &args.options)?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("creating {}", args.out_dir.display()))?;
    io::image::write_image(&args.out_dir.join(format!("{}.exr", spec.id)), &image)?;
    let ref_path = file.with_file_name(format!("{}_ref.exr", spec.id));
    let reference = read_image(&ref_path, None)?;
    let Some(e) = ImageErrors::compute(&image, &reference) else {
        return Ok(Err(format!(
            "size {}x{} differs from the reference's {}x{}",
            image.width, image.height, reference.width, reference.height
        )));
    };
    let detail = format!(
        "mae {:.3e} (<= {:.1e}), me {:.3e} (<= {:.1e}), {:.2} s",
        e.mae, spec.mae, e.me, spec.me, stats.seconds
    );
    if e.non_finite > 0 {
        return Ok(Err(format!("{} pixels are NaN or infinite", e.non_finite)));
    }
    if e.mae <= spec.mae && e.me <= spec.me {
        Ok(Ok(detail))
    } else {
        Ok(Err(detail))
    }
}

pub fn run(args: TestArgs) -> Result<bool> {
    args.options.init_threads()?;
    let files = collect(&args.paths)?;
    let (mut passed, mut failed) = (0usize, 0usize);
    for file in &files {
        let name = file.display();
        match run_one(file, &args) {
            Ok(Ok(detail)) => {
                passed += 1;
                println!("PASS {name}: {detail}");
            }
            Ok(Err(detail)) => {
                failed += 1;
                println!("FAIL {name}: {detail}");
            }
            Err(e) => {
                failed += 1;
                let mut msg = e.to_string();
                for c in e.chain().skip(1) {
                    msg.push_str(&format!(": {c}"));
                }
                println!("FAIL {name}: {msg}");
            }
        }
    }
    println!("{passed} passed, {failed} failed");
    Ok(failed == 0)
}
