//! Compiles the test kernels of `shaders/` (with `shaders/include` and Parallax's shared
//! includes) through parallax-glsl, the way any crate that brings its own kernels does.

use std::path::{Path, PathBuf};

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo"));
    let includes = [Path::new("shaders/include"), parallax_glsl::parallax_include_dir()];
    parallax_glsl::compile_dir_or_exit(Path::new("shaders"), &includes, &out);
}
