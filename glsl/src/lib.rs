//! parallax-glsl: compiles a folder of GLSL kernels with glslc from a build script, for
//! Parallax's own (the passes' `shaders/`, the backend's and testkit's few) and for crates that
//! bring their own kernels.
//!
//! In the `build.rs` of a crate with its kernels in `shaders/` (GLSL 460, `#include`):
//!
//! ```no_run
//! use std::path::{Path, PathBuf};
//!
//! let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
//! let includes = [Path::new("shaders/include"), parallax_glsl::parallax_include_dir()];
//! parallax_glsl::compile_dir_or_exit(Path::new("shaders"), &includes, &out);
//! ```
//!
//! and at run time `parallax_backend::include_shaders!()?` turns the table into a
//! `ShaderLibrary` for `ExecOptions::shaders`, while `parallax_backend::shader_bindings!()`
//! declares, from the same SPIR-V, each push-constant block as a Rust struct and each shader
//! as a typed id (`pub const FILL: Shader<FillPush>`), so a block is written once, in GLSL. Each shader is compiled for Vulkan 1.3 with
//! `-O -g -Werror`; `GLSLC` overrides which glslc runs.

mod bindings;
mod compiler;
mod depfile;
mod error;
pub mod reflect;
mod shader;
mod table;

use std::path::Path;

pub use compiler::Compiler;
pub use error::{GlslError, Result};
pub use shader::CompiledShader;

/// File name of the embedded-shader table that [`Compiler::compile_dir`] writes into its output
/// folder: `pub const EMBEDDED: &[(&str, &[u8])]`, shader name → SPIR-V bytes.
pub const TABLE_FILE: &str = "shaders.rs";

/// File name of the shader bindings [`compile_dir`] (a build script's call) writes beside the
/// table: a
/// `#[repr(C)]` struct per push-constant block and a typed id per shader, generated from the
/// SPIR-V (`parallax_backend::shader_bindings!()` includes it).
pub const BINDINGS_FILE: &str = "shader_bindings.rs";

/// The folder of Parallax's shared includes (`bindless.glsl`: the descriptor set and push
/// constants every kernel sees). It is found beside this crate's sources, which a path or git
/// dependency on the Parallax repository provides.
pub fn parallax_include_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shaders/include"))
}

/// For a build script: [`Compiler::compile_dir`] with the compiler of [`Compiler::new`], the
/// shader bindings ([`BINDINGS_FILE`]) written from the SPIR-V, and what cargo needs to run the
/// build script again when a shader changes: `rerun-if-changed` for the folders (a new
/// shader), every source and every `#include`d file, and `rerun-if-env-changed=GLSLC`.
pub fn compile_dir(src_dir: &Path, include_dirs: &[&Path], out_dir: &Path) -> Result<Vec<CompiledShader>> {
    compile_dirs(&[src_dir], include_dirs, out_dir)
}

/// [`compile_dir`] over several folders into one table ([`Compiler::compile_dirs`]).
pub fn compile_dirs(src_dirs: &[&Path], include_dirs: &[&Path], out_dir: &Path) -> Result<Vec<CompiledShader>> {
    println!("cargo:rerun-if-env-changed=GLSLC");
    for dir in src_dirs.iter().chain(include_dirs) {
        println!("cargo:rerun-if-changed={}", dir.display());
    }
    let shaders = Compiler::new().compile_dirs(src_dirs, include_dirs, out_dir)?;
    bindings::write(&shaders, &out_dir.join(BINDINGS_FILE))?;
    for dependency in shaders.iter().flat_map(|s| &s.dependencies) {
        println!("cargo:rerun-if-changed={}", dependency.display());
    }
    Ok(shaders)
}

/// [`compile_dirs`] for a build script's `main`, failing as [`compile_dir_or_exit`] does.
pub fn compile_dirs_or_exit(src_dirs: &[&Path], include_dirs: &[&Path], out_dir: &Path) -> Vec<CompiledShader> {
    compile_dirs(src_dirs, include_dirs, out_dir).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    })
}

/// [`compile_dir`] for a build script's `main`: on failure prints the error (glslc's report,
/// or how to install glslc) and exits with status 1, which cargo shows as the build script's
/// failure without a panic backtrace.
pub fn compile_dir_or_exit(src_dir: &Path, include_dirs: &[&Path], out_dir: &Path) -> Vec<CompiledShader> {
    compile_dir(src_dir, include_dirs, out_dir).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    })
}
