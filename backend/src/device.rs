//! One `VkDevice` with its queue, allocator, command pool and the small helpers every other
//! module needs (one-shot submissions, timeline semaphores, clock calibration).
//!
//! A `Device` is either one physical GPU or one of several logical devices created on the same
//! physical device (`--fake-devices`); nothing above this module can tell the two apart, which is
//! what lets lavapipe exercise every multi-device path.

use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use crate::device_support::{Extensions, Features, PhysicalProperties, QueueFamilies};
use crate::error::{BackendError, Result, VkContext};
use crate::instance::Instance;

/// What a person needs to know about a chosen device.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceInfo {
    /// Index of this logical device in the context (0 = primary, where views are gathered).
    pub index: usize,
    /// Index of the physical device in the loader's enumeration.
    pub physical_index: usize,
    pub name: String,
    pub driver: String,
    pub driver_info: String,
    /// `major.minor.patch` of the device's Vulkan API version.
    pub api_version: String,
    pub device_type: String,
    /// Whether the device is a CPU implementation (lavapipe): its work shares the host's cores
    /// with everything else the machine runs, so its progress is as slow as the host is busy.
    pub runs_on_host_cpu: bool,
    /// Whether GPU timestamps can be mapped to the host clock by VK_*_calibrated_timestamps.
    pub calibrated_timestamps: bool,
    /// `maxImageDimension2D`: the largest width or height of an image the device can create.
    pub max_image_dimension_2d: u32,
    /// Size of the largest device-local memory heap, in bytes: what a caller can check its
    /// working set against before allocating.
    pub device_local_heap_bytes: u64,
    /// 64-bit atomics on storage buffers (`shaderInt64` + `shaderBufferInt64Atomics`, enabled
    /// when offered): what the visibility G-buffer needs; without them it falls back to first hits.
    pub buffer_int64_atomics: bool,
    /// `shaderSharedInt64Atomics` (enabled when offered; no kernel needs it yet).
    pub shared_int64_atomics: bool,
    /// VK_EXT_shader_image_atomic_int64's `shaderImageInt64Atomics` is offered (not enabled).
    pub image_int64_atomics: bool,
}

/// Device-level functions of calibrated timestamps (EXT and KHR have the same shape).
enum CalibratedFns {
    Ext(ash::ext::calibrated_timestamps::Device),
    Khr(ash::khr::calibrated_timestamps::Device),
}

/// One logical Vulkan device and everything that belongs to it alone.
pub struct Device {
    pub info: DeviceInfo,
    pub(crate) instance: Arc<Instance>,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) raw: ash::Device,
    pub(crate) queue_family: u32,
    queue: Mutex<vk::Queue>,
    /// A transfer-only queue (the DMA engines of a GPU), when the device has one with
    /// timestamps: `(family, queue)`.
    copy_queue: Option<(u32, Mutex<vk::Queue>)>,
    /// Valid timestamp bits of the main and of the copy queue family.
    pub(crate) timestamp_bits: [u32; 2],
    allocator: Mutex<Option<Allocator>>,
    /// Pool for one-shot command buffers (init, readback); the executor has its own pools.
    one_shot_pool: Mutex<vk::CommandPool>,
    pub(crate) external_memory_host: Option<ash::ext::external_memory_host::Device>,
    pub(crate) min_host_pointer_alignment: u64,
    /// Opaque-fd export and import of transfer buffers, when the driver offers it (links.rs).
    pub(crate) external_memory_fd: Option<ash::khr::external_memory_fd::Device>,
    /// Opaque-fd export and import of timeline semaphores, when the driver offers it (links.rs).
    pub(crate) external_semaphore_fd: Option<ash::khr::external_semaphore_fd::Device>,
    /// `deviceUUID` and `driverUUID` of the physical device.
    pub(crate) uuids: [[u8; vk::UUID_SIZE]; 2],
    calibrated: Option<CalibratedFns>,
    /// VK_KHR_pipeline_executable_properties, enabled when `PARALLAX_PIPELINE_STATS` is set and
    /// the driver has it: compiled kernels' statistics (registers, local memory) go to stderr.
    pub(crate) pipeline_stats: Option<ash::khr::pipeline_executable_properties::Device>,
    /// Nanoseconds per timestamp tick.
    pub(crate) timestamp_period: f64,
}

/// Which queue of a device a submission goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum QueueKind {
    /// Compute (and graphics) queue: passes, and copies unless a copy queue is used.
    Main,
    /// Transfer-only queue, if the device has one; otherwise the main queue.
    Copy,
}

impl Device {
    /// Creates a logical device on `physical`. `need_host_import` makes
    /// VK_EXT_external_memory_host mandatory (needed as soon as there are two devices).
    pub(crate) fn new(
        instance: &Arc<Instance>,
        physical: vk::PhysicalDevice,
        index: usize,
        physical_index: usize,
        need_host_import: bool,
    ) -> Result<Arc<Self>> {
        let raw_instance = &instance.raw;
        let props = PhysicalProperties::query(raw_instance, physical);
        let missing = |what: &str| BackendError::MissingCapability {
            device: index,
            name: props.name.clone(),
            what: what.to_string(),
        };
        let extensions = Extensions::choose(instance, physical, need_host_import, &missing)?;
        let features = Features::query(raw_instance, physical);
        features.require_core(&missing)?;
        let families = QueueFamilies::choose(raw_instance, physical, &missing)?;
        features.require_queries_and_ray_kernels(&props, &missing)?;

        let int64_atomics = [features.buffer_int64_atomics(), features.shared_int64_atomics()];
        let raw = create_logical_device(raw_instance, physical, &families, &extensions, int64_atomics)?;
        let queue = unsafe { raw.get_device_queue(families.main, 0) };
        let copy_queue = families.copy.map(|f| (f, Mutex::new(unsafe { raw.get_device_queue(f, 0) })));
        let allocator = create_allocator(raw_instance, &raw, physical)?;
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(families.main)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let one_shot_pool = unsafe { raw.create_command_pool(&pool_info, None) }.vk("vkCreateCommandPool")?;

        let calibrated = extensions.calibrated.map(|ext| {
            if ext == ash::khr::calibrated_timestamps::NAME {
                CalibratedFns::Khr(ash::khr::calibrated_timestamps::Device::new(raw_instance, &raw))
            } else {
                CalibratedFns::Ext(ash::ext::calibrated_timestamps::Device::new(raw_instance, &raw))
            }
        });
        let external_memory_host =
            extensions.host_import.then(|| ash::ext::external_memory_host::Device::new(raw_instance, &raw));
        let external_memory_fd =
            extensions.memory_fd.then(|| ash::khr::external_memory_fd::Device::new(raw_instance, &raw));
        let external_semaphore_fd =
            extensions.semaphore_fd.then(|| ash::khr::external_semaphore_fd::Device::new(raw_instance, &raw));
        let pipeline_stats = extensions
            .pipeline_stats
            .then(|| ash::khr::pipeline_executable_properties::Device::new(raw_instance, &raw));

        let info = DeviceInfo {
            index,
            physical_index,
            name: props.name.clone(),
            driver: props.driver.clone(),
            driver_info: props.driver_info.clone(),
            api_version: props.api_version(),
            device_type: format!("{:?}", props.core.device_type),
            runs_on_host_cpu: props.core.device_type == vk::PhysicalDeviceType::CPU,
            calibrated_timestamps: calibrated.is_some(),
            max_image_dimension_2d: props.core.limits.max_image_dimension2_d,
            device_local_heap_bytes: largest_device_local_heap(raw_instance, physical),
            buffer_int64_atomics: int64_atomics[0],
            shared_int64_atomics: int64_atomics[1],
            image_int64_atomics: extensions.image_int64_atomics,
        };
        Ok(Arc::new(Self {
            info,
            instance: instance.clone(),
            physical,
            raw,
            queue_family: families.main,
            queue: Mutex::new(queue),
            copy_queue,
            timestamp_bits: families.timestamp_bits,
            allocator: Mutex::new(Some(allocator)),
            one_shot_pool: Mutex::new(one_shot_pool),
            external_memory_host,
            min_host_pointer_alignment: props.min_imported_host_pointer_alignment.max(1),
            external_memory_fd,
            external_semaphore_fd,
            uuids: props.uuids,
            calibrated,
            pipeline_stats,
            timestamp_period: f64::from(props.core.limits.timestamp_period),
        }))
    }

    /// The raw `ash` device.
    pub fn raw(&self) -> &ash::Device {
        &self.raw
    }

    /// Runs `f` with the allocator locked.
    pub(crate) fn with_allocator<T>(&self, f: impl FnOnce(&mut Allocator) -> T) -> T {
        let mut guard = self.allocator.lock().unwrap_or_else(|p| p.into_inner());
        f(guard.as_mut().expect("allocator lives until the device is dropped"))
    }

    /// Submits to the main queue (queue access must be externally synchronised).
    pub(crate) fn submit(&self, submits: &[vk::SubmitInfo2<'_>], fence: vk::Fence) -> Result<()> {
        self.submit_to(QueueKind::Main, submits, fence)
    }

    /// Submits to the queue of `kind` (the main queue if the device has no copy queue).
    pub(crate) fn submit_to(&self, kind: QueueKind, submits: &[vk::SubmitInfo2<'_>], fence: vk::Fence) -> Result<()> {
        let queue = match (&self.copy_queue, kind) {
            (Some((_, q)), QueueKind::Copy) => q,
            _ => &self.queue,
        };
        let queue = queue.lock().unwrap_or_else(|p| p.into_inner());
        unsafe { self.raw.queue_submit2(*queue, submits, fence) }.vk("vkQueueSubmit2")
    }

    /// Queue family of the queue `kind` resolves to.
    pub(crate) fn family_of(&self, kind: QueueKind) -> u32 {
        match (&self.copy_queue, kind) {
            (Some((f, _)), QueueKind::Copy) => *f,
            _ => self.queue_family,
        }
    }

    /// Whether copies can go to a transfer-only queue of their own.
    pub fn has_copy_queue(&self) -> bool {
        self.copy_queue.is_some()
    }

    /// Distinct queue families resources must be shared between (CONCURRENT sharing when two).
    pub(crate) fn families(&self) -> Vec<u32> {
        let mut f = vec![self.queue_family];
        if let Some((c, _)) = &self.copy_queue {
            f.push(*c);
        }
        f
    }

    /// Records `record` into a fresh command buffer, submits it and waits for it. For set-up
    /// and readback only, never on the render path.
    pub(crate) fn one_shot(&self, record: impl FnOnce(vk::CommandBuffer)) -> Result<()> {
        let pool = self.one_shot_pool.lock().unwrap_or_else(|p| p.into_inner());
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(*pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        let cb = unsafe { self.raw.allocate_command_buffers(&alloc) }.vk("vkAllocateCommandBuffers")?[0];
        let result = (|| {
            let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            unsafe { self.raw.begin_command_buffer(cb, &begin) }.vk("vkBeginCommandBuffer")?;
            record(cb);
            unsafe { self.raw.end_command_buffer(cb) }.vk("vkEndCommandBuffer")?;
            let fence = unsafe { self.raw.create_fence(&vk::FenceCreateInfo::default(), None) }.vk("vkCreateFence")?;
            let cbs = [vk::CommandBufferSubmitInfo::default().command_buffer(cb)];
            let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cbs)];
            let waited = self
                .submit(&submit, fence)
                .and_then(|()| unsafe { self.raw.wait_for_fences(&[fence], true, u64::MAX) }.vk("vkWaitForFences"));
            unsafe { self.raw.destroy_fence(fence, None) };
            waited
        })();
        unsafe { self.raw.free_command_buffers(*pool, &[cb]) };
        result
    }

    /// Creates a timeline semaphore starting at `initial`.
    pub(crate) fn create_timeline(&self, initial: u64) -> Result<vk::Semaphore> {
        let mut ty =
            vk::SemaphoreTypeCreateInfo::default().semaphore_type(vk::SemaphoreType::TIMELINE).initial_value(initial);
        let info = vk::SemaphoreCreateInfo::default().push_next(&mut ty);
        unsafe { self.raw.create_semaphore(&info, None) }.vk("vkCreateSemaphore")
    }

    /// A timeline semaphore that can be exported as an opaque fd (a producer's progress timeline
    /// that consumers of `gpu` links wait on, links.rs).
    pub(crate) fn create_exportable_timeline(&self) -> Result<vk::Semaphore> {
        let mut ty = vk::SemaphoreTypeCreateInfo::default().semaphore_type(vk::SemaphoreType::TIMELINE);
        let mut export =
            vk::ExportSemaphoreCreateInfo::default().handle_types(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD);
        let info = vk::SemaphoreCreateInfo::default().push_next(&mut ty).push_next(&mut export);
        unsafe { self.raw.create_semaphore(&info, None) }.vk("vkCreateSemaphore(exportable timeline)")
    }

    /// Host wait until `semaphore` reaches `value`; `Ok(false)` on timeout.
    pub(crate) fn wait_timeline(&self, semaphore: vk::Semaphore, value: u64, timeout_ns: u64) -> Result<bool> {
        let semaphores = [semaphore];
        let values = [value];
        let info = vk::SemaphoreWaitInfo::default().semaphores(&semaphores).values(&values);
        match unsafe { self.raw.wait_semaphores(&info, timeout_ns) } {
            Ok(()) => Ok(true),
            Err(vk::Result::TIMEOUT) => Ok(false),
            Err(result) => Err(BackendError::vk("vkWaitSemaphores", result)),
        }
    }

    /// Host wait, without a timeout, until any of `semaphores` reaches its value in `values`.
    pub(crate) fn wait_any_timeline(&self, semaphores: &[vk::Semaphore], values: &[u64]) -> Result<()> {
        let info =
            vk::SemaphoreWaitInfo::default().flags(vk::SemaphoreWaitFlags::ANY).semaphores(semaphores).values(values);
        unsafe { self.raw.wait_semaphores(&info, u64::MAX) }.vk("vkWaitSemaphores")
    }

    /// Host signal of a timeline semaphore (used by the cross-device relay).
    pub(crate) fn signal_timeline(&self, semaphore: vk::Semaphore, value: u64) -> Result<()> {
        let info = vk::SemaphoreSignalInfo::default().semaphore(semaphore).value(value);
        unsafe { self.raw.signal_semaphore(&info) }.vk("vkSignalSemaphore")
    }

    /// Current value of a timeline semaphore.
    pub(crate) fn timeline_value(&self, semaphore: vk::Semaphore) -> Result<u64> {
        unsafe { self.raw.get_semaphore_counter_value(semaphore) }.vk("vkGetSemaphoreCounterValue")
    }

    /// Waits until the device is idle (teardown, tests).
    pub fn wait_idle(&self) -> Result<()> {
        unsafe { self.raw.device_wait_idle() }.vk("vkDeviceWaitIdle")
    }

    /// Pairs a device timestamp with host CLOCK_MONOTONIC time. Uses calibrated timestamps
    /// when the device has them, else a submitted timestamp bracketed by two host clock reads.
    pub(crate) fn clock_offset(&self) -> Result<ClockCalibration> {
        if let Some(fns) = &self.calibrated {
            let infos = [
                vk::CalibratedTimestampInfoKHR::default().time_domain(vk::TimeDomainKHR::DEVICE),
                vk::CalibratedTimestampInfoKHR::default().time_domain(vk::TimeDomainKHR::CLOCK_MONOTONIC),
            ];
            let sampled = unsafe {
                match fns {
                    CalibratedFns::Ext(f) => f.get_calibrated_timestamps(&infos),
                    CalibratedFns::Khr(f) => f.get_calibrated_timestamps(&infos),
                }
            }
            .vk("vkGetCalibratedTimestamps")?;
            let (ts, deviation) = sampled;
            return Ok(ClockCalibration {
                reference_ticks: ts[0],
                reference_host_ns: ts[1] as f64,
                uncertainty_ns: deviation as f64,
                method: CalibrationMethod::CalibratedTimestamps,
            });
        }
        self.round_trip_calibration()
    }

    fn round_trip_calibration(&self) -> Result<ClockCalibration> {
        let pool_info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(1);
        let pool = unsafe { self.raw.create_query_pool(&pool_info, None) }.vk("vkCreateQueryPool")?;
        let before = host_now_ns();
        let recorded = self.one_shot(|cb| unsafe {
            self.raw.cmd_reset_query_pool(cb, pool, 0, 1);
            self.raw.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::ALL_COMMANDS, pool, 0);
        });
        let after = host_now_ns();
        let mut ticks = [0u64; 1];
        let read = recorded.and_then(|()| {
            unsafe {
                self.raw.get_query_pool_results(
                    pool,
                    0,
                    &mut ticks,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .vk("vkGetQueryPoolResults")
        });
        unsafe { self.raw.destroy_query_pool(pool, None) };
        read?;
        Ok(ClockCalibration {
            reference_ticks: ticks[0],
            reference_host_ns: (before + after) as f64 / 2.0,
            uncertainty_ns: (after - before) as f64 / 2.0,
            method: CalibrationMethod::SubmitRoundTrip,
        })
    }

    /// Host CLOCK_MONOTONIC ns of a timestamp written on queue `kind`, through `calibration`.
    ///
    /// Timestamps of a family with fewer than 64 valid bits wrap; they are unwrapped around the
    /// calibration's reference, which is sampled every frame, far closer than a wrap period
    /// (2^32 ns ≈ 4.3 s for 32 bits).
    pub(crate) fn timestamp_to_host_ns(&self, ticks: u64, kind: QueueKind, calibration: &ClockCalibration) -> u64 {
        timestamp_to_host_ns(ticks, self.timestamp_bits[kind as usize], self.timestamp_period, calibration)
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        unsafe {
            // Nothing may still run when memory and the device go away.
            let _ = self.raw.device_wait_idle();
            let pool = *self.one_shot_pool.get_mut().unwrap_or_else(|p| p.into_inner());
            self.raw.destroy_command_pool(pool, None);
            // Allocator frees its blocks; it must go before the device.
            drop(self.allocator.get_mut().unwrap_or_else(|p| p.into_inner()).take());
            let _turn = crate::lifetime_lock::hold();
            self.raw.destroy_device(None);
        }
    }
}

/// How GPU time was mapped to host time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum CalibrationMethod {
    /// VK_KHR/EXT_calibrated_timestamps sampled both clocks together.
    CalibratedTimestamps,
    /// A submitted timestamp bracketed by two host clock reads (error up to the round trip).
    SubmitRoundTrip,
}

/// Result of a clock calibration of one device: a device timestamp and the host time it
/// corresponds to.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ClockCalibration {
    pub reference_ticks: u64,
    pub reference_host_ns: f64,
    pub uncertainty_ns: f64,
    pub method: CalibrationMethod,
}

/// Maps a timestamp with `bits` valid bits to host ns (see [`Device::timestamp_to_host_ns`]).
fn timestamp_to_host_ns(ticks: u64, bits: u32, period_ns: f64, calibration: &ClockCalibration) -> u64 {
    let bits = bits.clamp(1, 64);
    let delta_ticks = if bits == 64 {
        ticks.wrapping_sub(calibration.reference_ticks) as i64
    } else {
        let modulus = 1u64 << bits;
        let d = ticks.wrapping_sub(calibration.reference_ticks) & (modulus - 1);
        if d >= modulus / 2 { d as i64 - modulus as i64 } else { d as i64 }
    };
    let host = calibration.reference_host_ns + delta_ticks as f64 * period_ns;
    host.max(0.0) as u64
}

/// Host CLOCK_MONOTONIC in nanoseconds: the common clock of every report and trace.
pub fn host_now_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // clock_gettime(CLOCK_MONOTONIC) cannot fail with a valid pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Creates the `VkDevice` with one queue of each chosen family, the features every kernel
/// relies on and, where offered, 64-bit buffer and shared atomics (`[buffer, shared]`, each
/// with `shaderInt64`).
fn create_logical_device(
    raw_instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    families: &QueueFamilies,
    extensions: &Extensions,
    [buffer_atomics, shared_atomics]: [bool; 2],
) -> Result<ash::Device> {
    let priorities = [1.0f32];
    let mut queue_infos =
        vec![vk::DeviceQueueCreateInfo::default().queue_family_index(families.main).queue_priorities(&priorities)];
    if let Some(f) = families.copy {
        queue_infos.push(vk::DeviceQueueCreateInfo::default().queue_family_index(f).queue_priorities(&priorities));
    }
    let enabled = extensions.names();
    let features = vk::PhysicalDeviceFeatures::default()
        .shader_storage_image_read_without_format(true)
        .shader_storage_image_write_without_format(true)
        .shader_int64(buffer_atomics || shared_atomics);
    let mut e12 = vk::PhysicalDeviceVulkan12Features::default()
        .timeline_semaphore(true)
        .host_query_reset(true)
        .buffer_device_address(true)
        .shader_int8(true)
        .shader_sampled_image_array_non_uniform_indexing(true)
        .shader_buffer_int64_atomics(buffer_atomics)
        .shader_shared_int64_atomics(shared_atomics);
    let mut e13 =
        vk::PhysicalDeviceVulkan13Features::default().synchronization2(true).maintenance4(true).dynamic_rendering(true);
    let mut executable_info =
        vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default().pipeline_executable_info(true);
    let mut create_info = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queue_infos)
        .enabled_extension_names(&enabled)
        .enabled_features(&features)
        .push_next(&mut e12)
        .push_next(&mut e13);
    if extensions.pipeline_stats {
        create_info = create_info.push_next(&mut executable_info);
    }
    let _turn = crate::lifetime_lock::hold();
    unsafe { raw_instance.create_device(physical, &create_info, None) }.vk("vkCreateDevice")
}

/// The device's memory allocator; on failure the device, which nothing else holds yet, is
/// destroyed.
fn create_allocator(
    raw_instance: &ash::Instance,
    raw: &ash::Device,
    physical: vk::PhysicalDevice,
) -> Result<Allocator> {
    let allocator = Allocator::new(&AllocatorCreateDesc {
        instance: raw_instance.clone(),
        device: raw.clone(),
        physical_device: physical,
        debug_settings: Default::default(),
        buffer_device_address: true,
        allocation_sizes: Default::default(),
    })
    .map_err(|source| BackendError::Allocation { what: "allocator".into(), source });
    if allocator.is_err() {
        let _turn = crate::lifetime_lock::hold();
        unsafe { raw.destroy_device(None) };
    }
    allocator
}

/// The largest DEVICE_LOCAL heap (lavapipe's one heap is system memory and is flagged so).
fn largest_device_local_heap(instance: &ash::Instance, physical: vk::PhysicalDevice) -> u64 {
    let memory = unsafe { instance.get_physical_device_memory_properties(physical) };
    let heaps = &memory.memory_heaps[..memory.memory_heap_count as usize];
    heaps.iter().filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL)).map(|h| h.size).max().unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibration(reference_ticks: u64) -> ClockCalibration {
        ClockCalibration {
            reference_ticks,
            reference_host_ns: 1_000_000_000.0,
            uncertainty_ns: 0.0,
            method: CalibrationMethod::CalibratedTimestamps,
        }
    }

    #[test]
    fn full_width_timestamps_map_linearly() {
        let c = calibration(5_000);
        assert_eq!(timestamp_to_host_ns(5_500, 64, 1.0, &c), 1_000_000_500);
        assert_eq!(timestamp_to_host_ns(4_000, 64, 2.0, &c), 999_998_000);
    }

    #[test]
    fn narrow_timestamps_unwrap_around_the_reference() {
        // Reference just below a 32-bit wrap; an event just after the wrap reads as a small value.
        let reference = (7u64 << 32) + (1 << 32) - 100;
        let c = calibration(reference);
        assert_eq!(timestamp_to_host_ns(50, 32, 1.0, &c), 1_000_000_150);
        // An event before the reference, without a wrap in between.
        assert_eq!(timestamp_to_host_ns((1 << 32) - 300, 32, 1.0, &c), 999_999_800);
    }
}
