//! The Rust side of a crate's shaders, written from their SPIR-V so that nothing is declared
//! twice: a `#[repr(C)]` struct for every push-constant block (and every struct inside one),
//! with the backend's `PushConstants` implemented from the block's own members, and one
//! compile-time id per shader, typed by its block (`Shader<TonemapPush>`), so a dispatch that
//! hands a shader another block's struct does not compile (and a draw too: a vertex or fragment
//! stage without a block is typed `Shader<NoPushBlock>` and takes the other stage's).
//!
//! The build refuses a block a `#[repr(C)]` struct cannot reproduce byte for byte (implicit
//! padding, a `vec3` array, a matrix) with the member named and the fix, and the file it writes
//! asserts every offset and size again when the crate compiles.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use crate::error::{GlslError, Result};
use crate::reflect::{MemberType, Scalar, StructType, push_constant_struct};
use crate::shader::CompiledShader;

/// Blocks of Parallax's shared include (`bindless.glsl`), which parallax-backend's bindings
/// define once and every other crate's bindings name by path, so that the backend's
/// `Recorder::dispatch_rows` takes the same type a user's shader id is typed by.
const SHARED_BLOCKS: &[&str] = &["PassParams"];
/// The crate whose build defines [`SHARED_BLOCKS`].
const SHARED_BLOCKS_CRATE: &str = "parallax-backend";
/// Where the generated code finds the backend (the backend names itself so too).
const BACKEND: &str = "::parallax_backend";

/// Writes the bindings of `shaders` to `path`; the shared blocks are defined here when the
/// build script runs for parallax-backend (`CARGO_PKG_NAME`), named by path otherwise.
pub(crate) fn write(shaders: &[CompiledShader], path: &Path) -> Result<()> {
    let defines_shared = std::env::var("CARGO_PKG_NAME").is_ok_and(|name| name == SHARED_BLOCKS_CRATE);
    let mut blocks = Vec::with_capacity(shaders.len());
    for shader in shaders {
        let bytes =
            std::fs::read(&shader.spirv).map_err(|source| GlslError::Read { path: shader.spirv.clone(), source })?;
        let words: Vec<u32> = bytes.chunks_exact(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])).collect();
        let block = push_constant_struct(&words).map_err(|defect| bindings_error(shader, defect.to_string()))?;
        blocks.push((shader, block));
    }
    let text = text(&blocks, defines_shared)?;
    std::fs::write(path, text).map_err(|source| GlslError::Write { path: path.to_path_buf(), source })
}

fn bindings_error(shader: &CompiledShader, problem: String) -> GlslError {
    GlslError::Bindings { file: shader.source.clone(), problem }
}

/// The bindings file of `blocks` (each shader with its push-constant block, if any).
fn text(blocks: &[(&CompiledShader, Option<StructType>)], defines_shared: bool) -> Result<String> {
    // Every struct once, by name, with the shaders that use it (for its doc comment).
    let mut structs: BTreeMap<String, (StructType, Vec<String>)> = BTreeMap::new();
    let mut out = String::from("// Written by parallax-glsl from the SPIR-V of this crate's shaders; do not edit.\n");
    for (shader, block) in blocks {
        let Some(block) = block else { continue };
        collect_structs(shader, block, &mut structs)?;
    }
    for (name, (ty, users)) in &structs {
        let shared = SHARED_BLOCKS.contains(&name.as_str());
        if shared && !defines_shared {
            writeln!(out, "const _: () = assert!(::std::mem::size_of::<{BACKEND}::{name}>() == {});", size_of(ty))
                .expect("write to String");
            continue;
        }
        let is_block = blocks.iter().any(|(_, b)| b.as_ref().is_some_and(|b| b.name == *name));
        write_struct(&mut out, ty, users, is_block);
    }
    for (shader, block) in blocks {
        let id = constant_name(&shader.name).ok_or_else(|| {
            bindings_error(shader, format!("`{}` is not a Rust identifier; rename the file", shader.name))
        })?;
        // A compute shader without push constants is dispatched with `&()`; a graphics stage
        // without them takes the block of the draw's other stage.
        let graphics = shader.source.extension().is_some_and(|e| e == "vert" || e == "frag");
        let push = match block {
            None if graphics => format!("{BACKEND}::NoPushBlock"),
            None => "()".to_string(),
            Some(block) if SHARED_BLOCKS.contains(&block.name.as_str()) && !defines_shared => {
                format!("{BACKEND}::{}", block.name)
            }
            Some(block) => block.name.clone(),
        };
        let file = shader.source.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
        writeln!(out, "/// `{file}`, by the name a [`{BACKEND}::ShaderLibrary`] holds it under.")
            .expect("write to String");
        writeln!(out, "pub const {id}: {BACKEND}::Shader<{push}> = {BACKEND}::Shader::new({:?});", shader.name)
            .expect("write to String");
    }
    Ok(out)
}

/// Adds `ty` and the structs inside it to `structs`, refusing two layouts under one name.
fn collect_structs(
    shader: &CompiledShader,
    ty: &StructType,
    structs: &mut BTreeMap<String, (StructType, Vec<String>)>,
) -> Result<()> {
    if ty.name.is_empty() {
        return Err(bindings_error(shader, "a push-constant struct has no name (compile with -g)".into()));
    }
    check_layout(ty).map_err(|problem| bindings_error(shader, problem))?;
    for member in &ty.members {
        let mut inner = &member.ty;
        while let MemberType::Array { element, .. } = inner {
            inner = element;
        }
        if let MemberType::Struct(nested) = inner {
            collect_structs(shader, nested, structs)?;
        }
    }
    match structs.get_mut(&ty.name) {
        Some((known, users)) if known != ty => Err(bindings_error(
            shader,
            format!(
                "`{}` here has another layout than in {}; give one of them another name",
                ty.name,
                users.join(", ")
            ),
        )),
        Some((_, users)) => {
            users.push(shader.name.clone());
            Ok(())
        }
        None => {
            structs.insert(ty.name.clone(), (ty.clone(), vec![shader.name.clone()]));
            Ok(())
        }
    }
}

/// Refuses a struct whose `#[repr(C)]` twin would differ: padding the GLSL leaves implicit
/// (bytemuck's `Pod` allows none) or an array stride other than its element's size.
fn check_layout(ty: &StructType) -> std::result::Result<(), String> {
    let mut end: u32 = 0;
    for member in &ty.members {
        let aligned = end.next_multiple_of(align_of(&member.ty));
        if member.offset != end || aligned != end {
            return Err(format!(
                "`{}.{}` starts at byte {} after {end} bytes of members: declare the padding \
                 (`uint pad;` members) so the Rust struct has no hidden bytes",
                ty.name, member.name, member.offset
            ));
        }
        if let MemberType::Array { element, stride, .. } = &member.ty
            && *stride != type_size(element)
        {
            return Err(format!(
                "`{}.{}` is an array of stride {stride} whose elements take {} bytes \
                 (a vec3 array?): use vec4 or scalars",
                ty.name,
                member.name,
                type_size(element)
            ));
        }
        end += type_size(&member.ty);
    }
    if end % struct_align(ty) != 0 {
        return Err(format!(
            "`{}` ends at byte {end}, not a multiple of its {}-byte alignment: add `uint pad;` at the end",
            ty.name,
            struct_align(ty)
        ));
    }
    Ok(())
}

fn write_struct(out: &mut String, ty: &StructType, users: &[String], is_block: bool) {
    let name = &ty.name;
    let role = if is_block { "Push constants" } else { "A struct inside the push constants" };
    let users = users.iter().map(|u| format!("`{u}`")).collect::<Vec<_>>().join(", ");
    if SHARED_BLOCKS.contains(&name.as_str()) {
        writeln!(out, "\n/// The push constants of Parallax's shared include `bindless.glsl` (`{name}`), which every")
            .expect("write to String");
        out.push_str("/// kernel that declares no block of its own reads: image indices, the row band and two\n");
        out.push_str("/// kernel-specific words.\n");
    } else {
        writeln!(out, "\n/// {role} of {users} (`{name}` in the GLSL).").expect("write to String");
    }
    writeln!(out, "#[repr(C)]\n#[derive(Clone, Copy, Debug, Default, PartialEq)]\npub struct {name} {{")
        .expect("write to String");
    for member in &ty.members {
        writeln!(out, "    pub {}: {},", field_name(&member.name), rust_type(&member.ty)).expect("write to String");
    }
    out.push_str("}\n");
    // SAFETY (of the impls below): repr(C), every field plain old data, and the assertions
    // after them prove there is no padding.
    writeln!(out, "unsafe impl {BACKEND}::bytemuck::Zeroable for {name} {{}}").expect("write to String");
    writeln!(out, "unsafe impl {BACKEND}::bytemuck::Pod for {name} {{}}").expect("write to String");
    writeln!(out, "const _: () = assert!(::std::mem::size_of::<{name}>() == {});", size_of(ty))
        .expect("write to String");
    for member in &ty.members {
        writeln!(
            out,
            "const _: () = assert!(::std::mem::offset_of!({name}, {}) == {});",
            field_name(&member.name),
            member.offset
        )
        .expect("write to String");
    }
    if is_block {
        writeln!(out, "impl {BACKEND}::PushConstants for {name} {{").expect("write to String");
        out.push_str("    const FIELDS: &'static [(&'static str, u32)] = &[\n");
        for member in &ty.members {
            writeln!(out, "        ({:?}, {}),", member.name, member.offset).expect("write to String");
        }
        out.push_str("    ];\n}\n");
    }
}

fn rust_type(ty: &MemberType) -> String {
    match ty {
        MemberType::Scalar(s) => scalar_name(*s).to_string(),
        MemberType::Vector(s, n) => format!("[{}; {n}]", scalar_name(*s)),
        MemberType::Array { element, length, .. } => format!("[{}; {length}]", rust_type(element)),
        MemberType::Struct(s) => s.name.clone(),
        MemberType::DeviceAddress => "u64".into(),
    }
}

fn scalar_name(s: Scalar) -> &'static str {
    match s {
        Scalar::U32 => "u32",
        Scalar::I32 => "i32",
        Scalar::F32 => "f32",
        Scalar::U64 => "u64",
        Scalar::I64 => "i64",
        Scalar::F64 => "f64",
    }
}

/// Bytes of `ty` in a `#[repr(C)]` struct (which [`check_layout`] proved equal to the GLSL's).
fn type_size(ty: &MemberType) -> u32 {
    match ty {
        MemberType::Scalar(s) => s.bytes(),
        MemberType::Vector(s, n) => s.bytes() * n,
        MemberType::Array { element, length, .. } => type_size(element) * length,
        MemberType::Struct(s) => size_of(s),
        MemberType::DeviceAddress => 8,
    }
}

fn size_of(ty: &StructType) -> u32 {
    ty.members.last().map_or(0, |m| m.offset + type_size(&m.ty))
}

/// Alignment of `ty` in a `#[repr(C)]` struct.
fn align_of(ty: &MemberType) -> u32 {
    match ty {
        MemberType::Scalar(s) | MemberType::Vector(s, _) => s.bytes(),
        MemberType::Array { element, .. } => align_of(element),
        MemberType::Struct(s) => struct_align(s),
        MemberType::DeviceAddress => 8,
    }
}

fn struct_align(ty: &StructType) -> u32 {
    ty.members.iter().map(|m| align_of(&m.ty)).max().unwrap_or(1)
}

/// `gbuffer_raster.vert` → `GBUFFER_RASTER_VERT`; `None` when that is not an identifier.
fn constant_name(shader: &str) -> Option<String> {
    let name: String =
        shader.chars().map(|c| if c == '.' || c == '-' { '_' } else { c.to_ascii_uppercase() }).collect();
    let starts_well = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic());
    (starts_well && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')).then_some(name)
}

/// A GLSL member name as a Rust field: a keyword becomes a raw identifier.
fn field_name(member: &str) -> String {
    const KEYWORDS: &[&str] = &[
        "as", "async", "await", "box", "break", "const", "continue", "dyn", "enum", "extern", "false", "fn", "for",
        "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return", "static", "struct",
        "trait", "true", "type", "unsafe", "use", "where", "while", "yield", "try", "macro",
    ];
    if KEYWORDS.contains(&member) { format!("r#{member}") } else { member.to_string() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reflect::TypedMember;
    use std::path::PathBuf;

    fn shader(name: &str) -> CompiledShader {
        CompiledShader {
            name: name.into(),
            source: PathBuf::from(format!("/src/{name}.comp")),
            spirv: PathBuf::from(format!("/out/{name}.comp.spv")),
            dependencies: vec![],
        }
    }

    fn member(name: &str, offset: u32, ty: MemberType) -> TypedMember {
        TypedMember { name: name.into(), offset, ty }
    }

    fn block(name: &str, members: Vec<TypedMember>) -> StructType {
        StructType { name: name.into(), members }
    }

    const U32: MemberType = MemberType::Scalar(Scalar::U32);

    #[test]
    fn a_block_becomes_a_pod_struct_with_its_fields_and_a_typed_id() {
        let fill = shader("fill");
        let push = block(
            "FillPush",
            vec![member("dst", 0, U32), member("type", 4, U32), member("at", 8, MemberType::DeviceAddress)],
        );
        let text = text(&[(&fill, Some(push))], false).unwrap();
        assert!(
            text.contains("pub struct FillPush {\n    pub dst: u32,\n    pub r#type: u32,\n    pub at: u64,\n}"),
            "{text}"
        );
        assert!(text.contains("(\"type\", 4),"), "{text}");
        assert!(text.contains("const _: () = assert!(::std::mem::size_of::<FillPush>() == 16);"), "{text}");
        assert!(text.contains(
            "pub const FILL: ::parallax_backend::Shader<FillPush> = ::parallax_backend::Shader::new(\"fill\");"
        ));
    }

    #[test]
    fn shared_blocks_are_named_by_path_outside_the_backend() {
        let fill = shader("fill");
        let params = block("PassParams", vec![member("dst", 0, U32)]);
        let outside = text(&[(&fill, Some(params.clone()))], false).unwrap();
        assert!(!outside.contains("pub struct PassParams"), "{outside}");
        assert!(outside.contains("Shader<::parallax_backend::PassParams>"), "{outside}");
        let inside = text(&[(&fill, Some(params))], true).unwrap();
        assert!(inside.contains("pub struct PassParams"), "{inside}");
    }

    #[test]
    fn implicit_padding_and_two_layouts_of_one_name_are_refused_with_the_member() {
        let a = shader("a");
        let padded = block("P", vec![member("x", 0, U32), member("at", 8, MemberType::DeviceAddress)]);
        let err = text(&[(&a, Some(padded))], false).unwrap_err().to_string();
        assert!(err.contains("`P.at` starts at byte 8 after 4 bytes") && err.contains("/src/a.comp"), "{err}");
        let trailing = block("T", vec![member("at", 0, MemberType::DeviceAddress), member("x", 8, U32)]);
        let err = text(&[(&a, Some(trailing))], false).unwrap_err().to_string();
        assert!(err.contains("`T` ends at byte 12, not a multiple of its 8-byte alignment"), "{err}");
        let b = shader("b");
        let one = block("P", vec![member("x", 0, U32)]);
        let other = block("P", vec![member("y", 0, U32)]);
        let err = text(&[(&a, Some(one)), (&b, Some(other))], false).unwrap_err().to_string();
        assert!(err.contains("`P` here has another layout than in a"), "{err}");
    }

    #[test]
    fn shader_names_become_constants_or_are_refused() {
        assert_eq!(constant_name("gbuffer_raster.vert").as_deref(), Some("GBUFFER_RASTER_VERT"));
        assert_eq!(constant_name("9lives"), None);
    }
}
