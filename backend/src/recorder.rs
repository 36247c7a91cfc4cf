//! The recording API that pass kernels see. The kernels themselves ([`crate::PassKernel`]) live in
//! kernel.rs, which imports this module: a recorder reads the data plan, never a kernel.
//!
//! A kernel never touches descriptors, barriers or timestamps: the executor binds the device's
//! descriptor set and puts the barriers ([`crate::Barriers`]) and timestamp pairs
//! ([`crate::Timing`]) between ops. The kernel only chooses a shader, fills [`PassParams`] from
//! the pass instance and dispatches.

use ash::vk;
use gpu_allocator::MemoryLocation;
use parallax_graph::{Access, AllocId, Format, PassInstance, Region};

use crate::PassParams;
use crate::error::{BackendError, Result};
use crate::memory::{Buffer, Image};
use crate::plan::{ExecResource, ExecutionPlan};
use crate::push::{self, PushConstants};
use crate::record::SegmentContext;
use crate::shader_id::{DrawStage, ShaderName};
use crate::shader_pipelines::{Bindless, GraphicsKey, PUSH_CONSTANT_BYTES, SHADER_STAGES, ShaderPipeline};

/// Bytes of the arguments of an indirect dispatch: `VkDispatchIndirectCommand` (x, y, z).
const INDIRECT_ARGS_BYTES: u64 = 12;

/// A draw of a raster pass: the render targets are plan images, the row band limits the render
/// area and the scissor (the viewport stays the whole image, so a band renders exactly its rows
/// of the frame). Vertex shaders pull their vertices from buffers by address (no vertex input).
#[derive(Clone, Debug)]
pub struct Draw<'a, V, F> {
    /// Vertex and fragment shaders (`name.vert`, `name.frag`), from `ExecOptions::shaders`,
    /// else built in (shaders/): generated ids ([`DrawStage`]), so that a push struct of
    /// another block than theirs does not compile, or names.
    pub vertex_shader: V,
    pub fragment_shader: F,
    /// Colour targets (resources), in fragment output location order.
    pub color_targets: &'a [AllocId],
    /// The depth attachment: a [`Format::Depth32f`] resource, tested LESS and written. Without
    /// one the draw has no depth test.
    pub depth_target: Option<AllocId>,
    /// Clear the targets within the band first (colour to zero, depth to 1.0); otherwise load
    /// their contents. Every target has the same size.
    pub clear: bool,
    pub rows: Region,
    pub vertex_count: u32,
    pub instance_count: u32,
}

/// A buffer that one op of a recording owns ([`Recorder::recording_buffer`]): host-written at
/// record time, then read and written by the op's shaders by address, and a source of indirect
/// arguments ([`Recorder::dispatch_indirect_from`]).
#[derive(Clone, Copy, Debug)]
pub struct RecordingBuffer {
    address: u64,
    bytes: u64,
    raw: vk::Buffer,
}

impl RecordingBuffer {
    /// GPU address of its first byte.
    pub fn address(&self) -> u64 {
        self.address
    }

    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

/// Records the work of one pass instance (or of a group of them, [`crate::PassKernel::record_group`])
/// into a device's command buffer.
pub struct Recorder<'a> {
    /// What the segment being recorded reads: the plan, the device, its resources and the
    /// slot's addresses (record.rs), borrowed, not copied.
    pub(crate) ctx: &'a SegmentContext<'a>,
    /// Name of the pass being recorded, for errors.
    pub(crate) pass: &'a str,
    pub(crate) cb: vk::CommandBuffer,
    /// The pipeline left bound by the last dispatch or draw of the command buffer.
    pub(crate) bound: Option<vk::Pipeline>,
    /// The device's pipelines (created on first use) and descriptor sets.
    pub(crate) bindless: &'a mut Bindless,
    /// The recording buffers of this device and frame slot, dropped when it records again.
    pub(crate) recording_buffers: &'a mut Vec<Buffer>,
}

impl<'a> Recorder<'a> {
    /// Index of `resource` in the device's image arrays (what shaders get in push constants):
    /// `images[]`, or `uimages[]` for `R32u`, or `depth_images[]` for `Depth32f` (bindless.glsl).
    pub fn image(&self, resource: AllocId) -> Result<u32> {
        let resource = self.resolve(resource);
        if let Some(&slot) = self.ctx.image_slots.get(&resource) {
            return Ok(slot);
        }
        if self.ctx.buffer_addresses.contains_key(&resource) {
            return Err(BackendError::KernelMisuse {
                kernel: format!("a kernel of device {}", self.ctx.device_index),
                instance: None,
                detail: format!("resource {resource} is a buffer: use Recorder::buffer_of, not image"),
            });
        }
        Err(BackendError::ResourceNotOnDevice { resource, device: self.ctx.device_index })
    }

    /// The resource an access to `resource` touches in the frame parity being recorded.
    fn resolve(&self, resource: AllocId) -> AllocId {
        self.ctx.parity_map.get(&resource).copied().unwrap_or(resource)
    }

    /// The image slot of access `access` (see [`Self::image`]).
    pub fn image_of(&self, access: &Access) -> Result<u32> {
        self.image(access.alloc)
    }

    /// The plan's description of `resource`.
    pub fn resource(&self, resource: AllocId) -> &ExecResource {
        self.ctx.plan.resource(resource)
    }

    /// Index of the device being recorded.
    pub fn device_index(&self) -> usize {
        self.ctx.device_index
    }

    /// The plan being recorded (pass instance `i` is `plan().pass(i)`).
    pub fn plan(&self) -> &'a ExecutionPlan {
        &self.ctx.plan.plan
    }

    /// A buffer of `bytes.len()` bytes (at least 4) holding `bytes`, for the op being recorded
    /// on this device and frame-in-flight slot: data a kernel knows only at record time and
    /// that does not fit its push constants (addresses and image indices of many instances,
    /// say), and room its shaders write every frame (counts, indirect arguments). It lives
    /// until the command buffers are recorded again, so the host never writes it while a frame
    /// runs; each slot records its own, so frames in flight never share one. Host-visible
    /// memory (device-local where the device allows). It is memory the pass does not declare:
    /// only the op that asked for it may touch it, and orders its own accesses to it (the
    /// barrier of [`Self::dispatch_indirect_from`] orders the dispatches before it).
    pub fn recording_buffer(&mut self, name: &str, bytes: &[u8]) -> Result<RecordingBuffer> {
        let mut buffer = Buffer::new(
            self.ctx.device,
            name,
            (bytes.len() as u64).max(4),
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
                | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        buffer.mapped_mut().expect("CpuToGpu buffers are mapped")[..bytes.len()].copy_from_slice(bytes);
        let handle = RecordingBuffer { address: buffer.device_address(), bytes: buffer.size, raw: buffer.raw };
        self.recording_buffers.push(buffer);
        Ok(handle)
    }

    /// Binds compute shader `shader` (from `ExecOptions::shaders`, else built in), pushes
    /// `push` and dispatches `groups`. `push` is [`PassParams`] or a kernel-defined block (the
    /// shader defines `PARALLAX_CUSTOM_PUSH_CONSTANTS` and declares it); either way its layout
    /// must match the shader's block ([`PushConstants`]).
    pub fn dispatch<P: PushConstants>(&mut self, shader: impl ShaderName<P>, push: &P, groups: [u32; 3]) -> Result<()> {
        self.bind_compute(shader.shader_name(), push)?;
        unsafe { self.ctx.raw.cmd_dispatch(self.cb, groups[0], groups[1], groups[2]) };
        Ok(())
    }

    /// Like [`Self::dispatch`], with the workgroup counts read on the GPU from the
    /// per-view buffer `resource` at `byte_offset`: three `u32` (x, y, z), as a pass of the same
    /// frame wrote them (compaction counts; see `ExecResource::reset` for counters that start
    /// from zero every frame).
    ///
    /// Writes of earlier passes are ordered by the barrier before every pass; this also orders
    /// the writes of this pass's own earlier dispatches, so a kernel may compute its counts and
    /// dispatch on them in one pass.
    pub fn dispatch_indirect<P: PushConstants>(
        &mut self,
        shader: impl ShaderName<P>,
        push: &P,
        resource: AllocId,
        byte_offset: u64,
    ) -> Result<()> {
        let shader = shader.shader_name();
        let invalid = |problem: String| BackendError::IndirectArgs {
            shader: shader.to_string(),
            resource,
            offset: byte_offset,
            problem,
        };
        if self.ctx.images.contains_key(&resource) {
            return Err(invalid("it is an image; indirect arguments live in a buffer resource".into()));
        }
        let buffer = self
            .ctx
            .buffers
            .get(&resource)
            .ok_or_else(|| invalid(format!("it is not allocated on device {}", self.ctx.device_index)))?;
        let (raw, size) = (buffer.raw, buffer.size);
        self.indirect(shader, push, raw, size, byte_offset, invalid)
    }

    /// [`Self::dispatch_indirect`] with the arguments in a [`RecordingBuffer`] of this op.
    pub fn dispatch_indirect_from<P: PushConstants>(
        &mut self,
        shader: impl ShaderName<P>,
        push: &P,
        args: &RecordingBuffer,
        byte_offset: u64,
    ) -> Result<()> {
        let shader = shader.shader_name();
        let invalid = |problem: String| BackendError::KernelMisuse {
            kernel: shader.to_string(),
            instance: None,
            detail: format!("indirect arguments at byte {byte_offset} of a recording buffer: {problem}"),
        };
        self.indirect(shader, push, args.raw, args.bytes, byte_offset, invalid)
    }

    /// Checks that `byte_offset` holds arguments in the `size`-byte buffer `raw`, then binds,
    /// puts the barrier and dispatches (see [`Self::dispatch_indirect`]).
    fn indirect<P: PushConstants>(
        &mut self,
        shader: &str,
        push: &P,
        raw: vk::Buffer,
        size: u64,
        byte_offset: u64,
        invalid: impl Fn(String) -> BackendError,
    ) -> Result<()> {
        if byte_offset % 4 != 0 {
            return Err(invalid("the offset is not a multiple of 4".into()));
        }
        if byte_offset.checked_add(INDIRECT_ARGS_BYTES).is_none_or(|end| end > size) {
            return Err(invalid(format!("{INDIRECT_ARGS_BYTES} bytes of arguments do not fit the {size}-byte buffer")));
        }
        self.bind_compute(shader, push)?;
        // Earlier dispatches of this pass → the argument read and the indirect shader itself
        // (which typically reads the count next to the arguments).
        let args_ready = [vk::MemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
            .src_access_mask(vk::AccessFlags2::SHADER_STORAGE_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::DRAW_INDIRECT | vk::PipelineStageFlags2::COMPUTE_SHADER)
            .dst_access_mask(
                vk::AccessFlags2::INDIRECT_COMMAND_READ
                    | vk::AccessFlags2::SHADER_STORAGE_READ
                    | vk::AccessFlags2::SHADER_STORAGE_WRITE,
            )];
        unsafe {
            self.ctx.raw.cmd_pipeline_barrier2(self.cb, &vk::DependencyInfo::default().memory_barriers(&args_ready));
            self.ctx.raw.cmd_dispatch_indirect(self.cb, raw, byte_offset);
        }
        Ok(())
    }

    /// Binds compute shader `shader` (unless bound already) and pushes `push` (at most 128
    /// bytes, a multiple of 4), once its layout is found to match the shader's block.
    fn bind_compute<P: PushConstants>(&mut self, shader: &str, push: &P) -> Result<()> {
        let bytes = bytemuck::bytes_of(push);
        if bytes.len() > PUSH_CONSTANT_BYTES as usize || bytes.len() % 4 != 0 {
            return Err(BackendError::KernelMisuse {
                kernel: shader.to_string(),
                instance: None,
                detail: format!("{} push-constant bytes (at most {PUSH_CONSTANT_BYTES}, a multiple of 4)", bytes.len()),
            });
        }
        let pipeline = self.bindless.compute_pipeline(shader)?;
        check_push::<P>(self.pass, pipeline)?;
        let pipeline = pipeline.raw;
        unsafe {
            if self.bound != Some(pipeline) {
                self.ctx.raw.cmd_bind_pipeline(self.cb, vk::PipelineBindPoint::COMPUTE, pipeline);
                self.bound = Some(pipeline);
            }
            if !bytes.is_empty() {
                self.ctx.raw.cmd_push_constants(self.cb, self.bindless.pipeline_layout, SHADER_STAGES, 0, bytes);
            }
        }
        Ok(())
    }

    /// GPU address of the per-view buffer `resource` (a `ResourceKind::Buffer` of the plan) on
    /// this device.
    pub fn buffer_of(&self, resource: AllocId) -> Result<u64> {
        self.ctx
            .buffer_addresses
            .get(&self.resolve(resource))
            .copied()
            .ok_or(BackendError::ResourceNotOnDevice { resource, device: self.ctx.device_index })
    }

    /// GPU address of the global buffer `name` on this device (see `Executor::upload_buffer`).
    pub fn buffer_address(&self, name: &str) -> Result<u64> {
        self.global_buffer(name).map(|(address, _)| address)
    }

    /// Size in bytes of the global buffer `name` (what was uploaded, at least 4): how many
    /// elements a draw or dispatch covers. Uploading another size records again, so a count
    /// derived from it stays right.
    pub fn buffer_bytes(&self, name: &str) -> Result<u64> {
        self.global_buffer(name).map(|(_, bytes)| bytes)
    }

    fn global_buffer(&self, name: &str) -> Result<(u64, u64)> {
        self.ctx
            .global_buffers
            .get(name)
            .copied()
            .ok_or_else(|| BackendError::UnknownBuffer { name: name.to_string(), device: self.ctx.device_index })
    }

    /// GPU address of this frame-in-flight slot's copy of the per-frame data (see
    /// `Executor::set_frame_data`); the contents change every frame without re-recording.
    pub fn frame_data_address(&self) -> u64 {
        self.ctx.frame_data_address
    }

    /// GPU address of the section `name` of the per-frame data (see `FrameData::section`), in
    /// this frame-in-flight slot's copy.
    pub fn frame_section_address(&self, name: &str) -> Result<u64> {
        self.ctx
            .frame_sections
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, offset)| self.ctx.frame_data_address + offset)
            .ok_or_else(|| BackendError::UnknownFrameSection {
                name: name.to_string(),
                known: self.ctx.frame_sections.iter().map(|(n, _)| n.clone()).collect(),
            })
    }

    /// GPU address of the frame block of cameras (see `FrameData::frame_block`), in this
    /// frame-in-flight slot's copy.
    pub fn frame_block_address(&self) -> Result<u64> {
        self.ctx
            .frame_block
            .map(|offset| self.ctx.frame_data_address + offset)
            .ok_or_else(|| BackendError::NoFrameBlock { pass: self.pass.to_string() })
    }

    /// The [`PassParams`] of a kernel that writes image `dst` over `pass`'s row band: `dst`,
    /// `view`, `y0`, `y1` and `width` set, the rest zero.
    pub fn row_params(&self, pass: &PassInstance, dst: AllocId) -> Result<PassParams> {
        Ok(PassParams {
            dst: self.image(dst)?,
            view: pass.view.0,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width: self.resource(dst).width,
            ..Default::default()
        })
    }

    /// Dispatches `shader` over `params.width` × rows `[y0, y1)` with the 8×8 workgroups every
    /// row-band kernel in shaders/ uses.
    pub fn dispatch_rows(&mut self, shader: impl ShaderName<PassParams>, params: PassParams) -> Result<()> {
        let rows = params.y1.saturating_sub(params.y0);
        self.dispatch(shader, &params, [params.width.div_ceil(8), rows.div_ceil(8), 1])
    }

    /// Renders `draw` with dynamic rendering into its colour and depth targets (images stay in
    /// `GENERAL`; the barrier before every pass orders the attachments against earlier passes).
    /// `push` goes to both stages, and must match the block of each that declares one.
    pub fn draw<P: PushConstants, V: DrawStage<P>, F: DrawStage<P>>(
        &mut self,
        draw: &Draw<'_, V, F>,
        push: &P,
    ) -> Result<()> {
        let misuse = |detail: String| BackendError::KernelMisuse {
            kernel: draw.vertex_shader.stage_name().to_string(),
            instance: None,
            detail,
        };
        let push_bytes = bytemuck::bytes_of(push);
        if push_bytes.len() > PUSH_CONSTANT_BYTES as usize || push_bytes.len() % 4 != 0 {
            return Err(misuse(format!(
                "{} push-constant bytes (at most {PUSH_CONSTANT_BYTES}, a multiple of 4)",
                push_bytes.len()
            )));
        }
        let Some(&first) = draw.color_targets.first().or(draw.depth_target.as_ref()) else {
            return Err(misuse("a draw needs a colour or a depth target".into()));
        };
        let targets = self.draw_targets(draw, first, &misuse)?;
        let key = GraphicsKey {
            vertex: draw.vertex_shader.stage_name().to_string(),
            fragment: draw.fragment_shader.stage_name().to_string(),
            color_formats: targets.color_formats.clone(),
            depth: targets.depth.is_some(),
        };
        let pipeline = self.bindless.graphics_pipeline(&key)?;
        check_push::<P>(self.pass, pipeline)?;
        let pipeline = pipeline.raw;
        self.record_draw(draw, &targets, pipeline, push_bytes);
        Ok(())
    }

    /// The draw's attachments, all of the size of its `first` target: colour targets of a
    /// colour format, the depth target `Depth32f`.
    fn draw_targets<V, F>(
        &self,
        draw: &Draw<'_, V, F>,
        first: AllocId,
        misuse: &dyn Fn(String) -> BackendError,
    ) -> Result<DrawTargets> {
        let (width, height) = (self.resource(first).width, self.resource(first).height);
        let target = |resource: AllocId| -> Result<&Image> {
            let desc = self.resource(resource);
            if (desc.width, desc.height) != (width, height) {
                return Err(misuse(format!(
                    "target `{}` is {}x{}, the draw's first target {width}x{height}",
                    desc.name, desc.width, desc.height
                )));
            }
            self.ctx
                .images
                .get(&self.resolve(resource))
                .ok_or(BackendError::ResourceNotOnDevice { resource, device: self.ctx.device_index })
        };
        let load_op = if draw.clear { vk::AttachmentLoadOp::CLEAR } else { vk::AttachmentLoadOp::LOAD };
        let mut color_formats = Vec::with_capacity(draw.color_targets.len());
        let mut colors = Vec::with_capacity(draw.color_targets.len());
        for &resource in draw.color_targets {
            let image = target(resource)?;
            if image.format.is_depth() {
                return Err(misuse(format!("colour target `{}` has a depth format", self.resource(resource).name)));
            }
            color_formats.push(crate::memory::vk_format(image.format)?);
            colors.push(
                vk::RenderingAttachmentInfo::default()
                    .image_view(image.view)
                    .image_layout(vk::ImageLayout::GENERAL)
                    .load_op(load_op)
                    .store_op(vk::AttachmentStoreOp::STORE),
            );
        }
        let depth = match draw.depth_target {
            Some(resource) => {
                let image = target(resource)?;
                if image.format != Format::Depth32f {
                    return Err(misuse(format!(
                        "depth target `{}` is {:?}, not Depth32f",
                        self.resource(resource).name,
                        image.format
                    )));
                }
                Some(
                    vk::RenderingAttachmentInfo::default()
                        .image_view(image.view)
                        .image_layout(vk::ImageLayout::GENERAL)
                        .load_op(load_op)
                        .store_op(vk::AttachmentStoreOp::STORE)
                        .clear_value(vk::ClearValue {
                            depth_stencil: vk::ClearDepthStencilValue { depth: 1.0, stencil: 0 },
                        }),
                )
            }
            None => None,
        };
        Ok(DrawTargets { width, height, color_formats, colors, depth })
    }

    /// Records the draw over its rows with `pipeline` into checked `targets`.
    fn record_draw<V, F>(
        &self,
        draw: &Draw<'_, V, F>,
        targets: &DrawTargets,
        pipeline: vk::Pipeline,
        push_bytes: &[u8],
    ) {
        let (width, height) = (targets.width, targets.height);
        let area = vk::Rect2D {
            offset: vk::Offset2D { x: 0, y: draw.rows.y0 as i32 },
            extent: vk::Extent2D { width, height: draw.rows.len() },
        };
        let mut rendering =
            vk::RenderingInfo::default().render_area(area).layer_count(1).color_attachments(&targets.colors);
        if let Some(depth) = &targets.depth {
            rendering = rendering.depth_attachment(depth);
        }
        let viewport =
            vk::Viewport { x: 0.0, y: 0.0, width: width as f32, height: height as f32, min_depth: 0.0, max_depth: 1.0 };
        unsafe {
            self.ctx.raw.cmd_begin_rendering(self.cb, &rendering);
            self.ctx.raw.cmd_bind_pipeline(self.cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            self.ctx.raw.cmd_bind_descriptor_sets(
                self.cb,
                vk::PipelineBindPoint::GRAPHICS,
                self.bindless.pipeline_layout,
                0,
                &[self.bindless.sets[self.ctx.slot]],
                &[],
            );
            self.ctx.raw.cmd_set_viewport(self.cb, 0, &[viewport]);
            self.ctx.raw.cmd_set_scissor(self.cb, 0, &[area]);
            if !push_bytes.is_empty() {
                self.ctx.raw.cmd_push_constants(self.cb, self.bindless.pipeline_layout, SHADER_STAGES, 0, push_bytes);
            }
            if draw.vertex_count > 0 && draw.instance_count > 0 {
                self.ctx.raw.cmd_draw(self.cb, draw.vertex_count, draw.instance_count, 0, 0);
            }
            self.ctx.raw.cmd_end_rendering(self.cb);
        }
    }

    /// The raw command buffer, for kernels that need a command the recorder does not wrap.
    pub fn command_buffer(&self) -> vk::CommandBuffer {
        self.cb
    }

    /// The raw device, with [`Self::command_buffer`].
    pub fn raw_device(&self) -> &ash::Device {
        self.ctx.raw
    }
}

/// Holds `P` against the push-constant block of each of `pipeline`'s shaders. A shader without
/// a block reads none of the bytes, so none can be misread.
fn check_push<P: PushConstants>(pass: &str, pipeline: &ShaderPipeline) -> Result<()> {
    let size = std::mem::size_of::<P>();
    for (shader, block) in &pipeline.push_blocks {
        if let Some(members) = block {
            push::compare(P::FIELDS, size, members).map_err(|mismatch| BackendError::PushConstantLayout {
                pass: pass.to_string(),
                shader: shader.clone(),
                rust_type: std::any::type_name::<P>(),
                field: mismatch.field,
                problem: mismatch.problem,
            })?;
        }
    }
    Ok(())
}

/// The checked attachments of one draw and their common size.
struct DrawTargets {
    width: u32,
    height: u32,
    color_formats: Vec<vk::Format>,
    colors: Vec<vk::RenderingAttachmentInfo<'static>>,
    depth: Option<vk::RenderingAttachmentInfo<'static>>,
}
