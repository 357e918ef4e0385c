//! Shared by the fuzz targets: each input is written to a file with the loader's
//! extension in a per-process folder, so the real entry points (`load_scene`,
//! `load_mesh`) run exactly as the CLI runs them.

use std::path::PathBuf;

pub fn input_file(extension: &str, data: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightpath-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(format!("input.{extension}"));
    std::fs::write(&path, data).expect("write input");
    path
}
