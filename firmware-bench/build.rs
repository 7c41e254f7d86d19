//! Puts this bench's memory.x on the linker path, and an empty defmt.x: the workspace's
//! `.cargo/config.toml` links every thumbv7em binary with `-Tdefmt.x`, and the bench has no
//! defmt.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("memory.x beside Cargo.toml");
    fs::write(out.join("defmt.x"), "/* no defmt in the bench */\n").expect("write defmt.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
