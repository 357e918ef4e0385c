//! Sets `lightpath_avx512` where the compiler has the AVX-512 intrinsics (stable since
//! Rust 1.89): the packet queries use them. Older compilers (down to the MSRV, e.g.
//! Debian's packaged rustc) build without them, and the packet queries go ray by ray.

use std::process::Command;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(lightpath_avx512)");
    println!("cargo::rerun-if-changed=build.rs");
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let minor = Command::new(rustc)
        .arg("--version")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|v| {
            // "rustc 1.95.0 (59807616e 2026-04-14)"
            let version = v.split_whitespace().nth(1)?;
            let mut parts = version.split('.');
            let major: u32 = parts.next()?.parse().ok()?;
            let minor: u32 = parts.next()?.parse().ok()?;
            (major == 1).then_some(minor)
        });
    if minor.is_some_and(|m| m >= 89) {
        println!("cargo::rustc-cfg=lightpath_avx512");
    }
}
