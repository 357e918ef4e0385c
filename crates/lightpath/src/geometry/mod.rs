//! Geometry: the shapes a scene is built from, each intersected in its own object space,
//! and the surface interactions they produce.

mod csg;
mod cubic_curves;
mod cuboid;
mod curves;
mod cylinder;
mod disk;
mod interaction;
mod mesh;
mod mesh_data;
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
mod packet;
mod plane;
mod rectangle;
mod shape;
mod sphere;
mod triangle_block;

pub use csg::{Csg, CsgNode, CsgOp, Solid};
pub use cubic_curves::{CubicBasis, CubicCurves};
pub use cuboid::Cuboid;
pub use curves::LinearCurves;
pub use cylinder::Cylinder;
pub use disk::Disk;
pub use interaction::{SurfaceInteraction, SHADOW_EPSILON};
pub use mesh::{
    intersect_triangle_watertight, AlphaMask, AlphaTest, MeshHits, TriangleMesh, WatertightRay,
};
pub use mesh_data::MeshData;
pub use plane::Plane;
pub use rectangle::Rectangle;
pub use shape::{Shape, ShapeHit};
pub use sphere::Sphere;
pub use triangle_block::TriangleBlock;
