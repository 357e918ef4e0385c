//! What a loaded scene holds, counted for `lightpath info` and `render --verbose`.

use lightpath::geometry::Shape;
use lightpath::io::LoadedScene;
use lightpath::math::Bounds3;
use std::collections::{BTreeMap, HashSet};
use std::fmt::{self, Write};
use std::sync::Arc;

/// Counts of a scene's contents.
#[derive(Debug, Clone)]
pub struct SceneSummary {
    /// Instances per shape kind.
    pub shapes: BTreeMap<String, usize>,
    /// Distinct triangle meshes and their triangles.
    pub meshes: usize,
    pub triangles: u64,
    /// Triangles counting every instance of a mesh.
    pub instanced_triangles: u64,
    /// Lights per kind (area lights: one per emitting instance).
    pub lights: BTreeMap<String, usize>,
    /// Instances that emit light.
    pub emitters: usize,
    /// Distinct materials per kind.
    pub materials: BTreeMap<String, usize>,
    /// Instances without a material (they absorb all light).
    pub without_material: usize,
    pub accel_bytes: usize,
    pub bounds: Bounds3,
    /// Camera kind and image size.
    pub camera: Option<(String, u32, u32)>,
    pub integrator: String,
    pub sampler: String,
    pub spp: u32,
}

impl SceneSummary {
    pub fn of(loaded: &LoadedScene) -> SceneSummary {
        let scene = &loaded.scene;
        let mut shapes = BTreeMap::new();
        let mut meshes = HashSet::new();
        let (mut triangles, mut instanced_triangles) = (0u64, 0u64);
        let mut materials_seen = HashSet::new();
        let mut materials = BTreeMap::new();
        let mut without_material = 0;
        for inst in &scene.instances {
            *shapes
                .entry(inst.shape.kind_name().to_string())
                .or_insert(0) += 1;
            if let Shape::TriangleMesh(m) = &*inst.shape {
                let n = m.triangle_count() as u64;
                instanced_triangles += n;
                if meshes.insert(Arc::as_ptr(m)) {
                    triangles += n;
                }
            }
            match &inst.material {
                Some(m) => {
                    if materials_seen.insert(Arc::as_ptr(m)) {
                        *materials.entry(variant_name(&**m)).or_insert(0) += 1;
                    }
                }
                None => without_material += 1,
            }
        }
        let mut lights = BTreeMap::new();
        for l in &scene.lights {
            *lights.entry(variant_name(l)).or_insert(0) += 1;
        }
        SceneSummary {
            shapes,
            meshes: meshes.len(),
            triangles,
            instanced_triangles,
            lights,
            emitters: scene
                .instances
                .iter()
                .filter(|i| i.emission.is_some())
                .count(),
            materials,
            without_material,
            accel_bytes: scene.accel_memory_bytes(),
            bounds: scene.bounds(),
            camera: scene.camera.as_ref().map(|c| {
                let r = c.resolution();
                let kind = match c {
                    lightpath::camera::Camera::Realistic(lens) => {
                        format!("realistic ({})", lens.describe())
                    }
                    _ => variant_name(c),
                };
                (kind, r.x, r.y)
            }),
            integrator: variant_name(&loaded.integrator),
            sampler: variant_name(&loaded.sampler),
            spp: loaded.sampler.samples_per_pixel(),
        }
    }

    /// Whether nothing in the scene gives off light.
    pub fn is_dark(&self) -> bool {
        self.lights.is_empty() && self.emitters == 0
    }

    pub fn material_count(&self) -> usize {
        self.materials.values().sum()
    }
}

/// `3 (sphere 1, mesh 2)`.
pub fn by_kind(counts: &BTreeMap<String, usize>) -> String {
    let total: usize = counts.values().sum();
    if counts.is_empty() {
        return total.to_string();
    }
    let parts: Vec<String> = counts.iter().map(|(k, n)| format!("{k} {n}")).collect();
    format!("{total} ({})", parts.join(", "))
}

/// `1.50 MiB`.
pub fn bytes(n: usize) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut v = n as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} B")
    } else {
        format!("{v:.2} {}", UNITS[unit])
    }
}

/// The name of an enum value's variant, from its `Debug` output (`PathTracer(..)` →
/// `path-tracer`), without formatting the payload: the writer stops the formatter at
/// the first character after the name. Works for every variant, present and future.
pub fn variant_name(value: &dyn fmt::Debug) -> String {
    struct Name(String);
    impl Write for Name {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            for c in s.chars() {
                if !c.is_alphanumeric() && c != '_' {
                    return Err(fmt::Error);
                }
                self.0.push(c);
            }
            Ok(())
        }
    }
    let mut name = Name(String::new());
    let _ = write!(name, "{value:?}");
    let mut out = String::new();
    for (i, c) in name.0.chars().enumerate() {
        if c.is_uppercase() && i > 0 {
            out.push('-');
        }
        out.extend(c.to_lowercase());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    #[allow(dead_code)]
    enum Demo {
        PathTracer(Vec<u8>),
        Point { x: f32 },
        Unit,
    }

    #[test]
    fn variant_names() {
        assert_eq!(variant_name(&Demo::PathTracer(vec![1; 3])), "path-tracer");
        assert_eq!(variant_name(&Demo::Point { x: 1.0 }), "point");
        assert_eq!(variant_name(&Demo::Unit), "unit");
    }

    #[test]
    fn formats() {
        assert_eq!(bytes(512), "512 B");
        assert_eq!(bytes(3 * 1024 * 1024 / 2), "1.50 MiB");
        let mut m = BTreeMap::new();
        m.insert("sphere".to_string(), 2);
        m.insert("mesh".to_string(), 1);
        assert_eq!(by_kind(&m), "3 (mesh 1, sphere 2)");
        assert_eq!(by_kind(&BTreeMap::new()), "0");
    }
}
