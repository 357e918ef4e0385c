//! Fuzzes the .ply loader: any input must give `Ok` or an `Err`, never a panic,
//! a hang or an allocation beyond libFuzzer's limit.
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = common::input_file("ply", data);
    let _ = lightpath::io::load_mesh(&path);
});
