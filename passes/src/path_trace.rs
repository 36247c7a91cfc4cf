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

use parallax_backend::{BackendError, PassKernel, PlanPass, Recorder, ResourceKind, TexelFormat};
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

impl PassKernel for PathTraceKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PlanPass, index: usize) -> parallax_backend::Result<()> {
        if pass.writes.is_empty() || pass.writes.len() > TRACE_OUTPUTS.len() || pass.reads.len() > 1 {
            return Err(misuse(
                index,
                format!(
                    "expects 1 to 4 image writes and at most 1 read (a pixel list), got {} and {}",
                    pass.writes.len(),
                    pass.reads.len()
                ),
            ));
        }
        let width = rec.resource(pass.writes[0].resource).width;
        let mut images = [NO_IMAGE; 4];
        for (slot, write) in images.iter_mut().zip(&pass.writes) {
            let target = rec.resource(write.resource);
            if target.kind != ResourceKind::Image || target.format == TexelFormat::R32Uint {
                return Err(misuse(index, format!("its write `{}` must be a float image", target.name)));
            }
            *slot = rec.image(write.resource)?;
        }
        let (list_mode, list_address, groups) = match pass.reads.first() {
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
        let trace_address = rec.frame_data_address() + u64::from(pass.view) * TRACE_PARAMS_BYTES;
        let mut push = scene_refs(rec)?;
        push.extend_from_slice(&trace_address.to_le_bytes());
        push.extend_from_slice(&list_address.to_le_bytes());
        for word in images.into_iter().chain([pass.rows.y0, pass.rows.y1, width, list_mode]) {
            push.extend_from_slice(&word.to_le_bytes());
        }
        rec.dispatch_bytes("pt_trace", &push, groups)
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
