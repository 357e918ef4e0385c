//! `lightpath render --record-rays DIR`: the path tracer's own rays, as it traces them,
//! in the ray files of `../shared/tools/embree-bench` (32-byte records of eight
//! little-endian f32, `ox oy oz tmin dx dy dz tmax`), with the geometry they were
//! traced against, so that a tracer can be timed on a renderer's real workload:
//!
//! - `DIR/paths.rays`: the closest-hit queries (camera rays and bounces), batch after
//!   batch as the renderer traced them (in packets of sixteen, batches of up to 128);
//! - `DIR/shadow.rays`: the shadow rays (occlusion queries within `[tmin, tmax]`);
//! - `DIR/scene.obj`: the scene's triangles in render space, one merged mesh, in the
//!   order of the triangle ids the hits report.
//!
//! `lightpath bench DIR/scene.obj --rays DIR --packet` then times our queries on them.
//! With several threads the batches of different tiles interleave in the files.

use crate::fsutil;
use anyhow::{Context, Result};
use lightpath::math::{Ray, Vec3};
use lightpath::render::RayBatch;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One ray file being written: to a temporary file, renamed into place by
/// [`RayRecorder::finish`].
struct RayFile {
    path: PathBuf,
    temp: PathBuf,
    out: BufWriter<File>,
    rays: u64,
}

impl RayFile {
    fn create(path: PathBuf) -> Result<RayFile> {
        let temp = fsutil::temp_path(&path)?;
        let file = File::create(&temp).with_context(|| format!("creating {}", temp.display()))?;
        Ok(RayFile {
            path,
            temp,
            out: BufWriter::with_capacity(1 << 20, file),
            rays: 0,
        })
    }

    fn write(&mut self, rays: &[Ray]) -> std::io::Result<()> {
        let mut bytes = Vec::with_capacity(rays.len() * 32);
        for r in rays {
            let o = r.origin;
            let d = r.direction;
            for v in [o.x, o.y, o.z, r.t_min, d.x, d.y, d.z, r.t_max] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        self.rays += rays.len() as u64;
        self.out.write_all(&bytes)
    }
}

/// Writes the batches [`lightpath::render::RenderControl::ray_batches`] reports.
pub struct RayRecorder {
    files: Mutex<Recording>,
}

struct Recording {
    paths: RayFile,
    shadow: RayFile,
    /// The first write that failed (the callback cannot return it).
    error: Option<std::io::Error>,
}

/// What [`RayRecorder::finish`] wrote.
pub struct Recorded {
    pub path_rays: u64,
    pub shadow_rays: u64,
}

impl RayRecorder {
    /// Creates `dir` (and its parents) and writes the scene's triangles there; the ray
    /// files stay temporary until [`RayRecorder::finish`].
    pub fn new(dir: &Path, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<RayRecorder> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let mut obj = String::with_capacity(32 * (positions.len() + triangles.len()));
        obj.push_str("# lightpath render --record-rays: the scene's triangles in render space\n");
        for p in positions {
            obj.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
        }
        for t in triangles {
            obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
        }
        fsutil::write_atomic(&dir.join("scene.obj"), obj.as_bytes())?;
        Ok(RayRecorder {
            files: Mutex::new(Recording {
                paths: RayFile::create(dir.join("paths.rays"))?,
                shadow: RayFile::create(dir.join("shadow.rays"))?,
                error: None,
            }),
        })
    }

    /// Appends a batch to its file (called from the worker threads).
    pub fn record(&self, batch: RayBatch<'_>) {
        let mut files = self.files.lock().unwrap_or_else(|e| e.into_inner());
        if files.error.is_some() {
            return;
        }
        let file = if batch.shadow {
            &mut files.shadow
        } else {
            &mut files.paths
        };
        if let Err(e) = file.write(batch.rays) {
            files.error = Some(e);
        }
    }

    /// Removes the unfinished ray files (a render that failed).
    pub fn discard(self) {
        let files = self.files.into_inner().unwrap_or_else(|e| e.into_inner());
        for file in [files.paths, files.shadow] {
            drop(file.out);
            let _ = std::fs::remove_file(&file.temp);
        }
    }

    /// Flushes the files and renames them into place; on error removes them.
    pub fn finish(self) -> Result<Recorded> {
        let files = self.files.into_inner().unwrap_or_else(|e| e.into_inner());
        let Recording {
            paths,
            shadow,
            error,
        } = files;
        let counts = Recorded {
            path_rays: paths.rays,
            shadow_rays: shadow.rays,
        };
        let mut result = match error {
            Some(e) => Err(anyhow::Error::new(e).context("writing the recorded rays")),
            None => Ok(()),
        };
        let mut done = Vec::new();
        for file in [paths, shadow] {
            let RayFile {
                path, temp, out, ..
            } = file;
            if result.is_ok() {
                result = out
                    .into_inner()
                    .map_err(|e| e.into_error())
                    .and_then(|_| std::fs::rename(&temp, &path))
                    .with_context(|| format!("writing {}", path.display()));
                if result.is_ok() {
                    done.push(path);
                    continue;
                }
            } else {
                drop(out);
            }
            let _ = std::fs::remove_file(&temp);
        }
        if result.is_err() {
            for path in done {
                let _ = std::fs::remove_file(path);
            }
        }
        result.map(|()| counts)
    }
}
