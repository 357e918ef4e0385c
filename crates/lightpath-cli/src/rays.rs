//! `lightpath rays MESH RAYS OUT`: traces a ray file against a mesh and writes the hits,
//! in the formats of `../shared/tools/embree-bench` so that Embree's answers and ours can
//! be compared ray by ray (`embree-bench compare RAYS EMBREE.hits OURS.hits`).
//!
//! - Ray file: 32-byte records of eight little-endian f32, `ox oy oz tmin dx dy dz tmax`.
//! - Hit file: 8-byte records, f32 `t` (in units of the ray's direction) then u32 triangle
//!   id; a miss is `t = +inf`, id `0xFFFFFFFF`.
//! - With `--occluded`: one byte per ray, 1 if anything blocks `[tmin, tmax]`.
//!
//! Triangle ids follow the mesh file (faces in order, polygons fan-triangulated), as
//! embree-bench numbers them.

use crate::fsutil;
use anyhow::{bail, Context, Result};
use lightpath::accel::{AccelKind, RayStats};
use lightpath::geometry::TriangleMesh;
use lightpath::math::{Ray, Vec3};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct RaysArgs {
    /// Triangle mesh (.ply or .obj).
    pub mesh: PathBuf,
    /// Ray file (32-byte records `ox oy oz tmin dx dy dz tmax`, f32 little-endian).
    pub rays: PathBuf,
    /// Output: hit file (8-byte records `t prim`), or occlusion bytes with --occluded.
    pub out: PathBuf,
    /// Any-hit (shadow) queries instead of closest hits.
    #[arg(long)]
    pub occluded: bool,
    /// Acceleration structure: list, bvh2, bvh4, bvh8 (default), bvh2-hq, bvh4-hq, bvh8-hq,
    /// bvh-course, grid, octree, kdtree, bsp.
    #[arg(long, default_value = "bvh8", value_parser = crate::names::ACCELS)]
    pub accel: String,
    /// Trace only the first N rays (e.g. for the brute-force list).
    #[arg(long)]
    pub limit: Option<usize>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(args: RaysArgs) -> Result<()> {
    if let Some(n) = args.threads {
        if n == 0 {
            bail!("--threads must be at least 1");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()?;
    }
    let kind = AccelKind::from_name(&args.accel).ok_or_else(|| {
        anyhow::anyhow!(
            "unknown --accel `{}`; known: {}",
            args.accel,
            AccelKind::NAMES.join(", ")
        )
    })?;
    let start = Instant::now();
    let data = lightpath::io::load_mesh(&args.mesh)?;
    let mesh = TriangleMesh::new(data, false, kind)
        .map_err(|m| anyhow::anyhow!("{}: {m}", args.mesh.display()))?;
    let build_s = start.elapsed().as_secs_f64();
    let mut rays = read_rays(&args.rays)?;
    if let Some(n) = args.limit {
        rays.truncate(n);
    }
    let trace_start = Instant::now();
    let out: Vec<u8> = if args.occluded {
        rays.par_iter()
            .map(|r| u8::from(mesh.occluded(r, &mut RayStats::default())))
            .collect()
    } else {
        rays.par_iter()
            .flat_map_iter(|r| {
                let (t, prim) = match mesh.intersect(r, &mut RayStats::default()) {
                    Some(h) => (h.t, h.prim),
                    None => (f32::INFINITY, u32::MAX),
                };
                let mut rec = [0u8; 8];
                rec[..4].copy_from_slice(&t.to_le_bytes());
                rec[4..].copy_from_slice(&prim.to_le_bytes());
                rec
            })
            .collect()
    };
    let trace_s = trace_start.elapsed().as_secs_f64();
    fsutil::write_atomic(&args.out, &out)?;
    if !args.quiet {
        let hits = if args.occluded {
            out.iter().filter(|&&b| b == 1).count()
        } else {
            out.chunks_exact(8)
                .filter(|r| f32::from_le_bytes(r[..4].try_into().unwrap()).is_finite())
                .count()
        };
        eprintln!(
            "{} rays, {hits} {}; build {:.3} s, trace {:.3} s ({:.2} Mrays/s, {} threads)",
            rays.len(),
            if args.occluded { "occluded" } else { "hits" },
            build_s,
            trace_s,
            rays.len() as f64 / trace_s.max(1e-9) / 1e6,
            rayon::current_num_threads()
        );
    }
    Ok(())
}

/// Reads an embree-bench ray file (32-byte records `ox oy oz tmin dx dy dz tmax`).
pub fn read_rays(path: &std::path::Path) -> Result<Vec<Ray>> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if bytes.len() % 32 != 0 {
        bail!(
            "{}: {} bytes is not a whole number of 32-byte ray records",
            path.display(),
            bytes.len()
        );
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
        bail!(
            "{}: ray {i} has a NaN or infinite origin or direction",
            path.display()
        );
    }
    Ok(rays)
}
