//! Puts the memory map of the board the target runs on onto the linker's search path as
//! `memory.x` (cortex-m-rt's link.x includes it): `memory/mps2-an386.x` for the Cortex-M4F
//! (thumbv7em-none-eabihf, the default), `memory/microbit.x` for the Cortex-M0
//! (thumbv6m-none-eabi, on-target tests without an FPU). The maps live in `memory/` rather
//! than as `memory.x` in this directory because the linker would find that one first, for
//! every target.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let target = env::var("TARGET").unwrap_or_default();
    let map = if target.starts_with("thumbv6m") {
        "memory/microbit.x"
    } else {
        "memory/mps2-an386.x"
    };
    fs::copy(map, out.join("memory.x")).expect("memory map in memory/");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory");
    println!("cargo:rerun-if-changed=build.rs");
}
