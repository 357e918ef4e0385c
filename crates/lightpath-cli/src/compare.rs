//! `lightpath compare A B`: error metrics between two images.

use anyhow::{Context, Result};
use lightpath::film::ImageErrors;
use lightpath::io::image::read_image;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The image under test.
    pub test: PathBuf,
    /// The reference image.
    pub reference: PathBuf,
}

pub fn run(args: CompareArgs) -> Result<()> {
    let a = read_image(&args.test, None)?;
    let b = read_image(&args.reference, None)?;
    let e = ImageErrors::compute(&a, &b).with_context(|| {
        format!(
            "image sizes differ: {}x{} vs {}x{}",
            a.width, a.height, b.width, b.height
        )
    })?;
    println!("mae    {:.6e}", e.mae);
    println!("me     {:.6e}", e.me);
    println!("rmse   {:.6e}", e.rmse);
    println!("relmse {:.6e}", e.rel_mse);
    if e.non_finite > 0 {
        println!(
            "non-finite pixels in {}: {}",
            args.test.display(),
            e.non_finite
        );
    }
    Ok(())
}
