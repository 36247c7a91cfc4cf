//! Struct layouts read from SPIR-V: the byte offset of every member (`OpMemberDecorate …
//! Offset`) and the stride of array members (`OpDecorate … ArrayStride`), found by the names
//! the compiler keeps with debug info (build.rs compiles with `-g`), and the block of a module's
//! push constants ([`push_constant_block`]), which pipeline creation holds a kernel's
//! [`crate::PushConstants`] against. A test holds other `#[repr(C)]` structs (buffer contents)
//! against the GLSL by comparing these with `std::mem::offset_of!` ([`rust_layout!`]), without
//! running anything on a GPU.
//!
//! Only explicitly laid-out types carry offsets: blocks (push constants, buffers, buffer
//! references) and the structs inside them.

use std::collections::HashMap;

const MAGIC: u32 = 0x0723_0203;
const OP_NAME: u32 = 5;
const OP_MEMBER_NAME: u32 = 6;
const OP_TYPE_STRUCT: u32 = 30;
const OP_TYPE_POINTER: u32 = 32;
const OP_VARIABLE: u32 = 59;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;
const DECORATION_ARRAY_STRIDE: u32 = 6;
const DECORATION_OFFSET: u32 = 35;
const STORAGE_CLASS_PUSH_CONSTANT: u32 = 9;

/// What can go wrong reading a layout.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReflectError {
    #[error("not a SPIR-V module (no magic number in the first word)")]
    NotSpirv,
    #[error("instruction at word {0} runs past the end of the module")]
    Truncated(usize),
    #[error("no struct `{0}` with explicit offsets in the module (is it used, and compiled with -g?)")]
    NoStruct(String),
    #[error("the module has several structs named `{0}` with different layouts")]
    Ambiguous(String),
}

/// One member of a laid-out struct.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemberLayout {
    pub name: String,
    /// Byte offset from the start of the struct.
    pub offset: u32,
    /// Bytes between elements, for an array member.
    pub array_stride: Option<u32>,
}

/// The members of struct `name` in declaration order.
pub fn struct_layout(words: &[u32], name: &str) -> Result<Vec<MemberLayout>, ReflectError> {
    let module = Module::parse(words)?;
    let mut layouts: Vec<Vec<MemberLayout>> = Vec::new();
    for &id in module.struct_members.keys() {
        if module.names.get(&id).map(String::as_str) != Some(name) {
            continue;
        }
        // A struct without offsets is the same type used where no layout applies.
        if let Some(layout) = module.layout(id)
            && !layouts.contains(&layout)
        {
            layouts.push(layout);
        }
    }
    match layouts.len() {
        0 => Err(ReflectError::NoStruct(name.to_string())),
        1 => Ok(layouts.remove(0)),
        _ => Err(ReflectError::Ambiguous(name.to_string())),
    }
}

/// The push-constant block of a module: its type's name (empty without debug info) and
/// members, or `None` when the shader declares no push constants.
pub fn push_constant_block(words: &[u32]) -> Result<Option<(String, Vec<MemberLayout>)>, ReflectError> {
    let module = Module::parse(words)?;
    let Some(block) = module.push_constant_block else {
        return Ok(None);
    };
    let name = module.names.get(&block).cloned().unwrap_or_default();
    let members = module.layout(block).ok_or_else(|| ReflectError::NoStruct(name.clone()))?;
    Ok(Some((name, members)))
}

/// The instructions a layout needs, by id.
#[derive(Default)]
struct Module {
    /// The struct type of the `PushConstant` variable (a module has at most one).
    push_constant_block: Option<u32>,
    /// Pointer type id → (storage class, pointee type id).
    pointers: HashMap<u32, (u32, u32)>,
    names: HashMap<u32, String>,
    member_names: HashMap<(u32, u32), String>,
    /// Struct id → member type ids.
    struct_members: HashMap<u32, Vec<u32>>,
    offsets: HashMap<(u32, u32), u32>,
    array_strides: HashMap<u32, u32>,
}

impl Module {
    fn parse(words: &[u32]) -> Result<Self, ReflectError> {
        if words.first() != Some(&MAGIC) {
            return Err(ReflectError::NotSpirv);
        }
        let mut module = Self::default();
        // Five header words, then instructions: word count in the high half, opcode in the low.
        let mut at = 5;
        while at < words.len() {
            let count = (words[at] >> 16) as usize;
            let opcode = words[at] & 0xffff;
            if count == 0 || at + count > words.len() {
                return Err(ReflectError::Truncated(at));
            }
            let operands = &words[at + 1..at + count];
            match (opcode, operands) {
                (OP_NAME, [id, text @ ..]) => {
                    module.names.insert(*id, literal_string(text));
                }
                (OP_MEMBER_NAME, [id, member, text @ ..]) => {
                    module.member_names.insert((*id, *member), literal_string(text));
                }
                (OP_TYPE_STRUCT, [id, members @ ..]) => {
                    module.struct_members.insert(*id, members.to_vec());
                }
                (OP_DECORATE, [id, DECORATION_ARRAY_STRIDE, stride]) => {
                    module.array_strides.insert(*id, *stride);
                }
                (OP_MEMBER_DECORATE, [id, member, DECORATION_OFFSET, offset]) => {
                    module.offsets.insert((*id, *member), *offset);
                }
                (OP_TYPE_POINTER, [id, storage, pointee]) => {
                    module.pointers.insert(*id, (*storage, *pointee));
                }
                // Types precede variables, so the pointer type is known here.
                (OP_VARIABLE, [pointer, _, STORAGE_CLASS_PUSH_CONSTANT, ..]) => {
                    module.push_constant_block = module.pointers.get(pointer).map(|&(_, pointee)| pointee);
                }
                _ => {}
            }
            at += count;
        }
        Ok(module)
    }
}

impl Module {
    /// The members of struct `id`, if it is a struct and every member has an explicit offset.
    fn layout(&self, id: u32) -> Option<Vec<MemberLayout>> {
        self.struct_members
            .get(&id)?
            .iter()
            .enumerate()
            .map(|(i, member_type)| {
                let offset = *self.offsets.get(&(id, i as u32))?;
                Some(MemberLayout {
                    name: self.member_names.get(&(id, i as u32)).cloned().unwrap_or_default(),
                    offset,
                    array_stride: self.array_strides.get(member_type).copied(),
                })
            })
            .collect()
    }
}

/// A nul-terminated UTF-8 string packed little-endian into words.
fn literal_string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).take_while(|&b| b != 0).collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// `(name, offset)` of every member of struct `name` in `words`: what [`rust_layout!`] gives for
/// the Rust twin.
pub fn member_offsets(words: &[u32], name: &str) -> Result<Vec<(String, u32)>, ReflectError> {
    Ok(struct_layout(words, name)?.into_iter().map(|m| (m.name, m.offset)).collect())
}

/// `(name, offset)` pairs of a `#[repr(C)]` struct's fields, to compare with
/// [`member_offsets`]: `rust_layout!(PathTracePush { scene, trace, .. })` lists the fields in
/// declaration order.
#[macro_export]
macro_rules! rust_layout {
    ($ty:ty { $($field:ident),* $(,)? }) => {
        vec![$((stringify!($field).to_string(), std::mem::offset_of!($ty, $field) as u32)),*]
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Words of a string operand.
    fn string(text: &str) -> Vec<u32> {
        let mut bytes = text.as_bytes().to_vec();
        bytes.resize((bytes.len() / 4 + 1) * 4, 0);
        bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
    }

    fn instruction(opcode: u32, operands: &[u32]) -> Vec<u32> {
        let mut words = vec![((operands.len() as u32 + 1) << 16) | opcode];
        words.extend_from_slice(operands);
        words
    }

    /// struct Params { uint a; float b[]; } with a at 0, b at 16 (stride 4): ids 1 = struct,
    /// 2 = uint, 3 = the array type.
    fn module() -> Vec<u32> {
        let mut words = vec![MAGIC, 0x0001_0600, 0, 10, 0];
        words.extend(instruction(OP_NAME, &[[1].as_slice(), &string("Params")].concat()));
        words.extend(instruction(OP_MEMBER_NAME, &[[1, 0].as_slice(), &string("a")].concat()));
        words.extend(instruction(OP_MEMBER_NAME, &[[1, 1].as_slice(), &string("b")].concat()));
        words.extend(instruction(OP_DECORATE, &[3, DECORATION_ARRAY_STRIDE, 4]));
        words.extend(instruction(OP_MEMBER_DECORATE, &[1, 0, DECORATION_OFFSET, 0]));
        words.extend(instruction(OP_MEMBER_DECORATE, &[1, 1, DECORATION_OFFSET, 16]));
        words.extend(instruction(OP_TYPE_STRUCT, &[1, 2, 3]));
        words
    }

    #[test]
    fn the_shared_pass_params_match_bindless_glsl() {
        let spirv = crate::spirv("bench_fill").unwrap();
        assert_eq!(crate::check_push_constants::<crate::PassParams>(&spirv), Ok(()));
        let (block, members) = push_constant_block(&spirv).unwrap().unwrap();
        assert_eq!((block.as_str(), members.len()), ("PassParams", 8));
    }

    #[test]
    fn members_come_with_offsets_names_and_strides() {
        let layout = struct_layout(&module(), "Params").unwrap();
        assert_eq!(
            layout,
            vec![
                MemberLayout { name: "a".into(), offset: 0, array_stride: None },
                MemberLayout { name: "b".into(), offset: 16, array_stride: Some(4) },
            ]
        );
    }

    #[test]
    fn bad_modules_and_missing_structs_are_errors() {
        assert_eq!(struct_layout(&[0, 1, 2], "Params"), Err(ReflectError::NotSpirv));
        assert_eq!(struct_layout(&module(), "Other"), Err(ReflectError::NoStruct("Other".into())));
        let mut cut = module();
        cut.truncate(cut.len() - 1);
        assert!(matches!(struct_layout(&cut, "Params"), Err(ReflectError::Truncated(_))));
    }
}
