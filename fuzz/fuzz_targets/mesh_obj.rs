//! Fuzzes the OBJ loaders: the geometry-only mesh reader (`load_mesh`) and the OBJ scene
//! reader with its MTL materials (`load_scene`). An input holding a line `@@MTL@@` is
//! split there: what follows is written as `input.mtl` beside `input.obj`. Any input must
//! give `Ok` or an `Err`, never a panic, a hang or an allocation beyond libFuzzer's limit.
#![no_main]

mod common;

const SEPARATOR: &[u8] = b"\n@@MTL@@\n";

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = match data.windows(SEPARATOR.len()).position(|w| w == SEPARATOR) {
        Some(i) => (&data[..i], &data[i + SEPARATOR.len()..]),
        None => (data, &[][..]),
    };
    common::input_file("mtl", mtl);
    let path = common::input_file("obj", obj);
    let _ = lightpath::io::load_mesh(&path);
    let _ = lightpath::io::load_scene(&path, &lightpath::io::LoadOptions::default());
});
