//! What the executor allocates per device for a plan: images and buffers (kept across plan
//! changes when their description is unchanged), descriptor layout, command pools and buffers,
//! query pools, timelines; the shared staging memory of cross-device copies; the fault-injection
//! gate.

use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::device::{Device, QueueKind};
use crate::error::{BackendError, Result, VkContext};
use crate::exec_options::ExecOptions;
use crate::kernel::KernelPlan;
use crate::link_memory::SharedDeviceBuffer;
use crate::links::LinkKind;
use crate::memory::{Buffer, Image, SharedHostBuffer};
use crate::plan::{AllocId, CopyId, DeviceId, ExecResource, ExecutionPlan, Format, ResourceKind};
use crate::record::{TimerLabel, timer_labels, timer_spans};
use crate::segments::{Item, Segment};
use crate::shader_pipelines::Bindless;
use crate::staging_ring::{RingLayout, STAGING_ALIGN};

/// Fault-injection gate: producer's first submission of a frame waits until the consumer's
/// segment `consumer_segment` of the same frame is done.
pub(crate) struct FaultGate {
    /// Semaphore on the producer device.
    pub(crate) semaphore: vk::Semaphore,
    pub(crate) producer: usize,
    pub(crate) consumer: usize,
    pub(crate) consumer_segment: usize,
}

/// Per device, per frame-in-flight slot.
pub(crate) struct SlotResources {
    pub(crate) command_buffers: Vec<vk::CommandBuffer>,
    pub(crate) query_pool: vk::QueryPool,
}

/// Everything the executor keeps for one device.
pub(crate) struct DeviceState {
    pub(crate) device: Arc<Device>,
    pub(crate) images: HashMap<AllocId, Image>,
    /// Per-view buffer resources (ResourceKind::Buffer).
    pub(crate) buffers: HashMap<AllocId, Buffer>,
    pub(crate) image_slots: HashMap<AllocId, u32>,
    pub(crate) bindless: Bindless,
    /// Command pools of the main and of the copy queue family.
    pub(crate) command_pools: [vk::CommandPool; 2],
    pub(crate) progress: vk::Semaphore,
    /// Ready timelines of the links into this device, or producers' progress timelines imported
    /// for `gpu` links (links.rs).
    pub(crate) ready: Vec<vk::Semaphore>,
    /// Fault injection: host-signalled semaphore holding this (producer) device back.
    pub(crate) gate: Option<vk::Semaphore>,
    pub(crate) segments: Vec<Segment>,
    /// Per segment, the items each of its timestamp pairs covers, in order.
    pub(crate) timer_spans: Vec<Vec<Range<usize>>>,
    pub(crate) timers: Vec<TimerLabel>,
    pub(crate) slots: Vec<SlotResources>,
    /// Per slot, the buffers its recorded ops own (`Recorder::recording_buffer`); apart from
    /// `slots`, so a recording can fill them while it reads the slot's command buffers.
    pub(crate) recording_buffers: Vec<Vec<Buffer>>,
}

impl Drop for DeviceState {
    fn drop(&mut self) {
        let raw = &self.device.raw;
        unsafe {
            let _ = raw.device_wait_idle();
            for slot in &self.slots {
                if slot.query_pool != vk::QueryPool::null() {
                    raw.destroy_query_pool(slot.query_pool, None);
                }
            }
            for pool in self.command_pools {
                raw.destroy_command_pool(pool, None);
            }
            raw.destroy_semaphore(self.progress, None);
            for s in self.ready.drain(..) {
                raw.destroy_semaphore(s, None);
            }
            if let Some(g) = self.gate.take() {
                raw.destroy_semaphore(g, None);
            }
        }
    }
}

/// Staging memory of cross-device copies: per link and frame-in-flight slot one buffer shared by
/// its two devices (device memory for `gpu` and `shared` links, host memory for `relay` ones),
/// each of the link's copies at a fixed offset.
pub(crate) struct Staging {
    /// `[link][slot]`.
    pub(crate) buffers: Vec<Vec<LinkBuffer>>,
    /// Per copy: its link and its offset in the link's buffers.
    pub(crate) places: Vec<(usize, u64)>,
    /// Bytes of host and of device memory over every link and slot.
    pub(crate) host_bytes: u64,
    pub(crate) device_bytes: u64,
}

/// A link's staging buffer of one slot.
pub(crate) enum LinkBuffer {
    Host(SharedHostBuffer),
    Device(SharedDeviceBuffer),
}

impl LinkBuffer {
    /// The host allocation of a `relay` or `remote` link.
    pub(crate) fn host_ptr(&self) -> Option<*mut u8> {
        match self {
            LinkBuffer::Host(b) => Some(b.host_ptr()),
            LinkBuffer::Device(_) => None,
        }
    }

    /// The `VkBuffer` through which device `device_index` sees it.
    pub(crate) fn buffer_on(&self, device_index: usize) -> Option<vk::Buffer> {
        match self {
            LinkBuffer::Host(b) => b.buffer_on(device_index),
            LinkBuffer::Device(b) => b.buffer_on(device_index),
        }
    }
}

impl Staging {
    /// Per copy, the staging buffer of slot `slot` as device `d` sees it and the copy's offset
    /// in it (a null buffer for copies `d` neither sends nor receives).
    pub(crate) fn of_device(&self, d: usize, slot: usize) -> Vec<(vk::Buffer, u64)> {
        self.places
            .iter()
            .map(|&(link, offset)| (self.buffers[link][slot].buffer_on(d).unwrap_or_default(), offset))
            .collect()
    }
}

/// Creates images, descriptor layout, command buffers and query pools of `device` (its
/// progress timeline exportable with `export_progress`: it produces for `gpu` links).
pub(crate) fn create_device_state(
    device: &Arc<Device>,
    plan: &KernelPlan,
    segments: Vec<Segment>,
    slots: usize,
    options: &ExecOptions,
    export_progress: bool,
    kept: &mut Kept,
) -> Result<DeviceState> {
    let d = device.info.index;
    let shaders = &options.shaders;
    let (resources, buffer_resources): (Vec<AllocId>, Vec<AllocId>) = plan
        .resources_of_device(DeviceId(d as u32))
        .into_iter()
        .partition(|&r| plan.resource(r).kind == ResourceKind::Image);
    let (images, fresh) = take_or_create_images(device, plan, d, &resources, kept)?;
    let (buffers, fresh_buffers) = take_or_create_buffers(device, plan, d, &buffer_resources, kept)?;
    clear_buffers(device, fresh_buffers.iter().map(|r| &buffers[r]))?;
    let placeholders = [
        Image::new(device, "float placeholder", 1, 1, Format::Rgba32f)?,
        Image::new(device, "uint placeholder", 1, 1, Format::R32u)?,
        Image::new(device, "depth placeholder", 1, 1, Format::Depth32f)?,
    ];
    initialise_images(device, fresh.iter().map(|r| &images[r]).chain(&placeholders))?;
    let image_slots: HashMap<AllocId, u32> = resources.iter().enumerate().map(|(slot, &r)| (r, slot as u32)).collect();
    let ordered: Vec<&Image> = resources.iter().map(|r| &images[r]).collect();
    let bindless = Bindless::new(device, &ordered, placeholders, slots, shaders.clone())?;
    let command_pools = create_command_pools(device)?;
    let timer_spans: Vec<Vec<Range<usize>>> = segments.iter().map(|s| timer_spans(plan, s, options.timing)).collect();
    let mut state = DeviceState {
        device: device.clone(),
        images,
        buffers,
        image_slots,
        bindless,
        command_pools,
        progress: vk::Semaphore::null(),
        ready: Vec::new(),
        gate: None,
        timers: timer_labels(plan, &segments, &timer_spans),
        timer_spans,
        segments,
        slots: Vec::new(),
        recording_buffers: (0..slots).map(|_| Vec::new()).collect(),
    };
    // A producer of `gpu` links exports its progress timeline to their consumers.
    state.progress = if export_progress { device.create_exportable_timeline()? } else { device.create_timeline(0)? };
    for _ in 0..slots {
        let slot = create_slot_resources(device, &command_pools, &state.segments, state.timers.len())?;
        state.slots.push(slot);
    }
    Ok(state)
}

/// The images of `resources` on device `d`: kept ones taken over, the others created (listed in
/// the second value: they need initialising).
fn take_or_create_images(
    device: &Arc<Device>,
    plan: &ExecutionPlan,
    d: usize,
    resources: &[AllocId],
    kept: &mut Kept,
) -> Result<(HashMap<AllocId, Image>, Vec<AllocId>)> {
    let mut images = HashMap::new();
    let mut fresh = Vec::new();
    for &r in resources {
        let desc = plan.resource(r);
        let image = match kept.images.remove(&(d, desc.clone())) {
            Some(image) => image,
            None => {
                fresh.push(r);
                Image::new(device, &format!("{} view {}", desc.name, desc.view), desc.width, desc.height, desc.format)?
            }
        };
        images.insert(r, image);
    }
    Ok((images, fresh))
}

/// The buffers of `resources` on device `d`: kept ones taken over, the others created (listed in
/// the second value: they need clearing).
fn take_or_create_buffers(
    device: &Arc<Device>,
    plan: &ExecutionPlan,
    d: usize,
    resources: &[AllocId],
    kept: &mut Kept,
) -> Result<(HashMap<AllocId, Buffer>, Vec<AllocId>)> {
    let mut buffers = HashMap::new();
    let mut fresh = Vec::new();
    for &r in resources {
        let desc = plan.resource(r);
        let buffer = match kept.buffers.remove(&(d, desc.clone())) {
            Some(buffer) => buffer,
            None => {
                fresh.push(r);
                Buffer::new(
                    device,
                    &format!("{} view {}", desc.name, desc.view),
                    desc.bytes(),
                    // INDIRECT_BUFFER: passes write dispatch arguments into their own buffers
                    // (Recorder::dispatch_indirect).
                    vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::TRANSFER_SRC
                        | vk::BufferUsageFlags::TRANSFER_DST
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
                        | vk::BufferUsageFlags::INDIRECT_BUFFER,
                    MemoryLocation::GpuOnly,
                )?
            }
        };
        buffers.insert(r, buffer);
    }
    Ok((buffers, fresh))
}

/// One command pool for the main queue and one for the copy queue.
fn create_command_pools(device: &Device) -> Result<[vk::CommandPool; 2]> {
    let mut command_pools = [vk::CommandPool::null(); 2];
    for (pool, kind) in command_pools.iter_mut().zip([QueueKind::Main, QueueKind::Copy]) {
        // Command buffers are recorded again in place when a global buffer moves.
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(device.family_of(kind))
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        *pool = unsafe { device.raw.create_command_pool(&info, None) }.vk("vkCreateCommandPool")?;
    }
    Ok(command_pools)
}

/// One slot's command buffers (one per segment, from its queue's pool) and its query pool of
/// two timestamps per timer (none without timers).
fn create_slot_resources(
    device: &Device,
    command_pools: &[vk::CommandPool; 2],
    segments: &[Segment],
    timers: usize,
) -> Result<SlotResources> {
    let raw = &device.raw;
    let mut command_buffers = Vec::with_capacity(segments.len());
    for segment in segments {
        let pool = command_pools[segment.queue as usize];
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        command_buffers.push(unsafe { raw.allocate_command_buffers(&info) }.vk("vkAllocateCommandBuffers")?[0]);
    }
    let query_pool = if timers == 0 {
        vk::QueryPool::null()
    } else {
        unsafe {
            raw.create_query_pool(
                &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(timers as u32 * 2),
                None,
            )
        }
        .vk("vkCreateQueryPool")?
    };
    Ok(SlotResources { command_buffers, query_pool })
}

/// Resources of the previous plan that the next one may take over, by device and description.
#[derive(Default)]
pub(crate) struct Kept {
    pub(crate) images: HashMap<(usize, ExecResource), Image>,
    pub(crate) buffers: HashMap<(usize, ExecResource), Buffer>,
}

/// Zeroes new buffers, for the same reason images are cleared.
fn clear_buffers<'a>(device: &Device, buffers: impl Iterator<Item = &'a Buffer>) -> Result<()> {
    let buffers: Vec<&Buffer> = buffers.collect();
    if buffers.is_empty() {
        return Ok(());
    }
    let raw = &device.raw;
    device.one_shot(|cb| unsafe {
        for b in &buffers {
            raw.cmd_fill_buffer(cb, b.raw, 0, vk::WHOLE_SIZE, 0);
        }
        crate::record::full_barrier(raw, cb);
    })
}

/// Moves new images to `GENERAL` (their layout for life) and clears them, colour to zero and
/// depth to 1.0 (far), so that a read of a never-written texel is deterministic.
fn initialise_images<'a>(device: &Device, images: impl Iterator<Item = &'a Image>) -> Result<()> {
    let images: Vec<&Image> = images.collect();
    if images.is_empty() {
        return Ok(());
    }
    let raw = &device.raw;
    device.one_shot(|cb| unsafe {
        let to_general: Vec<vk::ImageMemoryBarrier2> = images
            .iter()
            .map(|img| {
                vk::ImageMemoryBarrier2::default()
                    .src_stage_mask(vk::PipelineStageFlags2::NONE)
                    .dst_stage_mask(vk::PipelineStageFlags2::CLEAR)
                    .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                    .old_layout(vk::ImageLayout::UNDEFINED)
                    .new_layout(vk::ImageLayout::GENERAL)
                    .image(img.raw)
                    .subresource_range(img.range())
            })
            .collect();
        raw.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().image_memory_barriers(&to_general));
        for img in &images {
            if img.format.is_depth() {
                let far = vk::ClearDepthStencilValue { depth: 1.0, stencil: 0 };
                raw.cmd_clear_depth_stencil_image(cb, img.raw, vk::ImageLayout::GENERAL, &far, &[img.range()]);
            } else {
                let zero = vk::ClearColorValue::default();
                raw.cmd_clear_color_image(cb, img.raw, vk::ImageLayout::GENERAL, &zero, &[img.range()]);
            }
        }
        crate::record::full_barrier(raw, cb);
    })
}

/// Bytes copy `c` takes in its link's staging: its rows, rounded up so that the next copy
/// starts aligned.
pub(crate) fn staged_bytes(plan: &ExecutionPlan, c: CopyId) -> u64 {
    plan.copy_bytes(c).div_ceil(STAGING_ALIGN) * STAGING_ALIGN
}

/// The staging buffers of `links` (`(from, to, kind)`) for `slots` slots (`rings`: the links
/// whose buffer is a ring, its size and the offsets of its copies); `link_of_copy[c]` is
/// the link copy `c` travels over.
pub(crate) fn create_staging(
    devices: &[Arc<Device>],
    plan: &ExecutionPlan,
    links: &[(usize, usize, LinkKind)],
    link_of_copy: &[usize],
    slots: usize,
    rings: &[RingLayout],
) -> Result<Option<Staging>> {
    if plan.copies.is_empty() {
        return Ok(None);
    }
    let mut sizes = vec![0u64; links.len()];
    // A batch's copies side by side (ExecutionPlan::staging_order): one range per batch.
    let mut places = vec![(0, 0); plan.copies.len()];
    for c in plan.staging_order() {
        let link = link_of_copy[c.index()];
        places[c.index()] = (link, sizes[link]);
        sizes[link] += staged_bytes(plan, c);
    }
    // Links whose staging is a ring (staging_ring.rs): its size, its copies' offsets.
    for ring in rings {
        sizes[ring.link] = ring.size;
        for &(copy, offset) in &ring.offsets {
            places[copy.index()].1 = offset;
        }
    }
    let mut staging = Staging { buffers: Vec::with_capacity(links.len()), places, host_bytes: 0, device_bytes: 0 };
    for (&(from, to, kind), &size) in links.iter().zip(&sizes) {
        // A remote link has one end here (remote.rs).
        let ends: Vec<&Arc<Device>> = [from, to].iter().filter_map(|&d| devices.get(d)).collect();
        let mut per_slot = Vec::with_capacity(slots);
        for _ in 0..slots {
            per_slot.push(match kind {
                LinkKind::Gpu | LinkKind::Shared => {
                    let buffer = SharedDeviceBuffer::new(ends[0], &[ends[1]], size)?;
                    staging.device_bytes += buffer.size;
                    LinkBuffer::Device(buffer)
                }
                LinkKind::Relay | LinkKind::Remote => {
                    let buffer = SharedHostBuffer::new(&ends, size)?;
                    staging.host_bytes += buffer.size;
                    // A remote link's host thread reads and writes the staging itself, with no
                    // flush or invalidation: only coherent memory makes that right.
                    if let Some(device) = buffer.first_incoherent_device().filter(|_| kind == LinkKind::Remote) {
                        let detail = "a remote link's host staging imports here only as memory that is not \
                            host-coherent, and its MPI thread reads and writes that staging directly; under mpirun \
                            use --scheme multi-source (no links between ranks), or a driver that imports host \
                            pointers as HOST_COHERENT memory";
                        return Err(BackendError::HostImport { device, detail: detail.into() });
                    }
                    LinkBuffer::Host(buffer)
                }
            });
        }
        staging.buffers.push(per_slot);
    }
    Ok(Some(staging))
}

/// Sets up [`FaultInjection::DropCrossDeviceWait`] for `copy`.
pub(crate) fn fault_gate(plan: &ExecutionPlan, states: &mut [DeviceState], copy: CopyId) -> Result<FaultGate> {
    let target = plan
        .copies
        .get(copy.index())
        .ok_or_else(|| BackendError::FaultInjection(format!("the plan has no copy {copy}")))?;
    let consumer = &states[target.to.index()];
    let consumer_segment = consumer
        .segments
        .iter()
        .rposition(|s| s.items.iter().any(|i| matches!(i, Item::CopyIn(c) if c.copy == copy)))
        .expect("validated plan: the consumer copies in");
    if consumer.segments[..=consumer_segment].iter().any(|s| !s.waits.is_empty()) {
        return Err(BackendError::FaultInjection(format!(
            "device {} waits for another copy before copy-in {copy}; holding its producer back would deadlock",
            target.to
        )));
    }
    let producer = &mut states[target.from.index()];
    let semaphore = producer.device.create_timeline(0)?;
    producer.gate = Some(semaphore);
    Ok(FaultGate { semaphore, producer: target.from.index(), consumer: target.to.index(), consumer_segment })
}
