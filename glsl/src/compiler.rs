//! glslc, run once per shader of a folder.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::depfile;
use crate::error::{GlslError, Result};
use crate::shader::CompiledShader;
use crate::table;

/// The flags every Parallax kernel is compiled with: Vulkan 1.3 SPIR-V (what the backend's
/// devices run), optimised, with debug info (names in validation messages and profilers), and
/// warnings as errors.
const FLAGS: [&str; 4] = ["--target-env=vulkan1.3", "-O", "-g", "-Werror"];

/// Shader stages compiled from a folder, by file extension.
const STAGES: [&str; 3] = ["comp", "vert", "frag"];

/// A glslc to run: the one the `GLSLC` environment variable names, or `glslc` from `PATH`.
///
/// glslc (Debian package `glslc`) is used instead of the shaderc crate: Debian's libshaderc
/// does not link and building shaderc from source takes over ten minutes (shared/CRATES.md).
#[derive(Clone, Debug)]
pub struct Compiler {
    glslc: OsString,
}

impl Default for Compiler {
    fn default() -> Self {
        Self::new()
    }
}

impl Compiler {
    /// `$GLSLC`, else `glslc`.
    pub fn new() -> Self {
        Self::with_glslc(std::env::var_os("GLSLC").unwrap_or_else(|| "glslc".into()))
    }

    /// The compiler at `glslc` (a path, or a name looked up in `PATH`).
    pub fn with_glslc(glslc: impl Into<OsString>) -> Self {
        Self { glslc: glslc.into() }
    }

    /// Compiles `source` into `spirv`, writing glslc's depfile to `depfile`; `#include`s are
    /// searched in the source's folder, then in `include_dirs`. Returns the dependencies.
    pub fn compile_file(
        &self,
        source: &Path,
        include_dirs: &[&Path],
        spirv: &Path,
        depfile: &Path,
    ) -> Result<Vec<PathBuf>> {
        let mut command = Command::new(&self.glslc);
        command.args(FLAGS);
        for dir in include_dirs {
            command.arg(format!("-I{}", dir.display()));
        }
        command.args(["-MD", "-MF"]).arg(depfile).arg(source).arg("-o").arg(spirv);
        let output = command.output().map_err(|source| GlslError::MissingCompiler {
            glslc: self.glslc.to_string_lossy().into_owned(),
            source,
        })?;
        if !output.status.success() {
            return Err(GlslError::Compile {
                file: source.to_path_buf(),
                stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
            });
        }
        let text = std::fs::read_to_string(depfile)
            .map_err(|source| GlslError::Read { path: depfile.to_path_buf(), source })?;
        Ok(depfile::dependencies(&text))
    }

    /// Compiles every `*.comp`, `*.vert` and `*.frag` of `src_dir` (not its subfolders, which
    /// hold includes) into `out_dir`, in file-name order, and writes the table that embeds
    /// them, [`crate::TABLE_FILE`], into `out_dir`. Prints nothing: [`crate::compile_dir`] adds
    /// what cargo needs.
    pub fn compile_dir(&self, src_dir: &Path, include_dirs: &[&Path], out_dir: &Path) -> Result<Vec<CompiledShader>> {
        self.compile_dirs(&[src_dir], include_dirs, out_dir)
    }

    /// [`Self::compile_dir`] over several folders into one table, so one crate embeds kernels
    /// kept in several places (each example beside its code). Two shaders of one name in
    /// different folders are refused: a dispatch names a shader by its file stem alone.
    pub fn compile_dirs(
        &self,
        src_dirs: &[&Path],
        include_dirs: &[&Path],
        out_dir: &Path,
    ) -> Result<Vec<CompiledShader>> {
        let mut shaders: Vec<CompiledShader> = Vec::new();
        for src_dir in src_dirs {
            for shader in self.compile_sources(src_dir, include_dirs, out_dir)? {
                if let Some(first) = shaders.iter().find(|s| s.name == shader.name) {
                    return Err(GlslError::DuplicateName {
                        name: shader.name,
                        first: first.source.clone(),
                        second: shader.source,
                    });
                }
                shaders.push(shader);
            }
        }
        table::write(&shaders, &out_dir.join(crate::TABLE_FILE))?;
        Ok(shaders)
    }

    /// Compiles the shaders of one folder, without writing a table.
    fn compile_sources(&self, src_dir: &Path, include_dirs: &[&Path], out_dir: &Path) -> Result<Vec<CompiledShader>> {
        let entries =
            std::fs::read_dir(src_dir).map_err(|source| GlslError::Read { path: src_dir.to_path_buf(), source })?;
        let mut sources = Vec::new();
        for entry in entries {
            let path = entry.map_err(|source| GlslError::Read { path: src_dir.to_path_buf(), source })?.path();
            if path.is_file() && path.extension().is_some_and(|e| STAGES.iter().any(|s| e == *s)) {
                sources.push(path);
            }
        }
        sources.sort();
        let mut shaders = Vec::with_capacity(sources.len());
        for source in sources {
            let file =
                source.file_name().and_then(|f| f.to_str()).ok_or_else(|| GlslError::NonUtf8Name(source.clone()))?;
            let name = file.strip_suffix(".comp").unwrap_or(file).to_string();
            let spirv = out_dir.join(format!("{file}.spv"));
            let dependencies = self.compile_file(&source, include_dirs, &spirv, &out_dir.join(format!("{file}.d")))?;
            shaders.push(CompiledShader { name, source, spirv, dependencies });
        }
        Ok(shaders)
    }
}
