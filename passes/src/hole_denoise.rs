//! Denoising the hole pixels of targets when the pipeline denoises in sample space
//! (`--denoise samples`, [`crate::pipeline::Denoiser::Samples`]): SVGF ran on the sources before
//! reprojection, so a target's reprojected pixels are denoised already and only the pixels hole
//! filling traced carry fresh samples. `hole_temporal` (shaders/hole_temporal.comp) runs on
//! exactly those, one invocation per entry of the band's `hole_list` (an indirect dispatch on the
//! list's own header), so it costs in proportion to the holes, not to the views: on a still
//! camera each hole pixel becomes the exact running mean of its samples since the camera last
//! changed; any other frame restarts it (the shader says why and how stale texels are told).
//!
//! Not done: a spatial filter at hole pixels, and accumulation through `motion` on a moving
//! camera (it would need the history rows around a band, as `svgf_history` copies them for
//! SVGF): under motion a hole pixel shows its frame's own sample (docs/PIPELINE.md).

use std::sync::Arc;

use crate::shaders::{self, HoleTemporalPush};
use parallax_backend::{BackendError, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder, ResourceKind};
use parallax_graph::{Buffer, Format, Handle, HistorySlot, Image, ReadSlot, Role, WriteSlot};

/// Pass name.
pub const HOLE_TEMPORAL: &str = "hole_temporal";
/// Accumulation history at hole pixels: the running mean of the radiance (rgb) and its frames.
pub const HOLE_ACCUM: &str = "hole_accum";
/// The frame each `hole_accum` texel was written in (R32f, the frame index mod 2^24).
pub const HOLE_STAMP: &str = "hole_stamp";

/// Declares `hole_temporal` for every target: reads the band's `hole_list` (as `compact_holes`
/// wrote it) and last frame's `hole_accum` and `hole_stamp`, and modifies `radiance` (the
/// targets' radiance after hole filling) in place at the listed pixels only. With
/// `reconstructed` (subsampled hole filling, [`crate::hole_subsample`]) it also carries the
/// history of the pixels of that list, which were not traced, without adding to it. Returns
/// this frame's `hole_accum`.
pub fn declare_hole_denoise(
    graph: &mut KernelGraph,
    hole_list: &Handle<Buffer>,
    reconstructed: Option<&Handle<Buffer>>,
    radiance: &mut Handle<Image>,
) -> Handle<Image> {
    let mut accum = graph.image(HOLE_ACCUM, Format::Rgba32f);
    let mut stamp = graph.image(HOLE_STAMP, Format::R32f);
    let mut pass = graph.pass(HOLE_TEMPORAL, Role::Targets);
    let slots = HoleTemporalSlots {
        list: pass.read_slot(hole_list),
        reconstructed: reconstructed.map(|list| pass.read_slot(list)),
        // Read at the pixel's own texel only (a still camera reprojects onto itself).
        accum_before: pass.read_history_slot(&accum),
        stamp_before: pass.read_history_slot(&stamp),
        accum: pass.write_slot(&mut accum),
        stamp: pass.write_slot(&mut stamp),
        radiance: pass.modify_slot(radiance).1,
    };
    pass.kernel(Arc::new(HoleTemporalKernel(slots))).add();
    accum
}

/// What `hole_temporal` declared.
#[derive(Clone, Copy, Debug)]
struct HoleTemporalSlots {
    list: ReadSlot,
    /// The pixels whose history is carried, not added to (subsampled hole filling).
    reconstructed: Option<ReadSlot>,
    accum_before: HistorySlot,
    stamp_before: HistorySlot,
    accum: WriteSlot,
    stamp: WriteSlot,
    radiance: WriteSlot,
}

/// Records `hole_temporal` instances: one indirect dispatch on the band's list header, and one
/// on its reconstructed list's where declared.
struct HoleTemporalKernel(HoleTemporalSlots);

/// `HoleTemporalPush::carry`: the listed pixels' history is carried (shaders/hole_temporal.comp).
const CARRY: u32 = 1;

impl PassKernel for HoleTemporalKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let slots = &self.0;
        let history = |rec: &Recorder<'_>, slot: HistorySlot| rec.image(pass.history_read(slot)?.alloc);
        let write = |rec: &Recorder<'_>, slot: WriteSlot| rec.image(pass.write(slot)?.alloc);
        let push = HoleTemporalPush {
            list: 0,
            block: rec.frame_block_address()?,
            radiance: write(rec, slots.radiance)?,
            accum_in: history(rec, slots.accum_before)?,
            stamp_in: history(rec, slots.stamp_before)?,
            accum_out: write(rec, slots.accum)?,
            stamp_out: write(rec, slots.stamp)?,
            view: pass.view.0,
            carry: 0,
            pad: 0,
        };
        dispatch_over(rec, pass, index, slots.list, push)?;
        match slots.reconstructed {
            Some(list) => dispatch_over(rec, pass, index, list, HoleTemporalPush { carry: CARRY, ..push }),
            None => Ok(()),
        }
    }
}

/// One indirect dispatch of `push` over the band's section of the pixel list `slot`.
fn dispatch_over(
    rec: &mut Recorder<'_>,
    pass: &PassInstance,
    index: InstanceId,
    slot: ReadSlot,
    push: HoleTemporalPush,
) -> parallax_backend::Result<()> {
    let list = pass.read(slot)?;
    let buffer = rec.resource(list.alloc);
    if buffer.kind != ResourceKind::Buffer {
        let detail = format!("its read `{}` must be a pixel list's row buffer", buffer.name);
        return Err(BackendError::KernelMisuse { kernel: HOLE_TEMPORAL.into(), instance: Some(index), detail });
    }
    if list.region.is_empty() {
        return Ok(());
    }
    let offset = u64::from(list.region.y0) * buffer.row_bytes();
    let push = HoleTemporalPush { list: rec.buffer_of(list.alloc)? + offset, ..push };
    // The header's first three words are the indirect arguments (pixel_list.glsl).
    rec.dispatch_indirect(shaders::HOLE_TEMPORAL, &push, list.alloc, offset)
}
