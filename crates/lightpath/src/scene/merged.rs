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

/// Meshes above this many triangles stay instanced: merging copies a mesh into render
/// space beside its own (object-space) copy and tree, which a mesh of tens of millions
/// of triangles cannot afford. Below it merging pays even for one big mesh: a scene that
/// is all one merged mesh takes the path tracer's wavefront (packets of rays, vertices in
/// lanes). Mitsuba's Cornell box with a Stanford bunny (69k triangles) in it rendered
/// 1.6-2.2× the samples per second merged (2.1-2.7 against 1.2-1.3 M/s, 2 threads), for
/// 13-16 MB more memory and 25 ms more loading; with the 1.1M-triangle bunny_loop2,
/// 1.4-1.7× (1.65-1.97 against 1.06-1.16 M/s), for 205 MB more and 0.3 s more loading,
/// which 32 samples per pixel at 256² already repaid.
const MAX_MERGED_TRIANGLES: usize = 1 << 21;

/// One render-space mesh made of several instances' meshes.
///
/// Meshes that carry different attributes (vertex normals, texture coordinates,
/// vertex colours, smoothing) are merged too: `mesh` holds every triangle for intersection, and each set
/// of attributes keeps a mesh of its own (`parts`) that builds the interactions of its
/// triangles, so a ray walks one tree however the scene's meshes were written. A part's
/// triangles have the same render-space corners as in `mesh`, so a hit's distance and
/// barycentrics are valid in both.
#[derive(Debug, Clone)]
pub struct MergedMesh {
    /// All triangles; also their attributes when there is a single part.
    pub mesh: TriangleMesh,
    /// With several attribute sets: one mesh per set (brute-force accelerator, never
    /// traversed). Empty when `mesh` has the attributes itself.
    parts: Vec<TriangleMesh>,
    /// Per merged triangle: its part and its index in that part (with several parts).
    part: Vec<u32>,
    part_prim: Vec<u32>,
    /// Per merged triangle: the instance it came from and its index in that mesh.
    instance: Vec<u32>,
    prim: Vec<u32>,
}

impl MergedMesh {
    /// Groups the mergeable instances by the attributes their meshes carry (normals,
    /// texture coordinates, smoothing must agree within one part) and merges all of them
    /// into one mesh when there are at least two. Returns the merged meshes (at most one)
    /// and, per instance, whether it was merged.
    pub fn build(instances: &[Instance], accel: AccelKind) -> (Vec<MergedMesh>, Vec<bool>) {
        let mut uses: HashMap<*const TriangleMesh, usize> = HashMap::new();
        for inst in instances {
            if let Shape::TriangleMesh(m) = &*inst.shape {
                *uses.entry(Arc::as_ptr(m)).or_default() += 1;
            }
        }
        let mut groups: HashMap<(bool, bool, bool, bool), Vec<u32>> = HashMap::new();
        for (i, inst) in instances.iter().enumerate() {
            let Shape::TriangleMesh(m) = &*inst.shape else {
                continue;
            };
            // A cutout mesh keeps its own instance: its hits depend on its mask; so does
            // one whose instance flips its normals.
            if uses[&Arc::as_ptr(m)] != 1
                || m.triangle_count() > MAX_MERGED_TRIANGLES
                || m.alpha().is_some()
                || inst.flip_normals
            {
                continue;
            }
            let key = (
                m.smooth && !m.normals.is_empty(),
                !m.uvs.is_empty(),
                m.smooth,
                !m.colors.is_empty(),
            );
            groups.entry(key).or_default().push(i as u32);
        }
        let mut merged_flags = vec![false; instances.len()];
        if groups.values().map(Vec::len).sum::<usize>() < 2 {
            return (Vec::new(), merged_flags);
        }
        let mut keys: Vec<_> = groups.keys().copied().collect();
        keys.sort();
        // Each attribute set's triangles in render space.
        let mut part_data = Vec::new();
        let (mut part, mut part_prim, mut instance, mut prim) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for key in keys {
            let (with_normals, with_uvs, smooth, with_colors) = key;
            let mut data = MeshData::default();
            let mut flipped = Vec::new();
            for &i in &groups[&key] {
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
                if with_colors {
                    data.colors.extend_from_slice(&m.colors);
                }
                // A mirroring transform reverses the winding: its triangles keep their
                // corners (and so the default texture parameterisation) and are marked,
                // so that their geometric normal stays on the side the object-space
                // normal maps to.
                let flip = to.swaps_handedness();
                for (k, t) in m.indices.iter().enumerate() {
                    part.push(part_data.len() as u32);
                    part_prim.push(data.indices.len() as u32);
                    data.indices.push(t.map(|v| v + base));
                    flipped.push(flip);
                    instance.push(i);
                    prim.push(k as u32);
                }
                merged_flags[i as usize] = true;
            }
            part_data.push((data, smooth, flipped));
        }
        // The data comes from valid meshes; a failure here would be a bug.
        let valid = "merged mesh data is valid";
        let (mesh, parts) = if part_data.len() == 1 {
            let (data, smooth, flipped) = part_data.pop().unwrap();
            let mut mesh = TriangleMesh::new(data, smooth, accel).expect(valid);
            mesh.set_flipped(flipped);
            (mesh, Vec::new())
        } else {
            // The whole mesh only finds hits (the test is two-sided); the parts make the
            // interactions and carry the flags.
            let mut all = MeshData::default();
            for (data, _, _) in &part_data {
                let base = all.positions.len() as u32;
                all.positions.extend_from_slice(&data.positions);
                all.indices
                    .extend(data.indices.iter().map(|t| t.map(|v| v + base)));
            }
            let parts = part_data
                .into_iter()
                .map(|(data, smooth, flipped)| {
                    let mut part = TriangleMesh::new(data, smooth, AccelKind::List).expect(valid);
                    part.set_flipped(flipped);
                    part
                })
                .collect();
            (TriangleMesh::new(all, false, accel).expect(valid), parts)
        };
        if parts.is_empty() {
            part.clear();
            part_prim.clear();
        }
        let merged = MergedMesh {
            mesh,
            parts,
            part,
            part_prim,
            instance,
            prim,
        };
        (vec![merged], merged_flags)
    }

    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        self.mesh.intersect(ray, stats)
    }

    #[inline(always)]
    pub fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        self.mesh.occluded(ray, stats)
    }

    /// The render-space interaction of a hit, naming the original instance and triangle.
    #[inline(always)]
    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let k = hit.prim as usize;
        let mut si = if self.parts.is_empty() {
            self.mesh.interaction(ray, hit)
        } else {
            let part_hit = ShapeHit {
                prim: self.part_prim[k],
                ..*hit
            };
            self.parts[self.part[k] as usize].interaction(ray, &part_hit)
        };
        // The part's interaction has `wo` from the same ray already.
        si.instance = self.instance[k];
        si.prim = self.prim[k];
        si
    }

    /// Merged triangle `k`: the mesh that builds its interaction, its index there, and
    /// its instance.
    #[inline(always)]
    pub(crate) fn triangle(&self, k: u32) -> (&TriangleMesh, u32, u32) {
        let k = k as usize;
        if self.parts.is_empty() {
            (&self.mesh, k as u32, self.instance[k])
        } else {
            (
                &self.parts[self.part[k] as usize],
                self.part_prim[k],
                self.instance[k],
            )
        }
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
    /// Meshes with different attributes (flat, smooth with vertex normals, with texture
    /// coordinates) are merged into one tree, and each hit still gets its own mesh's
    /// shading normal and texture coordinates.
    #[test]
    fn meshes_with_different_attributes_merge_into_one_tree() {
        let mut rng = Pcg32::new(4, 8);
        let mut b = SceneBuilder::new();
        for k in 0..3 {
            let mut m = random_mesh(&mut rng, 25);
            let n = m.positions.len();
            let smooth = k == 1;
            if smooth {
                m.normals = (0..n)
                    .map(|_| {
                        warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()))
                    })
                    .collect();
            }
            if k == 2 {
                m.uvs = (0..n)
                    .map(|_| Vec2::new(rng.next_f32(), rng.next_f32()))
                    .collect();
            }
            let data = MeshData {
                positions: m.positions.clone(),
                normals: m.normals.clone(),
                uvs: m.uvs.clone(),
                indices: m.indices.clone(),
                colors: Vec::new(),
                face_colors: Vec::new(),
            };
            let mesh = TriangleMesh::new(data, smooth, crate::accel::AccelKind::Bvh2).unwrap();
            let id = b.add_shape(Shape::TriangleMesh(Arc::new(mesh)));
            // Mirrored, but a similarity: a non-uniform scale can turn a vertex normal
            // to the other side of the face in render space than in object space.
            let t = Transform::scale(Vec3::new(if k == 1 { -1.2 } else { 1.0 }, 1.2, 1.2))
                .unwrap()
                .then(&Transform::translate(Vec3::new(
                    k as f32 * 1.5 - 1.5,
                    0.0,
                    0.0,
                )));
            b.add_instance(id, t);
        }
        let scene = b.build();
        assert_eq!(scene.merged.len(), 1);
        assert_eq!(scene.merged[0].parts.len(), 3);
        let mut checked = [0; 3];
        for _ in 0..20_000 {
            let o =
                warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())) * 10.0;
            let target = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                * Vec3::new(6.0, 3.0, 3.0);
            let ray = Ray::new(o, target - o);
            let Some(g) = scene.intersect(&ray) else {
                continue;
            };
            let inst = &scene.instances[g.instance as usize];
            let Some(h) = inst.intersect(&ray, f32::INFINITY, &mut Default::default()) else {
                continue;
            };
            if h.prim != g.prim || (h.t - g.t).abs() > 1e-4 * g.t {
                continue; // a nearer triangle of another instance at almost the same distance
            }
            let si = inst.interaction(&ray, &h);
            assert!(g.n.dot(si.n) > 0.999, "{:?} vs {:?}", g.n, si.n);
            assert!(
                g.shading_n.dot(si.shading_n) > 0.999,
                "{:?} vs {:?}",
                g.shading_n,
                si.shading_n
            );
            // Texture coordinates and dp/du too, for meshes with and without their own
            // uvs, mirrored or not.
            assert!((g.uv - si.uv).length() < 1e-3, "{:?} vs {:?}", g.uv, si.uv);
            assert!(
                g.dpdu.normalize().dot(si.dpdu.normalize()) > 0.999,
                "{:?} vs {:?}",
                g.dpdu,
                si.dpdu
            );
            checked[g.instance as usize] += 1;
        }
        assert!(checked.iter().all(|&c| c > 500), "{checked:?}");
    }
}
