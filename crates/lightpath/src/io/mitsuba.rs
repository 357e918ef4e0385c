//! The Mitsuba 3 XML scene dialect (a root `<scene version="3...">`).
//!
//! The reader builds the same property tree as the lightwave dialect ([`Node`]), with
//! Mitsuba's rules: `<default name value>` defines `$name` unless a `-D` define gives
//! it; `<ref id>` may name an object defined later in the document (references resolve
//! when the scene is built); `<alias id as>` gives an object a second id; `<include
//! filename>` splices another file's objects. Typed properties are `integer float
//! boolean string rgb spectrum point vector`; a `spectrum` is one uniform value, or a
//! wavelength list whose values are all equal (anything else is an error naming it).
//! `<point>`/`<vector>` may give `x y z` attributes instead of `value`.
//!
//! Shapes: `obj`, `ply`, `serialized` (with `shape_index`; see [`super::serialized`]), `sphere`, `rectangle`, `disk`, `cube`, `cylinder`,
//! `linearcurve` and `bsplinecurve` (their control points moved by `to_world`, their
//! radii kept, as Mitsuba does; see [`crate::geometry::LinearCurves`] and
//! [`crate::geometry::CubicCurves`]), and `shapegroup` + `instance` (each instance places every shape of its group with the
//! group shape's `to_world` followed by the instance's; meshes are loaded once and shared).
//!
//! # Unsupported plugins and `--lenient`
//! An unsupported plugin or parameter is an error naming the file, line and plugin. With
//! [`LoadOptions::lenient`](super::LoadOptions) (`lightpath render --lenient`) it is a
//! logged warning instead, and the scene renders with these fallbacks: an unknown BSDF is
//! a diffuse 0.5 (Mitsuba's default BSDF), an unknown texture a constant 0.5, unknown
//! shapes and emitters are left out, an unknown integrator is `path`, sensor
//! `perspective`, film `hdrfilm`, reconstruction filter `box`, sampler `independent`;
//! unknown parameters are ignored.
//!
//! # Conventions and approximations
//! - Cameras: Mitsuba's camera space has +x to the image *left* and +y *up*; ours has +x
//!   right and +y down, so the sensor's `to_world` is preceded by a 180° turn about z.
//!   `fov_axis` `smaller`/`larger` pick x or y from the film size. Camera rays start at
//!   `near_clip` and end at `far_clip` (defaults 0.01 and 10⁴), measured along the
//!   viewing axis as Mitsuba measures them.
//! - Films: `hdrfilm` `width`/`height` (defaults 768×576), and the crop window
//!   `crop_offset_x`/`crop_offset_y`/`crop_width`/`crop_height` (the image is that part
//!   of the film, rendered as in the whole: [`crate::scene::CropWindow`]). `rfilter` `box`, `tent`
//!   (`radius`), `gaussian` (`stddev`; the default filter, as in Mitsuba), `mitchell`
//!   (`B`, `C`), `catmullrom` and `lanczos` (`lobes`) are applied by filter importance
//!   sampling ([`Filter`]; the last three, with negative lobes, by weighted samples).
//!   All but the box go through the 31 constant steps per radius in which Mitsuba's film
//!   applies them ([`Filter::with_steps`]): on `tests/mitsuba/filters.xml` with the
//!   Gaussian, relMSE against Mitsuba 4.5e-5 with the steps and 1.3e-4 without.
//! - Samplers: `independent` → independent; `stratified`, `multijitter`, `ldsampler`,
//!   `orthogonal` → our `sobol`; `sample_count` (default 4), `seed`.
//! - Integrators: `path` `max_depth` counts vertices as Mitsuba does (1: emitters only,
//!   2: direct lighting, -1: no limit), which is exactly our `PathTracer::max_depth`;
//!   `rr_depth` (default 5) is passed through. `direct` (its sample counts are ignored).
//!   Both take `hide_emitters` (emitters and the environment black where camera rays
//!   see them directly, as in Mitsuba; [`PathTracer::hide_emitters`]).
//!   `aov` with a single `nn:sh_normal`/`sh_normal`/`geo_normal` (→ normals, shown as
//!   (n+1)/2), `dd:depth` (→ distance) or `uv`.
//! - BSDFs: `diffuse`, `conductor` and `roughconductor` are one-sided as in Mitsuba
//!   (black from behind, [`OneSided`]) unless wrapped in `twosided`. `roughconductor`/`roughdielectric` `alpha`
//!   becomes our roughness `sqrt(alpha)`, with Mitsuba's default `beckmann` distribution
//!   or `ggx`. Named conductors (`material`) use the RGB (η, k) that Mitsuba's RGB
//!   variants derive from its spectral tables ([`fresnel::MITSUBA_METALS`]).
//!   `roughplastic` takes the same `alpha` (isotropic only) and `distribution`.
//!   `principled` is Mitsuba's Disney BSDF ([`crate::material::DisneyPrincipled`]) with
//!   all its parameters (`eta` or `specular`, not both; the three sampling rates);
//!   `principledthin` its thin-sheet sibling ([`crate::material::DisneyThin`]), likewise.
//!   `twosided` with two BSDFs uses the first in front, the second behind.
//!   `bumpmap` (its one texture, any name, as the height; `scale`) may be a shape's BSDF
//!   or a side of a `twosided` and wrap any BSDF ([`crate::material::BumpMap`]); inside
//!   a `blendbsdf`, `normalmap` or another `bumpmap` it is an error. `bumpmap` and
//!   `normalmap` take `flip_invalid_normals` and `use_shadowing_function` (both on by
//!   default, as in Mitsuba 3.7 and later). A `bitmap`'s height gradient is that of its
//!   bilinear interpolation (zero with `nearest` filtering, as in Mitsuba); other
//!   textures have none.
//! - Meshes (`obj`, `ply`, `serialized`) without normals get smooth ones, weighted by
//!   angle, as Mitsuba computes them (unless `face_normals`).
//!   `mask` (the shape's outermost BSDF, on meshes and rectangles) makes the surface
//!   transparent with probability 1 − `opacity` (one value, see below; default 0.5) at
//!   each point: rays pass through it there ([`crate::geometry::AlphaTest::Stochastic`]),
//!   shadow rays included; the nested BSDF scatters the rest. A masked shape's `area`
//!   emitter emits only where the surface is there, in proportion to `opacity` (see
//!   [`crate::light::AreaLight`]); Mitsuba adds the emission at every hit of the shape
//!   and samples its whole area. (Mitsuba 3.9.1 reads a
//!   `checkerboard` opacity with its two colours swapped, its single-channel lookup
//!   disagreeing with its colour one: there it renders the complement of the pattern
//!   that the same checkerboard shows as a colour; constant and bitmap opacities agree.)
//! - Emitters: `directional` `direction` is where the light travels (negated for ours).
//!   `envmap` follows Mitsuba's lat-long mapping: a local direction d reads
//!   u = atan2(d.x, −d.z)/2π, v = acos(d.y)/π; ours is the same with x and z swapped,
//!   so the envmap's `to_world` is preceded by that swap. `scale` multiplies it.
//!   Vertically Mitsuba interpolates rows with their centres from pole to pole (row
//!   y at v = y/(h−1)); ours at v = (y+½)/h: a shift of under half a row.
//! - `flip_normals` turns every shape's normals: a mesh's triangles as it loads, an
//!   analytic shape's through its instance ([`crate::scene::Instance::flip_normals`]),
//!   so one-sided BSDFs and area emission face the other side, as in Mitsuba.
//! - Shapes without a BSDF get Mitsuba's default: diffuse 0.5, or, on a shape with an
//!   area emitter, a black diffuse (the light reflects nothing).
//! - Float parameters (`opacity`, `weight`, and the Disney BSDFs' parameters other than
//!   `base_color`) read a colour texture as Mitsuba's `eval_1` does: an `rgb` constant
//!   as the mean of its channels, a `bitmap` as its luminance, a `checkerboard` as each
//!   colour's value (in the cell where its colour lookup shows that colour), a
//!   `mesh_attribute` as the vertex colour's luminance (Mitsuba 3.9.1 refuses to read a
//!   three-channel attribute as one value: `eval_attribute_1` throws).
//! - `mesh_attribute` reads `vertex_color` or `face_color` (a PLY file's `r`/`g`/`b`,
//!   `red`/`green`/`blue` or `color_0`/`color_1`/`color_2` on its vertices or faces;
//!   see [`super::ply`]), times `scale`; 8-bit colours are decoded from sRGB to [0, 1]
//!   (Mitsuba 3.9.1 keeps them as 0-255); a shape without colours reads white. A mesh
//!   holds one set of colours: where a file has both, `face_color` reads the vertices'.
//!   Other attribute names are an error.
//! - Texture coordinates follow Mitsuba: a `bitmap` has image row 0 at v = 0 (after its
//!   `to_uv` transform), and OBJ meshes flip v unless `flip_tex_coords` is false.

use super::image::Transfer;
use super::props::{Node, Property};
use super::xml::resolve_path;
use super::{LoadOptions, LoadedScene};
use crate::camera::{Camera, FovAxis, Orthographic, Perspective, ThinLens};
use crate::error::{Error, Location, Result};
use crate::film::{Filter, MITSUBA_FILTER_STEPS};
use crate::geometry::{
    AlphaMask, AlphaTest, Csg, CsgNode, CsgOp, CubicBasis, CubicCurves, Cuboid, Cylinder, Disk,
    LinearCurves, MeshData, Rectangle, Shape, Solid, Sphere, TriangleMesh,
};
use crate::integrator::{Aov, AovVariable, Direct, Integrator, PathTracer};
use crate::light::{
    DirectionalLight, Emission, Environment, Light, PointLight, SpotLight, SpotProfile,
};
use crate::material::microfacet::Distribution;
use crate::material::{
    fresnel, Blend, BumpMap, ComplexIor, Conductor, Dielectric, Diffuse, DisneyPrincipled,
    DisneyThin, Material, NormalMap, OneSided, Plastic, RoughConductor, RoughDielectric,
    RoughPlastic, ThinDielectric, TwoSided,
};
use crate::math::Transform;
use crate::sampling::{IndependentSampler, Sampler};
use crate::scene::{CropWindow, Instance, Scene};
use crate::texture::{
    BorderMode, Checkerboard, FilterMode, ImageTexture, Texture, TransformedTexture,
};
use glam::{Affine2, UVec2, Vec2, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;

/// Whether XML text is a Mitsuba 3 scene: its root is `<scene version="3...">`.
pub fn is_mitsuba(text: &str) -> bool {
    let Ok(doc) = roxmltree::Document::parse(text) else {
        return false;
    };
    let root = doc.root_element();
    root.tag_name().name() == "scene"
        && root
            .attribute("version")
            .is_some_and(|v| v.trim().starts_with('3'))
}

/// Loads a Mitsuba scene from its text; relative paths resolve from `path`'s folder.
pub fn load_str(text: &str, path: &Path, options: &LoadOptions) -> Result<LoadedScene> {
    let mut reader = Reader {
        ids: HashMap::new(),
        aliases: Vec::new(),
        stack: vec![path.canonicalize().unwrap_or_else(|_| path.to_path_buf())],
        defines: super::xml::sorted_defines(&options.defines),
        fixed: options.defines.iter().map(|(k, _)| k.clone()).collect(),
    };
    let root = reader.parse(text, path)?;
    for (id, alias, loc) in std::mem::take(&mut reader.aliases) {
        let target = reader.ids.get(&id).cloned().ok_or_else(|| {
            Error::scene(
                loc.clone(),
                format!("<alias id=\"{id}\">: no object has this id"),
            )
        })?;
        reader.ids.insert(alias, target);
    }
    let mut b = Builder {
        path: path.to_path_buf(),
        options: options.clone(),
        ids: reader.ids,
        meshes: HashMap::new(),
        materials: HashMap::new(),
        textures: HashMap::new(),
        grey_textures: HashMap::new(),
        images: HashMap::new(),
    };
    b.root(&root)
}

/// Property elements: `<float name="x" value="1"/>`.
const PROPERTY_TAGS: &[&str] = &[
    "integer", "float", "boolean", "string", "rgb", "spectrum", "point", "vector",
];

struct Reader {
    ids: HashMap<String, Rc<Node>>,
    aliases: Vec<(String, String, Location)>,
    stack: Vec<PathBuf>,
    /// `$name` values, longest name first.
    defines: Vec<(String, String)>,
    /// Names given by `-D`: a `<default>` does not change them.
    fixed: Vec<String>,
}

fn location(path: &Path, doc: &roxmltree::Document, pos: usize) -> Location {
    let p = doc.text_pos_at(pos);
    Location {
        file: path.to_path_buf(),
        line: p.row,
        column: p.col,
    }
}

impl Reader {
    fn parse(&mut self, text: &str, path: &Path) -> Result<Rc<Node>> {
        let doc = roxmltree::Document::parse(text).map_err(|e| {
            let pos = e.pos();
            Error::scene(
                Location {
                    file: path.to_path_buf(),
                    line: pos.row,
                    column: pos.col,
                },
                format!("malformed XML: {e}"),
            )
        })?;
        self.element(&doc, doc.root_element(), path)
    }

    /// Replaces `$name` by its value, longest names first.
    fn substitute(&self, value: &str) -> String {
        super::xml::substitute(value, &self.defines)
    }

    fn element(
        &mut self,
        doc: &roxmltree::Document,
        el: roxmltree::Node,
        path: &Path,
    ) -> Result<Rc<Node>> {
        let loc = location(path, doc, el.range().start);
        let mut node = Node::new(el.tag_name().name(), loc);
        for attr in el.attributes() {
            let value = self.substitute(attr.value());
            match attr.name() {
                "type" => node.type_name = Some(value),
                "id" => node.id = Some(value),
                "name" => node.name = Some(value),
                name => node.properties.push(Property {
                    name: name.to_string(),
                    value,
                    location: location(path, doc, attr.range().start),
                }),
            }
        }
        for child in el.children() {
            if child.is_text() {
                if child.text().is_some_and(|t| !t.trim().is_empty()) {
                    return Err(Error::scene(
                        location(path, doc, child.range().start),
                        "unexpected text in scene file",
                    ));
                }
                continue;
            }
            if !child.is_element() {
                continue;
            }
            let tag = child.tag_name().name();
            let cloc = location(path, doc, child.range().start);
            let attr = |name: &str| -> Result<String> {
                child
                    .attribute(name)
                    .map(|v| self.substitute(v))
                    .ok_or_else(|| {
                        Error::scene(cloc.clone(), format!("<{tag}> needs a `{name}` attribute"))
                    })
            };
            match tag {
                t if PROPERTY_TAGS.contains(&t) => {
                    let name = attr("name")?;
                    let value = match child.attribute("value") {
                        Some(v) => self.substitute(v),
                        None if t == "point" || t == "vector" => {
                            let c = |a: &str| self.substitute(child.attribute(a).unwrap_or("0"));
                            format!("{}, {}, {}", c("x"), c("y"), c("z"))
                        }
                        None => attr("value")?,
                    };
                    let value = if t == "spectrum" {
                        spectrum_value(&value).map_err(|m| {
                            Error::scene(cloc.clone(), format!("<spectrum name=\"{name}\">: {m}"))
                        })?
                    } else {
                        value
                    };
                    node.properties.push(Property {
                        name,
                        value,
                        location: cloc,
                    });
                }
                "default" => {
                    let name = attr("name")?;
                    let value = attr("value")?;
                    if !self.fixed.contains(&name) {
                        self.defines.retain(|(k, _)| *k != name);
                        self.defines.push((name, value));
                        // Kept longest name first, as substitution needs (sorted here,
                        // at each rare <default>, not for every attribute).
                        self.defines = super::xml::sorted_defines(&self.defines);
                    }
                }
                "alias" => {
                    self.aliases.push((attr("id")?, attr("as")?, cloc.clone()));
                }
                "include" => {
                    let file = attr("filename")?;
                    let inc = resolve_path(path, &file);
                    let text = std::fs::read_to_string(&inc).map_err(|e| {
                        Error::scene(
                            cloc.clone(),
                            format!("cannot read included file {}: {e}", inc.display()),
                        )
                    })?;
                    let canonical = inc.canonicalize().unwrap_or_else(|_| inc.clone());
                    if self.stack.contains(&canonical) {
                        return Err(Error::scene(
                            cloc,
                            format!("{} includes itself", inc.display()),
                        ));
                    }
                    self.stack.push(canonical);
                    let root = self.parse(&text, &inc)?;
                    self.stack.pop();
                    node.children.extend(root.children.iter().cloned());
                }
                "ref" => {
                    let mut r = Node::new("ref", cloc.clone());
                    r.id = Some(attr("id")?);
                    r.name = child.attribute("name").map(|n| n.to_string());
                    node.children.push(Rc::new(r));
                }
                _ => {
                    let c = self.element(doc, child, path)?;
                    node.children.push(c);
                }
            }
        }
        let node = Rc::new(node);
        if node.tag != "ref" {
            if let Some(id) = &node.id {
                self.ids.insert(id.clone(), node.clone());
            }
        }
        Ok(node)
    }
}

/// What Mitsuba 3's textures give a BSDF that asks for one value (`eval_1`), in every
/// channel: a constant colour gives the mean of its channels, a bitmap its luminance, a
/// checkerboard the value of each of its two colours. (Mitsuba 3.9.1's checkerboard
/// answers `eval_1` with the other cell's colour than `eval`; here both agree, so that a
/// checkerboard roughness lines up with a checkerboard colour.) A texture that is grey
/// already is returned as it is.
fn grey_texture(t: &Arc<Texture>) -> Arc<Texture> {
    let is_grey = |c: Vec3| c.x == c.y && c.y == c.z;
    let mean = |c: Vec3| Vec3::splat((c.x + c.y + c.z) / 3.0);
    let grey = match &**t {
        Texture::Constant(c) if is_grey(*c) => return t.clone(),
        Texture::Constant(c) => Texture::Constant(mean(*c)),
        Texture::Image(i) if i.image.pixels.iter().all(|&p| is_grey(p)) => return t.clone(),
        Texture::Image(i) => {
            let mut image = (*i.image).clone();
            for p in &mut image.pixels {
                *p = Vec3::splat(crate::light::luminance(*p));
            }
            Texture::Image(ImageTexture {
                image: Arc::new(image),
                ..i.clone()
            })
        }
        Texture::Checkerboard(c) if is_grey(c.color0) && is_grey(c.color1) => return t.clone(),
        Texture::Checkerboard(c) => Texture::Checkerboard(Checkerboard {
            color0: mean(c.color0),
            color1: mean(c.color1),
            ..c.clone()
        }),
        Texture::Luminance(_) => return t.clone(),
        Texture::VertexColor(_) => Texture::Luminance(t.clone()),
        // (Only made of grey textures, by `roughness`.)
        Texture::Sqrt(inner) => {
            let g = grey_texture(inner);
            if Arc::ptr_eq(&g, inner) {
                return t.clone();
            }
            Texture::Sqrt(g)
        }
        Texture::Transformed(tt) => {
            let inner = grey_texture(&tt.texture);
            if Arc::ptr_eq(&inner, &tt.texture) {
                return t.clone();
            }
            Texture::Transformed(TransformedTexture {
                to_uv: tt.to_uv,
                texture: inner,
            })
        }
    };
    Arc::new(grey)
}

/// A `<spectrum>` value as an RGB/grey property value: one number, or a wavelength list
/// `λ:v, ...` whose values are all equal.
fn spectrum_value(value: &str) -> std::result::Result<String, String> {
    if !value.contains(':') {
        return Ok(value.to_string());
    }
    let mut values = Vec::new();
    for pair in value.split(',') {
        let v = pair
            .split(':')
            .nth(1)
            .and_then(|v| v.trim().parse::<f32>().ok())
            .ok_or_else(|| format!("cannot read wavelength:value pair `{}`", pair.trim()))?;
        values.push(v);
    }
    let first = values[0];
    if values
        .iter()
        .all(|v| (v - first).abs() <= 1e-6 * first.abs().max(1.0))
    {
        Ok(first.to_string())
    } else {
        Err(
            "a wavelength-dependent spectrum is not supported (RGB rendering only; give \
             an <rgb> or a uniform value)"
                .to_string(),
        )
    }
}

/// Named indices of refraction (Mitsuba's table).
const IORS: &[(&str, f32)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

/// Mitsuba plugins this dialect reads, by element.
const INTEGRATORS: &[&str] = &["path", "direct", "aov"];
const SENSORS: &[&str] = &["perspective", "thinlens", "orthographic", "realistic"];
const FILMS: &[&str] = &["hdrfilm"];

/// What a `<film>` sets: the image size, the pixel filter and the crop window.
struct Film {
    resolution: UVec2,
    filter: Filter,
    crop: Option<CropWindow>,
}
const RFILTERS: &[&str] = &[
    "box",
    "tent",
    "gaussian",
    "mitchell",
    "catmullrom",
    "lanczos",
];
const SAMPLERS: &[&str] = &[
    "independent",
    "stratified",
    "multijitter",
    "ldsampler",
    "orthogonal",
];
const SHAPES: &[&str] = &[
    "obj",
    "ply",
    "serialized",
    "sphere",
    "rectangle",
    "disk",
    "cube",
    "cylinder",
    "linearcurve",
    "bsplinecurve",
    "instance",
    "shapegroup",
    "csg",
];
const EMITTERS: &[&str] = &["area", "point", "spot", "directional", "constant", "envmap"];
const TEXTURES: &[&str] = &["bitmap", "checkerboard", "mesh_attribute"];
const BSDFS: &[&str] = &[
    "diffuse",
    "conductor",
    "roughconductor",
    "dielectric",
    "roughdielectric",
    "thindielectric",
    "plastic",
    "roughplastic",
    "principled",
    "principledthin",
    "twosided",
    "blendbsdf",
    "normalmap",
    "bumpmap",
    "hair",
];

/// A Disney BSDF's `*_sampling_rate` (default 1): finite and not negative.
fn sampling_rate(node: &Node, plugin: &str, name: &str) -> Result<f32> {
    let r = node.float_or(name, 1.0)?;
    if r.is_finite() && r >= 0.0 {
        Ok(r)
    } else {
        Err(node.error(format!("{plugin} `{name}` {r} must be at least 0")))
    }
}

/// Where a `mask` BSDF applies.
const MASK_SHAPES: &str =
    "a `mask` BSDF is supported on meshes (`obj`, `ply`, `serialized`) and rectangles, as the shape's outermost BSDF";

/// `shape` with its surface masked: a mesh (a copy: the file's mesh may be shared), or a
/// rectangle as a two-triangle mesh over `accel` with the rectangle's parameterisation;
/// `None` for other shapes.
fn masked_shape(shape: &Shape, mask: AlphaMask, accel: crate::accel::AccelKind) -> Option<Shape> {
    let mut mesh = match shape {
        Shape::TriangleMesh(m) => (**m).clone(),
        Shape::Rectangle(_) => {
            let data = MeshData {
                positions: vec![
                    Vec3::new(-1.0, -1.0, 0.0),
                    Vec3::new(1.0, -1.0, 0.0),
                    Vec3::new(1.0, 1.0, 0.0),
                    Vec3::new(-1.0, 1.0, 0.0),
                ],
                normals: Vec::new(),
                uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
                indices: vec![[0, 1, 2], [0, 2, 3]],
                colors: Vec::new(),
                face_colors: Vec::new(),
            };
            TriangleMesh::new(data, false, accel).ok()?
        }
        _ => return None,
    };
    mesh.set_alpha(mask);
    Some(Shape::TriangleMesh(Arc::new(mesh)))
}

fn unknown_type(node: &Node, known: &[&str]) -> Error {
    let t = node.type_name.as_deref().unwrap_or("");
    node.error(format!(
        "unsupported Mitsuba {} plugin `{t}`; supported: {}",
        node.tag,
        known.join(", ")
    ))
}

/// What `--lenient` does with an unsupported plugin.
#[derive(Clone, Copy)]
enum Fallback {
    /// Build it as this supported plugin instead.
    Use(&'static str),
    /// Leave the object out of the scene.
    Skip,
    /// The caller substitutes what this describes.
    Replace(&'static str),
}

struct Builder {
    path: PathBuf,
    options: LoadOptions,
    ids: HashMap<String, Rc<Node>>,
    meshes: HashMap<(PathBuf, bool, bool, bool, usize), Arc<Shape>>,
    materials: HashMap<*const Node, Arc<Material>>,
    textures: HashMap<*const Node, Arc<Texture>>,
    /// The one-value copies of textures that float parameters use (by the address of the
    /// colour texture, which each entry keeps alive).
    grey_textures: HashMap<*const Texture, (Arc<Texture>, Arc<Texture>)>,
    images: HashMap<(PathBuf, bool), Arc<crate::film::Image>>,
}

impl Builder {
    /// A file named in the scene: like Mitsuba's file resolver, relative to the main
    /// scene file's folder, else to the folder of the file that names it.
    fn resolve_file(&self, node: &Node, file: &str) -> PathBuf {
        let main = resolve_path(&self.path, file);
        if main.exists() {
            main
        } else {
            resolve_path(&node.location.file, file)
        }
    }

    /// The object a child stands for: itself, or the target of a `<ref>`.
    fn resolve(&self, c: &Rc<Node>) -> Result<Rc<Node>> {
        if c.tag != "ref" {
            return Ok(c.clone());
        }
        let id = c.id.as_deref().unwrap_or("");
        self.ids
            .get(id)
            .cloned()
            .ok_or_else(|| c.error(format!("<ref id=\"{id}\">: no object has this id")))
    }

    /// The resolved children, with the slot name each was given (`name=`).
    fn children(&self, node: &Node) -> Result<Vec<(Option<String>, Rc<Node>)>> {
        node.children
            .iter()
            .map(|c| Ok((c.name.clone(), self.resolve(c)?)))
            .collect()
    }

    fn check_children(&self, node: &Node, allowed: &[&str]) -> Result<()> {
        for (_, c) in self.children(node)? {
            if !allowed.contains(&c.tag.as_str()) {
                return Err(c.error(format!(
                    "<{}> is not supported inside {}",
                    c.tag,
                    node.describe()
                )));
            }
        }
        Ok(())
    }

    fn root(&mut self, root: &Rc<Node>) -> Result<LoadedScene> {
        if root.tag != "scene" {
            return Err(root.error("a Mitsuba scene's root must be <scene>"));
        }
        root.string("version");
        root.check_all_used()?;
        let mut integrator = None;
        let mut sensor = None;
        let mut instances = Vec::new();
        let mut lights = Vec::new();
        for (_, child) in self.children(root)? {
            match child.tag.as_str() {
                "integrator" => {
                    if integrator.is_some() {
                        return Err(child.error("the scene has more than one <integrator>"));
                    }
                    integrator = Some(self.integrator(&child)?);
                }
                "sensor" => {
                    if sensor.is_some() {
                        return Err(child.error("the scene has more than one <sensor>"));
                    }
                    sensor = Some(self.sensor(&child)?);
                }
                "shape" => match self.plugin(&child, SHAPES, Fallback::Skip)?.as_deref() {
                    None => {}
                    // Shape groups are placed by instances.
                    Some("shapegroup") => {}
                    Some("instance") => instances.extend(self.instance(&child)?),
                    Some(_) => instances.push(self.shape(&child)?),
                },
                "emitter" => match child.type_name.as_deref() {
                    // Area emitters at the top level are for shapes' <ref>s.
                    Some("area") if child.id.is_some() => {}
                    _ => lights.extend(self.emitter(&child)?),
                },
                "bsdf" | "texture" if child.id.is_some() => {}
                other => {
                    return Err(child.error(format!(
                        "<{other}> is not supported at the top level of a Mitsuba scene"
                    )))
                }
            }
        }
        let integrator = match integrator {
            Some(i) => i,
            None => Integrator::PathTracer(PathTracer {
                max_depth: u32::MAX,
                rr_depth: 5,
                clamp: None,
                hide_emitters: false,
            }),
        };
        let (camera, sampler, film, clip) =
            sensor.ok_or_else(|| root.error("the scene has no <sensor>"))?;
        let mut scene = Scene::new(
            instances,
            Some(camera),
            self.options.accel.unwrap_or_default(),
        );
        scene.filter = film.filter;
        scene.crop = film.crop;
        scene.clip = Some(clip);
        let weights = vec![1.0; lights.len()];
        scene
            .set_lights(lights, &weights)
            .map_err(|m| root.error(m))?;
        Ok(LoadedScene {
            scene,
            integrator,
            sampler,
            test: None,
            path: self.path.clone(),
        })
    }

    /// The plugin type of `node` when it is one of `known`. Otherwise an error naming
    /// the plugin and line, or with `--lenient` a logged warning and the fallback's type
    /// (`None`: leave the object out).
    fn plugin(&self, node: &Node, known: &[&str], fallback: Fallback) -> Result<Option<String>> {
        match node.type_name.as_deref() {
            Some(t) if known.contains(&t) => Ok(Some(t.to_string())),
            _ if !self.options.lenient => Err(unknown_type(node, known)),
            _ => {
                let what = match fallback {
                    Fallback::Use(t) => format!("rendered as `{t}`"),
                    Fallback::Skip => "left out".to_string(),
                    Fallback::Replace(r) => format!("replaced by {r}"),
                };
                log::warn!("{} ({what}: --lenient)", unknown_type(node, known));
                Ok(match fallback {
                    Fallback::Use(t) => Some(t.to_string()),
                    Fallback::Skip | Fallback::Replace(_) => None,
                })
            }
        }
    }

    /// [`Node::check_all_used`], a warning instead of an error with `--lenient`.
    fn check_used(&self, node: &Node) -> Result<()> {
        match node.check_all_used() {
            Err(e) if self.options.lenient => {
                log::warn!("{e} (ignored: --lenient)");
                Ok(())
            }
            r => r,
        }
    }

    fn integrator(&mut self, node: &Node) -> Result<Integrator> {
        self.check_children(node, &[])?;
        let depth = |name: &str, default: i64| -> Result<u32> {
            match node.int(name)?.unwrap_or(default) {
                -1 => Ok(u32::MAX),
                d if d >= 1 && d <= u32::MAX as i64 => Ok(d as u32),
                d => Err(node.error(format!("`{name}` must be -1 or at least 1, got {d}"))),
            }
        };
        let kind = self.plugin(node, INTEGRATORS, Fallback::Use("path"))?;
        let integrator = match kind.as_deref() {
            Some("path") => {
                let max_depth = depth("max_depth", -1)?;
                let rr_depth = depth("rr_depth", 5)?;
                Integrator::PathTracer(PathTracer {
                    max_depth,
                    rr_depth,
                    clamp: None,
                    hide_emitters: node.bool_or("hide_emitters", false)?,
                })
            }
            Some("direct") => {
                node.int("emitter_samples")?;
                node.int("bsdf_samples")?;
                node.int("shading_samples")?;
                if node.bool_or("hide_emitters", false)? {
                    // The direct integrator is the path tracer of two vertices.
                    Integrator::PathTracer(PathTracer {
                        hide_emitters: true,
                        ..Direct::PATH_TRACER
                    })
                } else {
                    Integrator::Direct(Direct)
                }
            }
            Some("aov") => {
                let aovs = node
                    .string("aovs")
                    .ok_or_else(|| node.error("aov integrator needs `aovs`"))?;
                let list: Vec<&str> = aovs.split(',').map(str::trim).collect();
                if list.len() != 1 {
                    return Err(node.error(format!("aov: only one AOV is supported, got `{aovs}`")));
                }
                let kind = list[0].rsplit(':').next().unwrap_or("");
                let variable = match kind {
                    "sh_normal" | "geo_normal" => AovVariable::Normals,
                    "depth" => AovVariable::Distance,
                    "uv" => AovVariable::Uv,
                    other => {
                        return Err(node.error(format!(
                            "aov `{other}` is not supported; supported: sh_normal, geo_normal, \
                             depth, uv"
                        )))
                    }
                };
                Integrator::Aov(Aov {
                    variable,
                    scale: 1.0,
                })
            }
            _ => return Err(unknown_type(node, INTEGRATORS)),
        };
        self.check_used(node)?;
        Ok(integrator)
    }

    fn single(&self, node: &Node, tag: &str) -> Result<Option<Rc<Node>>> {
        let found: Vec<Rc<Node>> = self
            .children(node)?
            .into_iter()
            .map(|(_, c)| c)
            .filter(|c| c.tag == tag)
            .collect();
        if found.len() > 1 {
            return Err(found[1].error(format!("{} has more than one <{tag}>", node.describe())));
        }
        Ok(found.into_iter().next())
    }

    /// The `to_world` (or unnamed) `<transform>` child, identity if none.
    fn to_world(&self, node: &Node) -> Result<Transform> {
        match self.single(node, "transform")? {
            None => Ok(Transform::IDENTITY),
            Some(t) => {
                if let Some(name) = t.name.as_deref() {
                    if name != "to_world" {
                        return Err(t.error(format!(
                            "<transform name=\"{name}\"> is not supported here; expected \
                             to_world"
                        )));
                    }
                }
                transform(&t)
            }
        }
    }

    /// The camera, its sampler, its film and its near and far clip distances.
    fn sensor(&mut self, node: &Node) -> Result<(Camera, Sampler, Film, (f32, f32))> {
        self.check_children(node, &["transform", "film", "sampler"])?;
        let film = match &self.single(node, "film")? {
            Some(f) => self.film(f)?,
            None => Film {
                resolution: UVec2::new(768, 576),
                filter: Filter::gaussian(0.5).with_steps(MITSUBA_FILTER_STEPS),
                crop: None,
            },
        };
        let resolution = film.resolution;
        let sampler = match self.single(node, "sampler")? {
            Some(s) => self.sampler(&s)?,
            None => Sampler::Independent(IndependentSampler::new(4, 0)),
        };
        // Mitsuba's camera space: +x left, +y up; ours: +x right, +y down.
        let flip = Transform::scale(Vec3::new(-1.0, -1.0, 1.0)).expect("non-zero scale");
        let render_from_camera = flip.then(&self.to_world(node)?);
        // Mitsuba's defaults; rays start and end at these distances along the view axis.
        let near = node.float_or("near_clip", 1e-2)?;
        let far = node.float_or("far_clip", 1e4)?;
        if !(near > 0.0 && far > near && far.is_finite()) {
            return Err(node.error(format!(
                "need 0 < near_clip < far_clip, got {near} and {far}"
            )));
        }
        let axis = |node: &Node| -> Result<FovAxis> {
            let name = node.string_or("fov_axis", "x");
            let smaller_is_x = resolution.x <= resolution.y;
            match name.as_str() {
                "smaller" => Ok(if smaller_is_x { FovAxis::X } else { FovAxis::Y }),
                "larger" => Ok(if smaller_is_x { FovAxis::Y } else { FovAxis::X }),
                n => FovAxis::from_name(n).ok_or_else(|| {
                    node.error(format!(
                        "unknown fov_axis `{n}`; known: x, y, diagonal, smaller, larger"
                    ))
                }),
            }
        };
        let fov = |node: &Node| -> Result<f32> {
            let fov = match (node.float("fov")?, node.string("focal_length")) {
                (Some(f), None) => f,
                (None, Some(fl)) => {
                    let mm = super::props::parse_float(fl.trim_end_matches("mm"))
                        .ok_or_else(|| node.error(format!("cannot read focal_length `{fl}`")))?;
                    // A 35 mm film's width (36 mm) on the x axis.
                    return Ok(2.0 * (18.0 / mm).atan().to_degrees());
                }
                (None, None) => 39.3077,
                _ => return Err(node.error("give either `fov` or `focal_length`")),
            };
            if !(fov > 0.0 && fov < 180.0) {
                return Err(node.error(format!("fov must be between 0 and 180, got {fov}")));
            }
            Ok(fov)
        };
        let kind = self.plugin(node, SENSORS, Fallback::Use("perspective"))?;
        let camera = match kind.as_deref() {
            Some("perspective") => {
                node.float("focus_distance")?;
                let f = fov(node)?;
                let a = if node.has("focal_length") {
                    FovAxis::X
                } else {
                    axis(node)?
                };
                Camera::Perspective(Perspective::new(resolution, f, a, render_from_camera))
            }
            Some("thinlens") => {
                let f = fov(node)?;
                let a = axis(node)?;
                let aperture_radius = node.float_or("aperture_radius", 0.0)?;
                let focus_distance = node.float_or("focus_distance", 1.0)?;
                if aperture_radius < 0.0 || focus_distance <= 0.0 {
                    return Err(
                        node.error("thinlens needs aperture_radius >= 0 and focus_distance > 0")
                    );
                }
                Camera::ThinLens(ThinLens {
                    pinhole: Perspective::new(resolution, f, a, render_from_camera),
                    aperture_radius,
                    focus_distance,
                    aperture: crate::camera::Aperture::Disk,
                })
            }
            Some("orthographic") => Camera::Orthographic(Orthographic::new(
                resolution,
                1.0,
                FovAxis::X,
                render_from_camera,
            )),
            Some("realistic") => {
                let names = super::lens::RealisticNames {
                    lens_file: "lens_file",
                    aperture_diameter: "aperture_diameter",
                    focus_distance: "focus_distance",
                    film_diagonal: "film_diagonal",
                    blade_rotation: "blade_rotation",
                    flare_sampling: "flare_sampling",
                };
                super::lens::realistic_camera(node, resolution, render_from_camera, &names)?
            }
            _ => return Err(unknown_type(node, SENSORS)),
        };
        self.check_used(node)?;
        Ok((camera, sampler, film, (near, far)))
    }

    /// The film's size and reconstruction filter (Mitsuba's default: a Gaussian).
    fn film(&self, node: &Node) -> Result<Film> {
        self.plugin(node, FILMS, Fallback::Use("hdrfilm"))?;
        self.check_children(node, &["rfilter"])?;
        let mut filter = Filter::gaussian(0.5);
        for (_, f) in self.children(node)? {
            let positive = |name: &str, default: f32| -> Result<f32> {
                let v = f.float(name)?.unwrap_or(default);
                if v.is_finite() && v > 0.0 {
                    Ok(v)
                } else {
                    Err(f.error(format!("rfilter {name} must be positive, not {v}")))
                }
            };
            filter = match self.plugin(&f, RFILTERS, Fallback::Use("box"))?.as_deref() {
                Some("box") => Filter::Box,
                Some("tent") => Filter::Tent {
                    radius: positive("radius", 1.0)?,
                },
                Some("gaussian") => Filter::gaussian(positive("stddev", 0.5)?),
                Some("mitchell") => {
                    let b = f.float("B")?.unwrap_or(1.0 / 3.0);
                    let c = f.float("C")?.unwrap_or(1.0 / 3.0);
                    if !(b.is_finite() && c.is_finite()) {
                        return Err(
                            f.error(format!("mitchell B and C must be finite, not {b} and {c}"))
                        );
                    }
                    Filter::mitchell(b, c)
                }
                Some("catmullrom") => Filter::catmull_rom(),
                Some("lanczos") => {
                    let lobes = f.int("lobes")?.unwrap_or(3);
                    if !(1..=16).contains(&lobes) {
                        return Err(f.error(format!("lanczos lobes must be 1 to 16, not {lobes}")));
                    }
                    Filter::lanczos(lobes as u32)
                }
                _ => return Err(unknown_type(&f, RFILTERS)),
            };
            self.check_used(&f)?;
        }
        // Through the steps in which Mitsuba's film applies every filter.
        let filter = filter.with_steps(MITSUBA_FILTER_STEPS);
        let w = node.int("width")?.unwrap_or(768);
        let h = node.int("height")?.unwrap_or(576);
        for (name, v) in [("width", w), ("height", h)] {
            if !(1..=super::lightwave::MAX_IMAGE_SIDE).contains(&v) {
                return Err(node.error(format!("film {name} out of range: {v}")));
            }
        }
        let resolution = UVec2::new(w as u32, h as u32);
        // Mitsuba's crop: the size defaults to the whole film's, whatever the offset.
        let crop_value = |name: &str, default: u32| -> Result<u32> {
            let v = node.int(name)?.unwrap_or(default as i64);
            u32::try_from(v).map_err(|_| node.error(format!("film {name} out of range: {v}")))
        };
        let offset = UVec2::new(
            crop_value("crop_offset_x", 0)?,
            crop_value("crop_offset_y", 0)?,
        );
        let size = UVec2::new(
            crop_value("crop_width", resolution.x)?,
            crop_value("crop_height", resolution.y)?,
        );
        let crop = CropWindow { offset, size };
        if !crop.fits(resolution) {
            return Err(node.error(format!(
                "the film's crop of {}x{} pixels at ({}, {}) is empty or reaches outside its \
                 {w}x{h} pixels",
                size.x, size.y, offset.x, offset.y
            )));
        }
        let crop = (size != resolution).then_some(crop);
        for p in [
            "pixel_format",
            "file_format",
            "component_format",
            "banner",
            "sample_border",
            "compensate",
        ] {
            node.take(p);
        }
        self.check_used(node)?;
        Ok(Film {
            resolution,
            filter,
            crop,
        })
    }

    fn sampler(&self, node: &Node) -> Result<Sampler> {
        self.check_children(node, &[])?;
        let kind = match self
            .plugin(node, SAMPLERS, Fallback::Use("independent"))?
            .as_deref()
        {
            Some("independent") => "independent",
            Some("stratified" | "multijitter" | "ldsampler" | "orthogonal") => "sobol",
            _ => return Err(unknown_type(node, SAMPLERS)),
        };
        let count = node.int("sample_count")?.unwrap_or(4);
        if !(1..=1 << 24).contains(&count) {
            return Err(node.error(format!("sample_count out of range: {count}")));
        }
        let seed = node.int("seed")?.unwrap_or(0);
        node.bool_or("jitter", true)?;
        node.int("dimension")?;
        node.int("strength")?;
        node.check_all_used()?;
        let s = Sampler::Independent(IndependentSampler::new(count as u32, seed as u64));
        Ok(s.with_kind(kind).unwrap_or(s))
    }

    fn mesh(&mut self, node: &Node, file: &str) -> Result<Arc<Shape>> {
        let path = self.resolve_file(node, file);
        let face_normals = node.bool_or("face_normals", false)?;
        let flip = node.bool_or("flip_normals", false)?;
        // Mitsuba's OBJ reader flips v by default (its images have row 0 at v = 0); its
        // PLY reader keeps texture coordinates as they are.
        let is_obj = node.type_name.as_deref() == Some("obj");
        let flip_uv = is_obj && node.bool_or("flip_tex_coords", true)?;
        // A `.serialized` file may hold several meshes.
        let index = match node.type_name.as_deref() {
            Some("serialized") => {
                let i = node.int("shape_index")?.unwrap_or(0);
                usize::try_from(i)
                    .map_err(|_| node.error(format!("shape_index must be >= 0, not {i}")))?
            }
            _ => 0,
        };
        let canonical = path.canonicalize().unwrap_or_else(|_| path.clone());
        let key = (canonical, face_normals, flip, flip_uv, index);
        if let Some(s) = self.meshes.get(&key) {
            return Ok(s.clone());
        }
        let loaded = match node.type_name.as_deref() {
            Some("serialized") => crate::io::serialized::load_serialized(&path, index),
            _ => crate::io::load_mesh(&path),
        };
        let mut data = loaded.map_err(|e| node.error(format!("cannot load mesh: {e}")))?;
        if flip_uv {
            for uv in &mut data.uvs {
                uv.y = 1.0 - uv.y;
            }
        }
        if flip {
            for t in &mut data.indices {
                t.swap(1, 2);
            }
            for n in &mut data.normals {
                *n = -*n;
            }
        }
        // Mitsuba's mesh readers give a mesh without normals smooth ones. (Here in object
        // space, as the mesh may be shared by several placements; Mitsuba weighs the
        // angles after `to_world`, which differs only under a non-uniform scale.)
        if !face_normals && data.normals.is_empty() {
            data.compute_vertex_normals();
        }
        let mesh = TriangleMesh::new(data, !face_normals, self.options.accel.unwrap_or_default())
            .map_err(|m| node.error(format!("{}: {m}", path.display())))?;
        let s = Arc::new(Shape::TriangleMesh(Arc::new(mesh)));
        self.meshes.insert(key, s.clone());
        Ok(s)
    }

    /// A `linearcurve` (`basis` `None`) or `bsplinecurve`: Mitsuba moves the control
    /// points by `to_world` and keeps their radii.
    fn curves(
        &mut self,
        node: &Node,
        to_world: &Transform,
        basis: Option<CubicBasis>,
    ) -> Result<Arc<Shape>> {
        let file = node.string("filename").ok_or_else(|| {
            node.error(format!(
                "<shape type=\"{}\"> needs a `filename`",
                node.type_name.as_deref().unwrap_or("")
            ))
        })?;
        let path = self.resolve_file(node, &file);
        let curves = crate::io::curves::load_curves(&path, basis)
            .map_err(|e| node.error(format!("cannot load curves: {e}")))?;
        let placed: Vec<_> = curves
            .into_iter()
            .map(|c| c.into_iter().map(|(p, r)| (to_world.point(p), r)).collect())
            .collect();
        let accel = self.options.accel.unwrap_or_default();
        let shape = match basis {
            None => LinearCurves::new(&placed, accel).map(|c| Shape::LinearCurves(Arc::new(c))),
            Some(b) => CubicCurves::new(&placed, b, accel).map(|c| Shape::CubicCurves(Arc::new(c))),
        }
        .map_err(|m| node.error(format!("{}: {m}", path.display())))?;
        Ok(Arc::new(shape))
    }

    fn shape(&mut self, node: &Rc<Node>) -> Result<Instance> {
        if node.type_name.as_deref() == Some("csg") {
            self.check_children(node, &["transform", "bsdf", "shape", "string"])?;
        } else {
            self.check_children(node, &["transform", "bsdf", "emitter"])?;
        }
        let to_world = self.to_world(node)?;
        let (shape, object) = match node.type_name.as_deref() {
            Some("csg") => {
                // The whole tree's own transform is the instance's; operands keep theirs.
                let root = self.csg_operands(node, None)?;
                let csg = Csg::new(root).map_err(|m| node.error(m))?;
                (Arc::new(Shape::Csg(Arc::new(csg))), Transform::IDENTITY)
            }
            Some(t @ ("obj" | "ply" | "serialized")) => {
                let file = node.string("filename").ok_or_else(|| {
                    node.error(format!("<shape type=\"{t}\"> needs a `filename`"))
                })?;
                (self.mesh(node, &file)?, Transform::IDENTITY)
            }
            Some("sphere") => {
                let c = node.vec3("center")?.unwrap_or(Vec3::ZERO);
                let r = node.float_or("radius", 1.0)?;
                let s = Transform::scale(Vec3::splat(r))
                    .ok_or_else(|| node.error("sphere radius is zero"))?;
                (
                    Arc::new(Shape::Sphere(Sphere)),
                    s.then(&Transform::translate(c)),
                )
            }
            Some("rectangle") => (Arc::new(Shape::Rectangle(Rectangle)), Transform::IDENTITY),
            Some("disk") => (Arc::new(Shape::Disk(Disk)), Transform::IDENTITY),
            Some("cube") => (Arc::new(Shape::Cuboid(Cuboid)), Transform::IDENTITY),
            Some("cylinder") => (
                Arc::new(Shape::Cylinder(Cylinder { caps: false })),
                cylinder_placement(node)?,
            ),
            Some("linearcurve") => (self.curves(node, &to_world, None)?, Transform::IDENTITY),
            Some("bsplinecurve") => (
                self.curves(node, &to_world, Some(CubicBasis::BSpline))?,
                Transform::IDENTITY,
            ),
            _ => return Err(unknown_type(node, SHAPES)),
        };
        // Meshes flip their triangles' normals as they load; the analytic shapes through
        // their instance.
        let flip_normals = !matches!(
            node.type_name.as_deref(),
            Some("obj" | "ply" | "serialized" | "csg")
        ) && node.bool_or("flip_normals", false)?;
        // Curves have their control points placed already (their radii stay as given).
        let placement = if matches!(
            node.type_name.as_deref(),
            Some("linearcurve" | "bsplinecurve")
        ) {
            Transform::IDENTITY
        } else {
            object.then(&to_world)
        };
        let mut instance = Instance::new(shape, placement);
        let mut material = None;
        for (_, c) in self.children(node)? {
            match c.tag.as_str() {
                "bsdf" => {
                    if material.is_some() {
                        return Err(c.error("the shape has more than one <bsdf>"));
                    }
                    if c.type_name.as_deref() == Some("mask") {
                        // A mask acts on the surface itself, not on its scattering.
                        let (inner, mask) = self.mask(&c)?;
                        let accel = self.options.accel.unwrap_or_default();
                        let shape = masked_shape(&instance.shape, mask, accel)
                            .ok_or_else(|| c.error(MASK_SHAPES))?;
                        instance = Instance::new(Arc::new(shape), placement);
                        material = Some(inner);
                    } else {
                        material = Some(self.material(&c)?);
                    }
                }
                "emitter" => {
                    if c.type_name.as_deref() != Some("area") {
                        return Err(c.error("only an area <emitter> can be attached to a shape"));
                    }
                    if instance.emission.is_some() {
                        return Err(c.error("the shape has more than one <emitter>"));
                    }
                    self.check_children(&c, &["texture"])?;
                    let radiance = self.slot(&c, "radiance", Vec3::ONE)?;
                    c.check_all_used()?;
                    instance.emission = Some(Emission { radiance });
                }
                _ => {}
            }
        }
        // Mitsuba's default BSDF: diffuse 0.5, but black on an emitter (an area light
        // without a BSDF of its own reflects nothing).
        let default_albedo = if instance.emission.is_some() {
            0.0
        } else {
            0.5
        };
        instance.material = Some(match material {
            Some(m) => m,
            None => Arc::new(one_sided(Material::Diffuse(Diffuse {
                albedo: Arc::new(Texture::Constant(Vec3::splat(default_albedo))),
            }))),
        });
        instance.flip_normals = flip_normals;
        node.check_all_used()?;
        Ok(instance)
    }

    /// A `<shape type="instance">`: the shapes of the `shapegroup` it refers to, each
    /// placed by its own `to_world` and then the instance's. Meshes are loaded once and
    /// shared by every instance of their group.
    fn instance(&mut self, node: &Rc<Node>) -> Result<Vec<Instance>> {
        self.check_children(node, &["transform", "shape"])?;
        let to_world = self.to_world(node)?;
        let groups: Vec<Rc<Node>> = self
            .children(node)?
            .into_iter()
            .map(|(_, c)| c)
            .filter(|c| c.tag == "shape")
            .collect();
        let [group] = groups.as_slice() else {
            return Err(node.error("an instance needs exactly one <ref> to a shapegroup"));
        };
        if group.type_name.as_deref() != Some("shapegroup") {
            return Err(node.error(format!(
                "an instance must refer to a shapegroup, not to {}",
                group.describe()
            )));
        }
        self.check_children(group, &["shape"])?;
        let mut placed = Vec::new();
        for (_, c) in self.children(group)? {
            match self.plugin(&c, SHAPES, Fallback::Skip)?.as_deref() {
                None => {}
                Some("shapegroup" | "instance") => {
                    return Err(c.error("shape groups cannot be nested"));
                }
                Some(_) => {
                    let shape = self.shape(&c)?;
                    let mut instance = Instance::new(
                        shape.shape.clone(),
                        shape.render_from_object.then(&to_world),
                    );
                    instance.material = shape.material;
                    instance.emission = shape.emission;
                    instance.flip_normals = shape.flip_normals;
                    placed.push(instance);
                }
            }
        }
        self.check_used(group)?;
        self.check_used(node)?;
        Ok(placed)
    }

    /// The tree of a `<shape type="csg">` (a lightpath extension of the format: Mitsuba
    /// has no CSG): `<string name="op" value="union|difference|intersection"/>` and two or
    /// more operand `<shape>`s (sphere, cube, cylinder, obj/ply closed meshes, or nested
    /// csg), each with its own `to_world` and optional `<bsdf>`; operands without a bsdf
    /// take the nearest enclosing one.
    fn csg_operands(
        &mut self,
        node: &Rc<Node>,
        inherited: Option<Arc<Material>>,
    ) -> Result<CsgNode> {
        let mut material = inherited;
        for (_, c) in self.children(node)? {
            if c.tag == "bsdf" {
                material = Some(self.material(&c)?);
            }
        }
        let op_name = node.string("op").ok_or_else(|| {
            node.error(format!(
                "<shape type=\"csg\"> needs <string name=\"op\">: {}",
                CsgOp::NAMES.join(", ")
            ))
        })?;
        let op = CsgOp::from_name(&op_name).ok_or_else(|| {
            node.error(format!(
                "unknown csg op `{op_name}`; known: {}",
                CsgOp::NAMES.join(", ")
            ))
        })?;
        let operands: Vec<Rc<Node>> = self
            .children(node)?
            .into_iter()
            .filter(|(_, c)| c.tag == "shape")
            .map(|(_, c)| c)
            .collect();
        if operands.len() < 2 {
            return Err(node.error(format!(
                "<shape type=\"csg\"> needs at least two <shape> operands, found {}",
                operands.len()
            )));
        }
        let mut tree: Option<CsgNode> = None;
        for operand in &operands {
            let leaf = self.csg_operand(operand, material.clone())?;
            tree = Some(match tree {
                None => leaf,
                Some(left) => CsgNode::op(op, left, leaf),
            });
        }
        node.check_all_used()?;
        Ok(tree.expect("two or more operands"))
    }

    fn csg_operand(
        &mut self,
        node: &Rc<Node>,
        inherited: Option<Arc<Material>>,
    ) -> Result<CsgNode> {
        let to_world = self.to_world(node)?;
        if node.type_name.as_deref() == Some("csg") {
            self.check_children(node, &["transform", "bsdf", "shape", "string"])?;
            return Ok(self.csg_operands(node, inherited)?.transformed(&to_world));
        }
        self.check_children(node, &["transform", "bsdf"])?;
        let mut material = inherited;
        for (_, c) in self.children(node)? {
            if c.tag == "bsdf" {
                material = Some(self.material(&c)?);
            }
        }
        let (solid, object) = match node.type_name.as_deref() {
            Some("sphere") => {
                let c = node.vec3("center")?.unwrap_or(Vec3::ZERO);
                let r = node.float_or("radius", 1.0)?;
                let s = Transform::scale(Vec3::splat(r))
                    .ok_or_else(|| node.error("sphere radius is zero"))?;
                (Solid::Sphere, s.then(&Transform::translate(c)))
            }
            Some("cube") => (Solid::Cube, Transform::IDENTITY),
            Some(t @ ("obj" | "ply" | "serialized")) => {
                let file = node.string("filename").ok_or_else(|| {
                    node.error(format!("<shape type=\"{t}\"> needs a `filename`"))
                })?;
                let Shape::TriangleMesh(m) = &*self.mesh(node, &file)? else {
                    unreachable!("mesh() builds meshes")
                };
                (Solid::Mesh(m.clone()), Transform::IDENTITY)
            }
            // Mitsuba's cylinder is open; as a solid operand it is closed by caps.
            Some("cylinder") => (Solid::Cylinder, cylinder_placement(node)?),
            _ => {
                return Err(unknown_type(
                    node,
                    &[
                        "sphere",
                        "cube",
                        "cylinder",
                        "obj",
                        "ply",
                        "serialized",
                        "csg",
                    ],
                ))
            }
        };
        node.check_all_used()?;
        Ok(CsgNode::leaf(solid)
            .with_material(material)
            .transformed(&object.then(&to_world)))
    }

    /// A light, or `None` when `--lenient` leaves an unsupported emitter out.
    fn emitter(&mut self, node: &Node) -> Result<Option<Light>> {
        let Some(kind) = self.plugin(node, EMITTERS, Fallback::Skip)? else {
            return Ok(None);
        };
        let to_world = self.to_world(node)?;
        let light = match Some(kind.as_str()) {
            Some("point") => {
                self.check_children(node, &["transform"])?;
                let position = node
                    .vec3("position")?
                    .unwrap_or_else(|| to_world.point(Vec3::ZERO));
                let intensity = node.vec3("intensity")?.unwrap_or(Vec3::ONE);
                Light::Point(PointLight {
                    position,
                    intensity,
                })
            }
            Some("spot") => {
                self.check_children(node, &["transform", "texture"])?;
                let intensity = node.vec3("intensity")?.unwrap_or(Vec3::ONE);
                let cutoff = node.float_or("cutoff_angle", 20.0)?;
                let beam = node.float_or("beam_width", cutoff * 0.75)?;
                if !(0.0..=180.0).contains(&cutoff) || beam < 0.0 || beam > cutoff {
                    return Err(node.error("spot needs 0 <= beam_width <= cutoff_angle <= 180"));
                }
                if self.single(node, "texture")?.is_some() {
                    return Err(node.error("a spot light's texture is not supported"));
                }
                Light::Spot(SpotLight {
                    position: to_world.point(Vec3::ZERO),
                    direction: to_world.vector(Vec3::Z).normalize(),
                    intensity,
                    cos_falloff_start: beam.to_radians().cos(),
                    cos_cutoff: cutoff.to_radians().cos(),
                    profile: SpotProfile::LinearAngle,
                })
            }
            Some("directional") => {
                self.check_children(node, &["transform"])?;
                let travel = node
                    .vec3("direction")?
                    .unwrap_or_else(|| to_world.vector(Vec3::Z));
                if travel.length_squared() == 0.0 {
                    return Err(node.error("directional `direction` is zero"));
                }
                let intensity = node.vec3("irradiance")?.unwrap_or(Vec3::ONE);
                Light::Directional(DirectionalLight {
                    direction: -travel.normalize(),
                    intensity,
                })
            }
            Some("constant") => {
                self.check_children(node, &["texture"])?;
                let radiance = self.slot(node, "radiance", Vec3::ONE)?;
                Light::Environment(Environment::new(radiance, Transform::IDENTITY))
            }
            Some("envmap") => {
                self.check_children(node, &["transform"])?;
                let file = node
                    .string("filename")
                    .ok_or_else(|| node.error("envmap needs a `filename`"))?;
                let path = self.resolve_file(node, &file);
                let image = self.image(node, &path, false)?;
                let scale = node.float_or("scale", 1.0)?;
                let texture = Arc::new(Texture::Image(ImageTexture {
                    image,
                    border: BorderMode::Repeat,
                    filter: FilterMode::Bilinear,
                    exposure: scale,
                }));
                // Mitsuba's lat-long mapping is ours with x and z swapped.
                let swap = Transform::from_row_major(&[
                    0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
                ])
                .expect("invertible");
                Light::Environment(Environment::new(texture, swap.then(&to_world)))
            }
            Some("area") => return Err(node.error("an area emitter must be attached to a <shape>")),
            _ => return Err(unknown_type(node, EMITTERS)),
        };
        self.check_used(node)?;
        Ok(Some(light))
    }

    fn image(&mut self, node: &Node, path: &Path, raw: bool) -> Result<Arc<crate::film::Image>> {
        let key = (path.to_path_buf(), raw);
        if let Some(i) = self.images.get(&key) {
            return Ok(i.clone());
        }
        let transfer = if raw {
            Transfer::Linear
        } else {
            Transfer::Srgb
        };
        let img = crate::io::image::read_image(path, Some(transfer))
            .map_err(|e| node.error(format!("cannot load image: {e}")))?;
        let img = Arc::new(img);
        self.images.insert(key, img.clone());
        Ok(img)
    }

    /// A colour or float parameter: a `<texture name=...>` child (or a named `<ref>`),
    /// or an `rgb`/`spectrum`/`float` property, or `default`.
    fn slot(&mut self, node: &Node, name: &str, default: Vec3) -> Result<Arc<Texture>> {
        Ok(self
            .optional_slot(node, name)?
            .unwrap_or_else(|| Arc::new(Texture::Constant(default))))
    }

    /// A float parameter (Mitsuba's `eval_1`): as [`Self::slot`], but a colour texture
    /// gives its luminance, in every channel, as Mitsuba's textures do when a BSDF asks
    /// them for one value.
    fn scalar_slot(&mut self, node: &Node, name: &str, default: f32) -> Result<Arc<Texture>> {
        let t = self.slot(node, name, Vec3::splat(default))?;
        Ok(self.grey(t))
    }

    /// [`grey_texture`], made once per texture.
    fn grey(&mut self, t: Arc<Texture>) -> Arc<Texture> {
        let key = Arc::as_ptr(&t);
        if let Some(g) = self.grey_textures.get(&key) {
            return g.0.clone();
        }
        let g = grey_texture(&t);
        // The source is kept alive beside its grey copy so that its address stays unique.
        self.grey_textures.insert(key, (g.clone(), t));
        g
    }

    fn optional_slot(&mut self, node: &Node, name: &str) -> Result<Option<Arc<Texture>>> {
        for (slot, c) in self.children(node)? {
            if c.tag == "texture" && slot.as_deref() == Some(name) {
                return self.texture(&c).map(Some);
            }
        }
        Ok(node.vec3(name)?.map(|v| Arc::new(Texture::Constant(v))))
    }

    fn texture(&mut self, node: &Rc<Node>) -> Result<Arc<Texture>> {
        let key = Rc::as_ptr(node);
        if let Some(t) = self.textures.get(&key) {
            return Ok(t.clone());
        }
        let kind = self.plugin(node, TEXTURES, Fallback::Replace("a constant 0.5"))?;
        let texture = match kind.as_deref() {
            None => Texture::Constant(Vec3::splat(0.5)),
            Some("bitmap") => {
                self.check_children(node, &["transform"])?;
                let file = node
                    .string("filename")
                    .ok_or_else(|| node.error("bitmap needs a `filename`"))?;
                let path = self.resolve_file(node, &file);
                let raw = node.bool_or("raw", false)?;
                let image = self.image(node, &path, raw)?;
                let filter = match node.string_or("filter_type", "bilinear").as_str() {
                    "bilinear" => FilterMode::Bilinear,
                    "nearest" => FilterMode::Nearest,
                    f => return Err(node.error(format!("unknown filter_type `{f}`"))),
                };
                let border = match node.string_or("wrap_mode", "repeat").as_str() {
                    "repeat" => BorderMode::Repeat,
                    "clamp" => BorderMode::Clamp,
                    w => return Err(node.error(format!("unsupported wrap_mode `{w}`"))),
                };
                // Mitsuba reads row 0 of the image at v = 0, ours at v = 1: flip v after
                // the scene's own `to_uv`.
                let flip_v = Affine2::from_cols(Vec2::X, -Vec2::Y, Vec2::Y);
                let to_uv = match self.single(node, "transform")? {
                    Some(t) => {
                        let m = transform(&t)?;
                        let m = m.matrix();
                        Affine2::from_cols(
                            m.x_axis.truncate().truncate(),
                            m.y_axis.truncate().truncate(),
                            m.w_axis.truncate().truncate(),
                        )
                    }
                    None => Affine2::IDENTITY,
                };
                Texture::Transformed(TransformedTexture {
                    to_uv: flip_v * to_uv,
                    texture: Arc::new(Texture::Image(ImageTexture {
                        image,
                        border,
                        filter,
                        exposure: 1.0,
                    })),
                })
            }
            Some("checkerboard") => {
                self.check_children(node, &["transform"])?;
                // Mitsuba's checkerboard has 2×2 cells over the unit uv square.
                let mut scale = Vec2::splat(2.0);
                if let Some(t) = self.single(node, "transform")? {
                    let m = transform(&t)?;
                    let m = m.matrix();
                    if m.x_axis.y != 0.0
                        || m.y_axis.x != 0.0
                        || m.w_axis.x != 0.0
                        || m.w_axis.y != 0.0
                    {
                        return Err(t.error("checkerboard `to_uv`: only a scale is supported"));
                    }
                    scale *= Vec2::new(m.x_axis.x, m.y_axis.y);
                }
                Texture::Checkerboard(Checkerboard {
                    scale,
                    color0: node.vec3("color0")?.unwrap_or(Vec3::splat(0.4)),
                    color1: node.vec3("color1")?.unwrap_or(Vec3::splat(0.2)),
                })
            }
            Some("mesh_attribute") => {
                self.check_children(node, &[])?;
                let name = node
                    .string("name")
                    .ok_or_else(|| node.error("mesh_attribute needs a `name`"))?;
                if name != "vertex_color" && name != "face_color" {
                    return Err(node.error(format!(
                        "mesh_attribute `{name}`: only `vertex_color` and `face_color` (a \
                         PLY file's vertex or face colours) are supported"
                    )));
                }
                let scale = node.float_or("scale", 1.0)?;
                Texture::VertexColor(Arc::new(Texture::Constant(Vec3::splat(scale))))
            }
            _ => return Err(unknown_type(node, TEXTURES)),
        };
        if kind.is_some() {
            self.check_used(node)?;
        }
        let t = Arc::new(texture);
        self.textures.insert(key, t.clone());
        Ok(t)
    }

    /// An index of refraction: a number or a name from Mitsuba's table.
    fn ior(&self, node: &Node, name: &str, default: f32) -> Result<f32> {
        let Some(v) = node.string(name) else {
            return Ok(default);
        };
        if let Some(x) = super::props::parse_float(&v) {
            if x > 0.0 {
                return Ok(x);
            }
        }
        IORS.iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(&v))
            .map(|(_, x)| *x)
            .ok_or_else(|| node.error(format!("unknown `{name}` `{v}`")))
    }

    fn eta(&self, node: &Node, int_default: f32) -> Result<f32> {
        if node.has("eta") {
            return node.float_or("eta", 1.5);
        }
        Ok(self.ior(node, "int_ior", int_default)? / self.ior(node, "ext_ior", 1.000277)?)
    }

    /// `alpha` (or `alpha_u`/`alpha_v`), a number or a texture (one value, as
    /// [`grey_texture`] reads it), as our roughness √α, and the microfacet distribution
    /// (Mitsuba's default: Beckmann). Isotropic roughness is one texture for both
    /// directions.
    fn roughness(&mut self, node: &Node) -> Result<(Arc<Texture>, Arc<Texture>, Distribution)> {
        let name = node.string_or("distribution", "beckmann");
        let dist = Distribution::from_name(&name)
            .ok_or_else(|| node.error(format!("unknown distribution `{name}` (ggx, beckmann)")))?;
        // Visible normals are always sampled.
        node.bool_or("sample_visible", true)?;
        let mut alpha = |name: &str| -> Result<Option<Arc<Texture>>> {
            let Some(t) = self.optional_slot(node, name)? else {
                return Ok(None);
            };
            let t = self.grey(t);
            Ok(Some(Arc::new(match &*t {
                Texture::Constant(c) => Texture::Constant(Vec3::splat(c.x.max(0.0).sqrt())),
                _ => Texture::Sqrt(t),
            })))
        };
        match (alpha("alpha")?, alpha("alpha_u")?, alpha("alpha_v")?) {
            (a, None, None) => {
                let t =
                    a.unwrap_or_else(|| Arc::new(Texture::Constant(Vec3::splat(0.1f32.sqrt()))));
                Ok((t.clone(), t, dist))
            }
            (None, Some(u), Some(v)) => Ok((u, v, dist)),
            _ => Err(node.error("give `alpha` or both `alpha_u` and `alpha_v`")),
        }
    }

    /// A `mask` BSDF: the nested BSDF, and the `opacity` (default 0.5, one value as
    /// [`grey_texture`] reads it) as stochastic transparency of the surface.
    fn mask(&mut self, node: &Rc<Node>) -> Result<(Arc<Material>, AlphaMask)> {
        self.check_children(node, &["texture", "bsdf"])?;
        let coverage = self.scalar_slot(node, "opacity", 0.5)?;
        let [inner] = self
            .bsdfs(node)?
            .try_into()
            .map_err(|_: Vec<_>| node.error("a `mask` BSDF needs exactly one nested <bsdf>"))?;
        if inner.type_name.as_deref() == Some("mask") {
            return Err(inner.error("a `mask` BSDF cannot be nested in another"));
        }
        let material = self.material(&inner)?;
        node.check_all_used()?;
        Ok((
            material,
            AlphaMask {
                coverage,
                test: AlphaTest::Stochastic,
            },
        ))
    }

    fn bsdfs(&self, node: &Node) -> Result<Vec<Rc<Node>>> {
        Ok(self
            .children(node)?
            .into_iter()
            .map(|(_, c)| c)
            .filter(|c| c.tag == "bsdf")
            .collect())
    }

    fn material(&mut self, node: &Rc<Node>) -> Result<Arc<Material>> {
        let key = Rc::as_ptr(node);
        if let Some(m) = self.materials.get(&key) {
            return Ok(m.clone());
        }
        let kind = self.plugin(node, BSDFS, Fallback::Replace("a diffuse 0.5"))?;
        let material = match kind.as_deref() {
            None => Material::Diffuse(Diffuse {
                albedo: Arc::new(Texture::Constant(Vec3::splat(0.5))),
            }),
            Some("diffuse") => {
                self.check_children(node, &["texture"])?;
                Material::Diffuse(Diffuse {
                    albedo: self.slot(node, "reflectance", Vec3::splat(0.5))?,
                })
            }
            Some(t @ ("conductor" | "roughconductor")) => {
                self.check_children(node, &["texture"])?;
                let reflectance = self.slot(node, "specular_reflectance", Vec3::ONE)?;
                let ior = match (node.string("material"), node.vec3("eta")?, node.vec3("k")?) {
                    (Some(n), None, None) if n == "none" => None,
                    (Some(n), None, None) => {
                        let (eta, k) = fresnel::mitsuba_metal(&n).ok_or_else(|| {
                            let known: Vec<&str> =
                                fresnel::MITSUBA_METALS.iter().map(|m| m.0).collect();
                            node.error(format!(
                                "conductor material `{n}` is not supported; supported: none, {}",
                                known.join(", ")
                            ))
                        })?;
                        Some(ComplexIor { eta, k })
                    }
                    (None, None, None) => None,
                    (None, Some(eta), k) => Some(ComplexIor {
                        eta,
                        k: k.unwrap_or(Vec3::ZERO),
                    }),
                    _ => return Err(node.error("give either `material` or `eta`/`k`")),
                };
                if t == "conductor" {
                    Material::Conductor(Conductor { reflectance, ior })
                } else {
                    let (roughness_u, roughness_v, distribution) = self.roughness(node)?;
                    Material::RoughConductor(RoughConductor {
                        reflectance,
                        roughness_u,
                        roughness_v,
                        ior,
                        distribution,
                    })
                }
            }
            Some(t @ ("dielectric" | "thindielectric" | "roughdielectric")) => {
                self.check_children(node, &["texture"])?;
                let ior = self.eta(node, 1.5046)?;
                let reflectance = self.slot(node, "specular_reflectance", Vec3::ONE)?;
                let transmittance = self.slot(node, "specular_transmittance", Vec3::ONE)?;
                match t {
                    "dielectric" => Material::Dielectric(Dielectric {
                        ior,
                        reflectance,
                        transmittance,
                    }),
                    "thindielectric" => Material::ThinDielectric(ThinDielectric {
                        ior,
                        reflectance,
                        transmittance,
                    }),
                    _ => {
                        let (roughness, v, distribution) = self.roughness(node)?;
                        if !Arc::ptr_eq(&roughness, &v) {
                            return Err(
                                node.error("an anisotropic roughdielectric is not supported")
                            );
                        }
                        Material::RoughDielectric(RoughDielectric {
                            ior,
                            roughness,
                            reflectance,
                            transmittance,
                            distribution,
                        })
                    }
                }
            }
            Some(t @ ("plastic" | "roughplastic")) => {
                self.check_children(node, &["texture"])?;
                let diffuse = self.slot(node, "diffuse_reflectance", Vec3::splat(0.5))?;
                let specular = self.slot(node, "specular_reflectance", Vec3::ONE)?;
                let eta = self.eta(node, 1.49)?;
                let nonlinear = node.bool_or("nonlinear", false)?;
                if t == "plastic" {
                    Material::Plastic(Plastic::new(diffuse, specular, eta, nonlinear))
                } else {
                    let (roughness, v, distribution) = self.roughness(node)?;
                    if !Arc::ptr_eq(&roughness, &v) {
                        return Err(node.error("an anisotropic roughplastic is not supported"));
                    }
                    // Mitsuba's roughplastic takes a number (its tables are per BSDF).
                    let Texture::Constant(roughness) = &*roughness else {
                        return Err(node.error("roughplastic `alpha` must be a number"));
                    };
                    Material::RoughPlastic(RoughPlastic::new(
                        diffuse,
                        specular,
                        eta,
                        roughness.x,
                        distribution,
                        nonlinear,
                    ))
                }
            }
            Some("principled") => {
                self.check_children(node, &["texture"])?;
                let spec_trans = self
                    .optional_slot(node, "spec_trans")?
                    .map(|t| self.grey(t));
                // Mitsuba's `has_spec_trans`: given, and not the float 0.
                let transmits = spec_trans
                    .as_deref()
                    .is_some_and(|t| !matches!(t, Texture::Constant(c) if *c == Vec3::ZERO));
                let eta = match (node.float("eta")?, node.float("specular")?) {
                    (Some(_), Some(_)) => {
                        return Err(node.error("principled takes `eta` or `specular`, not both"))
                    }
                    // An index of 1 cannot refract: Mitsuba nudges it.
                    (Some(eta), None) if transmits && eta == 1.0 => 1.001,
                    (Some(eta), None) => eta,
                    (None, Some(s)) if !(0.0..=1.0).contains(&s) => {
                        return Err(
                            node.error(format!("principled `specular` {s} is not in [0, 1]"))
                        )
                    }
                    (None, specular) => {
                        let s = specular.unwrap_or(0.5);
                        let s = if transmits && s == 0.0 { 1e-3 } else { s };
                        DisneyPrincipled::eta_from_specular(s)
                    }
                };
                if !(eta.is_finite() && eta > 0.0) {
                    return Err(node.error(format!("principled `eta` {eta} must be positive")));
                }
                let rate = |name: &str| sampling_rate(node, "principled", name);
                let zero = Vec3::ZERO;
                Material::DisneyPrincipled(DisneyPrincipled {
                    base_color: self.slot(node, "base_color", Vec3::splat(0.5))?,
                    roughness: self.scalar_slot(node, "roughness", 0.5)?,
                    anisotropic: self.scalar_slot(node, "anisotropic", 0.0)?,
                    metallic: self.scalar_slot(node, "metallic", 0.0)?,
                    spec_trans: spec_trans.unwrap_or_else(|| Arc::new(Texture::Constant(zero))),
                    spec_tint: self.scalar_slot(node, "spec_tint", 0.0)?,
                    sheen: self.scalar_slot(node, "sheen", 0.0)?,
                    sheen_tint: self.scalar_slot(node, "sheen_tint", 0.0)?,
                    flatness: self.scalar_slot(node, "flatness", 0.0)?,
                    clearcoat: self.scalar_slot(node, "clearcoat", 0.0)?,
                    clearcoat_gloss: self.scalar_slot(node, "clearcoat_gloss", 0.0)?,
                    eta,
                    specular_sampling_rate: rate("main_specular_sampling_rate")?,
                    clearcoat_sampling_rate: rate("clearcoat_sampling_rate")?,
                    diffuse_sampling_rate: rate("diffuse_reflectance_sampling_rate")?,
                })
            }
            Some("principledthin") => {
                self.check_children(node, &["texture"])?;
                let rate = |name: &str| sampling_rate(node, "principledthin", name);
                let eta = self.scalar_slot(node, "eta", 1.5)?;
                if let Texture::Constant(c) = &*eta {
                    if !(c.x.is_finite() && c.x > 0.0) {
                        let e = format!("principledthin `eta` {} must be positive", c.x);
                        return Err(node.error(e));
                    }
                }
                Material::DisneyThin(DisneyThin {
                    base_color: self.slot(node, "base_color", Vec3::splat(0.5))?,
                    roughness: self.scalar_slot(node, "roughness", 0.5)?,
                    anisotropic: self.scalar_slot(node, "anisotropic", 0.0)?,
                    spec_trans: self.scalar_slot(node, "spec_trans", 0.0)?,
                    spec_tint: self.scalar_slot(node, "spec_tint", 0.0)?,
                    sheen: self.scalar_slot(node, "sheen", 0.0)?,
                    sheen_tint: self.scalar_slot(node, "sheen_tint", 0.0)?,
                    flatness: self.scalar_slot(node, "flatness", 0.0)?,
                    diff_trans: self.scalar_slot(node, "diff_trans", 0.0)?,
                    eta,
                    specular_reflectance_sampling_rate: rate("specular_reflectance_sampling_rate")?,
                    specular_transmittance_sampling_rate: rate(
                        "specular_transmittance_sampling_rate",
                    )?,
                    diffuse_reflectance_sampling_rate: rate("diffuse_reflectance_sampling_rate")?,
                    diffuse_transmittance_sampling_rate: rate(
                        "diffuse_transmittance_sampling_rate",
                    )?,
                })
            }
            Some("hair") => {
                self.check_children(node, &["texture"])?;
                let params = crate::material::HairParameters {
                    sigma_a: node.vec3("sigma_a")?,
                    color: self.optional_slot(node, "color")?,
                    eumelanin: node.float("eumelanin")?,
                    pheomelanin: node.float("pheomelanin")?,
                    eta: node.float("eta")?,
                    beta_m: node.float("beta_m")?,
                    beta_n: node.float("beta_n")?,
                    alpha: node.float("alpha")?,
                };
                Material::Hair(params.build().map_err(|m| node.error(m))?)
            }
            Some("twosided") => {
                self.check_children(node, &["bsdf"])?;
                let inner = self.bsdfs(node)?;
                match inner.len() {
                    1 => Material::TwoSided(TwoSided::new(self.material(&inner[0])?)),
                    2 if Rc::ptr_eq(&inner[0], &inner[1]) => {
                        Material::TwoSided(TwoSided::new(self.material(&inner[0])?))
                    }
                    2 => Material::TwoSided(TwoSided {
                        inner: self.material(&inner[0])?,
                        back: Some(self.material(&inner[1])?),
                    }),
                    n => {
                        return Err(
                            node.error(format!("twosided needs one or two <bsdf>s, found {n}"))
                        )
                    }
                }
            }
            Some("blendbsdf") => {
                self.check_children(node, &["bsdf", "texture"])?;
                let inner = self.bsdfs(node)?;
                if inner.len() != 2 {
                    return Err(node.error(format!(
                        "blendbsdf needs two <bsdf>s, found {}",
                        inner.len()
                    )));
                }
                Material::Blend(Blend {
                    weight: self.scalar_slot(node, "weight", 0.5)?,
                    first: self.material(&inner[0])?,
                    second: self.material(&inner[1])?,
                })
            }
            Some("normalmap") => {
                self.check_children(node, &["bsdf", "texture"])?;
                let normal = self
                    .optional_slot(node, "normalmap")?
                    .ok_or_else(|| node.error("normalmap needs a `normalmap` texture"))?;
                let inner = self.bsdfs(node)?;
                if inner.len() != 1 {
                    return Err(node.error("normalmap needs one <bsdf>"));
                }
                Material::NormalMap(NormalMap {
                    normal,
                    inner: self.material(&inner[0])?,
                    flip_invalid: node.bool_or("flip_invalid_normals", true)?,
                    shadowing: node.bool_or("use_shadowing_function", true)?,
                })
            }
            Some("bumpmap") => {
                self.check_children(node, &["bsdf", "texture"])?;
                // The height field is the one nested texture, whatever its name.
                let textures: Vec<_> = self
                    .children(node)?
                    .into_iter()
                    .filter(|(_, c)| c.tag == "texture")
                    .collect();
                let [(_, texture)] = textures.as_slice() else {
                    return Err(node.error(format!(
                        "bumpmap needs one <texture> (the height field), found {}",
                        textures.len()
                    )));
                };
                let height = self.texture(texture)?;
                let inner = self.bsdfs(node)?;
                if inner.len() != 1 {
                    return Err(node.error("bumpmap needs one <bsdf>"));
                }
                let scale = node.float_or("scale", 1.0)?;
                if !scale.is_finite() {
                    return Err(node.error(format!("bumpmap `scale` must be finite, not {scale}")));
                }
                Material::BumpMap(BumpMap {
                    height,
                    scale,
                    inner: self.material(&inner[0])?,
                    flip_invalid: node.bool_or("flip_invalid_normals", true)?,
                    shadowing: node.bool_or("use_shadowing_function", true)?,
                })
            }
            _ => return Err(unknown_type(node, BSDFS)),
        };
        check_bump_nesting(node, &material)?;
        if kind.is_some() {
            self.check_used(node)?;
        }
        let m = Arc::new(one_sided(material));
        self.materials.insert(key, m.clone());
        Ok(m)
    }
}

/// A `bumpmap` perturbs the frame where the material meets the surface, so it may be a
/// shape's BSDF or a side of a `twosided`, wrapping anything: an error for one nested
/// deeper (directly or through a `twosided`) in `material`, the BSDF `node` made.
fn check_bump_nesting(node: &Node, material: &Material) -> Result<()> {
    let has_bump_side = |m: &Material| match m {
        Material::TwoSided(t) => std::iter::once(&t.inner)
            .chain(t.back.as_ref())
            .any(|m| matches!(**m, Material::BumpMap(_))),
        _ => false,
    };
    let inner: Vec<&Material> = match material {
        Material::Blend(b) => vec![&*b.first, &*b.second],
        Material::NormalMap(m) => vec![&*m.inner],
        Material::BumpMap(m) => vec![&*m.inner],
        Material::TwoSided(t) => std::iter::once(&t.inner)
            .chain(t.back.as_ref())
            .map(|m| &**m)
            .collect(),
        _ => Vec::new(),
    };
    let in_twosided = matches!(material, Material::TwoSided(_));
    for m in inner {
        if (matches!(m, Material::BumpMap(_)) && !in_twosided) || has_bump_side(m) {
            return Err(node.error(format!(
                "a `bumpmap` is supported as a shape's BSDF or inside a `twosided` that is, \
                 not inside {}",
                node.describe()
            )));
        }
    }
    Ok(())
}

/// Mitsuba's reflective BSDFs are black from behind (only `twosided` makes them reflect
/// on both sides); ours reflect on both sides, so they are wrapped.
fn one_sided(material: Material) -> Material {
    match material {
        Material::Diffuse(_) | Material::Conductor(_) | Material::RoughConductor(_) => {
            Material::OneSided(OneSided {
                inner: Arc::new(material),
            })
        }
        m => m,
    }
}

/// A `<transform>`: its steps, each applied after (left-multiplied onto) the previous.
fn transform(node: &Node) -> Result<Transform> {
    node.check_all_used()?;
    let mut t = Transform::IDENTITY;
    for step in &node.children {
        let xyz = |default: f32| -> Result<Vec3> {
            Ok(Vec3::new(
                step.float_or("x", default)?,
                step.float_or("y", default)?,
                step.float_or("z", default)?,
            ))
        };
        let s = match step.tag.as_str() {
            "translate" => Transform::translate(match step.vec3("value")? {
                Some(v) => v,
                None => xyz(0.0)?,
            }),
            "scale" => {
                let v = match step.vec3("value")? {
                    Some(v) => v,
                    None => xyz(1.0)?,
                };
                Transform::scale(v).ok_or_else(|| step.error("scale by zero"))?
            }
            "rotate" => {
                let axis = match step.vec3("axis")? {
                    Some(a) => a,
                    None => xyz(0.0)?,
                };
                let angle = step
                    .float("angle")?
                    .ok_or_else(|| step.error("<rotate> needs an `angle`"))?;
                Transform::rotate(axis, angle).ok_or_else(|| step.error("<rotate> axis is zero"))?
            }
            "matrix" => {
                let v = step
                    .floats("value")?
                    .ok_or_else(|| step.error("<matrix> needs a `value`"))?;
                let arr: [f32; 16] = match v.len() {
                    16 => v.as_slice().try_into().expect("16"),
                    9 => [
                        v[0], v[1], v[2], 0.0, v[3], v[4], v[5], 0.0, v[6], v[7], v[8], 0.0, 0.0,
                        0.0, 0.0, 1.0,
                    ],
                    n => return Err(step.error(format!("<matrix> needs 16 or 9 numbers, got {n}"))),
                };
                Transform::from_row_major(&arr).ok_or_else(|| step.error("<matrix> is singular"))?
            }
            "lookat" => {
                let origin = step
                    .vec3("origin")?
                    .ok_or_else(|| step.error("<lookat> needs an `origin`"))?;
                let target = step
                    .vec3("target")?
                    .ok_or_else(|| step.error("<lookat> needs a `target`"))?;
                let up = step.vec3("up")?.unwrap_or(Vec3::Y);
                // Mitsuba's look-at matrix is the same as ours (x = up × dir).
                Transform::look_at(origin, target, up)
                    .ok_or_else(|| step.error("<lookat> is degenerate"))?
            }
            other => {
                return Err(step.error(format!(
                    "unsupported transform step <{other}>; supported: translate, rotate, \
                     scale, matrix, lookat"
                )))
            }
        };
        step.check_all_used()?;
        t = t.then(&s);
    }
    Ok(t)
}

/// Mitsuba's cylinder (`p0`, `p1`, `radius`) as a placement of our unit cylinder (radius
/// 1, z from 0 to 1).
fn cylinder_placement(node: &Node) -> Result<Transform> {
    let p0 = node.vec3("p0")?.unwrap_or(Vec3::ZERO);
    let p1 = node.vec3("p1")?.unwrap_or(Vec3::Z);
    let r = node.float_or("radius", 1.0)?;
    let d = p1 - p0;
    let len = d.length();
    if len == 0.0 || r <= 0.0 {
        return Err(node.error("cylinder needs p0 != p1 and radius > 0"));
    }
    let frame = crate::math::Frame::from_normal(d / len);
    let m = glam::Mat4::from_cols(
        frame.s.extend(0.0),
        frame.t.extend(0.0),
        frame.n.extend(0.0),
        p0.extend(1.0),
    );
    let place = Transform::from_matrix(m).ok_or_else(|| node.error("degenerate cylinder frame"))?;
    let scale = Transform::scale(Vec3::new(r, r, len)).expect("non-zero");
    Ok(scale.then(&place))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraSample;

    fn load(xml: &str, defines: &[(&str, &str)]) -> Result<LoadedScene> {
        let options = LoadOptions {
            defines: defines
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
            ..Default::default()
        };
        crate::io::load_scene_str(xml, Path::new("m.xml"), &options)
    }

    /// `mesh_attribute` reads the vertex colours (times `scale`); other attributes, and
    /// a missing name, are errors naming the line.
    #[test]
    fn mesh_attribute_textures() {
        let with = |texture: &str| {
            scene_with(&format!(
                r#"<shape type="rectangle"><bsdf type="diffuse">
                {texture}</bsdf></shape>"#
            ))
        };
        let loaded = load(
            &with(
                r#"<texture type="mesh_attribute" name="reflectance"><string name="name" value="vertex_color"/><float name="scale" value="0.5"/></texture>"#,
            ),
            &[],
        )
        .unwrap();
        let Material::Diffuse(d) = inner(loaded.scene.instances[0].material.as_deref().unwrap())
        else {
            panic!("not diffuse")
        };
        let at = crate::texture::TexCoord::new(Vec2::ZERO, Vec3::new(0.2, 0.4, 0.8));
        assert_eq!(d.albedo.eval(at), Vec3::new(0.1, 0.2, 0.4));
        // As a float parameter: the luminance of the scaled colour.
        let one = grey_texture(&d.albedo).eval(at);
        let l = crate::light::luminance(Vec3::new(0.1, 0.2, 0.4));
        assert!((one - Vec3::splat(l)).abs().max_element() < 1e-7, "{one}");
        for (texture, needle) in [
            (
                r#"<texture type="mesh_attribute" name="reflectance"><string name="name" value="vertex_weight"/></texture>"#,
                "only `vertex_color` and `face_color`",
            ),
            (
                r#"<texture type="mesh_attribute" name="reflectance"/>"#,
                "needs a `name`",
            ),
        ] {
            let e = load(&with(texture), &[]).unwrap_err().to_string();
            assert!(
                e.contains(needle) && e.contains("m.xml:8"),
                "{texture}: {e}"
            );
        }
    }

    /// The BSDF inside Mitsuba's one-sidedness.
    fn inner(m: &Material) -> &Material {
        match m {
            Material::OneSided(o) => &o.inner,
            m => m,
        }
    }

    /// `principled` is Mitsuba's Disney BSDF with every parameter in its field, `specular`
    /// converted to an index, Mitsuba's nudges for a transmissive index of 1 or
    /// specular 0, and its mistakes refused with the line named.
    #[test]
    fn principled_reads_every_parameter() {
        let bsdf = |body: &str| {
            let xml = format!(
                r#"<scene version="3.0.0">
                <shape type="sphere">
                <bsdf type="principled">{body}</bsdf>
                </shape><sensor type="perspective"/></scene>"#
            );
            load(&xml, &[]).map(|l| l.scene.instances[0].material.clone().unwrap())
        };
        let m = bsdf(
            r#"<rgb name="base_color" value="0.1,0.2,0.3"/><float name="roughness" value="0.11"/>
            <float name="anisotropic" value="0.12"/><float name="metallic" value="0.13"/>
            <float name="spec_trans" value="0.14"/><float name="spec_tint" value="0.15"/>
            <float name="sheen" value="0.16"/><float name="sheen_tint" value="0.17"/>
            <float name="flatness" value="0.18"/><float name="clearcoat" value="0.19"/>
            <float name="clearcoat_gloss" value="0.2"/><float name="eta" value="1.33"/>
            <float name="main_specular_sampling_rate" value="0.5"/>
            <float name="clearcoat_sampling_rate" value="0.25"/>
            <float name="diffuse_reflectance_sampling_rate" value="2"/>"#,
        )
        .unwrap();
        let Material::DisneyPrincipled(p) = &*m else {
            panic!("{m:?}")
        };
        let at = |t: &Arc<Texture>| t.eval(Vec2::ZERO);
        assert_eq!(at(&p.base_color), Vec3::new(0.1, 0.2, 0.3));
        let scalars = [
            &p.roughness,
            &p.anisotropic,
            &p.metallic,
            &p.spec_trans,
            &p.spec_tint,
            &p.sheen,
            &p.sheen_tint,
            &p.flatness,
            &p.clearcoat,
        ];
        for (k, t) in scalars.into_iter().enumerate() {
            assert!(
                (at(t).x - (0.11 + 0.01 * k as f32)).abs() < 1e-6,
                "parameter {k}"
            );
        }
        assert!((at(&p.clearcoat_gloss).x - 0.2).abs() < 1e-6);
        assert_eq!(p.eta, 1.33);
        let rates = (
            p.specular_sampling_rate,
            p.clearcoat_sampling_rate,
            p.diffuse_sampling_rate,
        );
        assert_eq!(rates, (0.5, 0.25, 2.0));

        let eta = |body: &str| match &*bsdf(body).unwrap() {
            Material::DisneyPrincipled(p) => p.eta,
            m => panic!("{m:?}"),
        };
        // specular 0.5 (the default): η = 2/(1 − √0.04) − 1 = 1.5.
        assert!((eta("") - 1.5).abs() < 1e-6);
        assert!((eta(r#"<float name="specular" value="0.5"/>"#) - 1.5).abs() < 1e-6);
        assert_eq!(eta(r#"<float name="specular" value="0"/>"#), 1.0);
        let nudged =
            eta(r#"<float name="specular" value="0"/><float name="spec_trans" value="1"/>"#);
        assert_eq!(nudged, DisneyPrincipled::eta_from_specular(1e-3));
        assert!(nudged > 1.0);
        let glass = r#"<float name="eta" value="1"/><float name="spec_trans" value="0.5"/>"#;
        assert_eq!(eta(glass), 1.001);

        for (body, needle) in [
            (
                r#"<float name="eta" value="1.5"/><float name="specular" value="0.5"/>"#,
                "not both",
            ),
            (r#"<float name="specular" value="1.5"/>"#, "not in [0, 1]"),
            (r#"<float name="eta" value="-1"/>"#, "must be positive"),
            (
                r#"<float name="clearcoat_sampling_rate" value="-1"/>"#,
                "must be at least 0",
            ),
            (r#"<float name="shininess" value="1"/>"#, "shininess"),
        ] {
            let e = bsdf(body).unwrap_err().to_string();
            assert!(e.contains(needle) && e.contains("m.xml:3"), "{body}: {e}");
        }

        // `principledthin`: its own parameters, `eta` a texture (default 1.5).
        let xml = r#"<scene version="3.0.0"><shape type="rectangle">
            <bsdf type="principledthin"><rgb name="base_color" value="0.1,0.2,0.3"/>
            <float name="roughness" value="0.11"/><float name="anisotropic" value="0.12"/>
            <float name="spec_trans" value="0.13"/><float name="spec_tint" value="0.14"/>
            <float name="sheen" value="0.15"/><float name="sheen_tint" value="0.16"/>
            <float name="flatness" value="0.17"/><float name="diff_trans" value="0.18"/>
            <float name="eta" value="0.19"/>
            <float name="specular_reflectance_sampling_rate" value="2"/>
            <float name="specular_transmittance_sampling_rate" value="3"/>
            <float name="diffuse_reflectance_sampling_rate" value="4"/>
            <float name="diffuse_transmittance_sampling_rate" value="5"/>
            </bsdf></shape><sensor type="perspective"/></scene>"#;
        let m = load(xml, &[]).unwrap().scene.instances[0]
            .material
            .clone()
            .unwrap();
        let Material::DisneyThin(t) = &*m else {
            panic!("{m:?}")
        };
        assert_eq!(at(&t.base_color), Vec3::new(0.1, 0.2, 0.3));
        let scalars = [
            &t.roughness,
            &t.anisotropic,
            &t.spec_trans,
            &t.spec_tint,
            &t.sheen,
            &t.sheen_tint,
            &t.flatness,
            &t.diff_trans,
            &t.eta,
        ];
        for (k, p) in scalars.into_iter().enumerate() {
            assert!(
                (at(p).x - (0.11 + 0.01 * k as f32)).abs() < 1e-6,
                "thin parameter {k}"
            );
        }
        let rates = [
            t.specular_reflectance_sampling_rate,
            t.specular_transmittance_sampling_rate,
            t.diffuse_reflectance_sampling_rate,
            t.diffuse_transmittance_sampling_rate,
        ];
        assert_eq!(rates, [2.0, 3.0, 4.0, 5.0]);
        let bad = xml.replace(r#"name="eta" value="0.19""#, r#"name="eta" value="0""#);
        let e = load(&bad, &[]).unwrap_err().to_string();
        assert!(
            e.contains("`eta` 0 must be positive") && e.contains("m.xml:2"),
            "{e}"
        );
    }

    /// Camera rays start at `near_clip` and end at `far_clip`: a sphere nearer than the
    /// near plane is not seen, the wall behind it is; a far plane before the wall hides it.
    #[test]
    fn near_and_far_clip_cut_camera_rays() {
        let centre_depth = |clip: &str| {
            let xml = format!(
                r#"<scene version="3.0.0">
                <integrator type="aov"><string name="aovs" value="dd:depth"/></integrator>
                <sensor type="perspective"><float name="fov" value="30"/>{clip}
                    <transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
                    <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
                    <film type="hdrfilm"><integer name="width" value="9"/><integer name="height" value="9"/>
                        <rfilter type="box"/></film>
                </sensor>
                <shape type="sphere"><float name="radius" value="0.5"/><point name="center" x="0" y="0" z="2"/></shape>
                <shape type="rectangle"><transform name="to_world"><scale value="10"/><translate z="5"/></transform></shape>
                </scene>"#
            );
            let loaded = load(&xml, &[]).unwrap();
            let image = loaded.renderer().unwrap().render(&|_| {}).unwrap().0;
            image.get(4, 4).x
        };
        let plain = centre_depth("");
        assert!((plain - 1.5).abs() < 0.05, "{plain}");
        let near = centre_depth(r#"<float name="near_clip" value="3"/>"#);
        assert!((near - 5.0).abs() < 0.05, "{near}");
        let far = centre_depth(
            r#"<float name="far_clip" value="4"/><float name="near_clip" value="3"/>"#,
        );
        assert_eq!(far, 0.0);
        assert!(load(
            &scene_with("").replace(
                "<float name=\"fov\" value=\"60\"/>",
                "<float name=\"near_clip\" value=\"-1\"/>"
            ),
            &[]
        )
        .is_err());
    }

    /// Diffuse, conductor and rough conductor are black from behind, as in Mitsuba;
    /// inside `twosided` they reflect on both sides, and a `twosided` of two BSDFs puts
    /// the first in front and the second behind.
    #[test]
    fn reflective_bsdfs_are_one_sided() {
        let loaded = load(
            &scene_with(
                r#"<shape type="rectangle"><bsdf type="diffuse"/></shape>
                   <shape type="rectangle"><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>
                   <shape type="rectangle"><bsdf type="roughconductor"/></shape>
                   <shape type="rectangle"><bsdf type="twosided">
                       <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
                       <bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.1, 0.8"/></bsdf>
                   </bsdf></shape>"#,
            ),
            &[],
        )
        .unwrap();
        let up = Vec3::new(0.3, 0.0, 1.0).normalize();
        let down = Vec3::new(-0.3, 0.0, -1.0).normalize();
        let si = crate::geometry::SurfaceInteraction {
            p: Vec3::ZERO,
            p_error: Vec3::ZERO,
            t: 1.0,
            n: Vec3::Z,
            shading_n: Vec3::Z,
            dpdu: Vec3::X,
            dpdv: Vec3::Y,
            uv: Vec2::splat(0.5),
            color: Vec3::ONE,
            wo: up,
            instance: 0,
            prim: 0,
        };
        let f = |i: usize, wo: Vec3, wi: Vec3| {
            let inst = &loaded.scene.instances[i];
            inst.material.as_ref().unwrap().eval(&si, wo, wi)
        };
        let wi_up = Vec3::new(-0.2, 0.1, 1.0).normalize();
        for i in [0, 2] {
            assert!(
                f(i, up, wi_up).max_element() > 0.0,
                "instance {i} from the front"
            );
            assert_eq!(f(i, down, -wi_up), Vec3::ZERO, "instance {i} from behind");
        }
        assert!(
            f(1, down, -wi_up).max_element() > 0.0,
            "twosided from behind"
        );
        // Lambertian: reflectance · cos θ / π on the side the BSDF serves.
        let front = f(3, up, wi_up) * std::f32::consts::PI / wi_up.z;
        let back = f(3, down, -wi_up) * std::f32::consts::PI / wi_up.z;
        assert!(
            (front - Vec3::new(0.8, 0.1, 0.1)).length() < 1e-5,
            "{front}"
        );
        assert!((back - Vec3::new(0.1, 0.1, 0.8)).length() < 1e-5, "{back}");
        let three = r#"<shape type="rectangle"><bsdf type="twosided">
            <bsdf type="diffuse"/><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf></shape>"#;
        let e = load(&scene_with(three), &[]).unwrap_err().to_string();
        assert!(
            e.contains("twosided needs one or two <bsdf>s, found 3"),
            "{e}"
        );
    }

    fn scene_with(body: &str) -> String {
        format!(
            r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="60"/>
        <transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
        <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
    </sensor>
{body}
</scene>"#
        )
    }

    /// A shape group placed twice: each instance composes the group shape's own
    /// `to_world` with the instance's, and both share the group's shapes.
    #[test]
    fn shapegroup_instances_compose_transforms() {
        let loaded = load(
            &scene_with(
                r#"<shape type="shapegroup" id="pair">
                    <shape type="sphere"><float name="radius" value="0.5"/>
                        <point name="center" x="1" y="0" z="0"/></shape>
                    <shape type="rectangle"><transform name="to_world"><scale value="0.25"/></transform>
                        <bsdf type="diffuse"><rgb name="reflectance" value="1,0,0"/></bsdf></shape>
                </shape>
                <shape type="instance"><ref id="pair"/>
                    <transform name="to_world"><translate z="5"/></transform></shape>
                <shape type="instance"><ref id="pair"/>
                    <transform name="to_world"><rotate y="1" angle="90"/><translate z="10"/></transform></shape>"#,
            ),
            &[],
        )
        .unwrap();
        let inst = &loaded.scene.instances;
        assert_eq!(inst.len(), 4);
        assert!(Arc::ptr_eq(
            &inst[1].material.clone().unwrap(),
            &inst[3].material.clone().unwrap()
        ));
        // First instance: the rectangle at z = 5 facing the camera; the sphere at x = 1.
        let hit = loaded
            .scene
            .intersect(&crate::math::Ray::new(Vec3::ZERO, Vec3::Z))
            .unwrap();
        assert!((hit.t - 5.0).abs() < 1e-4, "{}", hit.t);
        let b = inst[0].bounds;
        assert!(
            (b.min - Vec3::new(0.5, -0.5, 4.5)).abs().max_element() < 1e-4,
            "{b:?}"
        );
        // Second: rotated 90° about y, the sphere's centre (1, 0, 0) goes to (0, 0, -1),
        // then up by 10: (0, 0, 9).
        let b = inst[2].bounds;
        assert!(
            (b.min - Vec3::new(-0.5, -0.5, 8.5)).abs().max_element() < 1e-4,
            "{b:?}"
        );
        let err = load(
            &scene_with(
                r#"<shape type="sphere" id="s"/><shape type="instance"><ref id="s"/></shape>"#,
            ),
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("must refer to a shapegroup"), "{err}");
    }

    /// A `mask` cuts a rectangle's surface (a mesh with the rectangle's parameterisation
    /// then): an opacity of 0 lets every ray through, 1 none; on a shape it cannot cut,
    /// without a nested BSDF, or nested in another mask, it is an error naming the line.
    #[test]
    fn mask_cuts_rectangles_and_meshes_only() {
        let quad = |opacity: &str| {
            scene_with(&format!(
                r#"<shape type="rectangle"><bsdf type="mask"><float name="opacity" value="{opacity}"/>
                   <bsdf type="diffuse"/></bsdf></shape>"#
            ))
        };
        let ray = crate::math::Ray::new(Vec3::new(0.2, 0.3, 1.0), -Vec3::Z);
        let clear = load(&quad("0"), &[]).unwrap();
        assert!(clear.scene.intersect(&ray).is_none());
        let opaque = load(&quad("1"), &[]).unwrap();
        let si = opaque.scene.intersect(&ray).unwrap();
        assert!(
            (si.uv - Vec2::new(0.6, 0.65)).length() < 1e-5,
            "{:?}",
            si.uv
        );
        assert!(matches!(
            opaque.scene.material(&si),
            Some(Material::OneSided(_))
        ));
        for (body, message) in [
            (
                r#"<shape type="sphere"><bsdf type="mask"><bsdf type="diffuse"/></bsdf></shape>"#,
                "supported on meshes",
            ),
            (
                r#"<shape type="rectangle"><bsdf type="mask"><float name="opacity" value="0.5"/></bsdf></shape>"#,
                "exactly one nested",
            ),
            (
                r#"<shape type="rectangle"><bsdf type="mask"><bsdf type="mask"><bsdf type="diffuse"/></bsdf></bsdf></shape>"#,
                "cannot be nested",
            ),
        ] {
            let err = load(&scene_with(body), &[]).unwrap_err().to_string();
            assert!(err.contains("m.xml:") && err.contains(message), "{err}");
        }
    }

    /// A `bumpmap` becomes the shape's material, also inside a `twosided` (with Mitsuba's
    /// flip and shadowing on unless turned off); nested deeper, or without its one
    /// texture and one BSDF, it is an error naming the line.
    #[test]
    fn bumpmap_nests_where_the_frame_is_built() {
        let bump = |extra: &str| {
            format!(
                r#"<bsdf type="bumpmap"><texture type="checkerboard" name="h"/>{extra}
                   <bsdf type="diffuse"/></bsdf>"#
            )
        };
        let ray = crate::math::Ray::new(Vec3::new(0.2, 0.3, 1.0), -Vec3::Z);
        for (bsdf, flip_invalid, shadowing) in [
            (bump(""), true, true),
            (
                bump(r#"<boolean name="use_shadowing_function" value="false"/>"#),
                true,
                false,
            ),
            (
                format!(
                    r#"<bsdf type="twosided">{}</bsdf>"#,
                    bump(r#"<boolean name="flip_invalid_normals" value="false"/>"#)
                ),
                false,
                true,
            ),
        ] {
            let scene = load(
                &scene_with(&format!(r#"<shape type="rectangle">{bsdf}</shape>"#)),
                &[],
            )
            .unwrap();
            let si = scene.scene.intersect(&ray).unwrap();
            let b = match scene.scene.material(&si) {
                Some(Material::BumpMap(b)) => b,
                Some(Material::TwoSided(t)) => match &*t.inner {
                    Material::BumpMap(b) => b,
                    m => panic!("{m:?}"),
                },
                m => panic!("{m:?}"),
            };
            assert_eq!((b.flip_invalid, b.shadowing), (flip_invalid, shadowing));
        }
        for (body, message) in [
            (
                format!(
                    r#"<bsdf type="blendbsdf">{}<bsdf type="diffuse"/></bsdf>"#,
                    bump("")
                ),
                "not inside <bsdf type=\"blendbsdf\">",
            ),
            (
                format!(
                    r#"<bsdf type="normalmap"><rgb name="normalmap" value="0.5, 0.5, 1"/>{}</bsdf>"#,
                    bump("")
                ),
                "not inside",
            ),
            (
                format!(
                    r#"<bsdf type="blendbsdf"><bsdf type="twosided">{}</bsdf><bsdf type="diffuse"/></bsdf>"#,
                    bump("")
                ),
                "not inside",
            ),
            (
                r#"<bsdf type="bumpmap"><bsdf type="diffuse"/></bsdf>"#.to_string(),
                "needs one <texture>",
            ),
            (
                r#"<bsdf type="bumpmap"><texture type="checkerboard" name="h"/></bsdf>"#
                    .to_string(),
                "needs one <bsdf>",
            ),
        ] {
            let xml = scene_with(&format!(r#"<shape type="rectangle">{body}</shape>"#));
            let err = load(&xml, &[]).unwrap_err().to_string();
            assert!(err.contains("m.xml:") && err.contains(message), "{err}");
        }
    }

    /// Unsupported plugins and parameters are errors naming the plugin and line; with
    /// `lenient` they are left out or replaced by the documented fallbacks.
    #[test]
    fn lenient_turns_unsupported_plugins_into_fallbacks() {
        let xml = scene_with(
            r#"<bsdf type="hapke" id="h"><float name="w" value="0.5"/></bsdf>
               <shape type="sphere"><ref id="h"/><transform name="to_world"><translate z="4"/></transform></shape>
               <shape type="bezier"/>
               <emitter type="projector"/>
               <emitter type="constant"><rgb name="radiance" value="1"/><float name="glow" value="2"/></emitter>
               <shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" type="noise"/></bsdf>
                   <transform name="to_world"><translate z="9"/></transform></shape>"#,
        );
        let err = load(&xml, &[]).unwrap_err().to_string();
        assert!(err.contains("m.xml:") && err.contains("`hapke`"), "{err}");
        let options = LoadOptions {
            lenient: true,
            ..Default::default()
        };
        let loaded = crate::io::load_scene_str(&xml, Path::new("m.xml"), &options).unwrap();
        // The bezier curve and the projector are left out.
        assert_eq!(loaded.scene.instances.len(), 2);
        assert_eq!(loaded.scene.lights.len(), 1);
        // The Hapke BSDF is a diffuse 0.5, the noise texture a constant 0.5.
        for i in &loaded.scene.instances {
            match i.material.as_deref().map(inner) {
                Some(Material::Diffuse(d)) => {
                    assert_eq!(d.albedo.eval(glam::Vec2::ZERO), Vec3::splat(0.5))
                }
                m => panic!("{m:?}"),
            }
        }
    }

    /// `<shape type="csg">` (our extension): a sphere minus a cube, the cube in its own
    /// material. A ray along +z enters at the cube's cut face (z = -0.5), whose normal
    /// points into the hole (towards the ray), and the hit takes the cube's material.
    #[test]
    fn csg_difference_in_the_mitsuba_dialect() {
        let loaded = load(
            &scene_with(
                r#"<shape type="csg">
                    <string name="op" value="difference"/>
                    <bsdf type="diffuse"><rgb name="reflectance" value="0.8"/></bsdf>
                    <shape type="sphere"><float name="radius" value="1"/></shape>
                    <shape type="cube">
                        <bsdf type="diffuse"><rgb name="reflectance" value="1,0,0"/></bsdf>
                        <transform name="to_world"><scale value="0.5"/><translate z="-1"/></transform>
                    </shape>
                    <transform name="to_world"><translate z="5"/></transform>
                </shape>"#,
            ),
            &[],
        )
        .unwrap();
        let scene = &loaded.scene;
        let si = scene
            .intersect(&crate::math::Ray::new(Vec3::new(0.0, 0.0, 0.0), Vec3::Z))
            .unwrap();
        assert!((si.t - 4.5).abs() < 1e-4, "t = {}", si.t);
        assert!(
            (si.n - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-4,
            "n = {:?}",
            si.n
        );
        let Some(Material::Diffuse(d)) = scene.material(&si).map(inner) else {
            panic!("no diffuse material")
        };
        assert_eq!(d.albedo.eval(Vec2::ZERO), Vec3::new(1.0, 0.0, 0.0));
        // Off the cube, the sphere's own surface and the tree's material.
        let si = scene
            .intersect(&crate::math::Ray::new(Vec3::new(0.8, 0.0, 0.0), Vec3::Z))
            .unwrap();
        assert!(
            (si.t - (5.0 - (1.0f32 - 0.64).sqrt())).abs() < 1e-4,
            "t = {}",
            si.t
        );
        let Some(Material::Diffuse(d)) = scene.material(&si).map(inner) else {
            panic!("no diffuse material")
        };
        assert_eq!(d.albedo.eval(Vec2::ZERO), Vec3::splat(0.8));
        let bad = load(
            &scene_with(
                r#"<shape type="csg"><string name="op" value="xor"/><shape type="sphere"/><shape type="cube"/></shape>"#,
            ),
            &[],
        );
        assert!(bad
            .unwrap_err()
            .to_string()
            .contains("unknown csg op `xor`"));
    }

    #[test]
    fn defaults_substitution_and_overrides() {
        let xml = r#"<scene version="3.0.0">
            <default name="spp" value="7"/>
            <default name="res" value="16"/>
            <integrator type="path"><integer name="max_depth" value="$spp"/></integrator>
            <sensor type="perspective">
                <sampler type="ldsampler"><integer name="sample_count" value="$spp"/></sampler>
                <film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="$res"/>
                    <rfilter type="gaussian"/></film>
            </sensor></scene>"#;
        let a = load(xml, &[]).unwrap();
        assert_eq!(a.sampler.samples_per_pixel(), 7);
        assert!(matches!(a.sampler, Sampler::Sobol(_)));
        assert_eq!(
            a.scene.camera.as_ref().unwrap().resolution(),
            UVec2::new(16, 16)
        );
        match &a.integrator {
            Integrator::PathTracer(p) => assert_eq!(p.max_depth, 7),
            i => panic!("{i:?}"),
        }
        // -D wins over <default>.
        let b = load(xml, &[("res", "8"), ("spp", "3")]).unwrap();
        assert_eq!(b.sampler.samples_per_pixel(), 3);
        assert_eq!(
            b.scene.camera.as_ref().unwrap().resolution(),
            UVec2::new(8, 8)
        );
    }

    /// The filters are read with Mitsuba's parameters and in its steps (the box needs
    /// none); a bad `lobes` count is an error naming its line.
    #[test]
    fn filters_are_read_in_mitsubas_steps() {
        let scene = |rfilter: &str| {
            format!(
                r#"<scene version="3.0.0"><sensor type="perspective">
                <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
                {rfilter}</film></sensor></scene>"#
            )
        };
        let filter = |rfilter: &str| load(&scene(rfilter), &[]).unwrap().scene.filter;
        let stepped = |f: Filter| f.with_steps(MITSUBA_FILTER_STEPS);
        assert_eq!(filter(r#"<rfilter type="box"/>"#), Filter::Box);
        assert_eq!(filter(""), stepped(Filter::gaussian(0.5)));
        assert_eq!(
            filter(r#"<rfilter type="tent"><float name="radius" value="1.5"/></rfilter>"#),
            stepped(Filter::Tent { radius: 1.5 })
        );
        assert_eq!(
            filter(r#"<rfilter type="mitchell"/>"#),
            stepped(Filter::mitchell(1.0 / 3.0, 1.0 / 3.0))
        );
        assert_eq!(
            filter(
                r#"<rfilter type="mitchell"><float name="B" value="0.2"/><float name="C" value="0.4"/></rfilter>"#
            ),
            stepped(Filter::mitchell(0.2, 0.4))
        );
        assert_eq!(
            filter(r#"<rfilter type="catmullrom"/>"#),
            stepped(Filter::catmull_rom())
        );
        assert_eq!(
            filter(r#"<rfilter type="lanczos"/>"#),
            stepped(Filter::lanczos(3))
        );
        assert_eq!(
            filter(r#"<rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>"#),
            stepped(Filter::lanczos(2))
        );
        let err = load(
            &scene(r#"<rfilter type="lanczos"><integer name="lobes" value="0"/></rfilter>"#),
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("lobes must be 1 to 16, not 0") && err.contains(":3"),
            "{err}"
        );
    }

    fn parse_transform(xml: &str) -> Transform {
        let mut reader = Reader {
            ids: HashMap::new(),
            aliases: Vec::new(),
            stack: Vec::new(),
            defines: Vec::new(),
            fixed: Vec::new(),
        };
        let root = reader.parse(xml, Path::new("t.xml")).unwrap();
        transform(&root).unwrap()
    }

    #[test]
    fn transform_steps_compose_in_document_order() {
        // translate, then scale by 2, then rotate 90° about y: M = R · S · T.
        let t = parse_transform(
            r#"<transform name="to_world"><translate x="1"/><scale value="2"/><rotate y="1" angle="90"/></transform>"#,
        );
        let cases = [
            (Vec3::ZERO, Vec3::new(0.0, 0.0, -2.0)),
            (Vec3::Y, Vec3::new(0.0, 2.0, -2.0)),
            (Vec3::Z, Vec3::new(2.0, 0.0, -2.0)),
        ];
        for (p, e) in cases {
            assert!(
                (t.point(p) - e).length() < 1e-5,
                "{p} -> {} vs {e}",
                t.point(p)
            );
        }
        // A row-major matrix (translation in the last column), then a translation.
        let m = parse_transform(
            r#"<transform><matrix value="0 -1 0 5  1 0 0 6  0 0 1 7  0 0 0 1"/><translate value="1 0 0"/></transform>"#,
        );
        assert!((m.point(Vec3::X) - Vec3::new(6.0, 7.0, 7.0)).length() < 1e-5);
    }

    /// The pixel column at which the camera sees instance 0 (mean over hits), or None.
    fn hit_centre(loaded: &LoadedScene) -> Option<Vec2> {
        let cam = loaded.scene.camera.as_ref().unwrap();
        let res = cam.resolution();
        let (mut sum, mut n) = (Vec2::ZERO, 0.0);
        for y in 0..res.y {
            for x in 0..res.x {
                let film = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let ray = cam
                    .generate_ray(&CameraSample {
                        film,
                        lens: Vec2::splat(0.5),
                    })
                    .unwrap();
                if loaded.scene.intersect(&ray).is_some() {
                    sum += film;
                    n += 1.0;
                }
            }
        }
        (n > 0.0).then(|| sum / n)
    }

    /// Mitsuba's camera: looking along +z with +y up, world +x is on the image's left
    /// and world +y at its top.
    #[test]
    fn camera_orientation_matches_mitsuba() {
        let left = load(
            &scene_with(r#"<shape type="sphere"><point name="center" x="1" y="0" z="4"/><float name="radius" value="0.5"/></shape>"#),
            &[],
        )
        .unwrap();
        let c = hit_centre(&left).unwrap();
        assert!(c.x < 12.0 && (c.y - 16.0).abs() < 1.0, "{c}");
        let top = load(
            &scene_with(r#"<shape type="sphere"><transform name="to_world"><scale value="0.5"/><translate y="1" z="4"/></transform></shape>"#),
            &[],
        )
        .unwrap();
        let c = hit_centre(&top).unwrap();
        assert!(c.y < 12.0 && (c.x - 16.0).abs() < 1.0, "{c}");
    }

    #[test]
    fn unsupported_plugins_name_file_and_line() {
        let e = load(&scene_with("<shape type=\"teapot\"/>"), &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.xml:7:1") && e.contains("shape plugin `teapot`"),
            "{e}"
        );
        let e = load(&scene_with("<emitter type=\"sky\"/>"), &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.xml:7:1") && e.contains("emitter plugin `sky`"),
            "{e}"
        );
        let e = load(
            &scene_with(r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:0.1, 700:0.9"/></bsdf></shape>"#),
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("m.xml:7:") && e.contains("reflectance") && e.contains("wavelength"),
            "{e}"
        );
    }

    #[test]
    fn forward_refs_aliases_and_area_emitters() {
        let loaded = load(
            &scene_with(
                r#"<shape type="rectangle"><ref id="m"/><ref id="glow"/></shape>
                <alias id="white" as="m"/>
                <bsdf type="twosided" id="white"><bsdf type="diffuse"><spectrum name="reflectance" value="400:0.5, 700:0.5"/></bsdf></bsdf>
                <emitter type="area" id="glow"><rgb name="radiance" value="1, 2, 3"/></emitter>
                <emitter type="directional"><vector name="direction" x="0" y="-1" z="0"/></emitter>"#,
            ),
            &[],
        )
        .unwrap();
        let inst = &loaded.scene.instances[0];
        assert!(matches!(
            inst.material.as_deref(),
            Some(Material::TwoSided(_))
        ));
        let e = inst.emission.as_ref().unwrap();
        assert_eq!(e.radiance.eval(Vec2::ZERO), Vec3::new(1.0, 2.0, 3.0));
        let dir = loaded.scene.lights.iter().find_map(|l| match l {
            Light::Directional(d) => Some(d.direction),
            _ => None,
        });
        assert_eq!(dir, Some(Vec3::Y), "towards the light");
    }

    /// A sample of each supported plugin loads, with Mitsuba's parameters converted.
    #[test]
    fn plugins_convert_their_parameters() {
        let loaded = load(
            &scene_with(
                r#"<integrator type="aov"><string name="aovs" value="nn:sh_normal"/></integrator>
                <shape type="cylinder"><point name="p0" value="0,0,5"/><point name="p1" value="0,2,5"/>
                    <float name="radius" value="0.5"/>
                    <bsdf type="roughconductor"><float name="alpha" value="0.25"/><string name="material" value="Au"/></bsdf></shape>
                <shape type="disk"><bsdf type="dielectric"><string name="int_ior" value="bk7"/><string name="ext_ior" value="air"/></bsdf></shape>
                <shape type="cube"><bsdf type="roughplastic"><rgb name="diffuse_reflectance" value="0.2"/>
                    <float name="alpha" value="0.3"/></bsdf></shape>
                <shape type="rectangle"><bsdf type="blendbsdf"><float name="weight" value="0.3"/>
                    <bsdf type="diffuse"><texture name="reflectance" type="checkerboard"><rgb name="color0" value="1"/>
                        <transform name="to_uv"><scale x="4" y="4"/></transform></texture></bsdf>
                    <bsdf type="conductor"/></bsdf></shape>
                <emitter type="point"><transform name="to_world"><translate value="1,2,3"/></transform>
                    <rgb name="intensity" value="5"/></emitter>
                <emitter type="spot"><transform name="to_world"><lookat origin="0,1,0" target="0,0,0" up="0,0,1"/></transform></emitter>
                <emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>"#,
            ),
            &[],
        )
        .unwrap();
        assert!(matches!(
            loaded.integrator,
            Integrator::Aov(Aov {
                variable: AovVariable::Normals,
                ..
            })
        ));
        let inst = &loaded.scene.instances;
        // The cylinder from p0 to p1 with radius 0.5.
        let b = inst[0].bounds;
        assert!((b.min - Vec3::new(-0.5, 0.0, 4.5)).length() < 1e-4, "{b:?}");
        assert!((b.max - Vec3::new(0.5, 2.0, 5.5)).length() < 1e-4, "{b:?}");
        match inst[0].material.as_deref().map(inner) {
            Some(Material::RoughConductor(r)) => {
                assert!((r.roughness_u.eval(Vec2::ZERO).x - 0.5).abs() < 1e-6);
                assert!(r.ior.is_some());
            }
            m => panic!("{m:?}"),
        }
        match inst[1].material.as_deref() {
            Some(Material::Dielectric(d)) => assert!((d.ior - 1.5046 / 1.000277).abs() < 1e-6),
            m => panic!("{m:?}"),
        }
        match inst[2].material.as_deref() {
            Some(Material::RoughPlastic(p)) => {
                assert!((p.alpha - 0.3).abs() < 1e-6, "{}", p.alpha);
                assert_eq!(p.distribution, Distribution::Beckmann);
                assert!((p.eta - 1.49 / 1.000277).abs() < 1e-6);
            }
            m => panic!("{m:?}"),
        }
        match inst[3].material.as_deref() {
            Some(Material::Blend(b)) => match inner(&b.first) {
                Material::Diffuse(d) => match &*d.albedo {
                    Texture::Checkerboard(c) => assert_eq!(c.scale, Vec2::splat(8.0)),
                    t => panic!("{t:?}"),
                },
                m => panic!("{m:?}"),
            },
            m => panic!("{m:?}"),
        }
        let lights = &loaded.scene.lights;
        assert!(lights.iter().any(|l| matches!(l, Light::Point(p)
            if p.position == Vec3::new(1.0, 2.0, 3.0) && p.intensity == Vec3::splat(5.0))));
        assert!(lights.iter().any(|l| matches!(l, Light::Spot(s)
            if (s.direction + Vec3::Y).length() < 1e-6)));
        assert!(lights.iter().any(|l| matches!(l, Light::Environment(_))));
    }

    /// A fresh temporary folder holding `rgb.exr`, 2×2 pixels of (0.9, 0.2, 0.1).
    fn dir_with_rgb_bitmap(tag: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("lightpath-mts-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = crate::film::Image::new(2, 2);
        img.pixels.fill(Vec3::new(0.9, 0.2, 0.1));
        crate::io::image::write_image(&dir.join("rgb.exr"), &img).unwrap();
        dir
    }

    /// Float parameters read colour textures as Mitsuba 3.9's `eval_1` does (values from
    /// Mitsuba on the same data): an RGB bitmap (0.9, 0.2, 0.1) gives its luminance
    /// 0.34165, an `rgb` constant the mean of its channels (0.4), a checkerboard each
    /// colour's value; colour parameters keep the colour.
    #[test]
    fn float_parameters_read_colour_textures_as_mitsuba_does() {
        let dir = dir_with_rgb_bitmap("grey");
        let xml = scene_with(
            r#"<shape type="sphere"><bsdf type="principled">
                <texture type="bitmap" name="roughness" id="t">
                    <string name="filename" value="rgb.exr"/></texture>
                <ref name="base_color" id="t"/>
                <rgb name="metallic" value="0.9, 0.2, 0.1"/>
                <texture type="checkerboard" name="sheen">
                    <rgb name="color0" value="0.9, 0.6, 0.3"/><float name="color1" value="0.3"/>
                </texture>
            </bsdf></shape>
            <shape type="sphere"><bsdf type="blendbsdf">
                <texture type="bitmap" name="weight"><string name="filename" value="rgb.exr"/></texture>
                <bsdf type="diffuse"/><bsdf type="conductor"/>
            </bsdf></shape>"#,
        );
        let loaded =
            crate::io::load_scene_str(&xml, &dir.join("m.xml"), &LoadOptions::default()).unwrap();
        let material = |i: usize| loaded.scene.instances[i].material.clone().unwrap();
        let m = material(0);
        let Material::DisneyPrincipled(p) = inner(&m) else {
            panic!("{m:?}")
        };
        let at = |t: &Arc<Texture>, u: f32, v: f32| t.eval(Vec2::new(u, v));
        let close = |a: Vec3, b: f32| (a - Vec3::splat(b)).abs().max_element() < 2e-4;
        assert!(
            close(at(&p.roughness, 0.3, 0.3), 0.34165),
            "{:?}",
            p.roughness
        );
        assert_eq!(at(&p.base_color, 0.3, 0.3), Vec3::new(0.9, 0.2, 0.1));
        assert!(close(at(&p.metallic, 0.3, 0.3), 0.4));
        // Mitsuba's `eval` gives colour0 at (0.1, 0.1) and colour1 at (0.6, 0.1).
        let cells = [at(&p.sheen, 0.1, 0.1), at(&p.sheen, 0.6, 0.1)];
        assert!(close(cells[0], 0.6) && close(cells[1], 0.3), "{cells:?}");
        let m = material(1);
        let Material::Blend(b) = inner(&m) else {
            panic!("{m:?}")
        };
        assert!(close(at(&b.weight, 0.7, 0.2), 0.34165));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// `roughconductor` and `roughdielectric` take `alpha` (and `alpha_u`/`alpha_v`) as a
    /// texture, as Mitsuba 3 does, read as one value (an RGB bitmap's luminance) and
    /// turned into our roughness √α; `roughplastic`, whose `alpha` Mitsuba reads as a
    /// number only, refuses one, naming the line.
    #[test]
    fn microfacet_alpha_may_be_a_texture() {
        let dir = dir_with_rgb_bitmap("alpha");
        let load = |bsdf: &str| {
            let xml = scene_with(&format!(r#"<shape type="sphere">{bsdf}</shape>"#));
            crate::io::load_scene_str(&xml, &dir.join("m.xml"), &LoadOptions::default())
                .map(|l| l.scene.instances[0].material.clone().unwrap())
        };
        let bitmap = |name: &str| {
            format!(
                r#"<texture type="bitmap" name="{name}"><string name="filename" value="rgb.exr"/></texture>"#
            )
        };
        // √(luminance 0.34165) and √0.04.
        let (textured, constant) = (0.34165f32.sqrt(), 0.2);
        let at = |t: &Arc<Texture>| t.eval(Vec2::new(0.3, 0.7));
        let near = |v: Vec3, x: f32| (v - Vec3::splat(x)).abs().max_element() < 2e-4;

        let conductor = |body: String| match inner(&load(&body).unwrap()) {
            Material::RoughConductor(c) => (
                at(&c.roughness_u),
                at(&c.roughness_v),
                Arc::ptr_eq(&c.roughness_u, &c.roughness_v),
            ),
            m => panic!("{m:?}"),
        };
        let dielectric = |body: String| match inner(&load(&body).unwrap()) {
            Material::RoughDielectric(d) => (
                at(&d.roughness),
                matches!(&*d.roughness, Texture::Constant(_)),
            ),
            m => panic!("{m:?}"),
        };
        let (u, v, isotropic) = conductor(format!(
            r#"<bsdf type="roughconductor">{}</bsdf>"#,
            bitmap("alpha")
        ));
        assert!(near(u, textured) && near(v, textured) && isotropic, "{u:?}");
        let (u, v, isotropic) = conductor(format!(
            r#"<bsdf type="roughconductor">{}<float name="alpha_v" value="0.04"/></bsdf>"#,
            bitmap("alpha_u")
        ));
        assert!(near(u, textured) && near(v, constant) && !isotropic);
        let (r, is_constant) = dielectric(format!(
            r#"<bsdf type="roughdielectric">{}</bsdf>"#,
            bitmap("alpha")
        ));
        assert!(near(r, textured) && !is_constant);
        let (r, is_constant) = dielectric(
            r#"<bsdf type="roughdielectric"><float name="alpha" value="0.04"/></bsdf>"#.into(),
        );
        assert!(near(r, constant) && is_constant);

        let e = load(&format!(
            r#"<bsdf type="roughplastic">{}</bsdf>"#,
            bitmap("alpha")
        ))
        .unwrap_err();
        assert!(
            e.to_string().contains("must be a number") && e.to_string().contains("m.xml:7:"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    /// `flip_normals` on an analytic shape turns the normals of its hits (the
    /// rectangle faces the camera at z = 5: its normal, -z, flipped to +z) and is kept by
    /// the instances of a shape group; `false` and its absence leave them.
    #[test]
    fn flip_normals_turns_analytic_shapes() {
        let rectangle = |flip: &str| {
            format!(
                r#"<shape type="rectangle">{flip}
                    <transform name="to_world"><rotate y="1" angle="180"/><translate z="5"/></transform></shape>"#
            )
        };
        let ray = crate::math::Ray::new(Vec3::ZERO, Vec3::Z);
        for (flip, sign) in [
            (r#"<boolean name="flip_normals" value="true"/>"#, 1.0),
            (r#"<boolean name="flip_normals" value="false"/>"#, -1.0),
            ("", -1.0),
        ] {
            let loaded = load(&scene_with(&rectangle(flip)), &[]).unwrap();
            let si = loaded.scene.intersect(&ray).unwrap();
            assert!((si.t - 5.0).abs() < 1e-4);
            for n in [si.n, si.shading_n] {
                assert!((n - Vec3::Z * sign).length() < 1e-5, "{flip:?}: {n:?}");
            }
        }
        let loaded = load(
            &scene_with(&format!(
                r#"<shape type="shapegroup" id="g">{}</shape>
                <shape type="instance"><ref id="g"/></shape>"#,
                rectangle(r#"<boolean name="flip_normals" value="true"/>"#)
            )),
            &[],
        )
        .unwrap();
        assert!(loaded.scene.instances.iter().all(|i| i.flip_normals));
        let si = loaded.scene.intersect(&ray).unwrap();
        assert!((si.n - Vec3::Z).length() < 1e-5, "{:?}", si.n);
    }

    /// The film's crop window: read into the scene (the size defaulting to the film's,
    /// as in Mitsuba), none when it is the whole film, and an error naming the line when
    /// it is empty or reaches outside the film.
    #[test]
    fn film_crop_windows() {
        let with_film = |extra: &str| {
            format!(
                r#"<scene version="3.0.0"><sensor type="perspective">
    <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="30"/>
        {extra}</film>
</sensor></scene>"#
            )
        };
        let crop = |extra: &str| load(&with_film(extra), &[]).map(|l| l.scene.crop);
        assert_eq!(crop("").unwrap(), None);
        assert_eq!(
            crop(r#"<integer name="crop_width" value="40"/>"#).unwrap(),
            None
        );
        assert_eq!(
            crop(
                r#"<integer name="crop_offset_x" value="10"/><integer name="crop_offset_y" value="5"/>
                   <integer name="crop_width" value="30"/><integer name="crop_height" value="20"/>"#
            )
            .unwrap(),
            Some(CropWindow {
                offset: UVec2::new(10, 5),
                size: UVec2::new(30, 20),
            })
        );
        for bad in [
            // The size defaults to the whole film's, so an offset alone reaches outside.
            r#"<integer name="crop_offset_x" value="1"/>"#,
            r#"<integer name="crop_width" value="0"/>"#,
            r#"<integer name="crop_height" value="-3"/>"#,
        ] {
            let e = crop(bad).unwrap_err().to_string();
            assert!(e.contains("m.xml:2") && e.contains("crop"), "{bad}: {e}");
        }
    }

    /// A shape without a BSDF gets Mitsuba's default, diffuse 0.5, except an area light,
    /// whose default BSDF is black (Mitsuba 3.9's `Shape` makes it so).
    #[test]
    fn an_emitter_without_a_bsdf_reflects_nothing() {
        let xml = scene_with(
            r#"<shape type="rectangle"><emitter type="area"/></shape>
               <shape type="rectangle"/>
               <shape type="rectangle"><emitter type="area"/>
                   <bsdf type="diffuse"><rgb name="reflectance" value="0.3"/></bsdf></shape>"#,
        );
        let loaded = load(&xml, &[]).unwrap();
        let albedos: Vec<Vec3> = loaded
            .scene
            .instances
            .iter()
            .map(|i| match i.material.as_deref().map(inner) {
                Some(Material::Diffuse(d)) => d.albedo.eval(Vec2::ZERO),
                m => panic!("{m:?}"),
            })
            .collect();
        assert_eq!(
            albedos,
            [Vec3::ZERO, Vec3::splat(0.5), Vec3::splat(0.3)].to_vec()
        );
    }

    /// The envmap reads the image where Mitsuba 3 does (values checked with Mitsuba 3.9's
    /// `envmap.eval` on the same 8×4 image: red = column + 1, green = row + 1).
    #[test]
    fn envmap_follows_mitsubas_lat_long_mapping() {
        let dir = std::env::temp_dir().join(format!("lightpath-mts-env-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = crate::film::Image::new(8, 4);
        for y in 0..4 {
            for x in 0..8 {
                img.pixels[y * 8 + x] = Vec3::new(x as f32 + 1.0, y as f32 + 1.0, 0.0);
            }
        }
        crate::io::image::write_image(&dir.join("env.exr"), &img).unwrap();
        let xml = scene_with(
            r#"<emitter type="envmap"><string name="filename" value="env.exr"/></emitter>"#,
        );
        let loaded =
            crate::io::load_scene_str(&xml, &dir.join("m.xml"), &LoadOptions::default()).unwrap();
        let Some(Light::Environment(env)) = loaded.scene.lights.first() else {
            panic!("no environment")
        };
        // (direction from the scene, Mitsuba's value)
        let mitsuba = [
            (Vec3::X, Vec3::new(2.5, 2.5, 0.0)),
            (Vec3::NEG_X, Vec3::new(6.5, 2.5, 0.0)),
            (Vec3::Z, Vec3::new(4.5, 2.5, 0.0)),
            (Vec3::NEG_Z, Vec3::new(4.5, 2.5, 0.0)),
            (
                Vec3::new(1.0, 0.0, -1.0).normalize(),
                Vec3::new(1.5, 2.5, 0.0),
            ),
            (
                Vec3::new(1.0, 0.0, 1.0).normalize(),
                Vec3::new(3.5, 2.5, 0.0),
            ),
            // Off the equator rows differ slightly: Mitsuba puts the first and last
            // rows' centres on the poles (it gives green 1.375 at θ = π/8 where ours
            // gives 1, a row centre).
        ];
        for (d, e) in mitsuba {
            let v = env.eval(d);
            assert!((v - e).length() < 1e-3, "{d}: {v} vs Mitsuba's {e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn mean(img: &crate::film::Image) -> Vec3 {
        img.pixels.iter().copied().sum::<Vec3>() / img.pixels.len() as f32
    }

    fn render(loaded: &LoadedScene) -> crate::film::Image {
        loaded.renderer().unwrap().render(&|_| {}).unwrap().0
    }

    /// The Mitsuba Cornell box renders as our lightwave transcription of it does.
    #[test]
    fn cornell_box_matches_the_lightwave_version() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mts = root.join("../shared/models/cornell-box/mitsuba/cbox-rgb.xml");
        let mts = if mts.exists() {
            mts
        } else {
            PathBuf::from("/work/shared/models/cornell-box/mitsuba/cbox-rgb.xml")
        };
        let lw = root.join("benches/scenes/cbox.xml");
        if !mts.exists() || !lw.exists() {
            eprintln!("skipped: no Cornell box scenes");
            return;
        }
        let defines = |d: &[(&str, &str)]| LoadOptions {
            defines: d
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
            ..Default::default()
        };
        let a = crate::io::load_scene(
            &mts,
            &defines(&[("res", "64"), ("spp", "32"), ("max_depth", "6")]),
        )
        .unwrap();
        let b = crate::io::load_scene(
            &lw,
            &defines(&[
                ("res", "64"),
                ("spp", "32"),
                ("depth", "6"),
                ("sampler", "independent"),
            ]),
        );
        let Ok(b) = b else {
            eprintln!("skipped: the lightwave Cornell box cannot find its meshes");
            return;
        };
        let (ia, ib) = (render(&a), render(&b));
        let (ma, mb) = (mean(&ia), mean(&ib));
        let ratio = ma.element_sum() / mb.element_sum();
        assert!((ratio - 1.0).abs() < 0.02, "mean {ma} vs {mb}");
        // The red wall is on the left in both.
        let half_red = |img: &crate::film::Image, left: bool| -> f32 {
            let w = img.width as usize;
            img.pixels
                .iter()
                .enumerate()
                .filter(|(i, _)| ((i % w) < w / 2) == left)
                .map(|(_, p)| p.x - p.y)
                .sum()
        };
        assert!(half_red(&ia, true) > half_red(&ia, false));
        assert!(half_red(&ib, true) > half_red(&ib, false));
    }
}
