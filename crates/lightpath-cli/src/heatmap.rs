//! `lightpath bench --heatmap FILE.png`: the traversal cost of every primary ray (nodes
//! visited + primitives tested) drawn as an image with the viridis colour map, linear
//! from 0 to the largest cost, with a colour bar along the bottom.
//!
//! embree-bench writes the primary rays of a `W×H` camera image (default 1024×1024) in
//! 8×8 tiles, tiles row-major and pixels row-major inside a tile, top row first; the
//! rays are put back in place by that order. `W` is the ray count's square root unless
//! `--heatmap-width` gives it.

use anyhow::{bail, Result};
use lightpath::accel::RayStats;
use lightpath::film::Image;
use lightpath::geometry::TriangleMesh;
use lightpath::io::image::{srgb_to_linear, write_image};
use lightpath::math::{Ray, Vec3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Tile size of embree-bench's primary rays.
const TILE: usize = 8;
/// Height of the colour bar, in pixels.
const BAR: usize = 12;

/// Viridis at nine evenly spaced points (sRGB, 0–255).
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];

/// The viridis colour of `x` in [0, 1], as linear RGB.
pub fn viridis(x: f32) -> Vec3 {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let f = x * (VIRIDIS.len() - 1) as f32;
    let i = (f as usize).min(VIRIDIS.len() - 2);
    let w = f - i as f32;
    let c = |k: usize| Vec3::from_array(VIRIDIS[k].map(|v| v as f32 / 255.0));
    let srgb = c(i) * (1.0 - w) + c(i + 1) * w;
    Vec3::new(
        srgb_to_linear(srgb.x),
        srgb_to_linear(srgb.y),
        srgb_to_linear(srgb.z),
    )
}

/// `path`, or with several accelerators `path` with `-name` added to its stem.
pub fn path_for(path: &Path, name: &str, several: bool) -> PathBuf {
    if !several {
        return path.to_path_buf();
    }
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let ext = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    path.with_file_name(format!("{stem}-{name}{ext}"))
}

/// Pixel `(x, y)` of each ray, in embree-bench's tiled order.
fn pixel_order(width: usize, height: usize) -> Vec<(usize, usize)> {
    let mut order = Vec::with_capacity(width * height);
    for ty in (0..height).step_by(TILE) {
        for tx in (0..width).step_by(TILE) {
            for y in ty..(ty + TILE).min(height) {
                for x in tx..(tx + TILE).min(width) {
                    order.push((x, y));
                }
            }
        }
    }
    order
}

/// Traces the primary rays, writes the heat map atomically, and returns the largest
/// cost.
pub fn write(path: &Path, mesh: &TriangleMesh, rays: &[Ray], width: Option<usize>) -> Result<u32> {
    let width = match width {
        Some(w) => w,
        None => {
            let w = (rays.len() as f64).sqrt().round() as usize;
            if w * w != rays.len() {
                bail!(
                    "{} primary rays are not a square image; give its width with --heatmap-width",
                    rays.len()
                );
            }
            w
        }
    };
    if width == 0 || rays.is_empty() || rays.len() % width != 0 {
        bail!(
            "{} primary rays do not fill rows of --heatmap-width {width}",
            rays.len()
        );
    }
    let height = rays.len() / width;
    let cost: Vec<u32> = rays
        .par_iter()
        .map(|r| {
            let mut s = RayStats::default();
            mesh.intersect(r, &mut s);
            s.nodes_visited + s.prims_tested
        })
        .collect();
    let max = cost.iter().copied().max().unwrap_or(0);
    let scale = 1.0 / max.max(1) as f32;
    let mut image = Image::new(width as u32, (height + BAR) as u32);
    for (&(x, y), &c) in pixel_order(width, height).iter().zip(&cost) {
        image.set(x as u32, y as u32, viridis(c as f32 * scale));
    }
    // The colour bar: 0 at the left, the maximum at the right, a black line above.
    for x in 0..width {
        let colour = viridis(x as f32 / (width - 1).max(1) as f32);
        for y in height..height + BAR {
            let c = if y < height + 2 { Vec3::ZERO } else { colour };
            image.set(x as u32, y as u32, c);
        }
    }
    write_image(path, &image)?;
    Ok(max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiled_order_covers_every_pixel_once() {
        let order = pixel_order(20, 13);
        assert_eq!(order.len(), 260);
        assert_eq!(&order[..3], &[(0, 0), (1, 0), (2, 0)]);
        assert_eq!(order[8], (0, 1)); // the second row of the first tile
        assert_eq!(order[64], (8, 0)); // the second tile
        let mut seen = order.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), 260);
    }

    #[test]
    fn colour_map_runs_dark_to_bright() {
        let lum = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722));
        let mut last = -1.0;
        for i in 0..=20 {
            let l = lum(viridis(i as f32 / 20.0));
            assert!(l > last);
            last = l;
        }
        assert_eq!(
            path_for(Path::new("a/h.png"), "grid", true),
            PathBuf::from("a/h-grid.png")
        );
    }
}
