//! Struct layouts read from SPIR-V: the byte offset of every member (`OpMemberDecorate …
//! Offset`) and the stride of array members (`OpDecorate … ArrayStride`), found by the names
//! the compiler keeps with debug info (the compiler passes `-g`), and the block of a module's
//! push constants: its layout ([`push_constant_block`]), which the backend holds a kernel's
//! `PushConstants` against when it creates a pipeline, and its types
//! ([`push_constant_struct`]), from which the build writes the Rust struct of the block
//! (`crate::bindings`). A test holds other `#[repr(C)]` structs (buffer contents) against the
//! GLSL by comparing these with `std::mem::offset_of!` ([`rust_layout!`]), without running
//! anything on a GPU.
//!
//! Only explicitly laid-out types carry offsets: blocks (push constants, buffers, buffer
//! references) and the structs inside them.

use std::collections::HashMap;

const MAGIC: u32 = 0x0723_0203;
const OP_NAME: u32 = 5;
const OP_MEMBER_NAME: u32 = 6;
const OP_TYPE_INT: u32 = 21;
const OP_TYPE_FLOAT: u32 = 22;
const OP_TYPE_VECTOR: u32 = 23;
const OP_TYPE_ARRAY: u32 = 28;
const OP_TYPE_STRUCT: u32 = 30;
const OP_TYPE_POINTER: u32 = 32;
const OP_CONSTANT: u32 = 43;
const OP_VARIABLE: u32 = 59;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;
const DECORATION_ARRAY_STRIDE: u32 = 6;
const DECORATION_OFFSET: u32 = 35;
const STORAGE_CLASS_PUSH_CONSTANT: u32 = 9;
const STORAGE_CLASS_PHYSICAL_STORAGE_BUFFER: u32 = 5349;

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
    #[error("member `{member}` of `{block}` has a type a push-constant struct cannot spell ({what})")]
    UnsupportedType { block: String, member: String, what: String },
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

/// A scalar of a push-constant block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scalar {
    U32,
    I32,
    F32,
    U64,
    I64,
    F64,
}

impl Scalar {
    pub fn bytes(self) -> u32 {
        match self {
            Scalar::U32 | Scalar::I32 | Scalar::F32 => 4,
            Scalar::U64 | Scalar::I64 | Scalar::F64 => 8,
        }
    }
}

/// The type of a member of a push-constant block, as far as a `#[repr(C)]` struct spells it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MemberType {
    Scalar(Scalar),
    /// `vecN`, `uvecN`, `ivecN`: `count` scalars.
    Vector(Scalar, u32),
    /// A fixed-size array with its stride.
    Array {
        element: Box<MemberType>,
        length: u32,
        stride: u32,
    },
    /// A nested struct (with explicit offsets).
    Struct(StructType),
    /// A `buffer_reference`: a 64-bit device address.
    DeviceAddress,
}

/// A struct with explicit offsets and its members' types.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StructType {
    /// The GLSL type name (empty without debug info).
    pub name: String,
    pub members: Vec<TypedMember>,
}

/// One member of a [`StructType`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TypedMember {
    pub name: String,
    pub offset: u32,
    pub ty: MemberType,
}

/// The push-constant block of a module with every member's type, or `None` when the shader
/// declares no push constants: what the build turns into the Rust struct of the block.
pub fn push_constant_struct(words: &[u32]) -> Result<Option<StructType>, ReflectError> {
    let module = Module::parse(words)?;
    module.push_constant_block.map(|block| module.struct_type(block)).transpose()
}

/// A type instruction the typed reflection reads, by id.
#[derive(Clone, Copy, Debug)]
enum TypeOp {
    Int { width: u32, signed: bool },
    Float { width: u32 },
    Vector { component: u32, count: u32 },
    Array { element: u32, length: u32 },
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
    /// Scalar, vector and array types.
    types: HashMap<u32, TypeOp>,
    /// The first word of every 32-bit constant (array lengths).
    constants: HashMap<u32, u32>,
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
                (OP_TYPE_INT, [id, width, signed]) => {
                    module.types.insert(*id, TypeOp::Int { width: *width, signed: *signed == 1 });
                }
                (OP_TYPE_FLOAT, [id, width, ..]) => {
                    module.types.insert(*id, TypeOp::Float { width: *width });
                }
                (OP_TYPE_VECTOR, [id, component, count]) => {
                    module.types.insert(*id, TypeOp::Vector { component: *component, count: *count });
                }
                // The length is a constant defined before the array type.
                (OP_TYPE_ARRAY, [id, element, length]) => {
                    let length = module.constants.get(length).copied().unwrap_or(0);
                    module.types.insert(*id, TypeOp::Array { element: *element, length });
                }
                (OP_CONSTANT, [_, id, value, ..]) => {
                    module.constants.insert(*id, *value);
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

impl Module {
    /// Struct `id` with its members' types.
    fn struct_type(&self, id: u32) -> Result<StructType, ReflectError> {
        let name = self.names.get(&id).cloned().unwrap_or_default();
        let layout = self.layout(id).ok_or_else(|| ReflectError::NoStruct(name.clone()))?;
        let member_types = &self.struct_members[&id];
        let members = layout
            .into_iter()
            .zip(member_types)
            .map(|(member, &ty)| {
                let unsupported = |what: String| ReflectError::UnsupportedType {
                    block: name.clone(),
                    member: member.name.clone(),
                    what,
                };
                let ty = self.member_type(ty, &unsupported)?;
                Ok(TypedMember { name: member.name, offset: member.offset, ty })
            })
            .collect::<Result<_, ReflectError>>()?;
        Ok(StructType { name, members })
    }

    fn member_type(&self, id: u32, unsupported: &dyn Fn(String) -> ReflectError) -> Result<MemberType, ReflectError> {
        if self.struct_members.contains_key(&id) {
            return Ok(MemberType::Struct(self.struct_type(id)?));
        }
        if let Some(&(storage, _)) = self.pointers.get(&id) {
            return match storage {
                STORAGE_CLASS_PHYSICAL_STORAGE_BUFFER => Ok(MemberType::DeviceAddress),
                other => Err(unsupported(format!("a pointer of storage class {other}"))),
            };
        }
        match self.types.get(&id) {
            Some(&TypeOp::Int { .. } | &TypeOp::Float { .. }) => Ok(MemberType::Scalar(self.scalar(id, unsupported)?)),
            Some(&TypeOp::Vector { component, count }) => {
                Ok(MemberType::Vector(self.scalar(component, unsupported)?, count))
            }
            Some(&TypeOp::Array { element, length }) => {
                let stride = self.array_strides.get(&id).copied();
                match (length, stride) {
                    (1.., Some(stride)) => Ok(MemberType::Array {
                        element: Box::new(self.member_type(element, unsupported)?),
                        length,
                        stride,
                    }),
                    _ => Err(unsupported("an array without a constant length and stride".into())),
                }
            }
            None => Err(unsupported(format!("type id {id}: a matrix, bool or runtime array"))),
        }
    }

    fn scalar(&self, id: u32, unsupported: &dyn Fn(String) -> ReflectError) -> Result<Scalar, ReflectError> {
        match self.types.get(&id) {
            Some(TypeOp::Int { width: 32, signed: false }) => Ok(Scalar::U32),
            Some(TypeOp::Int { width: 32, signed: true }) => Ok(Scalar::I32),
            Some(TypeOp::Int { width: 64, signed: false }) => Ok(Scalar::U64),
            Some(TypeOp::Int { width: 64, signed: true }) => Ok(Scalar::I64),
            Some(TypeOp::Float { width: 32 }) => Ok(Scalar::F32),
            Some(TypeOp::Float { width: 64 }) => Ok(Scalar::F64),
            other => Err(unsupported(format!("{other:?}"))),
        }
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
