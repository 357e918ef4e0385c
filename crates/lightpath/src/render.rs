//! The renderer: cuts the image into 16×16 tiles and renders them on rayon. Every random
//! number is a pure function of (pixel, sample index, seed), so the image is
//! bit-identical for any thread count and tile order.

use crate::accel::RayStats;
use crate::camera::{Camera, CameraSample};
use crate::error::{Error, Result};
use crate::film::Image;
use crate::integrator::Integrator;
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::{UVec2, Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Tile edge length in pixels.
pub const TILE_SIZE: u32 = 16;

/// What the renderer reports after a render.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RenderStats {
    pub seconds: f64,
    pub samples: u64,
    /// Samples that were NaN or infinite and were dropped.
    pub non_finite_samples: u64,
    pub nodes_visited: u64,
    pub prims_tested: u64,
    /// Rays traced (camera, bounce and shadow rays).
    pub rays: u64,
}

/// A render job: the scene's camera, an integrator and a sampler.
pub struct Renderer<'a> {
    pub scene: &'a Scene,
    pub camera: &'a Camera,
    pub integrator: &'a Integrator,
    pub sampler: &'a Sampler,
}

impl Renderer<'_> {
    /// Renders the image. `progress` is called with the fraction done (0 to 1) from the
    /// worker threads as tiles complete.
    pub fn render(&self, progress: &(dyn Fn(f64) + Sync)) -> Result<(Image, RenderStats)> {
        let res = self.camera.resolution();
        if res.x == 0 || res.y == 0 {
            return Err(Error::Invalid(format!(
                "image size {}x{} is empty",
                res.x, res.y
            )));
        }
        let start = Instant::now();
        let tiles_x = res.x.div_ceil(TILE_SIZE);
        let tiles_y = res.y.div_ceil(TILE_SIZE);
        let n_tiles = (tiles_x * tiles_y) as u64;
        let done = AtomicU64::new(0);
        let results: Vec<(u32, u32, Vec<Vec3>, RenderStats)> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|tile| {
                let (tx, ty) = (tile % tiles_x, tile / tiles_x);
                let out = self.render_tile(tx * TILE_SIZE, ty * TILE_SIZE, res);
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(d as f64 / n_tiles as f64);
                (tx * TILE_SIZE, ty * TILE_SIZE, out.0, out.1)
            })
            .collect();
        let mut image = Image::new(res.x, res.y);
        let mut stats = RenderStats::default();
        for (x0, y0, pixels, s) in results {
            let w = TILE_SIZE.min(res.x - x0);
            for (i, p) in pixels.into_iter().enumerate() {
                let (x, y) = (x0 + i as u32 % w, y0 + i as u32 / w);
                image.set(x, y, p);
            }
            stats.samples += s.samples;
            stats.non_finite_samples += s.non_finite_samples;
            stats.nodes_visited += s.nodes_visited;
            stats.prims_tested += s.prims_tested;
            stats.rays += s.rays;
        }
        stats.seconds = start.elapsed().as_secs_f64();
        Ok((image, stats))
    }

    fn render_tile(&self, x0: u32, y0: u32, res: UVec2) -> (Vec<Vec3>, RenderStats) {
        let (x1, y1) = ((x0 + TILE_SIZE).min(res.x), (y0 + TILE_SIZE).min(res.y));
        let mut sampler = self.sampler.clone();
        let spp = sampler.samples_per_pixel().max(1);
        let mut pixels = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
        let mut stats = RenderStats::default();
        for y in y0..y1 {
            for x in x0..x1 {
                let pixel = UVec2::new(x, y);
                // Per-pixel counters, added into 64-bit totals (a tile's could overflow u32).
                let mut ray_stats = RayStats::default();
                let mut sum = Vec3::ZERO;
                for index in 0..spp {
                    sampler.start_pixel_sample(pixel, index);
                    let film = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                    let lens = sampler.next_2d();
                    let value = match self.camera.generate_ray(&CameraSample { film, lens }) {
                        Some(ray) => {
                            self.integrator
                                .li(self.scene, &ray, &mut sampler, &mut ray_stats)
                        }
                        None => self.integrator.no_ray_value(),
                    };
                    if value.is_finite() {
                        sum += value;
                    } else {
                        stats.non_finite_samples += 1;
                    }
                }
                stats.samples += spp as u64;
                stats.nodes_visited += ray_stats.nodes_visited as u64;
                stats.prims_tested += ray_stats.prims_tested as u64;
                stats.rays += ray_stats.rays as u64;
                pixels.push(sum / spp as f32);
            }
        }
        (pixels, stats)
    }
}
