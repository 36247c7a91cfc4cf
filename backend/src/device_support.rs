//! What a physical device must offer before `Device::new` creates a logical device on it, and
//! which optional extensions it gets: each step reads one part of the physical device and either
//! records what it found or names the first missing capability.

use std::ffi::{CStr, c_char};

use ash::vk;

use crate::error::{BackendError, Result, VkContext};
use crate::instance::Instance;

/// Builds the error for a capability the device lacks.
pub(crate) type Missing<'a> = &'a dyn Fn(&str) -> BackendError;

/// The physical device's properties that outlive device creation.
pub(crate) struct PhysicalProperties {
    pub(crate) core: vk::PhysicalDeviceProperties,
    pub(crate) name: String,
    pub(crate) driver: String,
    pub(crate) driver_info: String,
    pub(crate) min_imported_host_pointer_alignment: u64,
    /// `deviceUUID` and `driverUUID`: two logical devices with equal pairs are one physical GPU
    /// under one driver, which is what opaque-fd memory and semaphores may be shared between.
    pub(crate) uuids: [[u8; vk::UUID_SIZE]; 2],
    subgroup_operations: vk::SubgroupFeatureFlags,
    subgroup_stages: vk::ShaderStageFlags,
}

fn c_string(s: std::result::Result<&CStr, std::ffi::FromBytesUntilNulError>) -> String {
    s.map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

impl PhysicalProperties {
    pub(crate) fn query(raw_instance: &ash::Instance, physical: vk::PhysicalDevice) -> Self {
        let core = unsafe { raw_instance.get_physical_device_properties(physical) };
        let mut driver_props = vk::PhysicalDeviceDriverProperties::default();
        let mut host_props = vk::PhysicalDeviceExternalMemoryHostPropertiesEXT::default();
        let mut subgroup_props = vk::PhysicalDeviceSubgroupProperties::default();
        let mut id_props = vk::PhysicalDeviceIDProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default()
            .push_next(&mut id_props)
            .push_next(&mut driver_props)
            .push_next(&mut host_props)
            .push_next(&mut subgroup_props);
        unsafe { raw_instance.get_physical_device_properties2(physical, &mut props2) };
        Self {
            core,
            name: c_string(core.device_name_as_c_str()),
            driver: c_string(driver_props.driver_name_as_c_str()),
            driver_info: c_string(driver_props.driver_info_as_c_str()),
            min_imported_host_pointer_alignment: host_props.min_imported_host_pointer_alignment,
            uuids: [id_props.device_uuid, id_props.driver_uuid],
            subgroup_operations: subgroup_props.supported_operations,
            subgroup_stages: subgroup_props.supported_stages,
        }
    }

    /// `major.minor.patch` of the device's Vulkan API version.
    pub(crate) fn api_version(&self) -> String {
        let v = self.core.api_version;
        format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
    }
}

/// The device extensions to enable.
pub(crate) struct Extensions {
    /// VK_EXT_external_memory_host (cross-device copies through host memory).
    pub(crate) host_import: bool,
    /// The calibrated-timestamps extension, EXT or KHR, when the device can sample the host clock.
    pub(crate) calibrated: Option<&'static CStr>,
    /// VK_KHR_pipeline_executable_properties, when asked for by `PARALLAX_PIPELINE_STATS`.
    pub(crate) pipeline_stats: bool,
    /// VK_KHR_external_memory_fd, when the device can export and import transfer buffers as
    /// opaque fds (links between logical devices of one GPU, links.rs).
    pub(crate) memory_fd: bool,
    /// VK_KHR_external_semaphore_fd, when the device can export and import timeline semaphores
    /// as opaque fds (GPU-side waits across logical devices of one GPU, links.rs).
    pub(crate) semaphore_fd: bool,
    /// VK_EXT_shader_image_atomic_int64, when the device offers it (reported, not enabled: the
    /// visibility G-buffer uses buffer atomics).
    pub(crate) image_int64_atomics: bool,
}

impl Extensions {
    pub(crate) fn choose(
        instance: &Instance,
        physical: vk::PhysicalDevice,
        need_host_import: bool,
        missing: Missing<'_>,
    ) -> Result<Self> {
        let raw_instance = &instance.raw;
        let extensions = unsafe { raw_instance.enumerate_device_extension_properties(physical) }
            .vk("vkEnumerateDeviceExtensionProperties")?;
        let has_ext = |ext: &CStr| extensions.iter().any(|e| e.extension_name_as_c_str() == Ok(ext));
        let host_import = has_ext(ash::ext::external_memory_host::NAME);
        if !host_import && need_host_import {
            return Err(missing("VK_EXT_external_memory_host (cross-device copies)"));
        }
        // EXT first: the two are the same functions, and the Khronos validation layer that
        // Debian 12 ships (1.3.239) predates the KHR name and warns about it on NVIDIA, which
        // offers both.
        let calibrated = if has_ext(ash::ext::calibrated_timestamps::NAME) {
            Some(ash::ext::calibrated_timestamps::NAME)
        } else if has_ext(ash::khr::calibrated_timestamps::NAME) {
            Some(ash::khr::calibrated_timestamps::NAME)
        } else {
            None
        };
        let calibrated = calibrated.filter(|ext| samples_host_clock(instance, physical, ext));
        let want_stats = std::env::var_os("PARALLAX_PIPELINE_STATS").is_some_and(|v| !v.is_empty() && v != "0");
        let pipeline_stats = want_stats && has_ext(ash::khr::pipeline_executable_properties::NAME);
        let memory_fd = has_ext(ash::khr::external_memory_fd::NAME) && shares_buffers(instance, physical);
        let semaphore_fd = has_ext(ash::khr::external_semaphore_fd::NAME) && shares_timelines(instance, physical);
        let image_int64_atomics = has_ext(ash::ext::shader_image_atomic_int64::NAME);
        Ok(Self { host_import, calibrated, pipeline_stats, memory_fd, semaphore_fd, image_int64_atomics })
    }

    /// The names to pass to `vkCreateDevice`.
    pub(crate) fn names(&self) -> Vec<*const c_char> {
        let mut enabled = Vec::new();
        if self.host_import {
            enabled.push(ash::ext::external_memory_host::NAME.as_ptr());
        }
        if let Some(ext) = self.calibrated {
            enabled.push(ext.as_ptr());
        }
        if self.pipeline_stats {
            enabled.push(ash::khr::pipeline_executable_properties::NAME.as_ptr());
        }
        if self.memory_fd {
            enabled.push(ash::khr::external_memory_fd::NAME.as_ptr());
        }
        if self.semaphore_fd {
            enabled.push(ash::khr::external_semaphore_fd::NAME.as_ptr());
        }
        enabled
    }
}

/// Usage of every shared staging buffer: written by one copy, read by another.
pub(crate) const SHARED_BUFFER_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::TRANSFER_SRC.as_raw() | vk::BufferUsageFlags::TRANSFER_DST.as_raw(),
);

/// Whether transfer buffers can be exported and imported as opaque fds (what a link's shared
/// staging buffer is, memory.rs `SharedDeviceBuffer`).
fn shares_buffers(instance: &Instance, physical: vk::PhysicalDevice) -> bool {
    let info = vk::PhysicalDeviceExternalBufferInfo::default()
        .usage(SHARED_BUFFER_USAGE)
        .handle_type(vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD);
    let mut props = vk::ExternalBufferProperties::default();
    unsafe { instance.raw.get_physical_device_external_buffer_properties(physical, &info, &mut props) };
    let features = props.external_memory_properties.external_memory_features;
    features.contains(vk::ExternalMemoryFeatureFlags::EXPORTABLE | vk::ExternalMemoryFeatureFlags::IMPORTABLE)
}

/// Whether timeline semaphores (not only binary ones) can be exported and imported as opaque
/// fds: the extension alone does not promise it.
fn shares_timelines(instance: &Instance, physical: vk::PhysicalDevice) -> bool {
    let mut timeline = vk::SemaphoreTypeCreateInfo::default().semaphore_type(vk::SemaphoreType::TIMELINE);
    let info = vk::PhysicalDeviceExternalSemaphoreInfo::default()
        .handle_type(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD)
        .push_next(&mut timeline);
    let mut props = vk::ExternalSemaphoreProperties::default();
    unsafe { instance.raw.get_physical_device_external_semaphore_properties(physical, &info, &mut props) };
    props
        .external_semaphore_features
        .contains(vk::ExternalSemaphoreFeatureFlags::EXPORTABLE | vk::ExternalSemaphoreFeatureFlags::IMPORTABLE)
}

/// Calibration is only useful when the device can sample CLOCK_MONOTONIC, the clock the host side
/// of every report uses.
fn samples_host_clock(instance: &Instance, physical: vk::PhysicalDevice, ext: &CStr) -> bool {
    let raw_instance = &instance.raw;
    let domains = unsafe {
        if ext == ash::khr::calibrated_timestamps::NAME {
            ash::khr::calibrated_timestamps::Instance::new(&instance.entry, raw_instance)
                .get_physical_device_calibrateable_time_domains(physical)
        } else {
            ash::ext::calibrated_timestamps::Instance::new(&instance.entry, raw_instance)
                .get_physical_device_calibrateable_time_domains(physical)
        }
    }
    .unwrap_or_default();
    domains.contains(&vk::TimeDomainKHR::DEVICE) && domains.contains(&vk::TimeDomainKHR::CLOCK_MONOTONIC)
}

/// The optional features the device reports, checked in two groups (the order in which a
/// missing one is named is part of the error a user sees).
pub(crate) struct Features {
    core: vk::PhysicalDeviceFeatures,
    f12: vk::PhysicalDeviceVulkan12Features<'static>,
    f13: vk::PhysicalDeviceVulkan13Features<'static>,
}

impl Features {
    pub(crate) fn query(raw_instance: &ash::Instance, physical: vk::PhysicalDevice) -> Self {
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f12).push_next(&mut f13);
        unsafe { raw_instance.get_physical_device_features2(physical, &mut f2) };
        let core = f2.features;
        // The chain's pointers are not followed after this point.
        f12.p_next = std::ptr::null_mut();
        f13.p_next = std::ptr::null_mut();
        Self { core, f12, f13 }
    }

    /// Synchronisation, buffer references, dynamic rendering and format-less storage images.
    pub(crate) fn require_core(&self, missing: Missing<'_>) -> Result<()> {
        let (core, f12, f13) = (&self.core, &self.f12, &self.f13);
        // Global buffers (scene data, per-frame data) reach shaders as buffer references.
        if f12.buffer_device_address == vk::FALSE {
            return Err(missing("bufferDeviceAddress"));
        }
        // Timeline semaphores and sync2 carry all synchronisation.
        if f12.timeline_semaphore == vk::FALSE {
            return Err(missing("timelineSemaphore"));
        }
        if f13.synchronization2 == vk::FALSE {
            return Err(missing("synchronization2"));
        }
        // glslc targeting Vulkan 1.3 declares workgroup sizes with LocalSizeId, which needs
        // maintenance4.
        if f13.maintenance4 == vk::FALSE {
            return Err(missing("maintenance4"));
        }
        // Raster passes render without render-pass objects.
        if f13.dynamic_rendering == vk::FALSE {
            return Err(missing("dynamicRendering"));
        }
        // Scene textures are sampled from one array with a per-material (non-uniform) index.
        if f12.shader_sampled_image_array_non_uniform_indexing == vk::FALSE {
            return Err(missing("shaderSampledImageArrayNonUniformIndexing"));
        }
        // Storage images without a format qualifier let one bindless array hold every float format.
        if core.shader_storage_image_read_without_format == vk::FALSE
            || core.shader_storage_image_write_without_format == vk::FALSE
        {
            return Err(missing("shaderStorageImage{Read,Write}WithoutFormat"));
        }
        Ok(())
    }

    /// 64-bit integer atomics on storage buffers (`shaderInt64` and `shaderBufferInt64Atomics`,
    /// VkPhysicalDeviceShaderAtomicInt64Features promoted into Vulkan 1.2's features): what the
    /// visibility G-buffer's depth-and-triangle keys need (parallax-passes `visibility`).
    /// Optional: without it the pipeline traces first hits instead.
    pub(crate) fn buffer_int64_atomics(&self) -> bool {
        self.core.shader_int64 == vk::TRUE && self.f12.shader_buffer_int64_atomics == vk::TRUE
    }

    /// `shaderSharedInt64Atomics` (64-bit atomics on workgroup memory), reported only.
    pub(crate) fn shared_int64_atomics(&self) -> bool {
        self.core.shader_int64 == vk::TRUE && self.f12.shader_shared_int64_atomics == vk::TRUE
    }

    /// Host query resets (timestamps) and what the ray-casting kernels need.
    pub(crate) fn require_queries_and_ray_kernels(
        &self,
        props: &PhysicalProperties,
        missing: Missing<'_>,
    ) -> Result<()> {
        if self.f12.host_query_reset == vk::FALSE {
            return Err(missing("hostQueryReset"));
        }
        // The persistent ray schedule (shaders/bvh_raycast.glsl) hands out rays and tests
        // triangles by subgroup.
        let needed_subgroup_ops = vk::SubgroupFeatureFlags::BASIC
            | vk::SubgroupFeatureFlags::BALLOT
            | vk::SubgroupFeatureFlags::VOTE
            | vk::SubgroupFeatureFlags::SHUFFLE
            | vk::SubgroupFeatureFlags::SHUFFLE_RELATIVE
            | vk::SubgroupFeatureFlags::ARITHMETIC;
        if !props.subgroup_operations.contains(needed_subgroup_ops)
            || !props.subgroup_stages.contains(vk::ShaderStageFlags::COMPUTE)
        {
            return Err(missing(
                "subgroup basic, ballot, vote, shuffle, relative shuffle and arithmetic operations in compute shaders",
            ));
        }
        // BVH node bytes are converted to floats from 8-bit lanes (shaders/bvh_traverse.glsl).
        if self.f12.shader_int8 == vk::FALSE {
            return Err(missing("shaderInt8"));
        }
        Ok(())
    }
}

/// The queue families a device's queues come from.
pub(crate) struct QueueFamilies {
    /// A compute family with timestamps: passes, and copies without a copy family.
    pub(crate) main: u32,
    /// A transfer-only family with timestamps (the copy engines of a discrete GPU).
    pub(crate) copy: Option<u32>,
    /// Valid timestamp bits of the main and of the copy family (the main one's without a copy
    /// family).
    pub(crate) timestamp_bits: [u32; 2],
}

impl QueueFamilies {
    pub(crate) fn choose(
        raw_instance: &ash::Instance,
        physical: vk::PhysicalDevice,
        missing: Missing<'_>,
    ) -> Result<Self> {
        let families = unsafe { raw_instance.get_physical_device_queue_family_properties(physical) };
        let main = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE) && f.timestamp_valid_bits > 0)
            .ok_or_else(|| missing("a compute queue with timestamps"))?;
        let valid_bits = families[main].timestamp_valid_bits;
        // Transfer-only families are the copy engines on discrete GPUs; lavapipe has none.
        let copy = families.iter().position(|f| {
            f.queue_flags.contains(vk::QueueFlags::TRANSFER)
                && !f.queue_flags.intersects(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
                && f.timestamp_valid_bits > 0
                && f.queue_count > 0
        });
        let copy_bits = copy.map_or(valid_bits, |f| families[f].timestamp_valid_bits);
        Ok(Self { main: main as u32, copy: copy.map(|f| f as u32), timestamp_bits: [valid_bits, copy_bits] })
    }
}
