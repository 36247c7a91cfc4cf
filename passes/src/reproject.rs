//! The `reproject` pass: shaders/reproject.comp, the paper's spatial reprojection as a gather
//! (see the shader for the acceptance test), with a bound on view-dependence in place of the
//! paper's diffuse-only gate (§4.1): a source's radiance is reused wherever
//! [`crate::view_bound`] says it differs from the target's by at most
//! [`ReprojectionTolerances::view_dependence`]. Sky pixels get the sky and sun the path tracer
//! would give them and are not holes, except on silhouettes (a neighbour has a hit), where the
//! path tracer's jittered samples may hit the surface too. Targets only.
//!
//! Slots (docs/PIPELINE.md): reads its own `position_depth`, `normal_metallic`,
//! `albedo_roughness` and each source's `position_depth`, `normal_metallic`, `radiance`
//! (`read_sources`: the δ-edges), the view's `GpuTraceParams` in the per-frame data (camera,
//! sky, sun, sampling) and the frame block (the sources' cameras); writes `radiance` and
//! `holes`. Sources are tried in the view topology's order, nearest first; at most
//! [`MAX_SOURCES`].

use std::sync::Arc;

use parallax_backend::{InstanceId, KernelGraph, PassInstance, PassKernel, Recorder};
use parallax_graph::{Format, Handle, Image, ReadSlot, Role, SourcesSlot, WriteSlot};

use crate::error::{PassError, Result};
use crate::gbuffer::Gbuffer;
use crate::holes::HOLES;
use crate::path_trace::TRACE_PARAMS_BYTES;
use crate::shaders::{self, ReprojectPush};

/// Pass name.
pub const REPROJECT: &str = "reproject";
/// Sources one target pixel tries.
pub const MAX_SOURCES: usize = 4;

/// When a source pixel counts as the same surface, and when its radiance is close enough to
/// the target's to be reused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReprojectionTolerances {
    /// Allowed depth and world-position difference, relative to the distance from the source.
    pub position: f32,
    /// Least cosine between the target's and the source's normal.
    pub normal_cos: f32,
    /// Largest relative radiance error that view-dependence may cause: the bound of
    /// [`crate::view_bound::ViewBound::error`] for the angle between the target's and the
    /// source's view directions. 0 reprojects only from a source at the target's own position;
    /// mirror-like metals stay holes at any useful value.
    pub view_dependence: f32,
}

impl ReprojectionTolerances {
    /// The view-dependence tolerance `render --reprojection-tolerance` uses by default
    /// (docs/PIPELINE.md says which measurement chose it).
    pub const DEFAULT_VIEW_DEPENDENCE: f32 = 0.2;

    /// Every tolerance is a finite number, the view-dependence one at least 0.
    pub fn validate(&self) -> Result<()> {
        if !(self.view_dependence.is_finite() && self.view_dependence >= 0.0) {
            return Err(PassError::ReprojectionTolerance { name: "view_dependence", value: self.view_dependence });
        }
        if !(self.position.is_finite() && self.position >= 0.0) {
            return Err(PassError::ReprojectionTolerance { name: "position", value: self.position });
        }
        if !(self.normal_cos.is_finite() && self.normal_cos <= 1.0) {
            return Err(PassError::ReprojectionTolerance { name: "normal_cos", value: self.normal_cos });
        }
        Ok(())
    }
}

impl Default for ReprojectionTolerances {
    fn default() -> Self {
        // 1 % of the distance is ~8 pixel footprints at 1024 px and 65°: enough for the
        // sub-pixel shift between a target's pixel centre and the source pixel it lands in,
        // small against the depth steps occlusion makes.
        Self { position: 0.01, normal_cos: 0.9, view_dependence: Self::DEFAULT_VIEW_DEPENDENCE }
    }
}

/// Records `reproject` instances.
struct ReprojectKernel {
    tolerances: ReprojectionTolerances,
    slots: ReprojectSlots,
}

/// What `reproject` declares: the target's G-buffer, the sources' G-buffer and radiance, and
/// its two outputs.
struct ReprojectSlots {
    position_depth: ReadSlot,
    normal_metallic: ReadSlot,
    albedo_roughness: ReadSlot,
    source_position_depth: SourcesSlot,
    source_normal_metallic: SourcesSlot,
    source_radiance: SourcesSlot,
    radiance: WriteSlot,
    holes: WriteSlot,
}

impl PassKernel for ReprojectKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let slots = &self.slots;
        let image = |rec: &Recorder<'_>, slot| rec.image(pass.read(slot)?.alloc);
        let position_depth = pass.read(slots.position_depth)?.alloc;
        let width = rec.resource(position_depth).width;
        let mut sources = [[0u32; 4]; MAX_SOURCES];
        let mut count = 0;
        // One read of each per source, all in the view's source order.
        let source_reads = pass
            .sources(slots.source_radiance)?
            .zip(pass.sources(slots.source_position_depth)?)
            .zip(pass.sources(slots.source_normal_metallic)?);
        for (slot, ((radiance, position), normal)) in sources.iter_mut().zip(source_reads) {
            let view = rec.resource(radiance.alloc).view;
            *slot = [view, rec.image(position.alloc)?, rec.image(normal.alloc)?, rec.image(radiance.alloc)?];
            count += 1;
        }
        let t = self.tolerances;
        let push = ReprojectPush {
            block: rec.frame_block_address()?,
            trace: rec.frame_data_address() + u64::from(pass.view.0) * TRACE_PARAMS_BYTES,
            position_depth: rec.image(position_depth)?,
            normal_metallic: image(rec, slots.normal_metallic)?,
            albedo_roughness: image(rec, slots.albedo_roughness)?,
            radiance: rec.image(pass.write(slots.radiance)?.alloc)?,
            holes: rec.image(pass.write(slots.holes)?.alloc)?,
            source_count: count,
            y0: pass.region.y0,
            y1: pass.region.y1,
            position_tolerance: t.position,
            normal_cos: t.normal_cos,
            view_tolerance: t.view_dependence,
            pad: 0,
            sources,
        };
        rec.dispatch(shaders::REPROJECT, &push, [width.div_ceil(8), pass.region.len().div_ceil(8).max(1), 1])
    }
}

/// Declares `reproject` for every target: reads `gbuffer` of the target and of its sources and
/// the sources' `radiance`; writes the targets' `radiance` and returns the `holes` handle.
/// Tolerances that are not numbers in range are refused ([`ReprojectionTolerances::validate`]).
pub fn declare_reproject(
    graph: &mut KernelGraph,
    gbuffer: &Gbuffer,
    radiance: &mut Handle<Image>,
    tolerances: ReprojectionTolerances,
) -> Result<Handle<Image>> {
    tolerances.validate()?;
    let mut holes = graph.image(HOLES, Format::R32u);
    let mut pass = graph.pass(REPROJECT, Role::Targets);
    let slots = ReprojectSlots {
        position_depth: pass.read_slot(&gbuffer.position_depth),
        normal_metallic: pass.read_slot(&gbuffer.normal_metallic),
        albedo_roughness: pass.read_slot(&gbuffer.albedo_roughness),
        source_position_depth: pass.read_sources_slot(&gbuffer.position_depth),
        source_normal_metallic: pass.read_sources_slot(&gbuffer.normal_metallic),
        source_radiance: pass.read_sources_slot(radiance),
        radiance: pass.write_slot(radiance),
        holes: pass.write_slot(&mut holes),
    };
    pass.kernel(Arc::new(ReprojectKernel { tolerances, slots })).add();
    Ok(holes)
}
