//! Just enough SPIR-V reflection to hold a kernel's `#[repr(C)]` parameter struct against the
//! GLSL declaration it mirrors: the names and byte offsets of the push-constant block's
//! members, read from the module the build compiled (`glslc -g` keeps the names).
//!
//! A test per kernel compares these with `std::mem::offset_of!` on the Rust struct, so a field
//! added, moved or retyped on one side only fails the build's tests instead of shading garbage.

use std::collections::HashMap;

const OP_NAME_MEMBER: u32 = 6;
const OP_TYPE_POINTER: u32 = 32;
const OP_VARIABLE: u32 = 59;
const OP_MEMBER_DECORATE: u32 = 72;
const DECORATION_OFFSET: u32 = 35;
const STORAGE_CLASS_PUSH_CONSTANT: u32 = 9;

/// One member of a block: its name and byte offset.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockMember {
    pub name: String,
    pub offset: u32,
}

/// The members of the push-constant block of `spirv` in declaration order, or `None` if the
/// module has no push constants (or is not SPIR-V).
pub fn push_constant_members(spirv: &[u32]) -> Option<Vec<BlockMember>> {
    if spirv.len() < 5 || spirv[0] != 0x0723_0203 {
        return None;
    }
    let mut names: HashMap<(u32, u32), String> = HashMap::new();
    let mut offsets: HashMap<(u32, u32), u32> = HashMap::new();
    let mut pointee: HashMap<u32, (u32, u32)> = HashMap::new();
    let mut push_pointer = None;
    let mut at = 5;
    while at < spirv.len() {
        let (count, opcode) = ((spirv[at] >> 16) as usize, spirv[at] & 0xffff);
        if count == 0 || at + count > spirv.len() {
            return None;
        }
        let args = &spirv[at + 1..at + count];
        match opcode {
            OP_NAME_MEMBER if args.len() >= 3 => {
                names.insert((args[0], args[1]), literal_string(&args[2..]));
            }
            OP_MEMBER_DECORATE if args.len() >= 4 && args[2] == DECORATION_OFFSET => {
                offsets.insert((args[0], args[1]), args[3]);
            }
            OP_TYPE_POINTER if args.len() >= 3 => {
                pointee.insert(args[0], (args[1], args[2]));
            }
            OP_VARIABLE if args.len() >= 3 && args[2] == STORAGE_CLASS_PUSH_CONSTANT => push_pointer = Some(args[0]),
            _ => {}
        }
        at += count;
    }
    let (_, block) = pointee.get(&push_pointer?).copied()?;
    let mut members: Vec<(u32, BlockMember)> = offsets
        .iter()
        .filter(|((ty, _), _)| *ty == block)
        .map(|(&(_, member), &offset)| {
            let name = names.get(&(block, member)).cloned().unwrap_or_default();
            (member, BlockMember { name, offset })
        })
        .collect();
    members.sort_by_key(|(member, _)| *member);
    Some(members.into_iter().map(|(_, m)| m).collect())
}

/// A nul-terminated UTF-8 string packed into words.
fn literal_string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).take_while(|&b| b != 0).collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// `(name, offset)` pairs of a `#[repr(C)]` struct's fields, for comparing with
/// [`push_constant_members`]: `rust_layout!(PathTracePush { scene, trace, ... })`.
#[macro_export]
macro_rules! rust_layout {
    ($ty:ty { $($field:ident),* $(,)? }) => {
        vec![$($crate::reflect::BlockMember {
            name: stringify!($field).to_string(),
            offset: std::mem::offset_of!($ty, $field) as u32,
        }),*]
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recorder::PassParams;

    #[test]
    fn the_shared_pass_params_match_bindless_glsl() {
        let spirv = crate::spirv("fill").unwrap();
        let glsl = push_constant_members(&spirv).expect("fill.comp has push constants");
        let rust = rust_layout!(PassParams { dst, src0, src1, view, y0, y1, width, param });
        assert_eq!(glsl, rust);
    }

    #[test]
    fn bytes_that_are_not_spirv_have_no_layout() {
        assert_eq!(push_constant_members(&[1, 2, 3, 4, 5, 6]), None);
    }
}
