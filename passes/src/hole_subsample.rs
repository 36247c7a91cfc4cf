//! Subsampled hole filling ([`HoleFillMode::Subsampled`], `--hole-fill subsampled`): where
//! holes are dense, path trace only a rotating subset of the hole pixels each frame and
//! reconstruct the others from traced neighbours on the same surface; an isolated hole, or one
//! without such a neighbour, is traced as under [`HoleFillMode::Full`].
//!
//! 1. `compact_holes` (shaders/compact_holes_subsampled.comp, one pass per band as today's):
//!    the hole pixels with a hit of each aligned 2×2 block take turns by frame index, one
//!    traced per block and frame; every other hole pixel is reconstructed where one of its 8
//!    neighbours is a turn's traced pixel similar in the G-buffer (normal within ~26°, within
//!    2 % of depth of each other's tangent plane; shaders/hole_subsample.glsl), else traced.
//!    It writes the traced pixels to `hole_list` (what `hole_fill` traces, unchanged), the
//!    others to `hole_reconstruct_list`, and each pixel's choice to `hole_sampling`.
//! 2. `hole_fill` traces `hole_list` ([`crate::holes`]).
//! 3. Under [`crate::pipeline::Denoiser::Samples`], `hole_temporal` accumulates the traced
//!    pixels only and carries the reconstructed pixels' means of their traced frames
//!    ([`crate::hole_denoise`]).
//! 4. `hole_reconstruct` (shaders/hole_reconstruct.comp, one indirect dispatch per band over
//!    `hole_reconstruct_list`): the G-buffer-weighted mean of the traced neighbours (under
//!    `Samples`: a pixel's own mean where it has one) into `hole_reconstructed`;
//!    `hole_reconstruct_apply` copies it into the radiance. The gather reads 1 row (and
//!    the compaction 2 rows) beyond its band, so every band, on any device, makes the same
//!    choice and the same value as one device does.
//!
//! What it costs and where it fails: docs/PIPELINE.md ("Subsampled hole filling").

use std::sync::Arc;

use parallax_backend::{
    BackendError, Format, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder, ResourceKind,
};
use parallax_graph::{Buffer, Handle, Image, ReadSlot, Role, WriteSlot};

use crate::gbuffer::Gbuffer;
use crate::holes::{COMPACT_HOLES, HOLE_LIST, band_list_address, declare_hole_trace, hole_list_row_bytes};
use crate::path_trace::NO_IMAGE;
use crate::shaders::{self, CompactHolesSubsampledPush, HoleReconstructPush};

/// Slot of the per-band lists of the hole pixels reconstructed this frame (a `hole_list`-like
/// row buffer, reset each frame).
pub const HOLE_RECONSTRUCT_LIST: &str = "hole_reconstruct_list";
/// Slot of each pixel's choice (R32u): [`SAMPLING_NONE`], [`SAMPLING_TRACED`] or
/// [`SAMPLING_RECONSTRUCTED`].
pub const HOLE_SAMPLING: &str = "hole_sampling";
/// Slot of the reconstructed values (Rgba32f, written at reconstructed pixels only).
pub const HOLE_RECONSTRUCTED: &str = "hole_reconstructed";
/// Pass name of the gather.
pub const HOLE_RECONSTRUCT: &str = "hole_reconstruct";
/// Pass name of the copy into the radiance.
pub const HOLE_RECONSTRUCT_APPLY: &str = "hole_reconstruct_apply";
/// `hole_sampling`: not a hole (`HOLE_NONE` in shaders/hole_subsample.glsl).
pub const SAMPLING_NONE: u32 = 0;
/// `hole_sampling`: a hole pixel traced this frame.
pub const SAMPLING_TRACED: u32 = 1;
/// `hole_sampling`: a hole pixel reconstructed from traced neighbours.
pub const SAMPLING_RECONSTRUCTED: u32 = 2;
/// Frames within which a still camera traces every hole pixel: a 2×2 block's turns.
pub const SUBSAMPLING_PERIOD: u32 = 4;

/// Rows beyond its band the compaction reads: a neighbour's 2×2 block.
const COMPACT_REACH: u32 = 2;
/// Rows beyond its band the gather reads: its 3×3 window.
const GATHER_REACH: u32 = 1;

/// How the targets' holes are filled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum HoleFillMode {
    /// Every hole pixel path traced every frame ([`crate::holes`]).
    Full,
    /// A rotating subset traced, the rest reconstructed (this module).
    Subsampled,
}

/// What [`declare_subsampled_hole_fill`] declared, for the reconstruction and for readback.
pub struct SubsampledHoles {
    /// `hole_list`: per band, the pixels traced this frame.
    pub traced: Handle<Buffer>,
    /// `hole_reconstruct_list`: per band, the hole pixels reconstructed this frame.
    pub reconstructed: Handle<Buffer>,
    /// `hole_sampling`: each pixel's choice.
    pub sampling: Handle<Image>,
}

/// Declares the subsampling `compact_holes` and `hole_fill` for every target: reads `holes`
/// and the G-buffer's `position_depth` and `normal_metallic` (2 rows beyond the band), traces
/// the chosen pixels into `radiance` in place. The untraced hole pixels keep what was there
/// until [`declare_hole_reconstruction`] fills them.
pub fn declare_subsampled_hole_fill(
    graph: &mut KernelGraph,
    holes: &Handle<Image>,
    gbuffer: &Gbuffer,
    radiance: &mut Handle<Image>,
) -> SubsampledHoles {
    let row_bytes = hole_list_row_bytes(graph.topology().width);
    let mut traced = graph.row_buffer(HOLE_LIST, row_bytes);
    let mut reconstructed = graph.row_buffer(HOLE_RECONSTRUCT_LIST, row_bytes);
    graph.reset_each_frame(&traced, Vec::new());
    graph.reset_each_frame(&reconstructed, Vec::new());
    let mut sampling = graph.image(HOLE_SAMPLING, Format::R32u);
    let mut pass = graph.pass(COMPACT_HOLES, Role::Targets);
    let kernel = CompactHolesSubsampledKernel {
        holes: pass.read_halo_slot(holes, COMPACT_REACH),
        position: pass.read_halo_slot(&gbuffer.position_depth, COMPACT_REACH),
        normal: pass.read_halo_slot(&gbuffer.normal_metallic, GATHER_REACH),
        traced: pass.modify_slot(&mut traced).1,
        reconstructed: pass.modify_slot(&mut reconstructed).1,
        sampling: pass.write_slot(&mut sampling),
    };
    pass.kernel(Arc::new(kernel)).add();
    declare_hole_trace(graph, &traced, gbuffer.first_hit.as_ref(), radiance);
    SubsampledHoles { traced, reconstructed, sampling }
}

/// Declares `hole_reconstruct` and `hole_reconstruct_apply` for every target: each pixel of
/// `hole_reconstruct_list` gets the G-buffer-weighted mean of `radiance` at its traced
/// neighbours, or, with `accum` (this frame's `hole_accum` under `--denoise samples`), its
/// own mean of its traced frames where it has one; `radiance` is modified at those pixels only.
pub fn declare_hole_reconstruction(
    graph: &mut KernelGraph,
    holes: &SubsampledHoles,
    gbuffer: &Gbuffer,
    accum: Option<&Handle<Image>>,
    radiance: &mut Handle<Image>,
) {
    let mut values = graph.image(HOLE_RECONSTRUCTED, Format::Rgba32f);
    let mut pass = graph.pass(HOLE_RECONSTRUCT, Role::Targets);
    let stage = Stage::Gather {
        list: pass.read_slot(&holes.reconstructed),
        radiance: pass.read_halo_slot(radiance, GATHER_REACH),
        sampling: pass.read_halo_slot(&holes.sampling, GATHER_REACH),
        position: pass.read_halo_slot(&gbuffer.position_depth, GATHER_REACH),
        normal: pass.read_halo_slot(&gbuffer.normal_metallic, GATHER_REACH),
        accum: accum.map(|accum| pass.read_slot(accum)),
        values: pass.write_slot(&mut values),
    };
    pass.kernel(Arc::new(HoleReconstructKernel(stage))).add();
    let mut pass = graph.pass(HOLE_RECONSTRUCT_APPLY, Role::Targets);
    let stage = Stage::Apply {
        list: pass.read_slot(&holes.reconstructed),
        values: pass.read_slot(&values),
        radiance: pass.modify_slot(radiance).1,
    };
    pass.kernel(Arc::new(HoleReconstructKernel(stage))).add();
}

/// Records the subsampling `compact_holes` instances: one workgroup per 8×8 tile of the band.
struct CompactHolesSubsampledKernel {
    holes: ReadSlot,
    position: ReadSlot,
    normal: ReadSlot,
    traced: WriteSlot,
    reconstructed: WriteSlot,
    sampling: WriteSlot,
}

impl PassKernel for CompactHolesSubsampledKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let holes = pass.read(self.holes)?;
        let mask = rec.resource(holes.alloc);
        if mask.kind != ResourceKind::Image || mask.format != Format::R32u {
            let detail = format!("`{}` must be an R32u image", mask.name);
            return Err(BackendError::KernelMisuse { kernel: COMPACT_HOLES.into(), instance: Some(index), detail });
        }
        let size = (mask.width, mask.height);
        let (traced, reconstructed) = (pass.write(self.traced)?, pass.write(self.reconstructed)?);
        let push = CompactHolesSubsampledPush {
            traced: band_list_address(rec, traced, size, COMPACT_HOLES, index)?,
            reconstructed: band_list_address(rec, reconstructed, size, COMPACT_HOLES, index)?,
            holes: rec.image(holes.alloc)?,
            position_depth: rec.image(pass.read(self.position)?.alloc)?,
            normal_metallic: rec.image(pass.read(self.normal)?.alloc)?,
            sampling: rec.image(pass.write(self.sampling)?.alloc)?,
            y0: traced.region.y0,
            y1: traced.region.y1,
            width: size.0,
            height: size.1,
        };
        if traced.region.is_empty() {
            return Ok(());
        }
        // 8x8-pixel tiles, one workgroup each (see compact_holes_subsampled.comp).
        let groups = [size.0.div_ceil(8), traced.region.len().div_ceil(8), 1];
        rec.dispatch(shaders::COMPACT_HOLES_SUBSAMPLED, &push, groups)
    }
}

/// Which stage of the reconstruction a pass records, and its slots.
#[derive(Clone, Copy, Debug)]
enum Stage {
    Gather {
        list: ReadSlot,
        radiance: ReadSlot,
        sampling: ReadSlot,
        position: ReadSlot,
        normal: ReadSlot,
        accum: Option<ReadSlot>,
        values: WriteSlot,
    },
    /// `radiance` is modified in place at the listed pixels.
    Apply { list: ReadSlot, values: ReadSlot, radiance: WriteSlot },
}

/// `HoleReconstructPush::stage` (shaders/hole_reconstruct.comp).
const GATHER: u32 = 0;
const APPLY: u32 = 1;

/// Records both reconstruction passes: one indirect dispatch on the band's list header.
struct HoleReconstructKernel(Stage);

impl PassKernel for HoleReconstructKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let read = |rec: &Recorder<'_>, slot: ReadSlot| rec.image(pass.read(slot)?.alloc);
        let write = |rec: &Recorder<'_>, slot: WriteSlot| rec.image(pass.write(slot)?.alloc);
        let (list, push) = match self.0 {
            Stage::Gather { list, radiance, sampling, position, normal, accum, values } => {
                let push = HoleReconstructPush {
                    list: 0,
                    radiance: read(rec, radiance)?,
                    sampling: read(rec, sampling)?,
                    position_depth: read(rec, position)?,
                    normal_metallic: read(rec, normal)?,
                    accum: accum.map(|slot| read(rec, slot)).transpose()?.unwrap_or(NO_IMAGE),
                    reconstructed: write(rec, values)?,
                    stage: GATHER,
                    pad: 0,
                };
                (list, push)
            }
            Stage::Apply { list, values, radiance } => {
                let push = HoleReconstructPush {
                    list: 0,
                    radiance: write(rec, radiance)?,
                    sampling: NO_IMAGE,
                    position_depth: NO_IMAGE,
                    normal_metallic: NO_IMAGE,
                    accum: NO_IMAGE,
                    reconstructed: read(rec, values)?,
                    stage: APPLY,
                    pad: 0,
                };
                (list, push)
            }
        };
        let list = pass.read(list)?;
        let buffer = rec.resource(list.alloc);
        if buffer.kind != ResourceKind::Buffer {
            let detail = format!("its read `{}` must be the reconstruct list's row buffer", buffer.name);
            return Err(BackendError::KernelMisuse { kernel: HOLE_RECONSTRUCT.into(), instance: Some(index), detail });
        }
        if list.region.is_empty() {
            return Ok(());
        }
        let offset = u64::from(list.region.y0) * buffer.row_bytes();
        let push = HoleReconstructPush { list: rec.buffer_of(list.alloc)? + offset, ..push };
        // The header's first three words are the indirect arguments (pixel_list.glsl).
        rec.dispatch_indirect(shaders::HOLE_RECONSTRUCT, &push, list.alloc, offset)
    }
}
