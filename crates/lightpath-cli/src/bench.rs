//! `lightpath bench MESH --rays DIR`: build time, memory and traversal speed of the
//! acceleration structures on the ray sets `embree-bench gen-rays` writes (primary,
//! random, diffuse: closest hit; shadow: any hit) and a path tracer's own rays that
//! `lightpath render --record-rays` writes (paths: closest hit; shadow: any hit), timed the way embree-bench times them:
//! one untimed warm-up, then the median of `--reps` passes, file I/O excluded, single-
//! threaded and on all threads (ray by ray, each thread takes the next 1,024 rays from a
//! shared counter, as embree-bench's threads do). `--json FILE` writes embree-bench's key
//! layout per accelerator (`build.st.ms_median`,
//! `traversal.st.primary.mrays_per_s_median`, …), so the two outputs compare key by key.
//! The single-threaded entries also carry the mean nodes visited and primitives tested per
//! ray (`nodes_visited_per_ray`, `prims_tested_per_ray`), counted in a separate untimed
//! pass.

use crate::fsutil;
use crate::heatmap;
use crate::rays::read_rays;
use anyhow::{bail, Result};
use lightpath::accel::{AccelKind, RayStats};
use lightpath::geometry::TriangleMesh;
use lightpath::math::Ray;
use rayon::prelude::*;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Triangle mesh (.ply or .obj).
    pub mesh: PathBuf,
    /// Folder with primary.rays, random.rays, diffuse.rays, shadow.rays (from
    /// `embree-bench gen-rays MESH --outdir DIR`) or paths.rays and shadow.rays (from
    /// `lightpath render --record-rays DIR`); missing sets are skipped.
    #[arg(long)]
    pub rays: PathBuf,
    /// Accelerators to measure (repeatable): list, bvh2, bvh4, bvh8, bvh2-hq, bvh4-hq,
    /// bvh8-hq, bvh-course, grid, octree, kdtree, bsp.
    #[arg(long, default_values_t = vec!["bvh2".to_string(), "bvh4".to_string(), "bvh8".to_string()],
          value_parser = crate::names::ACCELS)]
    pub accel: Vec<String>,
    /// Timed passes (after one warm-up).
    #[arg(long, default_value_t = 5)]
    pub reps: usize,
    /// Write the results as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Draw the traversal cost (nodes visited + primitives tested) of each primary ray
    /// as a PNG heat map (viridis, colour bar along the bottom; the maximum is printed).
    /// With several accelerators, `-NAME` is added to the file stem of each.
    #[arg(long, value_name = "FILE.png")]
    pub heatmap: Option<PathBuf>,
    /// Width of the primary rays' image (embree-bench's `--width`); by default the ray
    /// count's square root.
    #[arg(long, value_name = "W")]
    pub heatmap_width: Option<usize>,
    /// Also time the stream queries (256 rays per call, several in flight at a time in
    /// the 8-wide BVH; ray by ray elsewhere), as embree-bench's `--stream` times
    /// `rtcIntersect1M`: JSON under `traversal.st.stream`, `traversal.mt.stream`.
    #[arg(long)]
    pub stream: bool,
    /// Also time the packet queries (16 rays per call, in the rays' file order, through
    /// the 8-wide BVH with AVX-512 where the processor has it; ray by ray elsewhere), as
    /// Embree's `rtcIntersect16` traces packets: JSON under `traversal.st.packet`,
    /// `traversal.mt.packet`.
    #[arg(long)]
    pub packet: bool,
}

/// How a pass hands its rays to the mesh.
#[derive(Clone, Copy, PartialEq)]
enum Mode {
    /// Ray by ray.
    Single,
    /// [`STREAM_CHUNK`] rays per call to the stream queries.
    Stream,
    /// [`STREAM_CHUNK`] rays per call to the packet queries (16 at a time).
    Packet,
}

const SETS: [(&str, bool); 5] = [
    ("primary", false),
    ("random", false),
    ("shadow", true),
    ("diffuse", false),
    // A path tracer's own closest-hit rays (`lightpath render --record-rays`).
    ("paths", false),
];

/// A table cell for a speed in Mrays/s: two decimals from 1 up, and at least three
/// significant digits below (the brute-force list's 0.000925 would otherwise read 0.00).
fn rate_cell(mrays: f64) -> String {
    if !(mrays > 0.0 && mrays < 1.0) {
        return format!("{mrays:.2}");
    }
    let decimals = (2 - mrays.log10().floor() as i32).clamp(2, 6) as usize;
    format!("{mrays:.decimals$}")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Rays per stream call (as embree-bench's `--stream` passes 256 rays per
/// `rtcIntersect1M`).
const STREAM_CHUNK: usize = 256;

/// Rays a thread takes at a time in the multi-threaded ray-by-ray passes (embree-bench's
/// chunk).
const SINGLE_CHUNK: usize = 1024;

/// Milliseconds of one pass over the rays and the number of hits: ray by ray, or in
/// calls of [`STREAM_CHUNK`] rays to the stream or packet queries.
fn pass(
    mesh: &TriangleMesh,
    rays: &[Ray],
    occluded: bool,
    threads: usize,
    mode: Mode,
) -> (f64, u64) {
    let start = Instant::now();
    let hits = if mode != Mode::Single {
        let chunk = |c: &[Ray]| {
            let stats = &mut RayStats::default();
            if occluded {
                let mut h = vec![false; c.len()];
                if mode == Mode::Packet {
                    mesh.occluded_packets(c, &mut h, stats);
                } else {
                    mesh.occluded_stream(c, &mut h, stats);
                }
                h.iter().filter(|&&x| x).count()
            } else {
                let mut h = vec![None; c.len()];
                if mode == Mode::Packet {
                    mesh.intersect_packets(c, &mut h, stats);
                } else {
                    mesh.intersect_stream(c, &mut h, stats);
                }
                h.iter().filter(|x| x.is_some()).count()
            }
        };
        if threads == 1 {
            rays.chunks(STREAM_CHUNK).map(chunk).sum()
        } else {
            rays.par_chunks(STREAM_CHUNK).map(chunk).sum()
        }
    } else if threads == 1 {
        rays.iter().filter(|r| trace(mesh, r, occluded)).count()
    } else {
        // As embree-bench: every thread pulls the next chunk of rays from a shared
        // counter, so the threads trace neighbouring rays at the same time.
        let next = AtomicUsize::new(0);
        rayon::broadcast(|_| {
            let mut hits = 0;
            loop {
                let begin = next.fetch_add(SINGLE_CHUNK, Ordering::Relaxed);
                if begin >= rays.len() {
                    break hits;
                }
                let end = rays.len().min(begin + SINGLE_CHUNK);
                hits += rays[begin..end]
                    .iter()
                    .filter(|r| trace(mesh, r, occluded))
                    .count();
            }
        })
        .into_iter()
        .sum()
    };
    (start.elapsed().as_secs_f64() * 1e3, hits as u64)
}

/// Mean nodes visited and primitives tested per ray, from an untimed pass.
fn cost_per_ray(mesh: &TriangleMesh, rays: &[Ray], occluded: bool) -> (f64, f64) {
    let (nodes, prims) = rays
        .par_iter()
        .map(|r| {
            let mut s = RayStats::default();
            if occluded {
                mesh.occluded(r, &mut s);
            } else {
                mesh.intersect(r, &mut s);
            }
            (u64::from(s.nodes_visited), u64::from(s.prims_tested))
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let n = rays.len().max(1) as f64;
    (nodes as f64 / n, prims as f64 / n)
}

#[inline]
fn trace(mesh: &TriangleMesh, r: &Ray, occluded: bool) -> bool {
    let mut s = RayStats::default();
    if occluded {
        mesh.occluded(r, &mut s)
    } else {
        mesh.intersect(r, &mut s).is_some()
    }
}

pub fn run(args: BenchArgs) -> Result<()> {
    if args.reps == 0 {
        bail!("--reps must be at least 1");
    }
    let kinds: Vec<(String, AccelKind)> = args
        .accel
        .iter()
        .map(|a| {
            AccelKind::from_name(a)
                .map(|k| (a.clone(), k))
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "unknown --accel `{a}`; known: {}",
                        AccelKind::NAMES.join(", ")
                    )
                })
        })
        .collect::<Result<_>>()?;
    let data = lightpath::io::load_mesh(&args.mesh)?;
    let triangles = data.indices.len();
    let mut sets = Vec::new();
    for (name, occluded) in SETS {
        let path = args.rays.join(format!("{name}.rays"));
        if path.exists() {
            sets.push((name, occluded, read_rays(&path)?));
        }
    }
    if sets.is_empty() {
        bail!(
            "{}: no primary/random/shadow/diffuse/paths .rays files (make them with `embree-bench gen-rays MESH --outdir DIR` or `lightpath render --record-rays DIR`)",
            args.rays.display()
        );
    }
    let all = rayon::current_num_threads();
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut report = serde_json::Map::new();
    let columns: String = sets.iter().map(|(set, ..)| format!(" {set:>8}")).collect();
    println!(
        "{:<11} {:>9} {:>9} {:>8} |{columns}  (Mrays/s, 1 thread / {all} threads)",
        "accel", "build ms", "bytes/tri", "MB"
    );
    for (name, kind) in &kinds {
        // Build: warm-up, then the median of the passes (the BVH builds in parallel).
        let mut build_ms = Vec::new();
        let mut mesh = None;
        for i in 0..=args.reps {
            // The copy of the input is not part of the build.
            let input = data.clone();
            let start = Instant::now();
            let m = TriangleMesh::new(input, false, *kind)
                .map_err(|e| anyhow::anyhow!("{}: {e}", args.mesh.display()))?;
            if i > 0 {
                build_ms.push(start.elapsed().as_secs_f64() * 1e3);
            }
            mesh = Some(m);
        }
        let mesh = mesh.expect("built");
        let bytes = mesh.accel_memory_bytes();
        // The binary tree's quality (bvh4 and bvh8 collapse the same tree).
        let bvh_stats = match &mesh.accel {
            lightpath::accel::Accel::Bvh(b) => Some(b.stats),
            _ => None,
        };
        let collapse_cost = mesh.accel.collapse_cost();
        if let Some(path) = &args.heatmap {
            let Some((_, _, rays)) = sets.iter().find(|(set, ..)| *set == "primary") else {
                bail!(
                    "--heatmap needs {}",
                    args.rays.join("primary.rays").display()
                );
            };
            let path = heatmap::path_for(path, name, kinds.len() > 1);
            let max = heatmap::write(&path, &mesh, rays, args.heatmap_width)?;
            println!(
                "{name}: heat map {} (nodes + primitives per primary ray, 0 to {max})",
                path.display()
            );
        }
        let mut traversal = serde_json::Map::new();
        let modes: Vec<Mode> = [
            (Mode::Single, true),
            (Mode::Stream, args.stream),
            (Mode::Packet, args.packet),
        ]
        .into_iter()
        .filter_map(|(m, on)| on.then_some(m))
        .collect();
        let mut line = vec![String::new(); 2 * modes.len()];
        for (variant, threads) in [("st", 1usize), ("mt", all)] {
            let mut per_set = serde_json::Map::new();
            let mut stream_sets = serde_json::Map::new();
            let mut packet_sets = serde_json::Map::new();
            for (set, occluded, rays) in &sets {
                for (m, &mode) in modes.iter().enumerate() {
                    let run_pass = || pass(&mesh, rays, *occluded, threads, mode);
                    let (_, hits) = if threads == 1 {
                        single.install(run_pass)
                    } else {
                        run_pass()
                    };
                    let times: Vec<f64> = (0..args.reps)
                        .map(|_| {
                            if threads == 1 {
                                single.install(run_pass).0
                            } else {
                                run_pass().0
                            }
                        })
                        .collect();
                    let best = times.iter().cloned().fold(f64::INFINITY, f64::min);
                    let ms = median(times);
                    let mrays = rays.len() as f64 / (ms * 1e3);
                    let mut entry = json!({
                        "query": if *occluded { "occluded" } else { "closest_hit" },
                        "rays": rays.len(),
                        "hits": hits,
                        "ms_median": ms,
                        "mrays_per_s_median": mrays,
                        "mrays_per_s_best": rays.len() as f64 / (best * 1e3),
                    });
                    if threads == 1 && mode == Mode::Single {
                        // Traversal cost, counted in a separate untimed pass.
                        let (nodes, prims) = cost_per_ray(&mesh, rays, *occluded);
                        let e = entry.as_object_mut().expect("an object");
                        e.insert("nodes_visited_per_ray".into(), json!(nodes));
                        e.insert("prims_tested_per_ray".into(), json!(prims));
                    }
                    match mode {
                        Mode::Single => per_set.insert(set.to_string(), entry),
                        Mode::Stream => stream_sets.insert(set.to_string(), entry),
                        Mode::Packet => packet_sets.insert(set.to_string(), entry),
                    };
                    line[usize::from(threads != 1) + 2 * m] += &format!(" {:>8}", rate_cell(mrays));
                }
            }
            per_set.insert("threads".into(), json!(threads));
            if args.stream {
                per_set.insert("stream".into(), Value::Object(stream_sets));
            }
            if args.packet {
                per_set.insert("packet".into(), Value::Object(packet_sets));
            }
            traversal.insert(variant.into(), Value::Object(per_set));
        }
        let build_median = median(build_ms);
        let sah = match (bvh_stats, collapse_cost) {
            (Some(s), _) => format!("  SAH cost {:.3}, depth {}", s.sah_cost, s.max_depth),
            (None, Some(c)) => format!("  collapse cost {c:.3}"),
            (None, None) => String::new(),
        };
        println!(
            "{:<11} {:>9.1} {:>9.1} {:>8.2} |{}\n{:<41}|{}",
            name,
            build_median,
            bytes as f64 / triangles.max(1) as f64,
            bytes as f64 / 1e6,
            line[0],
            sah,
            line[1]
        );
        for (m, mode) in modes.iter().enumerate().skip(1) {
            let label = if *mode == Mode::Stream {
                "stream"
            } else {
                "packet"
            };
            println!(
                "{:>41}|{}\n{:<41}|{}",
                label,
                line[2 * m],
                "",
                line[2 * m + 1]
            );
        }
        report.insert(
            name.clone(),
            json!({
                "build": {"ms_median": build_median, "bvh_bytes": bytes,
                          "bytes_per_tri": bytes as f64 / triangles.max(1) as f64,
                          "sah_cost": bvh_stats.map(|s| s.sah_cost),
                          "collapse_cost": collapse_cost},
                "traversal": Value::Object(traversal),
            }),
        );
    }
    if let Some(path) = &args.json {
        let doc = json!({
            "tool": "lightpath bench",
            "mesh": {"path": args.mesh.display().to_string(), "triangles": triangles},
            "config": {"reps": args.reps, "threads": all},
            "accels": Value::Object(report),
        });
        let mut text = serde_json::to_string_pretty(&doc)?;
        text.push('\n');
        fsutil::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::rate_cell;

    #[test]
    fn rate_cells_keep_three_significant_digits_below_one() {
        assert_eq!(rate_cell(16.414), "16.41");
        assert_eq!(rate_cell(1.0), "1.00");
        assert_eq!(rate_cell(0.67), "0.670");
        assert_eq!(rate_cell(0.0215), "0.0215");
        assert_eq!(rate_cell(0.000_924_557), "0.000925");
        assert_eq!(rate_cell(0.0), "0.00");
    }
}
