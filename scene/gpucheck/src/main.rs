//! GPU check for the CWBVH traversal: runs shaders/bvh_raycast.glsl through plain ash on the
//! first Vulkan device (a discrete GPU if there is one), compares every hit with the CPU
//! traversal of parallax-scene, and measures rays/s.
//!
//! A stop-gap outside the workspace: parallax-scene must not depend on ash, and the backend
//! has no API for scene buffers yet. It belongs in backend/ or passes/ once they can bind the
//! scene (parallax_scene::gpu::GpuScene); then this folder should go.
//!
//!   gpucheck check SCENE N                 N random rays: closest hit and any hit vs the CPU;
//!                                          exits 1 on any disagreement beyond a same-t tie
//!   gpucheck pt SCENE W H SPP FRAMES       shaders/pt_trace.glsl against the CPU reference
//!                                          (same view and random numbers); exits 1 if a
//!                                          channel mean differs by more than 1 %
//!   gpucheck bench SCENE W H [CAMERA]      primary, diffuse-bounce and any-hit rays/s at W x H;
//!                                          CAMERA = eye,target,up,yfov_degrees (10 numbers)
//!
//! SCENE is `default` or a glTF path. By default materials are made opaque and untextured on
//! both sides (kernels compiled with PT_SCENE_NO_TEXTURES); GPUCHECK_TEXTURES=1 binds the
//! scene's textures instead and keeps alpha masks on both sides. A scene without any light gets a sky
//! and a sun; GPUCHECK_CAMERA (10 numbers as for bench) replaces the default camera for `pt`. GPUCHECK_SPV / GPUCHECK_GROUP swap in another build of
//! the kernel and its workgroup size (for tuning).

use std::ffi::c_char;
use std::time::Instant;

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{AlphaMode, Camera, Scene, SceneBvh, load_scene};
use rayon::prelude::*;

const RAYCAST_SPV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/raycast.spv"));
const PT_TRACE_SPV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/pt_trace.spv"));
const RAYCAST_TEX_SPV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/raycast_tex.spv"));
const PT_TRACE_TEX_SPV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/pt_trace_tex.spv"));

/// GPUCHECK_TEXTURES=1: bind the scene's textures and keep alpha masks (textured kernels).
fn textured() -> bool {
    std::env::var("GPUCHECK_TEXTURES").is_ok_and(|v| v == "1")
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct RayIn {
    origin_tmin: [f32; 4],
    dir_tmax: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default, Debug)]
struct HitOut {
    prim: u32,
    t: f32,
    bary: [f32; 2],
}

struct Gpu {
    _entry: ash::Entry,
    instance: ash::Instance,
    device: ash::Device,
    queue: vk::Queue,
    pool: vk::CommandPool,
    mem: vk::PhysicalDeviceMemoryProperties,
    timestamp_period: f32,
    name: String,
}

struct Buf {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    size: u64,
}

impl Gpu {
    fn new() -> Self {
        unsafe {
            let entry = ash::Entry::load().expect("libvulkan.so.1");
            let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
            let instance = entry
                .create_instance(&vk::InstanceCreateInfo::default().application_info(&app), None)
                .expect("instance");
            let pdevs = instance.enumerate_physical_devices().unwrap();
            let pdev = *pdevs
                .iter()
                .find(|&&p| {
                    instance.get_physical_device_properties(p).device_type == vk::PhysicalDeviceType::DISCRETE_GPU
                })
                .unwrap_or(&pdevs[0]);
            let props = instance.get_physical_device_properties(pdev);
            let name = props.device_name_as_c_str().unwrap().to_string_lossy().into_owned();
            let qf = instance
                .get_physical_device_queue_family_properties(pdev)
                .iter()
                .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE) && q.timestamp_valid_bits > 0)
                .unwrap() as u32;
            let prio = [1.0f32];
            let qci = [vk::DeviceQueueCreateInfo::default().queue_family_index(qf).queue_priorities(&prio)];
            let exts: [*const c_char; 0] = [];
            let mut f12 = vk::PhysicalDeviceVulkan12Features::default()
                .host_query_reset(true)
                .runtime_descriptor_array(true)
                .shader_sampled_image_array_non_uniform_indexing(true);
            let device = instance
                .create_device(
                    pdev,
                    &vk::DeviceCreateInfo::default()
                        .queue_create_infos(&qci)
                        .enabled_extension_names(&exts)
                        .push_next(&mut f12),
                    None,
                )
                .expect("device");
            let queue = device.get_device_queue(qf, 0);
            let pool =
                device.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(qf), None).unwrap();
            let mem = instance.get_physical_device_memory_properties(pdev);
            Gpu {
                _entry: entry,
                instance,
                device,
                queue,
                pool,
                mem,
                timestamp_period: props.limits.timestamp_period,
                name,
            }
        }
    }

    fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> u32 {
        (0..self.mem.memory_type_count)
            .find(|&i| bits & (1 << i) != 0 && self.mem.memory_types[i as usize].property_flags.contains(flags))
            .expect("memory type")
    }

    fn buffer(&self, size: u64, usage: vk::BufferUsageFlags, host: bool) -> Buf {
        let size = size.max(16);
        unsafe {
            let buffer =
                self.device.create_buffer(&vk::BufferCreateInfo::default().size(size).usage(usage), None).unwrap();
            let req = self.device.get_buffer_memory_requirements(buffer);
            let flags = if host {
                vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT
            } else {
                vk::MemoryPropertyFlags::DEVICE_LOCAL
            };
            let memory = self
                .device
                .allocate_memory(
                    &vk::MemoryAllocateInfo::default()
                        .allocation_size(req.size)
                        .memory_type_index(self.memory_type(req.memory_type_bits, flags)),
                    None,
                )
                .unwrap();
            self.device.bind_buffer_memory(buffer, memory, 0).unwrap();
            Buf { buffer, memory, size }
        }
    }

    fn one_shot(&self, record: impl FnOnce(vk::CommandBuffer)) {
        unsafe {
            let cb = self
                .device
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default().command_pool(self.pool).command_buffer_count(1),
                )
                .unwrap()[0];
            self.device.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default()).unwrap();
            record(cb);
            self.device.end_command_buffer(cb).unwrap();
            let fence = self.device.create_fence(&vk::FenceCreateInfo::default(), None).unwrap();
            let cbs = [cb];
            self.device.queue_submit(self.queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], fence).unwrap();
            self.device.wait_for_fences(&[fence], true, u64::MAX).unwrap();
            self.device.destroy_fence(fence, None);
            self.device.free_command_buffers(self.pool, &cbs);
        }
    }

    /// A device-local storage buffer holding `data`.
    fn upload(&self, data: &[u8]) -> Buf {
        let staging = self.buffer(data.len() as u64, vk::BufferUsageFlags::TRANSFER_SRC, true);
        unsafe {
            let p = self.device.map_memory(staging.memory, 0, staging.size, vk::MemoryMapFlags::empty()).unwrap()
                as *mut u8;
            std::ptr::copy_nonoverlapping(data.as_ptr(), p, data.len());
            self.device.unmap_memory(staging.memory);
        }
        let dst = self.buffer(
            data.len() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::TRANSFER_SRC,
            false,
        );
        if !data.is_empty() {
            self.one_shot(|cb| unsafe {
                self.device.cmd_copy_buffer(
                    cb,
                    staging.buffer,
                    dst.buffer,
                    &[vk::BufferCopy::default().size(data.len() as u64)],
                )
            });
        }
        self.free(staging);
        dst
    }

    fn download(&self, src: &Buf, len: usize) -> Vec<u8> {
        let staging = self.buffer(len as u64, vk::BufferUsageFlags::TRANSFER_DST, true);
        self.one_shot(|cb| unsafe {
            self.device.cmd_copy_buffer(cb, src.buffer, staging.buffer, &[vk::BufferCopy::default().size(len as u64)])
        });
        let mut out = vec![0u8; len];
        unsafe {
            let p = self.device.map_memory(staging.memory, 0, staging.size, vk::MemoryMapFlags::empty()).unwrap()
                as *const u8;
            std::ptr::copy_nonoverlapping(p, out.as_mut_ptr(), len);
            self.device.unmap_memory(staging.memory);
        }
        self.free(staging);
        out
    }

    /// An RGBA8 UNORM sampled image holding `tex` (level 0 only), in SHADER_READ_ONLY layout.
    fn upload_texture(&self, tex: &parallax_scene::Texture) -> (vk::Image, vk::DeviceMemory, vk::ImageView) {
        let staging = self.buffer(tex.rgba8.len() as u64, vk::BufferUsageFlags::TRANSFER_SRC, true);
        unsafe {
            let p = self.device.map_memory(staging.memory, 0, staging.size, vk::MemoryMapFlags::empty()).unwrap()
                as *mut u8;
            std::ptr::copy_nonoverlapping(tex.rgba8.as_ptr(), p, tex.rgba8.len());
            self.device.unmap_memory(staging.memory);
            let extent = vk::Extent3D { width: tex.width, height: tex.height, depth: 1 };
            let image = self
                .device
                .create_image(
                    &vk::ImageCreateInfo::default()
                        .image_type(vk::ImageType::TYPE_2D)
                        .format(vk::Format::R8G8B8A8_UNORM)
                        .extent(extent)
                        .mip_levels(1)
                        .array_layers(1)
                        .samples(vk::SampleCountFlags::TYPE_1)
                        .tiling(vk::ImageTiling::OPTIMAL)
                        .usage(vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST),
                    None,
                )
                .unwrap();
            let req = self.device.get_image_memory_requirements(image);
            let memory = self
                .device
                .allocate_memory(
                    &vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(
                        self.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL),
                    ),
                    None,
                )
                .unwrap();
            self.device.bind_image_memory(image, memory, 0).unwrap();
            let range = vk::ImageSubresourceRange::default()
                .aspect_mask(vk::ImageAspectFlags::COLOR)
                .level_count(1)
                .layer_count(1);
            self.one_shot(|cb| {
                let to_dst = vk::ImageMemoryBarrier::default()
                    .image(image)
                    .subresource_range(range)
                    .old_layout(vk::ImageLayout::UNDEFINED)
                    .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                    .dst_access_mask(vk::AccessFlags::TRANSFER_WRITE);
                self.device.cmd_pipeline_barrier(
                    cb,
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                    vk::PipelineStageFlags::TRANSFER,
                    vk::DependencyFlags::empty(),
                    &[],
                    &[],
                    &[to_dst],
                );
                let region = vk::BufferImageCopy::default()
                    .image_subresource(
                        vk::ImageSubresourceLayers::default().aspect_mask(vk::ImageAspectFlags::COLOR).layer_count(1),
                    )
                    .image_extent(extent);
                self.device.cmd_copy_buffer_to_image(
                    cb,
                    staging.buffer,
                    image,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &[region],
                );
                let to_read = vk::ImageMemoryBarrier::default()
                    .image(image)
                    .subresource_range(range)
                    .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                    .new_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
                    .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                    .dst_access_mask(vk::AccessFlags::SHADER_READ);
                self.device.cmd_pipeline_barrier(
                    cb,
                    vk::PipelineStageFlags::TRANSFER,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    vk::DependencyFlags::empty(),
                    &[],
                    &[],
                    &[to_read],
                );
            });
            let view = self
                .device
                .create_image_view(
                    &vk::ImageViewCreateInfo::default()
                        .image(image)
                        .view_type(vk::ImageViewType::TYPE_2D)
                        .format(vk::Format::R8G8B8A8_UNORM)
                        .subresource_range(range),
                    None,
                )
                .unwrap();
            self.free(staging);
            (image, memory, view)
        }
    }

    fn free(&self, b: Buf) {
        unsafe {
            self.device.destroy_buffer(b.buffer, None);
            self.device.free_memory(b.memory, None);
        }
    }
}

/// The raycast pipeline with the scene bound in set 0.
struct Raycaster<'g> {
    gpu: &'g Gpu,
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layouts: [vk::DescriptorSetLayout; 2],
    pool: vk::DescriptorPool,
    scene_set: vk::DescriptorSet,
    _scene_bufs: Vec<Buf>,
}

fn storage_layout(gpu: &Gpu, n: u32) -> vk::DescriptorSetLayout {
    let bindings: Vec<_> = (0..n)
        .map(|i| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(i)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
        })
        .collect();
    unsafe {
        gpu.device
            .create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
            .unwrap()
    }
}

fn write_set(gpu: &Gpu, set: vk::DescriptorSet, bufs: &[&Buf]) {
    let infos: Vec<[vk::DescriptorBufferInfo; 1]> =
        bufs.iter().map(|b| [vk::DescriptorBufferInfo::default().buffer(b.buffer).range(vk::WHOLE_SIZE)]).collect();
    let writes: Vec<_> = infos
        .iter()
        .enumerate()
        .map(|(i, info)| {
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(i as u32)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(info)
        })
        .collect();
    unsafe { gpu.device.update_descriptor_sets(&writes, &[]) };
}

impl<'g> Raycaster<'g> {
    fn new(gpu: &'g Gpu, gs: &GpuScene) -> Self {
        let spv = match std::env::var("GPUCHECK_SPV") {
            Ok(p) => std::fs::read(p).unwrap(),
            Err(_) => if textured() { RAYCAST_TEX_SPV } else { RAYCAST_SPV }.to_vec(),
        };
        Self::with_kernel(gpu, gs, &spv, 2)
    }

    fn with_kernel(gpu: &'g Gpu, gs: &GpuScene, spv: &[u8], set1_bindings: u32) -> Self {
        let scene_bufs = vec![
            gpu.upload(gs.node_bytes()),
            gpu.upload(gs.triangle_bytes()),
            gpu.upload(gs.attribute_bytes()),
            gpu.upload(gs.material_bytes()),
            gpu.upload(gs.emissive_bytes()),
            gpu.upload(gs.light_bytes()),
        ];
        unsafe {
            let textured = textured();
            let texture_count = gs.textures.len().max(1) as u32;
            let scene_layout = if textured {
                let mut bindings: Vec<_> = (0..6)
                    .map(|i| {
                        vk::DescriptorSetLayoutBinding::default()
                            .binding(i)
                            .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                            .descriptor_count(1)
                            .stage_flags(vk::ShaderStageFlags::COMPUTE)
                    })
                    .collect();
                bindings.push(
                    vk::DescriptorSetLayoutBinding::default()
                        .binding(6)
                        .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                        .descriptor_count(texture_count)
                        .stage_flags(vk::ShaderStageFlags::COMPUTE),
                );
                gpu.device
                    .create_descriptor_set_layout(
                        &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                        None,
                    )
                    .unwrap()
            } else {
                storage_layout(gpu, 6)
            };
            let set_layouts = [scene_layout, storage_layout(gpu, set1_bindings)];
            let pc = [vk::PushConstantRange::default().stage_flags(vk::ShaderStageFlags::COMPUTE).size(8)];
            let layout = gpu
                .device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&pc),
                    None,
                )
                .unwrap();
            let code = ash::util::read_spv(&mut std::io::Cursor::new(spv)).unwrap();
            let module =
                gpu.device.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None).unwrap();
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(c"main");
            let pipeline = gpu
                .device
                .create_compute_pipelines(
                    vk::PipelineCache::null(),
                    &[vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout)],
                    None,
                )
                .unwrap()[0];
            gpu.device.destroy_shader_module(module, None);
            let sizes = [
                vk::DescriptorPoolSize::default().ty(vk::DescriptorType::STORAGE_BUFFER).descriptor_count(64),
                vk::DescriptorPoolSize::default()
                    .ty(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                    .descriptor_count(texture_count),
            ];
            let pool = gpu
                .device
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(16)
                        .pool_sizes(&sizes)
                        .flags(vk::DescriptorPoolCreateFlags::FREE_DESCRIPTOR_SET),
                    None,
                )
                .unwrap();
            let scene_set = gpu
                .device
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&set_layouts[..1]),
                )
                .unwrap()[0];
            write_set(gpu, scene_set, &scene_bufs.iter().collect::<Vec<_>>());
            if textured {
                // Textures live as long as the process: this harness never frees them.
                let sampler = gpu
                    .device
                    .create_sampler(
                        &vk::SamplerCreateInfo::default()
                            .mag_filter(vk::Filter::LINEAR)
                            .min_filter(vk::Filter::LINEAR)
                            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
                            .address_mode_u(vk::SamplerAddressMode::REPEAT)
                            .address_mode_v(vk::SamplerAddressMode::REPEAT)
                            .address_mode_w(vk::SamplerAddressMode::REPEAT)
                            .max_lod(0.0),
                        None,
                    )
                    .unwrap();
                let white = parallax_scene::Texture { width: 1, height: 1, rgba8: vec![255; 4] };
                let textures: Vec<&parallax_scene::Texture> =
                    if gs.textures.is_empty() { vec![&white] } else { gs.textures.iter().collect() };
                let infos: Vec<vk::DescriptorImageInfo> = textures
                    .iter()
                    .map(|t| {
                        let (_, _, view) = gpu.upload_texture(t);
                        vk::DescriptorImageInfo::default()
                            .sampler(sampler)
                            .image_view(view)
                            .image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
                    })
                    .collect();
                let write = vk::WriteDescriptorSet::default()
                    .dst_set(scene_set)
                    .dst_binding(6)
                    .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                    .image_info(&infos);
                gpu.device.update_descriptor_sets(&[write], &[]);
            }
            Raycaster { gpu, pipeline, layout, set_layouts, pool, scene_set, _scene_bufs: scene_bufs }
        }
    }

    /// Casts `rays`; returns the hits and the best and median GPU time (ns) over `repeats`.
    fn cast(&self, rays: &[RayIn], any_hit: bool, repeats: u32) -> (Vec<HitOut>, f64, f64) {
        let gpu = self.gpu;
        let ray_buf = gpu.upload(bytemuck::cast_slice(rays));
        let hit_buf = gpu.buffer(
            (rays.len() * 16) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
            false,
        );
        let mut times = Vec::new();
        unsafe {
            let set = gpu
                .device
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default()
                        .descriptor_pool(self.pool)
                        .set_layouts(&self.set_layouts[1..]),
                )
                .unwrap()[0];
            write_set(gpu, set, &[&ray_buf, &hit_buf]);
            let qp = gpu
                .device
                .create_query_pool(
                    &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2),
                    None,
                )
                .unwrap();
            for _ in 0..repeats {
                gpu.device.reset_query_pool(qp, 0, 2);
                gpu.one_shot(|cb| {
                    let d = &gpu.device;
                    d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, self.pipeline);
                    d.cmd_bind_descriptor_sets(
                        cb,
                        vk::PipelineBindPoint::COMPUTE,
                        self.layout,
                        0,
                        &[self.scene_set, set],
                        &[],
                    );
                    let pc = [rays.len() as u32, any_hit as u32];
                    d.cmd_push_constants(cb, self.layout, vk::ShaderStageFlags::COMPUTE, 0, bytemuck::cast_slice(&pc));
                    d.cmd_write_timestamp(cb, vk::PipelineStageFlags::TOP_OF_PIPE, qp, 0);
                    let group: u32 = std::env::var("GPUCHECK_GROUP").map_or(64, |g| g.parse().unwrap());
                    d.cmd_dispatch(cb, (rays.len() as u32).div_ceil(group), 1, 1);
                    d.cmd_write_timestamp(cb, vk::PipelineStageFlags::BOTTOM_OF_PIPE, qp, 1);
                });
                let mut ts = [0u64; 2];
                gpu.device
                    .get_query_pool_results(qp, 0, &mut ts, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT)
                    .unwrap();
                times.push((ts[1] - ts[0]) as f64 * gpu.timestamp_period as f64);
            }
            gpu.device.destroy_query_pool(qp, None);
            gpu.device.free_descriptor_sets(self.pool, &[set]).unwrap();
        }
        let hits: Vec<HitOut> = bytemuck::cast_slice(&gpu.download(&hit_buf, rays.len() * 16)).to_vec();
        gpu.free(ray_buf);
        gpu.free(hit_buf);
        times.sort_by(f64::total_cmp);
        (hits, times[0], times[times.len() / 2])
    }
}

impl Raycaster<'_> {
    /// Runs pt_trace.glsl over `pixels` of `view`; returns the pixels and the GPU time in ns.
    fn path_trace(
        &self,
        scene: &Scene,
        view: &parallax_scene::View,
        settings: &parallax_scene::TraceSettings,
        pixels: &parallax_scene::PixelSet,
    ) -> (Vec<parallax_scene::gpu::GpuPixel>, f64) {
        let gpu = self.gpu;
        let params = parallax_scene::gpu::GpuTraceParams::new(scene, view, settings, pixels);
        let coords = pixels.coordinates(view);
        let list: Vec<u32> = match pixels {
            parallax_scene::PixelSet::List(l) => l.iter().map(|&(x, y)| x | (y << 16)).collect(),
            _ => vec![0],
        };
        let params_buf = gpu.upload(bytemuck::bytes_of(&params));
        let list_buf = gpu.upload(bytemuck::cast_slice(&list));
        let out_buf = gpu.buffer(
            (coords.len() * 64) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
            false,
        );
        let mut ns = 0.0;
        unsafe {
            let set = gpu
                .device
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default()
                        .descriptor_pool(self.pool)
                        .set_layouts(&self.set_layouts[1..]),
                )
                .unwrap()[0];
            write_set(gpu, set, &[&params_buf, &list_buf, &out_buf]);
            let qp = gpu
                .device
                .create_query_pool(
                    &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2),
                    None,
                )
                .unwrap();
            gpu.device.reset_query_pool(qp, 0, 2);
            gpu.one_shot(|cb| {
                let d = &gpu.device;
                d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, self.pipeline);
                d.cmd_bind_descriptor_sets(
                    cb,
                    vk::PipelineBindPoint::COMPUTE,
                    self.layout,
                    0,
                    &[self.scene_set, set],
                    &[],
                );
                d.cmd_write_timestamp(cb, vk::PipelineStageFlags::TOP_OF_PIPE, qp, 0);
                d.cmd_dispatch(cb, (coords.len() as u32).div_ceil(64), 1, 1);
                d.cmd_write_timestamp(cb, vk::PipelineStageFlags::BOTTOM_OF_PIPE, qp, 1);
            });
            let mut ts = [0u64; 2];
            gpu.device
                .get_query_pool_results(qp, 0, &mut ts, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT)
                .unwrap();
            ns += (ts[1] - ts[0]) as f64 * gpu.timestamp_period as f64;
            gpu.device.destroy_query_pool(qp, None);
            gpu.device.free_descriptor_sets(self.pool, &[set]).unwrap();
        }
        let out = bytemuck::cast_slice(&gpu.download(&out_buf, coords.len() * 64)).to_vec();
        gpu.free(params_buf);
        gpu.free(list_buf);
        gpu.free(out_buf);
        (out, ns)
    }
}

/// GPU path tracer against the CPU reference on the same view, settings and random numbers.
///
/// Per channel: the image means must agree within 1 % (exit 1 otherwise). Per pixel: with F
/// frames (independent random numbers) on each side, d = mean_gpu - mean_cpu is compared with
/// its standard error sqrt((s2_cpu + s2_gpu) / F) from the two sample variances; the fraction
/// of pixel channels with |d| > 3 standard errors is printed next to what a Student t with
/// F - 1 degrees of freedom allows for independent estimates. Because both sides use the same
/// random numbers, most pixels agree exactly and the fraction is far below that bound.
fn compare_pt(gpu: &Gpu, scene: &Scene, w: u32, h: u32, spp: u32, frames: u32) {
    use parallax_scene::{CpuTracer, PixelSet, TraceSettings, View};
    let bvh = SceneBvh::build(scene);
    let gs = GpuScene::new(scene, &bvh);
    let pt = Raycaster::with_kernel(gpu, &gs, if textured() { PT_TRACE_TEX_SPV } else { PT_TRACE_SPV }, 3);
    let cpu = CpuTracer::new(scene, &bvh);
    let view = View { camera: scene.default_camera(), width: w, height: h, index: 0 };
    let n = (w * h) as usize;
    let zero = vec![glam::DVec3::ZERO; n];
    let (mut c_sum, mut c_sq, mut g_sum, mut g_sq) = (zero.clone(), zero.clone(), zero.clone(), zero);
    let (mut same, mut first_hit_differs) = (0usize, 0usize);
    let (mut gpu_ns, mut cpu_secs) = (0.0, 0.0);
    for frame in 0..frames {
        let settings = TraceSettings { spp, frame, ..Default::default() };
        let t = Instant::now();
        let (c, _) = cpu.trace(&view, &settings, &PixelSet::All, &|_| {}).unwrap();
        cpu_secs += t.elapsed().as_secs_f64();
        let (g, ns) = pt.path_trace(scene, &view, &settings, &PixelSet::All);
        gpu_ns += ns;
        for i in 0..n {
            let gr = Vec3::from_slice(&g[i].radiance[..3]);
            let cr = c[i].radiance;
            c_sum[i] += cr.as_dvec3();
            c_sq[i] += (cr * cr).as_dvec3();
            g_sum[i] += gr.as_dvec3();
            g_sq[i] += (gr * gr).as_dvec3();
            if (gr - cr).abs().max_element() <= 1e-3 * cr.max_element().max(1e-3) {
                same += 1;
            }
            if (g[i].radiance[3] > 0.5) != c[i].hit {
                first_hit_differs += 1;
            }
        }
    }
    let f = frames as f64;
    let (mut mean_c, mut mean_g) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    let mut beyond = 0usize;
    for i in 0..n {
        let (mc, mg) = (c_sum[i] / f, g_sum[i] / f);
        mean_c += mc;
        mean_g += mg;
        let var_c = (c_sq[i] / f - mc * mc).max(glam::DVec3::ZERO) * (f / (f - 1.0));
        let var_g = (g_sq[i] / f - mg * mg).max(glam::DVec3::ZERO) * (f / (f - 1.0));
        let se = ((var_c + var_g) / f).powf(0.5);
        let d = (mg - mc).abs();
        for k in 0..3 {
            if d[k] > 1e-6 && d[k] > 3.0 * se[k] {
                beyond += 1;
            }
        }
    }
    mean_c /= n as f64;
    mean_g /= n as f64;
    let rel = ((mean_g - mean_c) / mean_c.max(glam::DVec3::splat(1e-9))).abs();
    // Two-sided P(|t| > 3) for F - 1 degrees of freedom (F = 4, 8, 16, large).
    let t_bound = match frames {
        0..=4 => 0.058,
        5..=8 => 0.020,
        9..=16 => 0.009,
        _ => 0.0027,
    };
    println!(
        "{w}x{h} x {spp} spp x {frames} frames on {}: CPU mean {:.5?}, GPU mean {:.5?}, max rel diff {:.2e}; \
         {:.2} % of pixel estimates equal to 1e-3; first hit differs on {first_hit_differs} pixel-frames; \
         {:.3} % of pixel channels beyond 3 std. errors (independent estimates would allow {:.1} %); \
         GPU {:.1} ms, CPU {:.2} s",
        gpu.name,
        mean_c,
        mean_g,
        rel.max_element(),
        100.0 * same as f64 / (n as f64 * f),
        100.0 * beyond as f64 / (3.0 * n as f64),
        100.0 * t_bound,
        gpu_ns / 1e6,
        cpu_secs
    );
    if rel.max_element() > 0.01 {
        std::process::exit(1);
    }
}

fn xorshift(s: &mut u64) -> f32 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    (*s >> 40) as f32 / (1u64 << 24) as f32
}

fn random_rays(scene: &Scene, n: usize) -> Vec<RayIn> {
    let b = scene.bounds();
    let lo = b.min - 0.1 * (b.max - b.min);
    let hi = b.max + 0.1 * (b.max - b.min);
    (0..n)
        .map(|i| {
            let mut s = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
            for _ in 0..4 {
                xorshift(&mut s);
            }
            let o = lo + (hi - lo) * Vec3::new(xorshift(&mut s), xorshift(&mut s), xorshift(&mut s));
            let z = 2.0 * xorshift(&mut s) - 1.0;
            let phi = std::f32::consts::TAU * xorshift(&mut s);
            let r = (1.0 - z * z).max(0.0).sqrt();
            let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            RayIn { origin_tmin: [o.x, o.y, o.z, 1e-4], dir_tmax: [d.x, d.y, d.z, f32::INFINITY] }
        })
        .collect()
}

fn check(gpu: &Gpu, scene: &Scene, n: usize) {
    let t = Instant::now();
    let bvh = SceneBvh::build(scene);
    println!("CWBVH: {} nodes, build {:.2?}", bvh.node_count(), t.elapsed());
    let gs = GpuScene::new(scene, &bvh);
    let rc = Raycaster::new(gpu, &gs);
    let rays = random_rays(scene, n);
    let (gpu_hits, _, _) = rc.cast(&rays, false, 1);
    let (gpu_any, _, _) = rc.cast(&rays, true, 1);
    let results: Vec<(u32, u32, u32, f32)> = rays
        .par_iter()
        .zip(&gpu_hits)
        .zip(&gpu_any)
        .map(|((r, g), a)| {
            let o = Vec3::from_slice(&r.origin_tmin[..3]);
            let d = Vec3::from_slice(&r.dir_tmax[..3]);
            let cpu = bvh.closest_hit(scene, o, d, 1e-4, f32::INFINITY);
            let any_ok = (a.prim != u32::MAX) == cpu.is_some();
            match cpu {
                None => (u32::from(g.prim != u32::MAX), 0, u32::from(!any_ok), 0.0),
                Some(c) => {
                    let rel = (g.t - c.t).abs() / c.t.max(1e-6);
                    let wrong = g.prim == u32::MAX || rel > 1e-4;
                    let other = u32::from(!wrong && g.prim != c.bvh_primitive);
                    (u32::from(wrong), other, u32::from(!any_ok), if g.prim == u32::MAX { 0.0 } else { rel })
                }
            }
        })
        .collect();
    let wrong: u32 = results.iter().map(|r| r.0).sum();
    let other: u32 = results.iter().map(|r| r.1).sum();
    let any_wrong: u32 = results.iter().map(|r| r.2).sum();
    let max_rel = results.iter().map(|r| r.3).fold(0.0f32, f32::max);
    let hits = gpu_hits.iter().filter(|h| h.prim != u32::MAX).count();
    println!(
        "{n} rays on {} ({} hits): {wrong} disagree (miss/hit or t beyond 1e-4 rel), {other} same t on another triangle, max rel dt {max_rel:.2e}; any-hit disagreements {any_wrong}",
        gpu.name, hits
    );
    if wrong > 0 || any_wrong > 0 {
        std::process::exit(1);
    }
}

fn bench(gpu: &Gpu, scene: &Scene, camera: Camera, w: u32, h: u32) {
    let t = Instant::now();
    let bvh = SceneBvh::build(scene);
    println!("CWBVH: {} nodes, build {:.2?} (obvhs core {:.2?})", bvh.node_count(), t.elapsed(), bvh.core_build_time);
    let gs = GpuScene::new(scene, &bvh);
    let rc = Raycaster::new(gpu, &gs);
    let aspect = w as f32 / h as f32;
    let primary: Vec<RayIn> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let ndc = Vec2::new((x as f32 + 0.5) / w as f32 * 2.0 - 1.0, 1.0 - (y as f32 + 0.5) / h as f32 * 2.0);
            let d = camera.ray_direction(ndc, aspect);
            RayIn { origin_tmin: camera.eye.extend(0.0).into(), dir_tmax: d.extend(f32::INFINITY).into() }
        })
        .collect();
    let repeats = 9;
    let (hits, best, median) = rc.cast(&primary, false, repeats);
    let n = primary.len() as f64;
    println!(
        "primary: {} rays, {:.3} ms median ({:.3} best) -> {:.2e} rays/s",
        primary.len(),
        median / 1e6,
        best / 1e6,
        n / (median * 1e-9)
    );
    // Diffuse bounce: from each primary hit, a cosine-distributed direction about the face normal.
    let bounce: Vec<RayIn> = primary
        .par_iter()
        .zip(&hits)
        .enumerate()
        .filter(|(_, (_, h))| h.prim != u32::MAX)
        .map(|(i, (r, h))| {
            let tri = &gs.triangles[h.prim as usize];
            let (a, b, c) = (Vec3::from(tri.v0), Vec3::from(tri.v1), Vec3::from(tri.v2));
            let d = Vec3::from_slice(&r.dir_tmax[..3]);
            let mut n = (b - a).cross(c - a).normalize_or_zero();
            if n.dot(d) > 0.0 {
                n = -n;
            }
            let p = Vec3::from_slice(&r.origin_tmin[..3]) + d * h.t;
            let mut s = (i as u64).wrapping_mul(0xd129_4f3b_e5a1_0c77) | 1;
            xorshift(&mut s);
            let (u0, u1) = (xorshift(&mut s), xorshift(&mut s));
            let dir = parallax_scene::bsdf::sample_cosine_hemisphere(n, u0, u1);
            let o = parallax_scene::pt::offset_ray_origin(p, n);
            RayIn { origin_tmin: o.extend(0.0).into(), dir_tmax: dir.extend(f32::INFINITY).into() }
        })
        .collect();
    let (_, best, median) = rc.cast(&bounce, false, repeats);
    println!(
        "diffuse bounce: {} rays, {:.3} ms median ({:.3} best) -> {:.2e} rays/s",
        bounce.len(),
        median / 1e6,
        best / 1e6,
        bounce.len() as f64 / (median * 1e-9)
    );
    let (_, best, median) = rc.cast(&bounce, true, repeats);
    println!(
        "diffuse bounce, any hit: {} rays, {:.3} ms median ({:.3} best) -> {:.2e} rays/s",
        bounce.len(),
        median / 1e6,
        best / 1e6,
        bounce.len() as f64 / (median * 1e-9)
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut scene = load_scene(&args[2]).expect("scene");
    // Untextured kernels (the default): make the CPU side match (opaque, untextured).
    for m in scene.materials.iter_mut().filter(|_| !textured()) {
        m.alpha_mode = AlphaMode::Opaque;
        m.base_color_texture = None;
        m.metallic_roughness_texture = None;
        m.emissive_texture = None;
    }
    // A scene with no light at all (Sponza) gets a sky and a sun, as `parallax trace` would.
    let has_emitter = scene.materials.iter().any(|m| m.is_emissive());
    if scene.sky.is_none() && scene.sun.is_none() && scene.lights.is_empty() && !has_emitter {
        scene.sky = Some(parallax_scene::Sky::Constant(Vec3::new(0.5, 0.6, 0.8)));
        scene.sun = Some(parallax_scene::Sun {
            to_sun: Vec3::new(0.3, 1.0, 0.2).normalize(),
            irradiance: Vec3::splat(4.0),
            angular_radius: 0.5f32.to_radians(),
        });
    }
    if let Ok(c) = std::env::var("GPUCHECK_CAMERA") {
        let v: Vec<f32> = c.split(',').map(|x| x.parse().unwrap()).collect();
        let cam = Camera::look_at(
            Vec3::new(v[0], v[1], v[2]),
            Vec3::new(v[3], v[4], v[5]),
            Vec3::new(v[6], v[7], v[8]),
            v[9].to_radians(),
        );
        scene.cameras.insert(0, cam);
    }
    let gpu = Gpu::new();
    println!("device: {}", gpu.name);
    match args[1].as_str() {
        "check" => check(&gpu, &scene, args[3].parse().unwrap()),
        "pt" => compare_pt(
            &gpu,
            &scene,
            args[3].parse().unwrap(),
            args[4].parse().unwrap(),
            args[5].parse().unwrap(),
            args[6].parse().unwrap(),
        ),
        "bench" => {
            let camera = match args.get(5) {
                Some(c) => {
                    let v: Vec<f32> = c.split(',').map(|x| x.parse().unwrap()).collect();
                    Camera::look_at(
                        Vec3::new(v[0], v[1], v[2]),
                        Vec3::new(v[3], v[4], v[5]),
                        Vec3::new(v[6], v[7], v[8]),
                        v[9].to_radians(),
                    )
                }
                None => scene.default_camera(),
            };
            bench(&gpu, &scene, camera, args[3].parse().unwrap(), args[4].parse().unwrap())
        }
        other => panic!("unknown mode {other}"),
    }
    unsafe {
        gpu.device.device_wait_idle().unwrap();
    }
    let _ = &gpu.instance;
}
