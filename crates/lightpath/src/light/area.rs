//! Area lights: any shape instance with an `<emission>` emits light from its surface and is
//! sampled by next-event estimation, by area in general and by solid angle for spheres
//! (uniform cone sampling when the instance's transform keeps it a sphere).
//!
//! ```xml
//! <instance>
//!     <shape type="rectangle"/>
//!     <emission type="lambertian">
//!         <texture name="emission" type="constant" value="10"/>
//!     </emission>
//!     <transform><rotate axis="1,0,0" angle="-90"/><translate y="-0.98"/></transform>
//! </instance>
//! ```
//!
//! `lambertian` emission is one-sided: the surface emits its texture's radiance only to
//! the side its shading normal points to.
//!
//! A mesh cut by an alpha mask emits only where it is there, as rays find it (pbrt-v4's
//! rule): next-event estimation still picks points over the whole triangles, with the
//! same density, and weights each by the mask's coverage there (0 in a cut-out hole, α
//! for stochastic transparency), so it agrees with the light that BSDF-sampled rays
//! meet.

use super::LightSample;
use crate::geometry::{Shape, SurfaceInteraction, TriangleMesh};
use crate::math::{Transform, PI};
use crate::sampling::Distribution1D;
use crate::texture::Texture;
use glam::{Mat3, Mat4, Vec2, Vec3};
use std::sync::Arc;

/// Lambertian (constant radiance) emission, one-sided.
#[derive(Debug, Clone)]
pub struct Emission {
    pub radiance: Arc<Texture>,
}

impl Emission {
    /// Radiance leaving the surface at `si` in the unit direction `w`.
    #[inline]
    pub fn eval(&self, si: &SurfaceInteraction, w: Vec3) -> Vec3 {
        self.eval_at(si.shading_n, si.tex(), w)
    }

    /// Radiance leaving a point with unit shading normal `shading_n` and texture
    /// coordinates `uv` (or a [`crate::texture::TexCoord`]) in the unit direction `w`.
    #[inline]
    pub fn eval_at(
        &self,
        shading_n: Vec3,
        uv: impl Into<crate::texture::TexCoord>,
        w: Vec3,
    ) -> Vec3 {
        if shading_n.dot(w) > 0.0 {
            self.radiance.eval(uv)
        } else {
            Vec3::ZERO
        }
    }
}

/// A flat-shaded triangle mesh emitter set up for sampling: what `sample` needs of each
/// triangle (its object-space corners and texture coordinates, its render-space normal
/// and area density), so that a light sample costs a triangle pick, a barycentric warp
/// and one point transform instead of a full interaction moved to render space. The
/// values are those the general path computes, bit for bit.
#[derive(Debug, Clone)]
struct FlatMeshEmitter {
    /// Triangles in proportion to their object-space area (the mesh's own distribution).
    distribution: Distribution1D,
    triangles: Vec<EmitterTriangle>,
    /// The radiance where it is constant and the transform affine: the lights whose
    /// samples run many at once ([`AreaLight::flat_constant_sample`]).
    constant_radiance: Option<Vec3>,
}

#[derive(Debug, Clone, Copy)]
struct EmitterTriangle {
    /// Object-space corners.
    p: [Vec3; 3],
    /// Texture coordinates of the corners.
    uv: [Vec2; 3],
    /// Render-space unit geometric normal (also the shading normal: the mesh is flat).
    n: Vec3,
    /// Render-space area density of the triangle's points.
    area_pdf: f32,
}

impl FlatMeshEmitter {
    /// `None` for meshes with interpolated normals (the general path handles them) and
    /// for meshes without area.
    fn new(m: &TriangleMesh, render_from_object: &Transform, light: &AreaLight) -> Option<Self> {
        if m.smooth && !m.normals.is_empty() {
            return None;
        }
        let distribution = m.area_distribution().clone();
        let area = m.area();
        if distribution.is_empty() || area.is_nan() || area <= 0.0 {
            return None;
        }
        let ray = crate::math::Ray::new(Vec3::ZERO, Vec3::Z);
        let triangles = (0..m.triangle_count() as u32)
            .map(|prim| {
                let (p0, p1, p2) = m.vertices(prim);
                let uv = if m.uvs.is_empty() {
                    [Vec2::ZERO, Vec2::X, Vec2::ONE]
                } else {
                    let [i0, i1, i2] = m.indices[prim as usize];
                    [m.uvs[i0 as usize], m.uvs[i1 as usize], m.uvs[i2 as usize]]
                };
                // The normal as the general path finds it: the mesh's interaction (constant
                // over a flat triangle) moved to render space.
                let hit = crate::geometry::ShapeHit {
                    t: 1.0,
                    prim,
                    uv: Vec2::splat(1.0 / 3.0),
                };
                let n = m.interaction(&ray, &hit).transformed(render_from_object).n;
                EmitterTriangle {
                    p: [p0, p1, p2],
                    uv,
                    n,
                    area_pdf: light.render_area_pdf(1.0 / area, n),
                }
            })
            .collect();
        Some(FlatMeshEmitter {
            distribution,
            triangles,
            constant_radiance: match &*light.emission.radiance {
                Texture::Constant(radiance) if render_from_object.is_affine() => Some(*radiance),
                _ => None,
            },
        })
    }
}

/// The sample of light arriving at `p` from the point `q` of an emitter with unit normal
/// `n`, drawn with area density `area_pdf`; `le(w)` is the radiance leaving `q` in the unit
/// direction `w`. The solid-angle density is `area_pdf · dist² / cos θ_light`.
///
/// Written so that its divisions wait only on the distance's square root, not on each
/// other (this runs at every path vertex): `1/(area_pdf · dist²)` starts alongside the
/// root, then `1/dist` and `dist/|n·d|` together.
#[inline(always)]
fn towards_area_point(
    p: Vec3,
    q: Vec3,
    n: Vec3,
    area_pdf: f32,
    le: impl FnOnce(Vec3) -> Vec3,
) -> Option<LightSample> {
    let d = q - p;
    let dist2 = d.length_squared();
    let n_dot_d = n.dot(d).abs();
    if dist2 == 0.0 || n_dot_d == 0.0 {
        return None;
    }
    let area_dist2 = area_pdf * dist2;
    let inv_area_dist2 = 1.0 / area_dist2;
    let dist = dist2.sqrt();
    let inv_dist = 1.0 / dist;
    let inv_cos_light = dist / n_dot_d;
    let pdf = area_dist2 * inv_cos_light;
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    let wi = d * inv_dist;
    let cos_light = n_dot_d * inv_dist;
    Some(LightSample {
        wi,
        distance: dist,
        weight: le(-wi) * (cos_light * inv_area_dist2),
        pdf,
    })
}

/// One triangle of a flat, constant emitter as [`AreaLight::sample`] picks it with
/// numbers `u`: the point is `render_from_object` applied to the corners `p` weighted by
/// [`crate::sampling::warp::square_to_uniform_triangle`] of (`u.x`'s offset in the
/// triangle's cdf interval `cdf`, clamped below 1, and `u.y`), as
/// [`Distribution1D::sample_reuse`] reuses `u.x`.
pub(crate) struct FlatTriangleSample<'a> {
    /// Object-space corners.
    pub p: &'a [Vec3; 3],
    /// Render-space unit normal (the side that emits).
    pub n: Vec3,
    /// Render-space area density with which the light samples points on this triangle.
    pub area_pdf: f32,
    pub radiance: Vec3,
    /// An affine matrix.
    pub render_from_object: &'a Mat4,
    pub cdf: (f32, f32),
    /// The triangle's index in the light's mesh.
    pub prim: usize,
}

/// The emitting surface of one instance. A mesh cut by an alpha mask emits only where
/// rays find it: light samples are weighted by the mask's coverage at their point.
#[derive(Debug, Clone)]
pub struct AreaLight {
    pub shape: Arc<Shape>,
    pub render_from_object: Transform,
    pub emission: Emission,
    /// Linear part of `render_from_object`, for area densities.
    linear: Mat3,
    abs_det: f32,
    /// Centre and radius in render space when the instance is a sphere under a similarity
    /// transform (then sampled by solid angle).
    sphere: Option<(Vec3, f32)>,
    /// Approximate render-space area, for power estimates.
    area: f32,
    /// Flat triangle meshes, set up for sampling.
    flat_mesh: Option<FlatMeshEmitter>,
    /// Whether the instance's normals are flipped ([`AreaLight::with_flipped_normals`]).
    flip_normals: bool,
    /// Whether the surface is also scene geometry that rays can hit (then next-event
    /// estimation shares its paths with BSDF sampling by MIS); lightwave's area lights
    /// around an instance that is not in the scene are seen only by shadow rays.
    pub(crate) placed: bool,
}

impl AreaLight {
    pub fn new(shape: Arc<Shape>, render_from_object: Transform, emission: Emission) -> Self {
        let linear = Mat3::from_mat4(*render_from_object.matrix());
        let abs_det = linear.determinant().abs();
        let sphere = match &*shape {
            Shape::Sphere(_) => {
                // A similarity transform: MᵀM = s² I.
                let g = linear.transpose() * linear;
                let s2 = g.x_axis.x;
                let off = (g - Mat3::from_diagonal(Vec3::splat(s2)))
                    .to_cols_array()
                    .iter()
                    .fold(0.0f32, |a, v| a.max(v.abs()));
                (off <= 1e-5 * s2).then(|| (render_from_object.point(Vec3::ZERO), s2.sqrt()))
            }
            _ => None,
        };
        let area = shape.area() * abs_det.powf(2.0 / 3.0);
        let mut light = AreaLight {
            shape,
            render_from_object,
            emission,
            linear,
            abs_det,
            sphere,
            area,
            flat_mesh: None,
            flip_normals: false,
            placed: true,
        };
        if let Shape::TriangleMesh(m) = &*light.shape {
            // Masked meshes take the general path, which weighs each point's coverage;
            // so does radiance that reads vertex colours (from each point's interaction).
            if m.alpha().is_none() && !light.emission.radiance.uses_vertex_colors() {
                light.flat_mesh = FlatMeshEmitter::new(m, &render_from_object, &light);
            }
        }
        light
    }

    /// The light of an instance whose normals are flipped
    /// ([`crate::scene::Instance::flip_normals`]): its one-sided emission leaves the
    /// other side.
    pub fn with_flipped_normals(mut self) -> Self {
        self.flip_normals = true;
        if let Some(mesh) = &mut self.flat_mesh {
            for tri in &mut mesh.triangles {
                tri.n = -tri.n;
            }
        }
        self
    }

    /// An emitter that is not scene geometry: next-event estimation samples it, rays
    /// never hit it (it neither blocks nor reflects light, and the camera does not see it).
    pub fn unplaced(shape: Arc<Shape>, render_from_object: Transform, emission: Emission) -> Self {
        AreaLight {
            placed: false,
            ..AreaLight::new(shape, render_from_object, emission)
        }
    }

    /// Emitted power (approximate for non-uniform scaling), for light selection.
    pub fn power(&self) -> f32 {
        PI * self.area * super::luminance(self.emission.radiance.average())
    }

    /// Render-space area density of a point with render-space unit normal `n`, given its
    /// object-space density.
    #[inline]
    fn render_area_pdf(&self, object_pdf: f32, n: Vec3) -> f32 {
        object_pdf * (self.linear.transpose() * n).length() / self.abs_det
    }

    /// The cone of directions from `p` to the sphere: (centre direction, cos θmax), or
    /// `None` when `p` is inside.
    #[inline]
    fn cone(&self, p: Vec3) -> Option<(Vec3, f32, f32, f32)> {
        let (c, r) = self.sphere?;
        let d2 = (c - p).length_squared();
        let r2 = r * r;
        if d2 <= r2 * 1.0001 {
            return None;
        }
        let sin2 = r2 / d2;
        let cos_max = (1.0 - sin2).max(0.0).sqrt();
        Some((c - p, d2.sqrt(), cos_max, sin2))
    }

    /// Samples light arriving at `p`.
    #[inline]
    pub fn sample(&self, p: Vec3, u_prim: f32, u: Vec2) -> Option<LightSample> {
        if let Some(mesh) = &self.flat_mesh {
            return self.sample_flat_mesh(mesh, p, u);
        }
        self.sample_general(p, u_prim, u)
    }

    /// `sample_general` for a flat triangle mesh, from its precomputed triangles.
    #[inline(always)]
    fn sample_flat_mesh(&self, mesh: &FlatMeshEmitter, p: Vec3, u: Vec2) -> Option<LightSample> {
        // As the mesh's own `sample_area`: the triangle from `u.x`, reused inside it.
        let (prim, ux) = mesh.distribution.sample_reuse(u.x);
        let tri = &mesh.triangles[prim];
        let b = crate::sampling::warp::square_to_uniform_triangle(Vec2::new(ux, u.y));
        let (b1, b2) = (b.x, b.y);
        let b0 = 1.0 - b1 - b2;
        let [p0, p1, p2] = tri.p;
        let q = self.render_from_object.point(p0 * b0 + p1 * b1 + p2 * b2);
        let [uv0, uv1, uv2] = tri.uv;
        towards_area_point(p, q, tri.n, tri.area_pdf, |w| {
            self.emission
                .eval_at(tri.n, uv0 * b0 + uv1 * b1 + uv2 * b2, w)
        })
    }

    /// For lights whose samples run many at once ([`crate::integrator`]'s lanes): the
    /// triangle that [`AreaLight::sample`] picks from `u`, with everything its sample
    /// needs, where the light is a flat triangle mesh of constant radiance under an
    /// affine transform; `None` for other lights.
    #[inline(always)]
    pub(crate) fn flat_constant_sample(&self, u: Vec2) -> Option<FlatTriangleSample<'_>> {
        let mesh = self.flat_mesh.as_ref()?;
        let radiance = mesh.constant_radiance.as_ref()?;
        let (prim, c0, c1) = mesh.distribution.cell_interval(u.x);
        let tri = &mesh.triangles[prim];
        Some(FlatTriangleSample {
            p: &tri.p,
            n: tri.n,
            area_pdf: tri.area_pdf,
            radiance: *radiance,
            render_from_object: self.render_from_object.matrix(),
            cdf: (c0, c1),
            prim,
        })
    }

    /// Every triangle that [`AreaLight::flat_constant_sample`] can give, in index order
    /// (each with `u` zero), where it gives any: for code that tabulates them.
    pub(crate) fn flat_constant_triangles(
        &self,
    ) -> Option<impl ExactSizeIterator<Item = FlatTriangleSample<'_>>> {
        let mesh = self.flat_mesh.as_ref()?;
        let radiance = *mesh.constant_radiance.as_ref()?;
        let triangles = mesh.triangles.iter().enumerate();
        Some(triangles.map(move |(prim, tri)| FlatTriangleSample {
            p: &tri.p,
            n: tri.n,
            area_pdf: tri.area_pdf,
            radiance,
            render_from_object: self.render_from_object.matrix(),
            cdf: mesh.distribution.cell_bounds(prim),
            prim,
        }))
    }

    /// Samples light arriving at `p` for any shape: by solid angle for spheres, else by
    /// area through the shape's own sampling and interaction.
    fn sample_general(&self, p: Vec3, u_prim: f32, u: Vec2) -> Option<LightSample> {
        if let Some((axis, dc, cos_max, sin2)) = self.cone(p) {
            return self.sample_cone(p, axis / dc, dc, cos_max, sin2, u);
        }
        let (si_obj, object_pdf) = self.shape.sample_area(u_prim, u)?;
        let coverage = self.coverage(si_obj.uv);
        if coverage <= 0.0 {
            return None;
        }
        let mut si = si_obj.transformed(&self.render_from_object);
        if self.flip_normals {
            si.flip_normals();
        }
        let area_pdf = self.render_area_pdf(object_pdf, si.n);
        towards_area_point(p, si.p, si.n, area_pdf, |w| {
            self.emission.eval(&si, w) * coverage
        })
    }

    /// The fraction of rays that meet the emitter at texture coordinates `uv`: its alpha
    /// mask's coverage there, 1 without one.
    #[inline]
    fn coverage(&self, uv: Vec2) -> f32 {
        match &*self.shape {
            Shape::TriangleMesh(m) => m.alpha().map_or(1.0, |a| a.coverage_at(uv)),
            _ => 1.0,
        }
    }

    /// Uniform sampling of the cone the sphere subtends (pbrt-v3's construction, with the
    /// small-angle series for distant spheres).
    fn sample_cone(
        &self,
        p: Vec3,
        axis: Vec3,
        dc: f32,
        cos_max: f32,
        sin2_max: f32,
        u: Vec2,
    ) -> Option<LightSample> {
        let (c, r) = self.sphere?;
        let (cos_t, sin2_t) = if sin2_max < 0.00068523 {
            // sin²θmax small: 1 - cos θmax loses precision.
            let sin2 = sin2_max * u.x;
            ((1.0 - sin2).sqrt(), sin2)
        } else {
            let cos_t = (cos_max - 1.0) * u.x + 1.0;
            (cos_t, (1.0 - cos_t * cos_t).max(0.0))
        };
        let phi = 2.0 * PI * u.y;
        let frame = crate::math::Frame::from_normal(axis);
        let sin_t = sin2_t.sqrt();
        let wi = frame.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t));
        // The nearer intersection of the ray with the sphere, computed from the geometry.
        let ds = dc * cos_t - (r * r - dc * dc * sin2_t).max(0.0).sqrt();
        let q = p + wi * ds;
        let n = (q - c).normalize();
        let q = c + n * r;
        let si = self.sphere_interaction(q);
        let pdf = self.cone_pdf(cos_max, sin2_max);
        let le = self.emission.eval(&si, -wi);
        Some(LightSample {
            wi,
            distance: (q - p).length(),
            weight: le / pdf,
            pdf,
        })
    }

    fn cone_pdf(&self, cos_max: f32, sin2_max: f32) -> f32 {
        let one_minus_cos = if sin2_max < 0.00068523 {
            sin2_max / 2.0
        } else {
            1.0 - cos_max
        };
        1.0 / (2.0 * PI * one_minus_cos)
    }

    /// The render-space interaction at a point `q` on the (similarity-transformed) sphere.
    fn sphere_interaction(&self, q: Vec3) -> SurfaceInteraction {
        let object_from_render = self.render_from_object.inverse();
        let po = object_from_render.point(q).normalize();
        let ray = crate::math::Ray::new(po * 2.0, -po);
        let hit = crate::geometry::ShapeHit {
            t: 1.0,
            prim: 0,
            uv: Vec2::ZERO,
        };
        let mut si = self
            .shape
            .interaction(&ray, &hit)
            .transformed(&self.render_from_object);
        if self.flip_normals {
            si.flip_normals();
        }
        si
    }

    /// Solid-angle density with which `sample` from `p` picks the point `si` of this light
    /// (found by a ray from `p` in direction `wi`).
    pub fn pdf(&self, p: Vec3, si: &SurfaceInteraction, wi: Vec3) -> f32 {
        if let Some((_, _, cos_max, sin2)) = self.cone(p) {
            return self.cone_pdf(cos_max, sin2);
        }
        let object_pdf = match &*self.shape {
            Shape::TriangleMesh(m) => 1.0 / m.area(),
            s => 1.0 / s.area(),
        };
        let cos_light = si.n.dot(wi).abs();
        if cos_light == 0.0 {
            return 0.0;
        }
        let dist2 = (si.p - p).length_squared();
        self.render_area_pdf(object_pdf, si.n) * dist2 / cos_light
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Cuboid, Cylinder, Disk, Rectangle, Sphere};
    use crate::sampling::Pcg32;

    /// The cone of directions from `p` around the bounding sphere of `bounds`: its
    /// uniform density and a sampler of its directions.
    fn cone_towards(
        p: Vec3,
        bounds: crate::math::Bounds3,
    ) -> (f32, impl FnMut(&mut Pcg32) -> Vec3) {
        let c = (bounds.min + bounds.max) * 0.5;
        let r = bounds.diagonal().length() * 0.5;
        let cos_max = (1.0 - r * r / (c - p).length_squared()).sqrt();
        let frame = crate::math::Frame::from_normal((c - p).normalize());
        let direction = move |rng: &mut Pcg32| {
            let cos_t = 1.0 - rng.next_f32() * (1.0 - cos_max);
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let phi = 2.0 * PI * rng.next_f32();
            frame.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t))
        };
        (1.0 / (2.0 * PI * (1.0 - cos_max)), direction)
    }

    fn light(shape: Shape, t: Transform) -> AreaLight {
        AreaLight::new(
            Arc::new(shape),
            t,
            Emission {
                radiance: Arc::new(Texture::Constant(Vec3::ONE)),
            },
        )
    }

    /// Integrating the solid-angle pdf over the directions that see the light (uniform
    /// sphere Monte Carlo, intersecting the shape) gives 1, and `sample`'s pdf equals
    /// `pdf` at the sampled point: for every shape under a non-uniform transform, and for
    /// the sphere's cone sampling.
    #[test]
    fn sample_pdf_is_a_density_and_matches_pdf() {
        let t = Transform::scale(Vec3::new(0.5, 1.0, 0.8))
            .unwrap()
            .then(&Transform::rotate(Vec3::new(1.0, 2.0, 3.0), 40.0).unwrap())
            .then(&Transform::translate(Vec3::new(0.0, 0.0, 4.0)));
        let uniform = Transform::scale(Vec3::splat(0.7))
            .unwrap()
            .then(&Transform::translate(Vec3::new(0.3, 0.0, 3.0)));
        let cases = [
            (Shape::Sphere(Sphere), t),
            (Shape::Sphere(Sphere), uniform),
            (Shape::Rectangle(Rectangle), t),
            (Shape::Disk(Disk), t),
            (Shape::Cuboid(Cuboid), t),
            (Shape::Cylinder(Cylinder { caps: true }), t),
        ];
        let p = Vec3::new(0.1, -0.2, 0.0);
        let mut rng = Pcg32::new(3, 7);
        for (shape, t) in cases {
            let name = shape.kind_name();
            let l = light(shape, t);
            let mut b = crate::scene::SceneBuilder::new();
            let id = b.add_shape((*l.shape).clone());
            b.add_instance(id, t);
            let scene = b.build();
            // ∫ pdf dω = 1, summing the density of every surface point along each
            // direction (area sampling also picks points hidden behind the front), or of
            // the direction itself for cone sampling.
            let cone = l.cone(p).is_some();
            let hits_along = |w: Vec3| {
                let mut hits = Vec::new();
                let mut ray = crate::math::Ray::new(p, w);
                while let Some(si) = scene.intersect(&ray) {
                    hits.push(si);
                    ray = si.spawn_ray(w);
                    if hits.len() > 4 {
                        break;
                    }
                }
                hits
            };
            // Directions uniform in the cone around the instance's bounding sphere.
            let (cone_pdf, mut direction) = cone_towards(p, scene.bounds());
            let n = 200_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let w = direction(&mut rng);
                let hits = hits_along(w);
                let used = if cone { hits.len().min(1) } else { hits.len() };
                for si in &hits[..used] {
                    sum += (l.pdf(p, si, w) / cone_pdf) as f64;
                }
            }
            let integral = sum / n as f64;
            assert!(
                (integral - 1.0).abs() < 0.03,
                "{name}: pdf integrates to {integral}"
            );
            for _ in 0..200 {
                let ls = l
                    .sample(p, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()))
                    .unwrap();
                let hits = hits_along(ls.wi);
                let si = hits
                    .iter()
                    .find(|si| (si.p - p).length() > ls.distance * (1.0 - 1e-3))
                    .unwrap();
                assert!(
                    ((si.p - p).length() - ls.distance).abs() < 1e-3 * ls.distance,
                    "{name}: sampled point not on the surface"
                );
                let pdf = l.pdf(p, si, ls.wi);
                // At grazing angles the density is 1/cos: too sensitive to compare.
                if si.n.dot(ls.wi).abs() < 0.05 {
                    continue;
                }
                assert!(
                    (pdf - ls.pdf).abs() < 2e-3 * pdf,
                    "{name}: {pdf} vs {} dist {} {} n {:?} wi {:?}",
                    ls.pdf,
                    (si.p - p).length(),
                    ls.distance,
                    si.n,
                    ls.wi
                );
            }
        }
    }
    /// The precomputed path for flat meshes gives the general path's samples bit for bit,
    /// with and without texture coordinates, under a non-uniform mirroring transform.
    #[test]
    fn flat_mesh_sampling_equals_the_general_path() {
        use crate::geometry::MeshData;
        let mut rng = Pcg32::new(8, 5);
        let t = Transform::scale(Vec3::new(-0.5, 1.0, 0.8))
            .unwrap()
            .then(&Transform::rotate(Vec3::new(1.0, 2.0, 3.0), 40.0).unwrap())
            .then(&Transform::translate(Vec3::new(0.0, 0.0, 4.0)));
        for with_uvs in [false, true] {
            let mut data = MeshData::default();
            for i in 0..12u32 {
                for _ in 0..3 {
                    data.positions.push(Vec3::new(
                        rng.next_f32() * 2.0 - 1.0,
                        rng.next_f32() * 2.0 - 1.0,
                        rng.next_f32() - 0.5,
                    ));
                    if with_uvs {
                        data.uvs.push(Vec2::new(rng.next_f32(), rng.next_f32()));
                    }
                }
                data.indices.push([3 * i, 3 * i + 1, 3 * i + 2]);
            }
            let mesh =
                crate::geometry::TriangleMesh::new(data, false, crate::accel::AccelKind::Bvh2)
                    .unwrap();
            let radiance = Arc::new(Texture::Checkerboard(crate::texture::Checkerboard {
                scale: Vec2::splat(4.0),
                color0: Vec3::new(1.0, 2.0, 3.0),
                color1: Vec3::new(0.5, 0.25, 0.125),
            }));
            let l = AreaLight::new(
                Arc::new(Shape::TriangleMesh(Arc::new(mesh))),
                t,
                Emission { radiance },
            );
            assert!(l.flat_mesh.is_some());
            let mut some = 0;
            for _ in 0..5000 {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
                let (u_prim, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
                let fast = l.sample(p, u_prim, u);
                let general = l.sample_general(p, u_prim, u);
                assert_eq!(fast, general, "{p:?} {u_prim} {u:?}");
                some += fast.is_some_and(|s| s.weight != Vec3::ZERO) as u32;
            }
            assert!(some > 1000, "{some}");
        }
    }

    /// A quad emitter cut by a 2×2 alpha mask: the irradiance that next-event estimation
    /// finds at a point equals what rays sent towards the quad find (they pass through
    /// its holes, and through a stochastic mask with probability 1 − α), for a cutoff
    /// mask (two quarters there) and a stochastic one (quarters at α 0, 1, 0.75, 0.25).
    /// Emitting from the whole quad would find twice the light.
    #[test]
    fn alpha_masked_emitters_emit_where_rays_find_them() {
        use crate::film::Image;
        use crate::geometry::{AlphaMask, AlphaTest, TriangleMesh};
        use crate::texture::{BorderMode, FilterMode, ImageTexture};
        for test in [AlphaTest::Cutoff(0.5), AlphaTest::Stochastic] {
            let mut quad = unit_quad();
            quad.uvs = vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
            let mut mesh = TriangleMesh::new(quad, false, crate::accel::AccelKind::Bvh8).unwrap();
            mesh.set_alpha(AlphaMask {
                coverage: Arc::new(Texture::Image(ImageTexture {
                    image: Arc::new(Image {
                        width: 2,
                        height: 2,
                        pixels: [0.0, 1.0, 0.75, 0.25].map(Vec3::splat).to_vec(),
                    }),
                    border: BorderMode::Clamp,
                    filter: FilterMode::Nearest,
                    exposure: 1.0,
                })),
                test,
            });
            let shape = Shape::TriangleMesh(Arc::new(mesh));
            let l = light(shape.clone(), quad_placement());
            let (nee, rays) = nee_and_rays(&l, shape, 11);
            let (nee, rays) = (nee.x, rays.x);
            assert!(rays > 0.05, "{test:?}: the quad is lit and seen ({rays})");
            assert!(
                (nee - rays).abs() < 0.02 * rays,
                "{test:?}: next-event estimation {nee} against rays {rays}"
            );
        }
    }

    /// The placement of the quad emitters of the tests below (`unit_quad`, turned and
    /// moved).
    fn quad_placement() -> Transform {
        Transform::rotate(Vec3::new(1.0, -1.0, 0.5), 20.0)
            .unwrap()
            .then(&Transform::translate(Vec3::new(-0.3, 0.2, 0.0)))
    }

    /// The unit square of the xy plane as two triangles.
    fn unit_quad() -> crate::geometry::MeshData {
        crate::geometry::MeshData {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    /// The irradiance at a receiver above the quad placed by [`quad_placement`], facing
    /// it, from light `l` on `shape`: by next-event estimation (radiance / pdf times the
    /// receiver's cosine) and by rays uniform in the cone around the shape's bounding
    /// sphere that read the emission where they hit; per channel, 400,000 samples each.
    fn nee_and_rays(l: &AreaLight, shape: Shape, seed: u64) -> (glam::DVec3, glam::DVec3) {
        let (p, n_r) = (
            Vec3::new(0.35, 0.6, 1.2),
            Vec3::new(0.1, -0.2, -1.0).normalize(),
        );
        let mut b = crate::scene::SceneBuilder::new();
        let id = b.add_shape(shape);
        b.add_instance(id, quad_placement());
        let scene = b.build();
        let mut rng = Pcg32::new(seed, 4);
        let n = 400_000;
        let mut nee = glam::DVec3::ZERO;
        for _ in 0..n {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            if let Some(ls) = l.sample(p, rng.next_f32(), u) {
                nee += (ls.weight * n_r.dot(ls.wi).max(0.0)).as_dvec3();
            }
        }
        let (cone_pdf, mut direction) = cone_towards(p, scene.bounds());
        let mut rays = glam::DVec3::ZERO;
        for _ in 0..n {
            let w = direction(&mut rng);
            if let Some(si) = scene.intersect(&crate::math::Ray::new(p, w)) {
                let le = l.emission.eval(&si, -w);
                rays += (le * (n_r.dot(w).max(0.0) / cone_pdf)).as_dvec3();
            }
        }
        (nee / n as f64, rays / n as f64)
    }

    /// An emitter whose radiance is its mesh's vertex colours: next-event estimation (the
    /// general path, which reads each sampled point's colour) agrees with rays that find
    /// the mesh and read the colour at their hit, channel by channel.
    #[test]
    fn vertex_coloured_emitters_emit_their_colours() {
        use crate::geometry::TriangleMesh;
        let mut quad = unit_quad();
        // Red at one corner only, green along one edge, blue everywhere.
        quad.colors = vec![
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let mesh = TriangleMesh::new(quad, false, crate::accel::AccelKind::Bvh8).unwrap();
        let shape = Shape::TriangleMesh(Arc::new(mesh));
        let radiance = Arc::new(Texture::VertexColor(Arc::new(Texture::Constant(
            Vec3::splat(2.0),
        ))));
        let l = AreaLight::new(
            Arc::new(shape.clone()),
            quad_placement(),
            Emission { radiance },
        );
        assert!(
            l.flat_mesh.is_none(),
            "vertex colours take the general path"
        );
        let (nee, rays) = nee_and_rays(&l, shape, 12);
        // Blue is uniform; red (one corner) is the smallest share and green about half.
        assert!(
            rays.x > 0.0 && rays.x < 0.5 * rays.y && rays.y < rays.z,
            "{rays}"
        );
        for c in 0..3 {
            assert!(
                (nee[c] - rays[c]).abs() < 0.02 * rays[c],
                "channel {c}: next-event estimation {nee} against rays {rays}"
            );
        }
    }

    /// A light whose instance flips its normals emits from the other side: a rectangle
    /// (general area sampling) and a sphere (cone sampling, seen from outside, where its
    /// flipped emission faces inwards).
    #[test]
    fn flipped_lights_emit_from_the_other_side() {
        let t = Transform::translate(Vec3::new(0.2, -0.1, 0.0));
        let mut rng = Pcg32::new(5, 9);
        for (shape, p_front) in [
            (Shape::Rectangle(Rectangle), Vec3::new(0.3, 0.2, 2.0)),
            (Shape::Sphere(Sphere), Vec3::new(0.3, 0.2, 3.0)),
        ] {
            let name = shape.kind_name();
            // The point on the other side of the rectangle; the sphere has no other side
            // from which it can be sampled.
            let p_back = Vec3::new(p_front.x, p_front.y, -p_front.z);
            let plain = light(shape.clone(), t);
            let flipped = light(shape, t).with_flipped_normals();
            let total = |l: &AreaLight, p: Vec3, rng: &mut Pcg32| {
                (0..2000)
                    .filter_map(|_| {
                        l.sample(p, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()))
                    })
                    .map(|s| s.weight.x)
                    .sum::<f32>()
            };
            assert!(total(&plain, p_front, &mut rng) > 0.0, "{name}");
            assert_eq!(total(&flipped, p_front, &mut rng), 0.0, "{name}");
            if matches!(name, "rectangle") {
                assert_eq!(total(&plain, p_back, &mut rng), 0.0, "{name}");
                assert!(total(&flipped, p_back, &mut rng) > 0.0, "{name}");
            }
        }
    }
}
