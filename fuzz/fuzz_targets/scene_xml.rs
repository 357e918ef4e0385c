//! Fuzzes the .xml loader: any input must give `Ok` or an `Err`, never a panic,
//! a hang or an allocation beyond libFuzzer's limit.
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = common::input_file("xml", data);
    let _ = lightpath::io::load_scene(&path, &lightpath::io::LoadOptions::default());
});
