//! Fuzzes the glTF loader (`.gltf` JSON and `.glb` binary, chosen by the input's first
//! bytes): any input must give `Ok` or an `Err`, never a panic, a hang or an allocation
//! beyond libFuzzer's limit.
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let extension = if data.starts_with(b"glTF") { "glb" } else { "gltf" };
    let path = common::input_file(extension, data);
    let _ = lightpath::io::load_scene(&path, &lightpath::io::LoadOptions::default());
});
