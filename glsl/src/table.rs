//! The Rust file that embeds compiled shaders, for `include!`.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::{GlslError, Result};
use crate::shader::CompiledShader;

/// Writes `pub const EMBEDDED: &[(&str, &[u8])]`, one `(name, include_bytes!(spirv))` per
/// shader, to `path`.
pub(crate) fn write(shaders: &[CompiledShader], path: &Path) -> Result<()> {
    std::fs::write(path, text(shaders)).map_err(|source| GlslError::Write { path: path.to_path_buf(), source })
}

fn text(shaders: &[CompiledShader]) -> String {
    let mut table = String::from("/// Embedded SPIR-V, by shader name (file stem).\n");
    table.push_str("pub const EMBEDDED: &[(&str, &[u8])] = &[\n");
    for shader in shaders {
        // `{:?}` of the strings gives Rust string literals, escapes included.
        let spirv = shader.spirv.display().to_string();
        writeln!(table, "    ({:?}, include_bytes!({spirv:?})),", shader.name).expect("write to String");
    }
    table.push_str("];\n");
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn one_line_per_shader_with_its_name_and_spirv_path() {
        let shader = CompiledShader {
            name: "fill".into(),
            source: PathBuf::from("/src/fill.comp"),
            spirv: PathBuf::from("/out/fill.comp.spv"),
            dependencies: vec![],
        };
        assert_eq!(
            text(&[shader]),
            "/// Embedded SPIR-V, by shader name (file stem).\n\
             pub const EMBEDDED: &[(&str, &[u8])] = &[\n    \
             (\"fill\", include_bytes!(\"/out/fill.comp.spv\")),\n];\n"
        );
    }
}
