//! Pixel lists, the input of `path_trace`'s list mode: a per-view buffer holding a count and
//! then one x | y << 16 word per pixel. The reprojection pass will produce them from its hole
//! mask; until then [`StridedPixelListKernel`] writes a deterministic scattered selection, which
//! is what the subset-independence tests trace.

use parallax_backend::{BackendError, ExecPass, PassKernel, Recorder, ResourceKind};

/// Pass name of [`StridedPixelListKernel`].
pub const PIXEL_LIST: &str = "pixel_list";

/// Bytes of a pixel-list buffer able to hold `pixels` entries (count word included).
pub fn pixel_list_bytes(pixels: u64) -> u64 {
    4 * (pixels + 1)
}

/// The pixels a [`StridedPixelListKernel`] lists for a `width`×`height` view, in list order.
pub fn strided_pixels(width: u32, height: u32, stride: u32, phase: u32) -> Vec<(u32, u32)> {
    let n = width * height;
    (phase..n).step_by(stride.max(1) as usize).map(|l| (l % width, l / width)).collect()
}

/// Writes every `stride`-th pixel (row-major, from `phase`) of a `width`×`height` view into
/// `writes[0]`, a per-view buffer (which has no image shape, hence the size here). Entries
/// beyond the buffer's capacity are dropped.
pub struct StridedPixelListKernel {
    pub width: u32,
    pub height: u32,
    pub stride: u32,
    pub phase: u32,
}

impl PassKernel for StridedPixelListKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &ExecPass, index: usize) -> parallax_backend::Result<()> {
        let misuse = |detail: String| BackendError::KernelMisuse { kernel: PIXEL_LIST.into(), instance: index, detail };
        if pass.writes.len() != 1 || !pass.reads.is_empty() {
            return Err(misuse(format!(
                "expects 1 write (the list buffer) and no read, got {} and {}",
                pass.writes.len(),
                pass.reads.len()
            )));
        }
        let list = pass.writes[0].resource;
        if rec.resource(list).kind != ResourceKind::Buffer {
            return Err(misuse(format!("`{}` must be a buffer", rec.resource(list).name)));
        }
        let capacity = rec.resource(list).width.saturating_sub(1);
        let mut push = Vec::with_capacity(32);
        for word in [self.width, self.height, self.stride.max(1), self.phase, capacity, 0] {
            push.extend_from_slice(&word.to_le_bytes());
        }
        push.extend_from_slice(&rec.buffer_of(list)?.to_le_bytes());
        let groups = capacity.div_ceil(64).max(1);
        rec.dispatch_bytes("pixel_list_strided", &push, [groups.min(65535), groups.div_ceil(65535), 1])
    }
}
