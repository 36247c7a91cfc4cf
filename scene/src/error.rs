//! The error types of the crate, a leaf: every failure names the input it came from.

use std::path::PathBuf;

/// Everything that can go wrong while loading, tracing or writing a scene.
///
/// Loader errors carry the path of the file so that a user with several scenes knows which one
/// is broken and why; none of them is ever raised as a panic.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: cannot read file")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Not a regular file, too large, a symlink loop.
    #[error(transparent)]
    Input(InputError),
    #[error("{path}: malformed glTF JSON: {detail}")]
    MalformedJson { path: PathBuf, detail: String },
    #[error("{path}: requires glTF extension {extension}, which Parallax does not support (supported: {supported})")]
    UnsupportedExtension { path: PathBuf, extension: String, supported: &'static str },
    #[error("{path}: invalid glTF: {detail}")]
    InvalidGltf { path: PathBuf, detail: String },
    #[error("{path}: buffer {buffer} ({uri}) cannot be read: {detail}")]
    MissingBuffer { path: PathBuf, buffer: usize, uri: String, detail: String },
    #[error("{path}: image {image} ({uri}) cannot be read: {detail}")]
    BadImage { path: PathBuf, image: usize, uri: String, detail: String },
    #[error("{path}: accessor {accessor} is empty or reads past the end of its buffer view")]
    AccessorOutOfBounds { path: PathBuf, accessor: usize },
    #[error(
        "{path}: mesh {mesh} primitive {primitive}: vertex index {index} out of range (the primitive has {vertex_count} vertices)"
    )]
    IndexOutOfRange { path: PathBuf, mesh: usize, primitive: usize, index: u32, vertex_count: usize },
    #[error("{path}: mesh {mesh} primitive {primitive}: {what}")]
    BadPrimitive { path: PathBuf, mesh: usize, primitive: usize, what: String },
    #[error("{path}: uses {what}, which Parallax does not support")]
    Unsupported { path: PathBuf, what: String },
    #[error("{path}: the scene has no triangles to render")]
    NoGeometry { path: PathBuf },
    #[error("{path}: non-finite value in {what}")]
    NonFinite { path: PathBuf, what: String },
    #[error(
        "{path}: {what} has a coordinate of {value:e}; coordinates must lie within ±{limit:e} (beyond that f32 products in the BVH overflow): rescale the scene"
    )]
    CoordinateOutOfRange { path: PathBuf, what: String, value: f32, limit: f32 },
    #[error(
        "{path}: every triangle has zero area ({hint}), so nothing would be visible; fix the node scales or vertex positions"
    )]
    ZeroArea { path: PathBuf, hint: String },
    #[error(
        "{path}: {what} emits {value:e}, more than the {limit:e} a scene may (f32 sums would overflow to infinity): lower it"
    )]
    EmissionOutOfRange { path: PathBuf, what: String, value: f32, limit: f32 },
    #[error("{path}: camera {camera} (node {node}): {detail}")]
    BadCamera { path: PathBuf, camera: usize, node: usize, detail: String },
    #[error(
        "{path}: not a glTF file ({detail}); Parallax reads .gltf (JSON) and .glb (binary glTF): convert other formats such as .obj first, e.g. with Blender"
    )]
    NotGltf { path: PathBuf, detail: String },
    #[error("{path}: cannot read image: {detail}")]
    ImageRead { path: PathBuf, detail: String },
    #[error("{path}: cannot write image: {detail}")]
    ImageWrite { path: PathBuf, detail: String },
    #[error("{path}: image {image}: {detail}")]
    MalformedImage { path: PathBuf, image: usize, detail: String },
    /// An estimate of the load (triangles after instancing, textures after sharing, memory)
    /// beyond a limit, found before the work.
    #[error("{path}: {what}, more than {limit}: {fix}")]
    TooLarge { path: PathBuf, what: String, limit: String, fix: String },
    #[error("invalid trace settings: {0}")]
    InvalidSettings(String),
}

impl From<InputError> for SceneError {
    fn from(e: InputError) -> Self {
        match e {
            InputError::Io { path, error } => SceneError::Io { path, source: error },
            other => SceneError::Input(other),
        }
    }
}

/// Why an input cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("{path} is {kind}, not a regular file: give the path of a file")]
    NotRegular { path: PathBuf, kind: &'static str },
    #[error("{path} is {size} bytes, more than the {limit} bytes a {what} may have")]
    TooLarge { path: PathBuf, what: &'static str, size: u64, limit: u64 },
    #[error("{path} is a symlink loop (or a chain of more than 40 links): fix the links")]
    SymlinkLoop { path: PathBuf },
    /// The OS error is part of the message (not a `source`), so a chain prints it once.
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
}
