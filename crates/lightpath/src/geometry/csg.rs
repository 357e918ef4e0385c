//! Constructive solid geometry: closed solids combined by union, difference and
//! intersection, in trees of any depth.
//!
//! ```xml
//! <instance>
//!     <shape type="csg" op="difference">           <!-- union, difference, intersection -->
//!         <shape type="sphere"/>                   <!-- the first operand -->
//!         <shape type="cube">                      <!-- minus this one -->
//!             <transform><scale value="0.6"/><translate x="0.6" y="-0.6" z="-0.6"/></transform>
//!             <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.8,0.1,0.1"/></bsdf>
//!         </shape>
//!     </shape>
//!     <bsdf type="diffuse"/>                       <!-- for operands without their own -->
//!     <transform><translate z="4"/></transform>
//! </instance>
//! ```
//!
//! Operands (leaves) are closed solids: `sphere`, `cube`, `cylinder` (always with its
//! caps) and `mesh`, a closed triangle mesh whose winding makes its normals point
//! outwards. An operand may be a nested `<shape type="csg">`, so trees have any depth.
//! A node with more than two operands folds them from the left: `a − b − c`,
//! `a ∪ b ∪ c`. Every node and leaf may have a `<transform>` (node-to-parent, in
//! document order, like an instance's) and a `<bsdf>`; a leaf without a `<bsdf>` takes
//! its nearest enclosing node's, else the instance's.
//!
//! **Intersection.** Each leaf reports the intervals of the ray that lie inside it
//! (sphere: its two roots; cube: the slab interval; cylinder: the side's roots clipped by
//! the caps' slab; mesh: every triangle crossing found through the mesh's BVH, paired
//! into intervals by whether the ray enters or leaves). An inner node combines its
//! children's sorted interval lists by a merge sweep with its boolean operator, dropping
//! empty intervals and closing empty gaps (so touching solids have no inner faces). The
//! hit is the first interval end point after `t_min` that is not rounding error of the
//! ray origin. Because whole intervals are kept, a ray may start inside any solid:
//! shadow rays and rays refracted into CSG glass work.
//!
//! In the Mitsuba 3 dialect (an extension of that format, which has no CSG):
//!
//! ```xml
//! <shape type="csg">
//!     <string name="op" value="difference"/>
//!     <shape type="sphere"><float name="radius" value="1"/></shape>
//!     <shape type="cube">
//!         <bsdf type="diffuse"><rgb name="reflectance" value="0.8,0.1,0.1"/></bsdf>
//!         <transform name="to_world"><scale value="0.7"/><translate z="-0.8"/></transform>
//!     </shape>
//! </shape>
//! ```
//!
//! **Surfaces.** A hit keeps its leaf's normal, uv and material; the faces a difference
//! cuts out of its left operand are the right operand's surface with the normal flipped
//! (it points into the hole, out of the solid). `ShapeHit::prim` encodes the flip, the
//! leaf and the leaf's own primitive (box face, cylinder part, triangle).
//!
//! Bounds are as tight as the operator allows: a union's is the union of its operands'
//! boxes, an intersection's their overlap, a difference's its left operand's. The area
//! of a CSG surface is not known, so it cannot be an area light.

use super::{intersect_triangle_watertight, ShapeHit, SurfaceInteraction, WatertightRay};
use super::{Cuboid, Cylinder, Sphere, TriangleMesh};
use crate::accel::RayStats;
use crate::material::Material;
use crate::math::{gamma, Bounds3, Ray, Transform};
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::Arc;

/// A boolean operator of an inner node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CsgOp {
    Union,
    /// The left operand minus the right one.
    Difference,
    Intersection,
}

impl CsgOp {
    pub const NAMES: &'static [&'static str] = &["union", "difference", "intersection"];

    pub fn from_name(name: &str) -> Option<CsgOp> {
        match name {
            "union" => Some(CsgOp::Union),
            "difference" => Some(CsgOp::Difference),
            "intersection" => Some(CsgOp::Intersection),
            _ => None,
        }
    }

    /// Whether a point is in the result, given whether it is in each operand.
    #[inline]
    pub fn apply(self, in_left: bool, in_right: bool) -> bool {
        match self {
            CsgOp::Union => in_left || in_right,
            CsgOp::Difference => in_left && !in_right,
            CsgOp::Intersection => in_left && in_right,
        }
    }
}

/// A closed solid at a leaf, in its own space (the canonical shapes of the same name).
#[derive(Debug, Clone)]
pub enum Solid {
    /// The unit ball.
    Sphere,
    /// The box [-1, 1]³.
    Cube,
    /// Radius 1 around the z axis, z in [0, 1], closed by both caps.
    Cylinder,
    /// A closed, outward-wound triangle mesh.
    Mesh(Arc<TriangleMesh>),
}

impl Solid {
    pub fn name(&self) -> &'static str {
        match self {
            Solid::Sphere => "sphere",
            Solid::Cube => "cube",
            Solid::Cylinder => "cylinder",
            Solid::Mesh(_) => "mesh",
        }
    }

    fn bounds(&self) -> Bounds3 {
        match self {
            Solid::Sphere => Sphere.bounds(),
            Solid::Cube => Cuboid.bounds(),
            Solid::Cylinder => Cylinder { caps: true }.bounds(),
            Solid::Mesh(m) => m.bounds(),
        }
    }
}

/// A CSG tree as it is built (by a scene file or by hand); [`Csg::new`] flattens it.
#[derive(Debug, Clone)]
pub enum CsgNode {
    Leaf {
        solid: Solid,
        /// The node's space to its parent's (the CSG's object space for the root).
        parent_from_node: Transform,
        /// The leaf's own material; `None` uses the instance's.
        material: Option<Arc<Material>>,
    },
    Op {
        op: CsgOp,
        left: Box<CsgNode>,
        right: Box<CsgNode>,
        parent_from_node: Transform,
    },
}

impl CsgNode {
    pub fn leaf(solid: Solid) -> CsgNode {
        CsgNode::Leaf {
            solid,
            parent_from_node: Transform::IDENTITY,
            material: None,
        }
    }

    pub fn op(op: CsgOp, left: CsgNode, right: CsgNode) -> CsgNode {
        CsgNode::Op {
            op,
            left: Box::new(left),
            right: Box::new(right),
            parent_from_node: Transform::IDENTITY,
        }
    }

    /// Moves the node by `t`, after any transform it already has.
    pub fn transformed(mut self, t: &Transform) -> CsgNode {
        match &mut self {
            CsgNode::Leaf {
                parent_from_node, ..
            }
            | CsgNode::Op {
                parent_from_node, ..
            } => *parent_from_node = parent_from_node.then(t),
        }
        self
    }

    /// Gives a leaf its material (no effect on inner nodes).
    pub fn with_material(mut self, m: Option<Arc<Material>>) -> CsgNode {
        if let CsgNode::Leaf { material, .. } = &mut self {
            *material = m;
        }
        self
    }
}

/// A leaf, placed in the CSG's object space.
#[derive(Debug, Clone)]
struct Leaf {
    solid: Solid,
    object_from_leaf: Transform,
    material: Option<Arc<Material>>,
}

#[derive(Debug, Clone, Copy)]
enum FlatKind {
    Leaf(u32),
    Op(CsgOp, u32, u32),
}

/// A node of the flattened tree with its object-space bounds.
#[derive(Debug, Clone, Copy)]
struct FlatNode {
    kind: FlatKind,
    bounds: Bounds3,
}

/// A CSG shape: a flattened tree whose leaves carry their accumulated transforms.
#[derive(Debug, Clone)]
pub struct Csg {
    /// The root is `nodes[0]`.
    nodes: Vec<FlatNode>,
    leaves: Vec<Leaf>,
    /// Bits of `prim` that hold a leaf's own primitive; the leaf index sits above them
    /// and the flip flag in bit 31.
    prim_bits: u32,
}

/// Set in a hit's `prim` when the surface's normal is flipped (a difference's cut face).
const FLIP: u32 = 1 << 31;
/// The tag of an interval end that is no surface (a mesh interval open before `t_min`).
const NO_SURFACE: u32 = u32::MAX;

/// Where the ray crosses a leaf's surface.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    t: f32,
    /// Crossings at `t <= err` are rounding error of the ray origin: never a hit.
    err: f32,
    /// Encoded flip, leaf and leaf primitive (the hit's `prim`).
    tag: u32,
    /// The leaf's hit coordinates (barycentrics for meshes).
    uv: Vec2,
}

impl Crossing {
    const BEFORE: Crossing = Crossing {
        t: f32::NEG_INFINITY,
        err: 0.0,
        tag: NO_SURFACE,
        uv: Vec2::ZERO,
    };
    const AFTER: Crossing = Crossing {
        t: f32::INFINITY,
        err: 0.0,
        tag: NO_SURFACE,
        uv: Vec2::ZERO,
    };

    #[inline]
    fn flipped(self) -> Crossing {
        Crossing {
            tag: self.tag ^ FLIP,
            ..self
        }
    }
}

/// A stretch of the ray inside a solid.
#[derive(Debug, Clone, Copy)]
struct Span {
    enter: Crossing,
    exit: Crossing,
}

/// One triangle crossing of a mesh leaf.
#[derive(Debug, Clone, Copy)]
struct MeshCrossing {
    t: f32,
    entering: bool,
    prim: u32,
    uv: Vec2,
}

/// Reused buffers: the span lists of a tree walk live on one stack (`spans`), each node
/// leaving its result at the end.
#[derive(Debug, Default)]
struct Scratch {
    spans: Vec<Span>,
    merged: Vec<Span>,
    crossings: Vec<MeshCrossing>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

fn with_scratch<R>(f: impl FnOnce(&mut Scratch) -> R) -> R {
    SCRATCH.with(|cell| match cell.try_borrow_mut() {
        Ok(mut s) => f(&mut s),
        // Re-entered (never in practice): fresh buffers.
        Err(_) => f(&mut Scratch::default()),
    })
}

/// Checks that a mesh bounds a solid: closed (every edge, with vertices welded by
/// position, has as many triangles on one side as on the other, in opposite directions)
/// and wound outwards (positive signed volume).
fn check_closed_mesh(m: &TriangleMesh) -> Result<(), String> {
    if m.indices.is_empty() {
        return Err("a CSG mesh needs triangles".into());
    }
    let mut welded: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = m
        .positions
        .iter()
        .map(|p| {
            let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            let next = welded.len() as u32;
            *welded.entry(key).or_insert(next)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    let mut volume = 0.0f64;
    for tri in &m.indices {
        let v = tri.map(|i| ids[i as usize]);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            if a != b {
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        let [p0, p1, p2] = tri.map(|i| m.positions[i as usize].as_dvec3());
        volume += p0.dot(p1.cross(p2)) / 6.0;
    }
    if let Some((&(a, b), _)) = edges.iter().find(|(_, &n)| n != 0) {
        let pos = |id: u32| {
            let i = ids.iter().position(|&x| x == id).unwrap_or(0);
            m.positions[i]
        };
        return Err(format!(
            "a CSG mesh must be closed and consistently wound; the edge {} – {} is not matched \
             by an edge in the opposite direction",
            pos(a),
            pos(b)
        ));
    }
    if volume.is_nan() || volume <= 0.0 {
        return Err(format!(
            "a CSG mesh must be wound with its normals pointing outwards (its signed volume is {volume:.3e}); \
             reverse its triangles"
        ));
    }
    Ok(())
}

impl Csg {
    /// Flattens a tree. Fails for a mesh leaf that is not a closed, outward-wound
    /// surface, or when leaf and triangle indices do not fit a hit's `prim` together.
    pub fn new(root: CsgNode) -> Result<Csg, String> {
        let mut csg = Csg {
            nodes: Vec::new(),
            leaves: Vec::new(),
            prim_bits: 0,
        };
        csg.flatten(&root, &Transform::IDENTITY);
        let leaf_bits = (usize::BITS - (csg.leaves.len().max(2) - 1).leading_zeros()).max(1);
        if leaf_bits > 16 {
            return Err(format!(
                "a CSG tree has {} leaves; at most 65536 are supported",
                csg.leaves.len()
            ));
        }
        csg.prim_bits = 31 - leaf_bits;
        let mut checked: Vec<*const TriangleMesh> = Vec::new();
        for leaf in &csg.leaves {
            if let Solid::Mesh(m) = &leaf.solid {
                if (m.triangle_count() as u64) >= 1u64 << csg.prim_bits {
                    return Err(format!(
                        "a CSG mesh with {} triangles is too large for a tree of {} leaves",
                        m.triangle_count(),
                        csg.leaves.len()
                    ));
                }
                if !checked.contains(&Arc::as_ptr(m)) {
                    check_closed_mesh(m)?;
                    checked.push(Arc::as_ptr(m));
                }
            }
        }
        Ok(csg)
    }

    /// Appends `node` (and its subtree) to the flat arrays; returns its index.
    fn flatten(&mut self, node: &CsgNode, object_from_parent: &Transform) -> u32 {
        let index = self.nodes.len() as u32;
        match node {
            CsgNode::Leaf {
                solid,
                parent_from_node,
                material,
            } => {
                let object_from_leaf = object_from_parent.compose(parent_from_node);
                let mut bounds = object_from_leaf.bounds(&solid.bounds());
                // Room for rounding, so culling never drops a grazing ray.
                let pad = (bounds.max.abs().max(bounds.min.abs())) * 1e-5 + Vec3::splat(1e-12);
                bounds = Bounds3::new(bounds.min - pad, bounds.max + pad);
                self.nodes.push(FlatNode {
                    kind: FlatKind::Leaf(self.leaves.len() as u32),
                    bounds,
                });
                self.leaves.push(Leaf {
                    solid: solid.clone(),
                    object_from_leaf,
                    material: material.clone(),
                });
            }
            CsgNode::Op {
                op,
                left,
                right,
                parent_from_node,
            } => {
                let object_from_node = object_from_parent.compose(parent_from_node);
                self.nodes.push(FlatNode {
                    kind: FlatKind::Leaf(0),
                    bounds: Bounds3::EMPTY,
                });
                let l = self.flatten(left, &object_from_node);
                let r = self.flatten(right, &object_from_node);
                let (bl, br) = (self.nodes[l as usize].bounds, self.nodes[r as usize].bounds);
                let bounds = match op {
                    CsgOp::Union => bl.union(&br),
                    CsgOp::Intersection => {
                        let b = bl.intersection(&br);
                        if b.is_empty() {
                            Bounds3::EMPTY
                        } else {
                            b
                        }
                    }
                    CsgOp::Difference => bl,
                };
                self.nodes[index as usize] = FlatNode {
                    kind: FlatKind::Op(*op, l, r),
                    bounds,
                };
            }
        }
        index
    }

    /// Object-space bounds; a point at the origin when the solid is empty.
    pub fn bounds(&self) -> Bounds3 {
        let b = self.nodes[0].bounds;
        if b.is_empty() {
            Bounds3::from_point(Vec3::ZERO)
        } else {
            b
        }
    }

    pub fn leaf_count(&self) -> usize {
        self.leaves.len()
    }

    /// The leaf a hit's `prim` belongs to.
    #[inline]
    pub fn leaf_index(&self, prim: u32) -> usize {
        ((prim & !FLIP) >> self.prim_bits) as usize
    }

    /// The material of the leaf a hit's `prim` belongs to, if the leaf has its own.
    #[inline]
    pub fn leaf_material(&self, prim: u32) -> Option<&Material> {
        self.leaves
            .get(self.leaf_index(prim))
            .and_then(|l| l.material.as_deref())
    }

    /// Whether a hit's surface is a flipped operand surface (a difference's cut face).
    #[inline]
    pub fn is_flipped(prim: u32) -> bool {
        prim & FLIP != 0
    }

    #[inline]
    fn tag(&self, leaf: u32, prim: u32) -> u32 {
        (leaf << self.prim_bits) | prim
    }

    /// Closest hit within `(t_min, t_max)`.
    pub fn intersect(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        if ray.direction == Vec3::ZERO || !ray.direction.is_finite() {
            return None;
        }
        with_scratch(|s| {
            s.spans.clear();
            let inv_dir = ray.direction.recip();
            self.node_spans(0, ray, inv_dir, s, stats);
            for span in &s.spans {
                for c in [span.enter, span.exit] {
                    if c.t >= ray.t_max {
                        return None;
                    }
                    if c.t > ray.t_min && c.t > c.err {
                        return Some(ShapeHit {
                            t: c.t,
                            prim: c.tag,
                            uv: c.uv,
                        });
                    }
                }
            }
            None
        })
    }

    /// The full interaction of a hit, in object space.
    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let leaf = &self.leaves[self.leaf_index(hit.prim)];
        let leaf_ray = leaf_ray(&leaf.object_from_leaf, ray);
        let leaf_hit = ShapeHit {
            t: hit.t,
            prim: hit.prim & ((1 << self.prim_bits) - 1),
            uv: hit.uv,
        };
        let si = match &leaf.solid {
            Solid::Sphere => Sphere.interaction(&leaf_ray, &leaf_hit),
            Solid::Cube => Cuboid.interaction(&leaf_ray, &leaf_hit),
            Solid::Cylinder => Cylinder { caps: true }.interaction(&leaf_ray, &leaf_hit),
            Solid::Mesh(m) => m.interaction(&leaf_ray, &leaf_hit),
        };
        let mut si = si.transformed(&leaf.object_from_leaf);
        if Self::is_flipped(hit.prim) {
            si.n = -si.n;
            si.shading_n = -si.shading_n;
        }
        si.wo = -ray.direction.normalize();
        si.prim = hit.prim;
        si
    }

    /// Whether an object-space point is inside the solid (points on the surface may go
    /// either way).
    pub fn contains(&self, p: Vec3) -> bool {
        self.node_contains(0, p)
    }

    fn node_contains(&self, n: u32, p: Vec3) -> bool {
        let node = &self.nodes[n as usize];
        if !node.bounds.contains(p) {
            return false;
        }
        match node.kind {
            FlatKind::Leaf(l) => {
                let leaf = &self.leaves[l as usize];
                let q = leaf.object_from_leaf.inverse().point(p);
                match &leaf.solid {
                    Solid::Sphere => q.length_squared() <= 1.0,
                    Solid::Cube => q.abs().max_element() <= 1.0,
                    Solid::Cylinder => q.x * q.x + q.y * q.y <= 1.0 && (0.0..=1.0).contains(&q.z),
                    Solid::Mesh(m) => {
                        // Inside when the first crossing of a ray from q leaves the mesh.
                        let ray = Ray::new(q, Vec3::new(0.5773, 0.6172, 0.5347));
                        with_scratch(|s| {
                            let start = s.spans.len();
                            mesh_spans(
                                m,
                                &ray,
                                0,
                                &mut s.spans,
                                &mut s.crossings,
                                &mut RayStats::default(),
                            );
                            let inside = s.spans.len() > start
                                && s.spans[start].enter.t == f32::NEG_INFINITY;
                            s.spans.truncate(start);
                            inside
                        })
                    }
                }
            }
            FlatKind::Op(op, a, b) => {
                let in_a = self.node_contains(a, p);
                // Short-circuit where the right operand cannot change the answer.
                match (op, in_a) {
                    (CsgOp::Union, true) => true,
                    (CsgOp::Difference | CsgOp::Intersection, false) => false,
                    _ => op.apply(in_a, self.node_contains(b, p)),
                }
            }
        }
    }

    /// Appends the spans of node `n` along the object-space ray to `s.spans`, sorted and
    /// disjoint. Exact on `[t_min, t_max]`; outside that range they may differ from the
    /// true solid (culled subtrees, mesh spans that start at `t_min`).
    fn node_spans(&self, n: u32, ray: &Ray, inv_dir: Vec3, s: &mut Scratch, stats: &mut RayStats) {
        let node = &self.nodes[n as usize];
        if node
            .bounds
            .intersect_p(ray.origin, inv_dir, ray.t_min, ray.t_max)
            .is_none()
        {
            return;
        }
        match node.kind {
            FlatKind::Leaf(l) => self.leaf_spans(l, ray, s, stats),
            FlatKind::Op(op, a, b) => {
                let start = s.spans.len();
                self.node_spans(a, ray, inv_dir, s, stats);
                let mid = s.spans.len();
                if mid == start && op != CsgOp::Union {
                    return; // nothing to subtract from or intersect with
                }
                self.node_spans(b, ray, inv_dir, s, stats);
                let end = s.spans.len();
                if end == mid {
                    if op == CsgOp::Intersection {
                        s.spans.truncate(start);
                    }
                    return; // the left spans stand
                }
                if mid == start {
                    return; // a union with nothing on the left: the right spans stand
                }
                let Scratch { spans, merged, .. } = s;
                merged.clear();
                combine(op, &spans[start..mid], &spans[mid..end], merged);
                spans.truncate(start);
                spans.extend_from_slice(merged);
            }
        }
    }

    fn leaf_spans(&self, l: u32, ray: &Ray, s: &mut Scratch, stats: &mut RayStats) {
        let leaf = &self.leaves[l as usize];
        let r = leaf_ray(&leaf.object_from_leaf, ray);
        let crossing = |t: f32, err: f32, prim: u32| Crossing {
            t,
            err,
            tag: self.tag(l, prim),
            uv: Vec2::ZERO,
        };
        let span = match &leaf.solid {
            Solid::Sphere => Sphere::roots(&r).map(|(t0, t1, err)| Span {
                enter: crossing(t0, err, 0),
                exit: crossing(t1, err, 0),
            }),
            Solid::Cube => {
                let err = gamma(6) * (r.origin.abs().max_element() + 1.0) / r.direction.length();
                cube_interval(&r).map(|(t0, f0, t1, f1)| Span {
                    enter: crossing(t0, err, f0),
                    exit: crossing(t1, err, f1),
                })
            }
            Solid::Cylinder => {
                let err = gamma(12) * (r.origin.length() + 1.0) / r.direction.length();
                cylinder_interval(&r).map(|(t0, p0, t1, p1)| Span {
                    enter: crossing(t0, err, p0),
                    exit: crossing(t1, err, p1),
                })
            }
            Solid::Mesh(m) => {
                mesh_spans(m, &r, self.tag(l, 0), &mut s.spans, &mut s.crossings, stats);
                None
            }
        };
        if let Some(span) = span {
            if span.enter.t < span.exit.t {
                s.spans.push(span);
            }
        }
    }
}

/// The object-space ray in a leaf's space; `t` keeps its meaning.
#[inline]
fn leaf_ray(object_from_leaf: &Transform, ray: &Ray) -> Ray {
    let leaf_from_object = object_from_leaf.inverse();
    Ray {
        origin: leaf_from_object.point(ray.origin),
        direction: leaf_from_object.vector(ray.direction),
        ..*ray
    }
}

/// The ray's interval inside [-1, 1]³ with the faces it enters and leaves by (encoded as
/// `Cuboid` encodes them: axis * 2 + positive side).
#[inline]
fn cube_interval(r: &Ray) -> Option<(f32, u32, f32, u32)> {
    let (mut enter, mut enter_face) = (f32::NEG_INFINITY, 0);
    let (mut exit, mut exit_face) = (f32::INFINITY, 0);
    for axis in 0..3 {
        let (o, d) = (r.origin[axis], r.direction[axis]);
        if d == 0.0 {
            if o.abs() > 1.0 {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d;
        let (t_lo, t_hi) = ((-1.0 - o) * inv, (1.0 - o) * inv);
        let a = axis as u32 * 2;
        let (tn, fn_, tf, ff) = if d > 0.0 {
            (t_lo, a, t_hi, a + 1)
        } else {
            (t_hi, a + 1, t_lo, a)
        };
        if tn > enter {
            enter = tn;
            enter_face = fn_;
        }
        if tf < exit {
            exit = tf;
            exit_face = ff;
        }
    }
    (enter < exit).then_some((enter, enter_face, exit, exit_face))
}

/// The ray's interval inside the closed cylinder, with the parts it enters and leaves by
/// (0 side, 1 bottom cap, 2 top cap, as `Cylinder` numbers them).
#[inline]
fn cylinder_interval(r: &Ray) -> Option<(f32, u32, f32, u32)> {
    let (o, d) = (r.origin, r.direction);
    // The infinite tube.
    let (mut enter, mut enter_part, mut exit, mut exit_part) = if d.x == 0.0 && d.y == 0.0 {
        if o.x * o.x + o.y * o.y > 1.0 {
            return None;
        }
        (f32::NEG_INFINITY, 0, f32::INFINITY, 0)
    } else {
        let (t0, t1) = Cylinder::side_roots(r)?;
        (t0.min(t1), 0, t0.max(t1), 0)
    };
    // The slab between the caps.
    if d.z == 0.0 {
        if !(0.0..=1.0).contains(&o.z) {
            return None;
        }
    } else {
        let (t_bottom, t_top) = (-o.z / d.z, (1.0 - o.z) / d.z);
        let (tn, pn, tf, pf) = if d.z > 0.0 {
            (t_bottom, 1, t_top, 2)
        } else {
            (t_top, 2, t_bottom, 1)
        };
        if tn > enter {
            enter = tn;
            enter_part = pn;
        }
        if tf < exit {
            exit = tf;
            exit_part = pf;
        }
    }
    (enter < exit).then_some((enter, enter_part, exit, exit_part))
}

/// Appends the spans of a closed mesh along `r` from `r.t_min` on: every triangle
/// crossing after `t_min`, sorted, paired by whether the ray enters (against the
/// winding normal) or leaves. Crossings at (nearly) the same `t` are merged by their net
/// direction, so a ray through a shared edge counts once and one grazing a silhouette
/// not at all. A first crossing that leaves means the ray starts inside: that span opens
/// at -∞.
fn mesh_spans(
    m: &TriangleMesh,
    r: &Ray,
    tag_base: u32,
    out: &mut Vec<Span>,
    crossings: &mut Vec<MeshCrossing>,
    stats: &mut RayStats,
) {
    crossings.clear();
    let wr = WatertightRay::new(r);
    let search = Ray {
        t_max: f32::INFINITY,
        ..*r
    };
    m.accel.intersect(&search, stats, |prim, _| {
        let (p0, p1, p2) = m.vertices(prim);
        if let Some((t, _, b1, b2)) =
            intersect_triangle_watertight(&wr, r.t_min, f32::INFINITY, p0, p1, p2)
        {
            let facing = r.direction.dot((p1 - p0).cross(p2 - p0));
            if facing != 0.0 {
                crossings.push(MeshCrossing {
                    t,
                    entering: facing < 0.0,
                    prim,
                    uv: Vec2::new(b1, b2),
                });
            }
        }
        false // keep the whole ray: every crossing counts
    });
    crossings.sort_unstable_by(|a, b| a.t.total_cmp(&b.t));
    let mut inside: Option<bool> = None;
    let mut open = Crossing::BEFORE;
    let mut i = 0;
    while i < crossings.len() {
        // A group of crossings at the same distance (to rounding).
        let t0 = crossings[i].t;
        let mut j = i;
        let mut net = 0i32;
        while j < crossings.len() && crossings[j].t - t0 <= 1e-6 * t0.abs().max(1e-3) {
            net += if crossings[j].entering { 1 } else { -1 };
            j += 1;
        }
        if net != 0 {
            let entering = net > 0;
            let first = crossings[i..j]
                .iter()
                .find(|c| c.entering == entering)
                .copied()
                .unwrap_or(crossings[i]);
            let c = Crossing {
                t: first.t,
                // The watertight test only reports hits provably after `t_min`; this
                // bound only serves to merge touching solids.
                err: gamma(8) * first.t.abs(),
                tag: tag_base | first.prim,
                uv: first.uv,
            };
            let now_inside = *inside.get_or_insert(!entering);
            match (now_inside, entering) {
                (false, true) => {
                    open = c;
                    inside = Some(true);
                }
                (true, false) => {
                    out.push(Span {
                        enter: open,
                        exit: c,
                    });
                    inside = Some(false);
                }
                // A crossing against the running state (an inconsistent mesh): skipped.
                _ => {}
            }
        }
        i = j;
    }
    if inside == Some(true) {
        out.push(Span {
            enter: open,
            exit: Crossing::AFTER,
        });
    }
}

/// Merges two sorted, disjoint span lists with a boolean operator. Surfaces from the
/// right operand of a difference are flipped. Spans and gaps no longer than the rounding
/// error of their ends are dropped and closed (touching solids merge without inner
/// faces), so the result is again sorted and disjoint with positive lengths.
fn combine(op: CsgOp, a: &[Span], b: &[Span], out: &mut Vec<Span>) {
    #[inline]
    fn end(s: &[Span], k: usize) -> Crossing {
        if k % 2 == 0 {
            s[k / 2].enter
        } else {
            s[k / 2].exit
        }
    }
    let (na, nb) = (a.len() * 2, b.len() * 2);
    let (mut i, mut j) = (0, 0);
    let mut inside = false;
    let mut open = Crossing::BEFORE;
    while i < na || j < nb {
        let from_a = j >= nb || (i < na && end(a, i).t <= end(b, j).t);
        let c = if from_a {
            i += 1;
            end(a, i - 1)
        } else {
            j += 1;
            let c = end(b, j - 1);
            if op == CsgOp::Difference {
                c.flipped()
            } else {
                c
            }
        };
        // An odd count of ends passed means inside that operand.
        let now = op.apply(i % 2 == 1, j % 2 == 1);
        if now == inside {
            continue;
        }
        inside = now;
        if now {
            match out.last() {
                // A gap within rounding error (touching solids): reopen the previous span.
                Some(last) if c.t - last.exit.t <= last.exit.err + c.err => {
                    open = last.enter;
                    out.pop();
                }
                _ => open = c,
            }
        } else if c.t - open.t > open.err + c.err {
            out.push(Span {
                enter: open,
                exit: c,
            });
        }
    }
}

#[cfg(test)]
mod tests;
