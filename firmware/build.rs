//! Puts the board's memory map where the linker finds it and links with cortex-m-rt's
//! `link.x` (for tests too: `rustc-link-arg`, not `-bins`, or test images have no vector
//! table).
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    // Each board's map is in firmware/boards/, put here as `board.x`, which the workspace's
    // top-level `memory.x` includes (cortex-m-rt's `link.x` includes `memory.x`). The linker
    // looks for an INCLUDE in its working directory (the workspace root, where cargo runs it)
    // before the search path, so the root `memory.x` names no board itself; a copy of it
    // here serves a build run from elsewhere.
    // The board: a feature names it; none is the emulated Cortex-M4F.
    let boards = [
        ("CARGO_FEATURE_BOARD_STM32F405", "stm32f405", false),
        ("CARGO_FEATURE_BOARD_MPS2_AN500", "mps2_an500", true),
        ("CARGO_FEATURE_BOARD_STM32H743", "stm32h743", false),
    ];
    let chosen: Vec<_> = boards.iter().filter(|(f, _, _)| env::var_os(f).is_some()).collect();
    assert!(chosen.len() <= 1, "one board feature at a time (board-stm32f405, board-mps2-an500, board-stm32h743)");
    let (name, emulated) = chosen.first().map_or(("mps2_an386", true), |(_, n, e)| (*n, *e));
    let map = manifest.join(format!("boards/{name}.x"));
    // `emulated`: a QEMU board, which has the benchmark mode and the semihosting sources
    // (one name for the code to test, rather than a list of the real boards' features).
    println!("cargo::rustc-check-cfg=cfg(emulated)");
    if emulated {
        println!("cargo:rustc-cfg=emulated");
    }
    let root_map = manifest.join("../memory.x");
    fs::copy(&map, out.join("board.x")).expect("copy the board's memory map");
    fs::copy(&root_map, out.join("memory.x")).expect("copy the top-level memory.x");
    println!("cargo:rerun-if-changed={}", root_map.display());
    println!("cargo:rustc-link-search={}", out.display());
    for (_, n, _) in boards.iter().chain([&("", "mps2_an386", true)]) {
        println!("cargo:rerun-if-changed={}", manifest.join(format!("boards/{n}.x")).display());
    }
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumb") {
        println!("cargo:rustc-link-arg=-Tlink.x");
        if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
            println!("cargo:rustc-link-arg=-Tdefmt.x");
        }
    }
}
