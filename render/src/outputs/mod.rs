//! Output files a user can trust: every path is checked before any work starts, every file is
//! written whole or not at all, and nothing that is not a regular file is ever replaced.
//!
//! - [`Sink`]: `-` is stdout, anything else a path.
//! - [`check`]: the folder exists and is writable, the extension matches the format, no two
//!   outputs share a path, the target is not a folder.
//! - [`stage`] then [`Staged::commit`]: the bytes go to a temporary file in a staging folder
//!   inside the target's folder (see [`crate::outputs::pending`]) and are renamed over the target, so a reader (or a full disk, or Ctrl-C) never leaves a
//!   truncated file and a failed run keeps the previous good one. A target that exists and is
//!   not a regular file (a device such as /dev/null, a FIFO) is written through instead; a
//!   symlink is followed and its target replaced, the link kept.

pub mod budget;
pub mod disk;
pub mod host;
pub mod pending;
pub mod resident;

use std::ffi::OsStr;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use parallax_accuracy::{folder_gone, write_failure};
use tempfile::NamedTempFile;

/// Where an output goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Sink {
    Stdout,
    File(PathBuf),
}

/// The format of an output, which its file name must say.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Exr,
    Png,
    Json,
    Dot,
    Html,
    Markdown,
}

impl Format {
    fn extensions(self) -> &'static [&'static str] {
        match self {
            Format::Exr => &["exr"],
            Format::Png => &["png"],
            Format::Json => &["json"],
            Format::Dot => &["dot", "gv"],
            Format::Html => &["html"],
            Format::Markdown => &["md", "markdown"],
        }
    }
}

/// One output of a command: the flag that named it, where it goes and what it holds.
pub struct Output<'a> {
    pub flag: &'a str,
    pub sink: &'a Sink,
    pub format: Format,
}

/// Checks every output before any work: a problem found after minutes of tracing would waste
/// them. Only image outputs cannot go to stdout.
pub fn check(outputs: &[Output]) -> Result<()> {
    check_creating(outputs, None)
}

/// [`check`] for a command that creates the folder `created` before it writes (`render
/// --out-dir tr --trace tr/trace.json`): an output in that folder needs no folder yet; the
/// command checks that it can create it.
pub fn check_creating(outputs: &[Output], created: Option<&Path>) -> Result<()> {
    let mut seen: Vec<(PathBuf, &str)> = Vec::new();
    for o in outputs {
        let Sink::File(path) = o.sink else {
            if matches!(o.format, Format::Exr | Format::Png) {
                bail!("{} -: images cannot be written to stdout; give a file name", o.flag);
            }
            if let Some((_, other)) = seen.iter().find(|(p, _)| p.as_os_str() == "-") {
                return Err(crate::error::UsageError(format!(
                    "{} and {other} both write to stdout: send one of them to a file",
                    o.flag
                ))
                .into());
            }
            seen.push((PathBuf::from("-"), o.flag));
            continue;
        };
        let shown = path.display();
        check_name(o.flag, path)?;
        let meta = std::fs::metadata(path);
        // ELOOP: the OS's "too many levels of symbolic links".
        if meta.as_ref().is_err_and(|e| e.raw_os_error() == Some(40)) {
            bail!("{} {shown} is a symlink loop (or a chain of more than 40 links): fix the links", o.flag);
        }
        let meta = meta.ok();
        if meta.is_none() && std::fs::symlink_metadata(path).is_ok() {
            bail!("{} {shown} is a symlink to a missing file: remove it or fix it", o.flag);
        }
        if meta.as_ref().is_some_and(|m| m.is_dir()) {
            bail!("{} {shown} is a folder; give a file name such as {shown}/out.{}", o.flag, o.format.extensions()[0]);
        }
        let special = meta.as_ref().is_some_and(|m| !m.is_file());
        // Devices and FIFOs (/dev/null, a pipe) carry no extension and are written through.
        if !special {
            let ext = path.extension().and_then(OsStr::to_str).map(str::to_ascii_lowercase);
            if !ext.as_deref().is_some_and(|e| o.format.extensions().contains(&e)) {
                bail!(
                    "{} {shown}: the file name must end in .{} (it is written as {:?})",
                    o.flag,
                    o.format.extensions().join(" or ."),
                    o.format
                );
            }
            let folder = folder_of(path);
            // A folder the run makes holds nothing to look at yet: the command checked the
            // nearest existing folder above it.
            let made_by_the_run = created.is_some_and(|c| c == folder) && !folder.exists();
            if !made_by_the_run {
                if !folder.is_dir() {
                    bail!("{} {shown}: folder {} does not exist; create it first", o.flag, folder.display());
                }
                if let Err(e) = NamedTempFile::new_in(&folder) {
                    bail!(
                        "{} {shown}: folder {} is not writable: {}",
                        o.flag,
                        folder.display(),
                        write_failure(&folder, &e)
                    );
                }
            }
        }
        let key = identity(path);
        if let Some((_, other)) = seen.iter().find(|(p, _)| *p == key) {
            bail!("{} and {other} both write {shown}: give each output its own path", o.flag);
        }
        seen.push((key, o.flag));
    }
    Ok(())
}

/// Refuses an output that is one of the command's inputs (`render --scene s.json --trace
/// s.json`, `compare a.exr b.exr --json a.exr`), or two outputs on one path: compared as
/// canonical paths, so `./x/../a.exr` is `a.exr` and a symlink is its target. Called before any
/// work, after [`check`].
pub fn check_inputs(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> Result<()> {
    for (k, (flag, out)) in outputs.iter().enumerate() {
        let key = identity(out);
        if let Some((input_flag, input)) = inputs.iter().find(|(_, input)| identity(input) == key) {
            bail!(
                "{flag} {} is also read, as {input_flag} {}: writing it would destroy an input; give the output another path",
                out.display(),
                input.display()
            );
        }
        if let Some((other, _)) = outputs[..k].iter().find(|(_, o)| identity(o) == key) {
            bail!("{flag} and {other} both write {}: give each output its own path", out.display());
        }
    }
    Ok(())
}

/// The longest file name (bytes) and path most file systems take (Linux's NAME_MAX, PATH_MAX).
const NAME_MAX: usize = 255;
const PATH_MAX: usize = 4095;

/// A path that names a file: no trailing `/` (which names a folder, so `--out x.exr/` would fail
/// only after the work), a name and a path the file system can hold.
fn check_name(flag: &str, path: &Path) -> Result<()> {
    let shown = path.display();
    let text = path.as_os_str().as_encoded_bytes();
    if text.ends_with(b"/") || path.file_name().is_none() {
        bail!("{flag} {shown} ends in '/' or '..', which names a folder: give a file name");
    }
    let name = path.file_name().map_or(0, |n| n.len());
    if name > NAME_MAX {
        bail!(
            "{flag} {shown}: the file name is {name} bytes, more than the {NAME_MAX} a file system takes: shorten it"
        );
    }
    if text.len() > PATH_MAX {
        bail!("{flag}: the path is {} bytes, more than the {PATH_MAX} a file system takes: shorten it", text.len());
    }
    Ok(())
}

/// Refuses a path in `folder` that a run will write (`names`) but that is a folder or another
/// non-file (a folder named `view_000.exr` used to be found only when the views were renamed
/// into place, after all the tracing).
pub fn check_targets_in(folder: &Path, names: impl IntoIterator<Item = String>, flag: &str) -> Result<()> {
    for name in names {
        let path = folder.join(&name);
        if std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_dir()) {
            bail!(
                "{flag} {}: {name} there is a folder, and the run writes a file of that name: move it",
                folder.display()
            );
        }
    }
    Ok(())
}

/// The folder a file path lives in (`.` for a bare name).
fn folder_of(path: &Path) -> PathBuf {
    path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new(".")).to_path_buf()
}

/// A path's identity for duplicate checks: the canonical folder and the file name, or the
/// canonical target of an existing file (so `a.json` and `./x/../a.json` are one path).
fn identity(path: &Path) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(path) {
        return p;
    }
    let folder = std::fs::canonicalize(folder_of(path)).unwrap_or_else(|_| folder_of(path));
    folder.join(path.file_name().unwrap_or_default())
}

pub use crate::outputs::pending::{create_folder, create_subfolder, keep_folders};

/// An advisory lock on an output folder a run owns, held until dropped: a second run into the
/// same folder is refused instead of silently mixing its files with the first's. The lock is
/// on the folder itself (flock), so no lock file is left behind, and the OS drops it when the
/// process ends, however it ends.
pub struct FolderLock(#[allow(dead_code)] std::fs::File);

/// Locks `folder` (which exists) for this run, or says which flag names a folder in use.
pub fn lock_folder(folder: &Path, flag: &str) -> Result<FolderLock> {
    use std::os::fd::AsRawFd;
    let shown = folder.display();
    let handle = std::fs::File::open(folder).with_context(|| format!("{flag} {shown}: cannot open the folder"))?;
    // flock(2) rather than std's File::try_lock, which needs Rust 1.89 (the MSRV is 1.85).
    if unsafe { libc::flock(handle.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0 {
        return Ok(FolderLock(handle));
    }
    let error = std::io::Error::last_os_error();
    if error.kind() == std::io::ErrorKind::WouldBlock {
        bail!(
            "{flag} {shown} is in use by another parallax run (it holds the folder's lock): wait for it to end, or \
             give another {flag}"
        );
    }
    Err(error).with_context(|| format!("{flag} {shown}: cannot lock the folder"))
}

/// An output written to a temporary file and not yet in place. Dropped without a commit, the
/// temporary file is removed and the target left as it was.
pub struct Staged {
    /// `None` once persisted.
    temp: Option<NamedTempFile>,
    temp_path: PathBuf,
    /// The staging folder that holds the temporary file (see [`crate::outputs::pending`]).
    staging: PathBuf,
    target: PathBuf,
    /// The target exists and is not a regular file: copy the bytes into it, never replace it.
    write_through: bool,
}

impl Drop for Staged {
    fn drop(&mut self) {
        // The temporary file goes before its staging folder is released.
        drop(self.temp.take());
        crate::outputs::pending::release_staging(&self.staging);
    }
}

/// Writes one output through `write` (which is handed the temporary file's path) without
/// touching the target yet.
pub fn stage(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<Staged> {
    // Follow a symlink so that the link stays and its target is replaced.
    let target = match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(path)
            .with_context(|| format!("{} is a symlink to a missing file: remove it or fix it", path.display()))?,
        _ => path.to_path_buf(),
    };
    let write_through = std::fs::metadata(&target).is_ok_and(|m| !m.is_file());
    let folder = if write_through { std::env::temp_dir() } else { folder_of(&target) };
    let cannot = || format!("cannot write {}", path.display());
    let staging = crate::outputs::pending::staging_folder(&folder).with_context(cannot)?;
    let temp = match tempfile::Builder::new().prefix("output-").tempfile_in(&staging) {
        Ok(temp) => temp,
        Err(e) => {
            crate::outputs::pending::release_staging(&staging);
            bail!("{}: {}", cannot(), write_failure(&folder, &e));
        }
    };
    let temp_path = temp.path().to_path_buf();
    let staged = Staged { temp: Some(temp), temp_path, staging, target, write_through };
    let written = write(&staged.temp_path)
        .and_then(|()| std::fs::File::open(&staged.temp_path).and_then(|f| f.sync_all()).with_context(cannot));
    match written {
        // The writer's own error would name the temporary file and blame the write.
        Err(_) if !folder.is_dir() => bail!("{}: {}", cannot(), folder_gone(&folder)),
        Err(e) => Err(e),
        Ok(()) => Ok(staged),
    }
}

impl Staged {
    /// Puts the output in place: a rename for a file, a copy into a device or FIFO.
    pub fn commit(mut self) -> Result<()> {
        let shown = self.target.display().to_string();
        if self.write_through {
            let bytes = std::fs::read(&self.temp_path).with_context(|| format!("cannot write {shown}"))?;
            return std::fs::OpenOptions::new()
                .write(true)
                .open(&self.target)
                .and_then(|mut f| f.write_all(&bytes).and_then(|_| f.flush()))
                .with_context(|| format!("cannot write {shown}"));
        }
        // The folder may have been moved or removed since the output was staged: say so.
        let failed = |e: std::io::Error| {
            anyhow::anyhow!("cannot write {shown}: {}", write_failure(&folder_of(&self.target), &e))
        };
        set_published_permissions(&self.temp_path, &self.target).map_err(failed)?;
        let temp = self.temp.take().context("output committed twice")?;
        temp.persist(&self.target).map(drop).map_err(|e| failed(e.error))
    }
}

/// A new file gets the usual rw-r--r-- rather than the temporary file's rw-------; a replaced
/// one keeps its permissions.
#[cfg(unix)]
fn set_published_permissions(temp: &Path, target: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    let perms = std::fs::metadata(target).map(|m| m.permissions()).unwrap_or_else(|_| PermissionsExt::from_mode(0o644));
    std::fs::set_permissions(temp, perms)
}

#[cfg(not(unix))]
fn set_published_permissions(_: &Path, _: &Path) -> std::io::Result<()> {
    Ok(())
}

/// Writes `bytes` to `sink` whole or not at all.
pub fn write_bytes(sink: &Sink, bytes: &[u8]) -> Result<()> {
    match sink {
        Sink::Stdout => crate::console::to_stdout(bytes).context("cannot write to stdout"),
        Sink::File(path) => {
            stage(path, |temp| std::fs::write(temp, bytes).with_context(|| format!("cannot write {}", path.display())))?
                .commit()
        }
    }
}

/// Stages `value` as pretty JSON for `path`, to be committed after the other outputs.
pub fn stage_json(path: &Path, value: &impl serde::Serialize) -> Result<Staged> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    stage(path, |temp| std::fs::write(temp, text).with_context(|| format!("cannot write {}", path.display())))
}

/// Writes `value` as pretty JSON to `sink`.
pub fn write_json(sink: &Sink, value: &impl serde::Serialize) -> Result<()> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    write_bytes(sink, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(p: &Path) -> Sink {
        Sink::File(p.to_path_buf())
    }

    #[test]
    fn check_refuses_each_bad_output_by_its_flag() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (file(&dir.path().join("a.json")), file(&dir.path().join("x/../a.json")));
        let err = |outputs: &[Output]| check(outputs).unwrap_err().to_string();
        let json = |flag, sink| Output { flag, sink, format: Format::Json };
        std::fs::create_dir(dir.path().join("x")).unwrap();
        assert!(err(&[json("--json", &a), json("--trace", &b)]).starts_with("--trace and --json both write"));
        assert!(err(&[json("--json", &Sink::Stdout), json("--trace", &Sink::Stdout)]).contains("both write to stdout"));
        let png = file(&dir.path().join("a.exr"));
        assert!(
            err(&[Output { flag: "--png", sink: &png, format: Format::Png }])
                .ends_with("must end in .png (it is written as Png)")
        );
        let missing = file(&dir.path().join("none/a.json"));
        assert!(err(&[json("--json", &missing)]).ends_with("does not exist; create it first"));
        let folder = file(dir.path());
        assert!(err(&[json("--json", &folder)]).contains("is a folder"));
        let exr = Output { flag: "--out", sink: &Sink::Stdout, format: Format::Exr };
        assert!(err(&[exr]).contains("images cannot be written to stdout"));
        std::os::unix::fs::symlink("gone.json", dir.path().join("dangling.json")).unwrap();
        let dangling = file(&dir.path().join("dangling.json"));
        assert!(err(&[json("--json", &dangling)]).ends_with("is a symlink to a missing file: remove it or fix it"));
        // Devices carry no extension and are fine.
        assert!(check(&[json("--json", &file(Path::new("/dev/null")))]).is_ok());
    }

    #[test]
    fn a_committed_file_replaces_the_old_one_whole_and_readable() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.json");
        write_bytes(&file(&path), b"first").unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o644);
        let staged = stage(&path, |t| Ok(std::fs::write(t, "second")?)).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"first", "nothing changes before the commit");
        staged.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        // A failed writer leaves the old file and no temporary file.
        assert!(stage(&path, |_| anyhow::bail!("disk full")).is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no staging folder is left");
    }
}
