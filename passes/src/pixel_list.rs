//! Pixel lists, the input of `path_trace`'s list mode and of hole filling
//! (shaders/pixel_list.glsl). A list lives in one band's section of a buffer:
//! [`LIST_HEADER_WORDS`] header words `groups_x, groups_y, groups_z, count`, then `count` words
//! `x | y << 16`. The header doubles as indirect arguments covering exactly the listed entries,
//! for a consumer dispatched indirectly on one list; `path_trace` dispatches the section's
//! capacity instead and stops at `count`, and hole filling sums the counts of all its lists
//! into one indirect dispatch ([`crate::HoleFillKernel`]). A per-band list lives in a row buffer
//! (`hole_list`, [`crate::holes`]), band `[y0, y1)` at byte `y0 * row_bytes`; a whole-view list
//! in a plain buffer is one band at byte 0.
//!
//! [`StridedPixelListKernel`] writes a deterministic scattered selection into a plain buffer,
//! which is what the subset-independence tests trace.

use crate::shaders::{self, StridedListPush};
use parallax_backend::{BackendError, InstanceId, PassInstance, PassKernel, Recorder, ResourceKind, WriteSlot};

/// Pass name of [`StridedPixelListKernel`].
pub const PIXEL_LIST: &str = "pixel_list";

/// Words before a list's entries: `groups_x, groups_y, groups_z, count`.
pub const LIST_HEADER_WORDS: u32 = 4;

/// Invocations per workgroup of the kernels that trace a list (pt_trace.comp).
pub const LIST_GROUP: u32 = 64;

/// Workgroups along one axis that every Vulkan device supports.
const MAX_GROUPS: u32 = 65535;

/// Bytes of a pixel-list buffer able to hold `pixels` entries (header included).
pub fn pixel_list_bytes(pixels: u64) -> u64 {
    4 * (pixels + u64::from(LIST_HEADER_WORDS))
}

/// The indirect arguments a list of `count` entries carries (`pixel_list_groups` of
/// shaders/pixel_list.glsl): `[ceil(count / 64), 1, 1]`, folded into more rows of groups only
/// beyond 65535 groups.
pub fn list_groups(count: u32) -> [u32; 3] {
    let groups = count.div_ceil(LIST_GROUP);
    [groups.min(MAX_GROUPS), groups.div_ceil(MAX_GROUPS).max(1), 1]
}

/// The pixels a [`StridedPixelListKernel`] lists for a `width`×`height` view, in list order.
pub fn strided_pixels(width: u32, height: u32, stride: u32, phase: u32) -> Vec<(u32, u32)> {
    let n = width * height;
    (phase..n).step_by(stride.max(1) as usize).map(|l| (l % width, l / width)).collect()
}

/// Every `stride`-th pixel (row-major, from `phase`) of a `width`×`height` view: the list a
/// [`StridedPixelListKernel`] writes (the view's size is given here because the list is a plain
/// buffer, which has no image shape).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StridedPixels {
    pub width: u32,
    pub height: u32,
    pub stride: u32,
    pub phase: u32,
}

/// Writes the [`StridedPixels`] of `pixels` into its `list` write, a per-view plain buffer, as
/// one whole-view list. Entries beyond the buffer's capacity are dropped.
pub struct StridedPixelListKernel {
    pub pixels: StridedPixels,
    pub list: WriteSlot,
}

impl PassKernel for StridedPixelListKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let misuse =
            |detail: String| BackendError::KernelMisuse { kernel: PIXEL_LIST.into(), instance: Some(index), detail };
        let list = pass.write(self.list)?.alloc;
        let desc = rec.resource(list);
        if desc.kind != ResourceKind::Buffer || desc.height != 1 || desc.width < LIST_HEADER_WORDS {
            return Err(misuse(format!("`{}` must be a plain buffer with room for the list header", desc.name)));
        }
        let capacity = desc.width - LIST_HEADER_WORDS;
        let StridedPixels { width, height, stride, phase } = self.pixels;
        let push = StridedListPush {
            width,
            height,
            stride: stride.max(1),
            phase,
            capacity,
            pad: 0,
            list: rec.buffer_of(list)?,
        };
        let groups = capacity.div_ceil(LIST_GROUP).max(1);
        rec.dispatch(shaders::PIXEL_LIST_STRIDED, &push, [groups.min(MAX_GROUPS), groups.div_ceil(MAX_GROUPS), 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn list_groups_cover_the_count_and_fold_beyond_one_axis() {
        assert_eq!(list_groups(0), [0, 1, 1]);
        assert_eq!(list_groups(1), [1, 1, 1]);
        assert_eq!(list_groups(64), [1, 1, 1]);
        assert_eq!(list_groups(65), [2, 1, 1]);
        assert_eq!(list_groups(65535 * 64), [65535, 1, 1]);
        assert_eq!(list_groups(65535 * 64 + 1), [65535, 2, 1]);
        for count in [0, 1, 63, 64, 65, 4096 * 4096, u32::MAX] {
            let [x, y, z] = list_groups(count);
            assert!(u64::from(x) * u64::from(y) * u64::from(z) * 64 >= u64::from(count), "{count}");
        }
    }
}
