//! Push-constant blocks held against the shader that reads them.
//!
//! A kernel's push constants are a `#[repr(C)]` struct that implements [`PushConstants`]
//! (through [`push_constants!`]), naming its fields and their offsets. When the backend creates
//! a compute pipeline it reflects the shader's push-constant block from the SPIR-V
//! ([`crate::reflect::push_constant_block`]); every dispatch compares the two, so a field that
//! moved, was renamed or is missing on either side is an error naming the pass, the shader and
//! the field before anything runs, rather than a shader reading the wrong word.

use crate::reflect::{MemberLayout, push_constant_block};

/// Bytes of the smallest member a block can have (a 32-bit scalar).
const SCALAR_BYTES: u32 = 4;

/// A push-constant block: plain bytes (`Pod`) with the fields the shader reads, by name and
/// byte offset in declaration order. Implement it with [`push_constants!`].
pub trait PushConstants: bytemuck::Pod {
    const FIELDS: &'static [(&'static str, u32)];
}

/// A shader without push constants is dispatched with `&()`.
impl PushConstants for () {
    const FIELDS: &'static [(&'static str, u32)] = &[];
}

/// Implements [`PushConstants`] for a `#[repr(C)]` struct from the list of its fields, in
/// declaration order, named as the GLSL block names its members:
/// `push_constants!(TonemapPush { src, dst, y0, y1, width, exposure });`.
#[macro_export]
macro_rules! push_constants {
    ($ty:ty { $($field:ident),* $(,)? }) => {
        impl $crate::PushConstants for $ty {
            const FIELDS: &'static [(&'static str, u32)] =
                &[$((stringify!($field), std::mem::offset_of!($ty, $field) as u32)),*];
        }
    };
}

/// Where a Rust push-constant struct and a shader's block disagree.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LayoutMismatch {
    /// The member (or field) at fault, as the shader or the struct names it.
    pub field: String,
    pub problem: String,
}

/// Holds `P` against the push-constant block of the SPIR-V module `words` as a dispatch does,
/// without a GPU: what a kernel's unit test asserts for each shader it dispatches.
pub fn check_push_constants<P: PushConstants>(words: &[u32]) -> Result<(), LayoutMismatch> {
    match push_constant_block(words) {
        Ok(Some((_, members))) => compare(P::FIELDS, std::mem::size_of::<P>(), &members),
        Ok(None) => Ok(()),
        Err(defect) => Err(LayoutMismatch { field: String::new(), problem: defect.to_string() }),
    }
}

/// Compares `fields` of a `size`-byte struct with a shader's push-constant `block` (members in
/// declaration order). Members are matched by name; a module without debug info has no names,
/// and its members are then matched by position.
pub(crate) fn compare(fields: &[(&str, u32)], size: usize, block: &[MemberLayout]) -> Result<(), LayoutMismatch> {
    let mismatch = |field: &str, problem: String| Err(LayoutMismatch { field: field.to_string(), problem });
    let named = block.iter().all(|m| !m.name.is_empty());
    for (i, member) in block.iter().enumerate() {
        let field = if named { fields.iter().find(|(name, _)| *name == member.name) } else { fields.get(i) };
        let label = if named { member.name.clone() } else { format!("member {i}") };
        match field {
            None => {
                return mismatch(
                    &label,
                    format!("the shader reads it at byte {}, the struct has no such field", member.offset),
                );
            }
            Some(&(_, offset)) if offset != member.offset => {
                return mismatch(
                    &label,
                    format!("the shader reads it at byte {}, the struct puts it at byte {offset}", member.offset),
                );
            }
            Some(_) if member.offset + SCALAR_BYTES > size as u32 => {
                return mismatch(
                    &label,
                    format!("the shader reads it at byte {}, past the struct's {size} bytes", member.offset),
                );
            }
            Some(_) => {}
        }
    }
    let extra = if named {
        fields.iter().find(|(name, _)| !block.iter().any(|m| m.name == *name))
    } else {
        fields.get(block.len())
    };
    if let Some(&(name, offset)) = extra {
        return mismatch(name, format!("the struct has it at byte {offset}, the shader's block has no such member"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn member(name: &str, offset: u32) -> MemberLayout {
        MemberLayout { name: name.into(), offset, array_stride: None }
    }

    #[repr(C)]
    #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
    struct Twin {
        a: u32,
        b: u32,
        c: u64,
    }
    push_constants!(Twin { a, b, c });

    #[test]
    fn the_macro_lists_fields_with_their_offsets() {
        assert_eq!(Twin::FIELDS, &[("a", 0), ("b", 4), ("c", 8)]);
    }

    #[test]
    fn a_matching_block_passes_by_name_and_without_names_by_position() {
        let block = [member("a", 0), member("b", 4), member("c", 8)];
        assert_eq!(compare(Twin::FIELDS, 16, &block), Ok(()));
        let unnamed = [member("", 0), member("", 4), member("", 8)];
        assert_eq!(compare(Twin::FIELDS, 16, &unnamed), Ok(()));
    }

    #[test]
    fn each_difference_names_its_field() {
        let field = |block: &[MemberLayout]| compare(Twin::FIELDS, 16, block).unwrap_err().field;
        assert_eq!(field(&[member("a", 0), member("b", 8), member("c", 12)]), "b", "moved");
        assert_eq!(field(&[member("a", 0), member("b", 4), member("c", 8), member("d", 12)]), "d", "missing in Rust");
        assert_eq!(field(&[member("a", 0), member("b", 4)]), "c", "missing in the shader");
        assert_eq!(field(&[member("a", 0), member("bee", 4), member("c", 8)]), "bee", "renamed");
        assert_eq!(field(&[member("", 0), member("", 8), member("", 12)]), "member 1", "moved, no debug info");
    }
}
