//! The `hole_fill` kernel: path traces the holes that `compact_holes` listed, for every target
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

use parallax_backend::{
    BackendError, Format, InstanceId, PassInstance, PassKernel, ReadSlot, Recorder, ResourceKind, WriteSlot,
};

use crate::holes::HOLE_FILL;
use crate::path_trace::{NO_IMAGE, TRACE_PARAMS_BYTES, list_section};
use crate::scene_upload::scene_refs;

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

/// Push constants of hole_fill_prefix.comp (`HoleFillPrefixPush` there).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct HoleFillPrefixPush {
    /// Address of the op's target table.
    pub table: u64,
    pub target_count: u32,
    pub pad: u32,
}

parallax_backend::push_constants!(HoleFillPrefixPush { table, target_count, pad });

/// Push constants of hole_fill.comp (`HoleFillPush` there).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct HoleFillPush {
    /// Addresses of the scene buffers (`SceneRefs`, [`crate::SCENE_BUFFERS`] order).
    pub scene: [u64; 6],
    pub table: u64,
    pub target_count: u32,
    pub pad: u32,
}

parallax_backend::push_constants!(HoleFillPush { scene, table, target_count, pad });

/// Records `hole_fill` instances: each reads its band's section of [`crate::HOLE_LIST`] (as
/// `compact_holes` writes it) and, when declared, the view's `first_hit` layer over its band
/// (an R32u image, [`crate::gbuffer`]), and modifies the view's radiance (a float image),
/// writing nothing else; the views' `GpuTraceParams` come from the per-frame data like
/// `path_trace`'s ([`crate::trace_frame_data`]).
pub struct HoleFillKernel {
    pub(crate) list: ReadSlot,
    pub(crate) first_hit: Option<ReadSlot>,
    pub(crate) radiance: WriteSlot,
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
        rec.dispatch("hole_fill_prefix", &prefix, [1, 1, 1])?;
        let fill = HoleFillPush { scene: scene_refs(rec)?, table: table.address(), target_count, pad: 0 };
        // The arguments are the table's first words.
        rec.dispatch_indirect_from("hole_fill", &fill, &table, 0)
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
    use parallax_backend::reflect::member_offsets;
    use parallax_backend::{check_push_constants, rust_layout};

    #[test]
    fn the_structs_match_hole_fill_glsl() {
        let target = rust_layout!(HoleFillTarget { list, trace, radiance, first_group, count, first_hit });
        for shader in ["hole_fill", "hole_fill_prefix"] {
            let spirv = crate::shaders::spirv(shader).unwrap();
            assert_eq!(member_offsets(&spirv, "HoleFillTarget").unwrap(), target, "{shader}");
            let table: Vec<u32> =
                member_offsets(&spirv, "HoleFillTable").unwrap().into_iter().map(|(_, o)| o).collect();
            assert_eq!(table, [0, 4, 8, 12, TABLE_HEADER_BYTES as u32], "{shader}: arguments, total, targets");
        }
        assert_eq!(std::mem::size_of::<HoleFillTarget>(), 32);
    }

    #[test]
    fn the_push_structs_match_the_shaders() {
        let spirv = |shader| crate::shaders::spirv(shader).unwrap();
        assert_eq!(check_push_constants::<HoleFillPrefixPush>(&spirv("hole_fill_prefix")), Ok(()));
        assert_eq!(check_push_constants::<HoleFillPush>(&spirv("hole_fill")), Ok(()));
    }
}
