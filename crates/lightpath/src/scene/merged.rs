//! Flattening: triangle meshes that only one instance uses gain nothing from a two-level
//! structure, so their triangles are moved into render space and merged into one mesh
//! with one BVH (pbrt does the same with its non-instanced primitives). Rays then walk a
//! single tree instead of a top-level tree plus one bottom-level tree per overlapping
//! instance, and skip the object-space transforms. Meshes shared by several instances
//! stay instanced (BLAS/TLAS). Hits on the merged mesh report the original instance and
//! triangle, so materials, emission and area lights are unchanged.

use super::Instance;
use crate::accel::{AccelKind, RayStats};
use crate::geometry::{MeshData, Shape, ShapeHit, SurfaceInteraction, TriangleMesh};
use crate::math::Ray;
use std::collections::HashMap;
use std::sync::Arc;

/// Meshes above this many triangles stay instanced: their own tree dominates, and copying
/// them would double their memory.
const MAX_MERGED_TRIANGLES: usize = 1 << 16;

/// One render-space mesh made of several instances' meshes.
#[derive(Debug, Clone)]
pub struct MergedMesh {
    pub mesh: TriangleMesh,
    /// Per merged triangle: the instance it came from and its index in that mesh.
    instance: Vec<u32>,
    prim: Vec<u32>,
}

impl MergedMesh {
    /// Groups the mergeable instances by the attributes their meshes carry (normals,
    /// texture coordinates, smoothing must agree within one mesh) and merges each group of
    /// at least two. Returns the merged meshes and, per instance, whether it was merged.
    pub fn build(instances: &[Instance], accel: AccelKind) -> (Vec<MergedMesh>, Vec<bool>) {
        let mut uses: HashMap<*const TriangleMesh, usize> = HashMap::new();
        for inst in instances {
            if let Shape::TriangleMesh(m) = &*inst.shape {
                *uses.entry(Arc::as_ptr(m)).or_default() += 1;
            }
        }
        let mut groups: HashMap<(bool, bool, bool), Vec<u32>> = HashMap::new();
        for (i, inst) in instances.iter().enumerate() {
            let Shape::TriangleMesh(m) = &*inst.shape else {
                continue;
            };
            if uses[&Arc::as_ptr(m)] != 1 || m.triangle_count() > MAX_MERGED_TRIANGLES {
                continue;
            }
            let key = (
                m.smooth && !m.normals.is_empty(),
                !m.uvs.is_empty(),
                m.smooth,
            );
            groups.entry(key).or_default().push(i as u32);
        }
        let mut merged_flags = vec![false; instances.len()];
        let mut merged = Vec::new();
        let mut keys: Vec<_> = groups.keys().copied().collect();
        keys.sort();
        for key in keys {
            let members = &groups[&key];
            if members.len() < 2 {
                continue;
            }
            let (with_normals, with_uvs, smooth) = key;
            let mut data = MeshData::default();
            let mut instance = Vec::new();
            let mut prim = Vec::new();
            for &i in members {
                let inst = &instances[i as usize];
                let Shape::TriangleMesh(m) = &*inst.shape else {
                    unreachable!()
                };
                let to = &inst.render_from_object;
                let base = data.positions.len() as u32;
                data.positions
                    .extend(m.positions.iter().map(|&p| to.point(p)));
                if with_normals {
                    data.normals
                        .extend(m.normals.iter().map(|&n| to.normal(n).normalize_or_zero()));
                }
                if with_uvs {
                    data.uvs.extend_from_slice(&m.uvs);
                }
                // A mirroring transform reverses the winding; swapping two corners keeps
                // the geometric normal on the side the object-space normal maps to.
                let flip = to.swaps_handedness();
                for (k, t) in m.indices.iter().enumerate() {
                    let [a, b, c] = t.map(|v| v + base);
                    data.indices.push(if flip { [a, c, b] } else { [a, b, c] });
                    instance.push(i);
                    prim.push(k as u32);
                }
                merged_flags[i as usize] = true;
            }
            // The data comes from valid meshes; a failure here would be a bug.
            let mesh = TriangleMesh::new(data, smooth, accel).expect("merged mesh data is valid");
            merged.push(MergedMesh {
                mesh,
                instance,
                prim,
            });
        }
        (merged, merged_flags)
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        self.mesh.intersect(ray, stats)
    }

    #[inline]
    pub fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        self.mesh.occluded(ray, stats)
    }

    /// The render-space interaction of a hit, naming the original instance and triangle.
    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let mut si = self.mesh.interaction(ray, hit);
        si.wo = -ray.direction.normalize();
        si.instance = self.instance[hit.prim as usize];
        si.prim = self.prim[hit.prim as usize];
        si
    }

    /// The instance of each merged triangle.
    pub fn instances(&self) -> &[u32] {
        &self.instance
    }

    pub fn memory_bytes(&self) -> usize {
        self.mesh.accel_memory_bytes()
    }
}

#[cfg(test)]
mod tests {
    use crate::geometry::{MeshData, Shape, TriangleMesh};
    use crate::math::{Ray, Transform};
    use crate::sampling::{warp, Pcg32};
    use crate::scene::SceneBuilder;
    use glam::{Vec2, Vec3};
    use std::sync::Arc;

    fn random_mesh(rng: &mut Pcg32, n: usize) -> TriangleMesh {
        let mut data = MeshData::default();
        for i in 0..n {
            let c = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 2.0;
            for _ in 0..3 {
                data.positions
                    .push(c + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5));
            }
            let b = 3 * i as u32;
            data.indices.push([b, b + 1, b + 2]);
        }
        TriangleMesh::new(data, false, crate::accel::AccelKind::Bvh2).unwrap()
    }

    /// Flattened meshes give the same closest hits (distance, instance, triangle, normal
    /// side) as intersecting every instance on its own in object space, under scaling,
    /// rotation, translation and mirroring; shared meshes stay instanced.
    #[test]
    fn merged_hits_equal_per_instance_hits() {
        let mut rng = Pcg32::new(11, 2);
        let mut b = SceneBuilder::new();
        let shared = b.add_shape(Shape::TriangleMesh(Arc::new(random_mesh(&mut rng, 20))));
        for k in 0..6 {
            let mesh = if k < 4 {
                b.add_shape(Shape::TriangleMesh(Arc::new(random_mesh(&mut rng, 30))))
            } else {
                shared
            };
            let mirror = if k % 2 == 1 { -1.0 } else { 1.0 };
            let axis = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let t = Transform::scale(Vec3::new(mirror * (0.5 + rng.next_f32()), 1.0, 1.5))
                .unwrap()
                .then(&Transform::rotate(axis, rng.next_f32() * 360.0).unwrap())
                .then(&Transform::translate(Vec3::new(
                    k as f32 * 1.5 - 4.0,
                    0.0,
                    0.0,
                )));
            b.add_instance(mesh, t);
        }
        let scene = b.build();
        assert_eq!(
            scene.merged.len(),
            1,
            "the four single-use meshes are merged"
        );
        let (mut hits, mut checked) = (0, 0);
        for _ in 0..20_000 {
            let o =
                warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())) * 12.0;
            let target = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                * Vec3::new(10.0, 3.0, 3.0);
            let ray = Ray::new(o, target - o);
            let got = scene.intersect(&ray);
            // Each instance's own closest hit; the nearest of them is the answer.
            let mut all: Vec<(f32, usize, crate::geometry::SurfaceInteraction)> = Vec::new();
            for (i, inst) in scene.instances.iter().enumerate() {
                if let Some(h) = inst.intersect(&ray, f32::INFINITY, &mut Default::default()) {
                    all.push((h.t, i, inst.interaction(&ray, &h)));
                }
            }
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            match (got, all.first()) {
                (None, None) => {}
                (Some(g), Some((t, i, si))) => {
                    hits += 1;
                    assert!((g.t - t).abs() <= 1e-4 * t.max(1.0), "{} vs {t}", g.t);
                    // Where two instances are hit at nearly the same distance either may win.
                    if all.len() > 1 && all[1].0 - t < 1e-4 * t.max(1.0) {
                        continue;
                    }
                    assert_eq!(g.instance as usize, *i);
                    assert!(g.n.dot(si.n) > 0.999, "normal {:?} vs {:?}", g.n, si.n);
                    checked += 1;
                }
                (g, b) => panic!("hit mismatch: {:?} vs {:?}", g.map(|g| g.t), b.map(|b| b.0)),
            }
        }
        assert!(checked > 2_000, "{checked}");
        assert!(hits >= checked);
    }
}
