//! The passes' shaders: the top-level `shaders/`, compiled by this crate's build.rs through
//! parallax-glsl as any crate with kernels of its own compiles them.

use std::sync::OnceLock;

use parallax_backend::ShaderLibrary;

// The push-constant struct of every shader's block and a typed id per shader, written by the
// build from the SPIR-V (parallax-glsl's bindings), so a block is declared once, in GLSL.
parallax_backend::shader_bindings!();

/// The SPIR-V of every shader the passes' kernels dispatch, as the "the shaders of
/// parallax-passes" layer of a [`ShaderLibrary`]. Built once; a call after the first clones
/// shared words. [`crate::LightFieldRenderer`] puts it beneath the library of its options, so
/// a user's shader of the same name replaces a pass's; an executor of other passes' kernels
/// takes it in `ExecOptions::shaders`.
pub fn shader_library() -> ShaderLibrary {
    static LIBRARY: OnceLock<ShaderLibrary> = OnceLock::new();
    // build.rs wrote the table from glslc's output, which glslc checked; a defect here is a
    // broken build, not an input error.
    LIBRARY.get_or_init(|| parallax_backend::include_shaders!().expect("build.rs embeds valid SPIR-V")).clone()
}

/// The words of the passes' shader `name`, for the kernels' push-constant checks.
#[cfg(test)]
pub(crate) fn spirv(name: &str) -> parallax_backend::Result<Vec<u32>> {
    shader_library().spirv(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shader names of `shaders/`: file stems of compute shaders, file names of graphics stages.
    fn names_in_shader_dir() -> Vec<String> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("shaders");
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|entry| entry.unwrap().path())
            .filter_map(|path| match path.extension()?.to_str()? {
                "comp" => Some(path.file_stem()?.to_str()?.to_string()),
                "vert" | "frag" => Some(path.file_name()?.to_str()?.to_string()),
                _ => None,
            })
            .collect();
        names.sort();
        names
    }

    #[test]
    fn the_library_holds_every_shader_of_the_shader_folder() {
        let names: Vec<String> = shader_library().names().map(str::to_string).collect();
        assert_eq!(names, names_in_shader_dir());
        assert!(names.iter().any(|n| n == "pt_trace") && names.iter().any(|n| n == "gbuffer_raster.vert"));
    }

    #[test]
    fn the_backend_embeds_none_of_the_pipeline_shaders() {
        let backend: Vec<&str> = parallax_backend::shader_names().collect();
        for name in names_in_shader_dir() {
            assert!(!backend.contains(&name.as_str()), "{name} is embedded by the backend too");
        }
        assert!(ShaderLibrary::new().spirv("pt_trace").is_err());
        assert_eq!(shader_library().spirv("pt_trace").unwrap()[0], 0x0723_0203);
    }

    #[test]
    fn a_user_shader_replaces_the_pass_shader_of_its_name() {
        let words = parallax_backend::spirv("bench_fill").unwrap();
        let user = ShaderLibrary::new().with_spirv("tonemap", words.clone()).unwrap();
        let layered = user.layered_over(shader_library());
        assert_eq!(layered.spirv("tonemap").unwrap(), words);
        assert_eq!(layered.spirv("reproject").unwrap(), shader_library().spirv("reproject").unwrap());
        assert_ne!(shader_library().spirv("tonemap").unwrap(), words);
    }
}
