//! Reading input files a user cannot be hurt by: only regular files, never more bytes than the
//! format declares or a stated limit allows, and never anything a glTF file names outside its
//! own folder unless the user says so.
//!
//! Every input of the program goes through here: scenes and the buffers and images they name,
//! EXRs, JSON, TOML, partial references, chart points. A FIFO would block a plain `read` for
//! ever and `/dev/zero` would fill the memory, so a path is opened without blocking and
//! refused unless the opened file is a regular file; then at most `limit` bytes are read, even
//! if the file grows meanwhile.
//!
//! The limits, which the README states:
//! - [`SCENE_FILE_LIMIT`]: a .gltf/.glb file (a GLB's own length field is 32 bits) and each
//!   buffer, which is read only up to its declared `byteLength`;
//! - [`IMAGE_FILE_LIMIT`]: an image file a glTF names (decoded: at most
//!   [`IMAGE_SIDE_LIMIT`] pixels a side);
//! - [`EXR_FILE_LIMIT`]: an EXR (decoded: what its header declares, checked first);
//! - [`TEXT_FILE_LIMIT`]: JSON and TOML (render.json, chart points, traces, bench matrices).

use std::io::Read;
use std::path::{Component, Path, PathBuf};

pub use crate::error::InputError;

/// A .gltf/.glb file or one glTF buffer: 4 GiB.
pub const SCENE_FILE_LIMIT: u64 = 4 << 30;
/// An image file a glTF names: 1 GiB.
pub const IMAGE_FILE_LIMIT: u64 = 1 << 30;
/// The width and height of a decoded glTF image.
pub const IMAGE_SIDE_LIMIT: u32 = 16384;
/// An EXR file: 4 GiB.
pub const EXR_FILE_LIMIT: u64 = 4 << 30;
/// A JSON or TOML file: 256 MiB.
pub const TEXT_FILE_LIMIT: u64 = 256 << 20;

impl InputError {
    fn io(path: &Path, source: std::io::Error) -> Self {
        // ELOOP: the OS says "too many levels of symbolic links", which hides the cause.
        if source.raw_os_error() == Some(40) {
            return InputError::SymlinkLoop { path: path.to_path_buf() };
        }
        InputError::Io { path: path.to_path_buf(), error: source }
    }
}

/// What a non-regular file is, in words.
fn kind_of(file_type: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if file_type.is_char_device() {
            return "a character device";
        }
        if file_type.is_block_device() {
            return "a block device";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    if file_type.is_dir() { "a folder" } else { "not a file" }
}

/// Opens `path` for reading if it is a regular file (symlinks followed), with its size. The
/// open does not block on a FIFO: the type is checked on the opened file, so nothing can swap
/// the file between the check and the read.
pub fn open_regular(path: &Path) -> Result<(std::fs::File, u64), InputError> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // O_NONBLOCK: opening a FIFO without a writer would wait for one; it has no effect on
        // the reads of a regular file.
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(|e| InputError::io(path, e))?;
    let meta = file.metadata().map_err(|e| InputError::io(path, e))?;
    if !meta.is_file() {
        return Err(InputError::NotRegular { path: path.to_path_buf(), kind: kind_of(meta.file_type()) });
    }
    Ok((file, meta.len()))
}

/// The whole of regular file `path`, refused if it is larger than `limit` bytes (a `what`, for
/// the message).
pub fn read_bounded(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, InputError> {
    let (file, size) = open_regular(path)?;
    let too_large = |size| InputError::TooLarge { path: path.to_path_buf(), what, size, limit };
    if size > limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::with_capacity(size as usize);
    // One byte past the limit tells a file that grew since the size was taken.
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| InputError::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// At most the first `len` bytes of regular file `path` (a glTF buffer of declared
/// `byteLength` `len`): fewer only if the file is shorter.
pub fn read_prefix(path: &Path, len: u64) -> Result<Vec<u8>, InputError> {
    let (file, size) = open_regular(path)?;
    let mut bytes = Vec::with_capacity(size.min(len) as usize);
    file.take(len).read_to_end(&mut bytes).map_err(|e| InputError::io(path, e))?;
    Ok(bytes)
}

/// [`read_bounded`] with [`TEXT_FILE_LIMIT`], as UTF-8.
pub fn read_text(path: &Path, what: &'static str) -> Result<String, InputError> {
    let bytes = read_bounded(path, TEXT_FILE_LIMIT, what)?;
    String::from_utf8(bytes).map_err(|e| InputError::Io {
        path: path.to_path_buf(),
        error: std::io::Error::new(std::io::ErrorKind::InvalidData, format!("not UTF-8 text ({e})")),
    })
}

/// FNV-1a (64 bits) of `bytes`: how a resumed run recognises the files it was made from.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    fnv1a_continue(FNV1A_OFFSET, bytes)
}

/// The FNV-1a of nothing, where a hash over several pieces starts.
pub const FNV1A_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a continued from `hash` over `bytes`: the hash of pieces without joining them.
pub fn fnv1a_continue(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// A file a scene was loaded from, as a resumed run checks it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourceFile {
    /// As the scene names it: the scene's path, or a URI relative to its folder.
    pub name: String,
    /// Where it was read from.
    pub path: PathBuf,
    pub bytes: u64,
    pub fnv1a: u64,
}

impl SourceFile {
    pub fn of(name: impl Into<String>, path: &Path, bytes: &[u8]) -> Self {
        Self { name: name.into(), path: path.to_path_buf(), bytes: bytes.len() as u64, fnv1a: fnv1a(bytes) }
    }
}

impl std::fmt::Display for SourceFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (fnv1a {:016x}, {} bytes)", self.name, self.fnv1a, self.bytes)
    }
}

/// Where a glTF URI may point (beside `data:` URIs, which name no file).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UriPolicy {
    /// Only relative paths that stay inside the scene's folder tree.
    #[default]
    InsideSceneFolder,
    /// Also `../`, absolute paths and `file:` URIs (`--allow-outside-files`).
    Anywhere,
}

/// The file a glTF URI (not `data:`) names, relative to `base` (the scene's folder): percent
/// decoded; refused with a reason if it leaves the folder tree and `policy` does not allow it,
/// or uses a scheme other than `file:`.
pub fn resolve_uri(base: &Path, uri: &str, policy: UriPolicy) -> Result<PathBuf, String> {
    let outside = |what: &str| {
        format!(
            "{what} names a file outside the scene's folder; a glTF file may only read files beside it or \
             below: move the file there, or pass --allow-outside-files if you trust this scene"
        )
    };
    let (path, is_file_uri) = if let Some(rest) = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
        (rest, true)
    } else if uri.split('/').next().is_some_and(|first| first.contains(':')) {
        return Err(format!("URI scheme of '{uri}' is not supported (only relative paths and data: URIs)"));
    } else {
        (uri, false)
    };
    let decoded = urlencoding::decode(path).map_err(|e| format!("URI '{uri}' is not valid percent-encoding ({e})"))?;
    let relative = Path::new(decoded.as_ref());
    if policy == UriPolicy::Anywhere {
        return Ok(if relative.is_absolute() { relative.to_path_buf() } else { base.join(relative) });
    }
    if is_file_uri {
        return Err(outside(&format!("file: URI '{uri}'")));
    }
    let mut depth = 0usize;
    for component in relative.components() {
        match component {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir if depth > 0 => depth -= 1,
            Component::ParentDir => return Err(outside(&format!("URI '{uri}' (../)"))),
            Component::RootDir | Component::Prefix(_) => return Err(outside(&format!("absolute URI '{uri}'"))),
        }
    }
    Ok(base.join(relative))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn special_files_and_folders_are_refused_by_kind() {
        let dir = tempfile::tempdir().unwrap();
        let kind = |path: &Path| match read_bounded(path, 16, "test file") {
            Err(InputError::NotRegular { kind, .. }) => kind,
            other => panic!("{}: {other:?}", path.display()),
        };
        assert_eq!(kind(Path::new("/dev/zero")), "a character device");
        assert_eq!(kind(dir.path()), "a folder");
        let fifo = dir.path().join("fifo");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        // Opened without a writer: must not block.
        assert_eq!(kind(&fifo), "a FIFO (named pipe)");
        let file = dir.path().join("f");
        std::fs::write(&file, [7u8; 17]).unwrap();
        assert!(matches!(read_bounded(&file, 16, "test file"), Err(InputError::TooLarge { size: 17, limit: 16, .. })));
        assert_eq!(read_bounded(&file, 17, "test file").unwrap().len(), 17);
        assert_eq!(read_prefix(&file, 5).unwrap(), [7u8; 5]);
        std::os::unix::fs::symlink("loop", dir.path().join("loop")).unwrap();
        assert!(matches!(read_bounded(&dir.path().join("loop"), 16, "x"), Err(InputError::SymlinkLoop { .. })));
    }

    #[test]
    fn uris_stay_in_the_scene_folder_unless_allowed() {
        let base = Path::new("/scenes/a");
        let inside = UriPolicy::InsideSceneFolder;
        assert_eq!(resolve_uri(base, "tex/b%20c.png", inside).unwrap(), base.join("tex/b c.png"));
        assert_eq!(resolve_uri(base, "tex/../b.bin", inside).unwrap(), base.join("tex/../b.bin"));
        for uri in ["../b.bin", "tex/../../b.bin", "/etc/passwd", "file:///dev/zero", "file:b.bin"] {
            let err = resolve_uri(base, uri, inside).unwrap_err();
            assert!(err.contains("outside the scene's folder") && err.contains("--allow-outside-files"), "{err}");
        }
        assert!(resolve_uri(base, "http://x/b.bin", inside).unwrap_err().contains("not supported"));
        assert!(resolve_uri(base, "%FF.bin", inside).unwrap_err().contains("percent-encoding"));
        let anywhere = UriPolicy::Anywhere;
        assert_eq!(resolve_uri(base, "file:///dev/zero", anywhere).unwrap(), Path::new("/dev/zero"));
        assert_eq!(resolve_uri(base, "../b.bin", anywhere).unwrap(), base.join("../b.bin"));
    }
}
