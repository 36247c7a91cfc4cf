//! The `path_trace` pass: shaders/pt_trace.comp (the GPU twin of the CPU reference path
//! tracer) over any subset of a view's pixels.
//!
//! * Writes (1 to 4, in this order): radiance (rgb, a = 1 where the first hit exists), albedo
//!   and roughness, normal and metallic, position and linear depth: the [`TRACE_OUTPUTS`]
//!   images.
//! * Pixels: the instance's row band (a whole view or one device's strip), or, when its kernel
//!   is given a pixel-list read ([`PathTraceKernel::with_list`]), the listed pixels of its band: the list in the band's
//!   section of the buffer (a row buffer's rows `[y0, y1)`, or all of a plain buffer; see
//!   [`crate::pixel_list`]). The dispatch covers the section's capacity and the invocations past
//!   the list's count return at once. Hole filling traces its lists with its own kernel, one
//!   dispatch for all targets of a device ([`crate::HoleFillKernel`]), the same `trace_pixel_from`
//!   (its camera rays' traversals bounded by the G-buffer's `first_hit`, the same bits).
//! * Camera, frame index and settings come from the per-frame data, one
//!   [`GpuTraceParams`] per view ([`trace_frame_data`]), so frames change without
//!   re-recording; the scene from [`crate::upload_scene`].

use parallax_backend::{
    Access, BackendError, Format, InstanceId, PassInstance, PassKernel, ReadSlot, Recorder, ResourceKind, WriteSlot,
};
use parallax_graph::FamilyId;
use parallax_scene::gpu::{GpuPixel, GpuTraceParams, TraceLighting};
use parallax_scene::{PixelSet, Scene, TraceSettings, View};

use crate::error::{PassError, Result};
use crate::pixel_list::list_groups;
use crate::scene_upload::scene_refs;
use crate::shaders::{self, PathTracePush};

/// Pass name the kernel is registered under.
pub const PATH_TRACE: &str = "path_trace";

/// Images a `path_trace` pass writes, in write order, all `Rgba32f`.
pub const TRACE_OUTPUTS: [&str; 4] = ["radiance", "albedo_roughness", "normal_metallic", "position_depth"];

/// The declared resources of a compiled trace's [`TRACE_OUTPUTS`] images, in that order (radiance
/// always; a first-hit layer where the graph declares it): what [`crate::LightFieldRenderer::trace`]
/// reads the traced views from.
pub type TraceOutputs = [Option<FamilyId>; 4];

/// Image index meaning "not written" in the push constants.
pub(crate) const NO_IMAGE: u32 = u32::MAX;
/// Bytes of one view's parameters in the per-frame data.
pub const TRACE_PARAMS_BYTES: u64 = std::mem::size_of::<GpuTraceParams>() as u64;

/// Records `path_trace` instances (see the module docs) through the slots its pass declared:
/// the radiance write, optionally the G-buffer writes and a pixel list.
pub struct PathTraceKernel {
    /// In [`TRACE_OUTPUTS`] order; radiance always, the G-buffer layers where declared.
    outputs: [Option<WriteSlot>; 4],
    list: Option<ReadSlot>,
}

impl PathTraceKernel {
    /// Traces the band's pixels into the `radiance` write.
    pub fn new(radiance: WriteSlot) -> Self {
        Self { outputs: [Some(radiance), None, None, None], list: None }
    }

    /// Also writes the first hit's albedo and roughness, normal and metallic, position and
    /// linear depth.
    pub fn with_gbuffer(mut self, [albedo_roughness, normal_metallic, position_depth]: [WriteSlot; 3]) -> Self {
        self.outputs[1..].copy_from_slice(&[Some(albedo_roughness), Some(normal_metallic), Some(position_depth)]);
        self
    }

    /// Traces only the pixels of the list `list` reads (see the module docs).
    pub fn with_list(mut self, list: ReadSlot) -> Self {
        self.list = Some(list);
        self
    }
}

fn misuse(index: InstanceId, detail: String) -> BackendError {
    BackendError::KernelMisuse { kernel: PATH_TRACE.into(), instance: Some(index), detail }
}

impl PassKernel for PathTraceKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let mut images = [NO_IMAGE; 4];
        let mut width = 0;
        for (image, slot) in images.iter_mut().zip(self.outputs) {
            let Some(slot) = slot else { continue };
            let write = pass.write(slot)?;
            let target = rec.resource(write.alloc);
            width = target.width;
            if target.kind != ResourceKind::Image || target.format == Format::R32u || target.format.is_depth() {
                return Err(misuse(index, format!("its write `{}` must be a float image", target.name)));
            }
            *image = rec.image(write.alloc)?;
        }
        let list = match self.list {
            Some(slot) => Some(list_section(rec, pass.read(slot)?, index)?),
            None => None,
        };
        let push = PathTracePush {
            scene: scene_refs(rec)?,
            trace: rec.frame_data_address() + u64::from(pass.view.0) * TRACE_PARAMS_BYTES,
            pixel_list: list.map_or(0, |(address, _)| address),
            radiance: images[0],
            albedo_roughness: images[1],
            normal_metallic: images[2],
            position_depth: images[3],
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            list_mode: u32::from(list.is_some()),
        };
        match list {
            Some((_, capacity)) => rec.dispatch(shaders::PT_TRACE, &push, list_groups(capacity)),
            // 8x8-pixel tiles (see pt_trace.comp).
            None => {
                rec.dispatch(shaders::PT_TRACE, &push, [width.div_ceil(8), pass.region.len().div_ceil(8).max(1), 1])
            }
        }
    }
}

/// Where the list of `read` (a pixel-list read of this instance) is: the GPU address of its
/// band's section and how many entries the section holds. The section is the read's rows: the
/// instance's band of a row buffer, or row 0, all of it, of a plain buffer.
pub(crate) fn list_section(
    rec: &Recorder<'_>,
    read: &Access,
    index: InstanceId,
) -> parallax_backend::Result<(u64, u32)> {
    let list = rec.resource(read.alloc);
    let offset = u64::from(read.region.y0) * list.row_bytes();
    let section = u64::from(read.region.len()) * list.row_bytes();
    if list.kind != ResourceKind::Buffer || section < u64::from(crate::pixel_list::LIST_HEADER_WORDS) * 4 {
        let detail = format!("its read `{}` must be a pixel-list buffer with room for the list header", list.name);
        return Err(misuse(index, detail));
    }
    let capacity = u32::try_from(section / 4 - u64::from(crate::pixel_list::LIST_HEADER_WORDS)).unwrap_or(u32::MAX);
    Ok((rec.buffer_of(read.alloc)? + offset, capacity))
}

/// The per-frame data of `path_trace`: one [`GpuTraceParams`] per view, view `i` at
/// `i * TRACE_PARAMS_BYTES`. `views[i].index` must be `i` (it keys the random numbers and
/// locates the view's parameters).
pub fn trace_frame_data(scene: &Scene, views: &[View], settings: &TraceSettings) -> Result<Vec<u8>> {
    trace_frame_data_lit(&TraceLighting::new(scene), views, settings)
}

/// [`trace_frame_data`] with the scene's lighting gathered already (a renderer does it once,
/// not once per view and frame: it walks every triangle).
pub fn trace_frame_data_lit(lighting: &TraceLighting, views: &[View], settings: &TraceSettings) -> Result<Vec<u8>> {
    settings.validate()?;
    let mut bytes = Vec::with_capacity(views.len() * TRACE_PARAMS_BYTES as usize);
    for (position, view) in views.iter().enumerate() {
        if view.index as usize != position {
            return Err(PassError::ViewOrder { position, index: view.index });
        }
        if view.width > 1 << 16 || view.height > 1 << 16 {
            return Err(PassError::ViewTooLarge { width: view.width, height: view.height });
        }
        let params = GpuTraceParams::with_lighting(lighting, view, settings, &PixelSet::All);
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
