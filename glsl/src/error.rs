//! What can go wrong while compiling a folder of shaders; every message names the file and,
//! where a person can fix it, what to do.

use std::path::PathBuf;

/// Errors of [`crate::Compiler`].
#[derive(Debug, thiserror::Error)]
pub enum GlslError {
    /// `glslc` (or the program `GLSLC` names) could not be started.
    #[error(
        "cannot run `{glslc}` ({source}): the shader compiler is missing; install it with \
         `apt-get install glslc` (or point the GLSLC environment variable at one)"
    )]
    MissingCompiler { glslc: String, source: std::io::Error },

    /// glslc rejected a shader; `stderr` is its report (file, line, message).
    #[error("glslc failed on {}:\n{stderr}", .file.display())]
    Compile { file: PathBuf, stderr: String },

    /// A shader folder, a source or a depfile could not be read.
    #[error("cannot read {}: {source}", .path.display())]
    Read { path: PathBuf, source: std::io::Error },

    /// The embedded-shader table could not be written.
    #[error("cannot write {}: {source}", .path.display())]
    Write { path: PathBuf, source: std::io::Error },

    /// A shader whose file name is not UTF-8 cannot be named in the Rust table.
    #[error("shader file name {} is not UTF-8; rename it", .0.display())]
    NonUtf8Name(PathBuf),

    /// A shader's push-constant block cannot be written as a Rust struct (see `problem`).
    #[error("the push constants of {} cannot be bound from Rust: {problem}", .file.display())]
    Bindings { file: PathBuf, problem: String },

    /// Two folders compiled into one table hold shaders of one name.
    #[error("two shaders are named `{name}`: {} and {}; rename one", .first.display(), .second.display())]
    DuplicateName { name: String, first: PathBuf, second: PathBuf },
}

/// Shorthand used across the crate.
pub type Result<T> = std::result::Result<T, GlslError>;
