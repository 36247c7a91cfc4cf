//! A shader compiled by glslc: its name in the embedded table, its source, SPIR-V and dependencies.

use std::path::PathBuf;

/// One shader compiled by [`crate::Compiler::compile_dir`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CompiledShader {
    /// Name in the embedded table: the file stem of a compute shader (`fill` for `fill.comp`),
    /// the file name of a graphics stage (`raster.vert`), so that a pass's vertex and fragment
    /// shaders can share a stem.
    pub name: String,
    pub source: PathBuf,
    /// The SPIR-V file written into the output folder.
    pub spirv: PathBuf,
    /// Every file the shader was built from, as glslc reports it: the source and each
    /// `#include`d file.
    pub dependencies: Vec<PathBuf>,
}
