//! PLY (Stanford polygon file) mesh loader.
//!
//! This is a hand-written reader, not `ply-rs-bw`: `ply-rs-bw` builds a
//! string-keyed property map for every vertex and face, which is slow for
//! multi-million-element files, while this reader decodes the body straight into
//! a [`MeshData`] (a 1.1M-triangle binary file loads in a few tens of
//! milliseconds in release builds).
//!
//! Supported:
//! - `ascii`, `binary_little_endian` and `binary_big_endian` bodies;
//! - every PLY scalar type (`char`/`int8` ... `double`/`float64`), for any
//!   property, including list counts and list items;
//! - vertex properties `x`, `y`, `z` (required), `nx`, `ny`, `nz` (used when all
//!   three are present) and texture coordinates named `u`/`v`, `s`/`t`,
//!   `texture_u`/`texture_v` or `texture_s`/`texture_t` (first pair found, in
//!   that order), and vertex colours `red`/`green`/`blue`, `r`/`g`/`b`,
//!   `diffuse_red`/`diffuse_green`/`diffuse_blue` or `color_0`/`color_1`/`color_2`
//!   (Mitsuba's) (floats as linear RGB; unsigned integers, as scanners and MeshLab
//!   write them, as sRGB over the type's range, decoded to linear);
//! - face colours under the same names, where the vertices have none (one per triangle
//!   of the face: see [`MeshData::face_colors`]);
//! - a face list property `vertex_indices` or `vertex_index`;
//! - any other elements and properties, which are skipped.
//!
//! Faces become triangles in file order; a polygon `v0..vk` is fan-triangulated
//! into `(v0, vi, vi+1)`. Degenerate triangles (repeated indices, zero area) are
//! kept so that triangle ids stay aligned with other tools; faces with fewer than
//! three vertices produce no triangles (a warning is logged).
//!
//! Malformed files produce an [`Error`] naming the file and, where it applies,
//! the header line, the vertex or the face; the loader never panics on bad data.
//! Non-finite positions, normals or texture coordinates (NaN, infinities, doubles
//! beyond the `f32` range), indices outside `0..vertex count` and ascii integers
//! outside their declared type's range are errors.

use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::geometry::MeshData;

/// Reads a PLY file into triangle mesh data.
///
/// `normals` and `uvs` of the result are either empty or as long as `positions`.
pub fn load_ply(path: &Path) -> Result<MeshData> {
    let data = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_ply(&data).map_err(|message| Error::mesh(path, message))
}

/// Parses a whole PLY file held in memory; errors are plain messages that
/// [`load_ply`] attaches the path to.
fn parse_ply(data: &[u8]) -> std::result::Result<MeshData, String> {
    let header = parse_header(data)?;
    let body = &data[header.body_offset..];
    match header.format {
        Format::Ascii => read_body(&mut AsciiBody { data: body, pos: 0 }, &header, body.len()),
        Format::BinaryLittleEndian => read_body(
            &mut BinaryBody::<false> { data: body, pos: 0 },
            &header,
            body.len(),
        ),
        Format::BinaryBigEndian => read_body(
            &mut BinaryBody::<true> { data: body, pos: 0 },
            &header,
            body.len(),
        ),
    }
}

// ---------------------------------------------------------------------------
// Header
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => ScalarType::I8,
            "uchar" | "uint8" => ScalarType::U8,
            "short" | "int16" => ScalarType::I16,
            "ushort" | "uint16" => ScalarType::U16,
            "int" | "int32" => ScalarType::I32,
            "uint" | "uint32" => ScalarType::U32,
            "float" | "float32" => ScalarType::F32,
            "double" | "float64" => ScalarType::F64,
            _ => return None,
        })
    }

    fn is_integer(self) -> bool {
        !matches!(self, ScalarType::F32 | ScalarType::F64)
    }

    /// The PLY name of the type (for messages).
    fn name(self) -> &'static str {
        match self {
            ScalarType::I8 => "char",
            ScalarType::U8 => "uchar",
            ScalarType::I16 => "short",
            ScalarType::U16 => "ushort",
            ScalarType::I32 => "int",
            ScalarType::U32 => "uint",
            ScalarType::F32 => "float",
            ScalarType::F64 => "double",
        }
    }

    /// The values an integer type holds (floats: all).
    fn range(self) -> (f64, f64) {
        match self {
            ScalarType::I8 => (i8::MIN as f64, i8::MAX as f64),
            ScalarType::U8 => (0.0, u8::MAX as f64),
            ScalarType::I16 => (i16::MIN as f64, i16::MAX as f64),
            ScalarType::U16 => (0.0, u16::MAX as f64),
            ScalarType::I32 => (i32::MIN as f64, i32::MAX as f64),
            ScalarType::U32 => (0.0, u32::MAX as f64),
            ScalarType::F32 | ScalarType::F64 => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PropertyType {
    Scalar(ScalarType),
    List { count: ScalarType, item: ScalarType },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    ty: PropertyType,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    fn property(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }

    /// Index of a scalar property called `name`, if there is one.
    fn scalar_property(&self, name: &str) -> Option<usize> {
        self.property(name)
            .filter(|&i| matches!(self.properties[i].ty, PropertyType::Scalar(_)))
    }
}

#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Byte offset of the body (just past the `end_header` line).
    body_offset: usize,
}

fn parse_header(data: &[u8]) -> std::result::Result<Header, String> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0usize;
    let mut line_no = 0usize;
    loop {
        if pos >= data.len() {
            return Err(if line_no == 0 {
                "empty file, not a PLY file".to_string()
            } else {
                "malformed PLY header: no `end_header` line".to_string()
            });
        }
        let end = data[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(data.len(), |i| pos + i);
        let raw = &data[pos..end];
        pos = end + 1;
        line_no += 1;
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(if line_no == 1 {
                "not a PLY file (the first line must be `ply`)".to_string()
            } else {
                format!("malformed PLY header: line {line_no} is not text")
            });
        };
        let line = line.trim();
        if line_no == 1 {
            if line != "ply" {
                return Err("not a PLY file (the first line must be `ply`)".to_string());
            }
            continue;
        }
        let bad = |what: &str| format!("malformed PLY header, line {line_no}: {what}: `{line}`");
        let mut words = line.split_ascii_whitespace();
        let Some(keyword) = words.next() else {
            continue; // tolerate blank lines
        };
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                if format.is_some() {
                    return Err(bad("second `format` line"));
                }
                let f = match words.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::BinaryLittleEndian,
                    Some("binary_big_endian") => Format::BinaryBigEndian,
                    _ => return Err(bad("unknown format")),
                };
                match words.next() {
                    Some(version) if version.starts_with('1') => {}
                    _ => return Err(bad("unsupported or missing format version")),
                }
                format = Some(f);
            }
            "element" => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(bad("expected `element <name> <count>`"));
                };
                let count = count
                    .parse::<usize>()
                    .map_err(|_| bad("element count is not a non-negative integer"))?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(bad("duplicate element"));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(bad("property before any element"));
                };
                let words: Vec<&str> = words.collect();
                let (ty, name) = match words.as_slice() {
                    ["list", count, item, name] => {
                        let count = ScalarType::parse(count)
                            .ok_or_else(|| bad("unknown list count type"))?;
                        let item =
                            ScalarType::parse(item).ok_or_else(|| bad("unknown list item type"))?;
                        if !count.is_integer() {
                            return Err(bad("list count type must be an integer type"));
                        }
                        (PropertyType::List { count, item }, *name)
                    }
                    [ty, name] => (
                        PropertyType::Scalar(
                            ScalarType::parse(ty).ok_or_else(|| bad("unknown property type"))?,
                        ),
                        *name,
                    ),
                    _ => return Err(bad("expected `property <type> <name>`")),
                };
                if element.property(name).is_some() {
                    return Err(bad("duplicate property"));
                }
                element.properties.push(Property {
                    name: name.to_string(),
                    ty,
                });
            }
            "end_header" => break,
            _ => return Err(bad("unknown keyword")),
        }
    }
    let format = format.ok_or_else(|| "malformed PLY header: no `format` line".to_string())?;
    Ok(Header {
        format,
        elements,
        body_offset: pos.min(data.len()),
    })
}

// ---------------------------------------------------------------------------
// Body readers
// ---------------------------------------------------------------------------

/// A source of scalar values: the ascii or binary body of the file.
trait Body {
    /// Reads one value of type `ty`, widened to `f64` (exact for every PLY type).
    fn read(&mut self, ty: ScalarType) -> std::result::Result<f64, String>;

    /// Reads a list count.
    fn read_count(&mut self, ty: ScalarType) -> std::result::Result<usize, String> {
        let n = self.read(ty)?;
        if n < 0.0 || n.fract() != 0.0 {
            return Err(format!("invalid list length {n}"));
        }
        Ok(n as usize)
    }

    /// Reads and discards one property value (a scalar or a whole list).
    fn skip(&mut self, ty: PropertyType) -> std::result::Result<(), String> {
        match ty {
            PropertyType::Scalar(t) => {
                self.read(t)?;
            }
            PropertyType::List { count, item } => {
                let n = self.read_count(count)?;
                for _ in 0..n {
                    self.read(item)?;
                }
            }
        }
        Ok(())
    }
}

const UNEXPECTED_EOF: &str = "unexpected end of file";

/// Binary body; `BIG` selects big-endian byte order.
struct BinaryBody<'a, const BIG: bool> {
    data: &'a [u8],
    pos: usize,
}

impl<const BIG: bool> BinaryBody<'_, BIG> {
    #[inline]
    fn take<const N: usize>(&mut self) -> std::result::Result<[u8; N], String> {
        let bytes = self
            .data
            .get(self.pos..self.pos + N)
            .ok_or_else(|| UNEXPECTED_EOF.to_string())?;
        self.pos += N;
        let mut out = [0u8; N];
        out.copy_from_slice(bytes);
        Ok(out)
    }
}

macro_rules! decode {
    ($self:ident, $t:ty, $n:literal) => {{
        let b = $self.take::<$n>()?;
        (if BIG {
            <$t>::from_be_bytes(b)
        } else {
            <$t>::from_le_bytes(b)
        }) as f64
    }};
}

impl<const BIG: bool> Body for BinaryBody<'_, BIG> {
    #[inline]
    fn read(&mut self, ty: ScalarType) -> std::result::Result<f64, String> {
        Ok(match ty {
            ScalarType::I8 => decode!(self, i8, 1),
            ScalarType::U8 => decode!(self, u8, 1),
            ScalarType::I16 => decode!(self, i16, 2),
            ScalarType::U16 => decode!(self, u16, 2),
            ScalarType::I32 => decode!(self, i32, 4),
            ScalarType::U32 => decode!(self, u32, 4),
            ScalarType::F32 => decode!(self, f32, 4),
            ScalarType::F64 => decode!(self, f64, 8),
        })
    }
}

/// Ascii body: whitespace-separated tokens (line structure is not required).
struct AsciiBody<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> AsciiBody<'a> {
    fn token(&mut self) -> Option<&'a [u8]> {
        let data = self.data;
        while self.pos < data.len() && data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < data.len() && !data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        (self.pos > start).then(|| &data[start..self.pos])
    }
}

impl Body for AsciiBody<'_> {
    fn read(&mut self, ty: ScalarType) -> std::result::Result<f64, String> {
        let token = self.token().ok_or_else(|| UNEXPECTED_EOF.to_string())?;
        let text = std::str::from_utf8(token).map_err(|_| "non-text data in ascii body")?;
        let value = if ty.is_integer() {
            let v = match text.parse::<i64>() {
                Ok(v) => v as f64,
                // Some writers print integers as `3.0`; accept integral floats.
                Err(_) => match text.parse::<f64>() {
                    Ok(v) if v.fract() == 0.0 => v,
                    _ => return Err(format!("`{text}` is not an integer")),
                },
            };
            let (min, max) = ty.range();
            if v < min || v > max {
                return Err(format!("`{text}` is out of range for {}", ty.name()));
            }
            v
        } else {
            text.parse::<f64>()
                .map_err(|_| format!("`{text}` is not a number"))?
        };
        Ok(value)
    }
}

// ---------------------------------------------------------------------------
// Mesh assembly
// ---------------------------------------------------------------------------

/// Slots of the per-vertex value array.
const X: usize = 0;
const NX: usize = 3;
const U: usize = 6;
const C: usize = 8;
const SLOTS: usize = 11;

const COLOR_NAMES: [[&str; 3]; 4] = [
    ["red", "green", "blue"],
    ["r", "g", "b"],
    ["diffuse_red", "diffuse_green", "diffuse_blue"],
    // As Mitsuba 3 writes a three-channel attribute.
    ["color_0", "color_1", "color_2"],
];

const UV_NAMES: [(&str, &str); 4] = [
    ("u", "v"),
    ("s", "t"),
    ("texture_u", "texture_v"),
    ("texture_s", "texture_t"),
];

/// An element's colour properties (the first of [`COLOR_NAMES`] it has all three of)
/// and how each channel's stored value becomes linear RGB.
fn color_properties(element: &Element) -> Option<([usize; 3], [ColorDecode; 3])> {
    let props = COLOR_NAMES.iter().find_map(|names| {
        let [r, g, b] = names.map(|n| element.scalar_property(n));
        Some([r?, g?, b?])
    })?;
    let decode = props.map(|i| match element.properties[i].ty {
        PropertyType::Scalar(ty @ (ScalarType::U8 | ScalarType::U16 | ScalarType::U32)) => {
            ColorDecode::Srgb(ty.range().1)
        }
        _ => ColorDecode::Linear,
    });
    Some((props, decode))
}

/// How a colour channel's stored value becomes linear RGB.
#[derive(Debug, Clone, Copy)]
enum ColorDecode {
    /// Floats (and signed integers): the value itself.
    Linear,
    /// Unsigned integers: sRGB-encoded over `0..=max`.
    Srgb(f64),
}

impl ColorDecode {
    fn linear(self, value: f64) -> f32 {
        match self {
            ColorDecode::Linear => value as f32,
            ColorDecode::Srgb(max) => crate::io::image::srgb_to_linear((value / max) as f32),
        }
    }
}

/// Decodes the body into a mesh. `body_len` (bytes) bounds up-front reservations:
/// every vertex and face row takes at least one byte, so a header that lies about
/// its counts cannot trigger a huge allocation.
fn read_body<B: Body>(
    body: &mut B,
    header: &Header,
    body_len: usize,
) -> std::result::Result<MeshData, String> {
    let vertex = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .ok_or_else(|| "no `vertex` element in the header".to_string())?;
    if vertex.count > u32::MAX as usize {
        return Err(format!("too many vertices ({})", vertex.count));
    }

    // Where each vertex property goes (None: skipped).
    let mut slots: Vec<Option<usize>> = vec![None; vertex.properties.len()];
    for (slot, name) in ["x", "y", "z"].iter().enumerate() {
        let i = vertex
            .scalar_property(name)
            .ok_or_else(|| format!("the `vertex` element has no scalar property `{name}`"))?;
        slots[i] = Some(X + slot);
    }
    let normal_props = ["nx", "ny", "nz"].map(|n| vertex.scalar_property(n));
    let has_normals = normal_props.iter().all(Option::is_some);
    if has_normals {
        for (slot, i) in normal_props.iter().flatten().enumerate() {
            slots[*i] = Some(NX + slot);
        }
    }
    let uv_props = UV_NAMES
        .iter()
        .find_map(|(u, v)| Some((vertex.scalar_property(u)?, vertex.scalar_property(v)?)));
    if let Some((u, v)) = uv_props {
        slots[u] = Some(U);
        slots[v] = Some(U + 1);
    }
    let has_uvs = uv_props.is_some();
    // Vertex colours, and how each channel's stored value becomes linear RGB.
    let color_props = color_properties(vertex);
    let mut color_decode = [ColorDecode::Linear; 3];
    if let Some((props, decode)) = color_props {
        for (c, &i) in props.iter().enumerate() {
            slots[i] = Some(C + c);
        }
        color_decode = decode;
    }
    let has_colors = color_props.is_some();

    let face = header
        .elements
        .iter()
        .find(|e| e.name == "face")
        .ok_or_else(|| {
            "no `face` element in the header (point clouds are not supported)".to_string()
        })?;
    let index_property = face
        .property("vertex_indices")
        .or_else(|| face.property("vertex_index"))
        .ok_or_else(|| {
            "the `face` element has no `vertex_indices` or `vertex_index` property".to_string()
        })?;
    let PropertyType::List {
        count: index_count_ty,
        item: index_ty,
    } = face.properties[index_property].ty
    else {
        return Err("the face property `vertex_indices` is not a list".to_string());
    };

    let cap = |n: usize| n.min(body_len);
    let mut mesh = MeshData {
        positions: Vec::with_capacity(cap(vertex.count)),
        normals: Vec::with_capacity(if has_normals { cap(vertex.count) } else { 0 }),
        uvs: Vec::with_capacity(if has_uvs { cap(vertex.count) } else { 0 }),
        indices: Vec::with_capacity(cap(face.count)),
        colors: Vec::with_capacity(if has_colors { cap(vertex.count) } else { 0 }),
        face_colors: Vec::new(),
    };
    let vertex_count = vertex.count;
    // Face colours, used where the vertices have none: one per triangle while reading.
    let face_colors = if has_colors {
        None
    } else {
        color_properties(face)
    };
    let mut short_faces = 0usize;
    let mut polygon: Vec<u32> = Vec::with_capacity(8);

    for element in &header.elements {
        if std::ptr::eq(element, vertex) {
            let mut values = [0f64; SLOTS];
            for v in 0..element.count {
                for (property, slot) in element.properties.iter().zip(&slots) {
                    let result = match (slot, property.ty) {
                        (Some(slot), PropertyType::Scalar(ty)) => {
                            body.read(ty).map(|value| values[*slot] = value)
                        }
                        (_, ty) => body.skip(ty),
                    };
                    result.map_err(|e| format!("vertex {v}, property `{}`: {e}", property.name))?;
                }
                // Three slots from `at` as a vector (each value through `decode`), or an
                // error naming the vertex when one is not finite.
                let vector = |what: &str, at: usize, decode: &dyn Fn(usize, f64) -> f32| {
                    let value =
                        Vec3::from_array(std::array::from_fn(|k| decode(k, values[at + k])));
                    if value.is_finite() {
                        Ok(value)
                    } else {
                        Err(format!(
                            "vertex {v} has a non-finite {what} ({}, {}, {})",
                            values[at],
                            values[at + 1],
                            values[at + 2]
                        ))
                    }
                };
                let float = |_: usize, x: f64| x as f32;
                mesh.positions.push(vector("position", X, &float)?);
                if has_normals {
                    mesh.normals.push(vector("normal", NX, &float)?);
                }
                if has_uvs {
                    let uv = Vec2::new(values[U] as f32, values[U + 1] as f32);
                    if !uv.is_finite() {
                        return Err(format!(
                            "vertex {v} has non-finite texture coordinates ({}, {})",
                            values[U],
                            values[U + 1]
                        ));
                    }
                    mesh.uvs.push(uv);
                }
                if has_colors {
                    let decode = |k: usize, x: f64| color_decode[k].linear(x);
                    mesh.colors.push(vector("colour", C, &decode)?);
                }
            }
        } else if std::ptr::eq(element, face) {
            for f in 0..element.count {
                let first_triangle = mesh.indices.len();
                let mut color = [0f64; 3];
                for (p, property) in element.properties.iter().enumerate() {
                    let context =
                        |e: String| format!("face {f}, property `{}`: {e}", property.name);
                    let channel =
                        face_colors.and_then(|(props, _)| props.iter().position(|&i| i == p));
                    if let (Some(c), PropertyType::Scalar(ty)) = (channel, property.ty) {
                        color[c] = body.read(ty).map_err(context)?;
                        continue;
                    }
                    if p != index_property {
                        body.skip(property.ty).map_err(context)?;
                        continue;
                    }
                    let n = body.read_count(index_count_ty).map_err(context)?;
                    polygon.clear();
                    for _ in 0..n {
                        let index = body.read(index_ty).map_err(context)?;
                        if !(index >= 0.0 && index < vertex_count as f64 && index.fract() == 0.0) {
                            return Err(format!(
                                "face {f} has vertex index {index} out of range (the file has {vertex_count} vertices)"
                            ));
                        }
                        polygon.push(index as u32);
                    }
                    if polygon.len() < 3 {
                        short_faces += 1;
                    }
                    for i in 1..polygon.len().saturating_sub(1) {
                        mesh.indices.push([polygon[0], polygon[i], polygon[i + 1]]);
                    }
                }
                if let Some((_, decode)) = face_colors {
                    let c = Vec3::from_array(std::array::from_fn(|k| decode[k].linear(color[k])));
                    if !c.is_finite() {
                        return Err(format!(
                            "face {f} has a non-finite colour ({}, {}, {})",
                            color[0], color[1], color[2]
                        ));
                    }
                    let added = mesh.indices.len() - first_triangle;
                    mesh.face_colors.extend(std::iter::repeat_n(c, added));
                }
            }
        } else {
            for row in 0..element.count {
                for property in &element.properties {
                    body.skip(property.ty).map_err(|e| {
                        format!(
                            "element `{}` row {row}, property `{}`: {e}",
                            element.name, property.name
                        )
                    })?;
                }
            }
        }
    }
    if short_faces > 0 {
        log::warn!("PLY: {short_faces} face(s) with fewer than 3 vertices ignored");
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
                std::env::temp_dir().join(format!("lightpath-ply-test-{}-{n}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("create temp dir");
            TempDir(dir)
        }

        fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
            let path = self.0.join(name);
            std::fs::write(&path, bytes).expect("write temp file");
            path
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn load_bytes(bytes: &[u8]) -> Result<MeshData> {
        let dir = TempDir::new();
        let path = dir.write("mesh.ply", bytes);
        load_ply(&path)
    }

    fn mesh_error(bytes: &[u8]) -> String {
        match load_bytes(bytes) {
            Err(e @ Error::Mesh { .. }) => e.to_string(),
            other => panic!("expected a mesh error, got {other:?}"),
        }
    }

    const ASCII_QUAD: &str = "ply
format ascii 1.0
comment a quad and a degenerate triangle
element vertex 4
property float x
property float y
property float z
property float nx
property float ny
property float nz
property float u
property float v
element face 2
property list uchar int vertex_indices
end_header
0 0 0 0 0 1 0 0
1 0 0 0 0 1 1 0
1 1 0 0 0 1 1 1
0 1 0 0 0 1 0 1
4 0 1 2 3
3 1 1 2
";

    fn expected_quad() -> MeshData {
        MeshData {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            normals: vec![Vec3::Z; 4],
            uvs: vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 1.0),
            ],
            indices: vec![[0, 1, 2], [0, 2, 3], [1, 1, 2]],
            colors: Vec::new(),
            face_colors: Vec::new(),
        }
    }

    #[test]
    fn ascii_quad_fan_and_degenerate_kept() {
        let mesh = load_bytes(ASCII_QUAD.as_bytes()).expect("load");
        assert_eq!(mesh, expected_quad());
    }

    #[test]
    fn crlf_header_and_body() {
        let text = ASCII_QUAD.replace('\n', "\r\n");
        let mesh = load_bytes(text.as_bytes()).expect("load");
        assert_eq!(mesh, expected_quad());
    }

    /// Builds a binary PLY of the quad test mesh with double positions, `s`/`t`
    /// coordinates, an extra vertex property, an extra face property and an
    /// extra element, in the requested byte order.
    fn binary_quad(big: bool) -> Vec<u8> {
        let format = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut out = format!(
            "ply\nformat {format} 1.0\nelement vertex 4\nproperty double x\nproperty double y\n\
             property double z\nproperty uchar red\nproperty float nx\nproperty float ny\n\
             property float nz\nproperty float s\nproperty float t\n\
             element face 2\nproperty uchar flags\nproperty list ushort uint vertex_index\n\
             element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
        )
        .into_bytes();
        macro_rules! put {
            ($v:expr) => {
                if big {
                    out.extend_from_slice(&$v.to_be_bytes())
                } else {
                    out.extend_from_slice(&$v.to_le_bytes())
                }
            };
        }
        let m = expected_quad();
        for i in 0..4 {
            let p = m.positions[i].as_dvec3();
            put!(p.x);
            put!(p.y);
            put!(p.z);
            put!(200u8);
            put!(0.0f32);
            put!(0.0f32);
            put!(1.0f32);
            put!(m.uvs[i].x);
            put!(m.uvs[i].y);
        }
        put!(7u8);
        put!(4u16);
        for i in [0u32, 1, 2, 3] {
            put!(i);
        }
        put!(9u8);
        put!(3u16);
        for i in [1u32, 1, 2] {
            put!(i);
        }
        put!(0i32);
        put!(1i32);
        out
    }

    #[test]
    fn binary_little_and_big_endian() {
        for big in [false, true] {
            let mesh = load_bytes(&binary_quad(big)).expect("load");
            assert_eq!(mesh, expected_quad(), "big endian: {big}");
        }
    }

    #[test]
    fn truncated_binary_is_an_error() {
        let mut bytes = binary_quad(false);
        bytes.truncate(bytes.len() - 12);
        let message = mesh_error(&bytes);
        assert!(message.contains("face 1"), "{message}");
        assert!(message.contains("unexpected end of file"), "{message}");
    }

    /// Vertex colours under each name: floats as they are (linear), 8- and 16-bit
    /// unsigned integers over their range, decoded from sRGB; a NaN colour is an error.
    #[test]
    fn vertex_colours() {
        let srgb = crate::io::image::srgb_to_linear;
        for names in COLOR_NAMES {
            for (ty, values, expected) in [
                ("float", "0.25 1 0", Vec3::new(0.25, 1.0, 0.0)),
                (
                    "uchar",
                    "128 255 0",
                    Vec3::new(srgb(128.0 / 255.0), 1.0, 0.0),
                ),
                (
                    "ushort",
                    "65535 0 6554",
                    Vec3::new(1.0, 0.0, srgb(6554.0 / 65535.0)),
                ),
            ] {
                let [r, g, b] = names;
                let text = format!(
                    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                     property float y\nproperty float z\nproperty {ty} {r}\n\
                     property {ty} {g}\nproperty {ty} {b}\nelement face 1\n\
                     property list uchar uint vertex_indices\nend_header\n\
                     0 0 0 {values}\n1 0 0 {values}\n0 1 0 {values}\n3 0 1 2\n"
                );
                let mesh = load_bytes(text.as_bytes()).expect("load");
                assert_eq!(mesh.colors.len(), 3, "{names:?} {ty}");
                assert!(
                    (mesh.colors[2] - expected).abs().max_element() < 1e-6,
                    "{names:?} {ty}: {} against {expected}",
                    mesh.colors[2]
                );
            }
        }
        // Two of three channels are not a colour.
        let partial = ASCII_QUAD
            .replace("property float u\n", "property float red\n")
            .replace("property float v\n", "property float green\n");
        assert!(load_bytes(partial.as_bytes())
            .expect("load")
            .colors
            .is_empty());
        let nan = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                   property float y\nproperty float z\nproperty float r\nproperty float g\n\
                   property float b\nelement face 1\nproperty list uchar uint vertex_indices\n\
                   end_header\n0 0 0 1 1 1\n1 0 0 nan 1 1\n0 1 0 1 1 1\n3 0 1 2\n";
        let message = mesh_error(nan.as_bytes());
        assert!(
            message.contains("vertex 1 has a non-finite colour"),
            "{message}"
        );
    }

    /// Face colours, where the vertices have none: one per triangle of the face (a quad's
    /// two share it); `TriangleMesh::new` then gives each triangle vertices of its own.
    /// With vertex colours too, the faces' are not read.
    #[test]
    fn face_colours() {
        let text = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\n\
                    property float y\nproperty float z\nelement face 2\n\
                    property list uchar uint vertex_indices\nproperty uchar red\n\
                    property uchar green\nproperty uchar blue\nend_header\n\
                    0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n4 0 1 2 3 255 0 0\n3 1 4 2 0 0 255\n";
        let mesh = load_bytes(text.as_bytes()).expect("load");
        assert!(mesh.colors.is_empty());
        let (red, blue) = (Vec3::X, Vec3::Z);
        assert_eq!(mesh.face_colors, vec![red, red, blue]);
        let unwelded = mesh.clone().unweld_face_colors();
        assert_eq!(unwelded.positions.len(), 9);
        assert_eq!(unwelded.indices, vec![[0, 1, 2], [3, 4, 5], [6, 7, 8]]);
        assert_eq!(unwelded.colors[..3], [red; 3]);
        assert_eq!(unwelded.colors[6..], [blue; 3]);
        assert_eq!(unwelded.positions[7], mesh.positions[4]);
        let m =
            crate::geometry::TriangleMesh::new(mesh, false, crate::accel::AccelKind::Bvh2).unwrap();
        assert_eq!(m.colors.len(), 9);
        // Vertex colours win.
        let both = text
            .replace(
                "element face",
                "property float r\nproperty float g\nproperty float b\nelement face",
            )
            .replace(
                "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n",
                "0 0 0 1 1 1\n1 0 0 1 1 1\n1 1 0 1 1 1\n0 1 0 1 1 1\n2 0 0 1 1 1\n",
            );
        let mesh = load_bytes(both.as_bytes()).expect("load");
        assert_eq!(mesh.colors.len(), 5);
        assert!(mesh.face_colors.is_empty());
    }

    #[test]
    fn texture_coordinate_names() {
        for (u, v) in UV_NAMES {
            let text = format!(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nproperty float {u}\nproperty float {v}\n\
                 element face 1\nproperty list uchar uint vertex_indices\nend_header\n\
                 0 0 0 0.25 0.5\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n"
            );
            let mesh = load_bytes(text.as_bytes()).expect("load");
            assert_eq!(mesh.uvs.len(), 3, "{u}/{v}");
            assert_eq!(mesh.uvs[0], Vec2::new(0.25, 0.5), "{u}/{v}");
            assert!(mesh.normals.is_empty());
        }
    }

    #[test]
    fn positions_only_and_signed_index_types() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                    property float z\nelement face 1\nproperty list char short vertex_indices\n\
                    end_header\n0 0 0\n1 0 0\n0 1 0\n3 2 1 0\n";
        let mesh = load_bytes(text.as_bytes()).expect("load");
        assert_eq!(mesh.indices, vec![[2, 1, 0]]);
        assert!(mesh.normals.is_empty() && mesh.uvs.is_empty());
    }

    #[test]
    fn short_faces_produce_no_triangles() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                    property float z\nelement face 3\nproperty list uchar int vertex_indices\n\
                    end_header\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n0\n3 0 1 2\n";
        let mesh = load_bytes(text.as_bytes()).expect("load");
        assert_eq!(mesh.indices, vec![[0, 1, 2]]);
    }

    #[test]
    fn index_out_of_range_names_the_face() {
        let text = ASCII_QUAD.replace("3 1 1 2", "3 1 4 2");
        let message = mesh_error(text.as_bytes());
        assert!(message.contains("face 1"), "{message}");
        assert!(message.contains("out of range"), "{message}");
        let text = ASCII_QUAD.replace("3 1 1 2", "3 1 -1 2");
        let message = mesh_error(text.as_bytes());
        assert!(message.contains("face 1"), "{message}");
    }

    #[test]
    fn non_finite_position_names_the_vertex() {
        for bad in ["nan", "inf", "-inf", "1e300"] {
            let text = ASCII_QUAD.replace("1 1 0 0 0 1 1 1", &format!("1 {bad} 0 0 0 1 1 1"));
            let message = mesh_error(text.as_bytes());
            assert!(message.contains("vertex 2"), "{bad}: {message}");
        }
    }

    /// Appends `value` as PLY type `ty` in `format` (ascii: a token and a space).
    fn put_value(out: &mut Vec<u8>, format: &str, ty: &str, value: f64) {
        if format == "ascii" {
            out.extend_from_slice(format!("{value} ").as_bytes());
            return;
        }
        let big = format == "binary_big_endian";
        macro_rules! bytes {
            ($t:ty) => {{
                let v = value as $t;
                if big {
                    out.extend_from_slice(&v.to_be_bytes())
                } else {
                    out.extend_from_slice(&v.to_le_bytes())
                }
            }};
        }
        match ty {
            "char" | "int8" => bytes!(i8),
            "uchar" | "uint8" => bytes!(u8),
            "short" | "int16" => bytes!(i16),
            "ushort" | "uint16" => bytes!(u16),
            "int" | "int32" => bytes!(i32),
            "uint" | "uint32" => bytes!(u32),
            "float" | "float32" => bytes!(f32),
            "double" | "float64" => bytes!(f64),
            other => panic!("unknown type {other}"),
        }
    }

    const TYPES: [&str; 16] = [
        "char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8",
        "int16", "uint16", "int32", "uint32", "float32", "float64",
    ];
    const FORMATS: [&str; 3] = ["ascii", "binary_little_endian", "binary_big_endian"];

    /// Five vertices whose every property has type `vertex_ty`, a quad, a pentagon and a
    /// triangle whose list count and index types are `count_ty` and `index_ty`.
    fn typed_mesh(format: &str, vertex_ty: &str, count_ty: &str, index_ty: &str) -> Vec<u8> {
        let mut out = format!(
            "ply\nformat {format} 1.0\nelement vertex 5\n\
             property {vertex_ty} x\nproperty {vertex_ty} y\nproperty {vertex_ty} z\n\
             property {vertex_ty} nx\nproperty {vertex_ty} ny\nproperty {vertex_ty} nz\n\
             property {vertex_ty} u\nproperty {vertex_ty} v\n\
             element face 3\nproperty list {count_ty} {index_ty} vertex_indices\nend_header\n"
        )
        .into_bytes();
        for i in 0..5 {
            let i = i as f64;
            for value in [
                i,
                i % 2.0,
                2.0,
                0.0,
                0.0,
                1.0,
                i % 2.0,
                (i / 2.0).floor() % 2.0,
            ] {
                put_value(&mut out, format, vertex_ty, value);
            }
            if format == "ascii" {
                out.push(b'\n');
            }
        }
        for face in [
            &[0.0, 1.0, 2.0, 3.0][..],
            &[4.0, 3.0, 2.0, 1.0, 0.0],
            &[2.0, 4.0, 0.0],
        ] {
            put_value(&mut out, format, count_ty, face.len() as f64);
            for &index in face {
                put_value(&mut out, format, index_ty, index);
            }
            if format == "ascii" {
                out.push(b'\n');
            }
        }
        out
    }

    /// Every format and every scalar type name (aliases included) for vertex data, list
    /// counts and indices; quads and polygons fan-triangulated as `(v0, vi, vi+1)`.
    #[test]
    fn every_format_and_scalar_type() {
        let integers: Vec<&str> = TYPES
            .iter()
            .copied()
            .filter(|t| !t.starts_with("float") && *t != "double")
            .collect();
        let mut cases = 0;
        for format in FORMATS {
            for (k, vertex_ty) in TYPES.iter().enumerate() {
                let count_ty = integers[k % integers.len()];
                let index_ty = integers[(k + 3) % integers.len()];
                let bytes = typed_mesh(format, vertex_ty, count_ty, index_ty);
                let what = format!("{format} {vertex_ty} list {count_ty} {index_ty}");
                let mesh = load_bytes(&bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
                assert_eq!(
                    mesh.indices,
                    vec![
                        [0, 1, 2],
                        [0, 2, 3],
                        [4, 3, 2],
                        [4, 2, 1],
                        [4, 1, 0],
                        [2, 4, 0]
                    ],
                    "{what}"
                );
                for i in 0..5 {
                    let f = i as f32;
                    assert_eq!(mesh.positions[i], Vec3::new(f, f % 2.0, 2.0), "{what}");
                    assert_eq!(
                        mesh.uvs[i],
                        Vec2::new(f % 2.0, (f / 2.0).floor() % 2.0),
                        "{what}"
                    );
                }
                assert_eq!(mesh.normals, vec![Vec3::Z; 5], "{what}");
                cases += 1;
            }
        }
        assert_eq!(cases, 48);
    }

    /// NaN and infinities in any vertex data, in ascii and binary files, are errors that
    /// name the file and the vertex; so are ascii integers beyond their type.
    #[test]
    fn non_finite_vertex_data_and_out_of_range_values() {
        for format in FORMATS {
            for (slot, what) in [(0, "position"), (4, "normal"), (7, "texture")] {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300] {
                    let mut out = format!(
                        "ply\nformat {format} 1.0\nelement vertex 3\nproperty double x\n\
                         property double y\nproperty double z\nproperty double nx\n\
                         property double ny\nproperty double nz\nproperty double u\n\
                         property double v\nelement face 1\n\
                         property list uchar int vertex_indices\nend_header\n"
                    )
                    .into_bytes();
                    for v in 0..3 {
                        for s in 0..8 {
                            let value = if v == 1 && s == slot { bad } else { 0.5 };
                            put_value(&mut out, format, "double", value);
                        }
                    }
                    put_value(&mut out, format, "uchar", 3.0);
                    for i in 0..3 {
                        put_value(&mut out, format, "int", i as f64);
                    }
                    let dir = TempDir::new();
                    let path = dir.write("bad.ply", &out);
                    let message = load_ply(&path).expect_err("non-finite").to_string();
                    assert!(
                        message.starts_with(&path.display().to_string()),
                        "{message}"
                    );
                    assert!(
                        message.contains("vertex 1") && message.contains(what),
                        "{format} {slot} {bad}: {message}"
                    );
                }
            }
        }
        let text = ASCII_QUAD.replace("4 0 1 2 3", "256 0 1 2 3");
        let message = mesh_error(text.as_bytes());
        assert!(
            message.contains("face 0") && message.contains("out of range for uchar"),
            "{message}"
        );
        let text = ASCII_QUAD
            .replace("list uchar int", "list uchar char")
            .replace("3 1 1 2", "3 1 200 2");
        let message = mesh_error(text.as_bytes());
        assert!(message.contains("face 1"), "{message}");
    }

    #[test]
    fn malformed_headers() {
        let cases: &[(&str, &str)] = &[
            ("", "empty file"),
            ("plx\nformat ascii 1.0\nend_header\n", "not a PLY file"),
            ("ply\nformat ascii 1.0\nelement vertex 1\n", "end_header"),
            ("ply\nformat text 1.0\nend_header\n", "unknown format"),
            ("ply\nelement vertex 0\nend_header\n", "no `format`"),
            ("ply\nformat ascii 1.0\nelement vertex x\nend_header\n", "element count"),
            ("ply\nformat ascii 1.0\nproperty float x\nend_header\n", "before any element"),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n",
                "unknown property type",
            ),
            ("ply\nformat ascii 1.0\nbogus\nend_header\n", "unknown keyword"),
            (
                "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
                "no `vertex` element",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nend_header\n",
                "`z`",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
                "no `face` element",
            ),
        ];
        for (text, expected) in cases {
            let message = mesh_error(text.as_bytes());
            assert!(message.contains(expected), "{text:?}: {message}");
            assert!(message.contains("mesh.ply"), "{message}");
        }
    }

    #[test]
    fn garbage_body_is_an_error() {
        let text = ASCII_QUAD.replace("1 0 0 0 0 1 1 0", "1 zero 0 0 0 1 1 0");
        let message = mesh_error(text.as_bytes());
        assert!(message.contains("vertex 1"), "{message}");
        let text = ASCII_QUAD.replace("3 1 1 2\n", "3 1 1\n");
        let message = mesh_error(text.as_bytes());
        assert!(message.contains("face 1"), "{message}");
    }

    #[test]
    fn missing_file_is_an_io_error() {
        let dir = TempDir::new();
        let result = load_ply(&dir.0.join("does-not-exist.ply"));
        assert!(matches!(result, Err(Error::Io { .. })), "{result:?}");
    }

    #[test]
    fn empty_mesh_is_fine() {
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
                    property float y\nproperty float z\nelement face 0\n\
                    property list uchar int vertex_indices\nend_header\n";
        let mesh = load_bytes(text.as_bytes()).expect("load");
        assert_eq!(mesh, MeshData::default());
    }

    /// The Stanford bunny from the shared data, when it is present.
    #[test]
    fn stanford_bunny_counts() {
        let path = Path::new("/work/shared/models/stanford-bunny/bunny.ply");
        if !path.exists() {
            eprintln!("skipped: {} not present", path.display());
            return;
        }
        let mesh = load_ply(path).expect("load bunny");
        assert_eq!(mesh.positions.len(), 35_947);
        assert_eq!(mesh.indices.len(), 69_451);
        assert!(mesh.normals.is_empty() && mesh.uvs.is_empty());
    }

    /// The lightwave test meshes, when present: normals and uvs per vertex.
    #[test]
    fn lightwave_meshes() {
        let dir = Path::new("/work/shared/anchors/lightwave/tests/meshes");
        let Ok(entries) = std::fs::read_dir(dir) else {
            eprintln!("skipped: {} not present", dir.display());
            return;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.extension().and_then(|e| e.to_str()) != Some("ply") {
                continue;
            }
            let mesh = load_ply(&path).expect("load");
            assert!(!mesh.indices.is_empty(), "{}", path.display());
            assert_eq!(
                mesh.normals.len(),
                mesh.positions.len(),
                "{}",
                path.display()
            );
            assert_eq!(mesh.uvs.len(), mesh.positions.len(), "{}", path.display());
        }
    }

    /// Load time of the 1.1M-triangle bunny; run with
    /// `cargo test --release -p lightpath --lib io::ply -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bunny_loop2_load_time() {
        let path = Path::new("/work/shared/models/bunny-loop2/bunny_loop2.ply");
        if !path.exists() {
            return;
        }
        let mut best = f64::INFINITY;
        let mut mesh = MeshData::default();
        for _ in 0..3 {
            let start = std::time::Instant::now();
            mesh = load_ply(path).expect("load");
            best = best.min(start.elapsed().as_secs_f64());
        }
        eprintln!(
            "bunny_loop2.ply: {} vertices, {} triangles in {:.1} ms (best of 3)",
            mesh.positions.len(),
            mesh.indices.len(),
            best * 1e3
        );
        assert_eq!(mesh.indices.len(), 1_111_216);
    }
}
