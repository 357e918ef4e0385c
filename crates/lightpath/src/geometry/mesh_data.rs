//! Raw triangle mesh data as a mesh file holds it, before it becomes a `TriangleMesh`.

use glam::{Vec2, Vec3};

/// Triangles with optional per-vertex normals and texture coordinates.
///
/// `normals` and `uvs` are either empty or as long as `positions`. Triangle ids follow
/// the file: faces in file order, a polygon `v0..vk` fan-triangulated into
/// `(v0, vi, vi+1)`; degenerate triangles are kept so ids stay aligned with other tools.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshData {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
}
