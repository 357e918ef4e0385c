//! Mitsuba's `.serialized` meshes: one or more indexed triangle meshes, each a 4-byte
//! header (format identifier `0x041C`, version 3 or 4, little-endian `u16`s) followed by
//! a zlib stream of flags, (version 4) a null-terminated name, the vertex and triangle
//! counts (`u64`), the positions, optional normals, texture coordinates and colours (in
//! single or double precision, as the flags say) and the triangles' `u32` indices. A
//! dictionary at the end of the file gives each mesh's offset (`u64`s in version 4,
//! `u32`s in version 3) and then the mesh count (`u32`).
//!
//! As Mitsuba 3 reads them: vertex colours are skipped, the file's "face normals" flag is
//! ignored (the scene's `face_normals` decides), and a mesh without normals gets smooth
//! ones computed from its triangles.
//!
//! ```xml
//! <shape type="serialized">
//!     <string name="filename" value="meshes.serialized"/>
//!     <integer name="shape_index" value="1"/>
//!     <boolean name="face_normals" value="false"/>
//! </shape>
//! ```
//!
//! Malformed files (a wrong identifier or version, a shape index past the dictionary,
//! a truncated or corrupt stream, an index outside the vertices, non-finite values)
//! give an [`Error`] naming the file, the mesh and what is wrong.

use std::io::Read;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::geometry::MeshData;

const IDENTIFIER: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const DOUBLE_PRECISION: u32 = 0x2000;

/// Reads mesh `shape_index` (0 for the first) of a `.serialized` file.
///
/// `normals` and `uvs` of the result are either empty or as long as `positions`.
pub fn load_serialized(path: &Path, shape_index: usize) -> Result<MeshData> {
    let data = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&data, shape_index).map_err(|m| Error::mesh(path, m))
}

fn le_u16(b: &[u8]) -> u16 {
    u16::from_le_bytes([b[0], b[1]])
}

/// The file's version, after checking the header at `offset`.
fn header(data: &[u8], offset: usize, what: &str) -> std::result::Result<u16, String> {
    let head = data
        .get(offset..offset + 4)
        .ok_or_else(|| format!("{what}: the file ends before its 4-byte header"))?;
    let (id, version) = (le_u16(head), le_u16(&head[2..]));
    if id != IDENTIFIER {
        return Err(format!(
            "{what}: not a Mitsuba serialized mesh (identifier {id:#06x}, expected {IDENTIFIER:#06x})"
        ));
    }
    if version != 3 && version != 4 {
        return Err(format!(
            "{what}: unsupported serialized version {version} (supported: 3, 4)"
        ));
    }
    Ok(version)
}

/// Where mesh `index` starts, from the dictionary at the end of the file.
fn mesh_offset(data: &[u8], version: u16, index: usize) -> std::result::Result<usize, String> {
    let n = data.len();
    if n < 8 {
        return Err("the file is too short for its end-of-file dictionary".into());
    }
    let count = u32::from_le_bytes(data[n - 4..].try_into().expect("4 bytes")) as usize;
    if index >= count {
        return Err(format!(
            "shape_index {index} is out of range: the file holds {count} mesh{}",
            if count == 1 { "" } else { "es" }
        ));
    }
    let width = if version == 4 { 8 } else { 4 };
    let table = (count * width)
        .checked_add(4)
        .filter(|&t| t <= n)
        .ok_or_else(|| {
            format!("the end-of-file dictionary of {count} meshes does not fit in the file")
        })?;
    let at = n - table + index * width;
    let offset = if version == 4 {
        u64::from_le_bytes(data[at..at + 8].try_into().expect("8 bytes"))
    } else {
        u64::from(u32::from_le_bytes(
            data[at..at + 4].try_into().expect("4 bytes"),
        ))
    };
    usize::try_from(offset)
        .ok()
        .filter(|&o| o < n - table)
        .ok_or_else(|| format!("mesh {index}: its offset {offset} lies outside the file"))
}

/// Parses mesh `index` of a whole file held in memory.
fn parse(data: &[u8], index: usize) -> std::result::Result<MeshData, String> {
    let version = header(data, 0, "mesh 0")?;
    let what = format!("mesh {index}");
    let offset = if index == 0 {
        0
    } else {
        let offset = mesh_offset(data, version, index)?;
        if header(data, offset, &what)? != version {
            return Err(format!("{what}: its version differs from the file's"));
        }
        offset
    };
    let mut stream = flate2::read::ZlibDecoder::new(&data[offset + 4..]);
    let mut read = |buf: &mut [u8], field: &str| {
        stream.read_exact(buf).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => format!("{what}: truncated in its {field}"),
            _ => format!("{what}: corrupt compressed data in its {field}: {e}"),
        })
    };
    let mut b4 = [0u8; 4];
    read(&mut b4, "flags")?;
    let flags = u32::from_le_bytes(b4);
    if version == 4 {
        // The mesh's name, null-terminated; not used.
        let mut b = [0u8; 1];
        loop {
            read(&mut b, "name")?;
            if b[0] == 0 {
                break;
            }
        }
    }
    let mut b8 = [0u8; 8];
    read(&mut b8, "vertex count")?;
    let vertex_count = u64::from_le_bytes(b8);
    read(&mut b8, "triangle count")?;
    let triangle_count = u64::from_le_bytes(b8);
    if vertex_count > u64::from(u32::MAX) {
        return Err(format!(
            "{what}: {vertex_count} vertices (more than 32-bit indices can address)"
        ));
    }
    let scalar = if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 };
    let per_vertex = 3
        + if flags & HAS_NORMALS != 0 { 3 } else { 0 }
        + if flags & HAS_TEXCOORDS != 0 { 2 } else { 0 }
        + if flags & HAS_COLORS != 0 { 3 } else { 0 };
    let needed = vertex_count
        .checked_mul(per_vertex * scalar)
        .and_then(|v| {
            triangle_count
                .checked_mul(12)
                .and_then(|t| v.checked_add(t))
        })
        .filter(|&b| b < 1 << 40)
        .ok_or_else(|| {
            format!("{what}: absurd size ({vertex_count} vertices, {triangle_count} triangles)")
        })?;
    // Read what is there (growing as it arrives), so that a count larger than the data
    // is found truncated rather than allocated.
    let mut body = Vec::new();
    (&mut stream)
        .take(needed)
        .read_to_end(&mut body)
        .map_err(|e| format!("{what}: corrupt compressed data: {e}"))?;
    if (body.len() as u64) < needed {
        return Err(format!(
            "{what}: truncated: {} of the {needed} bytes of its {vertex_count} vertices and \
             {triangle_count} triangles",
            body.len()
        ));
    }
    let (nv, nt) = (vertex_count as usize, triangle_count as usize);
    let mut pos = 0;
    let mut floats = |count: usize| -> Vec<f32> {
        let bytes = &body[pos..pos + count * scalar as usize];
        pos += bytes.len();
        if scalar == 8 {
            bytes
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")) as f32)
                .collect()
        } else {
            bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect()
        }
    };
    let vec3s = |v: Vec<f32>, name: &str| -> std::result::Result<Vec<Vec3>, String> {
        v.chunks_exact(3)
            .enumerate()
            .map(|(i, c)| {
                let p = Vec3::new(c[0], c[1], c[2]);
                if p.is_finite() {
                    Ok(p)
                } else {
                    Err(format!("{what}: vertex {i}: {name} {p} is not finite"))
                }
            })
            .collect()
    };
    let positions = vec3s(floats(3 * nv), "position")?;
    let normals = if flags & HAS_NORMALS != 0 {
        vec3s(floats(3 * nv), "normal")?
    } else {
        Vec::new()
    };
    let uvs = if flags & HAS_TEXCOORDS != 0 {
        floats(2 * nv)
            .chunks_exact(2)
            .enumerate()
            .map(|(i, c)| {
                let uv = Vec2::new(c[0], c[1]);
                if uv.is_finite() {
                    Ok(uv)
                } else {
                    Err(format!(
                        "{what}: vertex {i}: texture coordinates {uv} are not finite"
                    ))
                }
            })
            .collect::<std::result::Result<_, _>>()?
    } else {
        Vec::new()
    };
    if flags & HAS_COLORS != 0 {
        floats(3 * nv); // Skipped, as Mitsuba 3 does.
    }
    let indices = body[pos..]
        .chunks_exact(12)
        .take(nt)
        .enumerate()
        .map(|(t, c)| {
            let index = |k: usize| u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().expect("4"));
            let tri = [index(0), index(1), index(2)];
            match tri.iter().find(|&&i| i as usize >= nv) {
                Some(i) => Err(format!(
                    "{what}: triangle {t}: vertex index {i} is out of range ({nv} vertices)"
                )),
                None => Ok(tri),
            }
        })
        .collect::<std::result::Result<_, _>>()?;
    Ok(MeshData {
        positions,
        normals,
        uvs,
        indices,
        colors: Vec::new(),
        face_colors: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// One mesh's record as Mitsuba writes it: header, then the zlib stream.
    fn record(version: u16, flags: u32, vertices: &[[f64; 8]], triangles: &[[u32; 3]]) -> Vec<u8> {
        let mut body = flags.to_le_bytes().to_vec();
        if version == 4 {
            body.extend(b"a mesh\0");
        }
        body.extend((vertices.len() as u64).to_le_bytes());
        body.extend((triangles.len() as u64).to_le_bytes());
        let double = flags & DOUBLE_PRECISION != 0;
        let put = |body: &mut Vec<u8>, range: std::ops::Range<usize>| {
            for v in vertices {
                for &x in &v[range.clone()] {
                    if double {
                        body.extend(x.to_le_bytes());
                    } else {
                        body.extend((x as f32).to_le_bytes());
                    }
                }
            }
        };
        put(&mut body, 0..3);
        if flags & HAS_NORMALS != 0 {
            put(&mut body, 3..6);
        }
        if flags & HAS_TEXCOORDS != 0 {
            put(&mut body, 6..8);
        }
        if flags & HAS_COLORS != 0 {
            put(&mut body, 0..3);
        }
        for t in triangles {
            for i in t {
                body.extend(i.to_le_bytes());
            }
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&body).unwrap();
        let mut out = IDENTIFIER.to_le_bytes().to_vec();
        out.extend(version.to_le_bytes());
        out.extend(z.finish().unwrap());
        out
    }

    /// A file of several records with its end-of-file dictionary.
    fn file(version: u16, records: &[Vec<u8>]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for r in records {
            offsets.push(out.len() as u64);
            out.extend(r);
        }
        for o in offsets {
            if version == 4 {
                out.extend(o.to_le_bytes());
            } else {
                out.extend((o as u32).to_le_bytes());
            }
        }
        out.extend((records.len() as u32).to_le_bytes());
        out
    }

    fn quad(z: f64) -> Vec<[f64; 8]> {
        vec![
            [0.0, 0.0, z, 0.0, 0.0, 1.0, 0.0, 0.0],
            [1.0, 0.0, z, 0.0, 0.0, 1.0, 1.0, 0.0],
            [1.0, 1.0, z, 0.0, 0.0, 1.0, 1.0, 1.0],
            [0.0, 1.0, z, 0.0, 0.0, 1.0, 0.0, 1.0],
        ]
    }

    const TRIS: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];

    #[test]
    fn reads_every_mesh_of_a_file_in_both_versions_and_precisions() {
        for version in [3, 4] {
            let records = [
                record(version, HAS_NORMALS | HAS_TEXCOORDS, &quad(0.0), &TRIS),
                record(
                    version,
                    DOUBLE_PRECISION | HAS_COLORS,
                    &quad(2.5),
                    &TRIS[..1],
                ),
                record(version, HAS_TEXCOORDS | HAS_COLORS, &quad(-1.0), &TRIS),
            ];
            let data = file(version, &records);
            let m = parse(&data, 0).unwrap();
            assert_eq!(m.positions[2], Vec3::new(1.0, 1.0, 0.0));
            assert_eq!(m.normals, vec![Vec3::Z; 4]);
            assert_eq!(m.uvs[1], Vec2::new(1.0, 0.0));
            assert_eq!(m.indices, TRIS.to_vec());
            let m = parse(&data, 1).unwrap();
            assert_eq!(m.positions[3], Vec3::new(0.0, 1.0, 2.5));
            assert!(m.normals.is_empty() && m.uvs.is_empty());
            assert_eq!(m.indices, vec![[0, 1, 2]]);
            // Colours come between the texture coordinates and the indices.
            let m = parse(&data, 2).unwrap();
            assert_eq!(m.positions[0], Vec3::new(0.0, 0.0, -1.0));
            assert_eq!(m.uvs[3], Vec2::new(0.0, 1.0));
            assert_eq!(m.indices, TRIS.to_vec());
        }
    }

    #[test]
    fn malformed_files_are_errors_that_say_why() {
        let good = file(4, &[record(4, HAS_NORMALS, &quad(0.0), &TRIS)]);
        let err = |data: &[u8], index: usize| parse(data, index).unwrap_err();

        let mut wrong = good.clone();
        wrong[0] = 0x1D;
        assert!(err(&wrong, 0).contains("not a Mitsuba serialized mesh"));
        let mut wrong = good.clone();
        wrong[2] = 5;
        assert!(err(&wrong, 0).contains("unsupported serialized version 5"));
        assert!(err(&good, 1).contains("shape_index 1 is out of range: the file holds 1 mesh"));
        assert!(err(&good[..20], 0).contains("mesh 0:"));
        assert!(err(&good[..2], 0).contains("4-byte header"));

        let bad = file(4, &[record(4, 0, &quad(0.0), &[[0, 1, 4]])]);
        assert!(err(&bad, 0).contains("triangle 0: vertex index 4 is out of range"));
        let mut nan = quad(0.0);
        nan[2][1] = f64::NAN;
        let bad = file(4, &[record(4, 0, &nan, &TRIS)]);
        assert!(err(&bad, 0).contains("vertex 2: position"));
        let mut far = quad(0.0);
        far[1][0] = 1e300; // beyond f32
        let bad = file(4, &[record(4, DOUBLE_PRECISION, &far, &TRIS)]);
        assert!(err(&bad, 0).contains("vertex 1: position"));

        // Counts larger than the data: truncated, not allocated.
        let mut body = 0u32.to_le_bytes().to_vec();
        body.extend(b"\0");
        body.extend(1_000_000_000u64.to_le_bytes());
        body.extend(1u64.to_le_bytes());
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&body).unwrap();
        let mut data = vec![0x1C, 0x04, 4, 0];
        data.extend(z.finish().unwrap());
        assert!(err(&data, 0).contains("truncated: 0 of the 12000000012 bytes"));
        let mut body = 0u32.to_le_bytes().to_vec();
        body.extend(b"\0");
        body.extend(u64::MAX.to_le_bytes());
        z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&body).unwrap();
        let mut data = vec![0x1C, 0x04, 4, 0];
        data.extend(z.finish().unwrap());
        assert!(err(&data, 0).contains("truncated in its triangle count"));

        // A dictionary pointing outside the file, and corrupt compressed bytes.
        let mut bad = file(
            4,
            &[
                good[..good.len() - 12].to_vec(),
                good[..good.len() - 12].to_vec(),
            ],
        );
        let n = bad.len();
        bad[n - 12..n - 4].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(err(&bad, 1).contains("outside the file"));
        let mut bad = good.clone();
        for b in &mut bad[4..12] {
            *b = 0xFF;
        }
        assert!(err(&bad, 0).contains("corrupt compressed data"));
    }
}
