//! Triangle meshes with flat or smooth (interpolated) normals and uvs, each with its own
//! bottom-level BVH, intersected with the watertight test of Woop, Benthin and Wald
//! (JCGT 2013): rays through shared edges and vertices never slip through a closed mesh.
//! With the wide BVHs (`bvh4`, `bvh8`, the default) the triangles are also kept packed in
//! the order of the tree's leaves ([`super::TriangleBlock`]) and tested four at a time,
//! or eight with AVX2, with results equal to the scalar test's bit for bit.
//!
//! ```xml
//! <instance>
//!     <shape type="mesh" filename="bunny.ply" smooth="true"/>
//! </instance>
//! ```

#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
use super::packet::{self, PacketHits, RayPacket, PACKET};
#[cfg(target_arch = "x86_64")]
use super::triangle_block::intersect_pair;
use super::triangle_block::{nearest_lane, TriangleBlock, BLOCK};
use super::{MeshData, ShapeHit, SurfaceInteraction};
use crate::accel::{Accel, AccelKind, RayStats};
use crate::math::{gamma, unit, Bounds3, Frame, Ray};
use glam::{Vec2, Vec3, Vec3A};

/// The closest-hit query over a mesh's SIMD blocks, as a macro so that it expands both
/// in [`TriangleMesh::intersect`] and inside the AVX2 and AVX-512 functions
/// ([`TriangleMesh::intersect_blocks_avx2`]): the leaf closure, which the traversal does
/// not inline, is then itself compiled for their features (closures inherit their
/// function's target features), with three-operand arithmetic and the 8-lane pair test
/// inlined. No multiplication and addition are fused (the `crate::cpu` tiers enable
/// FMA, but Rust never contracts on its own), so all expansions round alike.
macro_rules! intersect_blocks {
    ($mesh:expr, $ray:expr, $stats:expr, $avx2:expr, $masked:expr) => {{
        let (mesh, ray): (&TriangleMesh, &Ray) = ($mesh, $ray);
        // The watertight test's constants are set up at the first leaf, so rays that
        // reach none (most of those that miss) never pay for them.
        let mut lazy_wr = None;
        // The closest hit as (t, leaf position, barycentrics); the triangle's index is
        // read once at the end, from its block.
        let mut closest: Option<(f32, usize, Vec2)> = None;
        let prefetch = |first| mesh.prefetch_block(first);
        mesh.accel
            .intersect_leaves(ray, $stats, prefetch, |first, count, t_max| {
                let wr = &*lazy_wr.get_or_insert_with(|| WatertightRay::new(ray));
                mesh.leaf_closest::<{ $avx2 }, { $masked }>(
                    wr,
                    ray,
                    first,
                    count,
                    t_max,
                    &mut closest,
                )
            });
        closest.map(|(t, at, uv)| ShapeHit {
            t,
            prim: mesh.block_prim(at),
            uv,
        })
    }};
}

/// The any-hit query over a mesh's SIMD blocks (see [`intersect_blocks`]).
macro_rules! occluded_blocks {
    ($mesh:expr, $ray:expr, $stats:expr, $avx2:expr, $masked:expr) => {{
        let (mesh, ray): (&TriangleMesh, &Ray) = ($mesh, $ray);
        let prefetch = |first| mesh.prefetch_block(first);
        let mut lazy_wr = None;
        mesh.accel
            .occluded_leaves(ray, $stats, prefetch, |first, count| {
                let wr = &*lazy_wr.get_or_insert_with(|| WatertightRay::new(ray));
                mesh.leaf_blocks::<{ $avx2 }, { $masked }>(wr, ray, first, count)
            })
    }};
}

/// A triangle mesh in object space and its acceleration structure.
#[derive(Debug, Clone)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    /// Linear RGB per vertex, or empty.
    pub colors: Vec<Vec3>,
    /// Interpolate vertex normals (when the mesh has them).
    pub smooth: bool,
    pub accel: Accel,
    /// The triangles in the order of the accelerator's leaves, four to a SIMD block,
    /// when the accelerator hands out whole leaves (the wide BVHs); empty otherwise.
    blocks: Vec<TriangleBlock>,
    /// The accelerator's box, where the mesh has blocks and at least 90% of its triangles
    /// have an area of [`DELTA_T_BOUND_AREA`] times the box's largest extent squared;
    /// else empty. [`RayPacket::new`] bounds the triangle tests' `delta_t` from it.
    #[cfg_attr(not(all(target_arch = "x86_64", lightpath_avx512)), allow(dead_code))]
    delta_t_box: Bounds3,
    /// Whether the processor has the AVX2 tier (`crate::cpu`): the queries are then
    /// compiled for it.
    avx2: bool,
    /// Whether a leaf's blocks are tested two at a time as 8 lanes (AVX2 on full-width
    /// 256-bit units, [`crate::cpu::leaf_blocks_per_test`]); else one at a time as 4.
    /// Implies `avx2`.
    pair_blocks: bool,
    /// Whether the processor has AVX-512 (F, VL, DQ, BW) and the compiler its target
    /// features (`lightpath_avx512`): the block queries are then compiled for it (see
    /// [`crate::cpu::has_avx512`]).
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    avx512: bool,
    /// A packet's leaf entered by `r` rays in `b` blocks is tested ray by ray (each ray
    /// against 8-lane pairs of blocks) where `r · ⌈b/2⌉ ≤ leaf_rays · b`, else sixteen
    /// lanes at a time ([`crate::cpu::packet_leaf_rays_per_block`]).
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    leaf_rays: u32,
    /// The packets' leaves whose triangles share corners (see
    /// [`packet::SharedCorners`]).
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    shared: packet::SharedCorners,
    /// Triangle areas for area sampling, built the first time the mesh emits light.
    area_distribution: std::sync::OnceLock<crate::sampling::Distribution1D>,
    /// Triangles whose geometric normal points against their winding's (a mirrored
    /// instance flattened into render space keeps its corners, and so its texture
    /// parameterisation, and marks the triangle instead); empty when none is.
    flipped: Vec<bool>,
    /// Where the surface is not there for rays (see [`AlphaMask`]); `None`: everywhere.
    alpha: Option<AlphaMask>,
    /// The mesh without the triangles in its box's faces, for shadow rays inside the box.
    occluders: Option<Box<Occluders>>,
}

/// The triangles of a mesh that lie in a face of its box (all three corners on one of
/// the box's six planes: a room's walls, floor and ceiling, a ground plane under the
/// rest, a box's sides) cannot block a segment that starts in the box and ends inside
/// it: the segment meets such a face's plane at most at its start, where the triangle
/// test rejects a hit as not provably in front of the origin. So shadow rays whose
/// segments lie so ([`Occluders::hold`]) are traced against the mesh without them:
/// the same answers, with fewer triangles and tighter boxes. On Mitsuba's Cornell box
/// 14 of the 38 triangles are in the box's faces (the floor, the ceiling, the back and
/// the left wall, and the blocks' bottoms), and every shadow ray to the light, which
/// hangs half a unit below the ceiling, is such a segment.
///
/// A segment's end must lie inside the box by a margin of `2⁻¹²` of the box's size:
/// far more than the rounding of the end point and of the triangle test's distance, so
/// that a segment that ends just short of a face is not taken for one that reaches it.
/// Built for wide BVHs of at most [`OCCLUDERS_TRIANGLES`] triangles, a sixteenth or more
/// of which lie in the box's faces.
#[derive(Debug, Clone)]
struct Occluders {
    /// The mesh without the triangles in the box's faces; `None` where no other is left.
    mesh: Option<TriangleMesh>,
    /// The mesh's box: segments start in it, faces included.
    outer: Bounds3,
    /// The box shrunk by the margin: segments end strictly inside it.
    inner: Bounds3,
    /// The triangles in the box's faces, for closest hits (packets and single rays),
    /// which trace `mesh` for the others; `None` where there are more than a packet's
    /// width of them, or no others. Their entries follow `mesh`'s own blocks there.
    faces: Option<Box<FaceTable>>,
}

/// The most triangles a mesh may have for [`Occluders`] to be built for it (their BVH
/// is a second copy of most of the mesh's).
const OCCLUDERS_TRIANGLES: usize = 1 << 17;

impl Occluders {
    /// The occluders of the mesh of `positions` and `indices` whose accelerator (over
    /// those triangles, built as `kind`) is `accel` and box `bounds`, where they are
    /// built (see [`Occluders`]); their own accelerator is built as `kind` too.
    fn new(
        positions: &[Vec3],
        indices: &[[u32; 3]],
        kind: AccelKind,
        accel: &Accel,
        bounds: Bounds3,
    ) -> Result<Option<Box<Occluders>>, String> {
        if !matches!(accel, Accel::Bvh8(_) | Accel::Bvh4(_)) {
            return Ok(None);
        }
        if indices.is_empty() || indices.len() > OCCLUDERS_TRIANGLES || bounds.is_empty() {
            return Ok(None);
        }
        let size = (bounds.max - bounds.min).max_element()
            + bounds.min.abs().max(bounds.max.abs()).max_element();
        let margin = Vec3::splat(size / 4096.0);
        let inner = Bounds3 {
            min: bounds.min + margin,
            max: bounds.max - margin,
        };
        if !inner.min.cmplt(inner.max).all() {
            // A flat mesh: no segment ends inside it.
            return Ok(None);
        }
        // The face (`2k` for the `min[k]` plane, `2k + 1` for `max[k]`) a triangle lies in.
        let face_of = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            (0..6).find(|&f| {
                let k = f / 2;
                let p = if f % 2 == 0 {
                    bounds.min[k]
                } else {
                    bounds.max[k]
                };
                a[k] == p && b[k] == p && c[k] == p
            })
        };
        let mut kept = Vec::new();
        let mut kept_prims = Vec::new();
        let mut in_faces: [Vec<u32>; 6] = Default::default();
        for (i, t) in indices.iter().enumerate() {
            match face_of(t) {
                Some(f) => in_faces[f].push(i as u32),
                None => {
                    kept.push(*t);
                    kept_prims.push(i as u32);
                }
            }
        }
        let faces = indices.len() - kept.len();
        if faces == 0 || faces * 16 < indices.len() {
            return Ok(None);
        }
        let mut mesh = if kept.is_empty() {
            None
        } else {
            let data = MeshData {
                positions: positions.to_vec(),
                indices: kept,
                ..MeshData::default()
            };
            Some(TriangleMesh::new_in_pool(data, false, kind, false)?)
        };
        let faces = match &mut mesh {
            Some(m) if !m.blocks.is_empty() => {
                let corners =
                    |prim: u32| (prim, indices[prim as usize].map(|i| positions[i as usize]));
                let tables = in_faces
                    .clone()
                    .map(|f| f.into_iter().map(corners).collect());
                let base = (m.blocks.len() * BLOCK) as u32;
                let table = FaceTable::new(&tables, &bounds, margin.x, base);
                if table.is_some() {
                    // The mesh's hits name the whole mesh's triangles: its blocks'
                    // triangle indices become those, and the face triangles' blocks
                    // follow its own (the packets' hits gather their indices there).
                    for block in &mut m.blocks {
                        for p in &mut block.prim {
                            *p = kept_prims[*p as usize];
                        }
                    }
                    let order: Vec<u32> = in_faces.iter().flatten().copied().collect();
                    m.blocks.extend(pack_blocks(positions, indices, &order));
                }
                table.map(Box::new)
            }
            _ => None,
        };
        Ok(Some(Box::new(Occluders {
            mesh,
            outer: bounds,
            inner,
            faces,
        })))
    }

    /// Whether `ray`'s segment starts in the box and ends inside its margin, so that
    /// the triangles in the box's faces cannot block it.
    #[inline(always)]
    fn hold(&self, ray: &Ray) -> bool {
        let o = ray.origin;
        let end = o + ray.direction * ray.t_max;
        o.cmpge(self.outer.min).all()
            && o.cmple(self.outer.max).all()
            && end.cmpgt(self.inner.min).all()
            && end.cmplt(self.inner.max).all()
    }
}

/// The triangles of a mesh that lie in its box's faces (at most [`FACE_TABLE`]), for
/// closest-hit packets: such a triangle can only be hit where a ray crosses its face's
/// plane inside the face, so each ray tests only the triangles of the faces it crosses
/// there (its exit, and its entry where it starts outside), rather than every packet
/// testing all of them (see `mesh::Occluders`).
/// The most entries of a [`FaceTable`]: a packet's width, so that each of its rows is
/// one vector.
pub(crate) const FACE_TABLE: usize = 16;

#[derive(Debug, Clone)]
pub(crate) struct FaceTable {
    /// Corner `c`, axis `k` of entry `i`: `coords[c][k][i]` (the corners in the
    /// triangle's own order, as its block holds them).
    pub(super) coords: [[[f32; FACE_TABLE]; 3]; 3],
    /// The entries of face `2k` (the box's `min[k]` plane) and `2k + 1` (`max[k]`):
    /// `start..end`.
    pub(super) range: [(u32, u32); 6],
    /// Each face's plane.
    pub(super) plane: [f32; 6],
    /// The box widened by a margin far above rounding: a ray crossing a face's plane
    /// outside it misses the face's triangles.
    pub(super) lo: [f32; 3],
    pub(super) hi: [f32; 3],
    /// Leaf position of entry 0 (the entries follow in order).
    #[cfg_attr(not(all(target_arch = "x86_64", lightpath_avx512)), allow(dead_code))]
    pub(super) base: u32,
    /// Each entry's triangle in the mesh.
    prim: [u32; FACE_TABLE],
    /// Entries.
    pub(super) len: u32,
}

impl FaceTable {
    /// The table of `faces[f]` (the triangles in face `f`: their indices in the mesh
    /// and corners), whose
    /// first entry is at leaf position `base`, for the box `bounds` widened by
    /// `margin`; `None` beyond [`FACE_TABLE`] entries.
    pub(crate) fn new(
        faces: &[Vec<(u32, [Vec3; 3])>; 6],
        bounds: &Bounds3,
        margin: f32,
        base: u32,
    ) -> Option<FaceTable> {
        let len: usize = faces.iter().map(Vec::len).sum();
        if len == 0 || len > FACE_TABLE {
            return None;
        }
        let mut t = FaceTable {
            coords: [[[0.0; FACE_TABLE]; 3]; 3],
            range: [(0, 0); 6],
            plane: [0.0; 6],
            lo: (bounds.min - Vec3::splat(margin)).to_array(),
            hi: (bounds.max + Vec3::splat(margin)).to_array(),
            base,
            prim: [0; FACE_TABLE],
            len: len as u32,
        };
        let mut at = 0;
        for (f, tris) in faces.iter().enumerate() {
            t.plane[f] = if f % 2 == 0 {
                bounds.min[f / 2]
            } else {
                bounds.max[f / 2]
            };
            t.range[f] = (at as u32, (at + tris.len()) as u32);
            for (prim, tri) in tris {
                t.prim[at] = *prim;
                for (c, p) in tri.iter().enumerate() {
                    for k in 0..3 {
                        t.coords[c][k][at] = p[k];
                    }
                }
                at += 1;
            }
        }
        Some(t)
    }

    /// Entry `i`'s corners.
    pub(super) fn corners(&self, i: usize) -> (Vec3, Vec3, Vec3) {
        let c = |c: usize| {
            Vec3::new(
                self.coords[c][0][i],
                self.coords[c][1][i],
                self.coords[c][2][i],
            )
        };
        (c(0), c(1), c(2))
    }
    /// The closest hit of `ray` (whose watertight form is `wr`) among the table's
    /// triangles, as `(t, entry, barycentrics)`: the triangles and the order in which
    /// `packet::intersect_faces` tests them for a lane, with the same arithmetic, so
    /// that every tier finds the same hit.
    fn closest(&self, ray: &Ray, wr: &WatertightRay) -> Option<(f32, usize, Vec2)> {
        let (o, d) = (ray.origin, ray.direction);
        let mut crossed = [(0u32, 0u32); 2];
        let mut n = 0;
        for k in 0..3 {
            let r = 1.0 / d[k];
            for side in 0..2 {
                let f = 2 * k + side;
                let (start, end) = self.range[f];
                if start == end {
                    continue;
                }
                let t = (self.plane[f] - o[k]) * r;
                let inside = t > 0.0
                    && [(k + 1) % 3, (k + 2) % 3].iter().all(|&b| {
                        let p = o[b] + t * d[b];
                        p >= self.lo[b] && p <= self.hi[b]
                    });
                if inside {
                    if n < 2 {
                        crossed[n] = (start, end);
                    }
                    n += 1;
                }
            }
        }
        // (No allocation: this runs for every ray where packets do not.)
        let (first, second) = match n {
            0 => return None,
            1 => (crossed[0].0..crossed[0].1, 0..0),
            2 => (crossed[0].0..crossed[0].1, crossed[1].0..crossed[1].1),
            _ => (0..self.len, 0..0),
        };
        let entries = first.chain(second);
        let mut t_max = ray.t_max;
        let mut best = None;
        for e in entries {
            let (p0, p1, p2) = self.corners(e as usize);
            if let Some((t, _, b1, b2)) =
                intersect_triangle_watertight(wr, ray.t_min, t_max, p0, p1, p2)
            {
                t_max = t;
                best = Some((t, e as usize, Vec2::new(b1, b2)));
                if n == 1 {
                    break;
                }
            }
        }
        best
    }
}

/// A mesh's surface cut out or made partly transparent by a coverage texture (its
/// first channel at the hit's texture coordinates, α): where the surface is not there,
/// closest-hit and shadow rays pass through it as if the triangle were absent.
///
/// A masked mesh looks the coverage up at every candidate hit: the SIMD leaf tests drop
/// the lanes whose hit the mask removes (so the nearest remaining lane wins, and a
/// shadow ray is blocked only by a kept one); streams and packets go ray by ray. Area lights on a
/// masked mesh emit from the whole triangles.
///
/// Scene files make one from a glTF material's `alphaMode` (`MASK` with `alphaCutoff`:
/// [`AlphaTest::Cutoff`]; `BLEND`: [`AlphaTest::Stochastic`]), an MTL `map_d` (a cutoff
/// of one half), or a Mitsuba `mask` BSDF (stochastic):
///
/// ```xml
/// <shape type="rectangle">
///     <bsdf type="mask">
///         <texture name="opacity" type="bitmap">
///             <string name="filename" value="leaf_mask.png"/>
///         </texture>
///         <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
///     </bsdf>
/// </shape>
/// ```
#[derive(Debug, Clone)]
pub struct AlphaMask {
    pub coverage: std::sync::Arc<crate::texture::Texture>,
    pub test: AlphaTest,
}

impl AlphaMask {
    /// The fraction of rays that meet the surface at texture coordinates `uv`: 1 or 0
    /// for a cutoff, α clamped to [0, 1] for stochastic transparency (0 where α is NaN,
    /// which no ray meets either).
    pub fn coverage_at(&self, uv: Vec2) -> f32 {
        let alpha = self.coverage.eval(uv).x;
        match self.test {
            AlphaTest::Cutoff(cutoff) => f32::from(u8::from(alpha >= cutoff)),
            AlphaTest::Stochastic if alpha > 0.0 => alpha.min(1.0),
            AlphaTest::Stochastic => 0.0,
        }
    }
}

/// How an [`AlphaMask`]'s coverage decides whether a ray meets the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlphaTest {
    /// There where α is at least the cutoff (glTF's `MASK` with its `alphaCutoff`).
    Cutoff(f32),
    /// There with probability α (stochastic transparency: glTF's `BLEND`, Mitsuba's
    /// `mask`): each ray meets the surface at a point when α exceeds a uniform number
    /// hashed from the ray and the triangle, so a render averages to α times the
    /// surface plus 1 − α times what lies behind it, and the same ray always gets the
    /// same answer.
    Stochastic,
}

/// A uniform number in [0, 1) hashed from a ray's origin and direction and a triangle
/// (for [`AlphaTest::Stochastic`]).
#[inline]
fn alpha_hash(ray: &Ray, prim: u32) -> f32 {
    fn mix(mut z: u64) -> u64 {
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    let (o, d) = (ray.origin, ray.direction);
    let mut h = 0x9e37_79b9_7f4a_7c15 ^ u64::from(prim);
    for v in [o.x, o.y, o.z, d.x, d.y, d.z] {
        h = mix(h ^ u64::from(v.to_bits()));
    }
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// Per-ray constants of the watertight test: the axis permutation and shear that make
/// the ray the +z axis.
#[derive(Debug, Clone, Copy)]
pub struct WatertightRay {
    pub origin: Vec3,
    /// Each below 3 (see [`WatertightRay::axes`]).
    kx: usize,
    ky: usize,
    kz: usize,
    /// `(o[kx], o[ky], o[kz])`, permuted once here rather than at every block.
    origin_permuted: [f32; 3],
    shear: Vec3,
    /// `|d[kz]|`, the length the shear's `1/dz` divides by (see [`delta_t`]).
    dz_abs: f32,
}

impl WatertightRay {
    #[inline]
    pub fn new(ray: &Ray) -> Self {
        let d = ray.direction;
        let ad = d.abs();
        // The largest component (x, then y, on ties with z): 0 where x is largest, else
        // 1 or 2, from the comparisons' bits rather than branches, which incoherent rays'
        // directions would mispredict.
        let x_largest = (ad.x > ad.y) & (ad.x > ad.z);
        let kz = usize::from(!x_largest) * (2 - usize::from(ad.y > ad.z));
        let kx = kz + 1 - 3 * usize::from(kz == 2);
        let ky = kz + 2 - 3 * usize::from(kz != 0);
        // Indexing an array, not the vector (whose index is a three-way branch).
        let da = d.to_array();
        let (dx, dy, dz) = (da[kx], da[ky], da[kz]);
        let o = ray.origin.to_array();
        WatertightRay {
            origin: ray.origin,
            kx,
            ky,
            kz,
            origin_permuted: [o[kx], o[ky], o[kz]],
            shear: Vec3::new(-dx / dz, -dy / dz, 1.0 / dz),
            dz_abs: dz.abs(),
        }
    }

    /// Lane `i`'s constants of a packet, which [`RayPacket::new`] computes as `new` does
    /// (the same comparisons and operations), for its ray `i`.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[inline(always)]
    pub(crate) fn from_lane(packet: &RayPacket<'_>, i: usize) -> Self {
        // `axis4` holds 0, 4 or 8; the `min` keeps `axes`' promise without relying on it.
        let axis = |a: usize| ((packet.axis4[a][i] / 4) as usize).min(2);
        let lane = |v: &[[f32; PACKET]; 3]| [v[0][i], v[1][i], v[2][i]];
        WatertightRay {
            origin: packet.rays[i].origin,
            kx: axis(0),
            ky: axis(1),
            kz: axis(2),
            origin_permuted: lane(&packet.origin_permuted),
            shear: Vec3::from_array(lane(&packet.shear)),
            dz_abs: packet.dz_abs[i],
        }
    }

    /// The permutation `(kx, ky, kz)` that makes the largest direction component z.
    #[inline(always)]
    pub fn axes(&self) -> (usize, usize, usize) {
        // SAFETY: `new` and `from_lane` are the only constructors, and both set each
        // axis below 3. Saying so lets the per-block vertex loads `p[v][k]` go without
        // bounds checks.
        unsafe {
            std::hint::assert_unchecked(self.kx < 3 && self.ky < 3 && self.kz < 3);
        }
        (self.kx, self.ky, self.kz)
    }

    /// The origin's components `(o[kx], o[ky], o[kz])`.
    #[inline(always)]
    pub fn origin_permuted(&self) -> [f32; 3] {
        self.origin_permuted
    }

    /// The shear `(-dx/dz, -dy/dz, 1/dz)` of the permuted direction.
    #[inline(always)]
    pub fn shear(&self) -> Vec3 {
        self.shear
    }

    /// `|dz|`, the permuted direction's largest component's magnitude.
    #[inline(always)]
    pub fn dz_abs(&self) -> f32 {
        self.dz_abs
    }
}

/// Watertight ray/triangle test. Returns `(t, b0, b1, b2)` for a hit with
/// `t_min < t < t_max` that is provably in front of the origin.
#[inline]
pub fn intersect_triangle_watertight(
    wr: &WatertightRay,
    t_min: f32,
    t_max: f32,
    p0: Vec3,
    p1: Vec3,
    p2: Vec3,
) -> Option<(f32, f32, f32, f32)> {
    // Translate to the ray origin, permute, shear.
    let (kx, ky, kz) = (wr.kx, wr.ky, wr.kz);
    let a = p0 - wr.origin;
    let b = p1 - wr.origin;
    let c = p2 - wr.origin;
    let s = wr.shear;
    let (az, bz, cz) = (a[kz], b[kz], c[kz]);
    let ax = a[kx] + s.x * az;
    let ay = a[ky] + s.y * az;
    let bx = b[kx] + s.x * bz;
    let by = b[ky] + s.y * bz;
    let cx = c[kx] + s.x * cz;
    let cy = c[ky] + s.y * cz;
    // Edge functions.
    let mut e0 = bx * cy - by * cx;
    let mut e1 = cx * ay - cy * ax;
    let mut e2 = ax * by - ay * bx;
    // Exactly zero: recompute in double precision to decide edge ownership consistently.
    if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
        e0 = (bx as f64 * cy as f64 - by as f64 * cx as f64) as f32;
        e1 = (cx as f64 * ay as f64 - cy as f64 * ax as f64) as f32;
        e2 = (ax as f64 * by as f64 - ay as f64 * bx as f64) as f32;
    }
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None;
    }
    // Scaled hit distance and range tests without dividing.
    let (az, bz, cz) = (az * s.z, bz * s.z, cz * s.z);
    let t_scaled = e0 * az + e1 * bz + e2 * cz;
    if det < 0.0 && (t_scaled >= t_min * det || t_scaled < t_max * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= t_min * det || t_scaled > t_max * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    // Reject t that is not provably positive (pbrt-v4, section 6.8.4).
    if t <= delta_t(
        [ax, bx, cx],
        [ay, by, cy],
        [az, bz, cz],
        [e0, e1, e2],
        inv_det,
        wr.dz_abs,
    ) {
        return None;
    }
    Some((t, e0 * inv_det, e1 * inv_det, e2 * inv_det))
}

/// The error bound on the watertight test's `t` (pbrt-v4, section 6.8.4) from the
/// translated, permuted and sheared corners (`z` scaled), the edge functions, the
/// reciprocal determinant and the ray's `|dz|` ([`WatertightRay::dz_abs`]): a hit at
/// `t <= delta_t` is not provably in front.
///
/// The sheared `x` and `y` carry the error of the shear's product with the translated,
/// unscaled `z` (`|dx/dz|, |dy/dz| <= 1`), so their bounds take that `z`, not the scaled
/// one that pbrt's code uses there. The two agree within `√3` for a unit direction; for
/// the object-space ray of a scaled instance (direction `1/s` long) the scaled `z` is `s`
/// times larger, and pbrt's bound rejected every hit on a mesh scaled by 1000 (and on a
/// long direction, as a shadow ray's to its light point, it is too small). The unscaled
/// `z` is taken as `max|z·sz|·|dz|`, which every implementation of the test computes the
/// same way and which is within three roundings of it: `γ7` rather than pbrt's `γ5`
/// covers those.
#[inline(always)]
pub(crate) fn delta_t(
    x: [f32; 3],
    y: [f32; 3],
    z: [f32; 3],
    e: [f32; 3],
    inv_det: f32,
    dz_abs: f32,
) -> f32 {
    let max3 = |v: [f32; 3]| v[0].abs().max(v[1].abs()).max(v[2].abs());
    let max_zt = max3(z);
    let delta_z = gamma(3) * max_zt;
    let max_xt = max3(x);
    let max_yt = max3(y);
    let max_zu = max_zt * dz_abs;
    let delta_x = gamma(7) * (max_xt + max_zu);
    let delta_y = gamma(7) * (max_yt + max_zu);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = max3(e);
    3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs()
}

/// Takes the nearest of the lanes hit by the block(s) starting at block `b` as the closest
/// hit `(t, leaf position, barycentrics)`, lowering `t_max`; returns whether any lane
/// hit. The lanes come by reference: a copy of the pair test's lanes is a 512-bit move
/// in code compiled for AVX-512 (see [`super::triangle_block::PairHits`]).
#[inline(always)]
fn take_nearest<T: std::ops::Index<usize, Output = f32>>(
    b: usize,
    (bits, t, b1, b2): (u32, &T, &T, &T),
    t_max: &mut f32,
    closest: &mut Option<(f32, usize, Vec2)>,
) -> bool {
    if bits == 0 {
        return false;
    }
    let lane = nearest_lane(bits, t);
    *t_max = t[lane];
    let at = b * BLOCK + lane;
    *closest = Some((t[lane], at, Vec2::new(b1[lane], b2[lane])));
    true
}

/// Starts loading the cache line at `p` (a hint: never faults, whatever the address).
#[inline(always)]
fn prefetch_line<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: prefetching never faults, whatever the address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p as *const i8);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Packs the triangles at the accelerator's leaf positions into blocks of four.
///
/// The leaf order is the tree's, not the mesh's, so each block gathers its triangles'
/// indices and vertices from all over the mesh: on a mesh larger than the caches, twelve
/// dependent misses per block. Each block asks for the indices of the block
/// [`PACK_AHEAD`] blocks on and for the vertices of the one half as far on (whose
/// indices were asked for that many blocks ago), so that the misses overlap: bunny_loop2's
/// 280k blocks were packed in 16.5 ms on two threads without, 11 ms with (medians of 8).
fn pack_blocks(positions: &[Vec3], indices: &[[u32; 3]], order: &[u32]) -> Vec<TriangleBlock> {
    use rayon::prelude::*;
    let block = |b: usize| order.get(b * BLOCK..((b + 1) * BLOCK).min(order.len()));
    crate::accel::collect_huge(order.par_chunks(BLOCK).enumerate().map(|(b, chunk)| {
        for &prim in block(b + PACK_AHEAD).unwrap_or_default() {
            prefetch_line(indices.as_ptr().wrapping_add(prim as usize));
        }
        for &prim in block(b + PACK_AHEAD / 2).unwrap_or_default() {
            for &v in &indices[prim as usize] {
                prefetch_line(positions.as_ptr().wrapping_add(v as usize));
            }
        }
        let mut tris = [[Vec3::ZERO; 3]; BLOCK];
        let mut prims = [0; BLOCK];
        for (lane, tri) in tris.iter_mut().enumerate() {
            // A short last chunk repeats its last triangle (leaves are padded anyway).
            let prim = chunk[lane.min(chunk.len() - 1)];
            let [a, b, c] = indices[prim as usize];
            *tri = [
                positions[a as usize],
                positions[b as usize],
                positions[c as usize],
            ];
            prims[lane] = prim;
        }
        TriangleBlock::new(tris, prims)
    }))
}

/// How many blocks ahead [`pack_blocks`] asks for a block's triangle indices.
const PACK_AHEAD: usize = 16;

/// The closest hits of many rays on one mesh ([`TriangleMesh::intersect_to`]), in
/// structure-of-arrays form: ray `i`'s distance, triangle and barycentrics, the triangle
/// [`MeshHits::NONE`] where it hit nothing. Room for whole packets of rays.
#[derive(Debug, Clone, Default)]
pub struct MeshHits {
    t: Vec<f32>,
    prim: Vec<u32>,
    u: Vec<f32>,
    v: Vec<f32>,
}

impl MeshHits {
    /// The triangle of a miss.
    pub const NONE: u32 = u32::MAX;

    /// Room for `n` hits, rounded up to whole packets.
    fn resize(&mut self, n: usize) {
        // Sixteen: `PACKET`, which exists only where packets run.
        let n = n.next_multiple_of(16);
        if self.t.len() < n {
            self.t.resize(n, 0.0);
            self.prim.resize(n, Self::NONE);
            self.u.resize(n, 0.0);
            self.v.resize(n, 0.0);
        }
    }

    #[inline(always)]
    fn set(&mut self, i: usize, hit: Option<ShapeHit>) {
        let h = hit.unwrap_or(ShapeHit {
            t: f32::INFINITY,
            prim: Self::NONE,
            uv: Vec2::ZERO,
        });
        (self.t[i], self.prim[i], self.u[i], self.v[i]) = (h.t, h.prim, h.uv.x, h.uv.y);
    }

    /// Ray `i`'s hit.
    #[inline(always)]
    pub fn get(&self, i: usize) -> Option<ShapeHit> {
        (self.prim[i] != Self::NONE).then(|| ShapeHit {
            t: self.t[i],
            prim: self.prim[i],
            uv: Vec2::new(self.u[i], self.v[i]),
        })
    }
}

/// One triangle as [`TriangleMesh::lane_triangle`] gives it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LaneTriangle {
    pub p: [Vec3; 3],
    pub normals: Option<[Vec3; 3]>,
    pub flipped: bool,
}

/// Each ray `i` of `mask` alone: `test(wr, ray, closest)` with the packet's ray `i` cut
/// at lane `i`'s `t_max` (and its watertight constants from the packet's lane, not
/// computed again) returns whether it hit (any hit), or records its closest hit in
/// `closest`, which then lowers the lane's `t_max` and goes into `found`. Returns the
/// rays hit.
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
#[inline(always)]
fn each_ray_alone<const ANY_HIT: bool>(
    packet: &RayPacket<'_>,
    mask: u16,
    t_max: &mut [f32; PACKET],
    found: &mut PacketHits,
    mut test: impl FnMut(&WatertightRay, &Ray, &mut Option<(f32, usize, Vec2)>) -> bool,
) -> u16 {
    let mut any = 0;
    let mut bits = mask;
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let ray = Ray {
            t_max: t_max[i],
            ..packet.rays[i]
        };
        let mut closest = None;
        let mut hit = test(&WatertightRay::from_lane(packet, i), &ray, &mut closest);
        if !ANY_HIT {
            if let Some((t, at, uv)) = closest {
                t_max[i] = t;
                found.at[i] = at as u32;
                found.b1[i] = uv.x;
                found.b2[i] = uv.y;
            }
            hit = closest.is_some();
        }
        if hit {
            any |= 1 << i;
        }
    }
    any
}

/// The index of the first item of `items` for which `bad` holds, in parallel: in chunks
/// of [`CHECK_CHUNK`], each scanned serially, then within the first chunk that holds one.
/// `position_first` over the items themselves made a job of almost every item: the
/// checks of the Stanford bunny's 35k vertices and 69k triangles took 1.2 ms on one
/// thread, a twentieth of its BVH's build.
fn first_where<T: Sync>(items: &[T], bad: impl Fn(&T) -> bool + Sync) -> Option<usize> {
    use rayon::prelude::*;
    let chunk = items
        .par_chunks(CHECK_CHUNK)
        .position_first(|c| c.iter().any(&bad))?;
    let first = chunk * CHECK_CHUNK;
    let at = items[first..]
        .iter()
        .position(&bad)
        .expect("the chunk holds one");
    Some(first + at)
}

/// Items a parallel check ([`first_where`]) scans serially at a time.
const CHECK_CHUNK: usize = 1 << 13;

/// The area of the triangle with corners `p0`, `p1`, `p2`.
#[inline]
fn triangle_area(p0: Vec3, p1: Vec3, p2: Vec3) -> f32 {
    0.5 * (p1 - p0).cross(p2 - p0).length()
}

/// The smallest triangle area, as a fraction of the square of the mesh box's largest
/// extent, for which the packets' bound on `delta_t` pays (see
/// [`TriangleMesh::delta_t_box`]): the bound passes hits at distance `t` on triangles of
/// area above about `5e-5 R³ / t` (`R` the extent), so about `1.5e-4 R²` at a third of
/// the box; this asks seven times that.
const DELTA_T_BOUND_AREA: f32 = 1e-3;

/// The most triangles a mesh has for its packets to test leaves by shared corners
/// ([`packet::SharedCorners`]). On Mitsuba's Cornell box (38 triangles) that traced
/// the path tracer's recorded closest-hit packets 8% faster and its shadow packets 3%;
/// on the 1.1M-triangle bunny it added about a fifth to the BVH's build (204 to 250 ms
/// on two threads) and 12 bytes per triangle, for a gain not measured there. 2¹⁷ takes
/// in a Stanford bunny (69k triangles) merged into a Cornell box
/// (`benches/scenes/cbox-bunny.xml`): with the lanes' triangle table of as many
/// (`integrator::path_lanes`), renders there went from 2.54 to 2.86 M samples/s
/// (medians of six alternated 64-spp renders; the table alone 2.68), images
/// byte-identical, for 3 MB and 7 ms of loading.
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
const SHARED_CORNERS_TRIANGLES: usize = 1 << 17;

impl TriangleMesh {
    /// Builds a mesh from raw data. Fails if an index is out of range, a position is not
    /// finite, or attribute arrays do not match the vertex count.
    pub fn new(data: MeshData, smooth: bool, accel: AccelKind) -> Result<TriangleMesh, String> {
        crate::accel::in_pool(|| Self::new_in_pool(data, smooth, accel, true))
    }

    /// [`TriangleMesh::new`] on a thread of rayon's pool; with `occluders`, also the
    /// mesh's [`Occluders`] where it has them.
    fn new_in_pool(
        data: MeshData,
        smooth: bool,
        accel: AccelKind,
        occluders: bool,
    ) -> Result<TriangleMesh, String> {
        let n = data.positions.len();
        if !data.normals.is_empty() && data.normals.len() != n {
            return Err(format!("{} normals for {} vertices", data.normals.len(), n));
        }
        if !data.uvs.is_empty() && data.uvs.len() != n {
            return Err(format!("{} uvs for {} vertices", data.uvs.len(), n));
        }
        if !data.colors.is_empty() && data.colors.len() != n {
            return Err(format!("{} colours for {} vertices", data.colors.len(), n));
        }
        if let Some(i) = data.colors.iter().position(|c| !c.is_finite()) {
            return Err(format!("vertex {i} has a non-finite colour"));
        }
        let faces = data.indices.len();
        if !data.face_colors.is_empty() && data.face_colors.len() != faces {
            return Err(format!(
                "{} face colours for {faces} triangles",
                data.face_colors.len()
            ));
        }
        if let Some(i) = data.face_colors.iter().position(|c| !c.is_finite()) {
            return Err(format!("triangle {i} has a non-finite colour"));
        }
        // In parallel (a serial pass over a million triangles is a few percent of their
        // BVH's build on two threads, and more with more threads); the first offender
        // is named, as a serial pass would.
        use rayon::prelude::*;
        if let Some(i) = first_where(&data.positions, |p| !p.is_finite()) {
            return Err(format!("vertex {i} has a non-finite position"));
        }
        let out_of_range = |tri: &[u32; 3]| tri.iter().copied().find(|&i| i as usize >= n);
        if let Some(f) = first_where(&data.indices, |t| out_of_range(t).is_some()) {
            let bad = out_of_range(&data.indices[f]).expect("found above");
            return Err(format!(
                "triangle {f} refers to vertex {bad}, but there are {n}"
            ));
        }
        let data = data.unweld_face_colors();
        let positions = &data.positions;
        let kind = accel;
        let accel = Accel::build_from(kind, data.indices.len(), |i| {
            let t = &data.indices[i];
            let mut b = Bounds3::from_point(positions[t[0] as usize]);
            b.expand(positions[t[1] as usize]);
            b.expand(positions[t[2] as usize]);
            b
        });
        let blocks = match accel.leaf_order() {
            Some(order) => pack_blocks(&data.positions, &data.indices, order),
            None => Vec::new(),
        };
        // The packets' bound on `delta_t` (`RayPacket::t_bound`) grows with the cube of
        // the box and shrinks with a triangle's area: with triangles this large against the
        // box most hits pass it; with smaller ones (the 69k-triangle bunny in the Cornell
        // box: 7% slower) they mostly do not, and the test that tries it first costs more
        // than it saves. An empty box makes the bound infinite: every hit takes `delta_t`.
        // (The accelerator's box contains every triangle, which is all the bound needs.)
        let bounds = accel.bounds();
        let extent = (bounds.max - bounds.min).max_element();
        let large = || {
            data.indices
                .par_iter()
                .filter(|t| {
                    let [p0, p1, p2] = t.map(|i| positions[i as usize]);
                    triangle_area(p0, p1, p2) >= DELTA_T_BOUND_AREA * extent * extent
                })
                .count()
        };
        let delta_t_box = if !blocks.is_empty() && large() * 10 >= data.indices.len() * 9 {
            bounds
        } else {
            Bounds3::EMPTY
        };
        // Only for meshes of up to `SHARED_CORNERS_TRIANGLES` triangles (see there).
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        let shared = match &accel {
            Accel::Bvh8(bvh)
                if crate::accel::Bvh8::packets_supported()
                    && data.indices.len() <= SHARED_CORNERS_TRIANGLES =>
            {
                packet::SharedCorners::new(
                    &data.positions,
                    &data.indices,
                    bvh.prim_order(),
                    blocks.len(),
                    &bvh.leaves(),
                )
            }
            _ => packet::SharedCorners::default(),
        };
        let occluders = if occluders {
            Occluders::new(&data.positions, &data.indices, kind, &accel, bounds)?
        } else {
            None
        };
        // Normals that are not finite or zero make the mesh flat rather than NaN.
        let normals_ok = data
            .normals
            .par_iter()
            .all(|n| n.is_finite() && n.length_squared() > 0.0);
        Ok(TriangleMesh {
            positions: data.positions,
            normals: if normals_ok { data.normals } else { Vec::new() },
            uvs: data.uvs,
            indices: data.indices,
            colors: data.colors,
            smooth,
            accel,
            blocks,
            delta_t_box,
            avx2: crate::cpu::has_avx2(),
            pair_blocks: crate::cpu::leaf_blocks_per_test() == 2,
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            avx512: crate::cpu::has_avx512(),
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            leaf_rays: crate::cpu::packet_leaf_rays_per_block(),
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            shared,
            area_distribution: std::sync::OnceLock::new(),
            flipped: Vec::new(),
            alpha: None,
            occluders,
        })
    }

    /// Marks the triangles whose geometric normal is the opposite of their winding's
    /// (one flag per triangle, or none).
    pub(crate) fn set_flipped(&mut self, flipped: Vec<bool>) {
        debug_assert!(flipped.is_empty() || flipped.len() == self.indices.len());
        self.flipped = if flipped.iter().any(|&f| f) {
            flipped
        } else {
            Vec::new()
        };
    }

    /// Cuts the surface by an alpha mask (see [`AlphaMask`]).
    pub fn set_alpha(&mut self, mask: AlphaMask) {
        self.alpha = Some(mask);
    }

    /// The mesh's alpha mask, if it has one.
    pub fn alpha(&self) -> Option<&AlphaMask> {
        self.alpha.as_ref()
    }

    /// Whether `ray` meets the surface at barycentrics `(b1, b2)` of triangle `prim`:
    /// always without an alpha mask, else as the mask's test says.
    #[inline]
    fn covers(&self, ray: &Ray, prim: u32, b1: f32, b2: f32) -> bool {
        let Some(mask) = &self.alpha else {
            return true;
        };
        // A ray meets the surface with probability `coverage` (0 or 1 for a cutoff; the
        // hash, uniform in [0, 1), decides the fractions).
        let coverage = mask.coverage_at(self.uv_at(prim, b1, b2));
        coverage >= 1.0 || (coverage > 0.0 && coverage > alpha_hash(ray, prim))
    }

    /// Texture coordinates at barycentrics `(b1, b2)` of triangle `prim`: the mesh's,
    /// or pbrt's default parameterisation.
    #[inline(always)]
    fn uv_at(&self, prim: u32, b1: f32, b2: f32) -> Vec2 {
        let (uv0, uv1, uv2) = self.corner_uvs(prim);
        uv0 * (1.0 - b1 - b2) + uv1 * b1 + uv2 * b2
    }

    /// The texture coordinates of triangle `prim`'s corners (see [`TriangleMesh::uv_at`]).
    #[inline(always)]
    fn corner_uvs(&self, prim: u32) -> (Vec2, Vec2, Vec2) {
        if self.uvs.is_empty() {
            (Vec2::ZERO, Vec2::X, Vec2::ONE)
        } else {
            let [i0, i1, i2] = self.indices[prim as usize];
            (
                self.uvs[i0 as usize],
                self.uvs[i1 as usize],
                self.uvs[i2 as usize],
            )
        }
    }

    /// Bytes of the acceleration structure and the packed triangle blocks, with those of
    /// the mesh without its box's faces where it has one ([`Occluders`]).
    pub fn accel_memory_bytes(&self) -> usize {
        let shared = {
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            {
                self.shared.memory_bytes()
            }
            #[cfg(not(all(target_arch = "x86_64", lightpath_avx512)))]
            {
                0
            }
        };
        let occluders = self
            .occluders
            .as_ref()
            .and_then(|o| o.mesh.as_ref())
            .map_or(0, |m| m.accel_memory_bytes());
        self.accel.memory_bytes()
            + std::mem::size_of_val(self.blocks.as_slice())
            + shared
            + occluders
    }

    /// Object-space area of triangle `prim`.
    #[inline]
    pub fn triangle_area(&self, prim: u32) -> f32 {
        let (p0, p1, p2) = self.vertices(prim);
        triangle_area(p0, p1, p2)
    }

    /// Total object-space area.
    pub fn area(&self) -> f32 {
        let d = self.area_distribution();
        d.integral() * d.len() as f32
    }

    /// Triangles chosen in proportion to their area.
    pub fn area_distribution(&self) -> &crate::sampling::Distribution1D {
        self.area_distribution.get_or_init(|| {
            let areas: Vec<f32> = (0..self.indices.len() as u32)
                .map(|i| self.triangle_area(i))
                .collect();
            crate::sampling::Distribution1D::new(&areas)
        })
    }

    /// A point uniformly distributed over the surface (object space): the hit record of
    /// that point, and the area density 1 / total area.
    pub fn sample_area(&self, u: Vec2) -> Option<(ShapeHit, f32)> {
        let d = self.area_distribution();
        let area = self.area();
        if d.is_empty() || area.is_nan() || area <= 0.0 {
            return None;
        }
        // The triangle is chosen with `u.x`, which is then rescaled for use inside it: a
        // stratified `u` stays stratified over the whole surface (a quad's two triangles
        // share the 2D strata instead of taking a random subset each).
        let (prim, ux) = d.sample_reuse(u.x);
        let b = crate::sampling::warp::square_to_uniform_triangle(Vec2::new(ux, u.y));
        Some((
            ShapeHit {
                t: 1.0,
                prim: prim as u32,
                uv: b,
            },
            1.0 / area,
        ))
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    pub fn bounds(&self) -> Bounds3 {
        self.accel.bounds()
    }

    #[inline]
    pub(crate) fn vertices(&self, prim: u32) -> (Vec3, Vec3, Vec3) {
        let [a, b, c] = self.indices[prim as usize];
        (
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        )
    }

    /// What [`TriangleMesh::interaction`] reads of triangle `prim`, for code that builds
    /// many interactions at once: the corners, the vertex normals where it interpolates
    /// them, and whether its geometric normal is flipped. `None` for meshes with texture
    /// coordinates (their tangents come from the coordinates).
    #[inline(always)]
    pub(crate) fn lane_triangle(&self, prim: u32) -> Option<LaneTriangle> {
        if !self.uvs.is_empty() {
            return None;
        }
        let [i0, i1, i2] = self.indices[prim as usize];
        let normals = (self.smooth && !self.normals.is_empty()).then(|| {
            [
                self.normals[i0 as usize],
                self.normals[i1 as usize],
                self.normals[i2 as usize],
            ]
        });
        Some(LaneTriangle {
            p: [
                self.positions[i0 as usize],
                self.positions[i1 as usize],
                self.positions[i2 as usize],
            ],
            normals,
            flipped: self.flipped.get(prim as usize) == Some(&true),
        })
    }

    /// The index of the triangle at leaf position `at`, from its block (which a hit there
    /// has just loaded).
    #[inline(always)]
    fn block_prim(&self, at: usize) -> u32 {
        self.blocks[at / BLOCK].prim[at % BLOCK]
    }

    /// Starts loading the first block of the leaf at position `first`.
    #[inline(always)]
    fn prefetch_block(&self, first: u32) {
        let p = self.blocks.as_ptr().wrapping_add(first as usize / BLOCK) as *const u8;
        for line in 0..3 {
            prefetch_line(p.wrapping_add(64 * line));
        }
    }

    /// Closest hit through the mesh's BVH.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        // The triangles in the box's faces that the ray crosses, then the others, with
        // `t_max` lowered to a hit there (in the packets' order: the same hits).
        if let Some(Occluders {
            mesh: Some(others),
            faces: Some(faces),
            ..
        }) = self.occluders.as_deref()
        {
            if self.alpha.is_none() {
                let face = faces.closest(ray, &WatertightRay::new(ray));
                let mut rest = *ray;
                if let Some((t, ..)) = face {
                    rest.t_max = t;
                }
                return others
                    .intersect(&rest, stats)
                    .or(face.map(|(t, e, uv)| ShapeHit {
                        t,
                        prim: faces.prim[e],
                        uv,
                    }));
            }
        }
        if !self.blocks.is_empty() {
            if self.alpha.is_some() {
                return self.intersect_masked(ray, stats);
            }
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            if self.avx512 {
                // SAFETY: `avx512` is set only where the processor supports it.
                return unsafe { self.intersect_blocks_avx512(ray, stats) };
            }
            #[cfg(target_arch = "x86_64")]
            if self.avx2 {
                // SAFETY: `avx2` is set only where the processor has the AVX2 tier.
                return unsafe { self.intersect_blocks_avx2(ray, stats) };
            }
            return intersect_blocks!(self, ray, stats, false, false);
        }
        let wr = WatertightRay::new(ray);
        let mut best = None;
        self.accel.intersect(ray, stats, |prim, t_max| {
            let (p0, p1, p2) = self.vertices(prim);
            match intersect_triangle_watertight(&wr, ray.t_min, *t_max, p0, p1, p2) {
                Some((t, _b0, b1, b2)) if self.covers(ray, prim, b1, b2) => {
                    *t_max = t;
                    best = Some(ShapeHit {
                        t,
                        prim,
                        uv: Vec2::new(b1, b2),
                    });
                    true
                }
                _ => false,
            }
        });
        best
    }

    /// [`TriangleMesh::intersect`] over the SIMD blocks, compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn intersect_blocks_avx2(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        intersect_blocks!(self, ray, stats, true, false)
    }

    /// [`TriangleMesh::occluded`] over the SIMD blocks, compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn occluded_blocks_avx2(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        occluded_blocks!(self, ray, stats, true, false)
    }

    /// [`TriangleMesh::intersect`] over the SIMD blocks, compiled for AVX-512 (see
    /// [`crate::cpu::has_avx512`]).
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    unsafe fn intersect_blocks_avx512(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        intersect_blocks!(self, ray, stats, true, false)
    }

    /// [`TriangleMesh::occluded`] over the SIMD blocks, compiled for AVX-512.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    unsafe fn occluded_blocks_avx512(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        occluded_blocks!(self, ray, stats, true, false)
    }

    /// [`TriangleMesh::intersect`] over the SIMD blocks of a masked mesh (out of line:
    /// the unmasked leaf tests stay free of the mask's checks).
    #[cold]
    #[inline(never)]
    fn intersect_masked(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has the AVX2 tier.
            return unsafe { self.intersect_masked_avx2(ray, stats) };
        }
        intersect_blocks!(self, ray, stats, false, true)
    }

    /// [`TriangleMesh::intersect_masked`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn intersect_masked_avx2(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        intersect_blocks!(self, ray, stats, true, true)
    }

    /// [`TriangleMesh::occluded`] over the SIMD blocks of a masked mesh.
    #[cold]
    #[inline(never)]
    fn occluded_masked(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has the AVX2 tier.
            return unsafe { self.occluded_masked_avx2(ray, stats) };
        }
        occluded_blocks!(self, ray, stats, false, true)
    }

    /// [`TriangleMesh::occluded_masked`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn occluded_masked_avx2(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        occluded_blocks!(self, ray, stats, true, true)
    }

    /// The lanes of `bits` (hits of a block pair: lanes 0-3 in block `blocks[0]`, 4-7 in
    /// `blocks[1]`) where `ray` meets the surface under the alpha mask.
    #[cold]
    #[inline(never)]
    fn alpha_lanes<T: std::ops::Index<usize, Output = f32>>(
        &self,
        ray: &Ray,
        blocks: [usize; 2],
        bits: u32,
        b1: &T,
        b2: &T,
    ) -> u32 {
        let mut kept = 0;
        let mut rest = bits;
        while rest != 0 {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let prim = self.blocks[blocks[lane / BLOCK]].prim[lane % BLOCK];
            if self.covers(ray, prim, b1[lane], b2[lane]) {
                kept |= 1 << lane;
            }
        }
        kept
    }

    /// The closest-hit test of a whole leaf (positions `first..first + count` of the
    /// accelerator's leaf order), block by block: lowers `t_max` and records the hit in
    /// `closest` for a closer one.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn leaf_closest<const AVX2_CALLER: bool, const MASKED: bool>(
        &self,
        wr: &WatertightRay,
        ray: &Ray,
        first: u32,
        count: u32,
        t_max: &mut f32,
        closest: &mut Option<(f32, usize, Vec2)>,
    ) -> bool {
        let t_min = ray.t_min;
        let mut found = false;
        let mut b = first as usize / BLOCK;
        let end = (first + count).div_ceil(BLOCK as u32) as usize;
        // Two blocks at a time with 8-lane AVX2 where the processor has full-width
        // units for it (`pair_blocks`); an odd last block is paired with itself and its
        // copy's lanes dropped, so that every leaf takes the same path (which its size
        // would otherwise make a mispredicted branch). Elsewhere one block at a time: in
        // the AVX2 callers as VEX-encoded 4-lane code.
        #[cfg(target_arch = "x86_64")]
        if self.pair_blocks {
            while b < end {
                let last = b + 1 == end;
                let (x, y) = (&self.blocks[b], &self.blocks[if last { b } else { b + 1 }]);
                // SAFETY: `pair_blocks` is set only where the processor has the AVX2 tier.
                let mut hits = unsafe { intersect_pair::<AVX2_CALLER>(x, y, wr, t_min, *t_max) };
                hits.keep(if last { 0xf } else { 0xff });
                if let Some([t, b1, b2]) = hits.lanes() {
                    let mut bits = hits.bits();
                    if MASKED {
                        bits = self.alpha_lanes(ray, [b, b + 1], bits, b1, b2);
                    }
                    found |= take_nearest(b, (bits, t, b1, b2), t_max, closest);
                }
                b += 2;
            }
            return found;
        }
        while b < end {
            let mut hits = self.blocks[b].intersect(wr, t_min, *t_max);
            if MASKED {
                hits.0 = self.alpha_lanes(ray, [b, b], hits.0, &hits.2, &hits.3);
            }
            found |= take_nearest(b, (hits.0, &hits.1, &hits.2, &hits.3), t_max, closest);
            b += 1;
        }
        found
    }

    /// Whether a triangle of a whole leaf blocks `ray` (the any-hit test of the leaf at
    /// positions `first..first + count`).
    #[inline(always)]
    fn leaf_blocks<const AVX2_CALLER: bool, const MASKED: bool>(
        &self,
        wr: &WatertightRay,
        ray: &Ray,
        first: u32,
        count: u32,
    ) -> bool {
        let mut b = first as usize / BLOCK;
        let end = (first + count).div_ceil(BLOCK as u32) as usize;
        // As in `leaf_closest`: pairs of blocks, an odd last block paired with itself.
        #[cfg(target_arch = "x86_64")]
        if self.pair_blocks {
            while b < end {
                let by = if b + 1 == end { b } else { b + 1 };
                let (x, y) = (&self.blocks[b], &self.blocks[by]);
                // SAFETY: `pair_blocks` is set only where the processor has the AVX2 tier.
                let hits = unsafe { intersect_pair::<AVX2_CALLER>(x, y, wr, ray.t_min, ray.t_max) };
                if let Some([_, b1, b2]) = hits.lanes() {
                    if !MASKED || self.alpha_lanes(ray, [b, by], hits.bits(), b1, b2) != 0 {
                        return true;
                    }
                }
                b += 2;
            }
            return false;
        }
        while b < end {
            let hits = self.blocks[b].intersect(wr, ray.t_min, ray.t_max);
            if hits.0 != 0
                && (!MASKED || self.alpha_lanes(ray, [b, b], hits.0, &hits.2, &hits.3) != 0)
            {
                return true;
            }
            b += 1;
        }
        false
    }

    /// Closest hits of many rays at once (`hits[i]` for `rays[i]`), the same as
    /// [`TriangleMesh::intersect`] ray by ray. With the 8-wide BVH several rays are in
    /// flight at a time, so that their cache misses overlap
    /// ([`crate::accel::Bvh8::intersect_stream`]); other accelerators go ray by ray.
    pub fn intersect_stream(
        &self,
        rays: &[Ray],
        hits: &mut [Option<ShapeHit>],
        stats: &mut RayStats,
    ) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        let (Accel::Bvh8(bvh), Some(order), None) =
            (&self.accel, self.accel.leaf_order(), &self.alpha)
        else {
            for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                *hit = self.intersect(ray, stats);
            }
            return;
        };
        // A BVH8 mesh always has its blocks (see `TriangleMesh::new`).
        debug_assert!(!self.blocks.is_empty() || order.is_empty());
        // Per ray: the watertight constants (set up at its first leaf) and the closest
        // hit as (t, leaf position, barycentrics).
        type State = (Option<WatertightRay>, Option<(f32, usize, Vec2)>);
        bvh.intersect_stream(
            rays,
            stats,
            |first| self.prefetch_block(first),
            |_| -> State { (None, None) },
            |(wr, closest), ray, first, count, t_max| {
                let wr = &*wr.get_or_insert_with(|| WatertightRay::new(ray));
                self.leaf_closest::<false, false>(wr, ray, first, count, t_max, closest)
            },
            |i, (_, closest), _| {
                hits[i] = closest.map(|(t, at, uv)| ShapeHit {
                    t,
                    prim: self.block_prim(at),
                    uv,
                });
            },
        );
    }

    /// Any hits of many rays at once (`occluded[i]` for `rays[i]`), the same as
    /// [`TriangleMesh::occluded`] ray by ray, several in flight at a time with the
    /// 8-wide BVH (see [`TriangleMesh::intersect_stream`]).
    pub fn occluded_stream(&self, rays: &[Ray], occluded: &mut [bool], stats: &mut RayStats) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        let (Accel::Bvh8(bvh), None) = (&self.accel, &self.alpha) else {
            for (ray, o) in rays.iter().zip(occluded.iter_mut()) {
                *o = self.occluded(ray, stats);
            }
            return;
        };
        bvh.occluded_stream(
            rays,
            stats,
            |first| self.prefetch_block(first),
            |_| None,
            |wr: &mut Option<WatertightRay>, ray, first, count| {
                let wr = &*wr.get_or_insert_with(|| WatertightRay::new(ray));
                self.leaf_blocks::<false, false>(wr, ray, first, count)
            },
            |i, _, any| occluded[i] = any,
        );
    }

    /// Closest hits of many rays (`hits[i]` for `rays[i]`) in packets of sixteen
    /// through the 8-wide BVH where the processor has AVX-512
    /// ([`crate::accel::Bvh8::intersect_packet`]); elsewhere, and for other
    /// accelerators, ray by ray. The same distances as [`TriangleMesh::intersect`]; where
    /// two triangles are hit at exactly the same distance, either may be reported.
    pub fn intersect_packets(
        &self,
        rays: &[Ray],
        hits: &mut [Option<ShapeHit>],
        stats: &mut RayStats,
    ) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        if let Some(bvh) = self.packet_bvh() {
            let (mut t, mut found) = ([0.0; PACKET], PacketHits::default());
            for (rays, hits) in rays.chunks(PACKET).zip(hits.chunks_mut(PACKET)) {
                // SAFETY: the processor supports AVX-512F and DQ (checked above).
                let (hit, mesh) =
                    unsafe { self.packet_avx512::<false>(bvh, rays, stats, &mut t, &mut found) };
                for (i, h) in hits.iter_mut().enumerate() {
                    *h = (hit & (1 << i) != 0).then(|| ShapeHit {
                        t: t[i],
                        prim: mesh.block_prim(found.at[i] as usize),
                        uv: Vec2::new(found.b1[i], found.b2[i]),
                    });
                }
            }
            return;
        }
        for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
            *hit = self.intersect(ray, stats);
        }
    }

    /// [`TriangleMesh::intersect_packets`] into `hits` (resized to hold the rays), in
    /// structure-of-arrays form: each packet's hits go there with a few vector stores
    /// where packets run, rather than one `Option<ShapeHit>` at a time.
    pub(crate) fn intersect_to(&self, rays: &[Ray], hits: &mut MeshHits, stats: &mut RayStats) {
        hits.resize(rays.len());
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        if let Some(bvh) = self.packet_bvh() {
            // Leaf positions as words of the blocks (for the gather of their indices).
            const WORDS: usize = std::mem::size_of::<TriangleBlock>() / 4;
            if self.blocks.len() * WORDS <= i32::MAX as usize {
                let (mut t, mut found) = ([0.0; PACKET], PacketHits::default());
                for (p, rays) in rays.chunks(PACKET).enumerate() {
                    // SAFETY: the processor supports AVX-512F and DQ (checked above);
                    // `hits` holds whole packets; the blocks' words fit in `i32`.
                    unsafe {
                        let (hit, mesh) =
                            self.packet_avx512::<false>(bvh, rays, stats, &mut t, &mut found);
                        mesh.store_hits_avx512(hit, &t, &found, hits, p * PACKET);
                    }
                }
                return;
            }
        }
        for (i, ray) in rays.iter().enumerate() {
            hits.set(i, self.intersect(ray, stats));
        }
    }

    /// One packet's hits (`hit`: the lanes hit) into `hits` from position `at`: the
    /// distances and barycentrics as they are, and each hit lane's triangle index
    /// gathered from its block ([`MeshHits::NONE`] for the others).
    ///
    /// # Safety
    /// The processor must support AVX-512F; `hits` must hold sixteen positions from
    /// `at`, and the blocks' words must fit in `i32`.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    unsafe fn store_hits_avx512(
        &self,
        hit: u16,
        t: &[f32; PACKET],
        found: &PacketHits,
        hits: &mut MeshHits,
        at: usize,
    ) {
        use std::arch::x86_64::*;
        const WORDS: i32 = (std::mem::size_of::<TriangleBlock>() / 4) as i32;
        const PRIM: i32 = (std::mem::offset_of!(TriangleBlock, prim) / 4) as i32;
        assert!(hits.t.len() >= at + PACKET, "room for a packet's hits");
        // SAFETY (intrinsics): AVX-512F (the caller); sixteen-lane loads and stores inside
        // the arrays (checked above); the gather reads the lanes hit, whose leaf positions
        // are in the blocks.
        unsafe {
            let position = _mm512_loadu_si512(found.at.as_ptr() as *const __m512i);
            // Word of `blocks[position / 4].prim[position % 4]`.
            let word = _mm512_add_epi32(
                _mm512_mullo_epi32(_mm512_srli_epi32::<2>(position), _mm512_set1_epi32(WORDS)),
                _mm512_add_epi32(
                    _mm512_and_si512(position, _mm512_set1_epi32(3)),
                    _mm512_set1_epi32(PRIM),
                ),
            );
            let prim = _mm512_mask_i32gather_epi32::<4>(
                _mm512_set1_epi32(MeshHits::NONE as i32),
                hit,
                word,
                self.blocks.as_ptr() as *const i32,
            );
            _mm512_storeu_si512(hits.prim[at..].as_mut_ptr() as *mut __m512i, prim);
            _mm512_storeu_ps(hits.t[at..].as_mut_ptr(), _mm512_loadu_ps(t.as_ptr()));
            _mm512_storeu_ps(
                hits.u[at..].as_mut_ptr(),
                _mm512_loadu_ps(found.b1.as_ptr()),
            );
            _mm512_storeu_ps(
                hits.v[at..].as_mut_ptr(),
                _mm512_loadu_ps(found.b2.as_ptr()),
            );
        }
    }

    /// Whether [`TriangleMesh::intersect_packets`] and [`TriangleMesh::occluded_packets`]
    /// trace packets here (a `bvh8` mesh on a processor with AVX-512F and DQ) rather
    /// than ray by ray.
    pub fn traces_packets(&self) -> bool {
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        if self.packet_bvh().is_some() {
            return true;
        }
        false
    }

    /// The 8-wide BVH where packets run: a `bvh8` mesh without an alpha mask on a
    /// processor with AVX-512F and DQ.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    fn packet_bvh(&self) -> Option<&crate::accel::Bvh8> {
        match &self.accel {
            Accel::Bvh8(bvh) if crate::accel::Bvh8::packets_supported() && self.alpha.is_none() => {
                // A BVH8 mesh always has its blocks (see `TriangleMesh::new`).
                debug_assert!(!self.blocks.is_empty() || bvh.prim_order().is_empty());
                Some(bvh)
            }
            _ => None,
        }
    }

    /// One packet's traversal (`rays`: at most [`PACKET`]): returns the rays hit and,
    /// for closest hits, writes their distances to `t` and their hits to `found`.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    unsafe fn packet_avx512<const ANY_HIT: bool>(
        &self,
        bvh: &crate::accel::Bvh8,
        rays: &[Ray],
        stats: &mut RayStats,
        t: &mut [f32; PACKET],
        found: &mut PacketHits,
    ) -> (u16, &TriangleMesh) {
        // Shadow rays whose segments all lie in the box take the mesh without its box's
        // faces (`Occluders`); the packet's `delta_t` bound from this mesh's box holds
        // for that one's triangles too. Closest-hit rays test the triangles in the
        // faces they cross, and then that mesh (`packet::intersect_faces`).
        let occluders = match &self.occluders {
            Some(o) if self.alpha.is_none() => Some(&**o),
            _ => None,
        };
        // SAFETY: the caller guarantees AVX-512F and DQ.
        let (packet, t_max, held) = unsafe {
            RayPacket::new(
                rays,
                &self.delta_t_box,
                occluders.filter(|_| ANY_HIT).map(|o| (&o.outer, &o.inner)),
            )
        };
        *t = t_max;
        stats.rays += rays.len() as u32;
        let mut face_hits = 0;
        let (mesh, bvh) = match occluders {
            Some(o) if ANY_HIT && held == packet.boxes.active => match &o.mesh {
                Some(m) => match m.packet_bvh() {
                    Some(b) => (m, b),
                    None => (self, bvh),
                },
                None => return (0, self),
            },
            Some(Occluders {
                mesh: Some(m),
                faces: Some(faces),
                ..
            }) if !ANY_HIT => match m.packet_bvh() {
                Some(b) => {
                    // SAFETY: the caller guarantees AVX-512F and DQ.
                    face_hits = unsafe { packet::intersect_faces(faces, &packet, t, found) };
                    (m, b)
                }
                None => (self, bvh),
            },
            _ => (self, bvh),
        };
        let mut single_stats = RayStats::default();
        let leaf = |t_max: &mut [f32; PACKET], first: u32, count: u32, mask: u16| {
            if count == 0 {
                // SAFETY: the caller guarantees AVX-512F, which includes AVX2.
                return unsafe {
                    mesh.subtree_ray_by_ray::<ANY_HIT>(
                        bvh,
                        &packet,
                        first,
                        mask,
                        t_max,
                        found,
                        &mut single_stats,
                    )
                };
            }
            let end = (first + count).div_ceil(BLOCK as u32) as usize;
            let blocks = end - first as usize / BLOCK;
            let rays_in = mask.count_ones() as usize;
            // Few rays in a leaf: each alone through 8-lane pairs of blocks costs less
            // than sixteen-lane tests of every triangle (see `leaf_rays`).
            if rays_in * blocks.div_ceil(2) <= mesh.leaf_rays as usize * blocks {
                // SAFETY: the caller guarantees AVX-512F, which includes AVX2.
                return unsafe {
                    mesh.leaf_ray_by_ray::<ANY_HIT>(&packet, first, count, mask, t_max, found)
                };
            }
            if mesh.shared.has(first) {
                // SAFETY: the caller guarantees AVX-512F and DQ; the leaf's corners are shared.
                return unsafe {
                    let leaf = packet::SharedLeaf {
                        shared: &mesh.shared,
                        positions: &mesh.positions,
                        blocks: &mesh.blocks,
                        first,
                        count,
                    };
                    packet::intersect_leaf_shared::<ANY_HIT>(&leaf, &packet, t_max, mask, found)
                };
            }
            let mut any = 0;
            for b in first as usize / BLOCK..end {
                // An any-hit ray is done at its first hit.
                let lanes = if ANY_HIT { mask & !any } else { mask };
                let block = &mesh.blocks[b];
                // The leaf's own triangles in the block (not the last block's padding).
                let n = (first + count) as usize - b * BLOCK;
                // SAFETY: the caller guarantees AVX-512F and DQ.
                any |= unsafe {
                    // Rays of one octant (camera, shadow and other coherent rays)
                    // take the leaf test with early outs.
                    if packet.boxes.one_octant {
                        packet::intersect_block::<ANY_HIT, true>(
                            block, b, &packet, t_max, lanes, found, n,
                        )
                    } else {
                        packet::intersect_block::<ANY_HIT, false>(
                            block, b, &packet, t_max, lanes, found, n,
                        )
                    }
                };
                if ANY_HIT && any == mask {
                    break;
                }
            }
            any
        };
        // SAFETY: the caller guarantees AVX-512F and DQ.
        let hit = unsafe {
            if ANY_HIT {
                bvh.occluded_packet(&packet.boxes, t, stats, leaf)
            } else {
                bvh.intersect_packet(&packet.boxes, t, stats, leaf)
            }
        };
        stats.nodes_visited += single_stats.nodes_visited;
        stats.prims_tested += single_stats.prims_tested;
        (hit | face_hits, mesh)
    }

    /// The rays `mask` of a packet, each alone against the leaf at positions
    /// `first..first + count`: as [`TriangleMesh::packet_avx512`]'s leaf callback.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[inline]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn leaf_ray_by_ray<const ANY_HIT: bool>(
        &self,
        packet: &RayPacket<'_>,
        first: u32,
        count: u32,
        mask: u16,
        t_max: &mut [f32; PACKET],
        found: &mut PacketHits,
    ) -> u16 {
        each_ray_alone::<ANY_HIT>(packet, mask, t_max, found, |wr, ray, closest| {
            if ANY_HIT {
                return self.leaf_blocks::<true, false>(wr, ray, first, count);
            }
            let mut t = ray.t_max;
            self.leaf_closest::<true, false>(wr, ray, first, count, &mut t, closest)
        })
    }

    /// The rays `mask` of a packet, each alone through the subtree of inner node `node`
    /// (the packet traversal's slow path, kept out of its leaf loop): as
    /// [`TriangleMesh::packet_avx512`]'s leaf callback. Compiled for AVX-512 as its
    /// caller is (EVEX code with 32 vector registers): on a Stanford bunny in a Cornell
    /// box (`benches/scenes/cbox-bunny.xml`), where a third of a render is spent here,
    /// renders took 2% less time than with the AVX2 tier's code.
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    #[inline(never)]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512dq,avx512bw")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn subtree_ray_by_ray<const ANY_HIT: bool>(
        &self,
        bvh: &crate::accel::Bvh8,
        packet: &RayPacket<'_>,
        node: u32,
        mask: u16,
        t_max: &mut [f32; PACKET],
        found: &mut PacketHits,
        stats: &mut RayStats,
    ) -> u16 {
        let prefetch = |first| self.prefetch_block(first);
        each_ray_alone::<ANY_HIT>(packet, mask, t_max, found, |wr, ray, closest| {
            if ANY_HIT {
                return bvh.occluded_leaves_from(ray, (node, 0), stats, prefetch, |f, c| {
                    self.leaf_blocks::<true, false>(wr, ray, f, c)
                });
            }
            bvh.intersect_leaves_from(ray, (node, 0), stats, prefetch, |f, c, t| {
                self.leaf_closest::<true, false>(wr, ray, f, c, t, closest)
            })
        })
    }

    /// Any hits of many rays (`occluded[i]` for `rays[i]`) in packets of sixteen where
    /// the processor has AVX-512 (see [`TriangleMesh::intersect_packets`]); the same
    /// answers as [`TriangleMesh::occluded`].
    pub fn occluded_packets(&self, rays: &[Ray], occluded: &mut [bool], stats: &mut RayStats) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        if let Some(bvh) = self.packet_bvh() {
            let (mut t, mut found) = ([0.0; PACKET], PacketHits::default());
            for (rays, occluded) in rays.chunks(PACKET).zip(occluded.chunks_mut(PACKET)) {
                // SAFETY: the processor supports AVX-512F and DQ (checked above).
                let (hit, _) =
                    unsafe { self.packet_avx512::<true>(bvh, rays, stats, &mut t, &mut found) };
                for (i, o) in occluded.iter_mut().enumerate() {
                    *o = hit & (1 << i) != 0;
                }
            }
            return;
        }
        for (ray, o) in rays.iter().zip(occluded.iter_mut()) {
            *o = self.occluded(ray, stats);
        }
    }

    /// Any hit through the mesh's BVH.
    #[inline(always)]
    pub fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        if let Some(o) = &self.occluders {
            if self.alpha.is_none() && o.hold(ray) {
                return o.mesh.as_ref().is_some_and(|m| m.occluded(ray, stats));
            }
        }
        if !self.blocks.is_empty() {
            if self.alpha.is_some() {
                return self.occluded_masked(ray, stats);
            }
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            if self.avx512 {
                // SAFETY: `avx512` is set only where the processor supports it.
                return unsafe { self.occluded_blocks_avx512(ray, stats) };
            }
            #[cfg(target_arch = "x86_64")]
            if self.avx2 {
                // SAFETY: `avx2` is set only where the processor has the AVX2 tier.
                return unsafe { self.occluded_blocks_avx2(ray, stats) };
            }
            return occluded_blocks!(self, ray, stats, false, false);
        }
        let wr = WatertightRay::new(ray);
        self.accel.occluded(ray, stats, |prim| {
            let (p0, p1, p2) = self.vertices(prim);
            intersect_triangle_watertight(&wr, ray.t_min, ray.t_max, p0, p1, p2)
                .is_some_and(|(_, _, b1, b2)| self.covers(ray, prim, b1, b2))
        })
    }

    #[inline(always)]
    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        // The vector arithmetic runs in 4-lane `Vec3A`s: the same operations per
        // component, in the same order, as with `Vec3` (dot products add x, y, then z),
        // so the results are equal bit for bit, in fewer instructions.
        let [i0, i1, i2] = self.indices[hit.prim as usize];
        let (p0, p1, p2) = self.vertices(hit.prim);
        let (p0, p1, p2) = (Vec3A::from(p0), Vec3A::from(p1), Vec3A::from(p2));
        let (b1, b2) = (hit.uv.x, hit.uv.y);
        let b0 = 1.0 - b1 - b2;
        let (a0, a1, a2) = (p0 * b0, p1 * b1, p2 * b2);
        let p = a0 + a1 + a2;
        let p_error = gamma(7) * (a0.abs() + a1.abs() + a2.abs());
        // Texture coordinates: the mesh's, or pbrt's default parameterisation.
        let (uv0, uv1, uv2) = self.corner_uvs(hit.prim);
        let uv = uv0 * b0 + uv1 * b1 + uv2 * b2;
        let cross = (p1 - p0).cross(p2 - p0);
        let mut n = if cross.length_squared() > 0.0 {
            unit(cross)
        } else {
            // Degenerate triangle: a normal in f64, else any.
            let (q0, q1, q2) = (p0.as_dvec3(), p1.as_dvec3(), p2.as_dvec3());
            let c = (q1 - q0).cross(q2 - q0);
            if c.length_squared() > 0.0 {
                Vec3A::from(c.normalize().as_vec3())
            } else {
                Vec3A::Z
            }
        };
        if self.flipped.get(hit.prim as usize) == Some(&true) {
            n = -n;
        }
        let mut shading_n = n;
        if self.smooth && !self.normals.is_empty() {
            let normal = |i: u32| Vec3A::from(self.normals[i as usize]);
            let ns = normal(i0) * b0 + normal(i1) * b1 + normal(i2) * b2;
            if ns.length_squared() > 0.0 {
                shading_n = unit(ns);
                // The geometric normal follows the side the vertex normals define.
                if n.dot(shading_n) < 0.0 {
                    n = -n;
                }
            }
        }
        // dp/du and dp/dv from the uv parameterisation (pbrt-v4, section 6.5.3).
        let (mut dpdu, mut dpdv) = if self.uvs.is_empty() {
            // The default parameterisation (corners at uv (0, 0), (1, 0), (1, 1)): u
            // runs from corner 0 to corner 1, v from corner 1 to corner 2 (det = 1).
            (p1 - p0, p2 - p1)
        } else {
            let duv02 = uv0 - uv2;
            let duv12 = uv1 - uv2;
            let det = duv02.x * duv12.y - duv02.y * duv12.x;
            if det.abs() > 1e-12 {
                (
                    ((p0 - p2) * duv12.y - (p1 - p2) * duv02.y) / det,
                    ((p1 - p2) * duv02.x - (p0 - p2) * duv12.x) / det,
                )
            } else {
                (Vec3A::ZERO, Vec3A::ZERO)
            }
        };
        if !dpdu.is_finite() || dpdu.cross(n).length_squared() == 0.0 {
            dpdu = Vec3A::from(Frame::from_normal(Vec3::from(n)).s);
        }
        if !dpdv.is_finite() || dpdu.cross(dpdv).length_squared() == 0.0 {
            dpdv = n.cross(dpdu);
        }
        let color = if self.colors.is_empty() {
            Vec3::ONE
        } else {
            let c = |i: u32| self.colors[i as usize];
            c(i0) * b0 + c(i1) * b1 + c(i2) * b2
        };
        SurfaceInteraction {
            p: p.into(),
            p_error: p_error.into(),
            t: hit.t,
            n: n.into(),
            shading_n: shading_n.into(),
            dpdu: dpdu.into(),
            dpdv: dpdv.into(),
            uv,
            color,
            wo: (-unit(Vec3A::from(ray.direction))).into(),
            instance: 0,
            prim: hit.prim,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    /// An icosphere-like closed mesh: an octahedron subdivided `levels` times.
    pub(crate) fn closed_sphere_mesh(levels: u32) -> MeshData {
        let mut positions = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let mut indices: Vec<[u32; 3]> = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        for _ in 0..levels {
            let mut mid = std::collections::HashMap::new();
            let mut next = Vec::new();
            let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    positions
                        .push(((positions[a as usize] + positions[b as usize]) * 0.5).normalize());
                    positions.len() as u32 - 1
                })
            };
            for [a, b, c] in indices {
                let ab = midpoint(a, b, &mut positions);
                let bc = midpoint(b, c, &mut positions);
                let ca = midpoint(c, a, &mut positions);
                next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
            }
            indices = next;
        }
        MeshData {
            positions,
            normals: vec![],
            uvs: vec![],
            indices,
            colors: Vec::new(),
            face_colors: Vec::new(),
        }
    }

    #[test]
    fn single_triangle_analytic() {
        let data = MeshData {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![],
            uvs: vec![],
            indices: vec![[0, 1, 2]],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        let mesh = TriangleMesh::new(data, false, AccelKind::Bvh2).unwrap();
        let mut s = RayStats::default();
        let ray = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        let h = mesh.intersect(&ray, &mut s).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        let si = mesh.interaction(&ray, &h);
        assert!((si.p - Vec3::new(0.25, 0.25, 0.0)).length() < 1e-6);
        assert!((si.n - Vec3::Z).length() < 1e-6);
        // Barycentrics of (0.25, 0.25): b1 = 0.25, b2 = 0.25.
        assert!((h.uv - Vec2::splat(0.25)).length() < 1e-6);
        assert!(mesh
            .intersect(&Ray::new(Vec3::new(0.75, 0.75, 1.0), -Vec3::Z), &mut s)
            .is_none());
        // Backface hits count too (no culling).
        assert!(mesh
            .intersect(&Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z), &mut s)
            .is_some());
        // t range.
        assert!(mesh
            .intersect(
                &Ray::with_range(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, 0.5),
                &mut s
            )
            .is_none());
        assert!(mesh
            .intersect(
                &Ray::with_range(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 1.5, 9.0),
                &mut s
            )
            .is_none());
    }

    /// Rays whose directions are far from unit length find the same hits: the
    /// object-space rays of a mesh scaled up a thousandfold (directions 1e-3 long, as
    /// a scaled instance's), and shadow rays aimed at a far point (directions 1e3 long).
    /// `delta_t`'s bound once took the shear's scaled `z` for the unscaled one, and so
    /// rejected every hit of a direction 1e-3 long on a small mesh.
    #[test]
    fn directions_of_any_length_hit_alike() {
        // A small closed sphere (radius 0.08, as a Stanford bunny's size), rays from
        // 0.6 away at points on it.
        let mut data = closed_sphere_mesh(3);
        for p in &mut data.positions {
            *p *= 0.08;
        }
        let mut rng = Pcg32::new(17, 2);
        let mut rays = Vec::new();
        for _ in 0..64 {
            let mut u = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
            let o = u().normalize_or(Vec3::X) * 0.6;
            let target = u() * 0.08;
            rays.push(Ray::new(o, (target - o).normalize()));
        }
        for kind in [
            AccelKind::List,
            AccelKind::Bvh2,
            AccelKind::BvhCourse,
            AccelKind::Bvh4,
            AccelKind::Bvh8,
            AccelKind::Grid,
            AccelKind::KdTree,
        ] {
            let mesh = TriangleMesh::new(data.clone(), false, kind).unwrap();
            let mut s = RayStats::default();
            for scale in [1.0f32, 1e-3, 1e-5, 1e3] {
                let scaled: Vec<Ray> = rays
                    .iter()
                    .map(|r| Ray::new(r.origin, r.direction * scale))
                    .collect();
                let mut hits = MeshHits::default();
                mesh.intersect_to(&scaled, &mut hits, &mut s);
                let mut occluded = vec![false; scaled.len()];
                mesh.occluded_packets(&scaled, &mut occluded, &mut s);
                for (i, (ray, r)) in rays.iter().zip(&scaled).enumerate() {
                    let want = mesh.intersect(ray, &mut s).expect("unit rays hit");
                    let what = format!("{kind:?}, direction x{scale}, ray {i}");
                    let h = mesh
                        .intersect(r, &mut s)
                        .unwrap_or_else(|| panic!("{what}"));
                    assert_eq!(h.prim, want.prim, "{what}");
                    let t = h.t * scale;
                    assert!(
                        (t - want.t).abs() <= 1e-5 * want.t,
                        "{what}: {t} {}",
                        want.t
                    );
                    assert!(mesh.occluded(r, &mut s), "{what}");
                    let batch = hits.get(i).unwrap_or_else(|| panic!("{what}, batched"));
                    assert_eq!(batch.prim, want.prim, "{what}, batched");
                    assert!(occluded[i], "{what}, batched");
                }
            }
        }
    }

    #[test]
    fn bad_meshes_are_rejected() {
        let bad_index = MeshData {
            positions: vec![Vec3::ZERO; 3],
            normals: vec![],
            uvs: vec![],
            indices: vec![[0, 1, 3]],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        assert!(TriangleMesh::new(bad_index, true, AccelKind::Bvh2)
            .unwrap_err()
            .contains("vertex 3"));
        let nan = MeshData {
            positions: vec![Vec3::ZERO, Vec3::NAN, Vec3::X],
            normals: vec![],
            uvs: vec![],
            indices: vec![[0, 1, 2]],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        assert!(TriangleMesh::new(nan, true, AccelKind::Bvh2).is_err());
    }

    /// The parallel check finds the first offending item wherever it lies (in the
    /// first chunk, past it, at a chunk's last item, with later offenders too), and none
    /// where there is none.
    #[test]
    fn first_where_finds_the_first_offender() {
        let n = 3 * CHECK_CHUNK + 5;
        for bad in [
            vec![],
            vec![0],
            vec![7, 9],
            vec![CHECK_CHUNK - 1, CHECK_CHUNK, n - 1],
            vec![2 * CHECK_CHUNK + 3, 3 * CHECK_CHUNK + 1],
            vec![n - 1],
        ] {
            let items: Vec<bool> = (0..n).map(|i| bad.contains(&i)).collect();
            assert_eq!(first_where(&items, |&b| b), bad.first().copied(), "{bad:?}");
        }
        assert_eq!(first_where(&[] as &[bool], |&b| b), None);
    }

    /// Shoots rays through the shared vertices and edge points of a closed convex mesh,
    /// from inside and from outside in front of the point (so the ray crosses the surface
    /// there rather than grazing a silhouette): every one must hit.
    #[test]
    fn watertight_through_edges_and_vertices() {
        // Scalar triangle tests (bvh2) and SIMD blocks of four (bvh8).
        for kind in [AccelKind::Bvh2, AccelKind::Bvh8] {
            watertight_through_edges_and_vertices_with(kind);
        }
    }

    fn watertight_through_edges_and_vertices_with(kind: AccelKind) {
        let data = closed_sphere_mesh(4); // 2048 triangles
        let mesh = TriangleMesh::new(data, false, kind).unwrap();
        let mut rng = Pcg32::new(11, 7);
        let mut targets = Vec::new();
        for &[a, b, c] in &mesh.indices {
            let (pa, pb, pc) = (
                mesh.positions[a as usize],
                mesh.positions[b as usize],
                mesh.positions[c as usize],
            );
            targets.push(pa);
            for (p, q) in [(pa, pb), (pb, pc), (pc, pa)] {
                for _ in 0..3 {
                    let s = rng.next_f32();
                    targets.push(p + (q - p) * s);
                }
            }
        }
        let mut misses = 0usize;
        let mut shot = 0usize;
        let mut stats = RayStats::default();
        while shot < 500_000 {
            for &target in &targets {
                // From a random point outside, and from a random point inside.
                let jitter = Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                );
                let outside = target.normalize() * 3.0 + jitter;
                let inside = Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                ) * 0.5;
                for origin in [outside, inside] {
                    let ray = Ray::new(origin, target - origin);
                    if mesh.intersect(&ray, &mut stats).is_none() {
                        misses += 1;
                    }
                    shot += 1;
                }
            }
        }
        assert_eq!(misses, 0, "{misses} of {shot} rays slipped through");
    }

    /// The wide BVHs' SIMD triangle blocks find the same closest hits (distance,
    /// triangle, barycentrics) and the same occlusion as the brute-force list with the
    /// scalar test, on a random triangle soup, a closed sphere and a flat grid, with
    /// rays along the axes and limited ranges. Where two triangles share the hit
    /// distance exactly (an edge), either may be reported.
    /// The stream queries answer every ray exactly as the single-ray ones do (distance,
    /// triangle and barycentrics to the bit, occlusion, traversal counters), through the
    /// 8-wide BVH's stream traversal and through the ray-by-ray fallback of the other
    /// accelerators.
    #[test]
    fn streams_match_ray_by_ray() {
        let tris = crate::accel::testing::random_soup(4000, 12);
        let soup = soup_mesh(&tris);
        let rays = crate::accel::testing::rays_for(&tris, 3000, 4);
        for kind in [AccelKind::Bvh8, AccelKind::Bvh4, AccelKind::Bvh2] {
            let mesh = TriangleMesh::new(soup.clone(), false, kind).unwrap();
            let mut single_stats = RayStats::default();
            let single: Vec<_> = rays
                .iter()
                .map(|r| mesh.intersect(r, &mut single_stats))
                .collect();
            let single_occ: Vec<_> = rays
                .iter()
                .map(|r| mesh.occluded(r, &mut single_stats))
                .collect();
            let mut stats = RayStats::default();
            let mut hits = vec![None; rays.len()];
            let mut occ = vec![false; rays.len()];
            // In uneven pieces, so that streams start and end part-way.
            for (r, h) in rays.chunks(777).zip(hits.chunks_mut(777)) {
                mesh.intersect_stream(r, h, &mut stats);
            }
            for (r, o) in rays.chunks(500).zip(occ.chunks_mut(500)) {
                mesh.occluded_stream(r, o, &mut stats);
            }
            let bits = |h: &Option<ShapeHit>| {
                h.map(|h| (h.t.to_bits(), h.prim, h.uv.to_array().map(f32::to_bits)))
            };
            assert_eq!(
                single.iter().map(bits).collect::<Vec<_>>(),
                hits.iter().map(bits).collect::<Vec<_>>(),
                "{kind:?}"
            );
            assert_eq!(single_occ, occ, "{kind:?}");
            assert_eq!(
                (single_stats.nodes_visited, single_stats.prims_tested),
                (stats.nodes_visited, stats.prims_tested),
                "{kind:?}"
            );
            assert!(
                hits.iter().filter(|h| h.is_some()).count() > 500,
                "{kind:?}"
            );
            assert!(occ.iter().filter(|&&o| !o).count() > 100, "{kind:?}");
        }
    }

    /// Separate triangles as a mesh.
    fn soup_mesh(tris: &[[Vec3; 3]]) -> MeshData {
        MeshData {
            positions: tris.iter().flatten().copied().collect(),
            normals: vec![],
            uvs: vec![],
            indices: (0..tris.len() as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect(),
            colors: Vec::new(),
            face_colors: Vec::new(),
        }
    }

    /// An `n`×`n` grid of squares of side `step` at z = 1, two triangles each.
    fn grid_mesh(n: u32, step: f32) -> MeshData {
        let mut grid = MeshData {
            positions: vec![],
            normals: vec![],
            uvs: vec![],
            indices: vec![],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        for y in 0..=n {
            for x in 0..=n {
                grid.positions
                    .push(Vec3::new(x as f32 * step, y as f32 * step, 1.0));
                if x < n && y < n {
                    let i = y * (n + 1) + x;
                    grid.indices.push([i, i + 1, i + n + 2]);
                    grid.indices.push([i, i + n + 2, i + n + 1]);
                }
            }
        }
        grid
    }

    /// Checks `mesh`'s packet queries against its ray-by-ray ones on `rays` (in uneven
    /// pieces): the same answers, and the same closest hits, bit for bit, except that a
    /// tie at exactly the same distance may name the other triangle (which must then be
    /// hit there alone). With `near` above zero, a tie may also be between distances
    /// that differ by up to that fraction (triangles that meet where the ray passes,
    /// tested in another order). Returns the rays hit and missed.
    fn packets_match(mesh: &TriangleMesh, rays: &[Ray], near: f32) -> (usize, usize) {
        let s = &mut RayStats::default();
        let mut hits = vec![None; rays.len()];
        let mut occ = vec![false; rays.len()];
        // In uneven pieces, so that packets are partly filled.
        for (r, h) in rays.chunks(333).zip(hits.chunks_mut(333)) {
            mesh.intersect_packets(r, h, s);
        }
        for (r, o) in rays.chunks(250).zip(occ.chunks_mut(250)) {
            mesh.occluded_packets(r, o, s);
        }
        // The same packets' hits in arrays: the same hits (one `MeshHits` for all
        // pieces, as a renderer reuses it).
        let mut arrays = MeshHits::default();
        for (c, r) in rays.chunks(333).enumerate() {
            mesh.intersect_to(r, &mut arrays, s);
            for (j, want) in hits[333 * c..][..r.len()].iter().enumerate() {
                let got = arrays.get(j);
                assert_eq!(
                    got.map(|h| (h.t.to_bits(), h.prim, h.uv.to_array().map(f32::to_bits))),
                    want.map(|h| (h.t.to_bits(), h.prim, h.uv.to_array().map(f32::to_bits))),
                    "ray {}",
                    333 * c + j
                );
            }
        }
        let mut found = 0;
        for (i, ray) in rays.iter().enumerate() {
            let single = mesh.intersect(ray, s);
            assert_eq!(mesh.occluded(ray, s), occ[i], "ray {i}: {ray:?}");
            assert_eq!(single.is_some(), occ[i], "ray {i}");
            match (single, hits[i]) {
                (Some(a), Some(b)) => {
                    found += 1;
                    if near == 0.0 || a.t.to_bits() == b.t.to_bits() {
                        assert_eq!(a.t.to_bits(), b.t.to_bits(), "ray {i}");
                    } else {
                        assert!((a.t - b.t).abs() <= near * a.t, "ray {i}: {a:?}, {b:?}");
                    }
                    // A tie at exactly the same distance may name the other triangle;
                    // then that triangle alone must be hit there.
                    let wr = WatertightRay::new(ray);
                    let (p0, p1, p2) = mesh.vertices(b.prim);
                    let alone =
                        intersect_triangle_watertight(&wr, ray.t_min, ray.t_max, p0, p1, p2)
                            .expect("the reported triangle is hit");
                    assert_eq!(alone.0.to_bits(), b.t.to_bits(), "ray {i}");
                    assert_eq!(
                        [alone.2, alone.3].map(f32::to_bits),
                        b.uv.to_array().map(f32::to_bits),
                        "ray {i}"
                    );
                }
                (a, b) => assert_eq!(a.is_some(), b.is_some(), "ray {i}"),
            }
        }
        (found, occ.iter().filter(|&&o| !o).count())
    }

    /// A room of few triangles whose floor (two quads), ceiling, left and back walls
    /// lie in its box's faces; its right wall leans, a block floats in it, and its front
    /// is open. No two triangles overlap.
    fn small_room() -> MeshData {
        let mut m = MeshData::default();
        let v = Vec3::new;
        let mut quad = |q: [Vec3; 4]| {
            let k = m.positions.len() as u32;
            m.positions.extend(q);
            m.indices.push([k, k + 1, k + 2]);
            m.indices.push([k, k + 2, k + 3]);
        };
        let (x, y, z) = (4.0, 3.0, 5.0);
        quad([
            v(0.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(2.0, 0.0, z),
            v(0.0, 0.0, z),
        ]);
        quad([
            v(2.0, 0.0, 0.0),
            v(x, 0.0, 0.0),
            v(x, 0.0, z),
            v(2.0, 0.0, z),
        ]);
        quad([v(0.0, y, 0.0), v(0.0, y, z), v(x, y, z), v(x, y, 0.0)]);
        quad([v(0.0, 0.0, z), v(x, 0.0, z), v(x, y, z), v(0.0, y, z)]);
        quad([
            v(0.0, 0.0, 0.0),
            v(0.0, 0.0, z),
            v(0.0, y, z),
            v(0.0, y, 0.0),
        ]);
        quad([v(x, 0.0, 0.0), v(x, 0.0, z), v(3.7, y, z), v(3.7, y, 0.0)]);
        // The floating block, turned about the vertical.
        let (sn, cs) = 0.4f32.sin_cos();
        let p = |dx: f32, dz: f32, h: f32| v(1.8 + cs * dx - sn * dz, h, 2.4 + sn * dx + cs * dz);
        let c = [
            p(-0.6, -0.6, 0.5),
            p(0.6, -0.6, 0.5),
            p(0.6, 0.6, 0.5),
            p(-0.6, 0.6, 0.5),
            p(-0.6, -0.6, 1.6),
            p(0.6, -0.6, 1.6),
            p(0.6, 0.6, 1.6),
            p(-0.6, 0.6, 1.6),
        ];
        for f in [
            [0, 1, 2, 3],
            [4, 7, 6, 5],
            [0, 4, 5, 1],
            [1, 5, 6, 2],
            [2, 6, 7, 3],
            [3, 7, 4, 0],
        ] {
            quad(f.map(|i| c[i]));
        }
        m
    }

    /// Closest-hit packets through a mesh with few triangles in its box's faces test
    /// each ray against the faces it crosses only (`packet::intersect_faces`), then the
    /// rest: the same hits as the whole mesh ray by ray, for rays from inside and
    /// outside, from the walls themselves, grazing them, and through the box's edges
    /// and corners.
    #[test]
    fn closest_hits_take_the_box_faces_alike() {
        let data = small_room();
        let mesh = TriangleMesh::new(data.clone(), false, AccelKind::Bvh8).unwrap();
        let occluders = mesh.occluders.as_deref().expect("the room has occluders");
        #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
        assert!(occluders.faces.is_some(), "the room's faces are in a table");
        // The floor's four triangles, the ceiling's, the back's and the left wall's two.
        let kept = occluders.mesh.as_ref().unwrap().indices.len();
        assert_eq!(mesh.indices.len() - kept, 10);
        let b = mesh.accel.bounds();
        let size = b.max - b.min;
        let mut rng = Pcg32::new(21, 5);
        let mut u = || rng.next_f32();
        let mut rays = Vec::new();
        for i in 0..30_000usize {
            let inside = b.min + size * Vec3::new(u(), u(), u());
            let o = match i % 8 {
                0 | 1 => inside,
                // On the floor, the left wall and the back wall exactly.
                2 => Vec3::new(inside.x, 0.0, inside.z),
                3 => Vec3::new(0.0, inside.y, inside.z),
                4 => Vec3::new(inside.x, inside.y, 5.0),
                // Outside: in front (a camera), above, and anywhere around.
                5 => Vec3::new(2.0 + u(), 1.5 + u(), -3.0 - u()),
                6 => Vec3::new(inside.x, 3.5 + u(), inside.z),
                _ => b.min + size * (Vec3::new(u(), u(), u()) * 1.6 - Vec3::splat(0.3)),
            };
            let at = b.min + size * Vec3::new(u(), u(), u());
            let to = match i % 7 {
                // Through the box's edges and corners, and just inside and outside them.
                0 => {
                    let w = [0.0, 1e-6, -1e-6, 1e-3, -1e-3][i % 5];
                    let mut e = at.to_array();
                    let (k, j) = (i % 3, (i / 3) % 3);
                    e[k] = if i % 2 == 0 {
                        b.min[k] - w
                    } else {
                        b.max[k] + w
                    };
                    if j != k {
                        e[j] = if i % 4 < 2 {
                            b.min[j] + w
                        } else {
                            b.max[j] - w
                        };
                    }
                    Vec3::from_array(e)
                }
                1 => [
                    b.min,
                    b.max,
                    Vec3::new(0.0, 0.0, 5.0),
                    Vec3::new(0.0, 3.0, 5.0),
                ][i % 4],
                // On the floor and the left wall at their open front edge, and just
                // behind it (where rounding may put the crossing in front of the box).
                2 => {
                    let w = [0.0, 1e-7, 1e-6, 1e-5][i % 4];
                    match i % 3 {
                        0 => Vec3::new(at.x, 0.0, w),
                        1 => Vec3::new(0.0, at.y, w),
                        _ => Vec3::new(at.x, 3.0, w),
                    }
                }
                _ => at,
            };
            let mut d = to - o;
            // Grazing: in the plane of the floor or of a wall.
            match i % 11 {
                0 => d.y = 0.0,
                1 => d.x = 0.0,
                2 => d = [Vec3::X, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z][i % 4],
                _ => {}
            }
            let (t_min, t_max) = match i % 5 {
                0 => (0.0, 0.7),
                1 => (0.2, f32::INFINITY),
                _ => (0.0, f32::INFINITY),
            };
            rays.push(Ray::with_range(o, d, t_min, t_max));
        }
        // Rays through the box's edges and corners meet several triangles there, at
        // distances a few roundings apart, which the faces' table tests in another
        // order than the tree's leaves.
        let (found, missed) = packets_match(&mesh, &rays, 1e-6);
        assert!(
            found > 15_000 && missed > 1_000,
            "{found} hit, {missed} missed"
        );
        // The whole mesh ray by ray: the same hits as the mesh with the faces' table,
        // up to ties where triangles meet.
        let whole = crate::accel::in_pool(|| {
            TriangleMesh::new_in_pool(data.clone(), false, AccelKind::Bvh8, false)
        })
        .unwrap();
        assert!(whole.occluders.is_none());
        let s = &mut RayStats::default();
        let mut exact = 0;
        for (i, r) in rays.iter().enumerate() {
            let (a, b) = (whole.intersect(r, s), mesh.intersect(r, s));
            assert_eq!(a.is_some(), b.is_some(), "ray {i}: {r:?}");
            if let (Some(a), Some(b)) = (a, b) {
                assert!((a.t - b.t).abs() <= 1e-6 * a.t, "ray {i}: {a:?}, {b:?}");
                exact += (a.t.to_bits() == b.t.to_bits()) as usize;
            } else {
                exact += 1;
            }
        }
        // Only rays through edges and corners may differ at all.
        assert!(exact > rays.len() * 99 / 100, "{exact} hits the same");
    }

    #[test]
    fn packets_match_ray_by_ray() {
        let mut rng = Pcg32::new(5, 9);
        let soup = soup_mesh(&crate::accel::testing::random_soup(3000, 7));
        // A grid whose vertices and edges rays go through exactly (edge functions of 0:
        // the scalar fallback), and a closed sphere.
        let grid = grid_mesh(10, 0.25);
        let mut sphere = closed_sphere_mesh(3);
        for p in &mut sphere.positions {
            *p = *p * 1.2 + Vec3::splat(1.2);
        }
        for (k, data) in [soup, grid, sphere].into_iter().enumerate() {
            let mut b = crate::math::Bounds3::from_point(data.positions[0]);
            for &p in &data.positions {
                b.expand(p);
            }
            let mut rays = Vec::new();
            for i in 0..3001usize {
                let mut u = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                let mut o = b.min + (b.max - b.min) * (u() * 1.4 - Vec3::splat(0.2));
                let mut d = u() - Vec3::splat(0.5);
                match i % 7 {
                    // Axis-parallel, and through grid vertices and edges.
                    0 => d = [Vec3::Z, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Z][i % 4],
                    1 => {
                        o = Vec3::new((i % 11) as f32 * 0.25, (i / 11 % 11) as f32 * 0.25, -1.0);
                        d = Vec3::Z;
                    }
                    2 => d = Vec3::new(d.x, 0.0, d.z),
                    // From a point on a triangle (hits there, at t near 0, are not
                    // provably in front: the tests' `delta_t`).
                    3 => {
                        let [a, b, c] = data.indices[i % data.indices.len()]
                            .map(|k| data.positions[k as usize]);
                        let (r1, r2) = (rng.next_f32() * 0.5, rng.next_f32() * 0.5);
                        o = a + (b - a) * r1 + (c - a) * r2;
                    }
                    _ => {}
                }
                let (t_min, t_max) = match i % 5 {
                    0 => (0.0, 1.5),
                    1 => (0.3, f32::INFINITY),
                    _ => (0.0, f32::INFINITY),
                };
                rays.push(Ray::with_range(o, d, t_min, t_max));
            }
            let mesh = TriangleMesh::new(data.clone(), false, AccelKind::Bvh8).unwrap();
            // Scattered rays, and the same rays turned into one octant (packets of
            // coherent rays take the leaf test with early outs), with and without the
            // packets' bound on `delta_t`.
            let one_octant: Vec<Ray> = rays
                .iter()
                .map(|r| Ray {
                    direction: r.direction.abs(),
                    ..*r
                })
                .collect();
            // The random soup's triangles are too small for the bound to pay.
            assert_eq!(mesh.delta_t_box.is_empty(), k == 0);
            let mut unbounded = mesh.clone();
            unbounded.delta_t_box = Bounds3::EMPTY;
            // The grid's and the sphere's leaves share corners (tested once per leaf, see
            // `packet::SharedCorners`), the random soup's do not; each mesh is tested
            // block by block too.
            #[allow(unused_mut)]
            let mut blockwise = mesh.clone();
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            {
                if crate::accel::Bvh8::packets_supported() {
                    assert_eq!(mesh.shared.leaves() > 0, k > 0);
                }
                blockwise.shared = Default::default();
            }
            // Leaves taken sixteen lanes at a time whatever their rays, and ray by ray
            // where up to eight rays enter them (`leaf_rays`).
            #[allow(unused_mut)]
            let (mut lanes, mut alone) = (mesh.clone(), mesh.clone());
            #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
            {
                (lanes.leaf_rays, alone.leaf_rays) = (0, 4);
            }
            for (mesh, rays) in [
                (&mesh, rays.clone()),
                (&mesh, one_octant.clone()),
                (&unbounded, rays.clone()),
                (&unbounded, one_octant.clone()),
                (&blockwise, rays.clone()),
                (&blockwise, one_octant.clone()),
                (&lanes, rays.clone()),
                (&lanes, one_octant.clone()),
                (&alone, rays.clone()),
                (&alone, one_octant),
            ] {
                let (found, missed) = packets_match(mesh, &rays, 0.0);
                assert!(found > 300, "only {found} hits");
                assert!(missed > 300);
            }
        }
        // A mesh with nothing to hit answers every ray with a miss.
        let empty = MeshData {
            positions: vec![],
            normals: vec![],
            uvs: vec![],
            indices: vec![],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        let mesh = TriangleMesh::new(empty, false, AccelKind::Bvh8).unwrap();
        let rays = vec![Ray::new(Vec3::ZERO, Vec3::Z); 20];
        let (mut hits, mut occ) = (vec![None; 20], vec![true; 20]);
        let s = &mut RayStats::default();
        mesh.intersect_packets(&rays, &mut hits, s);
        mesh.occluded_packets(&rays, &mut occ, s);
        assert!(hits.iter().all(Option::is_none) && occ.iter().all(|&o| !o));
    }

    /// A room in the box `[0, 5.5] × [0, 5.4] × [0, 5.6]`: floor, ceiling, back and left
    /// walls in the box's faces (each a grid of quads), a slanted right wall that is
    /// not, a block standing on the floor (its bottom in the floor's face), a turned
    /// block in the air, and a light quad `drop` below the ceiling.
    fn room_mesh(drop: f32) -> MeshData {
        let mut m = MeshData::default();
        let mut quad = |m: &mut MeshData, q: [Vec3; 4], n: u32| {
            // An n×n grid of quads over the corners q (bilinear), two triangles each.
            let at = |u: f32, v: f32| {
                let (a, b) = (q[0] + (q[1] - q[0]) * u, q[3] + (q[2] - q[3]) * u);
                a + (b - a) * v
            };
            let base = m.positions.len() as u32;
            for j in 0..=n {
                for i in 0..=n {
                    m.positions
                        .push(at(i as f32 / n as f32, j as f32 / n as f32));
                }
            }
            for j in 0..n {
                for i in 0..n {
                    let k = base + j * (n + 1) + i;
                    m.indices.push([k, k + 1, k + n + 2]);
                    m.indices.push([k, k + n + 2, k + n + 1]);
                }
            }
        };
        let v = Vec3::new;
        let (x, y, z) = (5.5, 5.4, 5.6);
        quad(
            &mut m,
            [
                v(0.0, 0.0, 0.0),
                v(x, 0.0, 0.0),
                v(x, 0.0, z),
                v(0.0, 0.0, z),
            ],
            3,
        );
        quad(
            &mut m,
            [v(0.0, y, 0.0), v(0.0, y, z), v(x, y, z), v(x, y, 0.0)],
            3,
        );
        quad(
            &mut m,
            [v(0.0, 0.0, z), v(x, 0.0, z), v(x, y, z), v(0.0, y, z)],
            2,
        );
        quad(
            &mut m,
            [
                v(0.0, 0.0, 0.0),
                v(0.0, 0.0, z),
                v(0.0, y, z),
                v(0.0, y, 0.0),
            ],
            2,
        );
        quad(
            &mut m,
            [v(5.3, 0.0, 0.0), v(5.3, 0.0, z), v(x, y, z), v(x, y, 0.0)],
            1,
        );
        // Blocks: a box's six faces from its eight corners (bottom four, then top four).
        let block = |m: &mut MeshData,
                     c: [Vec3; 8],
                     quad: &mut dyn FnMut(&mut MeshData, [Vec3; 4], u32)| {
            for f in [
                [0, 1, 2, 3],
                [4, 7, 6, 5],
                [0, 4, 5, 1],
                [1, 5, 6, 2],
                [2, 6, 7, 3],
                [3, 7, 4, 0],
            ] {
                quad(m, f.map(|i| c[i]), 1);
            }
        };
        let turned = |cx: f32, cz: f32, h: f32, y0: f32, r: f32, a: f32| {
            let (s, c) = a.sin_cos();
            let p = |dx: f32, dz: f32, y: f32| v(cx + c * dx - s * dz, y, cz + s * dx + c * dz);
            [
                p(-r, -r, y0),
                p(r, -r, y0),
                p(r, r, y0),
                p(-r, r, y0),
                p(-r, -r, y0 + h),
                p(r, -r, y0 + h),
                p(r, r, y0 + h),
                p(-r, r, y0 + h),
            ]
        };
        block(&mut m, turned(1.8, 1.9, 1.6, 0.0, 0.8, 0.3), &mut quad);
        block(&mut m, turned(3.7, 3.6, 1.0, 1.5, 0.6, -0.5), &mut quad);
        let ly = y - drop;
        quad(
            &mut m,
            [
                v(2.1, ly, 2.2),
                v(2.1, ly, 3.3),
                v(3.4, ly, 3.3),
                v(3.4, ly, 2.2),
            ],
            1,
        );
        m
    }

    /// Shadow rays inside a mesh's box are traced without the triangles in the box's
    /// faces ([`Occluders`]) and get the same answers as through the whole mesh: from
    /// points on the mesh (on the floor with `y` exactly 0, in corners), inside the
    /// room and outside it, to the light, to points in the room, close to the walls and
    /// beyond them, ray by ray and in packets.
    #[test]
    fn shadow_rays_skip_the_box_faces_alike() {
        let data = room_mesh(0.25);
        let mesh = TriangleMesh::new(data.clone(), false, AccelKind::Bvh8).unwrap();
        let whole = crate::accel::in_pool(|| {
            TriangleMesh::new_in_pool(data.clone(), false, AccelKind::Bvh8, false)
        })
        .unwrap();
        let occluders = mesh.occluders.as_deref().expect("the room has occluders");
        assert!(whole.occluders.is_none());
        // The floor's 18, the ceiling's 18, the back's and left wall's 8 each and the
        // standing block's bottom 2.
        let kept = occluders.mesh.as_ref().unwrap().indices.len();
        assert_eq!(mesh.indices.len() - kept, 18 + 18 + 8 + 8 + 2);
        let b = mesh.accel.bounds();
        let mut rng = Pcg32::new(11, 3);
        let mut u = || rng.next_f32();
        let on_mesh = |u: &mut dyn FnMut() -> f32| {
            let t = data.indices[(u() * data.indices.len() as f32) as usize % data.indices.len()];
            let [a, b2, c] = t.map(|k| data.positions[k as usize]);
            let (r1, r2) = (u() * 0.5, u() * 0.5);
            a + (b2 - a) * r1 + (c - a) * r2
        };
        let mut rays = Vec::new();
        let mut held = 0;
        for i in 0..24_000usize {
            let o = match i % 6 {
                0 | 1 => on_mesh(&mut u),
                // On the floor exactly, some in the corner by the left and back walls.
                2 => Vec3::new(u() * 5.5 * (i % 4) as f32 / 3.0, 0.0, 5.6 - u() * 2.0),
                3 => b.min + (b.max - b.min) * Vec3::new(u(), u(), u()),
                4 => Vec3::new(u() * 0.01, u() * 0.01, u() * 5.6),
                _ => b.min + (b.max - b.min) * (Vec3::new(u(), u(), u()) * 1.4 - Vec3::splat(0.2)),
            };
            let end = match i % 5 {
                // On the light, and just below it.
                0 => Vec3::new(2.1 + u() * 1.3, 5.15 - u() * 0.01, 2.2 + u() * 1.1),
                1 => b.min + (b.max - b.min) * Vec3::new(u(), u(), u()),
                // Near the walls: within the margin, at it and beyond them; and grazing
                // the floor.
                2 => {
                    let w = [0.0, 1e-4, 1.5e-3, 3e-3, 1e-2, -1e-3][i % 6];
                    let p = b.min + (b.max - b.min) * Vec3::new(u(), u(), u());
                    let k = i % 3;
                    let mut p = p.to_array();
                    p[k] = if i % 2 == 0 {
                        b.min[k] + w
                    } else {
                        b.max[k] - w
                    };
                    Vec3::from_array(p)
                }
                3 => Vec3::new(u() * 5.5, 3e-3 + u() * 1e-3, u() * 5.6),
                _ => on_mesh(&mut u),
            };
            let d = end - o;
            let ray = if i % 2 == 0 {
                Ray::with_range(o, d, 0.0, 1.0 - 1e-4)
            } else {
                let len = d.length();
                Ray::with_range(o, d / len, 0.0, len * (1.0 - 1e-4))
            };
            held += occluders.hold(&ray) as usize;
            rays.push(ray);
        }
        assert!(held > 6000 && held < 20_000, "{held} rays held");
        let s = &mut RayStats::default();
        let want: Vec<bool> = rays.iter().map(|r| whole.occluded(r, s)).collect();
        let mut packets = vec![false; rays.len()];
        for (r, p) in rays.chunks(100).zip(packets.chunks_mut(100)) {
            mesh.occluded_packets(r, p, s);
        }
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(mesh.occluded(r, s), want[i], "ray {i}: {r:?}");
            assert_eq!(packets[i], want[i], "ray {i} in a packet: {r:?}");
        }
        let blocked = want.iter().filter(|&&w| w).count();
        assert!(blocked > 2000 && blocked < 22_000, "{blocked} rays blocked");
        // A light in the ceiling's plane is in a face of the box: rays to it are not held.
        let flush = TriangleMesh::new(room_mesh(0.0), false, AccelKind::Bvh8).unwrap();
        let o = flush.occluders.as_deref().unwrap();
        let to_light = Ray::with_range(
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.5, 5.4, 1.5),
            0.0,
            1.0 - 1e-4,
        );
        assert!(!o.hold(&to_light));
    }

    #[test]
    fn simd_blocks_match_the_scalar_list() {
        let mut rng = Pcg32::new(21, 4);
        let mut soup = MeshData {
            positions: vec![],
            normals: vec![],
            uvs: vec![],
            indices: vec![],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        for i in 0..3000u32 {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0;
            for _ in 0..3 {
                let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
                soup.positions.push(c + d * 0.6);
            }
            soup.indices.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let grid = grid_mesh(20, 0.2);
        let mut sphere = closed_sphere_mesh(3);
        for p in &mut sphere.positions {
            *p = *p * 1.5 + Vec3::splat(2.0);
        }
        for data in [soup, grid, sphere] {
            let list = TriangleMesh::new(data.clone(), false, AccelKind::List).unwrap();
            for kind in [AccelKind::Bvh4, AccelKind::Bvh8] {
                let best = TriangleMesh::new(data.clone(), false, kind).unwrap();
                assert!(!best.blocks.is_empty());
                // Every SIMD level the processor has: AVX-512, AVX2, 4-lane blocks.
                let mut levels = vec![best.clone()];
                #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
                if best.avx512 {
                    let mut m = best.clone();
                    m.avx512 = false;
                    levels.push(m);
                }
                if best.avx2 {
                    // AVX2 with the other leaf test than the processor's choice.
                    let mut m = levels.last().unwrap().clone();
                    m.pair_blocks = !m.pair_blocks;
                    levels.push(m);
                    let mut m = levels.last().unwrap().clone();
                    m.avx2 = false;
                    m.pair_blocks = false;
                    levels.push(m);
                }
                for mesh in &levels {
                    let mut hits = 0;
                    for i in 0..4000 {
                        let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0
                            - Vec3::ONE;
                        let mut d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())
                            - Vec3::splat(0.5);
                        if i % 5 == 0 {
                            d = [Vec3::Z, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Z][i % 4];
                        }
                        let t_max = if i % 3 == 0 { 2.0 } else { f32::INFINITY };
                        let ray = Ray::with_range(o, d, 0.0, t_max);
                        let s = &mut RayStats::default();
                        let (a, b) = (mesh.intersect(&ray, s), list.intersect(&ray, s));
                        match (a, b) {
                            (Some(a), Some(b)) => {
                                hits += 1;
                                assert_eq!(a.t.to_bits(), b.t.to_bits(), "{kind:?} ray {i}");
                                if a.prim == b.prim {
                                    assert_eq!(a.uv, b.uv, "{kind:?} ray {i}");
                                }
                            }
                            (a, b) => assert_eq!(a.is_some(), b.is_some(), "{kind:?} ray {i}"),
                        }
                        assert_eq!(mesh.occluded(&ray, s), b.is_some(), "{kind:?} ray {i}");
                    }
                    assert!(hits > 200, "{kind:?}: only {hits} hits");
                }
            }
        }
    }

    /// Two unit quads facing +z, a cut-out one at z = 0 and an opaque one at z = −1; the
    /// cut-out quad's coverage is a 2×2 nearest-filtered checker: its lower-left and
    /// upper-right quarters are there (coverage 0.75 and 1), the others not (0.25, 0).
    fn cutout_pair(kind: AccelKind) -> (TriangleMesh, TriangleMesh) {
        use crate::film::Image;
        use crate::texture::{BorderMode, FilterMode, ImageTexture, Texture};
        let quad = |z: f32| MeshData {
            positions: vec![
                Vec3::new(0.0, 0.0, z),
                Vec3::new(1.0, 0.0, z),
                Vec3::new(1.0, 1.0, z),
                Vec3::new(0.0, 1.0, z),
            ],
            normals: Vec::new(),
            uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        // Row 0 is the top of the image (v = 1).
        let coverage = Image {
            width: 2,
            height: 2,
            pixels: [0.0, 1.0, 0.75, 0.25].map(Vec3::splat).to_vec(),
        };
        let mut cut = TriangleMesh::new(quad(0.0), false, kind).unwrap();
        cut.set_alpha(AlphaMask {
            coverage: std::sync::Arc::new(Texture::Image(ImageTexture {
                image: std::sync::Arc::new(coverage),
                border: BorderMode::Clamp,
                filter: FilterMode::Nearest,
                exposure: 1.0,
            })),
            test: AlphaTest::Cutoff(0.5),
        });
        let back = TriangleMesh::new(quad(-1.0), false, kind).unwrap();
        (cut, back)
    }

    /// Rays through the holes of a cut-out quad pass (closest hit, shadow rays, streams
    /// and packets alike), rays elsewhere stop at it, for every accelerator.
    #[test]
    fn alpha_mask_lets_rays_through_its_holes() {
        for kind in [
            AccelKind::List,
            AccelKind::Bvh2,
            AccelKind::Bvh4,
            AccelKind::Bvh8,
            AccelKind::Grid,
            AccelKind::KdTree,
        ] {
            let (cut, back) = cutout_pair(kind);
            assert!(
                !cut.traces_packets(),
                "{kind:?}: a cut-out mesh traces ray by ray"
            );
            let mut rays = Vec::new();
            let mut expect = Vec::new();
            let mut rng = Pcg32::new(7, 3);
            for _ in 0..400 {
                let (x, y) = (rng.next_f32(), rng.next_f32());
                // Stay off the quarter borders, where the nearest texel is a coin toss.
                if (x - 0.5).abs() < 0.01 || (y - 0.5).abs() < 0.01 {
                    continue;
                }
                let there = (x < 0.5) == (y < 0.5);
                let origin = Vec3::new(x, y, 1.0);
                let d = Vec3::new(0.0, 0.0, -1.0);
                rays.push(Ray::new(origin, d));
                expect.push(there);
            }
            let mut stats = RayStats::default();
            for (ray, &there) in rays.iter().zip(&expect) {
                let hit = cut.intersect(ray, &mut stats);
                assert_eq!(
                    hit.is_some(),
                    there,
                    "{kind:?}: closest hit at {:?}",
                    ray.origin
                );
                if let Some(h) = hit {
                    assert!((h.t - 1.0).abs() < 1e-6);
                    // The interaction's texture coordinates are those the mask looked up.
                    let si = cut.interaction(ray, &h);
                    assert!((si.uv - ray.origin.truncate()).length() < 1e-5);
                }
                // A segment to the back quad is blocked only where the front one is there.
                let mut shadow = *ray;
                shadow.t_max = 1.5;
                assert_eq!(
                    cut.occluded(&shadow, &mut stats),
                    there,
                    "{kind:?}: shadow ray"
                );
                // Behind a hole, the back quad is what the ray reaches.
                let behind = back.intersect(ray, &mut stats).unwrap();
                assert!((behind.t - 2.0).abs() < 1e-6);
            }
            let mut hits = vec![None; rays.len()];
            cut.intersect_stream(&rays, &mut hits, &mut stats);
            let mut packet_hits = vec![None; rays.len()];
            cut.intersect_packets(&rays, &mut packet_hits, &mut stats);
            let mut occluded = vec![false; rays.len()];
            cut.occluded_stream(&rays, &mut occluded, &mut stats);
            let mut packet_occluded = vec![false; rays.len()];
            cut.occluded_packets(&rays, &mut packet_occluded, &mut stats);
            for i in 0..rays.len() {
                assert_eq!(hits[i].is_some(), expect[i], "{kind:?}: stream ray {i}");
                assert_eq!(
                    packet_hits[i].is_some(),
                    expect[i],
                    "{kind:?}: packet ray {i}"
                );
                assert_eq!(occluded[i], expect[i], "{kind:?}: stream shadow ray {i}");
                assert_eq!(
                    packet_occluded[i], expect[i],
                    "{kind:?}: packet shadow ray {i}"
                );
            }
        }
    }

    /// Stochastic transparency: over many rays, a quad of constant coverage 0.3 is met
    /// by 30% of them (within four standard deviations), closest-hit and shadow rays
    /// alike, and each ray gets the same answer from every query.
    #[test]
    fn stochastic_alpha_lets_the_uncovered_fraction_through() {
        use crate::texture::Texture;
        let data = MeshData {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            normals: Vec::new(),
            uvs: Vec::new(),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            colors: Vec::new(),
            face_colors: Vec::new(),
        };
        for kind in [AccelKind::Bvh8, AccelKind::Bvh2] {
            let mut mesh = TriangleMesh::new(data.clone(), false, kind).unwrap();
            mesh.set_alpha(AlphaMask {
                coverage: std::sync::Arc::new(Texture::Constant(Vec3::splat(0.3))),
                test: AlphaTest::Stochastic,
            });
            let mut rng = Pcg32::new(11, 5);
            let n = 20_000;
            let rays: Vec<Ray> = (0..n)
                .map(|_| {
                    let target = Vec3::new(rng.next_f32(), rng.next_f32(), 0.0);
                    let origin = Vec3::new(rng.next_f32(), rng.next_f32(), 1.0);
                    Ray::new(origin, target - origin)
                })
                .collect();
            let mut stats = RayStats::default();
            let hits: Vec<bool> = rays
                .iter()
                .map(|r| mesh.intersect(r, &mut stats).is_some())
                .collect();
            let fraction = hits.iter().filter(|&&h| h).count() as f64 / n as f64;
            let sigma = (0.3f64 * 0.7 / n as f64).sqrt();
            assert!((fraction - 0.3).abs() < 4.0 * sigma, "{kind:?}: {fraction}");
            let mut stream = vec![None; n];
            mesh.intersect_stream(&rays, &mut stream, &mut stats);
            for (i, ray) in rays.iter().enumerate() {
                assert_eq!(mesh.occluded(ray, &mut stats), hits[i], "{kind:?}: ray {i}");
                assert_eq!(stream[i].is_some(), hits[i], "{kind:?}: ray {i}");
            }
        }
    }
}
