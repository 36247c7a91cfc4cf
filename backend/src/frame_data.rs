//! The per-frame data ([`crate::Executor::set_frame`]): one blob per frame, copied into the
//! frame-in-flight slot's host-visible buffer at submission, cut into named sections so that
//! every pass finds its own parameters at its own offset ([`crate::Recorder::frame_section_address`]).
//!
//! Section addresses are baked into the recorded command buffers (kernels push them), so the
//! layout — names and offsets — is part of the recording: the executor records again when the
//! layout changes, never when only the bytes do. Building the same sections in the same order
//! every frame keeps the layout; put sections whose size varies last.

use crate::error::{BackendError, Result};

/// Alignment of every section: the largest `minStorageBufferOffsetAlignment` Vulkan allows, so a
/// section can hold any buffer-reference block (their alignments are at most 16) on any device.
pub const FRAME_SECTION_ALIGN: u64 = 256;

/// One frame's data: an optional unnamed blob at offset 0 ([`Self::whole`], what
/// `Recorder::frame_data_address` points at) followed by named sections.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameData {
    bytes: Vec<u8>,
    sections: Vec<(String, u64)>,
}

impl FrameData {
    /// No data and no sections.
    pub fn new() -> Self {
        Self::default()
    }

    /// `bytes` as one unnamed blob at offset 0 (what `Executor::set_frame_data` sets).
    pub fn whole(bytes: &[u8]) -> Self {
        Self { bytes: bytes.to_vec(), sections: Vec::new() }
    }

    /// Appends `bytes` as section `name` at the next multiple of [`FRAME_SECTION_ALIGN`];
    /// returns its offset from the start of the frame data.
    pub fn section(&mut self, name: &str, bytes: &[u8]) -> Result<u64> {
        if self.offset_of(name).is_some() {
            return Err(BackendError::DuplicateFrameSection(name.to_string()));
        }
        let offset = (self.bytes.len() as u64).next_multiple_of(FRAME_SECTION_ALIGN);
        self.bytes.resize(offset as usize, 0);
        self.bytes.extend_from_slice(bytes);
        self.sections.push((name.to_string(), offset));
        Ok(offset)
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
        assert_eq!(data.section("frame", &[7; 300]).unwrap(), 256);
        assert_eq!(data.section("fill", &[9; 4]).unwrap(), 768);
        assert_eq!(data.bytes().len(), 772);
        assert_eq!(&data.bytes()[..4], &[1, 2, 3, 0]);
        assert_eq!(data.bytes()[256], 7);
        assert_eq!(data.bytes()[768], 9);
        assert_eq!(data.offset_of("fill"), Some(768));
        assert_eq!(data.offset_of("missing"), None);
        let mut first = FrameData::new();
        assert_eq!(first.section("only", &[1]).unwrap(), 0, "no blob: the first section starts at 0");
    }

    #[test]
    fn a_section_name_is_taken_once() {
        let mut data = FrameData::new();
        data.section("frame", &[0; 4]).unwrap();
        assert!(matches!(data.section("frame", &[0; 4]), Err(BackendError::DuplicateFrameSection(n)) if n == "frame"));
    }
}
