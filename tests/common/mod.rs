//! Helpers shared by the CLI integration tests.

use std::path::{Path, PathBuf};

/// A fresh, empty directory for one test, removed again when the test is done with it.
pub struct ScratchDir(PathBuf);

impl std::ops::Deref for ScratchDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `$TMPDIR/parallax-<test file>-<pid>-<name>`, emptied.
pub fn scratch(test: &str, name: &str) -> ScratchDir {
    let dir = std::env::temp_dir().join(format!("parallax-{test}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    ScratchDir(dir)
}
