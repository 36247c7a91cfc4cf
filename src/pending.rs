//! What an interrupted or failed run must remove: the staging folders that hold outputs not yet
//! in place, and the folders the run created that hold nothing of a finished run yet.
//!
//! Ctrl-C, SIGTERM and SIGHUP end the process from the handler's thread while the main thread
//! goes on writing, so every step here is safe against that race:
//! - a folder is registered *before* it is created, under the lock the handler takes, so the
//!   handler never misses one;
//! - temporary files live in a per-folder staging folder (`.parallax-XXXXXX/`), not beside the
//!   target: writers open their file by path, and a file reopened after the handler removed it
//!   would outlive the run, while a file in a staging folder that is gone cannot be created;
//! - the handler keeps the lock until the process ends, so no folder is created after it looked.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use anyhow::{Context, Result};

#[derive(Default)]
pub struct Pending {
    /// Staging folders and how many staged outputs each holds; one is removed with its last.
    staging: Vec<(PathBuf, usize)>,
    /// Folders this run created, outermost first, until [`keep_folders`].
    created: Vec<PathBuf>,
}

static PENDING: Mutex<Pending> = Mutex::new(Pending { staging: Vec::new(), created: Vec::new() });

fn pending() -> MutexGuard<'static, Pending> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// A staging folder inside `folder` for one more staged output: created with the first one.
pub fn staging_folder(folder: &Path) -> Result<PathBuf> {
    let mut pending = pending();
    if let Some((dir, count)) = pending.staging.iter_mut().find(|(dir, _)| dir.parent() == Some(folder)) {
        *count += 1;
        return Ok(dir.clone());
    }
    let dir = tempfile::Builder::new()
        .prefix(".parallax-")
        .tempdir_in(folder)
        .with_context(|| format!("folder {} is not writable", folder.display()))?
        .keep();
    pending.staging.push((dir.clone(), 1));
    Ok(dir)
}

/// One staged output of `dir` is in place or dropped: the folder goes with its last one.
pub fn release_staging(dir: &Path) {
    let mut pending = pending();
    if let Some(i) = pending.staging.iter().position(|(d, _)| d == dir) {
        pending.staging[i].1 -= 1;
        if pending.staging[i].1 == 0 {
            let _ = std::fs::remove_dir_all(dir);
            pending.staging.swap_remove(i);
        }
    }
}

/// Creates `folder` and its missing parents, remembering the ones it creates so that an
/// interrupted or failed run removes them again (see [`remove_all`]) until [`keep_folders`].
pub fn create_folder(folder: &Path) -> std::io::Result<()> {
    let mut pending = pending();
    let missing: Vec<PathBuf> =
        folder.ancestors().take_while(|a| !a.as_os_str().is_empty() && !a.exists()).map(Path::to_path_buf).collect();
    pending.created.extend(missing.into_iter().rev());
    std::fs::create_dir_all(folder)
}

/// The run's outputs are in place: the folders it created stay.
pub fn keep_folders() {
    pending().created.clear();
}

/// Removes every staging folder with what it holds, then every folder this run created that is
/// still empty, innermost first; returns the lock so that the caller can end the process while
/// holding it (nothing is created after this looked).
pub fn remove_all() -> MutexGuard<'static, Pending> {
    let pending = pending();
    for (dir, _) in &pending.staging {
        // A writer may create a file between the listing and the removal of its folder: retry
        // until the folder is gone (once it is, no file can be created in it).
        for _ in 0..100 {
            match std::fs::remove_dir_all(dir) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => continue,
                _ => break,
            }
        }
    }
    for folder in pending.created.iter().rev() {
        // Fails on a folder that is not empty: only what this run left empty goes.
        let _ = std::fs::remove_dir(folder);
    }
    pending
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_staging_folder_lives_while_it_holds_an_output() {
        let dir = tempfile::tempdir().unwrap();
        let first = staging_folder(dir.path()).unwrap();
        let second = staging_folder(dir.path()).unwrap();
        assert_eq!(first, second, "one staging folder per output folder");
        assert!(first.file_name().unwrap().to_string_lossy().starts_with(".parallax-"));
        release_staging(&first);
        assert!(first.is_dir(), "kept while an output is still staged");
        release_staging(&first);
        assert!(!first.exists(), "removed with its last output");
    }
}
