//! `cargo bench -p lightpath --bench accel`: lightpath's accelerators against
//! [obvhs](https://crates.io/crates/obvhs), a Rust peer, on the same mesh and the same
//! rays in the same run (issue #3).
//!
//! The rays are the four sets `embree-bench gen-rays MESH --outdir DIR` writes (see
//! `../shared/tools/embree-bench/README.md`, "File formats"): 32-byte records of eight
//! little-endian `f32`, `ox oy oz tmin dx dy dz tmax`. `primary`, `random` and `diffuse`
//! are closest-hit queries, `shadow` an occlusion (any-hit) query.
//!
//! | variable                  | meaning                                               | default |
//! |---------------------------|-------------------------------------------------------|---------|
//! | `LIGHTPATH_BENCH_MESH`    | triangle mesh (`.ply`, `.obj`)                        | `../shared/models/stanford-bunny/bunny.ply` |
//! | `LIGHTPATH_BENCH_RAYS`    | folder with `{primary,random,shadow,diffuse}.rays`    | `../shared/tools/embree-bench/out/rays_bunny`, else `/tmp/rays_bunny` |
//! | `LIGHTPATH_BENCH_REPS`    | timed passes after one warm-up                        | 5 |
//! | `LIGHTPATH_BENCH_ACCELS`  | lightpath kinds, comma-separated (`bvh2,bvh4,kdtree,…`) | `bvh2,bvh4,bvh8` |
//! | `LIGHTPATH_BENCH_OBVHS`   | obvhs layouts, comma-separated (`cwbvh`, `bvh2`)      | `cwbvh` |
//! | `LIGHTPATH_BENCH_OBVHS_PRESET` | obvhs build preset: `fastest`, `very_fast`, `fast`, `medium`, `slow`, `very_slow` | `medium` |
//! | `RAYON_NUM_THREADS`       | threads of the multi-threaded passes                  | all cores |
//!
//! Relative paths are taken from the workspace root. A missing mesh or ray folder (a
//! fresh clone has no `../shared`) prints `skipped: …` and exits 0. Without the
//! `--bench` argument that `cargo bench` passes (e.g. under `cargo test --benches`) it
//! makes a smoke run: 4096 rays of each set (every k-th ray), one pass.
//!
//! What is compared, and how:
//! - **lightpath**: `TriangleMesh::new(data, false, kind)` and its `intersect` /
//!   `occluded` (the watertight triangle test in a closure handed to the accelerator),
//!   exactly what `lightpath bench` and `lightpath rays` call.
//! - **obvhs**: its CWBVH (8-wide compressed BVH, SIMD traversal: its fastest CPU path)
//!   built by `build_cwbvh_from_tris` with the `medium_build` preset (PLOC + reinsertion,
//!   the preset of its own documentation example, "around the same build time as Embree
//!   but with faster traversal"), with the `parallel` feature (rayon) as our builds use
//!   rayon too. The triangles are reordered by `primitive_indices` after the build, as
//!   obvhs recommends, and intersected with its `Triangle::intersect` (Möller–Trumbore,
//!   not watertight) through `ray_traverse` (closest hit) and `ray_traverse_miss` (any
//!   hit with early exit). Its BVH2 is available with `LIGHTPATH_BENCH_OBVHS=cwbvh,bvh2`.
//! - Both start from the same `lightpath::math::Ray` per record: obvhs's `Ray` (with its
//!   reciprocal direction) is made inside the timed loop, as lightpath's traversal makes
//!   its own per-ray constants inside.
//! - Build time: one warm-up build, then the median of `REPS` builds; for obvhs it
//!   includes making its `Triangle`s and the reordering, for lightpath the triangle boxes
//!   (the mesh data are cloned outside the timer).
//! - Traversal, timed as embree-bench does: one untimed warm-up pass, then the median of
//!   `REPS` passes, file I/O excluded; single-threaded (ST, the calling thread) and
//!   multi-threaded (MT, rayon over chunks of 1024 rays).
//! - Correctness: the number of hits and the mean hit distance of every accelerator are
//!   printed per set and compared with the first obvhs layout; a difference above 0.1%
//!   is flagged with `MISMATCH` (the bench still exits 0: the two triangle tests differ
//!   on edges, so a few rays may disagree).

use lightpath::accel::{AccelKind, RayStats};
use lightpath::geometry::{MeshData, TriangleMesh};
use lightpath::math::{Ray, Vec3};
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::RayHit;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The ray sets and whether each is an occlusion query.
const SETS: [(&str, bool); 4] = [
    ("primary", false),
    ("random", false),
    ("shadow", true),
    ("diffuse", false),
];

/// Rays per rayon task in the multi-threaded passes.
const CHUNK: usize = 1024;

/// Rays per set in a smoke run (without `--bench`, as under `cargo test --benches`).
const SMOKE_RAYS: usize = 4096;

/// Relative disagreement (hits, mean distance) that is flagged.
const TOLERANCE: f64 = 1e-3;

/// One accelerator over the mesh, answering the two queries.
trait Tracer: Sync {
    /// Distance to the closest hit.
    fn closest(&self, ray: &Ray) -> Option<f32>;
    /// Whether anything blocks `[t_min, t_max]`.
    fn occluded(&self, ray: &Ray) -> bool;
}

impl Tracer for TriangleMesh {
    #[inline]
    fn closest(&self, ray: &Ray) -> Option<f32> {
        self.intersect(ray, &mut RayStats::default()).map(|h| h.t)
    }
    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        TriangleMesh::occluded(self, ray, &mut RayStats::default())
    }
}

/// The two obvhs trees share their traversal signatures.
trait ObvhsTree: Sync {
    fn closest_hit<F: FnMut(&obvhs::ray::Ray, usize) -> f32>(
        &self,
        ray: obvhs::ray::Ray,
        hit: &mut RayHit,
        f: F,
    ) -> bool;
    fn miss<F: FnMut(&obvhs::ray::Ray, usize) -> f32>(&self, ray: obvhs::ray::Ray, f: F) -> bool;
    fn primitive_indices(&self) -> &[u32];
}

impl ObvhsTree for CwBvh {
    #[inline]
    fn closest_hit<F: FnMut(&obvhs::ray::Ray, usize) -> f32>(
        &self,
        ray: obvhs::ray::Ray,
        hit: &mut RayHit,
        f: F,
    ) -> bool {
        self.ray_traverse(ray, hit, f)
    }
    #[inline]
    fn miss<F: FnMut(&obvhs::ray::Ray, usize) -> f32>(&self, ray: obvhs::ray::Ray, f: F) -> bool {
        self.ray_traverse_miss(ray, f)
    }
    fn primitive_indices(&self) -> &[u32] {
        &self.primitive_indices
    }
}

impl ObvhsTree for Bvh2 {
    #[inline]
    fn closest_hit<F: FnMut(&obvhs::ray::Ray, usize) -> f32>(
        &self,
        ray: obvhs::ray::Ray,
        hit: &mut RayHit,
        f: F,
    ) -> bool {
        self.ray_traverse(ray, hit, f)
    }
    #[inline]
    fn miss<F: FnMut(&obvhs::ray::Ray, usize) -> f32>(&self, ray: obvhs::ray::Ray, f: F) -> bool {
        self.ray_traverse_miss(ray, f)
    }
    fn primitive_indices(&self) -> &[u32] {
        &self.primitive_indices
    }
}

/// An obvhs tree with its triangles in the tree's primitive order.
struct Obvhs<B> {
    tree: B,
    triangles: Vec<Triangle>,
}

impl<B: ObvhsTree> Obvhs<B> {
    fn build(data: &MeshData, build: impl Fn(&[Triangle]) -> B) -> Self {
        let p = |i: u32| data.positions[i as usize].into();
        let triangles: Vec<Triangle> = data
            .indices
            .iter()
            .map(|&[a, b, c]| Triangle {
                v0: p(a),
                v1: p(b),
                v2: p(c),
            })
            .collect();
        let tree = build(&triangles);
        let triangles = tree
            .primitive_indices()
            .iter()
            .map(|&i| triangles[i as usize])
            .collect();
        Obvhs { tree, triangles }
    }
}

#[inline]
fn obvhs_ray(ray: &Ray) -> obvhs::ray::Ray {
    obvhs::ray::Ray::new(
        ray.origin.into(),
        ray.direction.into(),
        ray.t_min,
        ray.t_max,
    )
}

impl<B: ObvhsTree> Tracer for Obvhs<B> {
    #[inline]
    fn closest(&self, ray: &Ray) -> Option<f32> {
        let mut hit = RayHit::none();
        self.tree
            .closest_hit(obvhs_ray(ray), &mut hit, |r, i| {
                self.triangles[i].intersect(r)
            })
            .then_some(hit.t)
    }
    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        !self
            .tree
            .miss(obvhs_ray(ray), |r, i| self.triangles[i].intersect(r))
    }
}

/// What one pass found: hits and the sum of their distances (closest-hit sets only).
#[derive(Clone, Copy, Default)]
struct Tally {
    hits: u64,
    t_sum: f64,
}

impl Tally {
    fn add(self, other: Tally) -> Tally {
        Tally {
            hits: self.hits + other.hits,
            t_sum: self.t_sum + other.t_sum,
        }
    }
    fn mean_t(&self) -> f64 {
        self.t_sum / self.hits.max(1) as f64
    }
}

#[inline]
fn trace_chunk(tracer: &impl Tracer, rays: &[Ray], occluded: bool) -> Tally {
    let mut tally = Tally::default();
    if occluded {
        tally.hits = rays.iter().filter(|r| tracer.occluded(r)).count() as u64;
    } else {
        for r in rays {
            if let Some(t) = tracer.closest(r) {
                tally.hits += 1;
                tally.t_sum += f64::from(t);
            }
        }
    }
    tally
}

/// Milliseconds of one pass over the rays, and what it found.
fn pass(tracer: &impl Tracer, rays: &[Ray], occluded: bool, parallel: bool) -> (f64, Tally) {
    let start = Instant::now();
    let tally = if parallel {
        rays.par_chunks(CHUNK)
            .map(|chunk| trace_chunk(tracer, chunk, occluded))
            .reduce(Tally::default, Tally::add)
    } else {
        trace_chunk(tracer, rays, occluded)
    };
    (start.elapsed().as_secs_f64() * 1e3, tally)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median milliseconds of `reps` calls after one warm-up, and the last result.
fn time_median<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = f();
    let mut ms = Vec::with_capacity(reps);
    for _ in 0..reps {
        let start = Instant::now();
        let next = f();
        ms.push(start.elapsed().as_secs_f64() * 1e3);
        out = next; // the previous result is dropped outside the timer
    }
    (median(ms), out)
}

/// One row of the results.
struct Row {
    name: String,
    is_peer: bool,
    build_ms: f64,
    /// Per set: (ST Mrays/s, MT Mrays/s, tally of the warm-up pass).
    sets: Vec<(f64, f64, Tally)>,
}

fn measure(
    name: String,
    is_peer: bool,
    build_ms: f64,
    tracer: &impl Tracer,
    sets: &[(&str, bool, Vec<Ray>)],
    reps: usize,
) -> Row {
    eprintln!("  tracing {name}");
    let mut out = Vec::new();
    for (_, occluded, rays) in sets {
        let mut mrays = [0.0; 2];
        let mut tally = Tally::default();
        for (i, parallel) in [false, true].into_iter().enumerate() {
            let (_, warm) = pass(tracer, rays, *occluded, parallel);
            if !parallel {
                tally = warm;
            }
            let ms = median(
                (0..reps)
                    .map(|_| pass(tracer, rays, *occluded, parallel).0)
                    .collect(),
            );
            mrays[i] = rays.len() as f64 / (ms * 1e3);
        }
        out.push((mrays[0], mrays[1], tally));
    }
    Row {
        name,
        is_peer,
        build_ms,
        sets: out,
    }
}

fn read_rays(path: &Path) -> Result<Vec<Ray>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if bytes.len() % 32 != 0 {
        return Err(format!(
            "{}: {} bytes is not a whole number of 32-byte ray records",
            path.display(),
            bytes.len()
        ));
    }
    let f = |r: &[u8], i: usize| f32::from_le_bytes(r[4 * i..4 * i + 4].try_into().unwrap());
    let rays: Vec<Ray> = bytes
        .chunks_exact(32)
        .map(|r| {
            Ray::with_range(
                Vec3::new(f(r, 0), f(r, 1), f(r, 2)),
                Vec3::new(f(r, 4), f(r, 5), f(r, 6)),
                f(r, 3),
                f(r, 7),
            )
        })
        .collect();
    if let Some(i) = rays.iter().position(|r| {
        !(r.origin.is_finite() && r.direction.is_finite()) || r.t_min.is_nan() || r.t_max.is_nan()
    }) {
        return Err(format!(
            "{}: ray {i} has a NaN or infinite origin or direction",
            path.display()
        ));
    }
    Ok(rays)
}

fn workspace_root() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    root.canonicalize().unwrap_or(root)
}

/// `$var` (relative to the workspace root), else the first default that exists, else
/// the first default (so the skip message names it).
fn path_from_env(var: &str, defaults: &[PathBuf]) -> PathBuf {
    match std::env::var_os(var) {
        Some(v) => workspace_root().join(v),
        None => defaults
            .iter()
            .find(|p| p.exists())
            .unwrap_or(&defaults[0])
            .clone(),
    }
}

fn list_from_env(var: &str, default: &str) -> Vec<String> {
    std::env::var(var)
        .unwrap_or_else(|_| default.to_string())
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect()
}

fn preset(name: &str) -> Option<BvhBuildParams> {
    Some(match name {
        "fastest" => BvhBuildParams::fastest_build(),
        "very_fast" => BvhBuildParams::very_fast_build(),
        "fast" => BvhBuildParams::fast_build(),
        "medium" => BvhBuildParams::medium_build(),
        "slow" => BvhBuildParams::slow_build(),
        "very_slow" => BvhBuildParams::very_slow_build(),
        _ => return None,
    })
}

fn fail(message: String) -> ! {
    eprintln!("error: {message}");
    std::process::exit(1);
}

fn skip(message: String) -> ! {
    println!("skipped: {message}");
    std::process::exit(0);
}

fn main() {
    // Configuration.
    let root = workspace_root();
    let mesh_path = path_from_env(
        "LIGHTPATH_BENCH_MESH",
        &[root.join("../shared/models/stanford-bunny/bunny.ply")],
    );
    let rays_dir = path_from_env(
        "LIGHTPATH_BENCH_RAYS",
        &[
            root.join("../shared/tools/embree-bench/out/rays_bunny"),
            PathBuf::from("/tmp/rays_bunny"),
        ],
    );
    // `cargo bench` passes `--bench`; without it (`cargo test --benches`) this is a quick
    // smoke run: one pass over a few rays of each set.
    let smoke = !std::env::args().any(|a| a == "--bench");
    let reps: usize = match std::env::var("LIGHTPATH_BENCH_REPS") {
        Ok(v) => match v.parse() {
            Ok(n) if n > 0 => n,
            _ => fail(format!(
                "LIGHTPATH_BENCH_REPS={v}: expected a positive integer"
            )),
        },
        Err(_) if smoke => 1,
        Err(_) => 5,
    };
    let kinds: Vec<(String, AccelKind)> = list_from_env("LIGHTPATH_BENCH_ACCELS", "bvh2,bvh4,bvh8")
        .into_iter()
        .map(|name| match AccelKind::from_name(&name) {
            Some(kind) => (name, kind),
            None => fail(format!(
                "LIGHTPATH_BENCH_ACCELS: unknown accelerator `{name}`; known: {}",
                AccelKind::NAMES.join(", ")
            )),
        })
        .collect();
    let layouts = list_from_env("LIGHTPATH_BENCH_OBVHS", "cwbvh");
    if let Some(bad) = layouts
        .iter()
        .find(|l| !matches!(l.as_str(), "cwbvh" | "bvh2"))
    {
        fail(format!(
            "LIGHTPATH_BENCH_OBVHS: unknown layout `{bad}`; known: cwbvh, bvh2"
        ));
    }
    let preset_name =
        std::env::var("LIGHTPATH_BENCH_OBVHS_PRESET").unwrap_or_else(|_| "medium".into());
    let params = preset(&preset_name).unwrap_or_else(|| {
        fail(format!(
            "LIGHTPATH_BENCH_OBVHS_PRESET={preset_name}: expected fastest, very_fast, fast, medium, slow or very_slow"
        ))
    });

    // Inputs; a fresh clone has neither, which is not an error.
    if !mesh_path.is_file() {
        skip(format!(
            "mesh {} not found (set LIGHTPATH_BENCH_MESH)",
            mesh_path.display()
        ));
    }
    let mut sets = Vec::new();
    for (name, occluded) in SETS {
        let path = rays_dir.join(format!("{name}.rays"));
        if path.is_file() {
            let mut rays = read_rays(&path).unwrap_or_else(|e| fail(e));
            if smoke && rays.len() > SMOKE_RAYS {
                // Every k-th ray, so the subset spans the whole set (the primary rays'
                // first tiles miss the mesh).
                let step = rays.len() / SMOKE_RAYS;
                rays = rays.into_iter().step_by(step).take(SMOKE_RAYS).collect();
            }
            sets.push((name, occluded, rays));
        }
    }
    if sets.is_empty() {
        skip(format!(
            "no primary/random/shadow/diffuse .rays in {} (set LIGHTPATH_BENCH_RAYS; make them with `embree-bench gen-rays MESH --outdir DIR`)",
            rays_dir.display()
        ));
    }
    let data = lightpath::io::load_mesh(&mesh_path)
        .unwrap_or_else(|e| fail(format!("{}: {e}", mesh_path.display())));
    let threads = rayon::current_num_threads();
    if smoke {
        println!(
            "smoke run (no --bench argument): {SMOKE_RAYS} rays per set, {reps} pass; `cargo bench` times properly"
        );
    }
    println!(
        "mesh {} ({} triangles), rays {} ({}), {reps} timed passes after a warm-up, MT = {threads} threads",
        mesh_path.display(),
        data.indices.len(),
        rays_dir.display(),
        sets.iter()
            .map(|(name, _, rays)| format!("{name} {}", rays.len()))
            .collect::<Vec<_>>()
            .join(", "),
    );

    // Build and trace, the peer first.
    let mut rows = Vec::new();
    for layout in &layouts {
        let name = format!("obvhs-{layout}-{preset_name}");
        eprintln!("  building {name}");
        if layout == "cwbvh" {
            let (build_ms, peer) = time_median(reps, || {
                Obvhs::build(&data, |t| {
                    obvhs::cwbvh::builder::build_cwbvh_from_tris(
                        t,
                        params,
                        &mut Duration::default(),
                    )
                })
            });
            rows.push(measure(name, true, build_ms, &peer, &sets, reps));
        } else {
            let (build_ms, peer) = time_median(reps, || {
                Obvhs::build(&data, |t| {
                    obvhs::bvh2::builder::build_bvh2_from_tris(t, params, &mut Duration::default())
                })
            });
            rows.push(measure(name, true, build_ms, &peer, &sets, reps));
        }
    }
    for (name, kind) in &kinds {
        eprintln!("  building {name}");
        let mut build_ms = Vec::new();
        let mut mesh = None;
        for i in 0..=reps {
            let copy = data.clone();
            let start = Instant::now();
            let m = TriangleMesh::new(copy, false, *kind)
                .unwrap_or_else(|e| fail(format!("{}: {e}", mesh_path.display())));
            if i > 0 {
                build_ms.push(start.elapsed().as_secs_f64() * 1e3);
            }
            mesh = Some(m);
        }
        let mesh = mesh.expect("built");
        rows.push(measure(
            format!("lightpath-{name}"),
            false,
            median(build_ms),
            &mesh,
            &sets,
            reps,
        ));
    }

    // Speed table (Mrays/s).
    println!();
    let mut header = "| accelerator | build ms |".to_string();
    let mut rule = "|---|---:|".to_string();
    for (set, ..) in &sets {
        header += &format!(" {set} ST / MT |");
        rule += "---:|";
    }
    println!("{header}\n{rule}");
    for row in &rows {
        let mut line = format!("| {} | {:.1} |", row.name, row.build_ms);
        for (st, mt, _) in &row.sets {
            line += &format!(" {st:.2} / {mt:.2} |");
        }
        println!("{line}");
    }
    let peer = rows.iter().find(|r| r.is_peer).expect("obvhs row");
    for row in rows.iter().filter(|r| !r.is_peer) {
        let mut line = format!(
            "| {} / {} | {:.2} |",
            row.name,
            peer.name,
            row.build_ms / peer.build_ms
        );
        for ((st, mt, _), (pst, pmt, _)) in row.sets.iter().zip(&peer.sets) {
            line += &format!(" {:.2} / {:.2} |", st / pst, mt / pmt);
        }
        println!("{line}");
    }
    println!(
        "(Mrays/s, median of {reps}; ratio rows: lightpath / obvhs, so a speed ratio above 1 means lightpath is faster and a build ratio above 1 means lightpath builds slower)"
    );

    // Correctness: hits and mean distance against the peer.
    println!();
    println!("| set | accelerator | hits | mean t | hits vs obvhs | mean t vs obvhs |");
    println!("|---|---|---:|---:|---:|---:|");
    let mut mismatches = 0;
    for (s, (set, occluded, _)) in sets.iter().enumerate() {
        let reference = peer.sets[s].2;
        for row in &rows {
            let tally = row.sets[s].2;
            let rel = |a: f64, b: f64| if b == 0.0 { a.abs() } else { (a - b) / b };
            let dh = rel(tally.hits as f64, reference.hits as f64);
            let dt = if *occluded {
                0.0
            } else {
                rel(tally.mean_t(), reference.mean_t())
            };
            let bad = dh.abs() > TOLERANCE || dt.abs() > TOLERANCE;
            mismatches += usize::from(bad);
            println!(
                "| {set} | {} | {} | {} | {:+.4}% | {} |{}",
                row.name,
                tally.hits,
                if *occluded {
                    "-".to_string()
                } else {
                    format!("{:.6}", tally.mean_t())
                },
                dh * 100.0,
                if *occluded {
                    "-".to_string()
                } else {
                    format!("{:+.4}%", dt * 100.0)
                },
                if bad { " MISMATCH" } else { "" }
            );
        }
    }
    if mismatches > 0 {
        let message = format!(
            "MISMATCH: {mismatches} result(s) differ from obvhs by more than {}% in hits or mean distance",
            TOLERANCE * 100.0
        );
        println!("\n{message}");
        eprintln!("{message}");
    } else {
        println!(
            "\nall accelerators agree with obvhs within {}% (hits, mean distance)",
            TOLERANCE * 100.0
        );
    }
}
