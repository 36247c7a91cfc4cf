//! The per-device descriptor layout every kernel shares, and compute and graphics pipelines
//! created on first use from the shaders of a [`ShaderLibrary`].
//!
//! Layout (set 0): binding 0 = every float storage image of the device (an array sized by the
//! specialisation constant `IMAGE_COUNT`), binding 1 = the frame-constants uniform buffer of the
//! frame-in-flight slot, binding 2 = the R32_UINT images at the same indices, binding 3 = the
//! sampled textures ([`MAX_TEXTURES`] combined image samplers, global like uploaded buffers),
//! binding 4 = the depth images ([`Format::Depth32f`]) as sampled images at the same indices
//! again (`depth_images[]`, read with `texelFetch`: depth formats cannot be storage images, and
//! a raster pass's depth attachment is a graph resource a later compute pass reads). Each image
//! array holds a 1x1 placeholder where another one holds the real image, and unused texture
//! slots hold a 1x1 white texture, so every descriptor is valid. Every image, depth ones
//! included, stays in `GENERAL`: valid for storage, sampling, transfers and (with dynamic
//! rendering) colour and depth attachments, so passes never track layouts. Kernels select
//! images and textures by index in push constants, so one descriptor set per slot serves every
//! pass and recorded command buffers only need new descriptors when the textures change.

use std::collections::HashMap;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;
use parallax_graph::Format;

use crate::device::Device;
use crate::error::{BackendError, Result, VkContext};
use crate::frame_block::FrameConstants;
use crate::memory::{Buffer, Image};
use crate::reflect::{MemberLayout, push_constant_block};
use crate::shaders::ShaderLibrary;
use crate::texture::{MAX_TEXTURES, Texture, TextureData, create_sampler};

/// Stages that see the descriptor set and the push constants: compute kernels and raster passes.
pub(crate) const SHADER_STAGES: vk::ShaderStageFlags = vk::ShaderStageFlags::from_raw(
    vk::ShaderStageFlags::COMPUTE.as_raw()
        | vk::ShaderStageFlags::VERTEX.as_raw()
        | vk::ShaderStageFlags::FRAGMENT.as_raw(),
);

/// What a graphics pipeline is specialised on.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct GraphicsKey {
    pub vertex: String,
    pub fragment: String,
    pub color_formats: Vec<vk::Format>,
    /// A `D32_SFLOAT` depth attachment, tested LESS and written.
    pub depth: bool,
}

/// Size of the push-constant range: `PassParams` (32 bytes) by default; kernels that define
/// their own block (`PARALLAX_CUSTOM_PUSH_CONSTANTS`) may use up to the 128 bytes every Vulkan
/// device guarantees.
pub const PUSH_CONSTANT_BYTES: u32 = 128;
/// Size of the frame-constants uniform block.
const FRAME_CONSTANT_BYTES: u64 = 16;

/// The members of a shader's push-constant block (`None`: it declares none), reflected when its
/// pipeline is created, which every dispatch's or draw's push constants are held to.
pub(crate) type PushBlock = Option<Vec<MemberLayout>>;

/// A Vulkan pipeline (compute or graphics) and the push-constant blocks of its shaders (by shader name).
pub(crate) struct ShaderPipeline {
    pub(crate) raw: vk::Pipeline,
    pub(crate) push_blocks: Vec<(String, PushBlock)>,
}

/// Descriptor layout, sets and pipelines of one device for one plan.
pub(crate) struct Bindless {
    device: Arc<Device>,
    set_layout: vk::DescriptorSetLayout,
    pub(crate) pipeline_layout: vk::PipelineLayout,
    pool: vk::DescriptorPool,
    /// One descriptor set per frame-in-flight slot.
    pub(crate) sets: Vec<vk::DescriptorSet>,
    /// Host-visible frame constants, one buffer per slot.
    frame_constants: Vec<Buffer>,
    image_count: u32,
    /// Where pipelines' shaders come from: the library's layers, then the backend's own.
    shaders: ShaderLibrary,
    pipelines: HashMap<String, ShaderPipeline>,
    graphics_pipelines: HashMap<GraphicsKey, ShaderPipeline>,
    /// Float, uint and depth 1x1 images shown where a binding's array has no image of its kind.
    placeholders: [Image; 3],
    /// What unused texture slots show, and the sampler of every slot.
    placeholder_texture: Texture,
    sampler: vk::Sampler,
}

/// Set 0 (see the module documentation), with image arrays of `image_count`.
fn set_bindings(image_count: u32) -> [vk::DescriptorSetLayoutBinding<'static>; 5] {
    let binding = |binding: u32, descriptor_type: vk::DescriptorType, count: u32| {
        vk::DescriptorSetLayoutBinding::default()
            .binding(binding)
            .descriptor_type(descriptor_type)
            .descriptor_count(count)
            .stage_flags(SHADER_STAGES)
    };
    [
        binding(0, vk::DescriptorType::STORAGE_IMAGE, image_count),
        binding(1, vk::DescriptorType::UNIFORM_BUFFER, 1),
        binding(2, vk::DescriptorType::STORAGE_IMAGE, image_count),
        binding(3, vk::DescriptorType::COMBINED_IMAGE_SAMPLER, MAX_TEXTURES),
        binding(4, vk::DescriptorType::SAMPLED_IMAGE, image_count),
    ]
}

/// The layout of set 0 and the push-constant range every pipeline shares.
fn create_pipeline_layout(raw: &ash::Device, set_layout: vk::DescriptorSetLayout) -> Result<vk::PipelineLayout> {
    let ranges = [vk::PushConstantRange::default().stage_flags(SHADER_STAGES).offset(0).size(PUSH_CONSTANT_BYTES)];
    let set_layouts = [set_layout];
    unsafe {
        raw.create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges),
            None,
        )
    }
    .vk("vkCreatePipelineLayout")
}

/// A pool for `slots` sets of set 0 with image arrays of `image_count`.
fn create_descriptor_pool(raw: &ash::Device, image_count: u32, slots: usize) -> Result<vk::DescriptorPool> {
    let sizes = [
        vk::DescriptorPoolSize::default()
            .ty(vk::DescriptorType::STORAGE_IMAGE)
            .descriptor_count(2 * image_count * slots as u32),
        vk::DescriptorPoolSize::default().ty(vk::DescriptorType::UNIFORM_BUFFER).descriptor_count(slots as u32),
        vk::DescriptorPoolSize::default()
            .ty(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
            .descriptor_count(MAX_TEXTURES * slots as u32),
        vk::DescriptorPoolSize::default()
            .ty(vk::DescriptorType::SAMPLED_IMAGE)
            .descriptor_count(image_count * slots as u32),
    ];
    unsafe {
        raw.create_descriptor_pool(
            &vk::DescriptorPoolCreateInfo::default().max_sets(slots as u32).pool_sizes(&sizes),
            None,
        )
    }
    .vk("vkCreateDescriptorPool")
}

impl Bindless {
    /// Creates the layout for `images` and `slots` descriptor sets, all written.
    /// `placeholders` are a float, a uint and a depth 1x1 image in `GENERAL` layout; they live as long
    /// as the descriptor sets that name them. Pipelines take their shaders from `shaders`.
    pub(crate) fn new(
        device: &Arc<Device>,
        images: &[&Image],
        placeholders: [Image; 3],
        slots: usize,
        shaders: ShaderLibrary,
    ) -> Result<Self> {
        // A zero-sized descriptor array is invalid; a device with no image still gets one slot
        // (never indexed), holding the placeholders.
        let image_count = images.len().max(1) as u32;
        let bindings = set_bindings(image_count);
        let placeholder_texture =
            Texture::new(device, "placeholder texture", &TextureData { width: 1, height: 1, rgba8: &[255; 4] })?;
        let sampler = create_sampler(device)?;
        let raw = &device.raw;
        let set_layout = unsafe {
            raw.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
        }
        .vk("vkCreateDescriptorSetLayout")?;
        let mut this = Self {
            device: device.clone(),
            set_layout,
            pipeline_layout: vk::PipelineLayout::null(),
            pool: vk::DescriptorPool::null(),
            sets: Vec::new(),
            frame_constants: Vec::new(),
            image_count,
            shaders,
            pipelines: HashMap::new(),
            graphics_pipelines: HashMap::new(),
            placeholders,
            placeholder_texture,
            sampler,
        };
        this.pipeline_layout = create_pipeline_layout(raw, set_layout)?;
        this.pool = create_descriptor_pool(raw, image_count, slots)?;
        let layouts = vec![set_layout; slots];
        this.sets = unsafe {
            raw.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default().descriptor_pool(this.pool).set_layouts(&layouts),
            )
        }
        .vk("vkAllocateDescriptorSets")?;
        for slot in 0..slots {
            this.frame_constants.push(Buffer::new(
                device,
                "frame constants",
                FRAME_CONSTANT_BYTES,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
                MemoryLocation::CpuToGpu,
            )?);
            this.write_set(slot, images);
        }
        this.set_textures(&[]);
        Ok(this)
    }

    /// Points the texture array of every slot at `textures` (at most [`MAX_TEXTURES`], checked
    /// by the executor); the other slots show the placeholder. No slot may be in flight, and
    /// command buffers recorded with the old descriptors must be recorded again.
    pub(crate) fn set_textures(&self, textures: &[vk::ImageView]) {
        let infos: Vec<vk::DescriptorImageInfo> = (0..MAX_TEXTURES as usize)
            .map(|i| {
                vk::DescriptorImageInfo::default()
                    .sampler(self.sampler)
                    .image_view(textures.get(i).copied().unwrap_or(self.placeholder_texture.view()))
                    .image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
            })
            .collect();
        let writes: Vec<vk::WriteDescriptorSet> = self
            .sets
            .iter()
            .map(|&set| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(3)
                    .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                    .image_info(&infos)
            })
            .collect();
        unsafe { self.device.raw.update_descriptor_sets(&writes, &[]) };
    }

    fn write_set(&self, slot: usize, images: &[&Image]) {
        let [float_placeholder, uint_placeholder, depth_placeholder] = &self.placeholders;
        let info = |img: &Image| {
            vk::DescriptorImageInfo::default().image_view(img.view).image_layout(vk::ImageLayout::GENERAL)
        };
        // Each image goes into the one array of its kind; the other arrays show a placeholder
        // at its index.
        let array = |own: fn(&Image) -> bool, placeholder: &Image| -> Vec<vk::DescriptorImageInfo> {
            if images.is_empty() {
                return vec![info(placeholder)];
            }
            images.iter().map(|&img| info(if own(img) { img } else { placeholder })).collect()
        };
        let float_infos = array(|img| img.format != Format::R32u && !img.format.is_depth(), float_placeholder);
        let uint_infos = array(|img| img.format == Format::R32u, uint_placeholder);
        let depth_infos = array(|img| img.format.is_depth(), depth_placeholder);
        let buffer_infos = [vk::DescriptorBufferInfo::default()
            .buffer(self.frame_constants[slot].raw)
            .offset(0)
            .range(FRAME_CONSTANT_BYTES)];
        let writes = [
            vk::WriteDescriptorSet::default()
                .dst_set(self.sets[slot])
                .dst_binding(0)
                .descriptor_type(vk::DescriptorType::STORAGE_IMAGE)
                .image_info(&float_infos),
            vk::WriteDescriptorSet::default()
                .dst_set(self.sets[slot])
                .dst_binding(1)
                .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
                .buffer_info(&buffer_infos),
            vk::WriteDescriptorSet::default()
                .dst_set(self.sets[slot])
                .dst_binding(2)
                .descriptor_type(vk::DescriptorType::STORAGE_IMAGE)
                .image_info(&uint_infos),
            vk::WriteDescriptorSet::default()
                .dst_set(self.sets[slot])
                .dst_binding(4)
                .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                .image_info(&depth_infos),
        ];
        unsafe { self.device.raw.update_descriptor_sets(&writes, &[]) };
    }

    /// Writes the frame constants of `slot` (the slot must not be in flight).
    pub(crate) fn set_frame_constants(&mut self, slot: usize, constants: FrameConstants) {
        if let Some(bytes) = self.frame_constants[slot].mapped_mut() {
            constants.write_into(bytes);
        }
    }

    /// The compute pipeline of shader `name`, created on first use.
    pub(crate) fn compute_pipeline(&mut self, name: &str) -> Result<&ShaderPipeline> {
        if self.pipelines.contains_key(name) {
            return Ok(&self.pipelines[name]);
        }
        let code = self.shaders.spirv(name)?;
        let push_blocks = vec![(name.to_string(), reflect_push_block(name, &code)?)];
        let raw = &self.device.raw;
        let module = unsafe { raw.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None) }
            .vk("vkCreateShaderModule")?;
        let entries = [vk::SpecializationMapEntry::default().constant_id(0).offset(0).size(4)];
        let data = self.image_count.to_le_bytes();
        let specialization = vk::SpecializationInfo::default().map_entries(&entries).data(&data);
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main")
            .specialization_info(&specialization);
        let flags = if self.device.pipeline_stats.is_some() {
            vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR
        } else {
            vk::PipelineCreateFlags::empty()
        };
        let info = [vk::ComputePipelineCreateInfo::default().flags(flags).stage(stage).layout(self.pipeline_layout)];
        let created = unsafe { raw.create_compute_pipelines(vk::PipelineCache::null(), &info, None) };
        unsafe { raw.destroy_shader_module(module, None) };
        let pipeline = created.map_err(|(_, result)| BackendError::vk("vkCreateComputePipelines", result))?.remove(0);
        if let Some(stats) = &self.device.pipeline_stats {
            print_pipeline_statistics(stats, pipeline, name, self.device.info.index);
        }
        Ok(self.pipelines.entry(name.to_string()).or_insert(ShaderPipeline { raw: pipeline, push_blocks }))
    }
}

impl Bindless {
    /// The graphics pipeline of `key`, created on first use: no vertex input (vertex shaders
    /// pull what they need from storage), triangle lists, no culling, dynamic viewport and
    /// scissor, depth test LESS with writes when asked, no blending.
    pub(crate) fn graphics_pipeline(&mut self, key: &GraphicsKey) -> Result<&ShaderPipeline> {
        if self.graphics_pipelines.contains_key(key) {
            return Ok(&self.graphics_pipelines[key]);
        }
        let raw = &self.device.raw;
        // Both shaders are looked up (and reflected) before either module exists, so an unknown
        // name leaks none.
        let codes = [self.shaders.spirv(&key.vertex)?, self.shaders.spirv(&key.fragment)?];
        let push_blocks = vec![
            (key.vertex.clone(), reflect_push_block(&key.vertex, &codes[0])?),
            (key.fragment.clone(), reflect_push_block(&key.fragment, &codes[1])?),
        ];
        let mut modules = Vec::new();
        for code in &codes {
            let module = unsafe { raw.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(code), None) }
                .vk("vkCreateShaderModule");
            match module {
                Ok(m) => modules.push(m),
                Err(e) => {
                    modules.iter().for_each(|&m| unsafe { raw.destroy_shader_module(m, None) });
                    return Err(e);
                }
            }
        }
        let entries = [vk::SpecializationMapEntry::default().constant_id(0).offset(0).size(4)];
        let data = self.image_count.to_le_bytes();
        let specialization = vk::SpecializationInfo::default().map_entries(&entries).data(&data);
        let stages = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(modules[0])
                .name(c"main")
                .specialization_info(&specialization),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(modules[1])
                .name(c"main")
                .specialization_info(&specialization),
        ];
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
        let input_assembly =
            vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(vk::CullModeFlags::NONE)
            .line_width(1.0);
        let multisample =
            vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(key.depth)
            .depth_write_enable(key.depth)
            .depth_compare_op(vk::CompareOp::LESS);
        let attachments: Vec<vk::PipelineColorBlendAttachmentState> = key
            .color_formats
            .iter()
            .map(|_| vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA))
            .collect();
        let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&attachments);
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let mut rendering = vk::PipelineRenderingCreateInfo::default().color_attachment_formats(&key.color_formats);
        if key.depth {
            rendering = rendering.depth_attachment_format(vk::Format::D32_SFLOAT);
        }
        let info = [vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&input_assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(self.pipeline_layout)
            .push_next(&mut rendering)];
        let created = unsafe { raw.create_graphics_pipelines(vk::PipelineCache::null(), &info, None) };
        modules.iter().for_each(|&m| unsafe { raw.destroy_shader_module(m, None) });
        let pipeline = created.map_err(|(_, result)| BackendError::vk("vkCreateGraphicsPipelines", result))?.remove(0);
        Ok(self.graphics_pipelines.entry(key.clone()).or_insert(ShaderPipeline { raw: pipeline, push_blocks }))
    }
}

/// The push-constant block of shader `name`.
fn reflect_push_block(name: &str, code: &[u32]) -> Result<PushBlock> {
    let block =
        push_constant_block(code).map_err(|defect| BackendError::Reflection { shader: name.to_string(), defect })?;
    Ok(block.map(|(_, members)| members))
}

impl Drop for Bindless {
    fn drop(&mut self) {
        let raw = &self.device.raw;
        unsafe {
            for (_, p) in self.pipelines.drain() {
                raw.destroy_pipeline(p.raw, None);
            }
            for (_, p) in self.graphics_pipelines.drain() {
                raw.destroy_pipeline(p.raw, None);
            }
            raw.destroy_descriptor_pool(self.pool, None);
            raw.destroy_sampler(self.sampler, None);
            raw.destroy_pipeline_layout(self.pipeline_layout, None);
            raw.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// Prints the driver's statistics of every executable of `pipeline` (on NVIDIA: register
/// count, local and shared memory) as one stderr line per executable: what sets a kernel's
/// occupancy, which no Vulkan profiler here can show.
fn print_pipeline_statistics(
    stats: &ash::khr::pipeline_executable_properties::Device,
    pipeline: vk::Pipeline,
    name: &str,
    device: usize,
) {
    let pipeline_info = vk::PipelineInfoKHR::default().pipeline(pipeline);
    let Ok(executables) = (unsafe { stats.get_pipeline_executable_properties(&pipeline_info) }) else {
        return;
    };
    for index in 0..executables.len() as u32 {
        let info = vk::PipelineExecutableInfoKHR::default().pipeline(pipeline).executable_index(index);
        let Ok(values) = (unsafe { stats.get_pipeline_executable_statistics(&info) }) else {
            continue;
        };
        let fields: Vec<String> = values
            .iter()
            .map(|v| {
                let label = v.name_as_c_str().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                let value = unsafe {
                    match v.format {
                        vk::PipelineExecutableStatisticFormatKHR::BOOL32 => (v.value.b32 != 0).to_string(),
                        vk::PipelineExecutableStatisticFormatKHR::INT64 => v.value.i64.to_string(),
                        vk::PipelineExecutableStatisticFormatKHR::UINT64 => v.value.u64.to_string(),
                        _ => v.value.f64.to_string(),
                    }
                };
                format!("{label}={value}")
            })
            .collect();
        // Not `eprintln!`, which panics when stderr cannot be written (`2> /dev/full`).
        let line = format!("pipeline statistics: device {device} {name} executable {index}: {}\n", fields.join(", "));
        let _ = std::io::Write::write_all(&mut std::io::stderr(), line.as_bytes());
    }
}
