//! Compiles the backend's own shaders, `backend/shaders/*.comp` (GLSL 460, `#include` from
//! Parallax's shared `shaders/include`), through parallax-glsl as any crate that brings its own
//! kernels does, and writes their table into OUT_DIR: the shaders the backend itself dispatches
//! (its benchmark's), which every `ShaderLibrary` falls back to. The pipeline's shaders, in
//! the top-level `shaders/`, are the passes crate's.

use std::path::{Path, PathBuf};

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo"));
    parallax_glsl::compile_dir_or_exit(Path::new("shaders"), &[parallax_glsl::parallax_include_dir()], &out);
}
