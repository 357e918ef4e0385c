//! [`PathTracer::scatter`] for sixteen path vertices at once, where it is both simplest
//! and most common: a diffuse surface (two-sided, or one-sided as Mitsuba's) of constant
//! albedo, lit by next-event estimation of a flat triangle-mesh emitter of constant
//! radiance (or by no light at all). A renderer that advances many paths together
//! ([`crate::render`]'s packet tile) hands each vertex to [`DiffuseLanes::step`], which
//! takes such vertices into lanes (building their interactions too, for hits on the
//! merged mesh) and runs the others as [`PathTracer::step`] does; when the lanes are
//! full, [`DiffuseLanes::run`] scatters them and [`DiffuseLanes::finish`] hands the
//! results back to the paths.
//!
//! The arithmetic is `scatter`'s (and `TriangleMesh::interaction`'s), operation for
//! operation: the same products and quotients, additions in the same order, no fused
//! multiply-adds, the same polynomial sine and cosine. So a vertex gets the same values,
//! bit for bit, whichever way it runs, and an image does not depend on which of its
//! paths ran here. The work is written with [`crate::math::lanes::F32x16`] operations
//! and selects in place of branches: one AVX-512 instruction per operation, or two AVX2
//! ones (the renderer compiles [`DiffuseLanes::run`] for each tier).
//!
//! Nothing in a scene file selects this: the Cornell box below takes it at every vertex.
//!
//! ```xml
//! <scene version="3.0.0">
//!     <shape type="obj" filename="meshes/walls.obj"><bsdf type="diffuse"/></shape>
//!     <shape type="obj" filename="meshes/light.obj">
//!         <emitter type="area"><rgb name="radiance" value="18.4, 15.6, 8.0"/></emitter>
//!     </shape>
//! </scene>
//! ```

use super::path_tracer::{PathState, PathTracer, Previous, ShadowQuery, VertexSamples};
use crate::geometry::{ShapeHit, SurfaceInteraction};
use crate::light::{FlatTriangleSample, Light};
use crate::material::Material;
use crate::math::lanes::{F32x16 as F, Mask16 as M, LANES};
use crate::math::{gamma, round_away, Ray, INV_PI, PI};
use crate::sampling::{Pcg32, Sampler};
use crate::scene::Scene;
use crate::texture::Texture;
use glam::{Vec3, Vec3A};

type F3 = [F; 3];

/// The three components of `$e` for `$c` = 0, 1, 2, written out (a closure might not
/// be inlined into the vector code).
macro_rules! each {
    ($c:ident => $e:expr) => {
        [
            {
                let $c = 0;
                $e
            },
            {
                let $c = 1;
                $e
            },
            {
                let $c = 2;
                $e
            },
        ]
    };
}

/// Up to [`LANES`] vertices in structure-of-arrays form, and their results.
#[derive(Default)]
pub(crate) struct DiffuseLanes {
    len: usize,
    /// The caller's tag of each vertex's path.
    tag: [u32; LANES],
    // The vertex.
    p: F3,
    p_error: F3,
    n: F3,
    shading_n: F3,
    dpdu: F3,
    wo: F3,
    albedo: F3,
    one_sided: M,
    beta: F3,
    u_dir: [F; 2],
    /// Whether Russian roulette runs after this vertex, with the number `u_rr`.
    roulette: M,
    u_rr: F,
    // Vertices pushed as hits on the merged mesh, whose interactions the lanes build
    // (`TriangleMesh::interaction`): the triangle, the barycentrics and the ray.
    from_hit: M,
    /// The vertices whose triangle's corners, flags and albedo the lanes take from its
    /// row in [`LaneInstances`]' table (row `hit_prim`).
    from_row: M,
    hit_corners: [F3; 3],
    hit_normals: [F3; 3],
    smooth: M,
    flipped: M,
    bary: [F; 2],
    direction: F3,
    /// The merged triangle and distance of each: its table row, and for the rare
    /// triangle without area its hit (built one by one, with `direction`).
    hit_prim: [u32; LANES],
    hit_t: [f32; LANES],
    // The light sample: whether a light was picked, and its triangle.
    lit: M,
    reachable: M,
    pick: F,
    light: LightTriangles,
    /// The numbers that pick the light (where the lanes pick it, [`LightPicks`]) and
    /// that pick the triangle and place the point on it.
    u_light: F,
    u_triangle: [F; 2],
    /// With `table`: the picked triangle's slot there (`light` is then filled from the
    /// table when the lanes run, not per vertex).
    slot: [u32; LANES],
    table: Option<Box<LightTable>>,
    /// Whether the table picks the lights ([`LightPicks`]).
    picks: bool,
    /// The vertices whose numbers the lanes draw themselves (the independent sampler's,
    /// where the lanes pick the light too): each one's PCG32 state and increment, and
    /// the state its draws leave, which [`DiffuseLanes::finish`] hands back.
    draws: M,
    rng_state: [u64; LANES],
    rng_inc: [u64; LANES],
    rng_out: [u64; LANES],
    // Results.
    shadow: M,
    shadow_origin: F3,
    shadow_direction: F3,
    contribution: F3,
    more: M,
    ray_origin: F3,
    ray_direction: F3,
    beta_out: F3,
    pdf: F,
}

/// What [`DiffuseLanes::finish`] hands back for one vertex. Both the next ray and the
/// shadow ray are filled in whether or not they exist, so that callers can take them
/// without branching on data that no predictor guesses (whether a path goes on, whether
/// its vertex has a shadow ray).
pub(crate) struct LaneResult {
    /// The tag it was pushed with.
    pub tag: u32,
    /// Whether the path goes on, with `next`.
    more: bool,
    next: Next,
    /// Whether the vertex has a shadow ray, `query`, as [`PathTracer::step`] gives it.
    has_shadow: bool,
    query: ShadowQuery,
    /// Where the lanes drew the vertex's numbers: the state its independent sampler's
    /// stream is left in (set it with [`Pcg32::set_state`]).
    rng_state: Option<u64>,
}

struct Next {
    prev: Previous,
    ray: Ray,
    beta: Vec3A,
}

/// Of each instance of a scene, the albedo and sidedness of its material where the lanes
/// run hits on it (it emits nothing, and its material is one [`lane_diffuse`] takes):
/// built once per render, so that a vertex finds them with one load rather than by
/// following the instance's material and texture. Where all the scene's geometry is one
/// merged mesh of at most [`LaneInstances::TABLE_TRIANGLES`] triangles, the same per
/// triangle too, with what the lanes read of it ([`TriangleMesh::lane_triangle`]) in one
/// 64-byte row: a vertex then stores just its row's index, and the lanes take the rows'
/// fields when they run ([`DiffuseLanes::take_rows`]).
///
/// [`TriangleMesh::lane_triangle`]: crate::geometry::TriangleMesh::lane_triangle
pub(crate) struct LaneInstances {
    materials: Vec<Option<(Vec3, bool)>>,
    /// Per merged triangle (empty where there is no table).
    triangles: Vec<HitTriangle>,
    /// Per merged triangle, its vertex normals where it interpolates them (empty where
    /// no triangle does).
    normals: Vec<[Vec3; 3]>,
}

/// A merged triangle as the lanes take a hit on it: its corners, and its instance's
/// albedo and sidedness (`flags`: [`HitTriangle::LANES`] where the lanes run its hits,
/// then the others).
#[derive(Clone, Copy, Default)]
#[repr(C, align(64))]
struct HitTriangle {
    p: [Vec3; 3],
    albedo: Vec3,
    instance: u32,
    flags: u32,
}

impl HitTriangle {
    const LANES: u32 = 1;
    const ONE_SIDED: u32 = 2;
    const FLIPPED: u32 = 4;
    const SMOOTH: u32 = 8;
}

/// What the lanes read of a hit's triangle (see [`LaneInstances::hit_triangle`]).
enum LaneHit<'a> {
    /// The triangle's row in the table.
    Row(&'a HitTriangle),
    /// The triangle as the mesh gives it.
    Mesh {
        p: [Vec3; 3],
        normals: Option<[Vec3; 3]>,
        flipped: bool,
        diffuse: (Vec3, bool),
        instance: u32,
    },
}

impl LaneHit<'_> {
    #[inline(always)]
    fn instance(&self) -> u32 {
        match self {
            LaneHit::Row(t) => t.instance,
            LaneHit::Mesh { instance, .. } => *instance,
        }
    }

    /// The albedo and sidedness, where the vertex takes them now (not from its row).
    #[inline(always)]
    fn diffuse(&self) -> Option<(Vec3, bool)> {
        match self {
            LaneHit::Row(_) => None,
            LaneHit::Mesh { diffuse, .. } => Some(*diffuse),
        }
    }
}

impl LaneInstances {
    /// The most merged triangles tabulated (8 MiB of table; 2¹⁷ takes in a Stanford
    /// bunny merged into a Cornell box, see `SHARED_CORNERS_TRIANGLES` in the mesh).
    pub(crate) const TABLE_TRIANGLES: usize = 1 << 17;

    pub(crate) fn new(scene: &Scene) -> LaneInstances {
        let mut lanes = LaneInstances {
            materials: scene
                .instances
                .iter()
                .map(|inst| match (&inst.emission, inst.material.as_deref()) {
                    (None, Some(material)) => lane_diffuse(material),
                    _ => None,
                })
                .collect(),
            triangles: Vec::new(),
            normals: Vec::new(),
        };
        let Some(count) = scene
            .merged_triangle_count()
            .filter(|&n| n <= Self::TABLE_TRIANGLES)
        else {
            return lanes;
        };
        let mut normals = vec![[Vec3::ZERO; 3]; count];
        let mut smooth = false;
        lanes.triangles = (0..count as u32)
            .map(|k| {
                let (mesh, prim, instance) = scene.merged_triangle(k);
                let mut t = HitTriangle {
                    instance,
                    ..Default::default()
                };
                if let (Some((albedo, one_sided)), Some(triangle)) =
                    (lanes.materials[instance as usize], mesh.lane_triangle(prim))
                {
                    t.p = triangle.p;
                    t.albedo = albedo;
                    t.flags = HitTriangle::LANES
                        | if one_sided { HitTriangle::ONE_SIDED } else { 0 }
                        | if triangle.flipped {
                            HitTriangle::FLIPPED
                        } else {
                            0
                        };
                    if let Some(n) = triangle.normals {
                        t.flags |= HitTriangle::SMOOTH;
                        normals[k as usize] = n;
                        smooth = true;
                    }
                }
                t
            })
            .collect();
        if smooth {
            lanes.normals = normals;
        }
        lanes
    }

    /// Without the per-triangle table (as for meshes of more triangles than it holds).
    #[cfg(test)]
    fn untabulated(scene: &Scene) -> LaneInstances {
        LaneInstances {
            triangles: Vec::new(),
            normals: Vec::new(),
            ..LaneInstances::new(scene)
        }
    }

    /// The triangle of a hit on the scene's merged mesh, where the lanes run hits on it:
    /// its table row where there is a table (the lanes take the row's fields when they
    /// run), else what the mesh gives.
    #[inline(always)]
    fn hit_triangle(&self, scene: &Scene, prim: u32) -> Option<LaneHit<'_>> {
        if let Some(t) = self.triangles.get(prim as usize) {
            return (t.flags & HitTriangle::LANES != 0).then_some(LaneHit::Row(t));
        }
        let (mesh, prim, instance) = scene.merged_triangle(prim);
        let diffuse = self.materials[instance as usize]?;
        let triangle = mesh.lane_triangle(prim)?;
        Some(LaneHit::Mesh {
            p: triangle.p,
            normals: triangle.normals,
            flipped: triangle.flipped,
            diffuse,
            instance,
        })
    }
}

impl LaneResult {
    /// Moves the vertex's path on as `scatter` would; returns whether it goes on. A path
    /// that ends is written too (its ray, throughput, depth and previous vertex become
    /// meaningless): all that is read of it afterwards is its radiance, which this leaves
    /// alone ([`PathTracer::finish`]).
    #[inline(always)]
    pub(crate) fn apply(&self, path: &mut PathState) -> bool {
        path.prev = Some(self.next.prev);
        path.ray = self.next.ray;
        path.depth += 1;
        path.beta = self.next.beta;
        self.more
    }

    /// The vertex's shadow ray, as [`PathTracer::step`] gives it.
    #[cfg(test)]
    pub(crate) fn shadow(&self) -> Option<ShadowQuery> {
        self.has_shadow.then_some(self.query)
    }

    /// Where the lanes drew the vertex's numbers, the state they leave its independent
    /// sampler's stream in; hand it to the path's sampler before it draws again.
    #[inline(always)]
    pub(crate) fn rng_state(&self) -> Option<u64> {
        self.rng_state
    }

    /// Whether the vertex has a shadow ray, and the ray (meaningless where it has none).
    #[inline(always)]
    pub(crate) fn shadow_query(&self) -> (bool, &ShadowQuery) {
        (self.has_shadow, &self.query)
    }
}

impl DiffuseLanes {
    /// Lanes for vertices of `scene`, with its lights' triangles tabulated where they
    /// fit ([`LightTable`]).
    pub(crate) fn new(scene: &Scene) -> Box<DiffuseLanes> {
        let table = LightTable::new(scene);
        Box::new(DiffuseLanes {
            picks: table.as_ref().is_some_and(|t| t.picks.is_some()),
            table: table.map(Box::new),
            ..Default::default()
        })
    }

    /// The light sample of a vertex with numbers `u` as the lanes take it (see
    /// [`lane_light`]; the lanes pick it themselves where the table can).
    #[inline(always)]
    fn light<'s>(&self, scene: &'s Scene, u: &VertexSamples) -> Option<LaneLight<'s>> {
        if self.picks {
            return Some(LaneLight::Picked);
        }
        lane_light(scene, u)
    }

    /// Lanes that take each vertex's light triangle field by field (as for scenes whose
    /// lights have more triangles than the table holds).
    #[cfg(test)]
    fn untabulated() -> Box<DiffuseLanes> {
        Box::default()
    }

    pub(crate) fn len(&self) -> usize {
        self.len
    }

    pub(crate) fn is_full(&self) -> bool {
        self.len == LANES
    }

    /// One vertex of a path whose ray found `hit` on the scene's merged mesh (by
    /// [`Scene::intersect_merged`]):
    /// [`PathTracer::step`], with the vertex taken into the lanes where they can run it.
    /// Returns `None` for a vertex taken (its results come from [`DiffuseLanes::finish`]
    /// after a [`DiffuseLanes::run`]; call those when the lanes are full), else whether
    /// the path goes on, with `shadow` set as `step` sets it.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(crate) fn step(
        &mut self,
        pt: &PathTracer,
        scene: &Scene,
        instances: &LaneInstances,
        tag: u32,
        path: &mut PathState,
        hit: Option<ShapeHit>,
        sampler: &mut Sampler,
        shadow: &mut Option<ShadowQuery>,
    ) -> Option<bool> {
        let Some(shape_hit) = hit else {
            pt.miss(scene, path);
            return Some(false);
        };
        // A triangle of a surface that emits nothing: `arrive` has nothing to add, and
        // the lanes can build the interaction.
        if let Some(triangle) = instances.hit_triangle(scene, shape_hit.prim) {
            if path.depth >= pt.max_depth {
                return Some(false);
            }
            let stream = match self.picks {
                true => sampler.independent_rng().map(|rng| rng.parts()),
                false => None,
            };
            let diffuse = triangle.diffuse();
            let k = match stream {
                // The lanes draw the vertex's numbers, and pick its light.
                Some(stream) => self.fill_stream(pt, tag, path, diffuse, stream),
                None => {
                    let u = VertexSamples::draw(sampler);
                    let Some(light) = self.light(scene, &u) else {
                        let si = scene.merged_interaction(&path.ray, &shape_hit);
                        let material = scene.instances[triangle.instance() as usize]
                            .material
                            .as_deref()
                            .expect("a lane instance's material");
                        return Some(pt.scatter(scene, path, &si, material, &u, sampler, shadow));
                    };
                    self.fill(pt, tag, path, diffuse, light, &u, sampler)
                }
            };
            self.from_hit.0[k] = true;
            match triangle {
                LaneHit::Row(t) => {
                    // The corners, flags and albedo come from the row when the lanes
                    // run ([`DiffuseLanes::take_rows`]); the vertex normals now.
                    if t.flags & HitTriangle::SMOOTH != 0 {
                        let normals = &instances.normals[shape_hit.prim as usize];
                        for (c, &n) in normals.iter().enumerate() {
                            set3(&mut self.hit_normals[c], k, n);
                        }
                    }
                }
                LaneHit::Mesh {
                    p,
                    normals,
                    flipped,
                    ..
                } => {
                    for (c, &p) in p.iter().enumerate() {
                        set3(&mut self.hit_corners[c], k, p);
                    }
                    // (Flat lanes do not read their normals.)
                    if let Some(normals) = normals {
                        for (c, &n) in normals.iter().enumerate() {
                            set3(&mut self.hit_normals[c], k, n);
                        }
                    }
                    self.smooth.0[k] = normals.is_some();
                    self.flipped.0[k] = flipped;
                }
            }
            self.bary[0][k] = shape_hit.uv.x;
            self.bary[1][k] = shape_hit.uv.y;
            set3(&mut self.direction, k, path.ray.direction);
            self.hit_prim[k] = shape_hit.prim;
            self.hit_t[k] = shape_hit.t;
            return None;
        }
        let si = scene.merged_interaction(&path.ray, &shape_hit);
        let Some(material) = pt.arrive(scene, path, &si) else {
            return Some(false);
        };
        let u = VertexSamples::draw(sampler);
        if self.push(pt, scene, tag, path, &si, material, &u, sampler) {
            return None;
        }
        Some(pt.scatter(scene, path, &si, material, &u, sampler, shadow))
    }

    /// Takes the vertex where [`PathTracer::arrive`] left `path` at `si` with `material`
    /// and the vertex's numbers `u`, when the lanes run this kind of vertex (then it also
    /// draws Russian roulette's number from `sampler`, as `scatter` would); else returns
    /// false and draws nothing. Call only while not full.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(crate) fn push(
        &mut self,
        pt: &PathTracer,
        scene: &Scene,
        tag: u32,
        path: &PathState,
        si: &SurfaceInteraction,
        material: &Material,
        u: &VertexSamples,
        sampler: &mut Sampler,
    ) -> bool {
        let (Some(diffuse), Some(light)) = (lane_diffuse(material), self.light(scene, u)) else {
            return false;
        };
        let k = self.fill(pt, tag, path, Some(diffuse), light, u, sampler);
        self.from_hit.0[k] = false;
        self.set_interaction(k, si);
        true
    }

    /// Lane `k`'s interaction.
    #[inline(always)]
    fn set_interaction(&mut self, k: usize, si: &SurfaceInteraction) {
        set3(&mut self.p, k, si.p);
        set3(&mut self.p_error, k, si.p_error);
        set3(&mut self.n, k, si.n);
        set3(&mut self.shading_n, k, si.shading_n);
        set3(&mut self.dpdu, k, si.dpdu);
        set3(&mut self.wo, k, si.wo);
    }

    /// Takes a vertex into the next lane, all but its interaction: the path, the
    /// material's albedo and sidedness, the light sample and the vertex's numbers `u`
    /// (and draws Russian roulette's number, as `scatter` would). Returns the lane.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn fill(
        &mut self,
        pt: &PathTracer,
        tag: u32,
        path: &PathState,
        diffuse: Option<(Vec3, bool)>,
        light: LaneLight<'_>,
        u: &VertexSamples,
        sampler: &mut Sampler,
    ) -> usize {
        let k = self.fill_vertex(pt, tag, path, diffuse);
        self.draws.0[k] = false;
        self.u_dir[0][k] = u.u_dir.x;
        self.u_dir[1][k] = u.u_dir.y;
        self.lit.0[k] = !matches!(light, LaneLight::None);
        self.u_triangle[0][k] = u.u_point.x;
        self.u_triangle[1][k] = u.u_point.y;
        match light {
            LaneLight::None => {}
            LaneLight::Triangle(t, pick, reachable, light) => {
                self.pick[k] = pick;
                self.reachable.0[k] = reachable;
                match &self.table {
                    // Every light the lanes run has its triangles in the table.
                    Some(table) => self.slot[k] = table.first[light] + t.prim as u32,
                    None => self.light.set(k, &t),
                }
                debug_assert!((self.slot[k] as usize) < LANES);
            }
            // The pick, reachability and slot come from the table when the lanes run.
            LaneLight::Picked => self.u_light[k] = u.u_light,
        }
        // `scatter` draws Russian roulette's number after the vertex's own, when the
        // path goes on past `rr_depth`; drawing it although the path then ends changes
        // nothing (the sampler starts the next sample afresh).
        if self.roulette.0[k] {
            self.u_rr[k] = sampler.next_1d();
        }
        k
    }

    /// [`DiffuseLanes::fill`] for a vertex whose numbers the lanes draw from its
    /// independent sampler's stream, `(state, increment)` (see
    /// [`DiffuseLanes::draw_numbers`]), with its light picked by the lanes too.
    #[inline(always)]
    fn fill_stream(
        &mut self,
        pt: &PathTracer,
        tag: u32,
        path: &PathState,
        diffuse: Option<(Vec3, bool)>,
        (state, inc): (u64, u64),
    ) -> usize {
        debug_assert!(
            self.picks,
            "the lanes pick the light of the numbers they draw"
        );
        let k = self.fill_vertex(pt, tag, path, diffuse);
        self.lit.0[k] = true;
        self.draws.0[k] = true;
        self.rng_state[k] = state;
        self.rng_inc[k] = inc;
        k
    }

    /// Takes a vertex into the next lane: the path, the material's albedo and
    /// sidedness (`None`: from the vertex's table row, see [`DiffuseLanes::take_rows`]),
    /// and whether Russian roulette runs after it. Returns the lane.
    #[inline(always)]
    fn fill_vertex(
        &mut self,
        pt: &PathTracer,
        tag: u32,
        path: &PathState,
        diffuse: Option<(Vec3, bool)>,
    ) -> usize {
        let k = self.len;
        debug_assert!(k < LANES, "push into full lanes");
        self.len += 1;
        self.tag[k] = tag;
        self.from_row.0[k] = diffuse.is_none();
        if let Some((albedo, one_sided)) = diffuse {
            set3(&mut self.albedo, k, albedo);
            self.one_sided.0[k] = one_sided;
        }
        set3(&mut self.beta, k, path.beta.into());
        self.roulette.0[k] = path.depth >= pt.rr_depth;
        k
    }

    /// The numbers of the vertices whose numbers the lanes draw: those
    /// [`VertexSamples::draw`] takes from the independent sampler (its stream's next
    /// seven: the light's, the triangle's two, the direction's two, and two the lanes
    /// do not use), then Russian roulette's (the eighth) where it runs, as
    /// [`DiffuseLanes::fill`] would draw it; and the state that leaves. Each number is
    /// one jump from the vertex's state ([`Pcg32::draw`]), lane by lane (the compiler
    /// vectorises the loop: 64-bit products and a rotate per lane).
    #[inline(always)]
    fn draw_numbers(&mut self) {
        for i in 0..LANES {
            let (state, inc) = (self.rng_state[i], self.rng_inc[i]);
            let (draws, roulette) = (self.draws.0[i], self.roulette.0[i]);
            let u = |k: usize, kept: f32| match draws {
                true => Pcg32::draw(k, state, inc),
                false => kept,
            };
            self.u_light[i] = u(0, self.u_light[i]);
            self.u_triangle[0][i] = u(2, self.u_triangle[0][i]);
            self.u_triangle[1][i] = u(3, self.u_triangle[1][i]);
            self.u_dir[0][i] = u(5, self.u_dir[0][i]);
            self.u_dir[1][i] = u(6, self.u_dir[1][i]);
            self.u_rr[i] = u(7, self.u_rr[i]);
            let (seven, eight) = (
                Pcg32::state_after(7, state, inc),
                Pcg32::state_after(8, state, inc),
            );
            self.rng_out[i] = if roulette { eight } else { seven };
        }
    }

    /// [`DiffuseLanes::run`] out of line, compiled for AVX-512 (the renderer's tile is
    /// too): the kernel's code apart from the tile loop's.
    ///
    /// # Safety
    /// The processor must support AVX-512 F, VL, DQ and BW.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[inline(never)]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    pub(crate) unsafe fn run_avx512(&mut self, scene: &Scene, instances: &LaneInstances) {
        self.run(scene, instances)
    }

    /// [`DiffuseLanes::run`] out of line, compiled for the AVX2 tier (two 8-lane
    /// instructions per operation; no multiply-adds fused, so the results are still
    /// the scalar code's bit for bit).
    ///
    /// # Safety
    /// The processor must have the AVX2 tier (`crate::cpu::has_avx2`).
    #[cfg(target_arch = "x86_64")]
    #[inline(never)]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(crate) unsafe fn run_avx2(&mut self, scene: &Scene, instances: &LaneInstances) {
        self.run(scene, instances)
    }

    /// The light triangles' fields of every lane, from the table by their slots.
    #[inline(always)]
    fn take_table(&mut self) {
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        if crate::cpu::has_avx512() {
            // SAFETY: the processor supports AVX-512 F, VL, DQ and BW (checked above).
            return unsafe { self.take_table_avx512() };
        }
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2() {
            // SAFETY: the processor has the AVX2 tier (checked above).
            return unsafe { self.take_table_avx2() };
        }
        self.take_table_with(
            |table, slot| {
                let mut r = F::ZERO;
                for i in 0..LANES {
                    r[i] = table[slot[i] as usize % LANES];
                }
                r
            },
            index,
        );
    }

    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    unsafe fn take_table_avx512(&mut self) {
        // SAFETY: the caller guarantees AVX-512.
        self.take_table_with(
            |table, slot| unsafe { lookup_avx512(table, slot) },
            |v| unsafe { index_avx512(v) },
        );
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn take_table_avx2(&mut self) {
        // SAFETY: the caller guarantees the AVX2 tier.
        self.take_table_with(
            |table, slot| unsafe { lookup_avx2(table, slot) },
            |v| unsafe { index_avx2(v) },
        );
    }

    /// The corners, flags and albedo of the vertices `from_row`, from their triangles'
    /// rows in `rows` (the table of [`LaneInstances`]).
    #[inline(always)]
    fn take_rows(&mut self, rows: &[HitTriangle]) {
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        if crate::cpu::has_avx512() {
            // SAFETY: the processor supports AVX-512 F, VL, DQ and BW (checked above);
            // every row index pushed is in `rows`.
            return unsafe { self.take_rows_avx512(rows) };
        }
        for k in 0..self.len {
            if !self.from_row.0[k] {
                continue;
            }
            let t = &rows[self.hit_prim[k] as usize];
            for (c, &p) in t.p.iter().enumerate() {
                set3(&mut self.hit_corners[c], k, p);
            }
            set3(&mut self.albedo, k, t.albedo);
            self.one_sided.0[k] = t.flags & HitTriangle::ONE_SIDED != 0;
            self.flipped.0[k] = t.flags & HitTriangle::FLIPPED != 0;
            self.smooth.0[k] = t.flags & HitTriangle::SMOOTH != 0;
        }
    }

    /// [`DiffuseLanes::take_rows`] by a transpose: each lane's row (64 bytes, sixteen
    /// words) in one register, turned into sixteen registers of one word each (64
    /// permutes; sixteen-lane gathers, one per field, made a Cornell box render take 2%
    /// longer on Zen 4).
    ///
    /// # Safety
    /// The processor must support AVX-512F; `self.hit_prim` of the lanes `from_row` (among
    /// the first `len`) must index `rows`.
    // The AVX-512 intrinsics are newer than the MSRV; the build script compiles this
    // only with compilers that have them (`lightpath_avx512`).
    #[allow(clippy::incompatible_msrv)]
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    unsafe fn take_rows_avx512(&mut self, rows: &[HitTriangle]) {
        use std::arch::x86_64::*;
        const _: () = assert!(
            std::mem::size_of::<HitTriangle>() == 64,
            "a row is 16 words"
        );
        const ALBEDO: usize = std::mem::offset_of!(HitTriangle, albedo) / 4;
        const FLAGS: usize = std::mem::offset_of!(HitTriangle, flags) / 4;
        let mut mask = 0u16;
        for k in 0..self.len {
            mask |= (self.from_row.0[k] as u16) << k;
        }
        // SAFETY (intrinsics): AVX-512F (the caller); each load is one whole row of
        // `rows` (lanes not `mask` load the first, which exists since some lane is);
        // loads and stores of sixteen lanes.
        unsafe {
            let r: [__m512; 16] = std::array::from_fn(|k| {
                let row = if mask >> k & 1 != 0 {
                    self.hit_prim[k] as usize
                } else {
                    0
                };
                _mm512_loadu_ps(rows[row].p.as_ptr() as *const f32)
            });
            let words = transpose16(r);
            let take = |field: &mut F, word: usize| {
                let v = _mm512_mask_mov_ps(_mm512_loadu_ps(field.0.as_ptr()), mask, words[word]);
                _mm512_storeu_ps(field.0.as_mut_ptr(), v);
            };
            for c in 0..3 {
                for a in 0..3 {
                    take(&mut self.hit_corners[c][a], 3 * c + a);
                }
            }
            for a in 0..3 {
                take(&mut self.albedo[a], ALBEDO + a);
            }
            let flags = _mm512_castps_si512(words[FLAGS]);
            let bit = |b: u32| _mm512_test_epi32_mask(flags, _mm512_set1_epi32(b as i32));
            let (one_sided, flipped, smooth) = (
                bit(HitTriangle::ONE_SIDED),
                bit(HitTriangle::FLIPPED),
                bit(HitTriangle::SMOOTH),
            );
            for k in 0..LANES {
                if mask >> k & 1 != 0 {
                    self.one_sided.0[k] = one_sided >> k & 1 != 0;
                    self.flipped.0[k] = flipped >> k & 1 != 0;
                    self.smooth.0[k] = smooth >> k & 1 != 0;
                }
            }
        }
    }

    /// [`DiffuseLanes::take_table`] with `lookup(field, slots)` giving each lane's value.
    #[inline(always)]
    fn take_table_with(
        &mut self,
        lookup: impl Fn(F, &[u32; LANES]) -> F,
        index: impl Fn(F) -> [u32; LANES],
    ) {
        let Some(table) = self.table.as_deref() else {
            return;
        };
        if let Some(picks) = &table.picks {
            let (slot, pick, reachable) = picks.pick(
                &table.triangles,
                self.u_light,
                self.u_triangle[0],
                &lookup,
                &index,
            );
            (self.slot, self.pick, self.reachable) = (slot, pick, reachable);
        }
        let (slot, from, to) = (&self.slot, &table.triangles, &mut self.light);
        for c in 0..3 {
            for a in 0..3 {
                to.corners[c][a] = lookup(from.corners[c][a], slot);
            }
        }
        for c in 0..4 {
            for a in 0..3 {
                to.matrix[c][a] = lookup(from.matrix[c][a], slot);
            }
        }
        for a in 0..3 {
            to.light_n[a] = lookup(from.light_n[a], slot);
            to.radiance[a] = lookup(from.radiance[a], slot);
        }
        to.area_pdf = lookup(from.area_pdf, slot);
        to.cdf = [lookup(from.cdf[0], slot), lookup(from.cdf[1], slot)];
    }

    /// [`PathTracer::scatter`] for all the vertices pushed, in lanes (see the module
    /// notes); lanes not pushed compute garbage that nobody reads.
    #[inline(always)]
    pub(crate) fn run(&mut self, scene: &Scene, instances: &LaneInstances) {
        if self.draws.0[..self.len].contains(&true) {
            self.draw_numbers();
        }
        if self.from_row.0[..self.len].contains(&true) {
            self.take_rows(&instances.triangles);
        }
        if self.from_hit.0[..self.len].contains(&true) {
            self.interactions(scene);
        }
        if self.table.is_some() {
            self.take_table();
        }
        let (p, n, sn, tangent, wo) = (self.p, self.n, self.shading_n, self.dpdu, self.wo);
        let one_sided = self.one_sided;
        let zero = F::ZERO;
        // The shading frame (`frame_from_normal_and_tangent`).
        let d = dot(sn, tangent);
        let g = [
            tangent[0] - sn[0] * d,
            tangent[1] - sn[1] * d,
            tangent[2] - sn[2] * d,
        ];
        let len2 = dot(g, g);
        let gram = len2.is_finite() & len2.gt(1e-8 * dot(tangent, tangent)) & len2.gt(zero);
        let r = len2.sqrt();
        let s1 = [g[0] / r, g[1] / r, g[2] / r];
        let t1 = cross(sn, s1);
        // Else `Frame::from_normal`.
        let (s2, t2) = duff(sn);
        let s = select3(gram, s1, s2);
        let t = select3(gram, t1, t2);

        let wo_l = [dot(wo, s), dot(wo, t), dot(wo, sn)];
        let albedo = self.albedo;

        // Next-event estimation (`sample_flat_mesh` and `towards_area_point`).
        // `sample_reuse`: the offset in the triangle's cdf interval, clamped below 1.
        let [u0, uy] = self.u_triangle;
        let [c0, c1] = self.light.cdf;
        let ux = c1.gt(c0).select((u0 - c0) / (c1 - c0), zero);
        let ux = ux.lt(zero).select(zero, ux);
        let below_one = F::splat(1.0 - f32::EPSILON / 2.0);
        let ux = ux.gt(below_one).select(below_one, ux);
        let lower = ux.lt(uy);
        let (hx, hy) = (ux / 2.0, uy / 2.0);
        let b1 = lower.select(hx, ux - hy);
        let b2 = lower.select(uy - hx, hy);
        let b0 = 1.0 - b1 - b2;
        let [c0, c1, c2] = self.light.corners;
        let o = each!(c => c0[c] * b0 + c1[c] * b1 + c2[c] * b2);
        let m = self.light.matrix;
        // `transform_point3`'s order: x, then y and z added onto it, then the translation.
        let q = each!(c => m[3][c] + (m[2][c] * o[2] + (m[1][c] * o[1] + m[0][c] * o[0])));
        let light_n = self.light.light_n;
        let dq = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
        let dist2 = dot(dq, dq);
        let n_dot_d = dot(light_n, dq).abs();
        let area_dist2 = self.light.area_pdf * dist2;
        let inv_area_dist2 = 1.0 / area_dist2;
        let dist = dist2.sqrt();
        let inv_dist = 1.0 / dist;
        let inv_cos_light = dist / n_dot_d;
        let light_pdf = area_dist2 * inv_cos_light;
        let sampled = self.lit
            & !(dist2.eq(zero) | n_dot_d.eq(zero))
            & light_pdf.gt(zero)
            & light_pdf.is_finite();
        let wi = [dq[0] * inv_dist, dq[1] * inv_dist, dq[2] * inv_dist];
        let cos_light = n_dot_d * inv_dist;
        let front = dot(light_n, [-wi[0], -wi[1], -wi[2]]).gt(zero);
        let scale = cos_light * inv_area_dist2;
        let weight = each!(c => front.select(self.light.radiance[c], zero) * scale);
        let wi_l = [dot(wi, s), dot(wi, t), dot(wi, sn)];
        // The diffuse BSDF's value and density, one-sided where the material is (the
        // tests as `Diffuse` and `OneSided` write them, which NaN fails alike).
        let same_side = !(wo_l[2] * wi_l[2]).le(zero);
        let upper = !(wo_l[2].le(zero) | wi_l[2].le(zero));
        let reflects = same_side & (!one_sided | upper);
        let cos_i = wi_l[2].abs();
        let f = each!(c => reflects.select(albedo[c] * INV_PI * cos_i, zero));
        let bsdf_pdf = reflects.select(cos_i * INV_PI, zero);
        self.shadow = sampled & nonzero(f) & nonzero(weight);
        // `spawn_ray_to` the point on the light.
        let target = each!(c => p[c] + wi[c] * dist);
        let p_error = self.p_error;
        let to_target = [target[0] - p[0], target[1] - p[1], target[2] - p[2]];
        let origin = offset_origin(p, p_error, n, to_target);
        let pick = self.pick;
        let mis = self
            .reachable
            .select(power_heuristic(pick * light_pdf, bsdf_pdf), F::splat(1.0));
        let beta = self.beta;
        let share = mis / pick;
        for c in 0..3 {
            self.shadow_origin[c] = origin[c];
            self.shadow_direction[c] = target[c] - origin[c];
            self.contribution[c] = beta[c] * f[c] * weight[c] * share;
        }

        // BSDF sampling: the cosine-weighted hemisphere (`square_to_cosine_hemisphere`).
        let ox = 2.0 * self.u_dir[0] - 1.0;
        let oy = 2.0 * self.u_dir[1] - 1.0;
        let wide = ox.abs().gt(oy.abs());
        let (num, den) = (wide.select(oy, ox), wide.select(ox, oy));
        let (sin, cos) = sin_cos_quarter((PI / 4.0) * (num / den));
        let centre = ox.eq(zero) & oy.eq(zero);
        let dx = centre.select(zero, wide.select(ox * cos, oy * sin));
        let dy = centre.select(zero, wide.select(ox * sin, oy * cos));
        let z = (1.0 - (dx * dx + dy * dy)).max(zero).sqrt();
        let z = wo_l[2].lt(zero).select(-z, z);
        let pdf = z.abs() * INV_PI;
        let sampled = !(pdf.le(zero) | wo_l[2].eq(zero))
            & (!one_sided | (!wo_l[2].le(zero) & z.gt(zero)))
            & pdf.is_finite()
            & albedo[0].is_finite()
            & albedo[1].is_finite()
            & albedo[2].is_finite();
        let wi_w = each!(c => s[c] * dx + t[c] * dy + sn[c] * z);
        let beta = [
            beta[0] * albedo[0],
            beta[1] * albedo[1],
            beta[2] * albedo[2],
        ];
        let alive = !(beta[0].eq(zero) & beta[1].eq(zero) & beta[2].eq(zero))
            & beta[0].is_finite()
            & beta[1].is_finite()
            & beta[2].is_finite();
        let origin = offset_origin(p, p_error, n, wi_w);
        // Russian roulette (`max_element` as glam takes it: max(max(x, z), max(y, z))).
        let q = beta[0]
            .max(beta[2])
            .max(beta[1].max(beta[2]))
            .min(F::splat(0.95));
        let roulette = self.roulette;
        let survives = !roulette | !self.u_rr.ge(q);
        self.more = sampled & alive & survives;
        self.pdf = pdf;
        for c in 0..3 {
            self.ray_origin[c] = origin[c];
            self.ray_direction[c] = wi_w[c];
            self.beta_out[c] = roulette.select(beta[c] / q, beta[c]);
        }
    }

    /// The interactions of the vertices pushed as hits ([`TriangleMesh::interaction`]'s
    /// arithmetic, operation for operation, for meshes without texture coordinates).
    #[inline(always)]
    fn interactions(&mut self, scene: &Scene) {
        let zero = F::ZERO;
        let [c0, c1, c2] = self.hit_corners;
        let [b1, b2] = self.bary;
        let b0 = 1.0 - b1 - b2;
        let a0 = each!(c => c0[c] * b0);
        let a1 = each!(c => c1[c] * b1);
        let a2 = each!(c => c2[c] * b2);
        let p = each!(c => a0[c] + a1[c] + a2[c]);
        let g7 = gamma(7);
        let p_error = each!(c => g7 * (a0[c].abs() + a1[c].abs() + a2[c].abs()));
        let e1 = each!(c => c1[c] - c0[c]);
        let e2 = each!(c => c2[c] - c0[c]);
        let cr = cross(e1, e2);
        let len2 = dot(cr, cr);
        // Triangles without area take the f64 path below, one by one.
        let degenerate = !len2.gt(zero);
        let recip = 1.0 / len2.sqrt();
        let n = each!(c => cr[c] * recip);
        let n = select3(self.flipped, neg3(n), n);
        // Interpolated vertex normals, and the geometric normal turned to their side.
        let [n0, n1, n2] = self.hit_normals;
        let ns = each!(c => n0[c] * b0 + n1[c] * b1 + n2[c] * b2);
        let ns_len2 = dot(ns, ns);
        let smooth = self.smooth & ns_len2.gt(zero);
        let recip = 1.0 / ns_len2.sqrt();
        let sn = select3(smooth, each!(c => ns[c] * recip), n);
        let n = select3(smooth & dot(n, sn).lt(zero), neg3(n), n);
        // dp/du of the default parameterisation, else any tangent.
        let dc = cross(e1, n);
        let usable =
            e1[0].is_finite() & e1[1].is_finite() & e1[2].is_finite() & dot(dc, dc).ne(zero);
        let dpdu = select3(usable, e1, duff(n).0);
        let d = self.direction;
        let recip = 1.0 / dot(d, d).sqrt();
        let wo = each!(c => -(d[c] * recip));
        let take = self.from_hit;
        for (field, value) in [
            (&mut self.p, p),
            (&mut self.p_error, p_error),
            (&mut self.n, n),
            (&mut self.shading_n, sn),
            (&mut self.dpdu, dpdu),
            (&mut self.wo, wo),
        ] {
            *field = select3(take, value, *field);
        }
        for k in 0..self.len {
            if take.0[k] && degenerate.0[k] {
                let hit = ShapeHit {
                    t: self.hit_t[k],
                    prim: self.hit_prim[k],
                    uv: glam::Vec2::new(self.bary[0][k], self.bary[1][k]),
                };
                // The interaction reads only the ray's direction.
                let d = self.direction;
                let ray = Ray::new(Vec3::ZERO, Vec3::new(d[0][k], d[1][k], d[2][k]));
                let si = scene.merged_interaction(&ray, &hit);
                self.set_interaction(k, &si);
            }
        }
    }

    /// Hands each vertex's results to `done`, in the order pushed, and empties the
    /// lanes.
    #[inline(always)]
    pub(crate) fn finish(&mut self, mut done: impl FnMut(LaneResult)) {
        for k in 0..self.len {
            let get = |a: &F3| Vec3::new(a[0][k], a[1][k], a[2][k]);
            let query = ShadowQuery {
                ray: Ray::with_range(
                    get(&self.shadow_origin),
                    get(&self.shadow_direction),
                    0.0,
                    1.0 - crate::geometry::SHADOW_EPSILON,
                ),
                contribution: Vec3A::from(get(&self.contribution)),
            };
            let next = Next {
                prev: Previous {
                    p: get(&self.p),
                    bsdf_pdf: self.pdf[k],
                    delta: false,
                },
                ray: Ray::new(get(&self.ray_origin), get(&self.ray_direction)),
                beta: Vec3A::from(get(&self.beta_out)),
            };
            done(LaneResult {
                tag: self.tag[k],
                more: self.more.0[k],
                next,
                has_shadow: self.shadow.0[k],
                query,
                rng_state: self.draws.0[k].then_some(self.rng_out[k]),
            });
        }
        self.len = 0;
    }
}

#[inline(always)]
fn set3(a: &mut F3, k: usize, v: Vec3) {
    a[0][k] = v.x;
    a[1][k] = v.y;
    a[2][k] = v.z;
}

/// glam's dot product: x, then y, then z added.
#[inline(always)]
fn dot(a: F3, b: F3) -> F {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// glam's cross product (each component one product less another).
#[inline(always)]
fn cross(a: F3, b: F3) -> F3 {
    [
        a[1] * b[2] - b[1] * a[2],
        a[2] * b[0] - b[2] * a[0],
        a[0] * b[1] - b[0] * a[1],
    ]
}

/// [`crate::math::Frame::from_normal`]'s `s` and `t` (Duff et al.) for the unit `n`.
#[inline(always)]
fn duff(n: F3) -> (F3, F3) {
    let sign = F::splat(1.0).copysign(n[2]);
    let a = -1.0 / (sign + n[2]);
    let b = n[0] * n[1] * a;
    let s = [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
    let t = [b, sign + n[1] * n[1] * a, -n[1]];
    (s, t)
}

/// Where any component is not zero (or is NaN).
#[inline(always)]
fn nonzero(v: F3) -> M {
    v[0].ne(F::ZERO) | v[1].ne(F::ZERO) | v[2].ne(F::ZERO)
}

#[inline(always)]
fn neg3(v: F3) -> F3 {
    [-v[0], -v[1], -v[2]]
}

/// The albedo and sidedness of a material the lanes run: diffuse of constant albedo,
/// two-sided or one-sided.
#[inline(always)]
fn lane_diffuse(material: &Material) -> Option<(Vec3, bool)> {
    let constant = |m: &Material| match m {
        Material::Diffuse(d) => match &*d.albedo {
            Texture::Constant(c) => Some(*c),
            _ => None,
        },
        _ => None,
    };
    match material {
        Material::OneSided(o) => Some((constant(&o.inner)?, true)),
        m => Some((constant(m)?, false)),
    }
}

/// A vertex's light sample as the lanes take it.
enum LaneLight<'s> {
    /// No light is picked.
    None,
    /// A triangle of a flat constant mesh emitter: its sample, the light's pick
    /// probability, whether rays reach the light, and the light's index.
    Triangle(FlatTriangleSample<'s>, f32, bool, usize),
    /// The lanes pick the light and its triangle from the vertex's numbers when they
    /// run ([`LightPicks`]).
    Picked,
}

/// The light sample of a vertex with numbers `u` as the lanes take it, picked one by
/// one; `None` for lights the lanes do not run.
#[inline(always)]
fn lane_light<'s>(scene: &'s Scene, u: &VertexSamples) -> Option<LaneLight<'s>> {
    let Some((index, pick)) = scene.light_sampler.sample(u.u_light) else {
        return Some(LaneLight::None);
    };
    match &scene.lights[index] {
        Light::Area(a) => Some(LaneLight::Triangle(
            a.flat_constant_sample(u.u_point)?,
            pick,
            a.placed,
            index,
        )),
        _ => None,
    }
}

/// The triangles of a scene's lights that the lanes run (flat triangle meshes of
/// constant radiance, [`AreaLight::flat_constant_sample`]) where there are at most
/// [`LANES`] of them in all (a quad light has two): each of the fields
/// [`DiffuseLanes::fill`] would store per vertex, as one vector with slot `s` in lane
/// `s`. A vertex then stores only its triangle's slot, and [`DiffuseLanes::run`] takes
/// the fields of sixteen vertices with one permute each (a gather is slow on some
/// processors, Zen 4's among them), instead of thirty scalar stores per vertex.
#[derive(Debug)]
struct LightTable {
    /// Per scene light: the slot of its first triangle (unused for other lights).
    first: Vec<u32>,
    triangles: LightTriangles,
    /// Where every light of the scene is in the table: what picking one takes.
    picks: Option<LightPicks>,
}

/// Where all of a scene's lights are in the [`LightTable`] (and the light sampler picks
/// among them), the lanes pick each vertex's light and its triangle themselves, sixteen
/// at a time, from the numbers [`lane_light`] would pick them with and with the same
/// outcome: [`LightSampler::sample`](crate::light::LightSampler::sample) and
/// [`AreaLight::flat_constant_sample`](crate::light::AreaLight)'s cell of the light's
/// triangle distribution, each counted as the cdf values at or below the number, one
/// compare per value. A vertex then stores two numbers in place of its light's pick
/// (two searches of a distribution, whose branches mispredict where a number decides).
#[derive(Debug)]
struct LightPicks {
    /// The light sampler's cdf past its first value (0): `cdf[1..=n]` for `n` lights.
    cdf: Vec<f32>,
    /// Lane `i` for light `i`: its pick probability, the slot of its first triangle,
    /// its triangle count, and 1 where rays reach it (else 0).
    probability: F,
    first: F,
    count: F,
    reachable: F,
    /// The slots in use (triangles over all the lights).
    slots: usize,
}

impl LightPicks {
    /// Each lane's triangle slot, pick probability and reachability, for light numbers
    /// `u_light` and triangle numbers `u_triangle` (`lookup(field, index)`: each lane's
    /// value of `field` at its index, as [`DiffuseLanes::take_table_with`] takes it;
    /// `index`: lanes of small whole numbers as indices, as [`index`]).
    #[inline(always)]
    fn pick(
        &self,
        triangles: &LightTriangles,
        u_light: F,
        u_triangle: F,
        lookup: &impl Fn(F, &[u32; LANES]) -> F,
        index: &impl Fn(F) -> [u32; LANES],
    ) -> ([u32; LANES], F, M) {
        let (zero, one) = (F::ZERO, F::splat(1.0));
        // `Distribution1D::sample_discrete` counts the cdf values at or below `u`
        // (cdf[0] = 0 among them where u >= 0) and takes one less, at most n - 1: the
        // count of the values past the first, at most n - 1 (0 where u < 0 or NaN).
        let mut light = zero;
        for &c in &self.cdf {
            light = light + F::splat(c).le(u_light).select(one, zero);
        }
        let light = index(light.min(F::splat((self.cdf.len() - 1) as f32)));
        let pick = lookup(self.probability, &light);
        let first = lookup(self.first, &light);
        let count = lookup(self.count, &light);
        let reachable = lookup(self.reachable, &light).gt(zero);
        // The light's triangle: its cdf is the slots' lower bounds and its last slot's
        // upper bound; the cell is the count at or below `u` less one, in 0..count.
        let end = first + count;
        let mut at = zero;
        for s in 0..self.slots {
            let slot = F::splat(s as f32);
            let counted =
                slot.ge(first) & slot.lt(end) & F::splat(triangles.cdf[0][s]).le(u_triangle);
            at = at + counted.select(one, zero);
        }
        let last = lookup(triangles.cdf[1], &index(end - 1.0));
        at = at + last.le(u_triangle).select(one, zero);
        let cell = (at - 1.0).max(zero).min(count - 1.0);
        (index(first + cell), pick, reachable)
    }
}

/// The lanes' small whole numbers (held exactly as floats) as indices.
#[inline(always)]
fn index(v: F) -> [u32; LANES] {
    v.0.map(|v| v as u32)
}

/// [`index`] in one AVX-512 conversion (the compiler converts lane by lane, for the
/// saturation that `as` promises and that numbers this small never need).
#[allow(clippy::incompatible_msrv)]
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
#[inline(always)]
unsafe fn index_avx512(v: F) -> [u32; LANES] {
    use std::arch::x86_64::*;
    let mut r = [0u32; LANES];
    // SAFETY: AVX-512F (the caller); a load and a store of sixteen lanes.
    unsafe {
        let i = _mm512_cvttps_epi32(_mm512_loadu_ps(v.0.as_ptr()));
        _mm512_storeu_si512(r.as_mut_ptr() as *mut __m512i, i);
    }
    r
}

/// [`index_avx512`] in two AVX2 conversions.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn index_avx2(v: F) -> [u32; LANES] {
    use std::arch::x86_64::*;
    let mut r = [0u32; LANES];
    // SAFETY: AVX2 (the caller); loads and stores of eight lanes inside the arrays.
    unsafe {
        for half in 0..2 {
            let i = _mm256_cvttps_epi32(_mm256_loadu_ps(v.0.as_ptr().add(8 * half)));
            _mm256_storeu_si256(r.as_mut_ptr().add(8 * half) as *mut __m256i, i);
        }
    }
    r
}

/// Light triangles in lanes: what a light sample needs of its triangle
/// ([`FlatTriangleSample`]) but the numbers that place the point.
#[derive(Debug, Default)]
struct LightTriangles {
    corners: [F3; 3],
    light_n: F3,
    area_pdf: F,
    radiance: F3,
    /// Columns of the light's affine render-from-object matrix.
    matrix: [F3; 4],
    /// The triangle's cdf interval, where the number that picked it fell.
    cdf: [F; 2],
}

impl LightTriangles {
    /// Lane `k` holds triangle `t`.
    #[inline(always)]
    fn set(&mut self, k: usize, t: &FlatTriangleSample<'_>) {
        for (c, &corner) in self.corners.iter_mut().zip(t.p) {
            set3(c, k, corner);
        }
        set3(&mut self.light_n, k, t.n);
        self.area_pdf[k] = t.area_pdf;
        set3(&mut self.radiance, k, t.radiance);
        let m = t.render_from_object;
        for (c, col) in self
            .matrix
            .iter_mut()
            .zip([m.x_axis, m.y_axis, m.z_axis, m.w_axis])
        {
            set3(c, k, col.truncate());
        }
        self.cdf[0][k] = t.cdf.0;
        self.cdf[1][k] = t.cdf.1;
    }
}

impl LightTable {
    fn new(scene: &Scene) -> Option<LightTable> {
        let mut table = LightTable {
            first: vec![0; scene.lights.len()],
            triangles: LightTriangles::default(),
            picks: None,
        };
        // Whether every light is tabulated, with at least one triangle.
        let mut all = true;
        let (mut first, mut count, mut reachable) = (F::ZERO, F::ZERO, F::ZERO);
        let mut slot = 0;
        for (i, light) in scene.lights.iter().enumerate() {
            let triangles = match light {
                Light::Area(a) => a.flat_constant_triangles().map(|t| (t, a.placed)),
                _ => None,
            };
            let Some((triangles, placed)) = triangles else {
                all = false;
                continue;
            };
            if slot + triangles.len() > LANES {
                return None;
            }
            table.first[i] = slot as u32;
            // (At most LANES lights get here, each with a triangle, or the table is
            // given up above.)
            if i < LANES {
                first[i] = slot as f32;
                count[i] = triangles.len() as f32;
                reachable[i] = if placed { 1.0 } else { 0.0 };
            }
            all &= triangles.len() > 0;
            for t in triangles {
                table.triangles.set(slot, &t);
                slot += 1;
            }
        }
        let n = scene.lights.len();
        if let (true, Some(cdf)) = (all && n <= LANES, scene.light_sampler.distribution()) {
            let mut probability = F::ZERO;
            for i in 0..n {
                probability[i] = scene.light_sampler.probability(i);
            }
            table.picks = Some(LightPicks {
                cdf: (0..n).map(|i| cdf.cell_bounds(i).1).collect(),
                probability,
                first,
                count,
                reachable,
                slots: slot,
            });
        }
        (slot > 0).then_some(table)
    }
}

/// The transpose of a 16×16 matrix of words given as its rows: register `j` of the
/// result holds word `j` of every row, lane `i` from row `i` (unpacks within 128-bit
/// lanes, then shuffles of 128-bit lanes: 64 permutes).
// The AVX-512 intrinsics are newer than the MSRV; the build script compiles this only
// with compilers that have them (`lightpath_avx512`).
#[allow(clippy::incompatible_msrv)]
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
#[inline(always)]
unsafe fn transpose16(r: [std::arch::x86_64::__m512; 16]) -> [std::arch::x86_64::__m512; 16] {
    use std::arch::x86_64::*;
    // SAFETY: AVX-512F (the caller); register operations only.
    unsafe {
        // Rows 2i and 2i + 1 interleaved: per 128-bit lane q, words 4q, 4q + 1 of both
        // (`lo`) and words 4q + 2, 4q + 3 (`hi`).
        let lo: [__m512; 8] = std::array::from_fn(|i| _mm512_unpacklo_ps(r[2 * i], r[2 * i + 1]));
        let hi: [__m512; 8] = std::array::from_fn(|i| _mm512_unpackhi_ps(r[2 * i], r[2 * i + 1]));
        // Per four rows 4g..4g+3: `w[4g + j]` holds word 4q + j of the four rows in its
        // 128-bit lane q.
        let w: [__m512; 16] = std::array::from_fn(|k| {
            let (g, j) = (k / 4, k % 4);
            let (a, b) = if j < 2 {
                (lo[2 * g], lo[2 * g + 1])
            } else {
                (hi[2 * g], hi[2 * g + 1])
            };
            if j % 2 == 0 {
                _mm512_shuffle_ps::<0x44>(a, b)
            } else {
                _mm512_shuffle_ps::<0xee>(a, b)
            }
        });
        // Rows 0-7 and 8-15: `x[8h + j]` (j < 4) holds words j and j + 8 of rows 8h..8h+7
        // (128-bit lanes: rows 8h..8h+3's word j, its word j + 8, rows 8h+4..8h+7's word
        // j, its word j + 8); `x[8h + 4 + j]` words j + 4 and j + 12.
        let x: [__m512; 16] = std::array::from_fn(|k| {
            let (h, j) = (k / 8, k % 8);
            let (a, b) = (w[8 * h + j % 4], w[8 * h + 4 + j % 4]);
            if j < 4 {
                _mm512_shuffle_f32x4::<0x88>(a, b)
            } else {
                _mm512_shuffle_f32x4::<0xdd>(a, b)
            }
        });
        std::array::from_fn(|word| {
            let (j, high) = (word % 8, word >= 8);
            let (a, b) = (x[j], x[8 + j]);
            if high {
                _mm512_shuffle_f32x4::<0xdd>(a, b)
            } else {
                _mm512_shuffle_f32x4::<0x88>(a, b)
            }
        })
    }
}

/// Lane `i` of the result is `table`'s lane `slot[i]` (each below [`LANES`]), by one
/// AVX-512 permute.
// The AVX-512 intrinsics are newer than the MSRV; the build script enables this code
// only with compilers that have them (`lightpath_avx512`).
#[allow(clippy::incompatible_msrv)]
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
#[inline(always)]
unsafe fn lookup_avx512(table: F, slot: &[u32; LANES]) -> F {
    use std::arch::x86_64::*;
    let mut r = F::ZERO;
    // SAFETY: AVX-512F (the caller); loads and a store of sixteen lanes.
    unsafe {
        let index = _mm512_loadu_si512(slot.as_ptr() as *const __m512i);
        let v = _mm512_permutexvar_ps(index, _mm512_loadu_ps(table.0.as_ptr()));
        _mm512_storeu_ps(r.0.as_mut_ptr(), v);
    }
    r
}

/// [`lookup_avx512`] with AVX2: each half of the lanes picks from both halves of the
/// table and keeps the one its slot's bit 3 names.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lookup_avx2(table: F, slot: &[u32; LANES]) -> F {
    use std::arch::x86_64::*;
    let mut r = F::ZERO;
    // SAFETY: AVX2 (the caller); loads and stores of eight lanes inside the arrays.
    unsafe {
        let lo = _mm256_loadu_ps(table.0.as_ptr());
        let hi = _mm256_loadu_ps(table.0.as_ptr().add(8));
        for half in 0..2 {
            let index = _mm256_loadu_si256(slot.as_ptr().add(8 * half) as *const __m256i);
            let high = _mm256_castsi256_ps(_mm256_slli_epi32::<28>(index));
            let v = _mm256_blendv_ps(
                _mm256_permutevar8x32_ps(lo, index),
                _mm256_permutevar8x32_ps(hi, index),
                high,
            );
            _mm256_storeu_ps(r.0.as_mut_ptr().add(8 * half), v);
        }
    }
    r
}

#[inline(always)]
fn select3(c: M, a: F3, b: F3) -> F3 {
    [
        c.select(a[0], b[0]),
        c.select(a[1], b[1]),
        c.select(a[2], b[2]),
    ]
}

/// [`crate::math::offset_ray_origin`] in lanes.
#[inline(always)]
fn offset_origin(p: F3, p_error: F3, n: F3, w: F3) -> F3 {
    let d = dot([n[0].abs(), n[1].abs(), n[2].abs()], p_error);
    let flip = dot(w, n).lt(F::ZERO);
    each!(c => {
        let off = n[c] * d;
        let off = flip.select(-off, off);
        (p[c] + off).lanewise(off, round_away)
    })
}

/// [`super::power_heuristic`] in lanes.
#[inline(always)]
fn power_heuristic(pdf_a: F, pdf_b: F) -> F {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    let sum = a + b;
    sum.eq(F::ZERO)
        .select(F::ZERO, a.is_infinite().select(F::splat(1.0), a / sum))
}

/// `warp`'s polynomial sine and cosine for `|x| ≤ π/4`, the same operations.
#[inline(always)]
fn sin_cos_quarter(x: F) -> (F, F) {
    let x2 = x * x;
    let sin = x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0))));
    let cos = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0))));
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::MeshHits;
    use crate::io::{load_scene_str, LoadOptions};
    use crate::material::{Conductor, Diffuse};
    use crate::sampling::{IndependentSampler, Pcg32};
    use glam::{UVec2, Vec2};
    use std::path::Path;
    use std::sync::Arc;

    /// A Mitsuba scene of one-sided diffuse quads (one with the light behind it, one
    /// mirrored, one with vertex normals) lit by a flat emitting quad (and, when
    /// `point`, also a point light, which the lanes leave to `scatter`).
    /// Writes an OBJ file at `path` of a strip of `n` quads (2n triangles) of growing
    /// size, at height `y`; returns its path.
    fn strip(path: &Path, n: usize, y: f32) -> String {
        let mut obj = String::new();
        for i in 0..n {
            let (x0, x1) = (i as f32, i as f32 + 0.5 + 0.1 * i as f32);
            for (x, z) in [(x0, 0.0), (x1, 0.0), (x1, 1.0), (x0, 1.0)] {
                obj += &format!("v {x} {y} {z}\n");
            }
            let k = 4 * i + 1;
            obj += &format!("f {} {} {}\nf {} {} {}\n", k, k + 1, k + 2, k, k + 2, k + 3);
        }
        std::fs::write(path, obj).unwrap();
        path.display().to_string()
    }

    /// The lights' triangles are tabulated, each with its own fields, where they are at
    /// most sixteen in all (over every light), and not beyond.
    #[test]
    fn light_table_holds_up_to_sixteen_triangles() {
        let dir = std::env::temp_dir().join(format!("lightpath-table-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let strip = |name: &str, n: usize, y: f32| strip(&dir.join(name), n, y);
        for (a, b) in [(3, 5), (4, 4), (4, 5), (9, 0)] {
            let (first, second) = (strip("a.obj", a, 2.0), strip("b.obj", b.max(1), 3.0));
            let emitter =
                r#"<emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>"#;
            let second = if b > 0 {
                format!(r#"<shape type="obj" filename="{second}">{emitter}</shape>"#)
            } else {
                String::new()
            };
            let xml = format!(
                r#"<scene version="3.0.0">
                    <sensor type="perspective"/>
                    <shape type="obj" filename="{first}">{emitter}</shape>
                    {second}
                    <emitter type="point"><point name="position" x="0" y="1" z="0"/></emitter>
                </scene>"#
            );
            let l = load_scene_str(&xml, Path::new("table.xml"), &LoadOptions::default()).unwrap();
            let scene = &l.scene;
            let lanes = DiffuseLanes::new(scene);
            let triangles = 2 * (a + b);
            assert_eq!(lanes.table.is_some(), triangles <= LANES, "{a} + {b} quads");
            let Some(table) = &lanes.table else { continue };
            let mut slots = 0;
            for (i, light) in scene.lights.iter().enumerate() {
                let Light::Area(area) = light else { continue };
                for t in area.flat_constant_triangles().unwrap() {
                    let s = table.first[i] as usize + t.prim;
                    assert_eq!(table.triangles.area_pdf[s], t.area_pdf);
                    assert_eq!(
                        (table.triangles.cdf[0][s], table.triangles.cdf[1][s]),
                        t.cdf
                    );
                    for c in 0..3 {
                        let corner = [0, 1, 2].map(|a| table.triangles.corners[c][a][s]);
                        assert_eq!(corner, t.p[c].to_array());
                    }
                    assert_eq!(
                        [0, 1, 2].map(|a| table.triangles.light_n[a][s]),
                        t.n.to_array()
                    );
                    slots += 1;
                }
            }
            assert_eq!(slots, triangles);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Where every light of a scene is tabulated, the lanes pick each vertex's light and
    /// its triangle themselves ([`LightPicks`]), exactly as [`lane_light`] picks them
    /// one by one: over lights of different powers and triangle counts, at random
    /// numbers and at the cdfs' own values and their neighbours. A point light among the
    /// lights, or lights of more triangles than the table holds, keep the pick one by one.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[test]
    fn transpose16_transposes() {
        if !crate::cpu::has_avx512() {
            return;
        }
        use std::arch::x86_64::*;
        let m: [[f32; 16]; 16] =
            std::array::from_fn(|i| std::array::from_fn(|j| (16 * i + j) as f32));
        // SAFETY: AVX-512F (checked above); loads and stores of sixteen lanes.
        let t = unsafe {
            let out = transpose16(std::array::from_fn(|i| _mm512_loadu_ps(m[i].as_ptr())));
            let mut t = [[0.0f32; 16]; 16];
            for (row, v) in t.iter_mut().zip(out) {
                _mm512_storeu_ps(row.as_mut_ptr(), v);
            }
            t
        };
        for i in 0..16 {
            for j in 0..16 {
                assert_eq!(t[j][i], m[i][j], "word {j} of row {i}");
            }
        }
    }

    #[test]
    fn lanes_pick_lights_as_one_by_one() {
        let dir = std::env::temp_dir().join(format!("lightpath-picks-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let strip = |name: &str, n: usize, y: f32| strip(&dir.join(name), n, y);
        let lookup = |table: F, slot: &[u32; LANES]| {
            let mut r = F::ZERO;
            for i in 0..LANES {
                r[i] = table[slot[i] as usize % LANES];
            }
            r
        };
        let mut rng = Pcg32::new(5, 7);
        let cases: [(&[usize], bool); 6] = [
            (&[1], false),
            (&[3, 1, 2], false),
            (&[1; 8], false),
            (&[2, 1, 4, 1], false),
            (&[2, 2], true),
            (&[5, 4], false),
        ];
        for (sizes, point) in cases {
            let mut shapes = String::new();
            for (k, &n) in sizes.iter().enumerate() {
                let file = strip(&format!("light{k}.obj"), n, 2.0 + k as f32);
                shapes += &format!(
                    r#"<shape type="obj" filename="{file}"><emitter type="area">
                        <rgb name="radiance" value="{}, 1, 2"/></emitter></shape>"#,
                    1.0 + 0.7 * k as f32
                );
            }
            let point = if point {
                r#"<emitter type="point"><point name="position" x="0" y="1" z="0"/></emitter>"#
            } else {
                ""
            };
            let xml = format!(
                r#"<scene version="3.0.0"><sensor type="perspective"/>{shapes}{point}</scene>"#
            );
            let l = load_scene_str(&xml, Path::new("picks.xml"), &LoadOptions::default()).unwrap();
            let scene = &l.scene;
            let lanes = DiffuseLanes::new(scene);
            let triangles: usize = 2 * sizes.iter().sum::<usize>();
            let fits = triangles <= LANES;
            assert_eq!(lanes.picks, fits && point.is_empty(), "{sizes:?}");
            if !lanes.picks {
                continue;
            }
            let table = lanes.table.as_deref().unwrap();
            let picks = table.picks.as_ref().unwrap();
            assert_eq!(picks.cdf.len(), sizes.len());
            // Random numbers, and the cdfs' values with their neighbours on each side.
            let mut us: Vec<Vec2> = (0..4000)
                .map(|_| Vec2::new(rng.next_f32(), rng.next_f32()))
                .collect();
            let cdfs = picks
                .cdf
                .iter()
                .chain(&table.triangles.cdf[0].0[..triangles]);
            for &c in cdfs {
                let around = [
                    c,
                    f32::from_bits(c.to_bits() + 1),
                    f32::from_bits(c.to_bits().max(1) - 1),
                ];
                for v in around.into_iter().filter(|v| (0.0..1.0).contains(v)) {
                    us.extend([
                        Vec2::new(v, rng.next_f32()),
                        Vec2::new(rng.next_f32(), v),
                        Vec2::splat(v),
                    ]);
                }
            }
            let mut seen = vec![false; triangles];
            for chunk in us.chunks(LANES) {
                let (mut u_light, mut u_triangle) = (F::ZERO, F::ZERO);
                for (i, u) in chunk.iter().enumerate() {
                    (u_light[i], u_triangle[i]) = (u.x, u.y);
                }
                let (slot, pick, reachable) =
                    picks.pick(&table.triangles, u_light, u_triangle, &lookup, &index);
                for (i, u) in chunk.iter().enumerate() {
                    let vertex = VertexSamples {
                        u_light: u.x,
                        u_prim: 0.5,
                        u_point: Vec2::new(u.y, 0.5),
                        u_lobe: 0.5,
                        u_dir: Vec2::splat(0.5),
                    };
                    let Some(LaneLight::Triangle(t, p, r, light)) = lane_light(scene, &vertex)
                    else {
                        panic!("no triangle picked at {u}");
                    };
                    let want = table.first[light] + t.prim as u32;
                    assert_eq!(slot[i], want, "{sizes:?} at {u}");
                    assert_eq!(pick[i].to_bits(), p.to_bits());
                    assert_eq!(reachable.0[i], r);
                    seen[want as usize] = true;
                }
            }
            assert!(
                seen.iter().all(|&s| s),
                "{sizes:?}: every triangle is picked"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn scene(point: bool) -> crate::io::LoadedScene {
        // A folder per call: tests run in parallel, and each removes its folder.
        static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir =
            std::env::temp_dir().join(format!("lightpath-lanes-{}-{call}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Quads; `bent` ones carry vertex normals tilted off the face, on the side
        // opposite their winding's normal.
        let quad_with = |name: &str, corners: [[f32; 3]; 4], bent: bool| {
            let mut obj = String::new();
            for c in corners {
                obj += &format!("v {} {} {}\n", c[0], c[1], c[2]);
            }
            if bent {
                obj += "vn 0.3 1 0\nvn -0.2 1 0.1\nvn 0 1 -0.4\nvn 0.1 0.9 0.2\n";
                obj += "f 1//1 2//2 3//3\nf 1//1 3//3 4//4\n";
            } else {
                obj += "f 1 2 3\nf 1 3 4\n";
            }
            let path = dir.join(name);
            std::fs::write(&path, obj).unwrap();
            path.display().to_string()
        };
        let quad = |name: &str, corners: [[f32; 3]; 4]| quad_with(name, corners, false);
        let shelf = quad_with(
            "shelf.obj",
            [
                [-0.9, 0.8, -0.9],
                [0.2, 0.8, -0.9],
                [0.2, 0.7, 0.2],
                [-0.9, 0.7, 0.2],
            ],
            true,
        );
        let floor = quad(
            "floor.obj",
            [[-1., 0., -1.], [-1., 0., 1.], [1., 0., 1.], [1., 0., -1.]],
        );
        let wall = quad(
            "wall.obj",
            [
                [-1., 0., -1.],
                [1., 0., -1.],
                [1., 2., -0.6],
                [-1., 2., -0.6],
            ],
        );
        // Facing down, over the light: seen from above, the light is behind it.
        let roof = quad(
            "roof.obj",
            [
                [-1., 2.2, -1.],
                [1., 2.2, -1.],
                [1., 2.2, 1.],
                [-1., 2.2, 1.],
            ],
        );
        let light = quad(
            "light.obj",
            [
                [-0.3, 1.9, -0.3],
                [0.3, 1.9, -0.3],
                [0.3, 1.9, 0.3],
                [-0.3, 1.9, 0.3],
            ],
        );
        let point = if point {
            r#"<emitter type="point"><point name="position" x="0.5" y="1.5" z="0.5"/><rgb name="intensity" value="0.5"/></emitter>"#
        } else {
            ""
        };
        let xml = format!(
            r#"<scene version="3.0.0">
                <sensor type="perspective"/>
                <shape type="obj" filename="{floor}"><bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.5, 0.3"/></bsdf></shape>
                <shape type="obj" filename="{wall}">
                    <bsdf type="diffuse"/>
                    <transform name="to_world"><scale x="-1"/></transform>
                </shape>
                <shape type="obj" filename="{shelf}"><bsdf type="diffuse"/></shape>
                <shape type="obj" filename="{roof}"><bsdf type="diffuse"/></shape>
                <shape type="obj" filename="{light}">
                    <emitter type="area"><rgb name="radiance" value="9, 8, 7"/></emitter>
                </shape>
                {point}
            </scene>"#
        );
        let l = load_scene_str(&xml, Path::new("lanes.xml"), &LoadOptions::default()).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        l
    }

    /// Per vertex: what `scatter` gave (path, shadow ray, whether it goes on), and the
    /// path and sampler as the lanes took them.
    /// A vertex in lanes: `step`'s path, shadow ray, outcome and sampler, and the path
    /// and sampler the lanes took it from.
    type Pending = (
        PathState,
        Option<ShadowQuery>,
        bool,
        Sampler,
        PathState,
        Sampler,
    );

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    fn ray_bits(r: &Ray) -> ([u32; 3], [u32; 3], u32, u32) {
        (
            bits(r.origin),
            bits(r.direction),
            r.t_min.to_bits(),
            r.t_max.to_bits(),
        )
    }

    /// A ray from inside the box or outside it (surfaces seen from behind): origin and
    /// unit direction.
    fn random_ray(rng: &mut Pcg32) -> (Vec3, Vec3) {
        let origin = Vec3::new(
            rng.next_f32() * 2.4 - 1.2,
            rng.next_f32() * 3.0 - 0.5,
            rng.next_f32() * 2.4 - 1.2,
        );
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        (origin, crate::sampling::warp::square_to_uniform_sphere(u))
    }

    /// Runs the lanes and compares each vertex's results with `scatter`'s or `step`'s.
    fn run_and_compare(
        lanes: &mut DiffuseLanes,
        scene: &Scene,
        instances: &LaneInstances,
        pending: &mut Vec<Pending>,
    ) {
        lanes.run(scene, instances);
        lanes.finish(|r| {
            let (want, want_shadow, want_more, want_sampler, path, sampler) =
                &mut pending[r.tag as usize];
            let more = r.apply(path);
            assert_same(path, more, &r.shadow(), want, *want_more, want_shadow);
            // A path that goes on has its sampler where `step` left it (where the lanes
            // drew its numbers, once given the state they leave).
            if let Some(state) = r.rng_state() {
                sampler.independent_rng().unwrap().set_state(state);
            }
            if *want_more {
                let next = |s: &Sampler| s.clone().next_1d().to_bits();
                assert_eq!(next(sampler), next(want_sampler));
            }
        });
        pending.clear();
    }

    /// Asserts that a path and its vertex's results equal `step`'s, bit for bit (what a
    /// path that ended holds no longer matters).
    fn assert_same(
        path: &PathState,
        more: bool,
        shadow: &Option<ShadowQuery>,
        want: &PathState,
        want_more: bool,
        want_shadow: &Option<ShadowQuery>,
    ) {
        assert_eq!(more, want_more);
        assert_eq!(bits(path.l.into()), bits(want.l.into()));
        if more {
            assert_eq!(ray_bits(&path.ray), ray_bits(&want.ray));
            assert_eq!(bits(path.beta.into()), bits(want.beta.into()));
            assert_eq!(path.depth, want.depth);
            let (p, q) = (path.prev.unwrap(), want.prev.unwrap());
            assert_eq!(
                (bits(p.p), p.bsdf_pdf.to_bits()),
                (bits(q.p), q.bsdf_pdf.to_bits())
            );
        }
        assert_eq!(shadow.is_some(), want_shadow.is_some());
        if let (Some(a), Some(b)) = (shadow, want_shadow) {
            assert_eq!(ray_bits(&a.ray), ray_bits(&b.ray));
            assert_eq!(bits(a.contribution.into()), bits(b.contribution.into()));
        }
    }

    /// Vertices in lanes get exactly what `scatter` gives them (next ray, throughput,
    /// previous vertex, depth, shadow ray and its light), for one- and two-sided diffuse
    /// surfaces seen from both sides, with and without Russian roulette; the lanes take
    /// no vertex whose material or picked light they cannot run.
    #[test]
    fn lanes_equal_scatter() {
        let pt = PathTracer {
            max_depth: 8,
            rr_depth: 2,
            clamp: None,
            hide_emitters: false,
        };
        // Lanes with the light's triangles tabulated and without.
        for (point, tabulated) in [(false, true), (true, true), (false, false), (true, false)] {
            let l = scene(point);
            let scene = &l.scene;
            let one_sided = scene.instances[0].material.clone().unwrap();
            assert!(matches!(&*one_sided, Material::OneSided(_)));
            let two_sided = Material::Diffuse(Diffuse {
                albedo: Arc::new(Texture::Constant(Vec3::new(0.2, 0.9, 0.6))),
            });
            let conductor = Material::Conductor(Conductor {
                reflectance: Arc::new(Texture::Constant(Vec3::ONE)),
                ior: None,
            });
            let mut rng = Pcg32::new(7, point as u64);
            let mut lanes = if tabulated {
                DiffuseLanes::new(scene)
            } else {
                DiffuseLanes::untabulated()
            };
            assert_eq!(lanes.table.is_some(), tabulated);
            let instances = LaneInstances::new(scene);
            let (mut taken, mut refused, mut shadows, mut ended) = (0, 0, 0, 0);
            let mut pending: Vec<Pending> = Vec::new();
            let check = |lanes: &mut DiffuseLanes, pending: &mut Vec<Pending>| {
                run_and_compare(lanes, scene, &instances, pending)
            };
            for trial in 0..6000 {
                let (origin, dir) = random_ray(&mut rng);
                let Some(si) = scene.intersect(&Ray::new(origin, dir)) else {
                    continue;
                };
                let material: &Material = match trial % 5 {
                    0 | 1 => &one_sided,
                    2 | 3 => &two_sided,
                    _ => &conductor,
                };
                let mut path = PathState::new(&Ray::new(origin, dir));
                path.beta = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0;
                path.depth = 1 + trial % 4;
                let mut sampler = Sampler::Independent(IndependentSampler::new(16, 5));
                sampler.start_pixel_sample(UVec2::new(trial, 3), 1);
                let u = VertexSamples::draw(&mut sampler);
                let mut want = path;
                let mut want_sampler = sampler.clone();
                let mut want_shadow = None;
                let want_more = pt.scatter(
                    scene,
                    &mut want,
                    &si,
                    material,
                    &u,
                    &mut want_sampler,
                    &mut want_shadow,
                );
                let tag = pending.len() as u32;
                let before = sampler.clone();
                if !lanes.push(&pt, scene, tag, &path, &si, material, &u, &mut sampler) {
                    refused += 1;
                    // Nothing drawn: the vertex can still take `scatter`.
                    assert_eq!(sampler.next_1d(), before.clone().next_1d());
                    continue;
                }
                taken += 1;
                shadows += want_shadow.is_some() as u32;
                ended += !want_more as u32;
                if want_more {
                    // The lanes drew what `scatter` drew.
                    assert_eq!(sampler.next_1d(), want_sampler.next_1d());
                }
                pending.push((want, want_shadow, want_more, want_sampler, path, sampler));
                if lanes.is_full() {
                    check(&mut lanes, &mut pending);
                }
            }
            if lanes.len() > 0 {
                check(&mut lanes, &mut pending);
            }
            assert!(taken > 800, "{taken} vertices in lanes");
            assert!(refused > 300, "{refused} refused");
            assert!(
                shadows > 300 && ended > 50,
                "{shadows} shadow rays, {ended} ended"
            );
        }
    }

    /// The lanes' whole vertex ([`DiffuseLanes::step`]: hits on the merged mesh whose
    /// interactions the lanes build, emitters, misses, the depth limit, and the vertices
    /// left to `scatter`) gives every path exactly what [`PathTracer::step`] gives it.
    #[test]
    fn lanes_step_equals_step() {
        let pt = PathTracer {
            max_depth: 5,
            rr_depth: 3,
            clamp: None,
            hide_emitters: false,
        };
        // Lanes with the light's triangles tabulated and without, and the hit triangles
        // (`LaneInstances`) tabulated and without.
        for (point, tabulated, hits_tabulated) in [
            (false, true, true),
            (false, true, false),
            (true, true, true),
            (false, false, false),
            (true, false, true),
        ] {
            let l = scene(point);
            let scene = &l.scene;
            let mut rng = Pcg32::new(8, point as u64);
            let mut lanes = if tabulated {
                DiffuseLanes::new(scene)
            } else {
                DiffuseLanes::untabulated()
            };
            assert_eq!(lanes.table.is_some(), tabulated);
            // The lanes pick the light themselves where it is the only one.
            assert_eq!(lanes.picks, tabulated && !point);
            let instances = if hits_tabulated {
                LaneInstances::new(scene)
            } else {
                LaneInstances::untabulated(scene)
            };
            assert_eq!(instances.triangles.is_empty(), !hits_tabulated);
            // The shelf's bent normals are tabulated too.
            assert_eq!(instances.normals.is_empty(), !hits_tabulated);
            let (mut taken, mut direct) = (0, 0);
            let mut pending: Vec<Pending> = Vec::new();
            let check = |lanes: &mut DiffuseLanes, pending: &mut Vec<Pending>| {
                run_and_compare(lanes, scene, &instances, pending)
            };
            for trial in 0..6000u32 {
                let (origin, dir) = random_ray(&mut rng);
                let dir = dir * (0.5 + rng.next_f32());
                let ray = Ray::new(origin, dir);
                let mut hits = MeshHits::default();
                scene.intersect_merged(&[ray], &mut hits, &mut Default::default());
                let hit = hits.get(0);
                let mut path = PathState::new(&ray);
                path.beta = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0;
                path.depth = 1 + trial % 5;
                if trial % 3 > 0 {
                    path.prev = Some(Previous {
                        p: origin,
                        bsdf_pdf: rng.next_f32(),
                        delta: trial % 7 == 0,
                    });
                }
                let mut sampler = Sampler::Independent(IndependentSampler::new(16, 5));
                sampler.start_pixel_sample(UVec2::new(trial, 4), 2);
                let (mut want, mut want_sampler, mut want_shadow) = (path, sampler.clone(), None);
                let si = hit.map(|h| scene.merged_interaction(&ray, &h));
                let want_more = pt.step(scene, &mut want, si, &mut want_sampler, &mut want_shadow);
                let tag = pending.len() as u32;
                let mut shadow = None;
                match lanes.step(
                    &pt,
                    scene,
                    &instances,
                    tag,
                    &mut path,
                    hit,
                    &mut sampler,
                    &mut shadow,
                ) {
                    Some(more) => {
                        direct += 1;
                        assert_same(&path, more, &shadow, &want, want_more, &want_shadow);
                    }
                    None => {
                        taken += 1;
                        pending.push((want, want_shadow, want_more, want_sampler, path, sampler));
                        if lanes.is_full() {
                            check(&mut lanes, &mut pending);
                        }
                    }
                }
            }
            if lanes.len() > 0 {
                check(&mut lanes, &mut pending);
            }
            assert!(
                taken > 1000 && direct > 1000,
                "{taken} in lanes, {direct} not"
            );
        }
    }
}
