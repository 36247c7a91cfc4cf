//! The per-frame data ([`crate::Executor::set_frame`]): one blob per frame, copied into the
//! frame-in-flight slot's host-visible buffer at submission, cut into named sections so that
//! every pass finds its own parameters at its own offset ([`crate::Recorder::frame_section_address`]),
//! and the frame block of cameras, which every pass finds without a name
//! ([`crate::Recorder::frame_block_address`]).
//!
//! Section addresses are baked into the recorded command buffers (kernels push them), so the
//! layout — names and offsets — is part of the recording: the executor records again when the
//! layout changes, never when only the bytes do. Building the same sections in the same order
//! every frame keeps the layout; put sections whose size varies last.

use crate::error::{BackendError, Result};
use crate::frame_block::FrameBlock;

/// Alignment of every section: the largest `minStorageBufferOffsetAlignment` Vulkan allows, so a
/// section can hold any buffer-reference block (their alignments are at most 16) on any device.
pub const FRAME_SECTION_ALIGN: u64 = 256;

/// One frame's data: an optional unnamed blob at offset 0 ([`Self::whole`], what
/// `Recorder::frame_data_address` points at) followed by named sections and at most one frame
/// block, in the order they were added.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameData {
    bytes: Vec<u8>,
    sections: Vec<(String, u64)>,
    frame_block: Option<u64>,
}

impl FrameData {
    /// No data and no sections.
    pub fn new() -> Self {
        Self::default()
    }

    /// `bytes` as one unnamed blob at offset 0 (what `Executor::set_frame_data` sets).
    pub fn whole(bytes: &[u8]) -> Self {
        Self { bytes: bytes.to_vec(), sections: Vec::new(), frame_block: None }
    }

    /// Appends `bytes` as section `name` at the next multiple of [`FRAME_SECTION_ALIGN`];
    /// returns its offset from the start of the frame data.
    pub fn section(&mut self, name: &str, bytes: &[u8]) -> Result<u64> {
        if self.offset_of(name).is_some() {
            return Err(BackendError::DuplicateFrameSection(name.to_string()));
        }
        let offset = self.append(bytes);
        self.sections.push((name.to_string(), offset));
        Ok(offset)
    }

    /// Appends the frame's `block` of cameras at the next multiple of [`FRAME_SECTION_ALIGN`];
    /// returns its offset. A frame has one block.
    pub fn frame_block(&mut self, block: &FrameBlock) -> Result<u64> {
        if self.frame_block.is_some() {
            return Err(BackendError::DuplicateFrameBlock);
        }
        let offset = self.append(&block.to_bytes());
        self.frame_block = Some(offset);
        Ok(offset)
    }

    /// Offset of the frame block, if the frame has one.
    pub fn frame_block_offset(&self) -> Option<u64> {
        self.frame_block
    }

    /// Whether `other` lays its sections and frame block out where this frame does: what the
    /// recorded command buffers depend on (the bytes may differ).
    pub fn same_layout(&self, other: &FrameData) -> bool {
        self.sections == other.sections && self.frame_block == other.frame_block
    }

    fn append(&mut self, bytes: &[u8]) -> u64 {
        let offset = (self.bytes.len() as u64).next_multiple_of(FRAME_SECTION_ALIGN);
        self.bytes.resize(offset as usize, 0);
        self.bytes.extend_from_slice(bytes);
        offset
    }

    /// Offset of section `name`.
    pub fn offset_of(&self, name: &str) -> Option<u64> {
        self.sections.iter().find(|(n, _)| n == name).map(|&(_, offset)| offset)
    }

    /// All bytes, sections included.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Section names and offsets, in the order they were added.
    pub fn sections(&self) -> &[(String, u64)] {
        &self.sections
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sections_are_aligned_after_the_blob_and_each_other() {
        let mut data = FrameData::whole(&[1, 2, 3]);
        assert_eq!(data.section("params", &[7; 300]).unwrap(), 256);
        assert_eq!(data.section("fill", &[9; 4]).unwrap(), 768);
        let block = crate::FrameClock::new().advance(&[crate::GpuCamera::default()]);
        assert_eq!(data.frame_block(&block).unwrap(), 1024);
        assert_eq!(data.bytes().len(), 1024 + block.to_bytes().len());
        assert_eq!(&data.bytes()[..4], &[1, 2, 3, 0]);
        assert_eq!(data.bytes()[256], 7);
        assert_eq!(data.bytes()[768], 9);
        assert_eq!(data.bytes()[1024], 1, "the block's view count");
        assert_eq!(data.offset_of("fill"), Some(768));
        assert_eq!(data.frame_block_offset(), Some(1024));
        assert_eq!(data.offset_of("missing"), None);
        let mut first = FrameData::new();
        assert_eq!(first.section("only", &[1]).unwrap(), 0, "no blob: the first section starts at 0");
    }

    #[test]
    fn a_section_name_is_taken_once() {
        let mut data = FrameData::new();
        data.section("fill", &[0; 4]).unwrap();
        assert!(matches!(data.section("fill", &[0; 4]), Err(BackendError::DuplicateFrameSection(n)) if n == "fill"));
        let block = crate::FrameBlock::default();
        data.frame_block(&block).unwrap();
        assert!(matches!(data.frame_block(&block), Err(BackendError::DuplicateFrameBlock)));
    }

    #[test]
    fn the_layout_is_the_sections_and_the_block_not_the_bytes() {
        let with = |salt: u8, block: bool| {
            let mut data = FrameData::whole(&[salt]);
            data.section("fill", &[salt; 4]).unwrap();
            if block {
                data.frame_block(&crate::FrameBlock::default()).unwrap();
            }
            data
        };
        assert!(with(1, true).same_layout(&with(2, true)));
        assert!(!with(1, true).same_layout(&with(1, false)));
    }
}
