//! The `gbuffer` pass: shaders/gbuffer_trace.comp, the first hit of each pixel's centre ray
//! (what the path tracer's first hit records, with no jitter) and the pixel's motion from the
//! previous frame's camera, over the instance's row band. On GPUs without fixed-function
//! raster to speak of (H100/H200) first hits are the fast way to a G-buffer (DESIGN.md §6).
//!
//! Slots (docs/PIPELINE.md): writes `position_depth`, `normal_metallic`, `albedo_roughness`
//! (Rgba32f), `motion` (Rg32f) and, when asked for (hole filling reads it), `first_hit` (R32u:
//! the BVH primitive the centre ray hit). Reads the view's `GpuTraceParams` in the per-frame
//! data ([`crate::trace_frame_data`]) and the frame block section.

use std::sync::Arc;

use parallax_backend::{InstanceId, KernelGraph, PassInstance, PassKernel, Recorder};
use parallax_graph::{Format, Handle, Image, ReadSlot, Role, WriteSlot};

use crate::path_trace::{NO_IMAGE, TRACE_PARAMS_BYTES};
use crate::scene_upload::scene_refs;
use crate::shaders::{self, GbufferPush, MotionPush};

/// Where the G-buffer comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum GbufferSource {
    /// First hits of each pixel's centre ray (the fast way on compute GPUs such as the H200).
    FirstHits,
    /// Rasterised (the paper's way; fast on GPUs with fixed-function raster), motion vectors
    /// from a compute pass.
    Raster,
    /// A compute visibility buffer (64-bit atomics of distance and triangle) resolved into the
    /// first-hit G-buffer's images ([`crate::visibility`]); needs 64-bit buffer atomics
    /// ([`crate::visibility::choose_gbuffer`] falls back to first hits without them).
    Visibility,
}

/// Pass name.
pub const GBUFFER: &str = "gbuffer";
/// Slot of the BVH primitive of each pixel's centre-ray hit (R32u, `u32::MAX`: no hit).
pub const FIRST_HIT: &str = "first_hit";

/// Records `gbuffer` instances into the G-buffer writes its pass declared.
struct GbufferKernel {
    position_depth: WriteSlot,
    normal_metallic: WriteSlot,
    albedo_roughness: WriteSlot,
    motion: WriteSlot,
    first_hit: Option<WriteSlot>,
}

impl PassKernel for GbufferKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let image = |rec: &Recorder<'_>, slot| rec.image(pass.write(slot)?.alloc);
        let position_depth = pass.write(self.position_depth)?.alloc;
        let width = rec.resource(position_depth).width;
        let push = GbufferPush {
            scene: scene_refs(rec)?,
            trace: rec.frame_data_address() + u64::from(pass.view.0) * TRACE_PARAMS_BYTES,
            block: rec.frame_block_address()?,
            position_depth: rec.image(position_depth)?,
            normal_metallic: image(rec, self.normal_metallic)?,
            albedo_roughness: image(rec, self.albedo_roughness)?,
            motion: image(rec, self.motion)?,
            view: pass.view.0,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            first_hit: self.first_hit.map_or(Ok(NO_IMAGE), |slot| image(rec, slot))?,
            pad: 0,
        };
        rec.dispatch(shaders::GBUFFER_TRACE, &push, [width.div_ceil(8), pass.region.len().div_ceil(8).max(1), 1])
    }
}

/// Pass name of [`MotionKernel`].
pub const MOTION: &str = "motion";

/// Records `motion` instances: motion vectors from a G-buffer's world positions and the
/// previous camera (for G-buffers that do not come with them, such as the raster one).
struct MotionKernel {
    position_depth: ReadSlot,
    motion: WriteSlot,
}

impl PassKernel for MotionKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let (position, motion) = (pass.read(self.position_depth)?, pass.write(self.motion)?);
        let desc = rec.resource(position.alloc);
        let (width, height) = (desc.width, desc.height);
        let push = MotionPush {
            block: rec.frame_block_address()?,
            position_depth: rec.image(position.alloc)?,
            motion: rec.image(motion.alloc)?,
            view: pass.view.0,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            height,
            pad: 0,
        };
        rec.dispatch(shaders::MOTION, &push, [width.div_ceil(8), pass.region.len().div_ceil(8).max(1), 1])
    }
}

/// The G-buffer of every view.
pub struct Gbuffer {
    pub position_depth: Handle<Image>,
    pub normal_metallic: Handle<Image>,
    pub albedo_roughness: Handle<Image>,
    pub motion: Handle<Image>,
    /// [`FIRST_HIT`], declared by [`declare_gbuffer`] when asked for (the raster G-buffer has
    /// no BVH hits).
    pub first_hit: Option<Handle<Image>>,
}

/// Declares the G-buffer images and the `gbuffer` pass that writes them for every view, with
/// the [`FIRST_HIT`] layer when `with_first_hit` (what hole filling reads).
pub fn declare_gbuffer(graph: &mut KernelGraph, with_first_hit: bool) -> Gbuffer {
    let mut g = Gbuffer {
        position_depth: graph.image("position_depth", Format::Rgba32f),
        normal_metallic: graph.image("normal_metallic", Format::Rgba32f),
        albedo_roughness: graph.image("albedo_roughness", Format::Rgba32f),
        motion: graph.image("motion", Format::Rg32f),
        first_hit: with_first_hit.then(|| graph.image(FIRST_HIT, Format::R32u)),
    };
    let mut pass = graph.pass(GBUFFER, Role::All);
    let kernel = GbufferKernel {
        position_depth: pass.write_slot(&mut g.position_depth),
        normal_metallic: pass.write_slot(&mut g.normal_metallic),
        albedo_roughness: pass.write_slot(&mut g.albedo_roughness),
        motion: pass.write_slot(&mut g.motion),
        first_hit: g.first_hit.as_mut().map(|first_hit| pass.write_slot(first_hit)),
    };
    pass.kernel(Arc::new(kernel)).add();
    g
}

/// Declares the raster G-buffer (`gbuffer_raster`, with its depth resource) and the `motion`
/// pass that completes it, for every view.
pub fn declare_gbuffer_rasterised(graph: &mut KernelGraph) -> Gbuffer {
    let raster = crate::raster_gbuffer::declare_gbuffer_raster(graph);
    let mut motion = graph.image("motion", Format::Rg32f);
    let mut pass = graph.pass(MOTION, Role::All);
    let position_depth = pass.read_slot(&raster.position_depth);
    let kernel = MotionKernel { position_depth, motion: pass.write_slot(&mut motion) };
    pass.kernel(Arc::new(kernel)).add();
    Gbuffer {
        position_depth: raster.position_depth,
        normal_metallic: raster.normal_metallic,
        albedo_roughness: raster.albedo_roughness,
        motion,
        first_hit: None,
    }
}
