//! Hole filling (paper §3.3, Table 1 stage 5), per row band: `compact_holes`
//! (shaders/compact_holes.comp) turns the `holes` mask of its band into the band's pixel list in
//! the `hole_list` row buffer, and `hole_fill` path traces exactly the listed pixels
//! ([`crate::hole_fill`]: one indirect dispatch for all target bands of a device, sized by the
//! lists' counts), so no hole ray is dropped. Both passes split into bands like any other, so
//! under the fine schemes each device compacts and fills its own strips.
//! Formats: docs/PIPELINE.md (`holes`, `hole_list`, `radiance`).

use std::sync::Arc;

use parallax_backend::{
    BackendError, Format, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder, ResourceKind,
};
use parallax_graph::{Buffer, Handle, Image, ReadSlot, Role, WriteSlot};

use crate::hole_fill::HoleFillKernel;
use crate::pixel_list::LIST_HEADER_WORDS;

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
/// ([`crate::hole_fill`]).
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
    pass.kernel(Arc::new(CompactHolesKernel { holes, list: written_list })).record();
    let mut pass = graph.pass(HOLE_FILL, Role::Targets);
    let read_list = pass.read_slot(&list);
    let first_hit = first_hit.map(|layer| pass.read_slot(layer));
    let (_, radiance) = pass.modify_slot(radiance);
    pass.kernel(Arc::new(HoleFillKernel { list: read_list, first_hit, radiance })).grouped().record();
    list
}

/// Push constants of `compact_holes.comp` (`CompactHolesPush` there; a test holds the two
/// layouts together).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CompactHolesPush {
    /// Address of the band's section of the hole list (`y0 * row_bytes` into the buffer).
    pub list: u64,
    /// Image index of the hole mask.
    pub holes: u32,
    pub y0: u32,
    pub y1: u32,
    pub width: u32,
}

parallax_backend::push_constants!(CompactHolesPush { list, holes, y0, y1, width });

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
        let buffer = rec.resource(list.alloc);
        // The band's section holds its header and an entry for every pixel of the band.
        let rows = u64::from(list.region.len());
        let fits = rows * buffer.row_bytes() >= 4 * (rows * u64::from(width) + u64::from(LIST_HEADER_WORDS));
        if buffer.kind != ResourceKind::Buffer || buffer.height != mask.height || !fits {
            return Err(misuse(format!(
                "`{}` must be a row buffer of {} rows and at least {} bytes per row",
                buffer.name,
                mask.height,
                hole_list_row_bytes(width)
            )));
        }
        if list.region.is_empty() {
            return Ok(());
        }
        let push = CompactHolesPush {
            list: rec.buffer_of(list.alloc)? + u64::from(list.region.y0) * buffer.row_bytes(),
            holes: rec.image(holes.alloc)?,
            y0: list.region.y0,
            y1: list.region.y1,
            width,
        };
        // 8x8-pixel tiles, one workgroup each (see compact_holes.comp).
        rec.dispatch("compact_holes", &push, [width.div_ceil(8), list.region.len().div_ceil(8), 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shaders::spirv;
    use parallax_backend::check_push_constants;

    #[test]
    fn the_push_struct_matches_compact_holes_comp() {
        assert_eq!(check_push_constants::<CompactHolesPush>(&spirv("compact_holes").unwrap()), Ok(()));
    }
}
