//! Linker set-up for the thumb builds (nothing to do on the host): the memory map of the
//! machine the binary is for, `link.x` from cortex-m-rt, and `defmt.x` for the board.
//! Link arguments come from here rather than a `.cargo/config.toml` so that
//! `cargo build -p firmware --target …` links the same from any directory.

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let target = env::var("TARGET").unwrap_or_default();
    let board = env::var_os("CARGO_FEATURE_BOARD").is_some();
    let qemu = env::var_os("CARGO_FEATURE_QEMU").is_some();
    let mem = match (board, qemu, target.as_str()) {
        (true, false, "thumbv7em-none-eabihf") => "memory/stm32g474re.x",
        (false, true, "thumbv7em-none-eabihf") => "memory/mps2-an386.x",
        (false, true, "thumbv6m-none-eabi") => "memory/microbit.x",
        (true, true, _) => {
            panic!("features `board` and `qemu` are exclusive: build QEMU images with --no-default-features --features qemu")
        }
        (b, q, t) => panic!("no memory map for target {t} (board={b}, qemu={q})"),
    };
    let out = PathBuf::from(env::var("OUT_DIR").unwrap_or_default());
    if let Err(e) = fs::copy(mem, out.join("memory.x")) {
        panic!("copy {mem}: {e}");
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if board {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
