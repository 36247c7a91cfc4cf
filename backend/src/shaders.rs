//! Where kernels' SPIR-V comes from: the user's [`ShaderLibrary`] (shaders of kernels outside
//! this repository, by name), then the table of `shaders/` that build.rs embeds.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::error::{BackendError, Result};

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

/// First word of every SPIR-V module.
const SPIRV_MAGIC: u32 = 0x0723_0203;
/// Words of a SPIR-V module header (magic, version, generator, bound, schema).
const SPIRV_HEADER_WORDS: usize = 5;

/// Names of all embedded shaders.
pub fn shader_names() -> impl Iterator<Item = &'static str> {
    embedded::EMBEDDED.iter().map(|(name, _)| *name)
}

/// SPIR-V words of the embedded shader `name` (file stem of `shaders/<name>.comp`, file name of
/// a graphics stage); the same as an empty [`ShaderLibrary`] gives.
pub fn spirv(name: &str) -> Result<Vec<u32>> {
    ShaderLibrary::new().spirv(name)
}

/// Why bytes or words are not a SPIR-V module.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SpirvDefect {
    /// SPIR-V is a sequence of 32-bit words.
    #[error("{bytes} bytes is not a whole number of 32-bit words")]
    Unaligned { bytes: usize },
    /// Shorter than the 5-word header.
    #[error("{words} words is shorter than the 5-word SPIR-V header")]
    TooShort { words: usize },
    /// The first word is not the SPIR-V magic number 0x07230203 (in either byte order).
    #[error("first word {found:#010x} is not the SPIR-V magic number 0x07230203")]
    BadMagic { found: u32 },
}

/// SPIR-V of user kernels by name, looked up before the built-in shaders (so a user shader may
/// also replace one). Hand it to the executor in [`crate::ExecOptions::shaders`]; names are
/// what [`crate::Recorder::dispatch`] and [`crate::Draw`] take.
#[derive(Clone, Default)]
pub struct ShaderLibrary {
    // Shared words: each device's descriptor state holds a clone of the library.
    user: BTreeMap<String, Arc<[u32]>>,
}

impl std::fmt::Debug for ShaderLibrary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShaderLibrary").field("shaders", &self.names().collect::<Vec<_>>()).finish()
    }
}

impl ShaderLibrary {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds (or replaces) shader `name` as SPIR-V words; refuses words that do not start with a
    /// SPIR-V header ([`BackendError::InvalidSpirv`]). Only the header is checked here: the rest
    /// of the module is the driver's to check, which the validation layer does
    /// (`PARALLAX_VALIDATION=1`) when the pipeline is created.
    pub fn with_spirv(mut self, name: impl Into<String>, words: impl Into<Vec<u32>>) -> Result<Self> {
        let name = name.into();
        let words = words.into();
        check_header(&words).map_err(|defect| BackendError::InvalidSpirv { shader: name.clone(), defect })?;
        self.user.insert(name, words.into());
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

    /// Every shader of a table that parallax-glsl generated, as [`crate::include_shaders!`]
    /// includes it.
    pub fn from_embedded(table: &[(&str, &[u8])]) -> Result<Self> {
        table.iter().try_fold(Self::new(), |library, (name, bytes)| library.with_spirv_bytes(*name, bytes))
    }

    /// Names of the user shaders, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.user.keys().map(String::as_str)
    }

    /// The words the executor uses for shader `name`: the user's, else the built-in one.
    pub fn spirv(&self, name: &str) -> Result<Vec<u32>> {
        if let Some(words) = self.user.get(name) {
            return Ok(words.to_vec());
        }
        let Some((_, bytes)) = embedded::EMBEDDED.iter().find(|(n, _)| *n == name) else {
            return Err(BackendError::UnknownShader {
                name: name.to_string(),
                user: self.names().map(str::to_string).collect(),
                builtin: shader_names().map(str::to_string).collect(),
            });
        };
        words_of(bytes).map_err(|defect| BackendError::InvalidSpirv { shader: name.to_string(), defect })
    }
}

/// Includes the shader table that parallax-glsl's `compile_dir` wrote into the calling crate's
/// `OUT_DIR` (from its build.rs) and returns it as a [`ShaderLibrary`]:
/// `ExecOptions { shaders: parallax_backend::include_shaders!()?, ..Default::default() }`.
#[macro_export]
macro_rules! include_shaders {
    () => {{
        mod parallax_embedded_shaders {
            // parallax_glsl::TABLE_FILE
            include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
        }
        $crate::ShaderLibrary::from_embedded(parallax_embedded_shaders::EMBEDDED)
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

    #[test]
    fn a_user_shader_comes_before_the_builtin_of_the_same_name() {
        let other = spirv("pixel_list_strided").unwrap();
        let library = ShaderLibrary::new().with_spirv("bench_fill", other.clone()).unwrap();
        assert_eq!(library.spirv("bench_fill").unwrap(), other);
        assert_eq!(ShaderLibrary::new().spirv("bench_fill").unwrap(), words_of(fill_bytes()).unwrap());
    }

    #[test]
    fn an_unknown_name_lists_both_places_looked_in() {
        let library = ShaderLibrary::new().with_spirv_bytes("mine", fill_bytes()).unwrap();
        match library.spirv("missing") {
            Err(BackendError::UnknownShader { name, user, builtin }) => {
                assert_eq!(name, "missing");
                assert_eq!(user, ["mine"]);
                assert_eq!(builtin, shader_names().collect::<Vec<_>>());
                assert!(builtin.iter().any(|b| b == "bench_fill"));
            }
            other => panic!("expected UnknownShader, got {other:?}"),
        }
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
