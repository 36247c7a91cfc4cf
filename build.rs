//! Compiles the GLSL of the examples through parallax-glsl, the way a crate outside this
//! repository compiles its kernels: every shader beside an example (`examples/*.comp`, and in
//! an example's own folder such as `examples/custom_pipeline/`) goes into one table, so a new
//! example's kernel needs no edit here. The examples (and their tests) embed the table with
//! `parallax_backend::include_shaders!()`.

use std::path::{Path, PathBuf};

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo"));
    let includes = [parallax_glsl::parallax_include_dir()];
    let examples = Path::new("examples");
    let mut folders: Vec<PathBuf> = std::fs::read_dir(examples)
        .expect("examples/ is part of the package")
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.is_dir())
        .collect();
    folders.sort();
    folders.insert(0, examples.to_path_buf());
    let folders: Vec<&Path> = folders.iter().map(PathBuf::as_path).collect();
    parallax_glsl::compile_dirs_or_exit(&folders, &includes, &out);
}
