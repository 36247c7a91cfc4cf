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
//! - the handler keeps the lock until the process ends, so no folder is created after it looked;
//! - a staging folder is removed where it is *now*: the run keeps it open, and the open folder
//!   says its current path, so a user who moves the output folder mid-run finds no
//!   `.parallax-XXXXXX/` left in it.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use anyhow::Result;

/// One staging folder: where it was made, the open folder, and how many staged outputs it holds
/// (it is removed with its last).
struct Staging {
    path: PathBuf,
    handle: Option<std::fs::File>,
    outputs: usize,
}

impl Staging {
    /// Where the folder is now: its path when it was made, unless the folder (or one above it)
    /// was moved since, which the open folder tells (Linux's /proc/self/fd).
    fn current_path(&self) -> PathBuf {
        #[cfg(target_os = "linux")]
        if let Some(handle) = &self.handle {
            use std::os::fd::AsRawFd;
            if let Ok(now) = std::fs::read_link(format!("/proc/self/fd/{}", handle.as_raw_fd()))
                && now.is_dir()
            {
                return now;
            }
        }
        self.path.clone()
    }

    /// Removes the folder and what it holds, wherever it is now.
    fn remove(&self) -> std::io::Result<()> {
        std::fs::remove_dir_all(self.current_path())
    }
}

#[derive(Default)]
pub struct Pending {
    staging: Vec<Staging>,
    /// Folders this run created, outermost first, until [`keep_folders`].
    created: Vec<PathBuf>,
}

static PENDING: Mutex<Pending> = Mutex::new(Pending { staging: Vec::new(), created: Vec::new() });

fn pending() -> MutexGuard<'static, Pending> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// A staging folder inside `folder` for one more staged output: created with the first one.
/// The error says why not: the folder is not writable, or it is gone (moved during the run).
pub fn staging_folder(folder: &Path) -> Result<PathBuf> {
    let mut pending = pending();
    if let Some(staging) = pending.staging.iter_mut().find(|s| s.path.parent() == Some(folder)) {
        staging.outputs += 1;
        return Ok(staging.path.clone());
    }
    let dir = match tempfile::Builder::new().prefix(".parallax-").tempdir_in(folder) {
        Ok(dir) => dir.keep(),
        Err(e) if folder.is_dir() => {
            anyhow::bail!(
                "folder {} is not writable: {}",
                folder.display(),
                parallax_accuracy::write_failure(folder, &e)
            )
        }
        Err(e) => anyhow::bail!(parallax_accuracy::write_failure(folder, &e)),
    };
    let handle = std::fs::File::open(&dir).ok();
    pending.staging.push(Staging { path: dir.clone(), handle, outputs: 1 });
    Ok(dir)
}

/// One staged output of `dir` is in place or dropped: the folder goes with its last one.
pub fn release_staging(dir: &Path) {
    let mut pending = pending();
    if let Some(i) = pending.staging.iter().position(|s| s.path == dir) {
        pending.staging[i].outputs -= 1;
        if pending.staging[i].outputs == 0 {
            let _ = pending.staging[i].remove();
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

/// Creates `folder` in its parent, which must exist (NotFound if it does not, e.g. moved
/// meanwhile), remembered as [`create_folder`] does; an existing folder is kept as it is.
pub fn create_subfolder(folder: &Path) -> std::io::Result<()> {
    let mut pending = pending();
    if folder.is_dir() {
        return Ok(());
    }
    pending.created.push(folder.to_path_buf());
    std::fs::create_dir(folder)
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
    for staging in &pending.staging {
        // A writer may create a file between the listing and the removal of its folder: retry
        // until the folder is gone (once it is, no file can be created in it).
        for _ in 0..100 {
            match staging.remove() {
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

    /// The output folder moved while an output was staged: the staging folder is removed
    /// where it now is, and a new one is refused naming the cause.
    #[test]
    fn a_staging_folder_is_removed_from_a_folder_that_moved() {
        let dir = tempfile::tempdir().unwrap();
        let (out, moved) = (dir.path().join("out"), dir.path().join("moved"));
        std::fs::create_dir(&out).unwrap();
        let staging = staging_folder(&out).unwrap();
        std::fs::rename(&out, &moved).unwrap();
        let err = staging_folder(&dir.path().join("gone")).unwrap_err().to_string();
        assert!(err.ends_with("gone no longer exists: it was moved or removed while the run went on; leave the output folder in place until the run ends"), "{err}");
        release_staging(&staging);
        assert_eq!(std::fs::read_dir(&moved).unwrap().count(), 0, "the staging folder went with the moved folder");
    }
}
