//! GPU memory: storage images and buffers through gpu-allocator, and the one thing it cannot
//! do: a host allocation imported into several devices (VK_EXT_external_memory_host), the
//! staging area of cross-device copies.

use std::alloc::Layout;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use parallax_graph::Format;

use crate::device::Device;
use crate::error::{BackendError, Result, VkContext};

/// The Vulkan format of a texel format: storage-image formats every Vulkan device has, and
/// `D32_SFLOAT`, the depth format every device can render to and sample.
pub fn vk_format(format: Format) -> Result<vk::Format> {
    Ok(match format {
        Format::Rgba32f => vk::Format::R32G32B32A32_SFLOAT,
        Format::Rgba16f => vk::Format::R16G16B16A16_SFLOAT,
        Format::Rg32f => vk::Format::R32G32_SFLOAT,
        Format::R32f => vk::Format::R32_SFLOAT,
        Format::Rgba8 => vk::Format::R8G8B8A8_UNORM,
        Format::R32u => vk::Format::R32_UINT,
        Format::Depth32f => vk::Format::D32_SFLOAT,
    })
}

fn allocation_error(what: &str) -> impl FnOnce(gpu_allocator::AllocationError) -> BackendError {
    let what = what.to_string();
    move |source| BackendError::Allocation { what, source }
}

/// A 2D image in device-local memory, kept in `GENERAL` layout for its whole life: colour
/// formats are storage images (storage writes, storage reads and transfers are all valid in
/// `GENERAL`, so no pass has to track layouts); [`Format::Depth32f`] is a depth attachment that
/// kernels sample and transfers copy, which `GENERAL` allows as well (with dynamic rendering a
/// depth attachment may be in `GENERAL`).
pub struct Image {
    device: Arc<Device>,
    pub(crate) raw: vk::Image,
    pub(crate) view: vk::ImageView,
    allocation: Option<Allocation>,
    pub format: Format,
    pub width: u32,
    pub height: u32,
}

impl Image {
    pub fn new(device: &Arc<Device>, name: &str, width: u32, height: u32, format: Format) -> Result<Self> {
        let vk_fmt = vk_format(format)?;
        let features = unsafe {
            device.instance.raw.get_physical_device_format_properties(device.physical, vk_fmt).optimal_tiling_features
        };
        let transfer = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
        if format.is_depth() {
            // Depth formats cannot be storage images: kernels read them through the sampled
            // depth array of the descriptor set (shader_pipelines.rs).
            let needed = vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT | vk::FormatFeatureFlags::SAMPLED_IMAGE;
            if !features.contains(needed) {
                return Err(BackendError::MissingCapability {
                    device: device.info.index,
                    name: device.info.name.clone(),
                    what: format!("D32_SFLOAT as a sampled depth attachment (image `{name}`)"),
                });
            }
            let usage = vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT | vk::ImageUsageFlags::SAMPLED | transfer;
            return Self::create(device, name, width, height, vk_fmt, usage, format);
        }
        let mut usage = vk::ImageUsageFlags::STORAGE | transfer;
        // Raster passes render into the same images where the format allows it.
        if features.contains(vk::FormatFeatureFlags::COLOR_ATTACHMENT) {
            usage |= vk::ImageUsageFlags::COLOR_ATTACHMENT;
        }
        Self::create(device, name, width, height, vk_fmt, usage, format)
    }

    /// An RGBA8 image that shaders sample, filled by a transfer (the texture array).
    pub(crate) fn new_sampled_rgba8(device: &Arc<Device>, name: &str, width: u32, height: u32) -> Result<Self> {
        Self::create(
            device,
            name,
            width,
            height,
            vk::Format::R8G8B8A8_UNORM,
            vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
            Format::Rgba8,
        )
    }

    fn create(
        device: &Arc<Device>,
        name: &str,
        width: u32,
        height: u32,
        vk_fmt: vk::Format,
        usage: vk::ImageUsageFlags,
        format: Format,
    ) -> Result<Self> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(vk_fmt)
            .extent(vk::Extent3D { width, height, depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // Copies may run on a transfer-only queue: share between its family and the main one
        // instead of transferring ownership at every copy.
        let families = device.families();
        let info = if families.len() > 1 {
            info.sharing_mode(vk::SharingMode::CONCURRENT).queue_family_indices(&families)
        } else {
            info
        };
        let raw = unsafe { device.raw.create_image(&info, None) }.vk("vkCreateImage")?;
        let requirements = unsafe { device.raw.get_image_memory_requirements(raw) };
        let allocation = device
            .with_allocator(|a| {
                a.allocate(&AllocationCreateDesc {
                    name,
                    requirements,
                    location: MemoryLocation::GpuOnly,
                    linear: false,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                })
            })
            .map_err(allocation_error(name));
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                unsafe { device.raw.destroy_image(raw, None) };
                return Err(e);
            }
        };
        let mut image = Self {
            device: device.clone(),
            raw,
            view: vk::ImageView::null(),
            allocation: Some(allocation),
            format,
            width,
            height,
        };
        let allocation = image.allocation.as_ref().expect("just set");
        unsafe { device.raw.bind_image_memory(raw, allocation.memory(), allocation.offset()) }
            .vk("vkBindImageMemory")?;
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(vk_fmt)
            .subresource_range(image.range());
        image.view = unsafe { device.raw.create_image_view(&view_info, None) }.vk("vkCreateImageView")?;
        Ok(image)
    }

    /// Bytes of one row of texels.
    pub fn row_bytes(&self) -> u64 {
        u64::from(self.width) * self.format.bytes_per_texel()
    }

    /// The aspect transfers, views and barriers of this image name.
    pub(crate) fn aspect(&self) -> vk::ImageAspectFlags {
        if self.format.is_depth() { vk::ImageAspectFlags::DEPTH } else { vk::ImageAspectFlags::COLOR }
    }

    /// The image's only layer, for copies (the depth aspect of a depth image).
    pub(crate) fn layers(&self) -> vk::ImageSubresourceLayers {
        vk::ImageSubresourceLayers { aspect_mask: self.aspect(), ..color_layers() }
    }

    /// The image's whole subresource, for barriers and views.
    pub(crate) fn range(&self) -> vk::ImageSubresourceRange {
        vk::ImageSubresourceRange { aspect_mask: self.aspect(), ..color_range() }
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        unsafe {
            if self.view != vk::ImageView::null() {
                self.device.raw.destroy_image_view(self.view, None);
            }
            self.device.raw.destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            // A failed free only leaks until the allocator is dropped with the device.
            let _ = self.device.with_allocator(|al| al.free(a));
        }
    }
}

/// The colour layer of a single-mip, single-layer image, for copies.
pub(crate) fn color_layers() -> vk::ImageSubresourceLayers {
    vk::ImageSubresourceLayers {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        mip_level: 0,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// The whole colour subresource of a single-mip, single-layer image.
pub(crate) fn color_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// A buffer from gpu-allocator; host-visible locations are persistently mapped.
pub struct Buffer {
    device: Arc<Device>,
    pub(crate) raw: vk::Buffer,
    allocation: Option<Allocation>,
    pub size: u64,
}

impl Buffer {
    pub fn new(
        device: &Arc<Device>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self> {
        let info =
            vk::BufferCreateInfo::default().size(size.max(4)).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        let raw = unsafe { device.raw.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        let requirements = unsafe { device.raw.get_buffer_memory_requirements(raw) };
        let allocation = device
            .with_allocator(|a| {
                a.allocate(&AllocationCreateDesc {
                    name,
                    requirements,
                    location,
                    linear: true,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                })
            })
            .map_err(allocation_error(name));
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                unsafe { device.raw.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        let buffer = Self { device: device.clone(), raw, allocation: Some(allocation), size };
        let allocation = buffer.allocation.as_ref().expect("just set");
        unsafe { device.raw.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) }
            .vk("vkBindBufferMemory")?;
        Ok(buffer)
    }

    /// A host-visible buffer holding a copy of `bytes`, the source of an upload.
    pub fn staging(device: &Arc<Device>, name: &str, bytes: &[u8]) -> Result<Self> {
        let mut staging =
            Self::new(device, name, bytes.len() as u64, vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu)?;
        staging.mapped_mut().expect("CpuToGpu buffers are mapped")[..bytes.len()].copy_from_slice(bytes);
        Ok(staging)
    }

    /// The mapped bytes of a host-visible buffer (`None` for device-local ones).
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation.as_ref().and_then(|a| a.mapped_slice()).map(|s| &s[..self.size as usize])
    }

    /// Mutable mapped bytes of a host-visible buffer.
    pub fn mapped_mut(&mut self) -> Option<&mut [u8]> {
        let size = self.size as usize;
        self.allocation.as_mut().and_then(|a| a.mapped_slice_mut()).map(|s| &mut s[..size])
    }

    pub fn raw(&self) -> vk::Buffer {
        self.raw
    }

    /// GPU address for shaders (`GL_EXT_buffer_reference`); the buffer needs
    /// `SHADER_DEVICE_ADDRESS` usage.
    pub fn device_address(&self) -> u64 {
        let info = vk::BufferDeviceAddressInfo::default().buffer(self.raw);
        unsafe { self.device.raw.get_buffer_device_address(&info) }
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        unsafe { self.device.raw.destroy_buffer(self.raw, None) };
        if let Some(a) = self.allocation.take() {
            let _ = self.device.with_allocator(|al| al.free(a));
        }
    }
}

/// One host allocation seen by several devices as a `VkBuffer` each. The producer of a
/// cross-device copy writes it with a GPU copy and the consumer reads it with a GPU copy; the
/// CPU never touches the bytes.
pub struct SharedHostBuffer {
    ptr: *mut u8,
    layout: Layout,
    imports: Vec<HostImport>,
    pub size: u64,
}

struct HostImport {
    device: Arc<Device>,
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    /// The memory type is `HOST_COHERENT`: the device's copies and the host's own reads and
    /// writes of the allocation see each other without flushes or invalidations.
    coherent: bool,
}

// The raw pointer is only handed to Vulkan; the struct owns the allocation outright.
unsafe impl Send for SharedHostBuffer {}
unsafe impl Sync for SharedHostBuffer {}

impl SharedHostBuffer {
    /// Allocates `size` bytes of zeroed host memory (rounded up to the import alignment) and
    /// imports it into every device of `devices`.
    pub fn new(devices: &[&Arc<Device>], size: u64) -> Result<Self> {
        let align = devices.iter().map(|d| d.min_host_pointer_alignment).max().unwrap_or(4096).max(64);
        let rounded = size.max(1).div_ceil(align) * align;
        let layout = Layout::from_size_align(rounded as usize, align as usize).map_err(|e| {
            BackendError::HostImport { device: devices.first().map_or(0, |d| d.info.index), detail: e.to_string() }
        })?;
        // Zeroed so that a copy-in that ran too early (a missing wait) reads zeros, never
        // stale bytes that could pass for a right answer.
        let ptr = unsafe { std::alloc::alloc_zeroed(layout) };
        if ptr.is_null() {
            std::alloc::handle_alloc_error(layout);
        }
        let mut shared = Self { ptr, layout, imports: Vec::with_capacity(devices.len()), size: rounded };
        for device in devices {
            let import = shared.import_into(device)?;
            shared.imports.push(import);
        }
        Ok(shared)
    }

    fn import_into(&self, device: &Arc<Device>) -> Result<HostImport> {
        let fail = |detail: String| BackendError::HostImport { device: device.info.index, detail };
        let emh = device
            .external_memory_host
            .as_ref()
            .ok_or_else(|| fail("VK_EXT_external_memory_host is not enabled".into()))?;
        let handle_type = vk::ExternalMemoryHandleTypeFlags::HOST_ALLOCATION_EXT;
        let mut host_props = vk::MemoryHostPointerPropertiesEXT::default();
        unsafe {
            (emh.fp().get_memory_host_pointer_properties_ext)(
                device.raw.handle(),
                handle_type,
                self.ptr.cast(),
                &mut host_props,
            )
        }
        .result()
        .vk("vkGetMemoryHostPointerPropertiesEXT")?;

        let mut external = vk::ExternalMemoryBufferCreateInfo::default().handle_types(handle_type);
        let info = vk::BufferCreateInfo::default()
            .size(self.size)
            .usage(vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST)
            .push_next(&mut external);
        let families = device.families();
        let info = if families.len() > 1 {
            info.sharing_mode(vk::SharingMode::CONCURRENT).queue_family_indices(&families)
        } else {
            info.sharing_mode(vk::SharingMode::EXCLUSIVE)
        };
        let buffer = unsafe { device.raw.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        let requirements = unsafe { device.raw.get_buffer_memory_requirements(buffer) };
        let memory_props = unsafe { device.instance.raw.get_physical_device_memory_properties(device.physical) };
        let candidates = host_props.memory_type_bits & requirements.memory_type_bits;
        // Prefer host-cached memory if offered: the bytes are read by the DMA engine anyway,
        // but some drivers only list one type.
        let memory_type = (0..memory_props.memory_type_count).filter(|t| candidates & (1 << t) != 0).min_by_key(|&t| {
            let flags = memory_props.memory_types[t as usize].property_flags;
            u32::from(!flags.contains(vk::MemoryPropertyFlags::HOST_COHERENT))
        });
        let Some(memory_type) = memory_type else {
            unsafe { device.raw.destroy_buffer(buffer, None) };
            return Err(fail(format!(
                "no memory type in host-pointer bits {:#x} & buffer bits {:#x}",
                host_props.memory_type_bits, requirements.memory_type_bits
            )));
        };
        let mut import =
            vk::ImportMemoryHostPointerInfoEXT::default().handle_type(handle_type).host_pointer(self.ptr.cast());
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(self.size)
            .memory_type_index(memory_type)
            .push_next(&mut import);
        let memory = match unsafe { device.raw.allocate_memory(&alloc, None) } {
            Ok(m) => m,
            Err(result) => {
                unsafe { device.raw.destroy_buffer(buffer, None) };
                return Err(BackendError::vk("vkAllocateMemory(host pointer import)", result));
            }
        };
        if let Err(result) = unsafe { device.raw.bind_buffer_memory(buffer, memory, 0) } {
            unsafe {
                device.raw.destroy_buffer(buffer, None);
                device.raw.free_memory(memory, None);
            }
            return Err(BackendError::vk("vkBindBufferMemory(host pointer import)", result));
        }
        let coherent = memory_props.memory_types[memory_type as usize]
            .property_flags
            .contains(vk::MemoryPropertyFlags::HOST_COHERENT);
        Ok(HostImport { device: device.clone(), buffer, memory, coherent })
    }

    /// The allocation's first byte, for the host threads of remote links (remote.rs), which
    /// read and write it while no device copies through it.
    pub(crate) fn host_ptr(&self) -> *mut u8 {
        self.ptr
    }

    /// The first device that imported the allocation as memory that is not `HOST_COHERENT`
    /// (the host would need to flush and invalidate around its own accesses), if any.
    pub(crate) fn first_incoherent_device(&self) -> Option<usize> {
        self.imports.iter().find(|i| !i.coherent).map(|i| i.device.info.index)
    }

    /// The `VkBuffer` through which device `device_index` sees the allocation.
    pub(crate) fn buffer_on(&self, device_index: usize) -> Option<vk::Buffer> {
        self.imports.iter().find(|i| i.device.info.index == device_index).map(|i| i.buffer)
    }
}

impl Drop for SharedHostBuffer {
    fn drop(&mut self) {
        // Every device must be done with its view before the host memory goes away.
        for import in self.imports.drain(..) {
            unsafe {
                let _ = import.device.raw.device_wait_idle();
                import.device.raw.destroy_buffer(import.buffer, None);
                import.device.raw.free_memory(import.memory, None);
            }
        }
        unsafe { std::alloc::dealloc(self.ptr, self.layout) };
    }
}
