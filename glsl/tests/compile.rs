//! The compiler on real glslc: a folder of shaders becomes SPIR-V plus a table, with every
//! dependency reported; a broken shader names its file; a missing glslc names the package.

use std::path::{Path, PathBuf};

use parallax_glsl::{Compiler, GlslError, TABLE_FILE};

/// A fresh folder for `test` under cargo's per-target temporary folder.
fn scratch(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("parallax-glsl").join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("include")).unwrap();
    dir
}

const VALID: &str = "#version 460\n#include \"double.glsl\"\nlayout(local_size_x = 1) in;\n\
                     layout(set = 0, binding = 0) buffer B { uint v[]; };\nvoid main() { v[0] = twice(v[0]); }\n";

#[test]
fn a_folder_compiles_to_spirv_and_a_table_with_every_dependency() {
    let dir = scratch("valid");
    std::fs::write(dir.join("double.comp"), VALID).unwrap();
    std::fs::write(dir.join("include/double.glsl"), "uint twice(uint x) { return 2u * x; }\n").unwrap();
    std::fs::write(dir.join("notes.txt"), "not a shader").unwrap();
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();

    let shaders = Compiler::new().compile_dir(&dir, &[&dir.join("include")], &out).unwrap();

    assert_eq!(shaders.len(), 1);
    let shader = &shaders[0];
    assert_eq!(shader.name, "double");
    let bytes = std::fs::read(&shader.spirv).unwrap();
    assert_eq!(bytes[..4], 0x0723_0203u32.to_le_bytes(), "SPIR-V magic");
    let names: Vec<_> = shader.dependencies.iter().filter_map(|d| d.file_name()).collect();
    assert_eq!(names, ["double.comp", "double.glsl"]);
    let table = std::fs::read_to_string(out.join(TABLE_FILE)).unwrap();
    assert!(
        table.contains(&format!("(\"double\", include_bytes!({:?}))", shader.spirv.display().to_string())),
        "{table}"
    );
}

#[test]
fn graphics_stages_keep_their_extension_in_the_name() {
    let dir = scratch("stages");
    let stage = "#version 460\nvoid main() { gl_Position = vec4(0.0); }\n";
    std::fs::write(dir.join("quad.vert"), stage).unwrap();
    std::fs::write(
        dir.join("quad.frag"),
        "#version 460\nlayout(location = 0) out vec4 c;\nvoid main() { c = vec4(1.0); }\n",
    )
    .unwrap();
    let shaders = Compiler::new().compile_dir(&dir, &[], &dir).unwrap();
    let names: Vec<&str> = shaders.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["quad.frag", "quad.vert"]);
}

#[test]
fn a_syntax_error_names_the_file_and_carries_glslc_report() {
    let dir = scratch("syntax");
    let broken = dir.join("broken.comp");
    std::fs::write(&broken, "#version 460\nlayout(local_size_x = 1) in;\nvoid main() { x }\n").unwrap();
    let err = Compiler::new().compile_dir(&dir, &[], &dir).unwrap_err();
    match &err {
        GlslError::Compile { file, stderr } => {
            assert_eq!(file, &broken);
            assert!(stderr.contains("broken.comp:3"), "{stderr}");
        }
        other => panic!("expected GlslError::Compile, got {other:?}"),
    }
    assert!(err.to_string().starts_with(&format!("glslc failed on {}:\n", broken.display())), "{err}");
}

#[test]
fn a_warning_is_an_error() {
    let dir = scratch("warning");
    // Without -Werror glslc only warns about an unsupported extension requested with `warn`.
    let warns = "#version 460\n#extension GL_EXT_parallax_no_such_extension : warn\n\
                 layout(local_size_x = 1) in;\nvoid main() {}\n";
    std::fs::write(dir.join("warns.comp"), warns).unwrap();
    let err = Compiler::new().compile_dir(&dir, &[], &dir).unwrap_err();
    assert!(matches!(err, GlslError::Compile { .. }), "{err:?}");
}

#[test]
fn a_missing_glslc_names_the_package_and_the_variable() {
    let dir = scratch("missing");
    std::fs::write(dir.join("double.comp"), VALID).unwrap();
    let err = Compiler::with_glslc("/nonexistent/glslc").compile_dir(&dir, &[], &dir).unwrap_err();
    match &err {
        GlslError::MissingCompiler { glslc, .. } => assert_eq!(glslc, "/nonexistent/glslc"),
        other => panic!("expected GlslError::MissingCompiler, got {other:?}"),
    }
    let message = err.to_string();
    assert!(message.contains("`apt-get install glslc`") && message.contains("GLSLC environment variable"), "{message}");
}

#[test]
fn a_missing_folder_is_a_read_error_naming_it() {
    let dir = scratch("absent").join("no-such-folder");
    let err = Compiler::new().compile_dir(&dir, &[], &dir).unwrap_err();
    assert!(matches!(&err, GlslError::Read { path, .. } if path == &dir), "{err:?}");
}

/// A block with a scalar of each kind, a buffer reference, a nested struct and an array.
const PUSHED: &str = "#version 460\n#extension GL_EXT_buffer_reference : require\n\
    layout(buffer_reference, std430) buffer Words { uint w[]; };\n\
    struct Pair { uint a; float b; };\n\
    layout(push_constant, std430) uniform FillPush { Words out_words; Pair pair; int signed_value; uint taps[3]; } pc;\n\
    layout(local_size_x = 1) in;\n\
    void main() { pc.out_words.w[0] = pc.pair.a + uint(pc.pair.b) + uint(pc.signed_value) + pc.taps[2]; }\n";

#[test]
fn the_build_writes_each_block_as_a_struct_and_each_shader_as_a_typed_id() {
    let dir = scratch("bindings");
    std::fs::write(dir.join("fill.comp"), PUSHED).unwrap();
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();

    parallax_glsl::compile_dir(&dir, &[], &out).unwrap();

    let bindings = std::fs::read_to_string(out.join(parallax_glsl::BINDINGS_FILE)).unwrap();
    assert!(
        bindings.contains(
            "pub struct FillPush {\n    pub out_words: u64,\n    pub pair: Pair,\n    pub signed_value: i32,\n    \
             pub taps: [u32; 3],\n}"
        ),
        "{bindings}"
    );
    assert!(bindings.contains("pub struct Pair {\n    pub a: u32,\n    pub b: f32,\n}"), "{bindings}");
    assert!(bindings.contains("const _: () = assert!(::std::mem::offset_of!(FillPush, taps) == 20);"), "{bindings}");
    assert!(bindings.contains("pub const FILL: ::parallax_backend::Shader<FillPush>"), "{bindings}");
}

#[test]
fn a_block_with_hidden_padding_fails_the_build_naming_the_member() {
    let dir = scratch("padded");
    let padded = PUSHED.replace("Words out_words; Pair pair;", "uint first; Words out_words; Pair pair;");
    std::fs::write(dir.join("fill.comp"), padded).unwrap();
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();

    let err = parallax_glsl::compile_dir(&dir, &[], &out).unwrap_err();

    assert!(matches!(err, GlslError::Bindings { .. }), "{err:?}");
    let message = err.to_string();
    assert!(
        message.contains("fill.comp") && message.contains("`FillPush.out_words` starts at byte 8 after 4 bytes"),
        "{message}"
    );
}
