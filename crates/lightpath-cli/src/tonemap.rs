//! Tone mapping options of display outputs, and `lightpath tonemap IN -o OUT.png`.

use crate::names;
use anyhow::{Context, Result};
use lightpath::film::{Image, Tonemap};
use lightpath::io::{self, image::read_image};
use std::path::{Path, PathBuf};

/// How display outputs (PNG images and previews) are made from linear radiance. EXR/HDR
/// output stays linear and untouched.
#[derive(clap::Args, Clone, Debug)]
pub struct ToneArgs {
    /// Tone mapping of display outputs (PNG, previews; EXR and HDR stay linear):
    /// clamp, reinhard, aces (Narkowicz's fit) or agx (Wrensch's approximation).
    #[arg(long, value_parser = names::TONEMAPS, default_value = "clamp", value_name = "NAME")]
    pub tonemap: String,
    /// Exposure of display outputs in stops: values are multiplied by 2^EV before
    /// tone mapping.
    #[arg(
        long,
        default_value_t = 0.0,
        allow_negative_numbers = true,
        value_name = "EV"
    )]
    pub exposure: f32,
}

impl ToneArgs {
    pub fn check(&self) -> Result<()> {
        if !self.exposure.is_finite() {
            anyhow::bail!("--exposure must be a finite number, got {}", self.exposure);
        }
        Ok(())
    }

    pub fn operator(&self) -> Tonemap {
        // The value parser only lets known names through.
        Tonemap::from_name(&self.tonemap).unwrap_or_default()
    }

    /// The display version of a linear image.
    pub fn display(&self, image: &Image) -> Image {
        self.operator().apply(image, self.exposure)
    }
}

/// Whether `path` is written as a display image (tone mapped, 8-bit sRGB).
pub fn is_display(path: &Path) -> bool {
    io::extension(path) == "png"
}

/// Writes `image` to `path` (atomically): tone mapped for display formats, linear for
/// EXR and HDR.
pub fn write(path: &Path, image: &Image, tone: &ToneArgs) -> Result<()> {
    let result = if is_display(path) {
        io::image::write_image(path, &tone.display(image))
    } else {
        io::image::write_image(path, image)
    };
    // The library's errors name the file.
    result.context("writing the image")
}

#[derive(clap::Args)]
pub struct TonemapArgs {
    /// A linear image (EXR or HDR; PNG and JPEG are sRGB-decoded first).
    pub input: PathBuf,
    /// The display image to write (.png).
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub tone: ToneArgs,
}

pub fn run(args: TonemapArgs) -> Result<()> {
    args.tone.check()?;
    if !is_display(&args.output) {
        anyhow::bail!(
            "{}: the output of `tonemap` is a display image; use .png",
            args.output.display()
        );
    }
    let image = read_image(&args.input, None)?;
    write(&args.output, &image, &args.tone)
}
