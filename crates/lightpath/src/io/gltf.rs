//! The glTF 2.0 scene format (`.gltf` JSON with external or `data:` URI buffers and
//! images, or a binary `.glb` container), read with the `gltf` crate.
//!
//! ```sh
//! lightpath render model.glb -o model.png --spp 64
//! ```
//!
//! # What maps to what
//! - **Space.** glTF's coordinates (right-handed, +Y up, metres) are our render space
//!   unchanged. Node transforms (`matrix`, or `translation`/`rotation` quaternion/`scale`)
//!   compose parent × child. The default scene (`scene`, else the first, else every root
//!   node) is loaded.
//! - **Meshes.** Each primitive of a mesh becomes one triangle-mesh shape, built once
//!   (one BLAS) and shared by every node that uses the mesh; each such node places it as
//!   an instance with the primitive's material. Instances appear in depth-first node
//!   order, one per primitive. `POSITION` is required; `NORMAL` (smooth shading),
//!   `TEXCOORD_0` and `COLOR_0` (RGB or RGBA, float or normalized u8/u16; it multiplies
//!   the base colour, its alpha is not read) are optional; indices may be u8/u16/u32 or
//!   absent (non-indexed).
//!   Only `TRIANGLES` primitives are rendered; other modes are skipped with a warning.
//!   glTF's texture origin is the top-left corner (v down) and ours the bottom-left, so
//!   `v` becomes `1 − v`. Tangents, `COLOR_1` and above, skins, morph targets and animations
//!   are ignored (the static bind pose is rendered); sparse accessors are an error.
//! - **Materials** (metallic-roughness) become our `principled` material: base colour =
//!   `baseColorFactor.rgb` × base colour texture (sRGB) × `COLOR_0`, roughness =
//!   `roughnessFactor` × the metallic-roughness texture's G channel, metallic =
//!   `metallicFactor` × its B channel (linear), `specular` 0.5 (a 4 % dielectric
//!   reflectance at normal incidence, as glTF's F0 = 0.04). A `normalTexture` (linear,
//!   its `scale` applied to x and y) wraps it in a `normalmap`. Approximations: the
//!   principled BSDF's Fresnel and lobe weights are the course's model, not glTF's exact
//!   BRDF; `alphaMode` `MASK` cuts the surface out where the base colour's alpha
//!   (`baseColorFactor`'s alpha × the base colour texture's alpha channel, bilinear
//!   unless the sampler says nearest) is below `alphaCutoff` (0.5 by default): camera,
//!   bounce and shadow rays pass through there (see [`crate::geometry::AlphaMask`]), and
//!   a primitive of constant alpha below the cutoff is skipped; `BLEND` is stochastic
//!   transparency: a ray meets the surface with probability alpha, so the image
//!   averages to alpha × the surface + (1 − alpha) × what lies behind (no refraction;
//!   [`crate::geometry::AlphaTest`]); `occlusionTexture` is ignored (a path tracer computes occlusion);
//!   `MIRRORED_REPEAT` is rendered as repeat; minification filters are bilinear; every
//!   texture reads `TEXCOORD_0`. A primitive without a material gets glTF's default
//!   (white, metallic 1, roughness 1).
//! - **Emission**: `emissiveFactor` × emissive texture (sRGB) ×
//!   `KHR_materials_emissive_strength`'s `emissiveStrength` is the radiance of a
//!   one-sided area light (front face: counter-clockwise winding or the vertex normals'
//!   side) on every instance of the primitive.
//! - **Cameras**: the first camera node in depth-first order is used. glTF cameras look
//!   down their −Z with +Y up; ours look down +z with +y down, so the node's transform is
//!   preceded by a 180° turn about x (its scale is removed). Perspective: `yfov` is the
//!   vertical field of view; the image is 480 pixels high and `aspectRatio` × 480 wide
//!   (4:3 without one). Orthographic: `ymag`/`xmag` are the half-height/half-width of
//!   the view, the image 480 pixels high with the aspect `xmag`/`ymag`. Clipping planes
//!   are ignored.
//! - **Lights** (`KHR_lights_punctual`): photometric units map one to one onto ours, so
//!   that the ratios between them hold: a point or spot light of `intensity` I candela
//!   is a radiant intensity of I (our W/sr, irradiance I/r² at distance r), a
//!   directional light of I lux an irradiance of I, and an emissive surface of
//!   luminance L (nits) a radiance of L; `color` multiplies all of them. Spot lights
//!   point down the node's −Z, full inside `innerConeAngle`, dark outside
//!   `outerConeAngle`, with the squared linear ramp in cos θ between that glTF's
//!   specification suggests. `range` is ignored (the inverse-square law applies without
//!   a cutoff).
//! - **Defaults.** Without a camera, a perspective camera (45° vertical field of view,
//!   640×480) looks at the centre of the scene's bounds from the front (+Z) and a little
//!   above, far enough back that the bounding sphere fits. Without any light (no punctual
//!   light and no emissive surface), a uniform white environment (radiance 1) lights the
//!   scene. The integrator is a path tracer (no depth limit, Russian roulette from depth
//!   5), the sampler independent with 64 samples per pixel.
//! - **Errors** name the file; JSON syntax errors give the line and column; everything
//!   else names the object (`mesh 2 "Cube" primitive 0`, `accessor 7`, `buffer 0`, ...).
//!   Ranges of accessors, buffer views and buffers are checked before any data is read,
//!   and non-finite positions or transforms are errors. Required extensions other than
//!   `KHR_lights_punctual` and `KHR_materials_emissive_strength` are errors.

use super::image::{read_alpha_bytes, read_image_bytes, Transfer};
use super::{LoadOptions, LoadedScene};
use crate::camera::{Camera, FovAxis, Orthographic, Perspective};
use crate::error::{Error, Location, Result};
use crate::film::Image;
use crate::geometry::{AlphaMask, AlphaTest, MeshData, Shape, TriangleMesh};
use crate::integrator::{Integrator, PathTracer};
use crate::light::{
    DirectionalLight, Emission, Environment, Light, PointLight, SpotLight, SpotProfile,
};
use crate::material::{Material, NormalMap, Principled};
use crate::math::{Bounds3, Transform};
use crate::sampling::{IndependentSampler, Sampler};
use crate::scene::{Instance, Scene};
use crate::texture::{BorderMode, FilterMode, ImageTexture, Texture};
use ::gltf::accessor::{DataType, Dimensions};
use glam::{Mat4, Quat, UVec2, Vec2, Vec3, Vec4};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Extensions whose meaning we render (a file that requires another one is an error).
const SUPPORTED_EXTENSIONS: &[&str] = &["KHR_lights_punctual", "KHR_materials_emissive_strength"];

/// Image height of glTF cameras and of the default camera.
const IMAGE_HEIGHT: u32 = 480;

/// Samples per pixel of a glTF scene (the CLI's `--spp` overrides it).
const DEFAULT_SPP: u32 = 64;

/// Whether a path names a glTF file (`.gltf` or `.glb`).
pub fn is_gltf(path: &Path) -> bool {
    matches!(super::extension(path).as_str(), "gltf" | "glb")
}

/// Loads a `.gltf` or `.glb` file; external buffers and images resolve from its folder.
pub fn load(path: &Path, options: &LoadOptions) -> Result<LoadedScene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let gltf = parse(path, &bytes)?;
    let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut loader = Loader {
        path: path.to_path_buf(),
        base,
        doc: &gltf.document,
        buffers: Vec::new(),
        images: HashMap::new(),
        textures: HashMap::new(),
        materials: HashMap::new(),
        shapes: HashMap::new(),
        options: options.clone(),
    };
    loader.check_extensions()?;
    loader.buffers = loader.load_buffers(gltf.blob.as_deref())?;
    loader.build()
}

/// The error of a file that does not parse: JSON syntax with its line and column, GLB
/// container problems, or the `gltf` crate's validation (every problem with its JSON
/// path).
/// Parses and validates a glTF document. The `gltf` crate's own validation indexes the
/// accessor of every primitive's `POSITION` without checking it exists (a panic found by
/// fuzzing), so every accessor reference of the meshes is checked first.
fn parse(path: &Path, bytes: &[u8]) -> Result<::gltf::Gltf> {
    let raw =
        ::gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| parse_error(path, e))?;
    let json = raw.document.as_json();
    let accessors = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let attributes = primitive.attributes.values().map(|a| a.value());
            for index in attributes.chain(primitive.indices.as_ref().map(|i| i.value())) {
                if index >= accessors {
                    return Err(Error::scene(
                        Location {
                            file: path.to_path_buf(),
                            line: 0,
                            column: 0,
                        },
                        format!(
                            "mesh {m} primitive {p} refers to accessor {index}, but the file \
                             has {accessors} accessors"
                        ),
                    ));
                }
            }
        }
    }
    let blob = raw.blob;
    let document =
        ::gltf::Document::from_json(raw.document.into_json()).map_err(|e| parse_error(path, e))?;
    Ok(::gltf::Gltf { document, blob })
}

fn parse_error(path: &Path, error: ::gltf::Error) -> Error {
    let at = |line: usize, column: usize| Location {
        file: path.to_path_buf(),
        line: line as u32,
        column: column as u32,
    };
    match error {
        ::gltf::Error::Deserialize(e) => Error::scene(
            at(e.line(), e.column()),
            format!("malformed glTF JSON: {e}"),
        ),
        ::gltf::Error::Validation(problems) => {
            let list: Vec<String> = problems
                .iter()
                .take(8)
                .map(|(p, e)| format!("{p}: {e}"))
                .collect();
            let more = match problems.len() {
                n if n > 8 => format!(" (and {} more)", n - 8),
                _ => String::new(),
            };
            Error::scene(at(0, 0), format!("invalid glTF: {}{more}", list.join("; ")))
        }
        ::gltf::Error::Binary(e) => Error::scene(at(0, 0), format!("malformed GLB container: {e}")),
        ::gltf::Error::Io(e) => Error::io(path, e),
        other => Error::scene(at(0, 0), format!("cannot read glTF: {other}")),
    }
}

/// [`Texel::key`]: the variant and the bits of its numbers.
type TexelKey = (u8, [u32; 3]);

/// How a texture's texels derive from its image's colours `c`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Texel {
    /// `c × factor` (base colour, emission; sRGB images).
    Scaled(Vec3),
    /// Channel `i` of `c` times a factor, as grey (metallic: B, roughness: G; linear).
    Channel(usize, f32),
    /// A tangent-space normal with its x and y scaled by a factor (linear).
    Normal(f32),
    /// The image's alpha channel times a factor, as grey (an alpha mask's coverage).
    Alpha(f32),
}

impl Texel {
    fn space(self) -> ColorSpace {
        match self {
            Texel::Scaled(_) => ColorSpace::Srgb,
            Texel::Channel(..) | Texel::Normal(_) => ColorSpace::Linear,
            Texel::Alpha(_) => ColorSpace::Alpha,
        }
    }

    fn apply(self, c: Vec3) -> Vec3 {
        match self {
            Texel::Scaled(factor) => c * factor,
            Texel::Channel(i, factor) => Vec3::splat(c[i] * factor),
            Texel::Alpha(factor) => Vec3::splat(c.x * factor),
            Texel::Normal(scale) => {
                let n = (2.0 * c - Vec3::ONE) * Vec3::new(scale, scale, 1.0);
                (n + Vec3::ONE) * 0.5
            }
        }
    }

    /// A hashable key for caching.
    fn key(self) -> TexelKey {
        match self {
            Texel::Scaled(f) => (0, f.to_array().map(f32::to_bits)),
            Texel::Channel(i, f) => (1, [i as u32, f.to_bits(), 0]),
            Texel::Normal(f) => (2, [f.to_bits(), 0, 0]),
            Texel::Alpha(f) => (3, [f.to_bits(), 0, 0]),
        }
    }
}

/// A material's alpha applied to a primitive ([`Loader::alpha_cut`]).
enum AlphaCut {
    /// Every point of the surface is there.
    Opaque,
    /// Cut out by a mask.
    Mask(AlphaMask),
    /// A constant alpha that leaves nothing: nothing is there.
    Hidden,
}

/// A glTF material as we render it: the BSDF and the emission, if any.
type BuiltMaterial = (Arc<Material>, Option<Emission>);

/// How an image's 8/16-bit values are decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum ColorSpace {
    Srgb,
    Linear,
    /// Not colour: the alpha channel (linear coverage; 1 where the image has none).
    Alpha,
}

struct Loader<'a> {
    path: PathBuf,
    base: PathBuf,
    doc: &'a ::gltf::Document,
    buffers: Vec<Vec<u8>>,
    /// Decoded images by (image index, colour space).
    images: HashMap<(usize, ColorSpace), Arc<Image>>,
    /// Textures by (texture index, texel derivation), shared by the materials using them.
    textures: HashMap<(usize, TexelKey), Arc<Texture>>,
    /// Materials and emissions by material index (`None`: the default material).
    /// Materials by (glTF material, whether the primitive has vertex colours).
    materials: HashMap<(Option<usize>, bool), BuiltMaterial>,
    /// Shapes by (mesh, primitive); `None` for skipped primitives.
    shapes: HashMap<(usize, usize), Option<Arc<Shape>>>,
    options: LoadOptions,
}

/// A name for messages: `mesh 2 "Cube"`.
fn describe(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{kind} {index} \"{n}\""),
        None => format!("{kind} {index}"),
    }
}

/// Decodes `%xx` escapes of a relative URI.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = uri.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// One component of an accessor element as f64 (exact for every glTF component type).
fn component(bytes: &[u8], data_type: DataType, normalized: bool) -> f64 {
    let v = match data_type {
        DataType::I8 => bytes[0] as i8 as f64,
        DataType::U8 => bytes[0] as f64,
        DataType::I16 => i16::from_le_bytes([bytes[0], bytes[1]]) as f64,
        DataType::U16 => u16::from_le_bytes([bytes[0], bytes[1]]) as f64,
        DataType::U32 => u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64,
        DataType::F32 => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64,
    };
    if !normalized {
        return v;
    }
    match data_type {
        DataType::I8 => (v / 127.0).max(-1.0),
        DataType::U8 => v / 255.0,
        DataType::I16 => (v / 32767.0).max(-1.0),
        DataType::U16 => v / 65535.0,
        _ => v,
    }
}

impl<'a> Loader<'a> {
    fn error(&self, message: impl Into<String>) -> Error {
        Error::scene(
            Location {
                file: self.path.clone(),
                line: 0,
                column: 0,
            },
            message,
        )
    }

    fn check_extensions(&self) -> Result<()> {
        for ext in self.doc.extensions_required() {
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                return Err(self.error(format!(
                    "the file requires the extension {ext}, which lightpath does not support \
                     (supported: {})",
                    SUPPORTED_EXTENSIONS.join(", ")
                )));
            }
        }
        for ext in self.doc.extensions_used() {
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                log::warn!("{}: the extension {ext} is ignored", self.path.display());
            }
        }
        Ok(())
    }

    /// The bytes a URI names: a `data:` URI's payload or a file relative to the glTF
    /// file's folder.
    fn read_uri(&self, uri: &str, what: &str) -> Result<Vec<u8>> {
        if uri.starts_with("data:") {
            return ::gltf::buffer::Data::from_source(::gltf::buffer::Source::Uri(uri), None)
                .map(|d| d.0)
                .map_err(|e| self.error(format!("{what}: cannot decode its data URI: {e}")));
        }
        let relative = if let Some(rest) = uri.strip_prefix("file://") {
            rest
        } else if let Some(rest) = uri.strip_prefix("file:") {
            rest
        } else if uri.contains("://") {
            return Err(self.error(format!(
                "{what}: the URI `{uri}` is not supported (only data: URIs and files)"
            )));
        } else {
            uri
        };
        let decoded = percent_decode(relative)
            .ok_or_else(|| self.error(format!("{what}: malformed URI `{uri}`")))?;
        let file = self.base.join(decoded);
        std::fs::read(&file)
            .map_err(|e| self.error(format!("{what}: cannot read `{}`: {e}", file.display())))
    }

    fn load_buffers(&self, blob: Option<&[u8]>) -> Result<Vec<Vec<u8>>> {
        let mut buffers = Vec::new();
        for buffer in self.doc.buffers() {
            let what = describe("buffer", buffer.index(), buffer.name());
            let data = match buffer.source() {
                ::gltf::buffer::Source::Bin => blob
                    .ok_or_else(|| {
                        self.error(format!(
                            "{what} refers to the GLB binary chunk, but the file has none"
                        ))
                    })?
                    .to_vec(),
                ::gltf::buffer::Source::Uri(uri) => self.read_uri(uri, &what)?,
            };
            if data.len() < buffer.length() {
                return Err(self.error(format!(
                    "{what} has {} bytes, but the file says {}",
                    data.len(),
                    buffer.length()
                )));
            }
            buffers.push(data);
        }
        Ok(buffers)
    }

    /// The bytes of a buffer view, checked against its buffer.
    fn view_bytes(&self, view: &::gltf::buffer::View) -> Result<&[u8]> {
        let buffer = &self.buffers[view.buffer().index()];
        let end = view.offset().checked_add(view.length());
        match end {
            Some(end) if end <= buffer.len() => Ok(&buffer[view.offset()..end]),
            _ => Err(self.error(format!(
                "buffer view {} (bytes {}..{}) is out of range of buffer {} ({} bytes)",
                view.index(),
                view.offset(),
                view.offset() as u128 + view.length() as u128,
                view.buffer().index(),
                buffer.len()
            ))),
        }
    }

    /// An accessor's elements as rows of f64 components, checking its type and that
    /// every byte it reads lies in its buffer view.
    fn read_accessor(
        &self,
        accessor: &::gltf::Accessor,
        what: &str,
        dimensions: Dimensions,
        types: &[DataType],
    ) -> Result<Vec<f64>> {
        let name = format!(
            "{what} ({})",
            describe("accessor", accessor.index(), accessor.name())
        );
        if accessor.dimensions() != dimensions || !types.contains(&accessor.data_type()) {
            return Err(self.error(format!(
                "{name} is {:?} {:?}; expected {dimensions:?} of {types:?}",
                accessor.dimensions(),
                accessor.data_type()
            )));
        }
        if accessor.sparse().is_some() {
            return Err(self.error(format!("{name} is sparse, which is not supported")));
        }
        let n = dimensions.multiplicity();
        let size = accessor.data_type().size();
        let count = accessor.count();
        let Some(view) = accessor.view() else {
            // No buffer view: all zeros.
            return Ok(vec![0.0; count * n]);
        };
        if count == 0 {
            return Ok(Vec::new());
        }
        let data = self.view_bytes(&view)?;
        let element = n * size;
        let stride = view.stride().unwrap_or(element);
        if stride < element {
            return Err(self.error(format!(
                "{name}: buffer view {} has a byte stride of {stride}, less than the \
                 element size {element}",
                view.index()
            )));
        }
        let end =
            (count as u128 - 1) * stride as u128 + element as u128 + accessor.offset() as u128;
        if end > data.len() as u128 {
            return Err(self.error(format!(
                "{name} reads bytes {}..{end} of buffer view {}, which has {} bytes",
                accessor.offset(),
                view.index(),
                data.len()
            )));
        }
        let normalized = accessor.normalized();
        let mut out = Vec::with_capacity(count * n);
        for i in 0..count {
            let start = accessor.offset() + i * stride;
            for c in 0..n {
                let at = start + c * size;
                out.push(component(
                    &data[at..at + size],
                    accessor.data_type(),
                    normalized,
                ));
            }
        }
        Ok(out)
    }

    /// The decoded pixels of image `index`.
    fn image(&mut self, image: ::gltf::Image, space: ColorSpace) -> Result<Arc<Image>> {
        if let Some(i) = self.images.get(&(image.index(), space)) {
            return Ok(i.clone());
        }
        let what = describe("image", image.index(), image.name());
        // Not `image.source()`: it unwraps a missing `mimeType` or `uri` (a panic found by
        // fuzzing). The decoder recognises the format from the bytes.
        let json = &self.doc.as_json().images[image.index()];
        let bytes = match (&json.buffer_view, &json.uri) {
            (Some(view), _) => {
                let view = self.doc.views().nth(view.value()).ok_or_else(|| {
                    self.error(format!(
                        "{what} refers to a missing buffer view {}",
                        view.value()
                    ))
                })?;
                self.view_bytes(&view)?.to_vec()
            }
            (None, Some(uri)) => self.read_uri(uri, &what)?,
            (None, None) => {
                return Err(self.error(format!("{what} has neither a uri nor a bufferView")))
            }
        };
        let decoded = match space {
            ColorSpace::Srgb => read_image_bytes(&bytes, Transfer::Srgb),
            ColorSpace::Linear => read_image_bytes(&bytes, Transfer::Linear),
            ColorSpace::Alpha => read_alpha_bytes(&bytes),
        }
        .map_err(|e| self.error(format!("{what}: cannot decode: {e}")))?;
        if decoded.width == 0 || decoded.height == 0 {
            return Err(self.error(format!("{what} is empty")));
        }
        let decoded = Arc::new(decoded);
        self.images.insert((image.index(), space), decoded.clone());
        Ok(decoded)
    }

    /// A texture whose texels derive from a glTF texture's image by `texel`, built once.
    fn texture(
        &mut self,
        info_texture: ::gltf::Texture,
        tex_coord: u32,
        texel: Texel,
    ) -> Result<Arc<Texture>> {
        let key = (info_texture.index(), texel.key());
        if let Some(t) = self.textures.get(&key) {
            return Ok(t.clone());
        }
        if tex_coord != 0 {
            log::warn!(
                "{}: texture {} uses TEXCOORD_{tex_coord}; TEXCOORD_0 is used instead",
                self.path.display(),
                info_texture.index()
            );
        }
        let source = self.image(info_texture.source(), texel.space())?;
        let mut image = (*source).clone();
        for p in &mut image.pixels {
            *p = texel.apply(*p);
        }
        let sampler = info_texture.sampler();
        use ::gltf::texture::{MagFilter, WrappingMode};
        let border = match (sampler.wrap_s(), sampler.wrap_t()) {
            (WrappingMode::ClampToEdge, WrappingMode::ClampToEdge) => BorderMode::Clamp,
            _ => BorderMode::Repeat,
        };
        let filter = match sampler.mag_filter() {
            Some(MagFilter::Nearest) => FilterMode::Nearest,
            _ => FilterMode::Bilinear,
        };
        let texture = Arc::new(Texture::Image(ImageTexture {
            image: Arc::new(image),
            border,
            filter,
            exposure: 1.0,
        }));
        self.textures.insert(key, texture.clone());
        Ok(texture)
    }

    /// The material (and emission) of a glTF material, built once; with
    /// `vertex_colors` (a primitive with `COLOR_0`), its base colour is multiplied by them.
    fn material(&mut self, m: ::gltf::Material, vertex_colors: bool) -> Result<BuiltMaterial> {
        let key = (m.index(), vertex_colors);
        if let Some(done) = self.materials.get(&key) {
            return Ok(done.clone());
        }
        let pbr = m.pbr_metallic_roughness();
        let factor = Vec4::from_array(pbr.base_color_factor()).truncate();
        let base_color = match pbr.base_color_texture() {
            Some(info) => self.texture(info.texture(), info.tex_coord(), Texel::Scaled(factor))?,
            None => Arc::new(Texture::Constant(factor)),
        };
        let base_color = if vertex_colors {
            Arc::new(Texture::VertexColor(base_color))
        } else {
            base_color
        };
        let (metallic_factor, roughness_factor) = (pbr.metallic_factor(), pbr.roughness_factor());
        let (metallic, roughness) = match pbr.metallic_roughness_texture() {
            Some(info) => (
                self.texture(
                    info.texture(),
                    info.tex_coord(),
                    Texel::Channel(2, metallic_factor),
                )?,
                self.texture(
                    info.texture(),
                    info.tex_coord(),
                    Texel::Channel(1, roughness_factor),
                )?,
            ),
            None => (
                Arc::new(Texture::Constant(Vec3::splat(metallic_factor))),
                Arc::new(Texture::Constant(Vec3::splat(roughness_factor))),
            ),
        };
        let mut material = Arc::new(Material::Principled(Principled {
            base_color,
            roughness,
            metallic,
            specular: Arc::new(Texture::Constant(Vec3::splat(0.5))),
        }));
        if let Some(normal) = m.normal_texture() {
            let texel = Texel::Normal(normal.scale());
            let normal = self.texture(normal.texture(), normal.tex_coord(), texel)?;
            material = Arc::new(Material::NormalMap(NormalMap::new(normal, material)));
        }
        let strength = m.emissive_strength().unwrap_or(1.0);
        let emissive = Vec3::from_array(m.emissive_factor()) * strength;
        let emission = if emissive.max_element() > 0.0 {
            let radiance = match m.emissive_texture() {
                Some(info) => {
                    self.texture(info.texture(), info.tex_coord(), Texel::Scaled(emissive))?
                }
                None => Arc::new(Texture::Constant(emissive)),
            };
            Some(Emission { radiance })
        } else {
            None
        };
        let done = (material, emission);
        self.materials.insert(key, done.clone());
        Ok(done)
    }

    /// What a material's alpha (`baseColorFactor`'s alpha × the base colour texture's
    /// alpha) does to a primitive's surface: `MASK` keeps the points where it is at
    /// least `alphaCutoff` (0.5 by default), `BLEND` makes the surface transparent
    /// stochastically (a ray meets it with probability alpha), `OPAQUE` keeps all.
    fn alpha_cut(&mut self, m: &::gltf::Material) -> Result<AlphaCut> {
        use ::gltf::material::AlphaMode;
        let test = match m.alpha_mode() {
            AlphaMode::Opaque => return Ok(AlphaCut::Opaque),
            AlphaMode::Blend => AlphaTest::Stochastic,
            AlphaMode::Mask => {
                let cutoff = m.alpha_cutoff().unwrap_or(0.5);
                if !cutoff.is_finite() {
                    let what = describe("material", m.index().unwrap_or(0), m.name());
                    return Err(self.error(format!("{what}: alphaCutoff {cutoff} is not finite")));
                }
                AlphaTest::Cutoff(cutoff)
            }
        };
        let pbr = m.pbr_metallic_roughness();
        let factor = pbr.base_color_factor()[3];
        let coverage = match pbr.base_color_texture() {
            Some(info) => self.texture(info.texture(), info.tex_coord(), Texel::Alpha(factor))?,
            None => {
                // A constant alpha: all there, none there, or (blend) partly there.
                let there = match test {
                    AlphaTest::Cutoff(cutoff) => Some(factor >= cutoff),
                    AlphaTest::Stochastic if factor >= 1.0 => Some(true),
                    AlphaTest::Stochastic if factor <= 0.0 => Some(false),
                    AlphaTest::Stochastic => None,
                };
                match there {
                    Some(true) => return Ok(AlphaCut::Opaque),
                    Some(false) => return Ok(AlphaCut::Hidden),
                    None => Arc::new(Texture::Constant(Vec3::splat(factor))),
                }
            }
        };
        Ok(AlphaCut::Mask(AlphaMask { coverage, test }))
    }

    /// The shape of one primitive, built once and shared by every node using its mesh;
    /// `None` if the primitive is skipped.
    fn primitive_shape(
        &mut self,
        mesh: &::gltf::Mesh,
        primitive: &::gltf::Primitive,
    ) -> Result<Option<Arc<Shape>>> {
        let key = (mesh.index(), primitive.index());
        if let Some(s) = self.shapes.get(&key) {
            return Ok(s.clone());
        }
        let what = format!(
            "{} primitive {}",
            describe("mesh", mesh.index(), mesh.name()),
            primitive.index()
        );
        let shape = if primitive.mode() != ::gltf::mesh::Mode::Triangles {
            log::warn!(
                "{}: {what} has mode {:?}; only triangles are rendered, it is skipped",
                self.path.display(),
                primitive.mode()
            );
            None
        } else {
            let data = self.primitive_data(primitive, &what)?;
            if data.indices.is_empty() {
                None
            } else {
                // The cut first: a hidden primitive needs no BVH.
                let cut = self.alpha_cut(&primitive.material())?;
                let build = || {
                    TriangleMesh::new(data, true, self.options.accel.unwrap_or_default())
                        .map_err(|m| self.error(format!("{what}: {m}")))
                };
                match cut {
                    AlphaCut::Opaque => Some(Arc::new(Shape::TriangleMesh(Arc::new(build()?)))),
                    AlphaCut::Mask(mask) => {
                        let mut mesh = build()?;
                        mesh.set_alpha(mask);
                        Some(Arc::new(Shape::TriangleMesh(Arc::new(mesh))))
                    }
                    AlphaCut::Hidden => {
                        log::info!(
                            "{}: {what}'s material has a constant alpha that leaves nothing \
                             of it (below its MASK cutoff, or 0 with BLEND); the primitive \
                             is invisible and skipped",
                            self.path.display()
                        );
                        None
                    }
                }
            }
        };
        self.shapes.insert(key, shape.clone());
        Ok(shape)
    }

    fn primitive_data(&self, primitive: &::gltf::Primitive, what: &str) -> Result<MeshData> {
        use ::gltf::Semantic;
        let positions = primitive
            .get(&Semantic::Positions)
            .ok_or_else(|| self.error(format!("{what} has no POSITION attribute")))?;
        let p = self.read_accessor(
            &positions,
            &format!("{what} POSITION"),
            Dimensions::Vec3,
            &[DataType::F32],
        )?;
        let positions = vec3s(&p);
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(self.error(format!(
                "{what}: POSITION {i} is not finite ({:?})",
                positions[i]
            )));
        }
        let n = positions.len();
        let normals = match primitive.get(&Semantic::Normals) {
            Some(a) => {
                let v = self.read_accessor(
                    &a,
                    &format!("{what} NORMAL"),
                    Dimensions::Vec3,
                    &[DataType::F32],
                )?;
                vec3s(&v)
            }
            None => Vec::new(),
        };
        let uvs = match primitive.get(&Semantic::TexCoords(0)) {
            Some(a) => {
                let v = self.read_accessor(
                    &a,
                    &format!("{what} TEXCOORD_0"),
                    Dimensions::Vec2,
                    &[DataType::F32, DataType::U8, DataType::U16],
                )?;
                // glTF's v runs down the image, ours up.
                v.chunks_exact(2)
                    .map(|c| Vec2::new(c[0] as f32, 1.0 - c[1] as f32))
                    .collect()
            }
            None => Vec::new(),
        };
        // COLOR_0 multiplies the base colour (linear RGB; RGBA's alpha is not read).
        let colors: Vec<Vec3> = match primitive.get(&Semantic::Colors(0)) {
            Some(a) => {
                let dims = if a.dimensions() == Dimensions::Vec4 {
                    Dimensions::Vec4
                } else {
                    Dimensions::Vec3
                };
                let v = self.read_accessor(
                    &a,
                    &format!("{what} COLOR_0"),
                    dims,
                    &[DataType::F32, DataType::U8, DataType::U16],
                )?;
                let colors: Vec<Vec3> = v
                    .chunks_exact(dims.multiplicity())
                    .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
                    .collect();
                if let Some(i) = colors.iter().position(|c| !c.is_finite()) {
                    return Err(self.error(format!(
                        "{what}: COLOR_0 {i} is not finite ({:?})",
                        colors[i]
                    )));
                }
                colors
            }
            None => Vec::new(),
        };
        for (name, len) in [
            ("NORMAL", normals.len()),
            ("TEXCOORD_0", uvs.len()),
            ("COLOR_0", colors.len()),
        ] {
            if len != 0 && len != n {
                return Err(self.error(format!(
                    "{what}: {name} has {len} elements but POSITION has {n}"
                )));
            }
        }
        let flat: Vec<u32> = match primitive.indices() {
            Some(a) => self
                .read_accessor(
                    &a,
                    &format!("{what} indices"),
                    Dimensions::Scalar,
                    &[DataType::U8, DataType::U16, DataType::U32],
                )?
                .into_iter()
                .map(|i| i as u32)
                .collect(),
            None => (0..n as u32).collect(),
        };
        if flat.len() % 3 != 0 {
            return Err(self.error(format!(
                "{what}: {} {} do not make whole triangles",
                flat.len(),
                if primitive.indices().is_some() {
                    "indices"
                } else {
                    "vertices (non-indexed)"
                }
            )));
        }
        if let Some(&bad) = flat.iter().find(|&&i| i as usize >= n) {
            return Err(self.error(format!(
                "{what}: index {bad} is out of range ({n} vertices)"
            )));
        }
        Ok(MeshData {
            positions,
            normals,
            uvs,
            indices: flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
            colors,
            face_colors: Vec::new(),
        })
    }

    /// The nodes of the scene to render with their render-from-node matrices, depth
    /// first.
    fn world_nodes(&self) -> Result<Vec<(::gltf::Node<'a>, Mat4)>> {
        let doc = self.doc;
        let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(scene) => scene.nodes().collect(),
            None => {
                let mut is_child = vec![false; doc.nodes().len()];
                for n in doc.nodes() {
                    for c in n.children() {
                        is_child[c.index()] = true;
                    }
                }
                doc.nodes().filter(|n| !is_child[n.index()]).collect()
            }
        };
        let mut visited = vec![false; self.doc.nodes().len()];
        let mut out = Vec::new();
        let mut stack: Vec<(::gltf::Node, Mat4)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        while let Some((node, parent)) = stack.pop() {
            let what = describe("node", node.index(), node.name());
            if std::mem::replace(&mut visited[node.index()], true) {
                return Err(self.error(format!(
                    "{what} is reached twice (a cycle or a node with two parents)"
                )));
            }
            let local = node_matrix(&node.transform());
            if !local.is_finite() {
                return Err(self.error(format!("{what} has a non-finite transform")));
            }
            let world = parent * local;
            for child in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((child, world));
            }
            out.push((node, world));
        }
        Ok(out)
    }

    fn build(&mut self) -> Result<LoadedScene> {
        let nodes = self.world_nodes()?;
        let mut instances = Vec::new();
        let mut camera = None;
        let mut lights = Vec::new();
        for (node, world) in &nodes {
            let what = describe("node", node.index(), node.name());
            if let Some(mesh) = node.mesh() {
                let Some(render_from_object) = Transform::from_matrix(*world) else {
                    log::warn!(
                        "{}: {what} has a singular transform (zero scale); its mesh is \
                         skipped",
                        self.path.display()
                    );
                    continue;
                };
                for primitive in mesh.primitives() {
                    let Some(shape) = self.primitive_shape(&mesh, &primitive)? else {
                        continue;
                    };
                    let colored = primitive.get(&::gltf::Semantic::Colors(0)).is_some();
                    let (material, emission) = self.material(primitive.material(), colored)?;
                    let mut instance = Instance::new(shape, render_from_object);
                    instance.material = Some(material);
                    instance.emission = emission;
                    instances.push(instance);
                }
            }
            if let Some(c) = node.camera() {
                if camera.is_none() {
                    camera = Some(self.camera(&c, world)?);
                } else {
                    log::info!(
                        "{}: {what}'s camera is not used (the first camera is)",
                        self.path.display()
                    );
                }
            }
            if let Some(l) = node.light() {
                lights.push(light(&l, world));
            }
        }
        let bounds = instances
            .iter()
            .fold(Bounds3::EMPTY, |b, i| b.union(&i.bounds));
        let camera = match camera {
            Some(c) => c,
            None => default_camera(&bounds),
        };
        if lights.is_empty() && instances.iter().all(|i| i.emission.is_none()) {
            lights.push(Light::Environment(Environment::new(
                Arc::new(Texture::Constant(Vec3::ONE)),
                Transform::IDENTITY,
            )));
        }
        log::info!(
            "{}: {} instances of {} shapes, {} lights",
            self.path.display(),
            instances.len(),
            self.shapes.values().flatten().count(),
            lights.len()
        );
        let mut scene = Scene::new(
            instances,
            Some(camera),
            self.options.accel.unwrap_or_default(),
        );
        let weights = vec![1.0; lights.len()];
        scene
            .set_lights(lights, &weights)
            .map_err(|m| self.error(m))?;
        Ok(LoadedScene {
            scene,
            integrator: Integrator::PathTracer(PathTracer {
                max_depth: u32::MAX,
                rr_depth: 5,
                clamp: None,
                hide_emitters: false,
            }),
            sampler: Sampler::Independent(IndependentSampler::new(DEFAULT_SPP, 0)),
            test: None,
            path: self.path.clone(),
        })
    }

    fn camera(&self, camera: &::gltf::Camera, world: &Mat4) -> Result<Camera> {
        let what = describe("camera", camera.index(), camera.name());
        let render_from_camera = camera_transform(world)
            .ok_or_else(|| self.error(format!("{what}: its node's transform is degenerate")))?;
        let resolution = |aspect: f32| -> Result<UVec2> {
            if !(aspect.is_finite() && aspect > 0.0) {
                return Err(self.error(format!("{what}: aspect ratio {aspect} is not positive")));
            }
            let width = (IMAGE_HEIGHT as f32 * aspect).round().clamp(1.0, 16384.0);
            Ok(UVec2::new(width as u32, IMAGE_HEIGHT))
        };
        match camera.projection() {
            ::gltf::camera::Projection::Perspective(p) => {
                let fov = p.yfov().to_degrees();
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(self.error(format!(
                        "{what}: yfov must be between 0 and π, got {}",
                        p.yfov()
                    )));
                }
                let res = resolution(p.aspect_ratio().unwrap_or(4.0 / 3.0))?;
                Ok(Camera::Perspective(Perspective::new(
                    res,
                    fov,
                    FovAxis::Y,
                    render_from_camera,
                )))
            }
            ::gltf::camera::Projection::Orthographic(o) => {
                let (x, y) = (o.xmag(), o.ymag());
                if !(x.is_finite() && y.is_finite() && x != 0.0 && y != 0.0) {
                    return Err(self.error(format!(
                        "{what}: xmag and ymag must be non-zero, got {x} and {y}"
                    )));
                }
                let res = resolution((x / y).abs())?;
                Ok(Camera::Orthographic(Orthographic::new(
                    res,
                    y.abs(),
                    FovAxis::Y,
                    render_from_camera,
                )))
            }
        }
    }
}

/// Rows of three components as vectors.
fn vec3s(values: &[f64]) -> Vec<Vec3> {
    values
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
        .collect()
}

/// A node's local matrix.
fn node_matrix(transform: &::gltf::scene::Transform) -> Mat4 {
    match transform {
        ::gltf::scene::Transform::Matrix { matrix } => Mat4::from_cols_array_2d(matrix),
        ::gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            let q = Quat::from_array(*rotation);
            let q = if q.length_squared() > 0.0 {
                q.normalize()
            } else {
                Quat::IDENTITY
            };
            Mat4::from_scale_rotation_translation(
                Vec3::from_array(*scale),
                q,
                Vec3::from_array(*translation),
            )
        }
    }
}

/// Our render-from-camera transform for a glTF camera node's world matrix: scale
/// removed, then glTF's camera space (−Z forward, +Y up) turned into ours (+z forward,
/// +y down) by a 180° rotation about x.
fn camera_transform(world: &Mat4) -> Option<Transform> {
    let x = world.x_axis.truncate().normalize_or_zero();
    let y = world.y_axis.truncate().normalize_or_zero();
    let z = world.z_axis.truncate().normalize_or_zero();
    let rigid = Mat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), world.w_axis);
    let flip = Mat4::from_diagonal(Vec4::new(1.0, -1.0, -1.0, 1.0));
    Transform::from_matrix(rigid * flip)
}

/// A glTF punctual light on a node (see the module docs for the units).
fn light(l: &::gltf::khr_lights_punctual::Light, world: &Mat4) -> Light {
    let intensity = Vec3::from_array(l.color()) * l.intensity();
    let position = world.transform_point3(Vec3::ZERO);
    let forward = world
        .transform_vector3(-Vec3::Z)
        .try_normalize()
        .unwrap_or(-Vec3::Z);
    match l.kind() {
        ::gltf::khr_lights_punctual::Kind::Point => Light::Point(PointLight {
            position,
            intensity,
        }),
        ::gltf::khr_lights_punctual::Kind::Directional => Light::Directional(DirectionalLight {
            direction: -forward,
            intensity,
        }),
        ::gltf::khr_lights_punctual::Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => Light::Spot(SpotLight {
            position,
            direction: forward,
            intensity,
            cos_falloff_start: inner_cone_angle.min(outer_cone_angle).cos(),
            cos_cutoff: outer_cone_angle.cos(),
            profile: SpotProfile::SquaredCosine,
        }),
    }
}

/// A camera that frames `bounds`: 45° vertical field of view, 640×480, looking at the
/// centre from the front (+Z) and a little above, the bounding sphere inside the view.
fn default_camera(bounds: &Bounds3) -> Camera {
    let fov_y = 45.0f32;
    let resolution = UVec2::new(640, IMAGE_HEIGHT);
    let (centre, radius) = if bounds.is_empty() || !bounds.diagonal().is_finite() {
        (Vec3::ZERO, 1.0)
    } else {
        (
            bounds.center(),
            (bounds.diagonal().length() * 0.5).max(1e-3),
        )
    };
    let half = (fov_y * 0.5).to_radians();
    let back = Vec3::new(0.0, 0.3, 1.0).normalize();
    let x = Vec3::Y.cross(back).normalize();
    let y = back.cross(x);
    let frame = |centre: Vec3, radius: f32| {
        let distance = radius / half.sin() * 1.05;
        let world = Mat4::from_cols(
            x.extend(0.0),
            y.extend(0.0),
            back.extend(0.0),
            (centre + back * distance).extend(1.0),
        );
        camera_transform(&world)
    };
    // Bounds near the float range overflow the camera's position (found by fuzzing):
    // such a scene gets the unit view instead.
    let render_from_camera = frame(centre, radius)
        .or_else(|| frame(Vec3::ZERO, 1.0))
        .expect("the unit view is an orthonormal frame");
    Camera::Perspective(Perspective::new(
        resolution,
        fov_y,
        FovAxis::Y,
        render_from_camera,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
        assert_eq!(percent_decode("plain.bin").as_deref(), Some("plain.bin"));
        assert_eq!(percent_decode("bad%2"), None);
        assert_eq!(percent_decode("bad%zz"), None);
    }

    #[test]
    fn normalized_components() {
        assert_eq!(component(&[255], DataType::U8, true), 1.0);
        assert_eq!(component(&[0x80], DataType::I8, true), -1.0);
        assert_eq!(component(&[0xff, 0xff], DataType::U16, true), 1.0);
        assert_eq!(component(&[1, 0, 0, 1], DataType::U32, false), 16777217.0);
    }

    /// glTF's camera looks down its −Z with +Y up: our ray through the image centre goes
    /// down the node's −Z, and the top of the image is the node's +Y.
    #[test]
    fn camera_convention() {
        let world = Mat4::from_rotation_y(0.5) * Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0));
        let cam = Perspective::new(
            UVec2::new(100, 100),
            60.0,
            FovAxis::Y,
            camera_transform(&world).unwrap(),
        );
        let sample = |x: f32, y: f32| crate::camera::CameraSample {
            film: Vec2::new(x, y),
            lens: Vec2::splat(0.5),
        };
        let centre = cam.generate_ray(&sample(50.0, 50.0));
        let forward = world.transform_vector3(-Vec3::Z);
        assert!((centre.direction - forward).length() < 1e-5);
        assert!((centre.origin - world.transform_point3(Vec3::ZERO)).length() < 1e-5);
        let top = cam.generate_ray(&sample(50.0, 0.0));
        let up = world.transform_vector3(Vec3::Y);
        assert!(top.direction.dot(up) > 0.4);
        let right = cam.generate_ray(&sample(100.0, 50.0));
        assert!(right.direction.dot(world.transform_vector3(Vec3::X)) > 0.4);
    }

    #[test]
    fn default_camera_sees_the_bounds() {
        let b = Bounds3::new(Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 1.0, 0.0));
        let Camera::Perspective(cam) = default_camera(&b) else {
            panic!("not perspective")
        };
        let ray = cam.generate_ray(&crate::camera::CameraSample {
            film: Vec2::new(320.0, 240.0),
            lens: Vec2::splat(0.5),
        });
        // The centre ray passes through the centre of the box.
        let to_centre = (b.center() - ray.origin).normalize();
        assert!((ray.direction - to_centre).length() < 1e-5);
        // Every corner is inside the view (in front, within the field of view).
        let camera_from_render = cam.render_from_camera.inverse();
        for c in b.corners() {
            let p = camera_from_render.point(c);
            assert!(p.z > 0.0);
            assert!((p.x / p.z).abs() <= cam.half_extents.x);
            assert!((p.y / p.z).abs() <= cam.half_extents.y);
        }
    }
}
