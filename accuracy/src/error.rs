//! Errors of the accuracy tools. Every variant names the input it is about and what to do.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum AccuracyError {
    #[error("cannot read {path}: {detail}")]
    Read { path: PathBuf, detail: String },
    #[error("cannot write {path}: {detail} (check the folder exists and is writable)")]
    Write { path: PathBuf, detail: String },
    #[error("{a} is {aw}x{ah} but {b} is {bw}x{bh}: compare images of the same size")]
    SizeMismatch { a: String, aw: usize, ah: usize, b: String, bw: usize, bh: usize },
    #[error(
        "{name}: {count} pixel(s) with a non-finite channel (NaN or infinity), first at ({x}, {y}); \
         metrics over them would be meaningless: fix the renderer or the file"
    )]
    NonFinite { name: String, count: usize, x: usize, y: usize },
    #[error(
        "{total} pixel(s) with a non-finite channel (NaN or infinity) in {report}; metrics over them \
         would be meaningless: fix the renderer or the files"
    )]
    NonFiniteViews {
        total: usize,
        /// Per image: `path: N pixel(s), first at (x, y)`, `; `-separated.
        report: String,
    },
    #[error("views missing from {folder}: {missing} (both folders need the same view_NNN.exr files)")]
    MissingViews { folder: PathBuf, missing: String },
    #[error("{path}: {detail}")]
    BadInput { path: PathBuf, detail: String },
    #[error(
        "the partial reference in {path} was made with other settings: {differences}; run again with \
         the partial's settings, or use another --out-dir (or delete {path}) to start over"
    )]
    SettingsDiffer {
        path: PathBuf,
        /// Every flag that differs, as `--flag stored (this run: --flag given)`, `; `-separated.
        differences: String,
    },
    /// Not a regular file, too large, a symlink loop.
    #[error(transparent)]
    Input(#[from] parallax_scene::input::InputError),
    #[error("chart: {0}")]
    Chart(String),
}

pub type Result<T> = std::result::Result<T, AccuracyError>;
