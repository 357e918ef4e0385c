//! Reading and writing images as linear RGB [`Image`]s.
//!
//! The format is chosen by the file extension (case-insensitive):
//!
//! | extension         | read                                  | write                      |
//! |-------------------|---------------------------------------|----------------------------|
//! | `.exr`            | first layer, `R`,`G`,`B` (or `Y`), f16/f32/u32 → f32, linear | RGB f32, ZIP, linear |
//! | `.hdr`            | Radiance RGBE, linear                 | RGBE (~1% precision), linear; negative and NaN → 0 |
//! | `.png`            | 8/16-bit, sRGB-decoded by default     | 8-bit RGB, sRGB-encoded    |
//! | `.jpg`, `.jpeg`   | 8-bit, sRGB-decoded by default        | –                          |
//!
//! Integer (8/16-bit) data is decoded with the exact sRGB transfer function, or the
//! transfer the caller names (a power law, or linear: values just scaled to [0, 1]).
//! Floating-point data (EXR, HDR) is
//! always taken as linear. Grey images become RGB; alpha is dropped. Row 0 of the
//! result is the top row of the image (EXR: the first row of the data window, y
//! increasing downward).
//!
//! Writing goes to a temporary file next to the target (`.name.tmp-<pid>-<n>`),
//! which is renamed over the target once complete, so an error never leaves a
//! half-written image behind; the temporary file is removed on error.

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;

use crate::error::{Error, Result};
use crate::film::Image;

/// The sRGB electro-optical transfer function: encoded value → linear value.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The inverse of [`srgb_to_linear`]: linear value → sRGB-encoded value.
#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Exr,
    Hdr,
    Png,
    Jpeg,
}

fn kind_of(path: &Path) -> Option<Kind> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    Some(match ext.as_str() {
        "exr" => Kind::Exr,
        "hdr" => Kind::Hdr,
        "png" => Kind::Png,
        "jpg" | "jpeg" => Kind::Jpeg,
        _ => return None,
    })
}

fn extension_text(path: &Path) -> String {
    match path.extension() {
        Some(ext) => format!("`.{}`", ext.to_string_lossy()),
        None => "(none)".to_string(),
    }
}

/// How 8/16-bit image data encodes linear values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Transfer {
    /// The exact sRGB curve (the default).
    Srgb,
    /// A pure power law, `linear = encoded^γ` (the lightwave course decodes 8-bit
    /// textures with γ = 2.2).
    Gamma(f32),
    /// Linear data: value / max.
    Linear,
}

impl Transfer {
    #[inline]
    pub fn decode(self, v: f32) -> f32 {
        match self {
            Transfer::Srgb => srgb_to_linear(v),
            Transfer::Gamma(g) => v.powf(g),
            Transfer::Linear => v,
        }
    }
}

/// Reads an image file into linear RGB.
///
/// `transfer` says how 8/16-bit data is encoded (`None`: sRGB). Float data (EXR,
/// HDR) is always linear.
pub fn read_image(path: &Path, transfer: Option<Transfer>) -> Result<Image> {
    match kind_of(path) {
        Some(Kind::Exr) => read_exr(path),
        Some(Kind::Hdr | Kind::Png | Kind::Jpeg) => {
            read_with_image_crate(path, transfer.unwrap_or(Transfer::Srgb))
        }
        None => Err(Error::image(
            path,
            format!(
                "unsupported image extension {} (expected .exr, .hdr, .png, .jpg or .jpeg)",
                extension_text(path)
            ),
        )),
    }
}

fn exr_error(path: &Path, error: exr::error::Error) -> Error {
    match error {
        exr::error::Error::Io(e) => Error::io(path, e),
        other => Error::image(path, format!("cannot read EXR: {other}")),
    }
}

fn read_exr(path: &Path) -> Result<Image> {
    use exr::prelude::traits::*;
    use exr::prelude::FlatSamples;

    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let exr_image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(BufReader::new(file))
        .map_err(|e| exr_error(path, e))?;
    let layer = &exr_image.layer_data;
    let (width, height) = (layer.size.0, layer.size.1);
    let pixel_count = width
        .checked_mul(height)
        .ok_or_else(|| Error::image(path, "image too large"))?;
    let (Ok(w32), Ok(h32)) = (u32::try_from(width), u32::try_from(height)) else {
        return Err(Error::image(path, "image too large"));
    };

    let channels = &layer.channel_data.list;
    // Exact channel name first, then a layer-prefixed one like `beauty.R`.
    let find = |name: &str| {
        channels.iter().find(|c| c.name.eq(name)).or_else(|| {
            let suffix = format!(".{name}");
            channels
                .iter()
                .find(|c| c.name.to_string().ends_with(&suffix))
        })
    };
    let to_f32 = |channel: &exr::prelude::AnyChannel<FlatSamples>| -> Result<Vec<f32>> {
        let values: Vec<f32> = match &channel.sample_data {
            FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
            FlatSamples::F32(v) => v.clone(),
            FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
        };
        if values.len() != pixel_count {
            return Err(Error::image(
                path,
                format!(
                    "EXR channel `{}` has {} samples for {width}x{height} pixels (subsampled channels are not supported)",
                    channel.name,
                    values.len()
                ),
            ));
        }
        Ok(values)
    };

    let pixels: Vec<Vec3> = match (find("R"), find("G"), find("B")) {
        (Some(r), Some(g), Some(b)) => {
            let (r, g, b) = (to_f32(r)?, to_f32(g)?, to_f32(b)?);
            r.iter()
                .zip(&g)
                .zip(&b)
                .map(|((&r, &g), &b)| Vec3::new(r, g, b))
                .collect()
        }
        _ => {
            let grey = find("Y").or(if channels.len() == 1 {
                channels.first()
            } else {
                None
            });
            let Some(grey) = grey else {
                let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
                return Err(Error::image(
                    path,
                    format!(
                        "EXR has no R, G, B or Y channels (channels: {})",
                        names.join(", ")
                    ),
                ));
            };
            to_f32(grey)?.into_iter().map(Vec3::splat).collect()
        }
    };
    Ok(Image {
        width: w32,
        height: h32,
        pixels,
    })
}

fn image_crate_error(path: &Path, error: image::ImageError) -> Error {
    match error {
        image::ImageError::IoError(e) => Error::io(path, e),
        other => Error::image(path, other.to_string()),
    }
}

fn read_with_image_crate(path: &Path, transfer: Transfer) -> Result<Image> {
    Ok(from_decoded(&decode_file(path)?, transfer))
}

/// Decodes a PNG, JPEG or HDR file with the `image` crate.
fn decode_file(path: &Path) -> Result<image::DynamicImage> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = image::ImageReader::new(BufReader::new(file));
    // The extension picks the format; the content overrides it when recognised.
    if let Ok(format) = image::ImageFormat::from_path(path) {
        reader.set_format(format);
    }
    let reader = reader
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    reader.decode().map_err(|e| image_crate_error(path, e))
}

/// Reads a coverage (opacity) map, such as an MTL `map_d`, as grey: the alpha channel
/// where the file has one, else the first channel, 8/16-bit values read linearly
/// (coverage is not a colour).
pub fn read_coverage(path: &Path) -> Result<Image> {
    let image = match kind_of(path) {
        Some(Kind::Hdr | Kind::Png | Kind::Jpeg) => {
            let decoded = decode_file(path)?;
            if decoded.color().has_alpha() {
                return Ok(alpha_from_decoded(&decoded));
            }
            from_decoded(&decoded, Transfer::Linear)
        }
        _ => read_image(path, Some(Transfer::Linear))?,
    };
    Ok(Image {
        pixels: image.pixels.iter().map(|p| Vec3::splat(p.x)).collect(),
        ..image
    })
}

/// Decodes an encoded image (PNG, JPEG, HDR; the format is guessed from the content)
/// held in memory, as embedded images in scene files are; the error says why it cannot.
pub fn read_image_bytes(bytes: &[u8], transfer: Transfer) -> Result<Image, String> {
    let decoded = image::load_from_memory(bytes).map_err(|e| e.to_string())?;
    Ok(from_decoded(&decoded, transfer))
}

/// The alpha channel of an encoded image held in memory (as [`read_image_bytes`] reads
/// its colour), as a grey image: alpha is linear coverage, never sRGB-encoded; an image
/// without alpha is opaque everywhere (1).
pub fn read_alpha_bytes(bytes: &[u8]) -> Result<Image, String> {
    let decoded = image::load_from_memory(bytes).map_err(|e| e.to_string())?;
    Ok(alpha_from_decoded(&decoded))
}

/// The alpha channel of a decoded image as grey (see [`read_alpha_bytes`]).
fn alpha_from_decoded(decoded: &image::DynamicImage) -> Image {
    let (width, height) = (decoded.width(), decoded.height());
    let pixels: Vec<Vec3> = if !decoded.color().has_alpha() {
        vec![Vec3::ONE; width as usize * height as usize]
    } else {
        decoded
            .to_rgba32f()
            .pixels()
            .map(|p| Vec3::splat(p.0[3]))
            .collect()
    };
    Image {
        width,
        height,
        pixels,
    }
}

/// Linear RGB from a decoded image: float data as is, integer data through `transfer`.
fn from_decoded(decoded: &image::DynamicImage, transfer: Transfer) -> Image {
    let (width, height) = (decoded.width(), decoded.height());

    use image::ColorType;
    let color = decoded.color();
    let is_float = matches!(color, ColorType::Rgb32F | ColorType::Rgba32F);
    let is_8bit = color.bytes_per_pixel() == color.channel_count();
    let pixels: Vec<Vec3> = if is_float {
        decoded
            .to_rgb32f()
            .pixels()
            .map(|p| Vec3::from_array(p.0))
            .collect()
    } else if is_8bit {
        let table: [f32; 256] = std::array::from_fn(|i| transfer.decode(i as f32 / 255.0));
        decoded
            .to_rgb8()
            .pixels()
            .map(|p| Vec3::from_array(p.0.map(|c| table[c as usize])))
            .collect()
    } else {
        let decode = |v: u16| transfer.decode(f32::from(v) / 65535.0);
        decoded
            .to_rgb16()
            .pixels()
            .map(|p| Vec3::from_array(p.0.map(decode)))
            .collect()
    };
    Image {
        width,
        height,
        pixels,
    }
}

/// Writes a linear RGB image: `.exr` (f32 RGB, ZIP compression, linear values),
/// `.hdr` (Radiance RGBE, linear; negative and NaN values become 0, infinities the
/// largest RGBE value) or `.png` (8-bit RGB, sRGB-encoded, clamped to [0, 1]).
///
/// The image is written to a temporary file in the target's directory and then
/// renamed over the target, so a failure never leaves a partial file.
pub fn write_image(path: &Path, image: &Image) -> Result<()> {
    let kind = match kind_of(path) {
        Some(kind @ (Kind::Exr | Kind::Hdr | Kind::Png)) => kind,
        _ => {
            return Err(Error::image(
                path,
                format!(
                    "unsupported image extension {} for writing (expected .exr, .hdr or .png)",
                    extension_text(path)
                ),
            ))
        }
    };
    let expected = image.width as usize * image.height as usize;
    if image.pixels.len() != expected {
        return Err(Error::image(
            path,
            format!(
                "image has {} pixels for {}x{}",
                image.pixels.len(),
                image.width,
                image.height
            ),
        ));
    }
    if expected == 0 {
        return Err(Error::image(path, "cannot write an empty image"));
    }

    let temp = temp_path(path)?;
    let result = write_to(&temp, path, kind, image)
        .and_then(|()| std::fs::rename(&temp, path).map_err(|e| Error::io(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    result
}

/// An extra EXR channel: its full name (`albedo.R`, `depth.Z`, ...) and one value per
/// pixel, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct ExrChannel {
    pub name: String,
    pub values: Vec<f32>,
}

/// Writes `image` as an EXR's `R`, `G`, `B` channels (what viewers show by default)
/// with `extra` channels beside them in the same part (f32, ZIP compression), layered
/// by name as viewers expect (`albedo.R` is channel `R` of layer `albedo`). Written
/// atomically like [`write_image`].
pub fn write_exr_channels(path: &Path, image: &Image, extra: &[ExrChannel]) -> Result<()> {
    use exr::prelude::{AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes};

    if kind_of(path) != Some(Kind::Exr) {
        return Err(Error::image(
            path,
            format!(
                "extra channels need an EXR file, not {}",
                extension_text(path)
            ),
        ));
    }
    let count = image.width as usize * image.height as usize;
    if image.pixels.len() != count || count == 0 {
        return Err(Error::image(
            path,
            format!(
                "cannot write {} pixels as a {}x{} image",
                image.pixels.len(),
                image.width,
                image.height
            ),
        ));
    }
    let mut channels: exr::prelude::SmallVec<[AnyChannel<FlatSamples>; 4]> = Default::default();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let values = image.pixels.iter().map(|p| p[c]).collect();
        channels.push(AnyChannel::new(*name, FlatSamples::F32(values)));
    }
    for channel in extra {
        if channel.values.len() != count {
            return Err(Error::image(
                path,
                format!(
                    "channel `{}` has {} values for {count} pixels",
                    channel.name,
                    channel.values.len()
                ),
            ));
        }
        if channels.iter().any(|c| c.name.to_string() == channel.name) {
            return Err(Error::image(
                path,
                format!("channel `{}` given twice", channel.name),
            ));
        }
        let name = exr::prelude::Text::new_or_none(&channel.name).ok_or_else(|| {
            Error::image(
                path,
                format!("`{}` is not a valid channel name", channel.name),
            )
        })?;
        channels.push(AnyChannel::new(
            name,
            FlatSamples::F32(channel.values.clone()),
        ));
    }
    let layer = Layer::new(
        (image.width as usize, image.height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    let exr_image = exr::prelude::Image::from_layer(layer);
    write_atomically(path, |writer| {
        use exr::prelude::traits::*;
        exr_image.write().to_buffered(writer).map_err(|e| match e {
            exr::error::Error::Io(e) => Error::io(path, e),
            other => Error::image(path, format!("cannot write EXR: {other}")),
        })
    })
}

/// Runs `write` on a temporary file next to `path`, then renames it over `path`; on
/// error the temporary file is removed.
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    let temp = temp_path(path)?;
    let result = (|| {
        let file = File::create(&temp).map_err(|e| Error::io(path, e))?;
        let mut writer = BufWriter::new(file);
        write(&mut writer)?;
        writer.flush().map_err(|e| Error::io(path, e))?;
        let file = writer
            .into_inner()
            .map_err(|e| Error::io(path, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(path, e))?;
        std::fs::rename(&temp, path).map_err(|e| Error::io(path, e))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    result
}

/// `.name.tmp-<pid>-<n>` next to `path`.
fn temp_path(path: &Path) -> Result<PathBuf> {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let name = path
        .file_name()
        .ok_or_else(|| Error::image(path, "not a file path"))?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    Ok(path.with_file_name(format!(
        ".{}.tmp-{}-{n}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Encodes `image` into the file `temp`; errors name the final `target`.
fn write_to(temp: &Path, target: &Path, kind: Kind, image: &Image) -> Result<()> {
    let file = File::create(temp).map_err(|e| Error::io(target, e))?;
    let mut writer = BufWriter::new(file);
    match kind {
        Kind::Exr => write_exr(&mut writer, target, image)?,
        Kind::Hdr => write_hdr(&mut writer, target, image)?,
        _ => write_png(&mut writer, target, image)?,
    }
    writer.flush().map_err(|e| Error::io(target, e))?;
    let file = writer
        .into_inner()
        .map_err(|e| Error::io(target, e.into_error()))?;
    file.sync_all().map_err(|e| Error::io(target, e))
}

fn write_exr(writer: &mut BufWriter<File>, target: &Path, image: &Image) -> Result<()> {
    use exr::prelude::traits::*;
    use exr::prelude::{Encoding, SpecificChannels, Vec2};

    let width = image.width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = image.pixels[y * width + x];
        (p.x, p.y, p.z)
    });
    let exr_image = exr::prelude::Image::from_encoded_channels(
        (width, image.height as usize),
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    exr_image.write().to_buffered(writer).map_err(|e| match e {
        exr::error::Error::Io(e) => Error::io(target, e),
        other => Error::image(target, format!("cannot write EXR: {other}")),
    })
}

fn write_hdr(writer: &mut BufWriter<File>, target: &Path, image: &Image) -> Result<()> {
    // RGBE stores no sign: negative and NaN values become 0, as do values below its
    // smallest exponent; values beyond its largest exponent (and infinities) saturate.
    let valid = |c: f32| if c >= 1e-37 { c.min(1e38) } else { 0.0 };
    let pixels: Vec<image::Rgb<f32>> = image
        .pixels
        .iter()
        .map(|p| image::Rgb(p.to_array().map(valid)))
        .collect();
    image::codecs::hdr::HdrEncoder::new(writer)
        .encode(&pixels, image.width as usize, image.height as usize)
        .map_err(|e| image_crate_error(target, e))
}

/// Linear value → 8-bit sRGB code (clamped, rounded; NaN → 0).
#[inline]
fn encode_srgb8(c: f32) -> u8 {
    let v = linear_to_srgb(c);
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

fn write_png(writer: &mut BufWriter<File>, target: &Path, image: &Image) -> Result<()> {
    use image::ImageEncoder;

    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| p.to_array().map(encode_srgb8))
        .collect();
    image::codecs::png::PngEncoder::new(writer)
        .write_image(
            &bytes,
            image.width,
            image.height,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| image_crate_error(target, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory under the system temp dir, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new() -> Self {
            static COUNTER: AtomicUsize = AtomicUsize::new(0);
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir()
                .join(format!("lightpath-image-test-{}-{n}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("create temp dir");
            TempDir(dir)
        }

        fn path(&self, name: &str) -> PathBuf {
            self.0.join(name)
        }

        /// Names of the files in the directory.
        fn files(&self) -> Vec<String> {
            let mut names: Vec<String> = std::fs::read_dir(&self.0)
                .expect("read dir")
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// A small deterministic test image with values in [0, scale].
    fn test_image(width: u32, height: u32, scale: f32) -> Image {
        let mut image = Image::new(width, height);
        let mut state = 0x2545_f491_u32;
        for y in 0..height {
            for x in 0..width {
                let mut next = || {
                    state ^= state << 13;
                    state ^= state >> 17;
                    state ^= state << 5;
                    (state >> 8) as f32 / (1u32 << 24) as f32 * scale
                };
                let v = Vec3::new(next(), next(), next());
                image.set(x, y, v);
            }
        }
        image
    }

    #[test]
    fn srgb_functions_invert_each_other() {
        for i in 0..=1000 {
            let c = i as f32 / 1000.0;
            let back = linear_to_srgb(srgb_to_linear(c));
            assert!((back - c).abs() < 2e-6, "{c}: {back}");
            let back = srgb_to_linear(linear_to_srgb(c));
            assert!((back - c).abs() < 2e-6, "{c}: {back}");
        }
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214_041_14).abs() < 1e-6);
        assert!((linear_to_srgb(0.18) - 0.461_356).abs() < 1e-5);
        assert_eq!(srgb_to_linear(0.04045), 0.04045 / 12.92);
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = TempDir::new();
        let path = dir.path("out.exr");
        let mut image = test_image(7, 5, 100.0);
        image.set(0, 0, Vec3::new(1e-8, 1e-38, 1e-42)); // tiny, including subnormal
        image.set(1, 0, Vec3::new(0.0, 65504.0, 3.0e38)); // large
        image.set(2, 0, Vec3::new(-1.5, 1.0 / 3.0, 0.1)); // negative, inexact
        write_image(&path, &image).expect("write");
        let back = read_image(&path, None).expect("read");
        assert_eq!(back.width, 7);
        assert_eq!(back.height, 5);
        for (a, b) in image.pixels.iter().zip(&back.pixels) {
            assert_eq!(
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits)
            );
        }
        assert_eq!(dir.files(), vec!["out.exr".to_string()]);
    }

    #[test]
    fn exr_orientation_top_row_first() {
        let dir = TempDir::new();
        let path = dir.path("rows.exr");
        let mut image = Image::new(2, 3);
        for y in 0..3 {
            for x in 0..2 {
                image.set(x, y, Vec3::new(x as f32, y as f32, 7.0));
            }
        }
        write_image(&path, &image).expect("write");
        // Read back independently of our reader: sample at (x=1, y=2) of the
        // data window, which the exr crate counts from the top.
        let raw = exr::prelude::read_first_flat_layer_from_file(&path).expect("exr read");
        let layer = &raw.layer_data;
        let g = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.eq("G"))
            .expect("G channel");
        assert_eq!(g.sample_data.value_by_flat_index(2 * 2 + 1).to_f32(), 2.0);
        assert_eq!(read_image(&path, None).expect("read"), image);
    }

    #[test]
    fn exr_sample_types_and_grey() {
        use exr::prelude::{f16, AnyChannel, AnyChannels, FlatSamples, SmallVec, WritableImage};
        let dir = TempDir::new();
        let (w, h) = (3usize, 2usize);
        let values: Vec<f32> = (0..w * h).map(|i| i as f32 * 0.5).collect();

        // f16 RGB with an alpha channel, which is ignored.
        let half: Vec<f16> = values.iter().map(|&v| f16::from_f32(v)).collect();
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![
            AnyChannel::new("R", FlatSamples::F16(half.clone())),
            AnyChannel::new("G", FlatSamples::F16(half.clone())),
            AnyChannel::new("B", FlatSamples::F16(half)),
            AnyChannel::new("A", FlatSamples::F16(vec![f16::ONE; w * h])),
        ]));
        let path = dir.path("half.exr");
        exr::prelude::Image::from_channels((w, h), channels)
            .write()
            .to_file(&path)
            .expect("write");
        let image = read_image(&path, None).expect("read");
        assert_eq!((image.width, image.height), (3, 2));
        for (p, v) in image.pixels.iter().zip(&values) {
            assert_eq!(*p, Vec3::splat(*v));
        }

        // A single u32 `Y` channel becomes grey.
        let ints: Vec<u32> = (0..(w * h) as u32).collect();
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
            "Y",
            FlatSamples::U32(ints),
        )]));
        let path = dir.path("grey.exr");
        exr::prelude::Image::from_channels((w, h), channels)
            .write()
            .to_file(&path)
            .expect("write");
        let image = read_image(&path, None).expect("read");
        for (i, p) in image.pixels.iter().enumerate() {
            assert_eq!(*p, Vec3::splat(i as f32));
        }
    }

    #[test]
    fn png_round_trip_within_one_code() {
        let dir = TempDir::new();
        let path = dir.path("out.png");
        let mut image = test_image(9, 4, 1.0);
        image.set(0, 0, Vec3::new(2.0, -1.0, f32::NAN)); // clamped, NaN → 0
        write_image(&path, &image).expect("write");
        let back = read_image(&path, None).expect("read");
        assert_eq!((back.width, back.height), (9, 4));
        assert_eq!(back.get(0, 0), Vec3::new(1.0, 0.0, 0.0));
        for (a, b) in image.pixels.iter().zip(&back.pixels).skip(1) {
            for (a, b) in a.to_array().into_iter().zip(b.to_array()) {
                let (a, b) = (linear_to_srgb(a), linear_to_srgb(b));
                assert!((a - b).abs() <= 0.5 / 255.0 + 1e-5, "{a} vs {b}");
            }
        }
        // As linear data: the raw codes / 255.
        let raw = read_image(&path, Some(Transfer::Linear)).expect("read");
        for (a, b) in back.pixels.iter().zip(&raw.pixels) {
            for (a, b) in a.to_array().into_iter().zip(b.to_array()) {
                assert!((a - srgb_to_linear(b)).abs() < 1e-6);
                assert_eq!((b * 255.0).round() / 255.0, b);
            }
        }
        assert_eq!(dir.files(), vec!["out.png".to_string()]);
    }

    #[test]
    fn grey_alpha_and_16_bit_png() {
        let dir = TempDir::new();
        let path = dir.path("ga.png");
        let grey = image::GrayAlphaImage::from_fn(2, 2, |x, y| {
            image::LumaA([(x * 100 + y * 50) as u8, 10])
        });
        grey.save(&path).expect("save");
        let image = read_image(&path, Some(Transfer::Linear)).expect("read");
        assert_eq!(image.get(1, 1), Vec3::splat(150.0 / 255.0));
        assert_eq!(image.get(0, 1), Vec3::splat(50.0 / 255.0));

        let path = dir.path("rgb16.png");
        let deep = image::ImageBuffer::<image::Rgb<u16>, Vec<u16>>::from_fn(2, 1, |x, _| {
            image::Rgb([0, 32768, if x == 0 { 65535 } else { 1000 }])
        });
        deep.save(&path).expect("save");
        let image = read_image(&path, None).expect("read");
        let p = image.get(1, 0);
        assert_eq!(p.x, 0.0);
        assert!((p.y - srgb_to_linear(32768.0 / 65535.0)).abs() < 1e-6);
        assert!((p.z - srgb_to_linear(1000.0 / 65535.0)).abs() < 1e-7);
        assert_eq!(image.get(0, 0).z, 1.0);
        let linear = read_image(&path, Some(Transfer::Linear)).expect("read");
        assert_eq!(linear.get(1, 0).y, 32768.0 / 65535.0);
    }

    #[test]
    fn jpeg_and_hdr_are_read() {
        let dir = TempDir::new();
        let path = dir.path("flat.jpg");
        image::RgbImage::from_pixel(8, 8, image::Rgb([128, 128, 128]))
            .save(&path)
            .expect("save");
        let image = read_image(&path, None).expect("read");
        let expected = srgb_to_linear(128.0 / 255.0);
        for p in &image.pixels {
            assert!((p.x - expected).abs() < 0.01, "{p}");
        }

        let path = dir.path("radiance.HDR");
        let file = std::fs::File::create(&path).expect("create");
        let pixels = vec![image::Rgb([0.5f32, 2.0, 10.0]); 6];
        image::codecs::hdr::HdrEncoder::new(file)
            .encode(&pixels, 3, 2)
            .expect("encode");
        let image = read_image(&path, None).expect("read");
        assert_eq!((image.width, image.height), (3, 2));
        for p in &image.pixels {
            assert!(
                (*p - Vec3::new(0.5, 2.0, 10.0)).abs().max_element() < 0.05,
                "{p}"
            );
        }
    }

    /// `.hdr` written and read back: values within RGBE precision (8-bit mantissa
    /// sharing the largest channel's exponent: 1/128 of that channel), negatives and NaN
    /// as 0, infinity saturated; the file replaced atomically.
    #[test]
    fn hdr_round_trip_within_rgbe_precision() {
        let dir = TempDir::new();
        let path = dir.path("out.hdr");
        let mut image = test_image(37, 5, 3.0);
        image.set(0, 0, Vec3::new(1e-3, 250.0, 0.7));
        image.set(1, 0, Vec3::new(-1.0, f32::NAN, 0.25));
        image.set(2, 0, Vec3::new(f32::INFINITY, 1.0, 0.0));
        write_image(&path, &image).expect("write");
        let back = read_image(&path, None).expect("read");
        assert_eq!((back.width, back.height), (37, 5));
        for (i, (a, b)) in image.pixels.iter().zip(&back.pixels).enumerate().skip(3) {
            let tolerance = a.max_element() / 128.0;
            assert!((*a - *b).abs().max_element() <= tolerance, "{i}: {a} {b}");
            // The largest channel itself is within 1%.
            assert!((a.max_element() - b.max_element()).abs() <= 0.01 * a.max_element());
        }
        let p = back.get(0, 0);
        assert!((p.y - 250.0).abs() <= 250.0 / 128.0, "{p}");
        assert_eq!(back.get(1, 0).x, 0.0);
        assert_eq!(back.get(1, 0).y, 0.0);
        assert!((back.get(1, 0).z - 0.25).abs() < 0.0025);
        assert!(back.get(2, 0).x > 1e37 && back.get(2, 0).x.is_finite());
        write_image(&path, &Image::new(2, 2)).expect("overwrite");
        assert_eq!(
            read_image(&path, None).expect("read").pixels,
            vec![Vec3::ZERO; 4]
        );
        assert_eq!(dir.files(), vec!["out.hdr"]);
    }

    /// Extra channels sit beside R, G, B; the image still reads back as before; bad
    /// requests are errors that leave nothing behind.
    #[test]
    fn exr_with_extra_channels() {
        let dir = TempDir::new();
        let path = dir.path("layers.exr");
        let image = test_image(5, 3, 2.0);
        let depth = ExrChannel {
            name: "depth.Z".into(),
            values: (0..15).map(|i| i as f32).collect(),
        };
        write_exr_channels(&path, &image, std::slice::from_ref(&depth)).expect("write");
        assert_eq!(read_image(&path, None).expect("read"), image);
        let read = exr::prelude::read_all_flat_layers_from_file(&path).expect("read");
        let channel = read.layer_data[0]
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == "depth.Z")
            .expect("depth.Z");
        assert!(
            matches!(&channel.sample_data, exr::prelude::FlatSamples::F32(v) if *v == depth.values)
        );
        let short = ExrChannel {
            name: "a.Z".into(),
            values: vec![0.0; 3],
        };
        let twice = ExrChannel {
            name: "G".into(),
            values: vec![0.0; 15],
        };
        for (name, extra) in [("x.exr", &short), ("y.exr", &twice), ("z.png", &depth)] {
            let result = write_exr_channels(&dir.path(name), &image, std::slice::from_ref(extra));
            assert!(
                matches!(result, Err(Error::Image { .. })),
                "{name}: {result:?}"
            );
        }
        assert_eq!(dir.files(), vec!["layers.exr"]);
    }

    #[test]
    fn bad_extensions_are_errors() {
        let dir = TempDir::new();
        let image = Image::new(1, 1);
        for name in ["out.bmp", "out", "out.tiff", "out.jpg"] {
            let result = write_image(&dir.path(name), &image);
            assert!(
                matches!(result, Err(Error::Image { .. })),
                "{name}: {result:?}"
            );
        }
        let result = read_image(&dir.path("in.bmp"), None);
        let message = result.expect_err("unsupported").to_string();
        assert!(message.contains(".bmp"), "{message}");
        assert!(dir.files().is_empty());
    }

    #[test]
    fn unreadable_files_are_errors() {
        let dir = TempDir::new();
        for name in ["missing.exr", "missing.png", "missing.hdr"] {
            let result = read_image(&dir.path(name), None);
            assert!(
                matches!(result, Err(Error::Io { .. })),
                "{name}: {result:?}"
            );
        }
        for name in ["garbage.exr", "garbage.png", "garbage.jpg", "garbage.hdr"] {
            let path = dir.path(name);
            std::fs::write(&path, b"this is not an image at all").expect("write");
            let result = read_image(&path, None);
            assert!(
                matches!(result, Err(Error::Image { .. } | Error::Io { .. })),
                "{name}: {result:?}"
            );
        }
    }

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = TempDir::new();
        let image = test_image(4, 4, 1.0);
        // The target's directory does not exist.
        let result = write_image(&dir.path("no-such-dir/out.exr"), &image);
        assert!(matches!(result, Err(Error::Io { .. })), "{result:?}");
        // Inconsistent pixel count.
        let mut broken = image.clone();
        broken.pixels.pop();
        assert!(write_image(&dir.path("broken.png"), &broken).is_err());
        // The target is a directory: encoding succeeds, the rename fails.
        std::fs::create_dir(dir.path("taken.png")).expect("mkdir");
        assert!(write_image(&dir.path("taken.png"), &image).is_err());
        assert_eq!(dir.files(), vec!["taken.png".to_string()]);
    }

    #[test]
    fn overwrites_existing_file() {
        let dir = TempDir::new();
        let path = dir.path("out.png");
        std::fs::write(&path, b"old").expect("write");
        let image = Image::new(2, 2);
        write_image(&path, &image).expect("write");
        assert_eq!(read_image(&path, None).expect("read"), image);
    }

    /// The lightwave reference renders, when present: half-float RGB, ZIP.
    #[test]
    fn reference_exr() {
        let path =
            Path::new("/work/shared/anchors/lightwave/tests/practical_1/sphere_outside_ref.exr");
        if !path.exists() {
            eprintln!("skipped: {} not present", path.display());
            return;
        }
        let image = read_image(path, None).expect("read");
        assert!(image.width > 0 && image.height > 0);
        assert_eq!(image.pixels.len(), (image.width * image.height) as usize);
        assert!(image.pixels.iter().all(|p| p.is_finite()));
        assert_eq!((image.width, image.height), (512, 512));
        // A normals AOV (n * 0.5 + 0.5) of a sphere seen by lightwave's camera,
        // whose image y axis points down (camera -y is the top of the image): the
        // top of the sphere has a small green value, the bottom a large one. Row 0
        // being the top row of the image puts them where the picture shows them.
        let top = image.get(256, 70);
        let bottom = image.get(256, 440);
        assert!(top.y < 0.2 && bottom.y > 0.8, "top {top}, bottom {bottom}");
        let left = image.get(70, 256);
        let right = image.get(440, 256);
        assert!(left.x < 0.2 && right.x > 0.8, "left {left}, right {right}");
    }
}
