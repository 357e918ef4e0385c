//! Wavefront OBJ mesh loader, built on `tobj`.
//!
//! All objects and groups of the file are merged into one [`MeshData`], in file
//! order. `tobj` is asked for a single index (`single_index: true`), so every
//! distinct `v/vt/vn` combination becomes one vertex and positions, normals and
//! texture coordinates stay aligned. Polygons are triangulated by `tobj` as a fan
//! `(v0, vi, vi+1)` in file order (quads as `(a, b, c), (a, c, d)`), the same
//! convention as the PLY loader; degenerate triangles are kept. Point and line
//! elements (`p`, `l`) are ignored. Materials (`mtllib`/`usemtl`) are not read:
//! the scene description assigns materials.
//!
//! Normals are kept only when every vertex has one; texture coordinates are kept
//! when any object has them, vertices without one get `(0, 0)`. Texture
//! coordinates are returned as written in the file (no `v` flip).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::geometry::MeshData;

/// Reads an OBJ file into triangle mesh data.
///
/// `normals` and `uvs` of the result are either empty or as long as `positions`.
pub fn load_obj(path: &Path) -> Result<MeshData> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = BufReader::new(file);
    // `..Default::default()` covers fields behind optional tobj features (e.g.
    // `merge_identical_points` with `merging`), which another crate may enable.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    // Materials are not needed: hand tobj an empty library for every `mtllib`.
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Ok((Vec::new(), Default::default()))
    })
    .map_err(|e| Error::mesh(path, format!("cannot parse OBJ: {e}")))?;

    let meshes: Vec<&tobj::Mesh> = models
        .iter()
        .map(|m| &m.mesh)
        .filter(|m| !m.positions.is_empty())
        .collect();
    let vertex_count = |m: &tobj::Mesh| m.positions.len() / 3;
    let has_normals = |m: &tobj::Mesh| m.normals.len() == m.positions.len();
    let has_uvs = |m: &tobj::Mesh| m.texcoords.len() / 2 == vertex_count(m);

    let keep_normals = !meshes.is_empty() && meshes.iter().all(|m| has_normals(m));
    let keep_uvs = meshes.iter().any(|m| has_uvs(m));
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
    };

    for m in meshes {
        let base = mesh.positions.len();
        let count = vertex_count(m);
        for (i, p) in m.positions.chunks_exact(3).enumerate() {
            let p = Vec3::new(p[0], p[1], p[2]);
            if !p.is_finite() {
                return Err(Error::mesh(
                    path,
                    format!("vertex {} has a non-finite position {p}", base + i),
                ));
            }
            mesh.positions.push(p);
        }
        if keep_normals {
            mesh.normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|n| Vec3::new(n[0], n[1], n[2])),
            );
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
