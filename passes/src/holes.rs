//! Hole filling (paper §3.3, Table 1 stage 5), per row band: `compact_holes`
//! (shaders/compact_holes.comp) turns the `holes` mask of its band into the band's pixel list in
//! the `hole_list` row buffer, and `hole_fill` path traces exactly the listed pixels
//! (one indirect dispatch for all target bands of a device, sized by the lists' counts), so no
//! hole ray is dropped. Both passes split into bands like any other, so under the fine schemes
//! each device compacts and fills its own strips.
//! Formats: docs/PIPELINE.md (`holes`, `hole_list`, `radiance`).
//!
//! The `hole_fill` kernel ([`HoleFillKernel`]) path traces the holes that `compact_holes` listed, for every target
//! band of one device in one op. The executor hands it each run of consecutive `hole_fill`
//! instances that no barrier separates ([`PassKernel::record_group`]); it records two
//! dispatches for the whole run:
//!
//! 1. shaders/hole_fill_prefix.comp (one workgroup) reads each band's hole count and numbers
//!    workgroups of 64 holes over all bands, each band starting a workgroup of its own; it
//!    writes their first workgroups and the indirect arguments into the op's target table;
//! 2. shaders/hole_fill.comp, one indirect dispatch of exactly those workgroups: each finds its
//!    band by binary search and traces its 64 entries with that band's view parameters.
//!
//! With a first-hit G-buffer the pass also reads its `first_hit` layer (the BVH primitive each
//! pixel's centre ray hit): a camera ray that hits that triangle too traverses the BVH only up
//! to it (shaders/pt_trace.glsl, `closest_hit_from`), with the bits of the unbounded traversal.
//! The camera rays stay the path tracer's jittered ones, so the G-buffer can stay at the pixel
//! centres that SVGF's guides and still-camera accumulation need (docs/PIPELINE.md, `hole_fill`).
//!
//! One dispatch per target, each over its band's capacity, left the GPU mostly idle or busy
//! with empty workgroups: on an H200 12.9 ns per hole against 8.6 ns per pixel of a full-view
//! trace for 99 targets (docs/RESULTS.md); indirect dispatches per target ran one after
//! another. The table ([`HoleFillTarget`] per band) is a recording buffer: addresses and image
//! indices are known when the op is recorded, the counts only on the GPU.

use std::sync::Arc;

use parallax_backend::{
    BackendError, Format, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder, ResourceKind,
};
use parallax_graph::{Access, Buffer, Handle, Image, ReadSlot, Role, WriteSlot};

use crate::path_trace::{NO_IMAGE, TRACE_PARAMS_BYTES, list_section};
use crate::pixel_list::LIST_HEADER_WORDS;
use crate::scene_upload::scene_refs;
use crate::shaders::{self, CompactHolesPush, HoleFillPrefixPush, HoleFillPush};

/// Pass name of [`CompactHolesKernel`].
pub const COMPACT_HOLES: &str = "compact_holes";
/// Pass name of the hole-filling path trace.
pub const HOLE_FILL: &str = "hole_fill";
/// Slot of the hole mask (R32u, nonzero = hole).
pub const HOLES: &str = "holes";
/// Slot of the per-band hole lists.
pub const HOLE_LIST: &str = "hole_list";

/// Bytes per image row of the `hole_list` row buffer of a `width`-wide view: room for an entry
/// per pixel plus four words, so every band, even of one row, has room for its header and an
/// entry for each of its pixels.
pub fn hole_list_row_bytes(width: u32) -> u64 {
    4 * (u64::from(width) + u64::from(LIST_HEADER_WORDS))
}

/// Declares hole filling for every target view: `compact_holes` reads `holes` and accumulates
/// into the returned `hole_list` row buffer (reset to zeros each frame), then `hole_fill` path
/// traces the listed pixels into `radiance` in place, so the pixels that are not holes keep
/// what was there (the reprojected radiance). `hole_fill` reads its views' `GpuTraceParams`
/// from the per-frame data like `path_trace` ([`crate::trace_frame_data`]) and, when given,
/// the G-buffer's `first_hit` layer, which bounds its camera rays' traversals
/// ([`HoleFillKernel`]).
pub fn declare_hole_fill(
    graph: &mut KernelGraph,
    holes: &Handle<Image>,
    first_hit: Option<&Handle<Image>>,
    radiance: &mut Handle<Image>,
) -> Handle<Buffer> {
    let mut list = graph.row_buffer(HOLE_LIST, hole_list_row_bytes(graph.topology().width));
    graph.reset_each_frame(&list, Vec::new());
    let mut pass = graph.pass(COMPACT_HOLES, Role::Targets);
    let (holes, (_, written_list)) = (pass.read_slot(holes), pass.modify_slot(&mut list));
    pass.kernel(Arc::new(CompactHolesKernel { holes, list: written_list })).add();
    declare_hole_trace(graph, &list, first_hit, radiance);
    list
}

/// Declares `hole_fill`: path traces the pixels of `list` (as a compaction pass wrote it) into
/// `radiance` in place, its camera rays bounded by `first_hit` where given.
pub(crate) fn declare_hole_trace(
    graph: &mut KernelGraph,
    list: &Handle<Buffer>,
    first_hit: Option<&Handle<Image>>,
    radiance: &mut Handle<Image>,
) {
    let mut pass = graph.pass(HOLE_FILL, Role::Targets);
    let read_list = pass.read_slot(list);
    let first_hit = first_hit.map(|layer| pass.read_slot(layer));
    let (_, radiance) = pass.modify_slot(radiance);
    pass.kernel(Arc::new(HoleFillKernel { list: read_list, first_hit, radiance })).grouped().add();
}

/// The address of a band's section of a pixel-list row buffer (`list`, written by `kernel`'s
/// instance `index` over a `width` × `height` view), after checking that it is one: a row
/// buffer of `height` rows whose band section holds its header and an entry per pixel.
pub(crate) fn band_list_address(
    rec: &Recorder<'_>,
    list: &Access,
    (width, height): (u32, u32),
    kernel: &str,
    index: InstanceId,
) -> parallax_backend::Result<u64> {
    let buffer = rec.resource(list.alloc);
    let rows = u64::from(list.region.len());
    let fits = rows * buffer.row_bytes() >= 4 * (rows * u64::from(width) + u64::from(LIST_HEADER_WORDS));
    if buffer.kind != ResourceKind::Buffer || buffer.height != height || !fits {
        return Err(BackendError::KernelMisuse {
            kernel: kernel.into(),
            instance: Some(index),
            detail: format!(
                "`{}` must be a row buffer of {height} rows and at least {} bytes per row",
                buffer.name,
                hole_list_row_bytes(width)
            ),
        });
    }
    Ok(rec.buffer_of(list.alloc)? + u64::from(list.region.y0) * buffer.row_bytes())
}

/// Records `compact_holes` instances: reads slot [`HOLES`] (an R32u image) over the band and
/// modifies slot [`HOLE_LIST`] (a row buffer of at least [`hole_list_row_bytes`] per row).
pub struct CompactHolesKernel {
    holes: ReadSlot,
    list: WriteSlot,
}

impl PassKernel for CompactHolesKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let misuse =
            |detail: String| BackendError::KernelMisuse { kernel: COMPACT_HOLES.into(), instance: Some(index), detail };
        let (holes, list) = (pass.read(self.holes)?, pass.write(self.list)?);
        let mask = rec.resource(holes.alloc);
        if mask.kind != ResourceKind::Image || mask.format != Format::R32u {
            return Err(misuse(format!("`{}` must be an R32u image", mask.name)));
        }
        let width = mask.width;
        let address = band_list_address(rec, list, (width, mask.height), COMPACT_HOLES, index)?;
        if list.region.is_empty() {
            return Ok(());
        }
        let push = CompactHolesPush {
            list: address,
            holes: rec.image(holes.alloc)?,
            y0: list.region.y0,
            y1: list.region.y1,
            width,
        };
        // 8x8-pixel tiles, one workgroup each (see compact_holes.comp).
        rec.dispatch(shaders::COMPACT_HOLES, &push, [width.div_ceil(8), list.region.len().div_ceil(8), 1])
    }
}

/// Bytes of the target table before its [`HoleFillTarget`]s: the indirect arguments and the
/// workgroup total (`HoleFillTable` in shaders/hole_fill.glsl).
pub const TABLE_HEADER_BYTES: usize = 16;

/// One target band of a `hole_fill` op (`HoleFillTarget` in shaders/hole_fill.glsl; a test
/// holds the two layouts together).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct HoleFillTarget {
    /// Address of the band's section of the hole list.
    pub list: u64,
    /// Address of the view's `GpuTraceParams` in the slot's per-frame data.
    pub trace: u64,
    /// Image index of the view's radiance.
    pub radiance: u32,
    /// Written by hole_fill_prefix.comp every frame: the band's first workgroup and count.
    pub first_group: u32,
    pub count: u32,
    /// Image index of the view's `first_hit` G-buffer layer (R32u), [`NO_IMAGE`] without one.
    pub first_hit: u32,
}

/// Records `hole_fill` instances: each reads its band's section of [`HOLE_LIST`] (as
/// `compact_holes` writes it) and, when declared, the view's `first_hit` layer over its band
/// (an R32u image, [`crate::gbuffer`]), and modifies the view's radiance (a float image),
/// writing nothing else; the views' `GpuTraceParams` come from the per-frame data like
/// `path_trace`'s ([`crate::trace_frame_data`]).
pub struct HoleFillKernel {
    list: ReadSlot,
    first_hit: Option<ReadSlot>,
    radiance: WriteSlot,
}

impl PassKernel for HoleFillKernel {
    fn record(&self, rec: &mut Recorder<'_>, _pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        self.record_group(rec, &[index])
    }

    fn records_groups(&self) -> bool {
        true
    }

    fn record_group(&self, rec: &mut Recorder<'_>, instances: &[InstanceId]) -> parallax_backend::Result<()> {
        let plan = rec.plan();
        let mut table = vec![0u8; TABLE_HEADER_BYTES];
        for &index in instances {
            let target = self.target_of(rec, plan.pass(index), index)?;
            table.extend_from_slice(bytemuck::bytes_of(&target));
        }
        let target_count = u32::try_from(instances.len()).map_err(|_| BackendError::KernelMisuse {
            kernel: HOLE_FILL.into(),
            instance: Some(instances[0]),
            detail: format!("{} instances in one op", instances.len()),
        })?;
        let table = rec.recording_buffer("hole fill targets", &table)?;
        let prefix = HoleFillPrefixPush { table: table.address(), target_count, pad: 0 };
        rec.dispatch(shaders::HOLE_FILL_PREFIX, &prefix, [1, 1, 1])?;
        let fill = HoleFillPush { scene: scene_refs(rec)?, table: table.address(), target_count, pad: 0 };
        // The arguments are the table's first words.
        rec.dispatch_indirect_from(shaders::HOLE_FILL, &fill, &table, 0)
    }
}

impl HoleFillKernel {
    /// The table entry of instance `index`, after checking its slots.
    fn target_of(
        &self,
        rec: &Recorder<'_>,
        pass: &PassInstance,
        index: InstanceId,
    ) -> parallax_backend::Result<HoleFillTarget> {
        let misuse =
            |detail: String| BackendError::KernelMisuse { kernel: HOLE_FILL.into(), instance: Some(index), detail };
        let (list, radiance) = (pass.read(self.list)?, pass.write(self.radiance)?);
        if pass.writes.len() != 1 {
            return Err(misuse("writes its radiance only".into()));
        }
        let image = rec.resource(radiance.alloc);
        if image.kind != ResourceKind::Image || image.format == Format::R32u || image.format.is_depth() {
            return Err(misuse(format!("its write `{}` must be a float image", image.name)));
        }
        let first_hit = match self.first_hit {
            Some(slot) => {
                let layer = pass.read(slot)?.alloc;
                let desc = rec.resource(layer);
                if desc.kind != ResourceKind::Image || desc.format != Format::R32u {
                    return Err(misuse(format!("its read `{}` must be an R32u image", desc.name)));
                }
                rec.image(layer)?
            }
            None => NO_IMAGE,
        };
        let (list, _capacity) = list_section(rec, list, index)?;
        Ok(HoleFillTarget {
            list,
            trace: rec.frame_data_address() + u64::from(pass.view.0) * TRACE_PARAMS_BYTES,
            radiance: rec.image(radiance.alloc)?,
            first_group: 0,
            count: 0,
            first_hit,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shaders::spirv;
    use parallax_backend::reflect::member_offsets;
    use parallax_backend::rust_layout;

    #[test]
    fn the_structs_match_hole_fill_glsl() {
        let target = rust_layout!(HoleFillTarget { list, trace, radiance, first_group, count, first_hit });
        for shader in ["hole_fill", "hole_fill_prefix"] {
            let spirv = spirv(shader).unwrap();
            assert_eq!(member_offsets(&spirv, "HoleFillTarget").unwrap(), target, "{shader}");
            let table: Vec<u32> =
                member_offsets(&spirv, "HoleFillTable").unwrap().into_iter().map(|(_, o)| o).collect();
            assert_eq!(table, [0, 4, 8, 12, TABLE_HEADER_BYTES as u32], "{shader}: arguments, total, targets");
        }
        assert_eq!(std::mem::size_of::<HoleFillTarget>(), 32);
    }
}
