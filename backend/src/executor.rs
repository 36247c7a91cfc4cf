//! The executor: turns an [`ExecutionPlan`] into per-device command buffers recorded once, and submits
//! them frame after frame.
//!
//! * Within a device, submissions are ordered by the queue and made memory-safe by barriers;
//!   each submission signals the device's progress timeline (values from
//!   [`crate::segments::progress_value`]).
//! * Across devices, the consumer's copy-in waits on a per-copy "ready" timeline that a host
//!   relay thread signals once the producer's copy-out is done ([`crate::relay`]).
//! * The host submits a frame's segments across the devices in an order where each comes after
//!   every segment it waits for ([`crate::segments::submission_order`]), keeping at most
//!   `max_queued_segments` of a device's segments queued: everything submitted can complete,
//!   so a driver that blocks vkQueueSubmit on a full queue only ever waits for progress.
//! * Up to `frames_in_flight` frames are submitted before the host waits for the oldest; each
//!   frame-in-flight slot has its own command buffers, query pool, descriptor set, per-frame
//!   data and staging memory, so nothing is re-recorded unless the plan changes
//!   ([`Executor::set_plan`]) or a global buffer is reallocated ([`Executor::upload_buffer`]).
//! * Images and buffers live as long as the plan's resources: their contents carry over from
//!   frame to frame (history), and over a plan change for resources that keep their
//!   description; buffers the plan resets are rewritten at the start of every frame.
//! * The frame loop ([`Executor::submit_frame`], [`Executor::wait_readback`]) reads back the
//!   exported resources of each frame without waiting for any later frame (readback.rs).

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::time::Instant;

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::context::Context;
use crate::device::{CalibrationMethod, ClockCalibration, Device, host_now_ns};
use crate::device_state::{DeviceState, Kept, Staging, create_device_state, create_staging, fault_gate};
use crate::error::{BackendError, Result, VkContext};
use crate::frame_data::FrameData;
use crate::instance::Instance;
use crate::memory::Buffer;
use crate::plan::ExecutionPlan;
use crate::readback::{FrameReadback, FrameTicket, Readback};
use crate::record::{SegmentContext, SegmentPlace, record_segment};
use crate::relay::{Relay, RelayJob};
use crate::segments::{
    Chunk, Run, Segment, chunks_of_copies, cross_device_waits, progress_value, ready_value, segment_devices,
    submission_order,
};
use crate::shaders::ShaderLibrary;
use crate::texture::{MAX_TEXTURES, Texture, TextureData};
use crate::timing::{FrameReport, TimedEvent};

/// How long the host waits for a frame before declaring it lost.
const FRAME_TIMEOUT_S: u64 = 60;

/// Deliberate faults, for tests that must show the synchronisation is really needed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultInjection {
    /// The consumer of `copy` does not wait for it. To make the resulting race lose every
    /// time instead of now and then, the producer device is held back (by a host-signalled
    /// semaphore) until the consumer has executed the copy-in; the copy-in then reads the
    /// zero-initialised staging memory. Only possible when nothing the consumer does up to
    /// that copy-in waits for another copy.
    DropCrossDeviceWait { copy: usize },
    /// Submitting frame `frame` fails as on a lost device ([`BackendError::DeviceLost`]) before
    /// its last run of segments, so the rest of its segments are on the queues: what every
    /// caller must end cleanly from (one error, no hang, nothing half-written).
    LoseDevice { frame: u64 },
}

/// Executor settings.
#[derive(Clone, Debug)]
pub struct ExecOptions {
    /// Frames submitted before the host waits for the oldest (at least 1).
    pub frames_in_flight: usize,
    /// Copies larger than this are split into row bands submitted separately, so that the
    /// consumer's upload of one band overlaps the producer's download of the next.
    pub chunk_bytes: u64,
    /// Submit copies to a transfer-only queue (a GPU's copy engines) where the device has one.
    /// Copies then form submissions of their own, ordered against the passes through the
    /// device's progress timeline. On a device without such a queue the same submissions go to
    /// the main queue (which is how lavapipe tests this path). On by default: on two H200s the
    /// copy engines let download and upload overlap (38 GB/s end to end against 23 GB/s on the
    /// main queue, docs/RESULTS.md).
    pub separate_copy_queue: bool,
    /// Capacity of the per-frame data buffer ([`Executor::set_frame_data`]).
    pub frame_data_bytes: u64,
    /// Copy the plan's exported resources to host memory at the end of every frame, for
    /// [`Executor::submit_frame`]. Off by default: it costs a host-visible copy of every export
    /// per frame in flight and a device→host copy per frame, which callers that read results
    /// once with [`Executor::read_image`] do not need.
    pub read_back_exports: bool,
    pub fault: Option<FaultInjection>,
    /// SPIR-V of kernels outside this repository, by the name they dispatch; looked up before
    /// the built-in shaders of `shaders/`.
    pub shaders: ShaderLibrary,
    /// Most segments (submissions) of one device the host keeps submitted and not yet done; the
    /// host waits for the device before submitting more (at least 1). Drivers hold a bounded
    /// number of pending submissions and block vkQueueSubmit beyond it; the fine schemes cut a
    /// frame into thousands of segments per device.
    pub max_queued_segments: usize,
    /// Where the recorded command buffers put barriers between ops.
    pub barriers: Barriers,
    /// What each GPU timestamp pair covers.
    pub timing: Timing,
}

/// Where barriers go between the ops of a device (record.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Barriers {
    /// Before every op: always right, and what synchronisation validation can check.
    #[default]
    EveryOp,
    /// Before an op only where its declared accesses conflict with an op since the last
    /// barrier, so instances of one pass for many views overlap on the GPU. Synchronisation
    /// validation reports false hazards here: it takes every dispatch to touch the whole
    /// bindless image array.
    Tracked,
}

/// What the GPU timestamp pairs of a frame cover (record.rs). A timestamp waits for every
/// earlier command of its queue to finish (NVIDIA drains the queue for one), so timing every op
/// serialises ops that `Barriers::Tracked` would let overlap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Timing {
    /// One pair around every op: per-view figures and timelines, at the price of the overlap.
    /// Instances a kernel records as one group (`PassKernel::record_group`) are one op, timed
    /// together; the event carries the first one's view and index.
    #[default]
    PerOp,
    /// One pair around each run of consecutive instances of one pass on a queue (and around
    /// every copy): per-stage figures, and the instances of a stage overlap under tracked
    /// barriers. An event then stands for the run: its `view` and `index` are its first op's.
    PerStage,
}

impl Default for ExecOptions {
    fn default() -> Self {
        Self {
            frames_in_flight: 2,
            chunk_bytes: 8 << 20,
            separate_copy_queue: true,
            frame_data_bytes: 64 << 10,
            read_back_exports: false,
            fault: None,
            shaders: ShaderLibrary::default(),
            max_queued_segments: 256,
            barriers: Barriers::EveryOp,
            timing: Timing::PerOp,
        }
    }
}

/// Fault-injection gate: producer's first submission of a frame waits until the consumer's
/// segment `consumer_segment` of the same frame is done.
pub(crate) struct FaultGate {
    /// Semaphore on the producer device.
    pub(crate) semaphore: vk::Semaphore,
    pub(crate) producer: usize,
    pub(crate) consumer: usize,
    pub(crate) consumer_segment: usize,
}

/// What one segment's `VkSubmitInfo2` points at.
struct SegmentSubmit {
    waits: Vec<vk::SemaphoreSubmitInfo<'static>>,
    signal: [vk::SemaphoreSubmitInfo<'static>; 1],
    command_buffer: [vk::CommandBufferSubmitInfo<'static>; 1],
}

struct InFlight {
    frame: u64,
    /// Frame index relative to the current plan (timeline values restart with each plan).
    local: u64,
    slot: usize,
    submit_start_ns: u64,
    submit_cpu_ns: u64,
    /// Host time its submission waited for the frame it reuses the slot of to retire.
    slot_wait_ns: u64,
    passes: usize,
    segments: usize,
    /// Submitted by `submit_frame`: its readback is kept when it retires.
    read_back: bool,
}

/// Executes an [`ExecutionPlan`] on the devices of a [`Context`].
pub struct Executor {
    instance: Arc<Instance>,
    devices: Vec<Arc<Device>>,
    plan: ExecutionPlan,
    options: ExecOptions,
    chunks: Vec<Vec<Chunk>>,
    states: Vec<DeviceState>,
    /// Ready timeline of each copy (owned by the consumer's state).
    ready: Vec<vk::Semaphore>,
    staging: Option<Staging>,
    relay: Option<Relay>,
    gate: Option<FaultGate>,
    /// The order every frame's segments are submitted in (`segments::submission_order`).
    submission_order: Vec<Run>,
    /// A frame's submission failed part-way: frame `next_frame` is partly on the queues.
    cut_short: bool,
    next_frame: u64,
    /// First frame of the current plan.
    plan_epoch: u64,
    /// First frame whose history reads are not last frame's output (plan start, reset): history
    /// is valid from the frame after it.
    history_origin: u64,
    in_flight: VecDeque<InFlight>,
    reports: Vec<FrameReport>,
    calibration: Vec<ClockCalibration>,
    recordings: u64,
    last_record_ns: u64,
    /// Command buffers must be (re-)recorded before the next frame: after a plan change or a
    /// global buffer that moved.
    needs_record: bool,
    /// Global buffers per device, by name; they outlive plan changes.
    globals: Vec<HashMap<String, Buffer>>,
    /// Sampled textures per device (the `textures[]` array); they outlive plan changes.
    textures: Vec<Vec<Texture>>,
    /// Per frame-in-flight slot and device: host-visible copy of the per-frame data.
    frame_data_buffers: Vec<Vec<Buffer>>,
    frame_data: FrameData,
    /// With `ExecOptions::read_back_exports`.
    readback: Option<Readback>,
}

impl Executor {
    /// Validates `plan` and allocates its resources. Command buffers are recorded at the first
    /// frame (so global buffers can be uploaded first) and then reused.
    pub fn new(context: &Context, plan: ExecutionPlan, options: ExecOptions) -> Result<Self> {
        let calibration = context.devices.iter().map(|d| d.clock_offset()).collect::<Result<Vec<_>>>()?;
        let mut executor = Self {
            instance: context.instance.clone(),
            devices: context.devices.clone(),
            plan: ExecutionPlan::default(),
            options: ExecOptions { frames_in_flight: options.frames_in_flight.max(1), ..options },
            chunks: Vec::new(),
            states: Vec::new(),
            ready: Vec::new(),
            staging: None,
            relay: None,
            gate: None,
            submission_order: Vec::new(),
            cut_short: false,
            next_frame: 0,
            plan_epoch: 0,
            history_origin: 0,
            in_flight: VecDeque::new(),
            reports: Vec::new(),
            calibration,
            recordings: 0,
            last_record_ns: 0,
            needs_record: true,
            globals: context.devices.iter().map(|_| HashMap::new()).collect(),
            textures: context.devices.iter().map(|_| Vec::new()).collect(),
            frame_data_buffers: Vec::new(),
            frame_data: FrameData::new(),
            readback: options.read_back_exports.then(Readback::new),
        };
        executor.frame_data_buffers = (0..executor.slot_count())
            .map(|_| {
                executor
                    .devices
                    .iter()
                    .map(|d| {
                        Buffer::new(
                            d,
                            "frame data",
                            executor.options.frame_data_bytes.max(16),
                            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                            MemoryLocation::CpuToGpu,
                        )
                    })
                    .collect::<Result<Vec<_>>>()
            })
            .collect::<Result<Vec<_>>>()?;
        executor.build(plan)?;
        Ok(executor)
    }

    /// Replaces the plan. Returns `false` (and re-records nothing) when `plan` equals the
    /// current one; otherwise waits for all frames, keeps the images whose resource description
    /// is unchanged (their contents survive), and records everything anew at the next frame.
    pub fn set_plan(&mut self, plan: ExecutionPlan) -> Result<bool> {
        if plan == self.plan {
            return Ok(false);
        }
        self.finish()?;
        self.build(plan)?;
        Ok(true)
    }

    fn build(&mut self, plan: ExecutionPlan) -> Result<()> {
        plan.validate(self.devices.len())?;
        // Threads first (they use the old semaphores), then the old states.
        self.relay = None;
        let mut kept = Kept::default();
        for (d, mut state) in std::mem::take(&mut self.states).into_iter().enumerate() {
            for (resource, image) in state.images.drain() {
                kept.images.insert((d, self.plan.resources[resource].clone()), image);
            }
            for (resource, buffer) in state.buffers.drain() {
                kept.buffers.insert((d, self.plan.resources[resource].clone()), buffer);
            }
        }
        self.staging = None;

        let chunks = chunks_of_copies(&plan, self.options.chunk_bytes);
        let slots = self.slot_count();
        let dropped_wait = match self.options.fault {
            Some(FaultInjection::DropCrossDeviceWait { copy }) => Some(copy),
            _ => None,
        };
        let mut states = Vec::with_capacity(self.devices.len());
        let cut =
            segment_devices(&plan, &chunks, self.options.chunk_bytes, dropped_wait, self.options.separate_copy_queue);
        for ((d, device), segments) in self.devices.iter().enumerate().zip(cut) {
            let state = create_device_state(device, &plan, d, segments, slots, &self.options, &mut kept)?;
            let views: Vec<vk::ImageView> = self.textures[d].iter().map(Texture::view).collect();
            state.bindless.set_textures(&views);
            states.push(state);
        }
        drop(kept);
        let mut ready = Vec::with_capacity(plan.copies.len());
        for (c, copy) in plan.copies.iter().enumerate() {
            let consumer = &mut states[copy.to];
            let semaphore = consumer.device.create_timeline(0)?;
            consumer.ready.insert(c, semaphore);
            ready.push(semaphore);
        }
        self.gate = match self.options.fault {
            Some(FaultInjection::DropCrossDeviceWait { copy }) => Some(fault_gate(&plan, &mut states, copy)?),
            _ => None,
        };
        let segments: Vec<Vec<Segment>> = states.iter().map(|s| s.segments.clone()).collect();
        let mut waits = cross_device_waits(&segments);
        if let Some(gate) = &self.gate {
            // The producer's first segment waits for the consumer's gate segment.
            waits[gate.producer][0].push((gate.consumer, gate.consumer_segment));
        }
        self.submission_order =
            submission_order(&waits).ok_or(BackendError::ExecutionPlan(crate::plan::ExecutionPlanError::WaitCycle))?;
        self.staging = create_staging(&self.devices, &plan, slots)?;
        if let Some(readback) = &mut self.readback {
            readback.allocate(&self.devices[0], &plan, slots)?;
        }
        self.plan = plan;
        self.chunks = chunks;
        self.states = states;
        self.ready = ready;
        self.needs_record = true;
        let progress: Vec<vk::Semaphore> = self.states.iter().map(|s| s.progress).collect();
        self.relay = Some(Relay::new(&self.devices, &progress));
        self.plan_epoch = self.next_frame;
        self.history_origin = self.next_frame;
        Ok(())
    }

    /// Recorded frame slots: frames in flight rounded up to even, so a slot's frame parity never
    /// changes and history pairs can be swapped in the recording (see `ExecutionPlan::history_pairs`).
    fn slot_count(&self) -> usize {
        self.options.frames_in_flight.div_ceil(2) * 2
    }

    /// Marks history invalid for the next frame (a camera cut, a teleport): its kernels see
    /// `history_valid = 0` and must not blend in what their history reads return.
    pub fn reset_history(&mut self) {
        self.history_origin = self.next_frame;
    }

    fn record_all(&mut self) -> Result<()> {
        let started = Instant::now();
        let plan = &self.plan;
        let parity_maps = [plan.parity_map(0), plan.parity_map(1)];
        let addresses: Vec<HashMap<String, (u64, u64)>> = self
            .globals
            .iter()
            .map(|g| g.iter().map(|(name, b)| (name.clone(), (b.device_address(), b.size))).collect())
            .collect();
        for (d, state) in self.states.iter_mut().enumerate() {
            let buffer_addresses: HashMap<usize, u64> =
                state.buffers.iter().map(|(&r, b)| (r, b.device_address())).collect();
            for slot in 0..state.slots.len() {
                // Recording happens with no frame in flight (every cause of it waits for the
                // frames first), so the buffers of the last recording are free.
                state.recording_buffers[slot].clear();
                let readback = match &self.readback {
                    Some(readback) if d == 0 => readback.targets(slot),
                    _ => Vec::new(),
                };
                let staging =
                    self.staging.as_ref().and_then(|s| s.buffers[slot].buffer_on(d).map(|b| (b, s.offsets.as_slice())));
                let mut ctx = SegmentContext {
                    barriers: self.options.barriers,
                    raw: &state.device.raw,
                    device_index: d,
                    plan,
                    parity_map: &parity_maps[slot % 2],
                    bindless: &mut state.bindless,
                    images: &state.images,
                    image_slots: &state.image_slots,
                    slot,
                    query_pool: state.slots[slot].query_pool,
                    staging,
                    global_buffers: &addresses[d],
                    buffers: &state.buffers,
                    buffer_addresses: &buffer_addresses,
                    frame_data_address: self.frame_data_buffers[slot][d].device_address(),
                    frame_sections: self.frame_data.sections(),
                    readback: &readback,
                    device: &state.device,
                    recording_buffers: &mut state.recording_buffers[slot],
                };
                let mut first_timer = 0u32;
                let segment_count = state.segments.len();
                for (j, segment) in state.segments.iter().enumerate() {
                    let cb = state.slots[slot].command_buffers[j];
                    let place = SegmentPlace { first: j == 0, last: j + 1 == segment_count };
                    let spans = &state.timer_spans[j];
                    record_segment(&mut ctx, cb, segment, first_timer, spans, place)?;
                    first_timer += spans.len() as u32;
                }
            }
        }
        self.recordings += 1;
        self.last_record_ns = started.elapsed().as_nanos() as u64;
        self.needs_record = false;
        Ok(())
    }

    /// Uploads `bytes` as the global buffer `name` on every device (scene data: BVH nodes,
    /// triangles, materials, ...), reachable from kernels through
    /// `Recorder::buffer_address(name)`. Waits for all frames in flight. Re-uploading the same
    /// size keeps the buffer (and the recorded command buffers); another size replaces it and
    /// the command buffers are recorded again before the next frame.
    pub fn upload_buffer(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        self.finish()?;
        let size = (bytes.len() as u64).max(4);
        for (d, device) in self.devices.iter().enumerate() {
            let keep = self.globals[d].get(name).is_some_and(|b| b.size == size);
            if !keep {
                let buffer = Buffer::new(
                    device,
                    name,
                    size,
                    vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::TRANSFER_DST
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                    MemoryLocation::GpuOnly,
                )?;
                self.globals[d].insert(name.to_string(), buffer);
                self.needs_record = true;
            }
            let staging = Buffer::staging(device, "upload staging", bytes)?;
            let target = self.globals[d][name].raw;
            let raw = &device.raw;
            device.one_shot(|cb| unsafe {
                crate::record::full_barrier(raw, cb);
                raw.cmd_copy_buffer(cb, staging.raw, target, &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size }]);
                crate::record::full_barrier(raw, cb);
            })?;
        }
        Ok(())
    }

    /// Uploads `textures` on every device as the sampled-texture array every kernel sees
    /// (`textures[i]` in shaders/include/bindless.glsl), replacing earlier ones. Waits for all
    /// frames in flight; command buffers are recorded again before the next frame.
    pub fn upload_textures(&mut self, textures: &[TextureData<'_>]) -> Result<()> {
        if textures.len() > MAX_TEXTURES as usize {
            return Err(BackendError::TooManyTextures { count: textures.len(), max: MAX_TEXTURES });
        }
        self.finish()?;
        for (d, device) in self.devices.iter().enumerate() {
            let uploaded = textures
                .iter()
                .enumerate()
                .map(|(i, t)| Texture::new(device, &format!("texture {i}"), t))
                .collect::<Result<Vec<_>>>()?;
            let views: Vec<vk::ImageView> = uploaded.iter().map(Texture::view).collect();
            // No frame is in flight (finish above), so the descriptor sets can change; the old
            // textures go only after the sets no longer name them.
            self.states[d].bindless.set_textures(&views);
            self.textures[d] = uploaded;
        }
        self.needs_record = true;
        Ok(())
    }

    /// Sets the per-frame data (camera matrices, sample counters, ...) that every following
    /// frame's kernels read at `Recorder::frame_data_address()`; copied into the frame's slot at
    /// each `run_frame`, so recorded command buffers stay valid. The same as
    /// `set_frame(&FrameData::whole(bytes))`.
    pub fn set_frame_data(&mut self, bytes: &[u8]) -> Result<()> {
        self.set_frame(&FrameData::whole(bytes))
    }

    /// Sets the per-frame data of every following frame, sections included (kernels find them
    /// at `Recorder::frame_section_address`). The same sections at the same offsets as before
    /// only change bytes; another layout waits for the frames in flight and has the command
    /// buffers recorded again before the next frame.
    pub fn set_frame(&mut self, data: &FrameData) -> Result<()> {
        let bytes = data.bytes().len();
        if bytes as u64 > self.options.frame_data_bytes {
            return Err(BackendError::FrameDataTooLarge { bytes, capacity: self.options.frame_data_bytes });
        }
        if data.sections() != self.frame_data.sections() {
            self.finish()?;
            self.needs_record = true;
        }
        self.frame_data.clone_from(data);
        Ok(())
    }

    /// Submits one frame; returns its index. Waits only if `frames_in_flight` frames are
    /// already in flight (for the oldest of them).
    pub fn run_frame(&mut self) -> Result<u64> {
        self.submit(false)
    }

    /// Submits one frame like [`Self::run_frame`]; its exported resources (`ExecResource::exported`)
    /// can then be waited for with [`Self::wait_readback`]. Needs
    /// `ExecOptions::read_back_exports`.
    pub fn submit_frame(&mut self) -> Result<FrameTicket> {
        if self.readback.is_none() {
            return Err(BackendError::ReadbackDisabled);
        }
        Ok(FrameTicket { frame: self.submit(true)? })
    }

    /// Waits for the frame of `ticket` (and so for the frames submitted before it, which finish
    /// first) — not for later frames — and returns its exported resources.
    pub fn wait_readback(&mut self, ticket: FrameTicket) -> Result<FrameReadback> {
        while self.in_flight.front().is_some_and(|f| f.frame <= ticket.frame) {
            self.retire_oldest()?;
        }
        self.readback
            .as_mut()
            .and_then(|r| r.take(ticket.frame))
            .ok_or(BackendError::ReadbackUnavailable { frame: ticket.frame })
    }

    fn submit(&mut self, read_back: bool) -> Result<u64> {
        if self.cut_short {
            return Err(BackendError::SubmissionCutShort { frame: self.next_frame });
        }
        let slot_wait = Instant::now();
        if self.in_flight.len() >= self.options.frames_in_flight {
            self.retire_oldest()?;
        }
        let slot_wait_ns = slot_wait.elapsed().as_nanos() as u64;
        self.relay.as_ref().expect("relay exists after build").check()?;
        if self.needs_record {
            self.record_all()?;
        }
        let submit_start_ns = host_now_ns();
        let cpu_start = Instant::now();
        let frame = self.next_frame;
        let local = frame - self.plan_epoch;
        let slot = (frame % self.slot_count() as u64) as usize;
        let history_valid = frame > self.history_origin;
        for state in &mut self.states {
            state.bindless.set_frame_constants(slot, frame, history_valid);
        }
        let frame_bytes = self.frame_data.bytes();
        if !frame_bytes.is_empty() {
            for buffer in &mut self.frame_data_buffers[slot] {
                buffer.mapped_mut().expect("CpuToGpu buffers are mapped")[..frame_bytes.len()]
                    .copy_from_slice(frame_bytes);
            }
        }
        // The slot's previous frame has retired: its queries were read and can be reset.
        for state in &self.states {
            if !state.timers.is_empty() {
                unsafe {
                    state.device.raw.reset_query_pool(state.slots[slot].query_pool, 0, state.timers.len() as u32 * 2)
                };
            }
        }
        let mut submitted_segments = 0;
        // Until the whole frame is submitted, a failure leaves its first segments on the queues,
        // waiting for signals of segments that never come (see `Drop`).
        self.cut_short = true;
        for (i, run) in self.submission_order.iter().enumerate() {
            if self.options.fault == Some(FaultInjection::LoseDevice { frame }) && i + 1 == self.submission_order.len()
            {
                return Err(BackendError::DeviceLost { call: "vkQueueSubmit2 (FaultInjection::LoseDevice)" });
            }
            self.submit_run(run, frame, local, slot)?;
            submitted_segments += run.segments.len();
        }
        self.cut_short = false;
        self.in_flight.push_back(InFlight {
            frame,
            local,
            slot,
            submit_start_ns,
            submit_cpu_ns: cpu_start.elapsed().as_nanos() as u64,
            slot_wait_ns,
            passes: self.plan.passes.len(),
            segments: submitted_segments,
            read_back,
        });
        self.next_frame += 1;
        Ok(frame)
    }

    /// Submits the segments of `run` of frame `frame` (`local` to the plan): one vkQueueSubmit2
    /// per stretch on one queue, with at most `max_queued_segments` of the device's segments
    /// submitted and not yet done; then queues the relay jobs of the copy-outs among them.
    fn submit_run(&self, run: &Run, frame: u64, local: u64, slot: usize) -> Result<()> {
        let d = run.device;
        let state = &self.states[d];
        let segment_count = state.segments.len();
        let window = self.options.max_queued_segments.max(1);
        let mut start = run.segments.start;
        while start < run.segments.end {
            let queue = state.segments[start].queue;
            let limit = run.segments.end.min(start + window);
            let end = (start..limit).find(|&j| state.segments[j].queue != queue).unwrap_or(limit);
            // Everything this waits for is submitted already (`submission_order`), so it ends.
            let last = progress_value(local, segment_count, end - 1);
            if let Some(done) = last.checked_sub(window as u64).filter(|&v| v > 0) {
                self.wait_for_progress(d, done, frame)?;
            }
            let infos: Vec<SegmentSubmit> = (start..end).map(|j| self.segment_submit(d, j, local, slot)).collect();
            let submits: Vec<vk::SubmitInfo2> = infos
                .iter()
                .map(|i| {
                    vk::SubmitInfo2::default()
                        .wait_semaphore_infos(&i.waits)
                        .command_buffer_infos(&i.command_buffer)
                        .signal_semaphore_infos(&i.signal)
                })
                .collect();
            state.device.submit_to(queue, &submits, vk::Fence::null())?;
            start = end;
        }
        self.queue_relays(run, local)
    }

    /// The waits, command buffer and progress signal of segment `j` of device `d`.
    fn segment_submit(&self, d: usize, j: usize, local: u64, slot: usize) -> SegmentSubmit {
        let state = &self.states[d];
        let segment = &state.segments[j];
        let segment_count = state.segments.len();
        let on = |semaphore: vk::Semaphore, value: u64| {
            vk::SemaphoreSubmitInfo::default()
                .semaphore(semaphore)
                .value(value)
                .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        };
        let mut waits: Vec<vk::SemaphoreSubmitInfo<'static>> = segment
            .waits
            .iter()
            .map(|wait| on(self.ready[wait.copy], ready_value(local, self.chunks[wait.copy].len(), wait.chunk)))
            .collect();
        // A segment on another queue than its predecessor (in program order, across the frame
        // boundary too) waits for it: the two queues run one program.
        let previous = match j {
            0 if local > 0 => Some((segment_count - 1, local - 1)),
            0 => None,
            _ => Some((j - 1, local)),
        };
        if let Some((p, p_frame)) = previous
            && state.segments[p].queue != segment.queue
        {
            waits.push(on(state.progress, progress_value(p_frame, segment_count, p)));
        }
        if let (Some(gate), 0) = (state.gate, j) {
            waits.push(on(gate, local + 1));
        }
        SegmentSubmit {
            waits,
            signal: [on(state.progress, progress_value(local, segment_count, j))],
            command_buffer: [
                vk::CommandBufferSubmitInfo::default().command_buffer(state.slots[slot].command_buffers[j])
            ],
        }
    }

    /// Relay jobs of the copy-outs in `run`, in segment order (see relay.rs).
    fn queue_relays(&self, run: &Run, local: u64) -> Result<()> {
        let relay = self.relay.as_ref().expect("relay exists after build");
        let d = run.device;
        let segment_count = self.states[d].segments.len();
        for j in run.segments.clone() {
            let watch_value = progress_value(local, segment_count, j);
            for chunk in &self.states[d].segments[j].relays {
                let consumer = self.plan.copies[chunk.copy].to;
                relay.push(
                    d,
                    RelayJob {
                        watch_value,
                        target: self.devices[consumer].clone(),
                        semaphore: self.ready[chunk.copy],
                        signal_value: ready_value(local, self.chunks[chunk.copy].len(), chunk.index),
                    },
                )?;
            }
            if let Some(gate) = &self.gate
                && gate.consumer == d
                && gate.consumer_segment == j
            {
                relay.push(
                    d,
                    RelayJob {
                        watch_value,
                        target: self.devices[gate.producer].clone(),
                        semaphore: gate.semaphore,
                        signal_value: local + 1,
                    },
                )?;
            }
        }
        Ok(())
    }

    /// Waits until device `d`'s progress timeline reaches `value`, in short steps so that a
    /// failed relay thread is reported instead of hanging, and at most `FRAME_TIMEOUT_S`.
    fn wait_for_progress(&self, d: usize, value: u64, frame: u64) -> Result<()> {
        let state = &self.states[d];
        let deadline = Instant::now() + std::time::Duration::from_secs(FRAME_TIMEOUT_S);
        while !state.device.wait_timeline(state.progress, value, 100_000_000)? {
            self.relay.as_ref().map_or(Ok(()), Relay::check)?;
            if Instant::now() > deadline {
                return Err(BackendError::FrameTimeout { frame, device: d, seconds: FRAME_TIMEOUT_S });
            }
        }
        Ok(())
    }

    /// Waits for the oldest frame in flight and turns its timestamps into a report.
    fn retire_oldest(&mut self) -> Result<()> {
        let Some(f) = self.in_flight.pop_front() else {
            return Ok(());
        };
        let mut events = Vec::new();
        for (d, state) in self.states.iter().enumerate() {
            let segment_count = state.segments.len();
            if segment_count == 0 {
                continue;
            }
            self.wait_for_progress(d, progress_value(f.local, segment_count, segment_count - 1), f.frame)?;
            let timers = state.timers.len();
            if timers == 0 {
                continue;
            }
            let mut ticks = vec![0u64; timers * 2];
            unsafe {
                state.device.raw.get_query_pool_results(
                    state.slots[f.slot].query_pool,
                    0,
                    &mut ticks,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .vk("vkGetQueryPoolResults")?;
            // Calibrated timestamps are cheap: re-sample so that clock drift never accumulates.
            if self.calibration[d].method == CalibrationMethod::CalibratedTimestamps {
                self.calibration[d] = state.device.clock_offset()?;
            }
            let calibration = self.calibration[d];
            for (t, label) in state.timers.iter().enumerate() {
                let to_host = |ticks: u64| state.device.timestamp_to_host_ns(ticks, label.queue, &calibration);
                events.push(TimedEvent {
                    name: label.name.clone(),
                    kind: label.kind,
                    device: d,
                    view: label.view,
                    index: label.index,
                    chunk: label.chunk,
                    bytes: label.bytes,
                    gather: label.gather,
                    start_ns: to_host(ticks[2 * t]),
                    end_ns: to_host(ticks[2 * t + 1]),
                });
            }
        }
        let mut report = FrameReport::new(
            f.frame,
            f.submit_start_ns,
            f.submit_cpu_ns,
            f.passes,
            f.segments,
            self.devices.len(),
            events,
        );
        report.slot_wait_ns = f.slot_wait_ns;
        self.reports.push(report);
        if let (true, Some(readback)) = (f.read_back, &mut self.readback) {
            readback.retire(f.frame, f.slot);
        }
        Ok(())
    }

    /// After a failure (a relay thread died, a frame timed out), submissions may wait on values
    /// nobody will signal, and waiting for the devices to go idle would hang. Signals every
    /// cross-device semaphore to the last value any submitted frame waits for, so the queues
    /// drain (with meaningless contents) and teardown can proceed. That includes the frame
    /// `next_frame`, whose submission the failure may have cut short: its first segments can
    /// be on the queues already.
    fn unblock_device_waits(&mut self) {
        self.relay = None;
        let local = self.next_frame.saturating_sub(self.plan_epoch);
        for (c, copy) in self.plan.copies.iter().enumerate() {
            let chunks = self.chunks[c].len();
            let value = ready_value(local, chunks, chunks.saturating_sub(1) as u32);
            raise_timeline(&self.devices[copy.to], self.ready[c], value);
        }
        if let Some(gate) = &self.gate {
            raise_timeline(&self.devices[gate.producer], gate.semaphore, local + 1);
        }
        self.in_flight.clear();
    }

    /// Waits for every frame in flight (their reports become available).
    pub fn finish(&mut self) -> Result<()> {
        while !self.in_flight.is_empty() {
            self.retire_oldest()?;
        }
        Ok(())
    }

    /// Reports of retired frames, oldest first, removed from the executor. They pile up until
    /// taken: a long frame loop takes them every frame and folds them into a
    /// [`crate::FrameStats`], so its memory stays flat.
    pub fn take_reports(&mut self) -> Vec<FrameReport> {
        std::mem::take(&mut self.reports)
    }

    /// Reports of retired frames so far.
    pub fn reports(&self) -> &[FrameReport] {
        &self.reports
    }

    /// How many times the command buffers were recorded (once per plan).
    pub fn recordings(&self) -> u64 {
        self.recordings
    }

    /// CPU time of the last recording of all command buffers (every slot), in ns.
    pub fn last_record_ns(&self) -> u64 {
        self.last_record_ns
    }

    /// The plan being executed.
    pub fn plan(&self) -> &ExecutionPlan {
        &self.plan
    }

    /// Clock calibration of each device (GPU → host CLOCK_MONOTONIC).
    pub fn calibration(&self) -> &[ClockCalibration] {
        &self.calibration
    }

    /// Fails if the validation layer reported anything since the last check.
    pub fn check_validation(&self) -> Result<()> {
        self.instance.check_validation()
    }

    /// Reads `resource` back from `device` as tightly packed rows (waits for all frames).
    pub fn read_image(&mut self, device: usize, resource: usize) -> Result<Vec<u8>> {
        self.read_resource(device, resource)
    }

    /// Reads an image (tightly packed rows) or a buffer back from `device` (waits for all
    /// frames).
    pub fn read_resource(&mut self, device: usize, resource: usize) -> Result<Vec<u8>> {
        self.finish()?;
        // A history allocation's halves swap by frame parity: read the half the last frame
        // wrote in `resource`'s place (and its other half for the pair's other member).
        let last_parity = self.next_frame.saturating_sub(1) % 2;
        let resource = self.plan.parity_map(last_parity as usize).get(&resource).copied().unwrap_or(resource);
        let state = &self.states[device];
        let image = state.images.get(&resource);
        let buffer = state.buffers.get(&resource);
        if image.is_none() && buffer.is_none() {
            return Err(BackendError::ResourceNotOnDevice { resource, device });
        }
        let size = self.plan.resources[resource].bytes();
        let readback =
            Buffer::new(&state.device, "readback", size, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)?;
        let raw = &state.device.raw;
        state.device.one_shot(|cb| unsafe {
            crate::record::full_barrier(raw, cb);
            if let Some(image) = image {
                let region = vk::BufferImageCopy::default()
                    .image_subresource(image.layers())
                    .image_extent(vk::Extent3D { width: image.width, height: image.height, depth: 1 });
                raw.cmd_copy_image_to_buffer(cb, image.raw, vk::ImageLayout::GENERAL, readback.raw, &[region]);
            } else if let Some(buffer) = buffer {
                raw.cmd_copy_buffer(
                    cb,
                    buffer.raw,
                    readback.raw,
                    &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size }],
                );
            }
            let to_host = [vk::MemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::COPY)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::HOST)
                .dst_access_mask(vk::AccessFlags2::HOST_READ)];
            raw.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&to_host));
        })?;
        Ok(readback.mapped().expect("GpuToCpu buffers are mapped").to_vec())
    }
}

impl Drop for Executor {
    fn drop(&mut self) {
        // Frames in flight must end before their memory and semaphores go; relay threads
        // before the semaphores they wait on.
        if self.finish().is_err() || self.cut_short {
            self.unblock_device_waits();
        }
        for device in &self.devices {
            let _ = device.wait_idle();
        }
        self.relay = None;
        self.staging = None;
        self.states.clear();
        self.globals.clear();
        self.textures.clear();
        self.frame_data_buffers.clear();
    }
}

/// Host-signals `semaphore` to `value` unless it is already there (a timeline never goes back).
/// Errors are ignored: this only runs while tearing down after a failure.
fn raise_timeline(device: &Device, semaphore: vk::Semaphore, value: u64) {
    if device.timeline_value(semaphore).is_ok_and(|current| current < value) {
        let _ = device.signal_timeline(semaphore, value);
    }
}
