//! Wavefront OBJ mesh loader, built on `tobj`.
//!
//! All objects and groups of the file are merged into one [`MeshData`], in file
//! order. `tobj` is asked for a single index (`single_index: true`), so every
//! distinct `v/vt/vn` combination becomes one vertex and positions, normals and
//! texture coordinates stay aligned. Polygons are triangulated by `tobj` as a fan
//! `(v0, vi, vi+1)` in file order (quads as `(a, b, c), (a, c, d)`), the same
//! convention as the PLY loader; degenerate triangles are kept. Point and line
//! elements (`p`, `l`) are ignored. [`load_obj`] reads geometry only (`mtllib` and
//! `usemtl` are skipped): a scene file that uses an OBJ mesh assigns its own material.
//! [`load_scene`] reads the OBJ as a whole scene, with its MTL materials (see there).
//!
//! Vertex colours (`v x y z r g b`, linear RGB) are kept when every vertex has one.
//! Normals are kept only when every vertex has one; texture coordinates are kept
//! when any object has them, vertices without one get `(0, 0)`. Texture
//! coordinates are returned as written in the file (no `v` flip: OBJ's `v` runs up the
//! image, as lightpath's textures' does).
//!
//! A malformed file is an error naming the file and the first line that cannot be read.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{UVec2, Vec2, Vec3};

use super::image::{read_coverage, read_image, Transfer};
use super::mtl::{load_mtl, MapRef, MtlMaterial};
use super::{LoadOptions, LoadedScene};
use crate::camera::{Camera, FovAxis, Perspective};
use crate::error::{Error, Location, Result};
use crate::film::Image;
use crate::geometry::{AlphaMask, AlphaTest, MeshData, Shape, TriangleMesh};
use crate::integrator::{Integrator, PathTracer};
use crate::light::{Emission, Environment, Light};
use crate::material::{Dielectric, Diffuse, Material, NormalMap, Principled};
use crate::math::Transform;
use crate::sampling::{IndependentSampler, Sampler};
use crate::scene::{Instance, Scene};
use crate::texture::{BorderMode, FilterMode, ImageTexture, Texture};

/// The options every OBJ is read with.
fn tobj_options() -> tobj::LoadOptions {
    // `..Default::default()` covers fields behind optional tobj features (e.g.
    // `merge_identical_points` with `merging`), which another crate may enable.
    #[allow(clippy::needless_update)]
    tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    }
}

/// A library-less material loader: every `mtllib` reads as empty.
fn no_materials(_: &Path) -> tobj::MTLLoadResult {
    Ok((Vec::new(), Default::default()))
}

fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// The 1-based line at which `tobj` first fails on `text`: the shortest failing prefix
/// of lines, found by bisection (only called once parsing has failed).
fn error_line(text: &str) -> Option<u32> {
    let lines: Vec<&str> = text.lines().collect();
    let options = tobj_options();
    let fails = |k: usize| {
        let prefix = lines[..k].join("\n");
        tobj::load_obj_buf(&mut prefix.as_bytes(), &options, no_materials).is_err()
    };
    if !fails(lines.len()) {
        return None;
    }
    let (mut ok, mut bad) = (0, lines.len());
    while bad - ok > 1 {
        let mid = (ok + bad) / 2;
        if fails(mid) {
            bad = mid;
        } else {
            ok = mid;
        }
    }
    Some(bad as u32)
}

/// "line N: " for an OBJ parse error, when the line can be found.
fn parse_error(text: &str, e: tobj::LoadError) -> (u32, String) {
    let line = error_line(text).unwrap_or(0);
    (line, format!("cannot parse OBJ: {e}"))
}

/// Appends `flat`'s (x, y, z) triples to `out`, or fails naming the first one that is not
/// finite as vertex `base + i`'s `what`.
fn push_finite(
    out: &mut Vec<Vec3>,
    flat: &[f32],
    what: &str,
    base: usize,
    path: &Path,
) -> Result<()> {
    for (i, v) in flat.chunks_exact(3).enumerate() {
        let v = Vec3::new(v[0], v[1], v[2]);
        if !v.is_finite() {
            return Err(Error::mesh(
                path,
                format!("vertex {} has a non-finite {what} {v}", base + i),
            ));
        }
        out.push(v);
    }
    Ok(())
}

/// Reads an OBJ file into triangle mesh data (geometry only).
///
/// `normals` and `uvs` of the result are either empty or as long as `positions`.
pub fn load_obj(path: &Path) -> Result<MeshData> {
    let text = read_text(path)?;
    let (models, _materials) =
        tobj::load_obj_buf(&mut text.as_bytes(), &tobj_options(), no_materials).map_err(|e| {
            let (line, message) = parse_error(&text, e);
            if line > 0 {
                Error::mesh(path, format!("line {line}: {message}"))
            } else {
                Error::mesh(path, message)
            }
        })?;
    let meshes: Vec<&tobj::Mesh> = models.iter().map(|m| &m.mesh).collect();
    merge_meshes(path, &meshes)
}

/// Merges tobj meshes (in order) into one [`MeshData`].
fn merge_meshes(path: &Path, meshes: &[&tobj::Mesh]) -> Result<MeshData> {
    let meshes: Vec<&tobj::Mesh> = meshes
        .iter()
        .copied()
        .filter(|m| !m.positions.is_empty())
        .collect();
    let vertex_count = |m: &tobj::Mesh| m.positions.len() / 3;
    let has_normals = |m: &tobj::Mesh| m.normals.len() == m.positions.len();
    let has_uvs = |m: &tobj::Mesh| m.texcoords.len() / 2 == vertex_count(m);

    let keep_normals = !meshes.is_empty() && meshes.iter().all(|m| has_normals(m));
    let keep_uvs = meshes.iter().any(|m| has_uvs(m));
    // Vertex colours (`v x y z r g b`, linear), kept when every vertex has one.
    let has_colors = |m: &tobj::Mesh| m.vertex_color.len() == m.positions.len();
    let keep_colors = !meshes.is_empty() && meshes.iter().all(|m| has_colors(m));
    if !keep_normals && meshes.iter().any(|m| !m.normals.is_empty()) {
        log::warn!(
            "{}: some vertices have no normal; all normals dropped",
            path.display()
        );
    }
    if keep_uvs && !meshes.iter().all(|m| has_uvs(m)) {
        log::warn!(
            "{}: some vertices have no texture coordinates; they get (0, 0)",
            path.display()
        );
    }

    let total_vertices: usize = meshes.iter().map(|m| vertex_count(m)).sum();
    let total_triangles: usize = meshes.iter().map(|m| m.indices.len() / 3).sum();
    if total_vertices > u32::MAX as usize {
        return Err(Error::mesh(path, "too many vertices"));
    }
    let mut mesh = MeshData {
        positions: Vec::with_capacity(total_vertices),
        normals: Vec::with_capacity(if keep_normals { total_vertices } else { 0 }),
        uvs: Vec::with_capacity(if keep_uvs { total_vertices } else { 0 }),
        indices: Vec::with_capacity(total_triangles),
        colors: Vec::with_capacity(if keep_colors { total_vertices } else { 0 }),
        face_colors: Vec::new(),
    };

    for m in meshes {
        let base = mesh.positions.len();
        let count = vertex_count(m);
        push_finite(&mut mesh.positions, &m.positions, "position", base, path)?;
        if keep_normals {
            mesh.normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|n| Vec3::new(n[0], n[1], n[2])),
            );
        }
        if keep_colors {
            push_finite(&mut mesh.colors, &m.vertex_color, "colour", base, path)?;
        }
        if keep_uvs {
            if has_uvs(m) {
                mesh.uvs
                    .extend(m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], t[1])));
            } else {
                mesh.uvs.extend(std::iter::repeat_n(Vec2::ZERO, count));
            }
        }
        if m.indices.len() % 3 != 0 {
            return Err(Error::mesh(
                path,
                "triangulated index count is not a multiple of 3",
            ));
        }
        for tri in m.indices.chunks_exact(3) {
            let mut out = [0u32; 3];
            for (o, &i) in out.iter_mut().zip(tri) {
                if i as usize >= count {
                    return Err(Error::mesh(
                        path,
                        format!(
                            "triangle {} has vertex index out of range",
                            mesh.indices.len()
                        ),
                    ));
                }
                *o = (base + i as usize) as u32;
            }
            mesh.indices.push(out);
        }
    }
    Ok(mesh)
}

/// Image size of the camera an OBJ scene gets.
pub const SCENE_RESOLUTION: UVec2 = UVec2::new(640, 480);
/// Vertical field of view of that camera, in degrees.
pub const SCENE_FOV_Y: f32 = 40.0;
/// Samples per pixel an OBJ scene asks for (`--spp` overrides it).
pub const SCENE_SPP: u32 = 64;

/// Reads an OBJ file with its MTL materials as a scene (`lightpath render model.obj`).
///
/// - **Shapes.** The faces of each material become one triangle mesh (one instance),
///   in order of the materials' first use; faces without a material (or whose `usemtl`
///   names no material of the libraries: a warning) share a grey diffuse (0.5).
/// - **Materials** (MTL statements; a map replaces its constant, as Blender's importer
///   does, and is sampled bilinearly with repeat):
///   - `illum` 4, 6 or 7, or `d` < 1 (`Tr` > 0): a smooth dielectric of index `Ni`
///     (default 1.5), transmittance `Tf` (default 1). Partial opacity is rendered as
///     glass, not as a blend.
///   - otherwise, with a non-zero `Ks` (or a `map_Ks`) and `illum` not 0 or 1: the
///     principled material with base colour `Kd`/`map_Kd` (sRGB), metallic 0,
///     `specular` = the largest component of `Ks` (F0 = 0.08·specular; `map_Ks` gives
///     it per texel by its red channel) and roughness from the Phong exponent `Ns`
///     (default 0) by α = sqrt(2 / (Ns + 2)), roughness = sqrt(α) (lightpath's
///     α = roughness²). The colour of `Ks` is dropped.
///   - otherwise: diffuse, `Kd`/`map_Kd` (default 0.5).
///   - `Ke`/`map_Ke` (sRGB) non-zero: the shape is an area light of that radiance,
///     emitting on the side its normals face; its BSDF is the one above.
///   - `map_Bump`, `bump` or `norm`: a tangent-space normal map (linear) around the
///     material, if the image looks like one (its mean colour is blue: z > 0.6 and
///     above x and y by 0.15); otherwise (a height map) it is ignored with a warning.
///   - `map_d`: an alpha cutout (see [`crate::geometry::AlphaMask`]): the surface is
///     there where the map (its alpha channel if it has one, else its first channel,
///     read linearly, bilinear with repeat) is at least 0.5; elsewhere camera, bounce
///     and shadow rays pass through (foliage and fences drawn on quads, as in Sponza).
/// - **Camera.** A 640×480 perspective camera with a 40° vertical field of view
///   looking down −z at the centre of the bounds, far enough that the bounding sphere
///   fits in the image (+y up, as OBJ files are usually written).
/// - **Lights.** The emitting shapes; when there are none, a constant white environment.
/// - **Integrator.** A path tracer (Russian roulette from depth 5), an independent
///   sampler at 64 samples per pixel.
///
/// A missing `.mtl` or texture file is an error naming it and the OBJ or MTL line that
/// refers to it; so are malformed OBJ and MTL lines.
pub fn load_scene(path: &Path, options: &LoadOptions) -> Result<LoadedScene> {
    let text = read_text(path)?;
    let folder = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let location = |line: u32| Location {
        file: path.to_path_buf(),
        line,
        column: 1,
    };

    // `mtllib` and `usemtl` lines, for errors tobj cannot place.
    let mut libraries: Vec<u32> = Vec::new();
    let mut uses: Vec<(u32, String)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line_no = i as u32 + 1;
        let trimmed = line.trim_start();
        let (keyword, rest) = trimmed
            .split_once(char::is_whitespace)
            .unwrap_or((trimmed, ""));
        match keyword {
            "mtllib" => libraries.push(line_no),
            "usemtl" => uses.push((line_no, rest.trim().to_string())),
            _ => {}
        }
    }

    // Libraries are parsed by `mtl`; tobj gets their names to number the materials.
    let materials: RefCell<Vec<MtlMaterial>> = RefCell::new(Vec::new());
    let first_error: RefCell<Option<Error>> = RefCell::new(None);
    let calls = RefCell::new(0usize);
    let loader = |file: &Path| -> tobj::MTLLoadResult {
        let k = *calls.borrow();
        *calls.borrow_mut() += 1;
        let line = libraries.get(k).copied().unwrap_or(0);
        let mtl_path = folder.join(file.to_string_lossy().replace('\\', "/"));
        match load_mtl(&mtl_path) {
            Ok(list) => {
                let stubs: Vec<tobj::Material> = list
                    .iter()
                    .map(|m| tobj::Material {
                        name: m.name.clone(),
                        ..Default::default()
                    })
                    .collect();
                let map = list
                    .iter()
                    .enumerate()
                    .map(|(i, m)| (m.name.clone(), i))
                    .collect();
                materials.borrow_mut().extend(list);
                Ok((stubs, map))
            }
            Err(e) => {
                let e = match e {
                    Error::Io { path: p, source } => Error::scene(
                        location(line),
                        format!("mtllib: cannot read {}: {source}", p.display()),
                    ),
                    other => other,
                };
                first_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::GenericFailure)
            }
        }
    };
    let parsed = tobj::load_obj_buf(&mut text.as_bytes(), &tobj_options(), loader);
    if let Some(e) = first_error.into_inner() {
        return Err(e);
    }
    let (models, _) = parsed.map_err(|e| {
        let (line, message) = parse_error(&text, e);
        Error::scene(location(line), message)
    })?;
    let materials = materials.into_inner();
    for (line, name) in &uses {
        if !materials.iter().any(|m| &m.name == name) {
            log::warn!(
                "{}:{line}: usemtl `{name}`: no material of that name in the mtllib files; \
                 its faces are grey diffuse",
                path.display()
            );
        }
    }

    // One mesh per material, in order of first use.
    let mut groups: Vec<(Option<usize>, Vec<&tobj::Mesh>)> = Vec::new();
    for model in &models {
        let id = model.mesh.material_id.filter(|&i| i < materials.len());
        match groups.iter_mut().find(|(g, _)| *g == id) {
            Some((_, meshes)) => meshes.push(&model.mesh),
            None => groups.push((id, vec![&model.mesh])),
        }
    }
    let accel = options.accel.unwrap_or_default();
    let mut builder = MaterialBuilder::default();
    let mut instances = Vec::new();
    for (id, meshes) in &groups {
        let data = merge_meshes(path, meshes)?;
        if data.indices.is_empty() {
            continue;
        }
        let mut mesh = TriangleMesh::new(data, true, accel).map_err(|m| Error::mesh(path, m))?;
        if let Some(m) = id.map(|i| &materials[i]) {
            if let Some(map) = &m.map_d {
                mesh.set_alpha(AlphaMask {
                    coverage: builder.coverage(map, &m.file)?,
                    test: AlphaTest::Cutoff(0.5),
                });
            }
        }
        let mut instance = Instance::new(
            Arc::new(Shape::TriangleMesh(Arc::new(mesh))),
            Transform::IDENTITY,
        );
        match id {
            Some(i) => {
                let (material, emission) = builder.material(&materials[*i])?;
                instance.material = Some(material);
                instance.emission = emission;
            }
            None => instance.material = Some(grey()),
        }
        instances.push(instance);
    }
    if instances.is_empty() {
        return Err(Error::mesh(path, "the OBJ has no faces to render"));
    }

    let has_emitters = instances.iter().any(|i| i.emission.is_some());
    let mut scene = Scene::new(instances, None, accel);
    scene.camera = Some(framing_camera(&scene));
    let lights = if has_emitters {
        Vec::new()
    } else {
        vec![Light::Environment(Environment::new(
            Arc::new(Texture::Constant(Vec3::ONE)),
            Transform::IDENTITY,
        ))]
    };
    let weights = vec![1.0; lights.len()];
    scene
        .set_lights(lights, &weights)
        .map_err(|m| Error::mesh(path, m))?;
    Ok(LoadedScene {
        scene,
        integrator: Integrator::PathTracer(PathTracer {
            max_depth: u32::MAX,
            rr_depth: 5,
            clamp: None,
            hide_emitters: false,
        }),
        sampler: Sampler::Independent(IndependentSampler::new(SCENE_SPP, 0)),
        test: None,
        path: path.to_path_buf(),
    })
}

fn grey() -> Arc<Material> {
    Arc::new(Material::Diffuse(Diffuse {
        albedo: Arc::new(Texture::Constant(Vec3::splat(0.5))),
    }))
}

/// The camera of an OBJ scene: looking down −z at the bounds' centre from where the
/// bounding sphere just fits the image.
fn framing_camera(scene: &Scene) -> Camera {
    let b = scene.bounds();
    let (centre, radius) = if b.min.is_finite() && b.max.is_finite() {
        ((b.min + b.max) * 0.5, (b.max - b.min).length() * 0.5)
    } else {
        (Vec3::ZERO, 1.0)
    };
    let radius = if radius > 0.0 { radius } else { 1.0 };
    let res = SCENE_RESOLUTION;
    let half_y = (SCENE_FOV_Y * 0.5).to_radians();
    let half_x = (half_y.tan() * res.x as f32 / res.y as f32).atan();
    let distance = radius / half_y.min(half_x).sin();
    let origin = centre + Vec3::Z * distance;
    // Camera +y is image down: `up` is given as −y so that world +y is up in the image.
    let render_from_camera =
        Transform::look_at(origin, centre, -Vec3::Y).unwrap_or(Transform::IDENTITY);
    Camera::Perspective(Perspective::new(
        res,
        SCENE_FOV_Y,
        FovAxis::Y,
        render_from_camera,
    ))
}

/// Turns MTL materials into lightpath materials, sharing images between them.
#[derive(Default)]
struct MaterialBuilder {
    images: HashMap<(PathBuf, bool), Arc<Image>>,
}

impl MaterialBuilder {
    fn image(&mut self, map: &MapRef, mtl: &Path, linear: bool) -> Result<Arc<Image>> {
        let key = (map.path.clone(), linear);
        if let Some(i) = self.images.get(&key) {
            return Ok(i.clone());
        }
        let transfer = if linear {
            Transfer::Linear
        } else {
            Transfer::Srgb
        };
        let image = read_image(&map.path, Some(transfer)).map_err(|e| {
            Error::scene(
                Location {
                    file: mtl.to_path_buf(),
                    line: map.line,
                    column: 1,
                },
                format!("cannot load texture: {e}"),
            )
        })?;
        let image = Arc::new(image);
        self.images.insert(key, image.clone());
        Ok(image)
    }

    /// The coverage texture of a `map_d` (see [`read_coverage`]).
    fn coverage(&mut self, map: &MapRef, mtl: &Path) -> Result<Arc<Texture>> {
        let image = read_coverage(&map.path).map_err(|e| {
            Error::scene(
                Location {
                    file: mtl.to_path_buf(),
                    line: map.line,
                    column: 1,
                },
                format!("cannot load map_d: {e}"),
            )
        })?;
        Ok(Arc::new(Texture::Image(ImageTexture {
            image: Arc::new(image),
            border: BorderMode::Repeat,
            filter: FilterMode::Bilinear,
            exposure: 1.0,
        })))
    }

    /// A map's texture, else the constant, else `default`.
    fn slot(
        &mut self,
        map: &Option<MapRef>,
        constant: Option<Vec3>,
        default: Vec3,
        mtl: &Path,
    ) -> Result<Arc<Texture>> {
        Ok(Arc::new(match map {
            Some(map) => Texture::Image(ImageTexture {
                image: self.image(map, mtl, false)?,
                border: BorderMode::Repeat,
                filter: FilterMode::Bilinear,
                exposure: 1.0,
            }),
            None => Texture::Constant(constant.unwrap_or(default)),
        }))
    }

    /// The material of an MTL block and its emission, if any (see [`load_scene`]).
    fn material(&mut self, m: &MtlMaterial) -> Result<(Arc<Material>, Option<Emission>)> {
        let mtl = m.file.as_path();
        let transparent = matches!(m.illum, Some(4 | 6 | 7)) || m.dissolve.is_some_and(|d| d < 1.0);
        let glossy = !matches!(m.illum, Some(0 | 1))
            && (m.map_ks.is_some() || m.ks.is_some_and(|k| k.max_element() > 0.0));
        let mut material = if transparent {
            Material::Dielectric(Dielectric {
                ior: m.ni.unwrap_or(1.5),
                reflectance: Arc::new(Texture::Constant(Vec3::ONE)),
                transmittance: Arc::new(Texture::Constant(m.tf.unwrap_or(Vec3::ONE))),
            })
        } else if glossy {
            let specular = match &m.map_ks {
                Some(map) => self.slot(&Some(map.clone()), None, Vec3::ZERO, mtl)?,
                None => Arc::new(Texture::Constant(Vec3::splat(
                    m.ks.unwrap_or(Vec3::ZERO).max_element().min(1.0),
                ))),
            };
            Material::Principled(Principled {
                base_color: self.slot(&m.map_kd, m.kd, Vec3::splat(0.5), mtl)?,
                roughness: Arc::new(Texture::Constant(Vec3::splat(phong_roughness(
                    m.ns.unwrap_or(0.0),
                )))),
                metallic: Arc::new(Texture::Constant(Vec3::ZERO)),
                specular,
            })
        } else {
            Material::Diffuse(Diffuse {
                albedo: self.slot(&m.map_kd, m.kd, Vec3::splat(0.5), mtl)?,
            })
        };
        if let Some(map) = &m.map_normal {
            let image = self.image(map, mtl, true)?;
            let mean =
                image.pixels.iter().copied().sum::<Vec3>() / image.pixels.len().max(1) as f32;
            if mean.z > 0.6 && mean.z > mean.x + 0.15 && mean.z > mean.y + 0.15 {
                material = Material::NormalMap(NormalMap::new(
                    Arc::new(Texture::Image(ImageTexture {
                        image,
                        border: BorderMode::Repeat,
                        filter: FilterMode::Bilinear,
                        exposure: 1.0,
                    })),
                    Arc::new(material),
                ));
            } else {
                log::warn!(
                    "{}:{}: {} looks like a height (bump) map, not a normal map; ignored",
                    mtl.display(),
                    map.line,
                    map.path.display()
                );
            }
        }
        let emits = m.map_ke.is_some() || m.ke.is_some_and(|k| k.max_element() > 0.0);
        let emission = if emits {
            Some(Emission {
                radiance: self.slot(&m.map_ke, m.ke, Vec3::ZERO, mtl)?,
            })
        } else {
            None
        };
        Ok((Arc::new(material), emission))
    }
}

/// Roughness (lightpath's: α = roughness²) of a Phong exponent, by the usual
/// α = sqrt(2 / (Ns + 2)).
pub fn phong_roughness(ns: f32) -> f32 {
    (2.0 / (ns.max(0.0) + 2.0)).sqrt().sqrt()
}
#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A fresh directory under the system temp dir, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new() -> Self {
            static COUNTER: AtomicUsize = AtomicUsize::new(0);
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let dir =
                std::env::temp_dir().join(format!("lightpath-obj-test-{}-{n}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("create temp dir");
            TempDir(dir)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn load_text(text: &str) -> Result<MeshData> {
        let dir = TempDir::new();
        let path = dir.0.join("mesh.obj");
        std::fs::write(&path, text).expect("write");
        load_obj(&path)
    }

    #[test]
    fn quad_becomes_fan_with_normals_and_uvs() {
        let text = "\
# a unit quad
mtllib missing.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl whatever
f 1/1/1 2/2/1 3/3/1 4/4/1
";
        let mesh = load_text(text).expect("load");
        assert_eq!(
            mesh.positions,
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ]
        );
        assert_eq!(mesh.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(mesh.normals, vec![Vec3::Z; 4]);
        assert_eq!(
            mesh.uvs,
            vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 1.0),
            ]
        );
    }

    #[test]
    fn polygon_fan_and_groups_merged() {
        let text = "\
o pentagon
v 0 0 0
v 1 0 0
v 2 1 0
v 1 2 0
v 0 1 0
f 1 2 3 4 5
o tri
v 5 5 5
v 6 5 5
v 5 6 5
f -3 -2 -1
f 6 6 7
";
        let mesh = load_text(text).expect("load");
        assert_eq!(mesh.positions.len(), 8);
        assert_eq!(
            mesh.indices,
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [5, 6, 7], [5, 5, 6]]
        );
        assert_eq!(mesh.positions[5], Vec3::splat(5.0));
        assert!(mesh.normals.is_empty());
        assert!(mesh.uvs.is_empty());
    }

    /// `v x y z r g b` vertex colours are kept when every vertex has one.
    #[test]
    fn vertex_colours() {
        let text = "\
v 0 0 0 1 0 0
v 1 0 0 0 1 0
v 0 1 0 0 0 0.5
v 1 1 0 0.25 0.25 0.25
f 1 2 3
f 2 4 3
";
        let mesh = load_text(text).expect("load");
        assert_eq!(mesh.colors.len(), mesh.positions.len());
        let at = |p: Vec3| mesh.colors[mesh.positions.iter().position(|&q| q == p).unwrap()];
        assert_eq!(at(Vec3::Y), Vec3::new(0.0, 0.0, 0.5));
        assert_eq!(at(Vec3::new(1.0, 1.0, 0.0)), Vec3::splat(0.25));
        // A face using a vertex without a colour among coloured ones: `tobj` refuses the
        // file, and the error names the line.
        let mixed = text.replace("v 1 1 0 0.25 0.25 0.25", "v 1 1 0");
        let message = load_text(&mixed).unwrap_err().to_string();
        assert!(message.contains("line 6"), "{message}");
    }

    #[test]
    fn missing_uvs_in_one_group_are_zero() {
        let text = "\
v 0 0 0
v 1 0 0
v 0 1 0
vt 0.5 0.25
g a
f 1/1 2/1 3/1
g b
f 1 2 3
";
        let mesh = load_text(text).expect("load");
        assert_eq!(mesh.positions.len(), 6);
        assert_eq!(mesh.uvs.len(), 6);
        assert_eq!(mesh.uvs[0], Vec2::new(0.5, 0.25));
        assert_eq!(mesh.uvs[5], Vec2::ZERO);
        assert_eq!(mesh.indices, vec![[0, 1, 2], [3, 4, 5]]);
    }

    #[test]
    fn bad_index_is_an_error() {
        let result = load_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
        assert!(matches!(result, Err(Error::Mesh { .. })), "{result:?}");
    }

    #[test]
    fn missing_file_is_an_io_error() {
        let dir = TempDir::new();
        let result = load_obj(&dir.0.join("nope.obj"));
        assert!(matches!(result, Err(Error::Io { .. })), "{result:?}");
    }

    /// The Stanford bunny OBJ from the shared data, when it is present.
    #[test]
    fn stanford_bunny_obj() {
        let path = Path::new("/work/shared/models/stanford-bunny/stanford-bunny.obj");
        if !path.exists() {
            eprintln!("skipped: {} not present", path.display());
            return;
        }
        let mesh = load_obj(path).expect("load");
        assert!(!mesh.indices.is_empty());
        assert!(mesh.normals.is_empty() || mesh.normals.len() == mesh.positions.len());
        assert!(mesh.uvs.is_empty() || mesh.uvs.len() == mesh.positions.len());
    }
}
