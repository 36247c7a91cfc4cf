//! Compiles the pipeline's shaders, the top-level `shaders/*.{comp,vert,frag}` (GLSL 460,
//! `#include` from `shaders/` and the shared `shaders/include`), through parallax-glsl exactly
//! as a crate that brings its own kernels does; [`shader_library`](src/shaders.rs) embeds the
//! table with `parallax_backend::include_shaders!()`.

use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let shader_dir = manifest.join("..").join("shaders");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo"));
    parallax_glsl::compile_dir_or_exit(&shader_dir, &[parallax_glsl::parallax_include_dir()], &out);
}
