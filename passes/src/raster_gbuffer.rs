//! The `gbuffer_raster` pass: the G-buffer of a view rasterised (shaders/gbuffer_raster.vert,
//! .frag), the paper's path to first-hit data and the fast one on GPUs with fixed-function
//! graphics (DESIGN.md §6; on compute chips the first hits of `path_trace` are faster).
//!
//! * Writes the slots [`RASTER_OUTPUTS`] (`Rgba32f` colour targets, in the path tracer's
//!   first-hit conventions, so a later pass takes either G-buffer) and [`RASTER_DEPTH`], a
//!   [`Format::Depth32f`] graph resource cleared to 1.0 at the pass start, tested LESS and
//!   written; a later compute pass reads it through `depth_images[]` (shaders/include/bindless.glsl).
//!   Pixels no triangle covers keep zeros in the colour targets (a path-trace miss) and 1.0
//!   in depth.
//! * Vertices come from the uploaded scene ([`crate::upload_scene`]) by buffer address: one
//!   non-indexed draw of three vertices per BVH-ordered triangle.
//! * The camera is this view's current one in the frame block (`FrameData::frame_block`,
//!   `FrameClock::advance`); [`raster_camera`] builds the one whose pixel
//!   centres see exactly the path tracer's primary rays (jitter off), with a near plane and
//!   no far plane, so the depth attachment holds `1 - near / linear_depth`.
//! * A row band renders its rows only: the scissor and render area are the band, the viewport
//!   the whole view, so any split over devices gives the same texels.
//! * Alpha-masked materials are discarded where their alpha is below the cutoff, by the rule
//!   the path tracer's traversal uses.

use std::sync::Arc;

use glam::Vec2;
use parallax_backend::{
    AllocId, BackendError, Draw, Format, GpuCamera, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder,
    ResourceKind,
};
use parallax_graph::{Handle, Image, Role, WriteSlot};
use parallax_scene::View;
use parallax_scene::gpu::GpuTriangle;

use crate::error::{PassError, Result};
use crate::scene_upload::scene_refs;
use crate::shaders::{self, GbufferRasterPush};

/// Pass name of the raster G-buffer.
pub const GBUFFER_RASTER: &str = "gbuffer_raster";

/// Colour targets of `gbuffer_raster`, in fragment output order, all `Rgba32f`: the first-hit
/// layers of [`crate::TRACE_OUTPUTS`] (everything but radiance).
pub const RASTER_OUTPUTS: [&str; 3] = ["albedo_roughness", "normal_metallic", "position_depth"];

/// The depth slot of `gbuffer_raster` (a `Depth32f` resource).
pub const RASTER_DEPTH: &str = "depth";

/// Records `gbuffer_raster` instances (see the module docs) into the colour targets (the
/// [`RASTER_OUTPUTS`] writes, in that order) and the depth write its pass declared.
pub struct GbufferRasterKernel {
    color_targets: [WriteSlot; 3],
    depth: WriteSlot,
}

fn misuse(index: InstanceId, detail: String) -> BackendError {
    BackendError::KernelMisuse { kernel: GBUFFER_RASTER.into(), instance: Some(index), detail }
}

impl PassKernel for GbufferRasterKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let mut color_targets = [AllocId::UNASSIGNED; 3];
        for (target, &slot) in color_targets.iter_mut().zip(&self.color_targets) {
            let write = pass.write(slot)?;
            let desc = rec.resource(write.alloc);
            if desc.kind != ResourceKind::Image || desc.format != Format::Rgba32f {
                return Err(misuse(
                    index,
                    format!("its write `{}` must be an Rgba32f image, not {:?}", desc.name, desc.format),
                ));
            }
            *target = write.alloc;
        }
        let depth = pass.write(self.depth)?;
        let triangle_bytes = rec.buffer_bytes(crate::SCENE_BUFFERS[1])?;
        let triangles = triangle_bytes / std::mem::size_of::<GpuTriangle>() as u64;
        let vertex_count = u32::try_from(3 * triangles)
            .map_err(|_| misuse(index, format!("{triangles} triangles exceed one draw's vertex count")))?;
        let push =
            GbufferRasterPush { scene: scene_refs(rec)?, frame: rec.frame_block_address()?, view: pass.view.0, pad: 0 };
        rec.draw(
            &Draw {
                vertex_shader: shaders::GBUFFER_RASTER_VERT,
                fragment_shader: shaders::GBUFFER_RASTER_FRAG,
                color_targets: &color_targets,
                depth_target: Some(depth.alloc),
                clear: true,
                rows: pass.region,
                vertex_count,
                instance_count: 1,
            },
            &push,
        )
    }
}

/// The resources [`declare_gbuffer_raster`] declares, as the pass wrote them.
#[derive(Debug)]
pub struct GbufferHandles {
    pub albedo_roughness: Handle<Image>,
    pub normal_metallic: Handle<Image>,
    pub position_depth: Handle<Image>,
    pub depth: Handle<Image>,
}

/// Declares, for every view, a `gbuffer_raster` pass writing the [`RASTER_OUTPUTS`] images and
/// the [`RASTER_DEPTH`] resource; exports nothing (the caller reads or exports what it needs).
pub fn declare_gbuffer_raster(graph: &mut KernelGraph) -> GbufferHandles {
    let [mut albedo_roughness, mut normal_metallic, mut position_depth] =
        RASTER_OUTPUTS.map(|name| graph.image(name, Format::Rgba32f));
    let mut depth = graph.image(RASTER_DEPTH, Format::Depth32f);
    let mut pass = graph.pass(GBUFFER_RASTER, Role::All);
    let kernel = GbufferRasterKernel {
        color_targets: [
            pass.write_slot(&mut albedo_roughness),
            pass.write_slot(&mut normal_metallic),
            pass.write_slot(&mut position_depth),
        ],
        depth: pass.write_slot(&mut depth),
    };
    pass.kernel(Arc::new(kernel)).add();
    GbufferHandles { albedo_roughness, normal_metallic, position_depth, depth }
}

/// The frame-block camera of `view` for the raster G-buffer: world → clip such that pixel
/// centre (x + ½, y + ½) lies on the path tracer's primary ray through it (same basis, field of
/// view, aspect and off-axis shift; `parallax_scene::Camera::ray_direction`), clip w is the
/// linear depth, and the depth is `1 - near / w`: 0 at the near plane, 1 at infinity (no far
/// plane). Geometry nearer than `near` (> 0, in scene units) is clipped.
pub fn raster_camera(view: &View, near: f32) -> Result<GpuCamera> {
    if !(near.is_finite() && near > 0.0) {
        return Err(PassError::NearPlane { near });
    }
    // The projection every pass shares (y up, as the path tracer's image plane); the vertex
    // shader flips y for Vulkan's framebuffer, whose rows grow downwards.
    let view_proj = crate::camera::view_projection_near(view, near);
    if !view_proj.is_finite() {
        return Err(PassError::NearPlane { near });
    }
    let camera = &view.camera;
    Ok(GpuCamera::new(view_proj, camera.eye, Vec2::ZERO))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Mat4, Vec3};
    use parallax_scene::Camera;

    #[test]
    fn pixel_centres_project_along_the_path_tracers_primary_rays() {
        let mut camera = Camera::look_at(Vec3::new(0.3, 1.0, 4.0), Vec3::new(0.0, 0.5, 0.0), Vec3::Y, 0.9);
        camera.shift = Vec2::new(0.125, -0.0625);
        let view = View { camera, width: 40, height: 30, index: 0 };
        let near = 0.05;
        let view_proj = Mat4::from_cols_array_2d(&raster_camera(&view, near).unwrap().view_proj);
        for (x, y) in [(0u32, 0u32), (17, 9), (39, 29)] {
            let ndc = Vec2::new((x as f32 + 0.5) / 40.0 * 2.0 - 1.0, 1.0 - (y as f32 + 0.5) / 30.0 * 2.0);
            let dir = camera.ray_direction(ndc, view.aspect());
            let point = camera.eye + dir * 3.0;
            let clip = view_proj * point.extend(1.0);
            let linear = (point - camera.eye).dot(camera.forward.normalize());
            // y up in clip space (the vertex shader flips it for the framebuffer).
            let pixel = ((clip.x / clip.w + 1.0) * 20.0, (1.0 - clip.y / clip.w) * 15.0);
            assert!(
                (pixel.0 - (x as f32 + 0.5)).abs() < 1e-4 && (pixel.1 - (y as f32 + 0.5)).abs() < 1e-4,
                "{pixel:?}"
            );
            assert!((clip.w - linear).abs() < 1e-5);
            assert!((clip.z / clip.w - (1.0 - near / linear)).abs() < 1e-6);
        }
        assert!(matches!(raster_camera(&view, 0.0), Err(PassError::NearPlane { .. })));
        assert!(matches!(raster_camera(&view, f32::NAN), Err(PassError::NearPlane { .. })));
    }
}
