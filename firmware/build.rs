//! Puts the board's memory map where the linker finds it and links with cortex-m-rt's
//! `link.x` (for tests too: `rustc-link-arg`, not `-bins`, or test images have no vector
//! table).
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    // Each board's map is in firmware/boards/, copied here as the `memory.x` that
    // cortex-m-rt's `link.x` includes. No `memory.x` may lie in the workspace root: cargo runs
    // the linker there, and the linker looks for an INCLUDE in its working directory before
    // the search path, so a root `memory.x` would be every board's map (the STM32F405 image
    // was linked at 0x0 that way until `boards/mps2_an386.x` moved out of the root).
    let map = if env::var_os("CARGO_FEATURE_BOARD_STM32F405").is_some() {
        manifest.join("boards/stm32f405.x")
    } else {
        manifest.join("boards/mps2_an386.x")
    };
    fs::copy(&map, out.join("memory.x")).expect("copy the memory map");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", map.display());
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumb") {
        println!("cargo:rustc-link-arg=-Tlink.x");
        if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
            println!("cargo:rustc-link-arg=-Tdefmt.x");
        }
    }
}
