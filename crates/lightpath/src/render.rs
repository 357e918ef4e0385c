//! The renderer: cuts the image into 16×16 tiles and renders them on rayon. Every random
//! number is a pure function of (pixel, sample index, seed), so the image is
//! bit-identical for any thread count and tile order.
//!
//! Rendering is progressive: [`Renderer::render_progressive`] renders the image in
//! passes, pass k adding sample indices `[a, b)` to every pixel's running sum, and
//! develops the image (sum / samples) after each pass. A pixel's samples are added in
//! index order whatever the passes are, so N samples per pixel give the same image, bit
//! for bit, in one pass or in many. Passes end only at pass boundaries, so every pixel
//! of a developed image has the same number of samples.

use crate::accel::RayStats;
use crate::camera::{Camera, CameraSample};
use crate::error::{Error, Result};
use crate::film::Image;
use crate::integrator::Integrator;
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::{UVec2, Vec2, Vec3};
use rayon::prelude::*;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

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

impl RenderStats {
    fn add(&mut self, other: &RenderStats) {
        self.samples += other.samples;
        self.non_finite_samples += other.non_finite_samples;
        self.nodes_visited += other.nodes_visited;
        self.prims_tested += other.prims_tested;
        self.rays += other.rays;
    }
}

/// A render job: the scene's camera, an integrator and a sampler.
pub struct Renderer<'a> {
    pub scene: &'a Scene,
    pub camera: &'a Camera,
    pub integrator: &'a Integrator,
    pub sampler: &'a Sampler,
}

/// Progress of a progressive render, reported from the worker threads as tiles finish.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Fraction done, 0 to 1: of the samples when there is a sample limit, of the time
    /// budget when there is one, whichever is further.
    pub fraction: f64,
    /// Samples per pixel of the passes completed so far.
    pub spp: u32,
    /// Samples taken so far, including the finished tiles of the current pass.
    pub samples: u64,
    /// Rays traced so far, including the finished tiles of the current pass.
    pub rays: u64,
    /// Time since the render started.
    pub elapsed: Duration,
}

/// How long a progressive render runs, and who hears about it.
#[derive(Clone, Copy, Default)]
pub struct RenderControl<'a> {
    /// Stop after this many samples per pixel. `None`: the sampler's count, or, with a
    /// time budget, no limit.
    pub max_spp: Option<u32>,
    /// Stop once this much time is spent. Passes are sized from the measured speed to
    /// end within the budget; a pass that would still overrun it is abandoned (its
    /// samples are dropped) so that the render stops close to the budget. The first
    /// pass (one sample per pixel) always completes.
    pub time_budget: Option<Duration>,
    /// Size passes to take about this long (for previews), instead of letting them
    /// double without bound.
    pub pass_interval: Option<Duration>,
    /// Called from the worker threads as tiles finish.
    pub progress: Option<&'a (dyn Fn(&Progress) + Sync)>,
}

/// A finished pass, handed to the `on_pass` callback of
/// [`Renderer::render_progressive`].
#[derive(Debug, Clone, Copy)]
pub struct Pass<'a> {
    /// 0-based index of the pass.
    pub index: u32,
    /// Samples per pixel of the image so far.
    pub spp: u32,
    /// The image developed from all passes so far.
    pub image: &'a Image,
    /// Statistics of all passes so far (`seconds`: time since the start).
    pub stats: &'a RenderStats,
    /// Whether this is the last pass (the render returns this image).
    pub last: bool,
}

/// The result of a progressive render.
#[derive(Debug, Clone)]
pub struct Rendered {
    pub image: Image,
    pub stats: RenderStats,
    /// Samples per pixel of the image.
    pub spp: u32,
    /// Passes that went into the image.
    pub passes: u32,
}

/// Chooses pass sizes.
#[derive(Debug, Clone, Copy)]
struct Schedule {
    /// Sample limit (`u32::MAX`: none).
    max_spp: u32,
    budget: Option<Duration>,
    interval: Option<Duration>,
    /// Render everything in one pass.
    single: bool,
}

/// Passes are sized to take at most this fraction of the remaining time budget at the
/// last pass's speed: the passes near the end shrink geometrically, so a slowdown of up
/// to 2x still ends within the budget, and a pass that overruns it anyway (and is
/// abandoned) wastes little.
const BUDGET_FILL: f64 = 0.5;

impl Schedule {
    /// The size of the next pass after `done` samples per pixel, `elapsed` time, and a
    /// measured cost of `seconds_per_spp` (of the last pass); 0: stop.
    fn next(&self, done: u32, elapsed: Duration, seconds_per_spp: Option<f64>) -> u32 {
        let left = self.max_spp - done;
        if left == 0 {
            return 0;
        }
        if self.single {
            return left;
        }
        // Doubling: 1, 1, 2, 4, ... so the total doubles with every pass.
        let mut size = done.max(1).min(left);
        if let Some(t) = seconds_per_spp.filter(|t| *t > 0.0) {
            if let Some(interval) = self.interval {
                let fit = (interval.as_secs_f64() / t).floor();
                size = size.min(fit.clamp(1.0, u32::MAX as f64) as u32);
            }
            if let Some(budget) = self.budget {
                let remaining = budget.as_secs_f64() - elapsed.as_secs_f64();
                let mut fit = (remaining * BUDGET_FILL / t).floor();
                if fit < 1.0 && remaining >= t {
                    // Too little time left for the halving rule, but one more sample
                    // per pixel is expected to fit (if it does not, the pass is
                    // abandoned at the budget: time is never exceeded, only wasted).
                    fit = 1.0;
                }
                if fit < 1.0 {
                    return 0;
                }
                size = size.min(fit.min(u32::MAX as f64) as u32);
            }
        } else if done > 0 && self.budget.is_some_and(|b| elapsed >= b) {
            return 0;
        }
        size
    }
}

impl Renderer<'_> {
    /// Renders the image. `progress` is called with the fraction done (0 to 1) from the
    /// worker threads as tiles complete.
    pub fn render(&self, progress: &(dyn Fn(f64) + Sync)) -> Result<(Image, RenderStats)> {
        let spp = self.sampler.samples_per_pixel().max(1);
        let report = |p: &Progress| progress(p.fraction);
        let schedule = Schedule {
            max_spp: spp,
            budget: None,
            interval: None,
            single: true,
        };
        let out = self.run(schedule, Some(&report), &mut |_| ControlFlow::Continue(()))?;
        Ok((out.image, out.stats))
    }

    /// Renders the image in passes until `control.max_spp` samples per pixel are taken
    /// or `control.time_budget` is spent, calling `on_pass` after each pass with the
    /// image so far; `on_pass` returning `ControlFlow::Break` ends the render with that
    /// image. The sampler's own count only shapes its sequences (e.g. the Sobol
    /// sampler's shuffle); `max_spp` equal to it gives the image of [`Renderer::render`],
    /// bit for bit.
    pub fn render_progressive(
        &self,
        control: &RenderControl,
        on_pass: &mut dyn FnMut(&Pass) -> ControlFlow<()>,
    ) -> Result<Rendered> {
        let max_spp = match (control.max_spp, control.time_budget) {
            (Some(0), _) => {
                return Err(Error::Invalid("the sample count must be at least 1".into()))
            }
            (Some(n), _) => n,
            (None, Some(_)) => u32::MAX,
            (None, None) => self.sampler.samples_per_pixel().max(1),
        };
        let schedule = Schedule {
            max_spp,
            budget: control.time_budget,
            interval: control.pass_interval,
            single: false,
        };
        self.run(schedule, control.progress, on_pass)
    }

    fn run(
        &self,
        schedule: Schedule,
        progress: Option<&(dyn Fn(&Progress) + Sync)>,
        on_pass: &mut dyn FnMut(&Pass) -> ControlFlow<()>,
    ) -> Result<Rendered> {
        let res = self.camera.resolution();
        if res.x == 0 || res.y == 0 {
            return Err(Error::Invalid(format!(
                "image size {}x{} is empty",
                res.x, res.y
            )));
        }
        let start = Instant::now();
        let deadline = schedule.budget.map(|b| start + b);
        let mut sums = vec![Vec3::ZERO; res.x as usize * res.y as usize];
        let mut image = Image::new(res.x, res.y);
        let mut stats = RenderStats::default();
        let (mut done, mut passes) = (0u32, 0u32);
        let mut seconds_per_spp = None;
        loop {
            let size = schedule.next(done, start.elapsed(), seconds_per_spp);
            if size == 0 {
                break;
            }
            let pass_start = Instant::now();
            let job = PassJob {
                res,
                first: done,
                count: size,
                // The first pass always completes: the image needs a sample per pixel.
                deadline: if done > 0 { deadline } else { None },
                schedule: &schedule,
                start,
                base: stats,
                progress,
            };
            let Some(pass_stats) = self.render_pass(&job, &mut sums) else {
                break; // abandoned at the deadline
            };
            done += size;
            passes += 1;
            stats.add(&pass_stats);
            stats.seconds = start.elapsed().as_secs_f64();
            seconds_per_spp = Some(pass_start.elapsed().as_secs_f64() / size as f64);
            let scale = done as f32;
            for (p, s) in image.pixels.iter_mut().zip(&sums) {
                *p = *s / scale;
            }
            let last = schedule.next(done, start.elapsed(), seconds_per_spp) == 0;
            let pass = Pass {
                index: passes - 1,
                spp: done,
                image: &image,
                stats: &stats,
                last,
            };
            if on_pass(&pass).is_break() || last {
                break;
            }
        }
        stats.seconds = start.elapsed().as_secs_f64();
        Ok(Rendered {
            image,
            stats,
            spp: done,
            passes,
        })
    }

    /// Adds samples `[job.first, job.first + job.count)` of every pixel to `sums`.
    /// `None` (and `sums` untouched) if the pass was abandoned at the deadline.
    fn render_pass(&self, job: &PassJob, sums: &mut [Vec3]) -> Option<RenderStats> {
        let res = job.res;
        let tiles_x = res.x.div_ceil(TILE_SIZE);
        let tiles_y = res.y.div_ceil(TILE_SIZE);
        let n_tiles = (tiles_x * tiles_y) as u64;
        let tiles_done = AtomicU64::new(0);
        let samples = AtomicU64::new(job.base.samples);
        let rays = AtomicU64::new(job.base.rays);
        let abandoned = AtomicBool::new(false);
        let current: &[Vec3] = sums;
        let results: Vec<Option<TileResult>> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|tile| {
                let (x0, y0) = ((tile % tiles_x) * TILE_SIZE, (tile / tiles_x) * TILE_SIZE);
                let (pixels, s) = self.render_tile(x0, y0, job, current, &abandoned)?;
                if let Some(progress) = job.progress {
                    let d = tiles_done.fetch_add(1, Ordering::Relaxed) + 1;
                    let samples = samples.fetch_add(s.samples, Ordering::Relaxed) + s.samples;
                    let rays = rays.fetch_add(s.rays, Ordering::Relaxed) + s.rays;
                    let elapsed = job.start.elapsed();
                    let spp_now = job.first as f64 + job.count as f64 * d as f64 / n_tiles as f64;
                    progress(&Progress {
                        fraction: job.schedule.fraction(spp_now, elapsed),
                        spp: job.first,
                        samples,
                        rays,
                        elapsed,
                    });
                }
                Some((x0, y0, pixels, s))
            })
            .collect();
        if abandoned.load(Ordering::Relaxed) {
            return None;
        }
        let mut stats = RenderStats::default();
        for (x0, y0, pixels, s) in results.into_iter().flatten() {
            let w = TILE_SIZE.min(res.x - x0);
            for (i, p) in pixels.into_iter().enumerate() {
                let (x, y) = (x0 + i as u32 % w, y0 + i as u32 / w);
                sums[y as usize * res.x as usize + x as usize] = p;
            }
            stats.add(&s);
        }
        Some(stats)
    }

    /// The new sums of a tile's pixels; `None` once the pass is abandoned.
    fn render_tile(
        &self,
        x0: u32,
        y0: u32,
        job: &PassJob,
        sums: &[Vec3],
        abandoned: &AtomicBool,
    ) -> Option<(Vec<Vec3>, RenderStats)> {
        let res = job.res;
        let (x1, y1) = ((x0 + TILE_SIZE).min(res.x), (y0 + TILE_SIZE).min(res.y));
        let mut sampler = self.sampler.clone();
        let mut pixels = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
        let mut stats = RenderStats::default();
        for y in y0..y1 {
            for x in x0..x1 {
                if let Some(deadline) = job.deadline {
                    if abandoned.load(Ordering::Relaxed) || Instant::now() > deadline {
                        abandoned.store(true, Ordering::Relaxed);
                        return None;
                    }
                }
                let pixel = UVec2::new(x, y);
                // Per-pixel counters, added into 64-bit totals (a tile's could overflow u32).
                let mut ray_stats = RayStats::default();
                // Continue the pixel's running sum in sample order: the same additions,
                // in the same order, as rendering all samples in one pass.
                let mut sum = sums[y as usize * res.x as usize + x as usize];
                for index in job.first..job.first + job.count {
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
                stats.samples += job.count as u64;
                stats.nodes_visited += ray_stats.nodes_visited as u64;
                stats.prims_tested += ray_stats.prims_tested as u64;
                stats.rays += ray_stats.rays as u64;
                pixels.push(sum);
            }
        }
        Some((pixels, stats))
    }
}

/// A rendered tile: its corner, its pixels' new sums, its statistics.
type TileResult = (u32, u32, Vec<Vec3>, RenderStats);

/// One pass of a render.
struct PassJob<'a> {
    res: UVec2,
    first: u32,
    count: u32,
    /// Abandon the pass after this instant.
    deadline: Option<Instant>,
    schedule: &'a Schedule,
    start: Instant,
    /// Statistics before this pass.
    base: RenderStats,
    progress: Option<&'a (dyn Fn(&Progress) + Sync)>,
}

impl Schedule {
    /// The fraction done at `spp` samples per pixel (fractional within a pass) and
    /// `elapsed` time.
    fn fraction(&self, spp: f64, elapsed: Duration) -> f64 {
        let mut f: f64 = 0.0;
        if self.max_spp != u32::MAX {
            f = f.max(spp / self.max_spp as f64);
        }
        if let Some(b) = self.budget {
            f = f.max(elapsed.as_secs_f64() / b.as_secs_f64().max(1e-9));
        }
        f.min(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{load_scene_str, LoadOptions, LoadedScene};
    use std::path::Path;

    fn scene(sampler: &str, spp: u32) -> LoadedScene {
        // A point light on diffuse shapes: sample values are fractional, so the order in
        // which they are added shows in the bits.
        let xml = format!(
            r#"<integrator type="direct">
                <scene>
                    <camera type="perspective">
                        <integer name="width" value="37"/>
                        <integer name="height" value="21"/>
                        <transform><lookat origin="0,-1,-5" target="0,0,0" up="0,-1,0"/></transform>
                    </camera>
                    <light type="point" position="1,-3,-2" intensity="10"/>
                    <light type="envmap"><texture type="constant" value="0.3"/></light>
                    <instance>
                        <shape type="sphere"/>
                        <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.7"/></bsdf>
                    </instance>
                    <instance>
                        <shape type="plane"/>
                        <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.4"/></bsdf>
                        <transform><rotate axis="1,0,0" angle="-90"/><translate y="1"/></transform>
                    </instance>
                </scene>
                <sampler type="{sampler}" count="{spp}"/>
            </integrator>"#
        );
        load_scene_str(&xml, Path::new("progressive.xml"), &LoadOptions::default()).unwrap()
    }

    fn renderer(l: &LoadedScene) -> Renderer<'_> {
        Renderer {
            scene: &l.scene,
            camera: l.scene.camera.as_ref().unwrap(),
            integrator: &l.integrator,
            sampler: &l.sampler,
        }
    }

    fn bits(image: &Image) -> Vec<[u32; 3]> {
        image
            .pixels
            .iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect()
    }

    /// N samples per pixel in several passes give the single-pass image bit for bit,
    /// for both samplers, whether the passes double or are cut short by an interval.
    #[test]
    fn progressive_passes_equal_one_pass() {
        for sampler in ["independent", "sobol"] {
            let l = scene(sampler, 13);
            let r = renderer(&l);
            let (single, single_stats) = r.render(&|_| {}).unwrap();
            for interval in [None, Some(Duration::ZERO)] {
                let mut spps = Vec::new();
                let out = r
                    .render_progressive(
                        &RenderControl {
                            max_spp: Some(13),
                            pass_interval: interval,
                            ..Default::default()
                        },
                        &mut |p| {
                            spps.push(p.spp);
                            ControlFlow::Continue(())
                        },
                    )
                    .unwrap();
                assert_eq!(out.spp, 13);
                match interval {
                    None => assert_eq!(spps, vec![1, 2, 4, 8, 13], "{sampler}"),
                    Some(_) => assert_eq!(spps, (1..=13).collect::<Vec<_>>(), "{sampler}"),
                }
                assert_eq!(out.passes as usize, spps.len());
                assert_eq!(bits(&out.image), bits(&single), "{sampler} {interval:?}");
                assert_eq!(out.stats.samples, single_stats.samples);
                assert_eq!(out.stats.rays, single_stats.rays);
            }
        }
    }

    /// The image after each pass is the image of that many samples per pixel.
    #[test]
    fn each_pass_is_a_complete_image() {
        let l = scene("independent", 4);
        let r = renderer(&l);
        let mut images = Vec::new();
        r.render_progressive(
            &RenderControl {
                max_spp: Some(4),
                ..Default::default()
            },
            &mut |p| {
                images.push((p.spp, p.image.clone(), p.last));
                ControlFlow::Continue(())
            },
        )
        .unwrap();
        assert_eq!(images.len(), 3);
        assert!(images[2].2 && !images[1].2);
        for (spp, image, _) in images {
            let sampler = l.sampler.with_samples_per_pixel(spp);
            let r1 = Renderer {
                sampler: &sampler,
                ..renderer(&l)
            };
            // The independent sampler's streams do not depend on the declared count.
            assert_eq!(bits(&r1.render(&|_| {}).unwrap().0), bits(&image), "{spp}");
        }
    }

    #[test]
    fn on_pass_can_stop_the_render() {
        let l = scene("sobol", 64);
        let r = renderer(&l);
        let out = r
            .render_progressive(&RenderControl::default(), &mut |p| {
                if p.spp >= 4 {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            })
            .unwrap();
        assert_eq!((out.spp, out.passes), (4, 3));
        assert_eq!(out.stats.samples, 4 * 37 * 21);
    }

    /// With a time budget and no sample limit, the render stops near the budget with a
    /// whole number of samples in every pixel.
    #[test]
    fn time_budget_stops_the_render() {
        let l = scene("independent", 1);
        let r = renderer(&l);
        let budget = Duration::from_millis(300);
        let fractions = std::sync::Mutex::new(Vec::new());
        let report = |p: &Progress| fractions.lock().unwrap().push(p.fraction);
        let start = Instant::now();
        let out = r
            .render_progressive(
                &RenderControl {
                    time_budget: Some(budget),
                    progress: Some(&report),
                    ..Default::default()
                },
                &mut |_| ControlFlow::Continue(()),
            )
            .unwrap();
        let took = start.elapsed();
        assert!(took < budget + Duration::from_millis(250), "{took:?}");
        assert!(out.spp > 1, "{}", out.spp);
        assert_eq!(out.stats.samples, out.spp as u64 * 37 * 21);
        let fractions = fractions.into_inner().unwrap();
        assert!(fractions.iter().all(|f| (0.0..=1.0).contains(f)));
    }

    #[test]
    fn schedule_sizes() {
        let s = Schedule {
            max_spp: 100,
            budget: None,
            interval: None,
            single: false,
        };
        let mut done = 0;
        let mut sizes = Vec::new();
        loop {
            let n = s.next(done, Duration::ZERO, Some(0.01));
            if n == 0 {
                break;
            }
            sizes.push(n);
            done += n;
        }
        assert_eq!(sizes, vec![1, 1, 2, 4, 8, 16, 32, 36]);
        // A budget with 1 s left at 0.1 s per spp: passes fit in half of it.
        let b = Schedule {
            max_spp: u32::MAX,
            budget: Some(Duration::from_secs(3)),
            ..s
        };
        assert_eq!(b.next(0, Duration::ZERO, None), 1);
        assert_eq!(b.next(64, Duration::from_secs(2), Some(0.1)), 5);
        assert_eq!(b.next(64, Duration::from_millis(2850), Some(0.1)), 1);
        assert_eq!(b.next(64, Duration::from_millis(2950), Some(0.1)), 0);
        assert_eq!(b.next(64, Duration::from_secs(4), Some(0.1)), 0);
        // An interval of 0.25 s at 0.1 s per spp: passes of 2.
        let i = Schedule {
            interval: Some(Duration::from_millis(250)),
            ..s
        };
        assert_eq!(i.next(64, Duration::ZERO, Some(0.1)), 2);
    }
}
