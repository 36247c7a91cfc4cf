//! Where kernels' SPIR-V comes from: the layers of a [`ShaderLibrary`] (a crate's shaders by
//! name: the passes crate's pipeline shaders, a user's kernels), then the backend's own shaders
//! (`backend/shaders/`, the ones the backend itself dispatches), which build.rs embeds.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::error::{BackendError, Result, SearchedShaders, SpirvDefect};

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

/// First word of every SPIR-V module.
const SPIRV_MAGIC: u32 = 0x0723_0203;
/// Words of a SPIR-V module header (magic, version, generator, bound, schema).
const SPIRV_HEADER_WORDS: usize = 5;

/// Names of the backend's own shaders (`backend/shaders/`, embedded by build.rs).
pub fn shader_names() -> impl Iterator<Item = &'static str> {
    embedded::EMBEDDED.iter().map(|(name, _)| *name)
}

/// SPIR-V words of the backend's own shader `name` (file stem of `backend/shaders/<name>.comp`);
/// the same as an empty [`ShaderLibrary`] gives.
pub fn spirv(name: &str) -> Result<Vec<u32>> {
    ShaderLibrary::new().spirv(name)
}

/// SPIR-V of kernels by name, in layers looked in first to last, then the backend's own shaders
/// ([`shader_names`]): a library of its own (a crate's [`crate::include_shaders!`], or shaders
/// added with [`Self::with_spirv`]) layered over another ([`Self::layered_over`]) adds kernels
/// to it and replaces its shaders of the same names. Hand it to the executor in
/// [`crate::ExecOptions::shaders`]; names are what [`crate::Recorder::dispatch`] and
/// [`crate::Draw`] take.
#[derive(Clone)]
pub struct ShaderLibrary {
    /// Never empty; [`Self::with_spirv`] adds to the first.
    layers: Vec<Layer>,
}

/// One library's own shaders.
#[derive(Clone)]
struct Layer {
    /// Where the shaders come from, as [`BackendError::UnknownShader`] names it.
    origin: Arc<str>,
    // Shared map and words: each device's descriptor state holds a clone of the library, and a
    // library built once (a crate's) is layered under others without copying.
    shaders: Arc<BTreeMap<String, Arc<[u32]>>>,
}

/// Origin of the shaders of [`ShaderLibrary::new`].
pub const USER_SHADERS: &str = "the user shaders";
/// Origin of the backend's own shaders, looked in after every layer.
pub const BACKEND_SHADERS: &str = "the backend's own shaders";

impl Default for ShaderLibrary {
    fn default() -> Self {
        Self::named(USER_SHADERS)
    }
}

impl std::fmt::Debug for ShaderLibrary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let layers = self.layers.iter().map(|l| (&*l.origin, l.shaders.keys().collect::<Vec<_>>()));
        f.debug_map().entries(layers).finish()
    }
}

impl ShaderLibrary {
    /// An empty library of [`USER_SHADERS`].
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty library whose shaders come from `origin` (how an unknown shader's error names
    /// it, e.g. "the shaders of my-crate").
    pub fn named(origin: impl Into<String>) -> Self {
        Self { layers: vec![Layer { origin: origin.into().into(), shaders: Arc::default() }] }
    }

    /// Adds (or replaces) shader `name` as SPIR-V words; refuses words that do not start with a
    /// SPIR-V header ([`BackendError::InvalidSpirv`]). Only the header is checked here: the rest
    /// of the module is the driver's to check, which the validation layer does
    /// (`PARALLAX_VALIDATION=1`) when the pipeline is created.
    pub fn with_spirv(mut self, name: impl Into<String>, words: impl Into<Vec<u32>>) -> Result<Self> {
        let name = name.into();
        let words = words.into();
        check_header(&words).map_err(|defect| BackendError::InvalidSpirv { shader: name.clone(), defect })?;
        Arc::make_mut(&mut self.layers[0].shaders).insert(name, words.into());
        Ok(self)
    }

    /// [`Self::with_spirv`] from the bytes of a `.spv` file (either byte order).
    pub fn with_spirv_bytes(self, name: impl Into<String>, bytes: &[u8]) -> Result<Self> {
        let name = name.into();
        match words_of(bytes) {
            Ok(words) => self.with_spirv(name, words),
            Err(defect) => Err(BackendError::InvalidSpirv { shader: name, defect }),
        }
    }

    /// Every shader of a table that parallax-glsl generated, as a library of `origin`;
    /// [`crate::include_shaders!`] includes the table and names the crate.
    pub fn from_embedded(origin: impl Into<String>, table: &[(&str, &[u8])]) -> Result<Self> {
        table.iter().try_fold(Self::named(origin), |library, (name, bytes)| library.with_spirv_bytes(*name, bytes))
    }

    /// This library looked in first, then `beneath` (a crate's library such as the passes'):
    /// a shader of this one replaces one of `beneath` of the same name. Layers already present
    /// (the same library layered twice) are not added again.
    pub fn layered_over(mut self, beneath: ShaderLibrary) -> Self {
        for layer in beneath.layers {
            if !self.layers.iter().any(|l| Arc::ptr_eq(&l.shaders, &layer.shaders)) {
                self.layers.push(layer);
            }
        }
        self
    }

    /// Names of the shaders of every layer (not the backend's own), sorted, each once.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        let names: std::collections::BTreeSet<&str> =
            self.layers.iter().flat_map(|l| l.shaders.keys().map(String::as_str)).collect();
        names.into_iter()
    }

    /// The words the executor uses for shader `name`: those of the first layer that has it,
    /// else the backend's own.
    pub fn spirv(&self, name: &str) -> Result<Vec<u32>> {
        if let Some(words) = self.layers.iter().find_map(|l| l.shaders.get(name)) {
            return Ok(words.to_vec());
        }
        let Some((_, bytes)) = embedded::EMBEDDED.iter().find(|(n, _)| *n == name) else {
            return Err(BackendError::UnknownShader { name: name.to_string(), searched: self.searched() });
        };
        words_of(bytes).map_err(|defect| BackendError::InvalidSpirv { shader: name.to_string(), defect })
    }

    /// Every place [`Self::spirv`] looks, in order: the layers, then the backend's own shaders.
    fn searched(&self) -> Vec<SearchedShaders> {
        let layers = self
            .layers
            .iter()
            .map(|l| SearchedShaders { origin: l.origin.to_string(), names: l.shaders.keys().cloned().collect() });
        let backend = SearchedShaders {
            origin: BACKEND_SHADERS.to_string(),
            names: shader_names().map(str::to_string).collect(),
        };
        layers.chain(std::iter::once(backend)).collect()
    }
}

/// Includes the shader table that parallax-glsl's `compile_dir` wrote into the calling crate's
/// `OUT_DIR` (from its build.rs) and returns it as a [`ShaderLibrary`] of "the shaders of" and
/// the crate's name:
/// `ExecOptions { shaders: parallax_backend::include_shaders!()?, ..Default::default() }`.
#[macro_export]
macro_rules! include_shaders {
    () => {{
        mod parallax_embedded_shaders {
            // parallax_glsl::TABLE_FILE
            include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
        }
        $crate::ShaderLibrary::from_embedded(
            concat!("the shaders of ", env!("CARGO_PKG_NAME")),
            parallax_embedded_shaders::EMBEDDED,
        )
    }};
}

/// Words of `bytes`, little-endian or, as SPIR-V allows, big-endian (told apart by the magic).
fn words_of(bytes: &[u8]) -> std::result::Result<Vec<u32>, SpirvDefect> {
    if bytes.len() % 4 != 0 {
        return Err(SpirvDefect::Unaligned { bytes: bytes.len() });
    }
    let mut words: Vec<u32> = bytes.chunks_exact(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])).collect();
    if words.first() == Some(&SPIRV_MAGIC.swap_bytes()) {
        words.iter_mut().for_each(|w| *w = w.swap_bytes());
    }
    check_header(&words)?;
    Ok(words)
}

fn check_header(words: &[u32]) -> std::result::Result<(), SpirvDefect> {
    if words.len() < SPIRV_HEADER_WORDS {
        return Err(SpirvDefect::TooShort { words: words.len() });
    }
    if words[0] != SPIRV_MAGIC {
        return Err(SpirvDefect::BadMagic { found: words[0] });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fill_bytes() -> &'static [u8] {
        embedded::EMBEDDED.iter().find(|(n, _)| *n == "bench_fill").map(|(_, b)| *b).unwrap()
    }

    /// A module of the header only, told apart from others by its `bound` word.
    fn header_only(bound: u32) -> Vec<u32> {
        vec![SPIRV_MAGIC, 0x0001_0600, 0, bound, 0]
    }

    #[test]
    fn a_user_shader_comes_before_the_builtin_of_the_same_name() {
        let other = header_only(7);
        let library = ShaderLibrary::new().with_spirv("bench_fill", other.clone()).unwrap();
        assert_eq!(library.spirv("bench_fill").unwrap(), other);
        assert_eq!(ShaderLibrary::new().spirv("bench_fill").unwrap(), words_of(fill_bytes()).unwrap());
    }

    #[test]
    fn a_layer_replaces_the_shader_of_the_same_name_beneath_it() {
        let beneath = ShaderLibrary::named("the shaders of below")
            .with_spirv("shared", header_only(1))
            .unwrap()
            .with_spirv("below_only", header_only(2))
            .unwrap();
        let library = ShaderLibrary::new().with_spirv("shared", header_only(3)).unwrap().layered_over(beneath);
        assert_eq!(library.spirv("shared").unwrap(), header_only(3));
        assert_eq!(library.spirv("below_only").unwrap(), header_only(2));
        assert_eq!(library.spirv("bench_fill").unwrap(), words_of(fill_bytes()).unwrap());
        assert_eq!(library.names().collect::<Vec<_>>(), ["below_only", "shared"]);
        // Added after layering, a shader still goes into the top layer and wins.
        let library = library.with_spirv("below_only", header_only(4)).unwrap();
        assert_eq!(library.spirv("below_only").unwrap(), header_only(4));
    }

    #[test]
    fn an_unknown_name_lists_every_place_looked_in() {
        let beneath = ShaderLibrary::named("the shaders of below").with_spirv("theirs", header_only(1)).unwrap();
        let library = ShaderLibrary::new().with_spirv_bytes("mine", fill_bytes()).unwrap().layered_over(beneath);
        let err = library.spirv("missing").unwrap_err();
        match &err {
            BackendError::UnknownShader { name, searched } => {
                assert_eq!(name, "missing");
                let places: Vec<(&str, Vec<&str>)> = searched
                    .iter()
                    .map(|s| (s.origin.as_str(), s.names.iter().map(String::as_str).collect()))
                    .collect();
                let builtin: Vec<&str> = shader_names().collect();
                assert!(builtin.contains(&"bench_fill"));
                assert_eq!(
                    places,
                    [
                        (USER_SHADERS, vec!["mine"]),
                        ("the shaders of below", vec!["theirs"]),
                        (BACKEND_SHADERS, builtin)
                    ]
                );
            }
            other => panic!("expected UnknownShader, got {other:?}"),
        }
        let message = err.to_string();
        assert!(message.contains("`missing`") && message.contains("the shaders of below (theirs)"), "{message}");
    }

    #[test]
    fn a_library_layered_twice_is_looked_in_once() {
        let crate_library = ShaderLibrary::named("the shaders of below").with_spirv("theirs", header_only(1)).unwrap();
        let library = ShaderLibrary::new().layered_over(crate_library.clone()).layered_over(crate_library);
        let Err(BackendError::UnknownShader { searched, .. }) = library.spirv("missing") else {
            panic!("expected UnknownShader");
        };
        let origins: Vec<&str> = searched.iter().map(|s| s.origin.as_str()).collect();
        assert_eq!(origins, [USER_SHADERS, "the shaders of below", BACKEND_SHADERS]);
    }

    #[test]
    fn big_endian_bytes_read_as_the_same_words() {
        let swapped: Vec<u8> = fill_bytes().chunks_exact(4).flat_map(|w| [w[3], w[2], w[1], w[0]]).collect();
        assert_eq!(words_of(&swapped).unwrap(), words_of(fill_bytes()).unwrap());
    }

    #[test]
    fn words_without_a_header_are_refused() {
        let err = ShaderLibrary::new().with_spirv("short", vec![SPIRV_MAGIC, 0x0001_0600]).unwrap_err();
        assert!(matches!(
            err,
            BackendError::InvalidSpirv { ref shader, defect: SpirvDefect::TooShort { words: 2 } } if shader == "short"
        ));
    }
}
