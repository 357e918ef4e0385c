//! Light-traced lens flare: the ghosts of a realistic camera with `flare` (and the
//! default `flareSampling="light"`) are not found by camera rays but by paths from the
//! lights. Each path takes a point on the lens's front entrance, samples a light from
//! there (the scene's light sampler, as next-event estimation does), checks that nothing
//! blocks it, and carries the light through the lens along a ghost path to the film
//! ([`Realistic::ghost_splat`]), where it adds to the pixel it lands in. A pass traces as
//! many paths per sample index as the image has pixels, so the ghosts converge with the
//! image; every random number is a function of the sampler's seed, the sample index
//! and the path's chunk, so the result does not depend on the thread count or on how
//! the samples are split into passes.
//!
//! ```xml
//! <camera type="realistic">
//!     <string name="lensFile" value="lenses/double-doublet.50mm.dat"/>
//!     <boolean name="flare" value="true"/>
//!     <string name="flareSampling" value="light"/>  <!-- the default; or "camera" -->
//! </camera>
//! ```

use super::{RenderStats, Renderer};
use crate::camera::Realistic;
use crate::geometry::SHADOW_EPSILON;
use crate::math::{Ray, Transform};
use crate::sampling::{mix_bits, Pcg32};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Light paths per task.
const CHUNK: usize = 4096;

impl Renderer<'_> {
    /// Adds the ghosts of sample indices `[first, first + count)` to `sums` (per-pixel
    /// sums over samples); returns the rays traced.
    pub(super) fn add_flare(
        &self,
        camera: &Realistic,
        first: u32,
        count: u32,
        sums: &mut [Vec3],
    ) -> RenderStats {
        let pixels = sums.len();
        let camera_from_render = camera.render_from_camera.inverse();
        let chunks = pixels.div_ceil(CHUNK);
        let seed = mix_bits(self.sampler.seed() ^ 0x666c_6172_6500);
        let mut stats = RenderStats::default();
        for index in first..first + count {
            let splats: Vec<(Vec<(usize, Vec3)>, u64)> = (0..chunks)
                .into_par_iter()
                .map(|c| {
                    let mut rng = Pcg32::new(mix_bits(seed ^ index as u64), c as u64);
                    let n = CHUNK.min(pixels - c * CHUNK);
                    let mut out = Vec::new();
                    let mut rays = 0;
                    for _ in 0..n {
                        if let Some(s) =
                            self.flare_path(camera, &camera_from_render, &mut rng, &mut rays)
                        {
                            out.push(s);
                        }
                    }
                    (out, rays)
                })
                .collect();
            let scale = 1.0 / pixels as f32;
            for (out, rays) in splats {
                for (i, v) in out {
                    sums[i] += v * scale;
                }
                stats.rays += rays;
                stats.shadow_rays += rays;
            }
        }
        stats
    }

    /// One light path's splat: the pixel and its value (see the module notes).
    fn flare_path(
        &self,
        camera: &Realistic,
        camera_from_render: &Transform,
        rng: &mut Pcg32,
        rays: &mut u64,
    ) -> Option<(usize, Vec3)> {
        let mut u2 = || Vec2::new(rng.next_f32(), rng.next_f32());
        let (u_front, u_light, u_point, u_path) = (u2(), u2(), u2(), u2());
        let (x_lens, x_camera) = camera.front_point(u_front);
        let x = camera.render_from_camera.point(x_camera);
        let (index, pick) = self.scene.light_sampler.sample(u_light.x)?;
        let ls = self.scene.lights[index].sample(x, u_light.y, u_point)?;
        if ls.weight == Vec3::ZERO || pick.is_nan() || pick <= 0.0 {
            return None;
        }
        let travel = camera_from_render.vector(-ls.wi);
        let (raster, w) = camera.ghost_splat(x_lens, travel, u_path.x, u_path.y)?;
        let shadow = if ls.distance.is_finite() {
            Ray::with_range(x, ls.wi, 0.0, ls.distance * (1.0 - SHADOW_EPSILON))
        } else {
            Ray::new(x, ls.wi)
        };
        *rays += 1;
        if self.scene.occluded(&shadow) {
            return None;
        }
        let value = ls.weight * w / pick;
        if !value.is_finite() {
            return None;
        }
        let res = camera.resolution;
        let (px, py) = (
            (raster.x as u32).min(res.x - 1),
            (raster.y as u32).min(res.y - 1),
        );
        Some((py as usize * res.x as usize + px as usize, value))
    }
}
