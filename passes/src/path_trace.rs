//! The `path_trace` pass: shaders/pt_trace.comp (the GPU twin of the CPU reference path
//! tracer) over any subset of a view's pixels.
//!
//! * Writes (1 to 4, in this order): radiance (rgb, a = 1 where the first hit exists), albedo
//!   and roughness, normal and metallic, position and linear depth: the [`TRACE_OUTPUTS`]
//!   images. A pass that needs only radiance (hole filling) declares only the first.
//! * Pixels: the instance's row band (a whole view or one device's strip), or, when the pass
//!   reads a per-view buffer, the pixel list in it, whatever the band (word 0 = count, then x | y << 16 per
//!   pixel; see [`crate::pixel_list`]). The dispatch covers the buffer's capacity and threads
//!   past the count return, so the list can be produced on the GPU in the same frame.
//! * Camera, frame index and settings come from the per-frame data, one
//!   [`GpuTraceParams`] per view ([`trace_frame_data`]), so frames change without
//!   re-recording; the scene from [`crate::upload_scene`].

use parallax_backend::{BackendError, ExecPass, Format, PassKernel, Recorder, ResourceKind};
use parallax_scene::gpu::{GpuPixel, GpuTraceParams};
use parallax_scene::{PixelSet, Scene, TraceSettings, View};

use crate::error::{PassError, Result};
use crate::scene_upload::scene_refs;

/// Pass name the kernel is registered under.
pub const PATH_TRACE: &str = "path_trace";

/// Images a `path_trace` pass writes, in write order, all `Rgba32f`.
pub const TRACE_OUTPUTS: [&str; 4] = ["radiance", "albedo_roughness", "normal_metallic", "position_depth"];

/// Image index meaning "not written" in the push constants.
const NO_IMAGE: u32 = u32::MAX;
/// Workgroup size of pt_trace.comp.
const GROUP: u32 = 64;
/// Per-axis limit on workgroup counts every Vulkan device supports.
const MAX_GROUPS: u32 = 65535;
/// Bytes of one view's parameters in the per-frame data.
pub const TRACE_PARAMS_BYTES: u64 = std::mem::size_of::<GpuTraceParams>() as u64;

/// Records `path_trace` instances (see the module docs).
pub struct PathTraceKernel;

fn misuse(index: usize, detail: String) -> BackendError {
    BackendError::KernelMisuse { kernel: PATH_TRACE.into(), instance: index, detail }
}

/// Push constants of `pt_trace.comp` (`PathTracePush` there; a test holds the two layouts
/// together).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PathTracePush {
    /// Addresses of the scene buffers (`SceneRefs`, [`crate::SCENE_BUFFERS`] order).
    pub scene: [u64; 6],
    /// Address of this view's `TraceParams` in the per-frame data.
    pub trace: u64,
    /// Address of the pixel list (list mode only).
    pub pixel_list: u64,
    /// Image indices of the outputs, [`NO_IMAGE`] where not written.
    pub radiance: u32,
    pub albedo_roughness: u32,
    pub normal_metallic: u32,
    pub position_depth: u32,
    pub y0: u32,
    pub y1: u32,
    pub width: u32,
    /// 1: trace the pixel list instead of rows `y0..y1`.
    pub list_mode: u32,
}

impl PassKernel for PathTraceKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &ExecPass, index: usize) -> parallax_backend::Result<()> {
        let outputs = TRACE_OUTPUTS.map(|slot| pass.output(slot));
        let Some(radiance) = outputs[0] else {
            return Err(misuse(index, format!("writes no `{}` slot", TRACE_OUTPUTS[0])));
        };
        let width = rec.resource(radiance.resource).width;
        let mut images = [NO_IMAGE; 4];
        for (slot, write) in images.iter_mut().zip(outputs) {
            let Some(write) = write else { continue };
            let target = rec.resource(write.resource);
            if target.kind != ResourceKind::Image || target.format == Format::R32u || target.format.is_depth() {
                return Err(misuse(index, format!("its write `{}` must be a float image", target.name)));
            }
            *slot = rec.image(write.resource)?;
        }
        let (list_mode, pixel_list, groups) = match pass.input(crate::pixel_list::PIXEL_LIST) {
            Some(read) => {
                let list = rec.resource(read.resource);
                if list.kind != ResourceKind::Buffer {
                    return Err(misuse(index, format!("its read `{}` must be a pixel-list buffer", list.name)));
                }
                let capacity = list.width.saturating_sub(1);
                let groups = capacity.div_ceil(GROUP).max(1);
                (1u32, rec.buffer_of(read.resource)?, [groups.min(MAX_GROUPS), groups.div_ceil(MAX_GROUPS), 1])
            }
            // 8x8-pixel tiles (see pt_trace.comp).
            None => (0, 0, [width.div_ceil(8), pass.rows.len().div_ceil(8).max(1), 1]),
        };
        let push = PathTracePush {
            scene: scene_refs(rec)?,
            trace: rec.frame_data_address() + u64::from(pass.view) * TRACE_PARAMS_BYTES,
            pixel_list,
            radiance: images[0],
            albedo_roughness: images[1],
            normal_metallic: images[2],
            position_depth: images[3],
            y0: pass.rows.y0,
            y1: pass.rows.y1,
            width,
            list_mode,
        };
        rec.dispatch_bytes("pt_trace", bytemuck::bytes_of(&push), groups)
    }
}

/// The per-frame data of `path_trace`: one [`GpuTraceParams`] per view, view `i` at
/// `i * TRACE_PARAMS_BYTES`. `views[i].index` must be `i` (it keys the random numbers and
/// locates the view's parameters).
pub fn trace_frame_data(scene: &Scene, views: &[View], settings: &TraceSettings) -> Result<Vec<u8>> {
    settings.validate()?;
    let mut bytes = Vec::with_capacity(views.len() * TRACE_PARAMS_BYTES as usize);
    for (position, view) in views.iter().enumerate() {
        if view.index as usize != position {
            return Err(PassError::ViewOrder { position, index: view.index });
        }
        if view.width > 1 << 16 || view.height > 1 << 16 {
            return Err(PassError::ViewTooLarge { width: view.width, height: view.height });
        }
        let params = GpuTraceParams::new(scene, view, settings, &PixelSet::All);
        bytes.extend_from_slice(bytemuck::bytes_of(&params));
    }
    Ok(bytes)
}

/// Reassembles [`GpuPixel`]s from the four output images as read back (tightly packed RGBA32F
/// rows, `TRACE_OUTPUTS` order); missing layers read as zero.
pub fn pixels_from_images(width: u32, height: u32, layers: [Option<&[u8]>; 4]) -> Vec<GpuPixel> {
    let n = width as usize * height as usize;
    let texel = |layer: Option<&[u8]>, i: usize| -> [f32; 4] {
        layer.map_or([0.0; 4], |bytes| bytemuck::pod_read_unaligned(&bytes[16 * i..16 * i + 16]))
    };
    (0..n)
        .map(|i| GpuPixel {
            radiance: texel(layers[0], i),
            albedo_roughness: texel(layers[1], i),
            normal_metallic: texel(layers[2], i),
            position_depth: texel(layers[3], i),
        })
        .collect()
}

/// The CPU reference's view of a traced pixel (same fields as `parallax_scene::PixelSample`).
pub fn to_pixel_sample(p: &GpuPixel) -> parallax_scene::PixelSample {
    use glam::Vec3;
    parallax_scene::PixelSample {
        radiance: Vec3::from_slice(&p.radiance[..3]),
        albedo: Vec3::from_slice(&p.albedo_roughness[..3]),
        normal: Vec3::from_slice(&p.normal_metallic[..3]),
        depth: p.position_depth[3],
        position: Vec3::from_slice(&p.position_depth[..3]),
        roughness: p.albedo_roughness[3],
        metallic: p.normal_metallic[3],
        hit: p.radiance[3] > 0.5,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parallax_backend::reflect::member_offsets;
    use parallax_backend::rust_layout;

    #[test]
    fn the_push_struct_matches_pt_trace_comp() {
        let glsl = member_offsets(&parallax_backend::spirv("pt_trace").unwrap(), "PathTracePush").unwrap();
        let rust = rust_layout!(PathTracePush {
            scene,
            trace,
            pixel_list,
            radiance,
            albedo_roughness,
            normal_metallic,
            position_depth,
            y0,
            y1,
            width,
            list_mode
        });
        assert_eq!(glsl, rust);
        assert_eq!(std::mem::size_of::<PathTracePush>(), 96);
    }
}
