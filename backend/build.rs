//! Compiles every `shaders/*.{comp,vert,frag}` (GLSL 460, `#include` from `shaders/include`) to
//! SPIR-V with glslc (through parallax-glsl, which user crates use the same way) and writes
//! `shaders.rs` into OUT_DIR, which embeds them by name.

use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let shader_dir = manifest.join("..").join("shaders");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo"));
    parallax_glsl::compile_dir_or_exit(&shader_dir, &[&shader_dir.join("include")], &out);
}
