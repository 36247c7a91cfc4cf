//! Compiles the GLSL of the `custom_pipeline` example (`examples/custom_pipeline/`) through
//! parallax-glsl, the way a crate outside this repository compiles its kernels; the example
//! (and its test) embed the table with `parallax_backend::include_shaders!()`.

use std::path::{Path, PathBuf};

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo"));
    let includes = [parallax_glsl::parallax_include_dir()];
    parallax_glsl::compile_dir_or_exit(Path::new("examples/custom_pipeline"), &includes, &out);
}
