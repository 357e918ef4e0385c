//! Raw triangle mesh data as a mesh file holds it, before it becomes a `TriangleMesh`.

use glam::{Vec2, Vec3};

/// Triangles with optional per-vertex normals, texture coordinates and colours.
///
/// `normals`, `uvs` and `colors` are each either empty or as long as `positions`;
/// `face_colors` is empty or as long as `indices`.
/// Colours are linear RGB (a file's 8-bit colours are decoded from sRGB by its reader). Triangle ids follow
/// the file: faces in file order, a polygon `v0..vk` fan-triangulated into
/// `(v0, vi, vi+1)`; degenerate triangles are kept so ids stay aligned with other tools.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshData {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    pub colors: Vec<Vec3>,
    /// One linear-RGB colour per triangle, or empty; used where `colors` is empty:
    /// [`crate::geometry::TriangleMesh::new`] gives each triangle vertices of its own
    /// carrying its colour.
    pub face_colors: Vec<Vec3>,
}

impl MeshData {
    /// Face colours held as vertex colours: each triangle gets three vertices of its own
    /// (positions, normals and texture coordinates copied) carrying its colour, so the
    /// colour is constant over the face. Unchanged without face colours, or where there
    /// are vertex colours (they win).
    pub fn unweld_face_colors(self) -> MeshData {
        if self.face_colors.is_empty() || !self.colors.is_empty() {
            return self;
        }
        let n = 3 * self.indices.len();
        let mut out = MeshData {
            positions: Vec::with_capacity(n),
            normals: Vec::with_capacity(if self.normals.is_empty() { 0 } else { n }),
            uvs: Vec::with_capacity(if self.uvs.is_empty() { 0 } else { n }),
            indices: Vec::with_capacity(self.indices.len()),
            colors: Vec::with_capacity(n),
            face_colors: Vec::new(),
        };
        for (t, (tri, &c)) in self.indices.iter().zip(&self.face_colors).enumerate() {
            for &v in tri {
                let v = v as usize;
                out.positions.push(self.positions[v]);
                if !self.normals.is_empty() {
                    out.normals.push(self.normals[v]);
                }
                if !self.uvs.is_empty() {
                    out.uvs.push(self.uvs[v]);
                }
                out.colors.push(c);
            }
            let b = 3 * t as u32;
            out.indices.push([b, b + 1, b + 2]);
        }
        out
    }

    /// Smooth vertex normals from the triangles, as Mitsuba computes them for a mesh
    /// file without normals: each triangle adds its unit normal weighted by its angle at
    /// the vertex (Thürmer and Wüthrich 1998); degenerate triangles add nothing, and a
    /// vertex that no triangle gives a direction gets +x. Where every triangle's three
    /// normals come out as its own face normal (a mesh of planar pieces, such as a quad
    /// light), none are stored: the shading is the same, and the mesh stays flat for the
    /// code that relies on flat meshes (flat emitters).
    pub fn compute_vertex_normals(&mut self) {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        for t in &self.indices {
            let v = t.map(|i| self.positions[i as usize]);
            let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
            if n == Vec3::ZERO {
                continue;
            }
            for k in 0..3 {
                let d0 = (v[(k + 1) % 3] - v[k]).normalize_or_zero();
                let d1 = (v[(k + 2) % 3] - v[k]).normalize_or_zero();
                let angle = d0.dot(d1).clamp(-1.0, 1.0).acos();
                normals[t[k] as usize] += n * angle;
            }
        }
        for n in &mut normals {
            *n = n.try_normalize().unwrap_or(Vec3::X);
        }
        let flat = self.indices.iter().all(|t| {
            let v = t.map(|i| self.positions[i as usize]);
            let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
            n == Vec3::ZERO || t.iter().all(|&i| normals[i as usize].dot(n) > 1.0 - 1e-6)
        });
        self.normals = if flat { Vec::new() } else { normals };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_normals_weigh_each_triangle_by_its_angle() {
        // A vertex at the origin with two triangles: one in the xy plane with a right
        // angle there, one in the xz plane with 45 degrees.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let mut m = MeshData {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(s, 0.0, -s),
                Vec3::new(5.0, 5.0, 5.0), // in no triangle
            ],
            indices: vec![[0, 1, 2], [0, 1, 3]],
            ..Default::default()
        };
        m.compute_vertex_normals();
        // Normals: +z weighted by pi/2 and +y weighted by pi/4.
        let expect = (Vec3::Z * 2.0 + Vec3::Y).normalize();
        assert!((m.normals[0] - expect).length() < 1e-6, "{}", m.normals[0]);
        assert!((m.normals[2] - Vec3::Z).length() < 1e-6);
        assert_eq!(m.normals[4], Vec3::X);

        // A planar quad keeps no normals: they would all be its face normal.
        let mut quad = MeshData {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::ONE, Vec3::new(0.0, 1.0, 1.0)],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        };
        quad.compute_vertex_normals();
        assert!(quad.normals.is_empty());
    }
}
