//! `render --stats` (a table on stdout) and `render --stats-json FILE` (written
//! atomically).
//!
//! The JSON object's keys:
//!
//! | key                  | meaning                                                      |
//! |----------------------|--------------------------------------------------------------|
//! | `seconds.load`       | reading the scene, meshes and textures, and building the accelerators (the build is part of loading) |
//! | `seconds.render`     | rendering, all passes                                        |
//! | `seconds.write`      | writing the output image                                     |
//! | `seconds.total`      | the three together                                           |
//! | `samples`            | camera samples taken (pixels × spp)                          |
//! | `samples_per_second` | `samples / seconds.render`                                   |
//! | `rays`               | rays traced: camera, bounce and shadow rays                  |
//! | `rays_per_second`    | `rays / seconds.render`                                      |
//! | `rays_by_kind`       | `camera`, `bounce` (closest-hit rays after the first) and `shadow` rays |
//! | `nodes_visited`      | acceleration-structure nodes entered                         |
//! | `prims_tested`       | primitives tested for intersection                           |
//! | `non_finite_samples` | NaN or infinite samples, dropped                             |
//! | `accel_bytes`        | memory of the top-level and all mesh accelerators            |
//! | `tlas`               | top level: `instances`, `bytes`, `build_seconds`             |
//! | `blas`               | bottom level (distinct meshes): `count`, `triangles`, `bytes`, `build_seconds` |
//! | `width`, `height`    | image size in pixels                                         |
//! | `spp`                | samples per pixel of the image                               |
//! | `passes`             | progressive passes that went into the image                  |

use crate::fsutil;
use anyhow::Result;
use lightpath::render::RenderStats;
use serde_json::json;
use std::path::Path;

/// Everything the statistics report.
#[derive(Debug, Clone)]
pub struct Report {
    pub load_seconds: f64,
    pub render_seconds: f64,
    pub write_seconds: f64,
    pub stats: RenderStats,
    pub accel_bytes: usize,
    pub accel: lightpath::scene::AccelReport,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub passes: u32,
}

impl Report {
    fn per_second(&self, n: u64) -> f64 {
        if self.render_seconds > 0.0 {
            n as f64 / self.render_seconds
        } else {
            0.0
        }
    }

    pub fn json(&self) -> serde_json::Value {
        let s = &self.stats;
        json!({
            "seconds": {
                "load": self.load_seconds,
                "render": self.render_seconds,
                "write": self.write_seconds,
                "total": self.load_seconds + self.render_seconds + self.write_seconds,
            },
            "samples": s.samples,
            "samples_per_second": self.per_second(s.samples),
            "rays": s.rays,
            "rays_per_second": self.per_second(s.rays),
            "rays_by_kind": {
                "camera": s.camera_rays,
                "bounce": s.rays.saturating_sub(s.camera_rays + s.shadow_rays),
                "shadow": s.shadow_rays,
            },
            "nodes_visited": s.nodes_visited,
            "prims_tested": s.prims_tested,
            "non_finite_samples": s.non_finite_samples,
            "accel_bytes": self.accel_bytes,
            "tlas": {
                "instances": self.accel.tlas_instances,
                "bytes": self.accel.tlas_bytes,
                "build_seconds": self.accel.tlas_build_seconds,
            },
            "blas": {
                "count": self.accel.blas_count,
                "triangles": self.accel.blas_triangles,
                "bytes": self.accel.blas_bytes,
                "build_seconds": self.accel.blas_build_seconds,
            },
            "width": self.width,
            "height": self.height,
            "spp": self.spp,
            "passes": self.passes,
            "threads": rayon::current_num_threads(),
            "simd": lightpath::simd_tier().name(),
        })
    }

    pub fn write_json(&self, path: &Path) -> Result<()> {
        let mut text = serde_json::to_string_pretty(&self.json())?;
        text.push('\n');
        fsutil::write_atomic(path, text.as_bytes())
    }

    /// The human-readable table.
    pub fn table(&self) -> String {
        let s = &self.stats;
        let per = |n: u64| crate::progress::si(self.per_second(n));
        let per_sample = |n: u64| n as f64 / s.samples.max(1) as f64;
        [
            format!("load (incl. build)  {:>10.3} s", self.load_seconds),
            format!("render              {:>10.3} s", self.render_seconds),
            format!("write               {:>10.3} s", self.write_seconds),
            format!(
                "image               {}x{}, {} spp in {} passes",
                self.width, self.height, self.spp, self.passes
            ),
            format!(
                "samples             {:>10} ({}/s)",
                s.samples,
                per(s.samples)
            ),
            format!("rays                {:>10} ({}/s)", s.rays, per(s.rays)),
            format!(
                "  by kind           camera {}, bounce {}, shadow {}",
                s.camera_rays,
                s.rays.saturating_sub(s.camera_rays + s.shadow_rays),
                s.shadow_rays
            ),
            format!(
                "nodes visited       {:>10} ({:.1} per sample)",
                s.nodes_visited,
                per_sample(s.nodes_visited)
            ),
            format!(
                "prims tested        {:>10} ({:.1} per sample)",
                s.prims_tested,
                per_sample(s.prims_tested)
            ),
            format!("non-finite samples  {:>10}", s.non_finite_samples),
            format!(
                "accelerator memory  {:>10}",
                crate::summary::bytes(self.accel_bytes)
            ),
            format!(
                "TLAS                {:>10} instances, {}, built in {:.3} s",
                self.accel.tlas_instances,
                crate::summary::bytes(self.accel.tlas_bytes),
                self.accel.tlas_build_seconds
            ),
            format!(
                "BLAS                {:>10} meshes, {} triangles, {}, built in {:.3} s",
                self.accel.blas_count,
                self.accel.blas_triangles,
                crate::summary::bytes(self.accel.blas_bytes),
                self.accel.blas_build_seconds
            ),
        ]
        .join("\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_keys() {
        let r = Report {
            load_seconds: 1.0,
            render_seconds: 2.0,
            write_seconds: 0.5,
            stats: RenderStats {
                samples: 100,
                rays: 300,
                ..Default::default()
            },
            accel_bytes: 64,
            accel: Default::default(),
            width: 10,
            height: 10,
            spp: 1,
            passes: 1,
        };
        let j = r.json();
        assert_eq!(j["seconds"]["total"], 3.5);
        assert_eq!(j["samples_per_second"], 50.0);
        assert_eq!(j["rays_per_second"], 150.0);
        assert!(r.table().contains("10x10, 1 spp in 1 passes"));
    }
}
