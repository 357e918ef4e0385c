//! Programmatic scene construction.
//!
//! ```
//! use lightpath::prelude::*;
//! let mut builder = SceneBuilder::new();
//! let sphere = builder.add_shape(Shape::Sphere(Sphere));
//! builder.add_instance(sphere, Transform::translate(Vec3::new(0.0, 0.0, 5.0)));
//! let scene = builder.build();
//! let hit = scene.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).unwrap();
//! assert!((hit.t - 4.0).abs() < 1e-5);
//! ```

use super::{Instance, Scene};
use crate::accel::AccelKind;
use crate::camera::Camera;
use crate::geometry::Shape;
use crate::math::Transform;
use std::sync::Arc;

/// Collects shapes, instances and a camera, then builds an immutable [`Scene`].
#[derive(Debug, Default)]
pub struct SceneBuilder {
    shapes: Vec<Arc<Shape>>,
    instances: Vec<Instance>,
    camera: Option<Camera>,
    accel: AccelKind,
}

/// A handle to a shape added to a builder; shapes are shared by all instances using them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShapeId(usize);

impl SceneBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Chooses the top-level accelerator.
    pub fn set_accel(&mut self, accel: AccelKind) -> &mut Self {
        self.accel = accel;
        self
    }

    pub fn add_shape(&mut self, shape: Shape) -> ShapeId {
        self.shapes.push(Arc::new(shape));
        ShapeId(self.shapes.len() - 1)
    }

    /// Places a shape; returns the instance index.
    pub fn add_instance(&mut self, shape: ShapeId, render_from_object: Transform) -> u32 {
        self.instances.push(Instance::new(
            self.shapes[shape.0].clone(),
            render_from_object,
        ));
        self.instances.len() as u32 - 1
    }

    /// Gives instance `instance` a material.
    pub fn set_material(&mut self, instance: u32, material: Arc<crate::material::Material>) {
        self.instances[instance as usize].material = Some(material);
    }

    pub fn set_camera(&mut self, camera: Camera) -> &mut Self {
        self.camera = Some(camera);
        self
    }

    pub fn build(self) -> Scene {
        Scene::new(self.instances, self.camera, self.accel)
    }
}
