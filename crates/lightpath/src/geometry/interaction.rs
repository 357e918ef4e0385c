//! What a ray knows about the surface it hit, and how new rays leave that surface.

use crate::math::{offset_ray_origin, Ray, Transform};
use glam::{Vec2, Vec3};

/// A ray–surface intersection with everything shading needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceInteraction {
    /// Hit point.
    pub p: Vec3,
    /// Absolute error bound of `p` per axis; spawned rays start outside it.
    pub p_error: Vec3,
    /// Ray parameter of the hit.
    pub t: f32,
    /// Unit geometric normal, on the shape's outside (not flipped towards the ray).
    pub n: Vec3,
    /// Unit shading normal (interpolated vertex normals, later normal maps).
    pub shading_n: Vec3,
    /// Surface tangent along increasing `u` (not necessarily unit length).
    pub dpdu: Vec3,
    /// Surface tangent along increasing `v` (not necessarily unit length, nor orthogonal
    /// to `dpdu`): with `dpdu`, how far the point moves per unit of texture coordinates,
    /// which bump mapping needs.
    pub dpdv: Vec3,
    /// Texture coordinates.
    pub uv: Vec2,
    /// The vertex colour (a mesh's per-vertex colours interpolated; white elsewhere).
    pub color: Vec3,
    /// Unit direction towards the ray origin.
    pub wo: Vec3,
    /// Index of the instance that was hit (set by the scene).
    pub instance: u32,
    /// Index of the primitive within the shape (triangle id for meshes, else 0).
    pub prim: u32,
}

impl SurfaceInteraction {
    /// Moves the interaction from object to render space.
    pub fn transformed(&self, render_from_object: &Transform) -> SurfaceInteraction {
        let (p, p_error) = render_from_object.point_with_error(self.p, self.p_error);
        SurfaceInteraction {
            p,
            p_error,
            t: self.t,
            n: render_from_object.normal(self.n).normalize_or_zero(),
            shading_n: render_from_object
                .normal(self.shading_n)
                .normalize_or_zero(),
            dpdu: render_from_object.vector(self.dpdu),
            dpdv: render_from_object.vector(self.dpdv),
            uv: self.uv,
            color: self.color,
            wo: render_from_object.vector(self.wo).normalize_or_zero(),
            instance: self.instance,
            prim: self.prim,
        }
    }

    /// Where textures are looked up at this point.
    #[inline(always)]
    pub fn tex(&self) -> crate::texture::TexCoord {
        crate::texture::TexCoord::new(self.uv, self.color)
    }

    /// Turns the surface's normals the other way (geometric and shading together).
    #[inline]
    pub fn flip_normals(&mut self) {
        self.n = -self.n;
        self.shading_n = -self.shading_n;
    }

    /// The origin for a ray leaving the surface towards `w`, offset by the error bound.
    #[inline]
    pub fn offset_origin(&self, w: Vec3) -> Vec3 {
        offset_ray_origin(self.p, self.p_error, self.n, w)
    }

    /// A ray leaving the surface in direction `w`.
    #[inline]
    pub fn spawn_ray(&self, w: Vec3) -> Ray {
        Ray::new(self.offset_origin(w), w)
    }

    /// A ray from the surface towards the point `target`, ending just before it
    /// (`t_max = 1 - ε` with the direction spanning the whole distance).
    #[inline]
    pub fn spawn_ray_to(&self, target: Vec3) -> Ray {
        let origin = self.offset_origin(target - self.p);
        Ray::with_range(origin, target - origin, 0.0, 1.0 - SHADOW_EPSILON)
    }
}

/// How far short of its target a shadow ray stops, relative to its length.
pub const SHADOW_EPSILON: f32 = 1e-4;
