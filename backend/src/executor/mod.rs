//! The executor: turns a [`KernelPlan`] into per-device command buffers recorded once, and submits
//! them frame after frame.
//!
//! * Within a device, submissions are ordered by the queue and made memory-safe by barriers;
//!   each submission signals the device's progress timeline (values from
//!   [`crate::segments::progress_value`]).
//! * Across devices, the consumer's copy-in waits on its link (one per producer and consumer
//!   device, [`crate::links`]): on the producer's progress timeline imported into the consumer
//!   (`gpu` links), or on a "ready" timeline that a host relay thread raises once the producer's
//!   copy-out is done ([`crate::relay`]).
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
//!
//! Rooms: `options` (settings), `build` (state for a plan), `record` (command buffers),
//! `upload` (global buffers, textures, per-frame data), `submit` (a frame's segments),
//! `retire` (waiting, reports), `read` (reading a resource back), `teardown` (drop, recovery).

mod build;
mod read;
mod record;
mod retire;
mod submit;
mod teardown;
mod upload;

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::context::Context;
use crate::device::{ClockCalibration, Device};
use crate::device_state::{DeviceState, FaultGate, Staging};
use crate::error::Result;
use crate::exec_options::ExecOptions;
use crate::frame_data::FrameData;
use crate::instance::Instance;
use crate::kernel::KernelPlan;
use crate::links::{ChunkLink, DeviceSubmissions, Link, LinkInfo, LinkKinds, link_kinds};
use crate::memory::Buffer;
use crate::readback::Readback;
use crate::relay::Relay;
use crate::remote::Remote;
use crate::segments::{Chunk, Run};
use crate::texture::Texture;
use crate::timing::FrameReport;

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

/// Executes a [`KernelPlan`] on the devices of a [`Context`].
pub struct Executor {
    instance: Arc<Instance>,
    devices: Vec<Arc<Device>>,
    /// Shared, not copied: the caller that compiled it (or a rank that cut it) keeps a handle.
    plan: Arc<KernelPlan>,
    options: ExecOptions,
    chunks: Vec<Vec<Chunk>>,
    states: Vec<DeviceState>,
    /// The plan's links (their ready timelines are owned by the consumer's state).
    links: Vec<Link>,
    /// Per copy and chunk: its link, position among the link's chunks, producer segment.
    chunk_links: Vec<Vec<ChunkLink>>,
    /// The kind of link between every two devices, chosen at creation.
    link_kinds: LinkKinds,
    staging: Option<Staging>,
    relay: Option<Relay>,
    /// Links to and from other processes' devices (remote.rs).
    remote: Option<Remote>,
    gate: Option<FaultGate>,
    /// The order every frame's segments are submitted in (`segments::submission_order`, with
    /// the space waits of staging rings).
    submission_order: Vec<Run>,
    /// `[device][segment]`: the space waits of its copy-outs and the space signals of its
    /// copy-ins, as (link, value within the frame): staging_ring.rs.
    space_waits: Vec<Vec<Vec<(usize, u64)>>>,
    space_signals: Vec<Vec<Vec<(usize, u64)>>>,
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
    /// When the host saw the executor's first frame done (host CLOCK_MONOTONIC ns).
    first_frame_done_ns: Option<u64>,
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
    /// Chooses the links between devices (refusing a requested kind some pair cannot use),
    /// validates `plan` and allocates its resources. Command buffers are recorded at the first
    /// frame (so global buffers can be uploaded first) and then reused.
    pub fn new(context: &Context, plan: impl Into<Arc<KernelPlan>>, options: ExecOptions) -> Result<Self> {
        let link_kinds = link_kinds(&context.devices, options.link)?;
        let calibration = context.devices.iter().map(|d| d.clock_offset()).collect::<Result<Vec<_>>>()?;
        let mut executor = Self {
            instance: context.instance.clone(),
            devices: context.devices.clone(),
            plan: Arc::default(),
            options: ExecOptions { frames_in_flight: options.frames_in_flight.max(1), ..options },
            chunks: Vec::new(),
            states: Vec::new(),
            links: Vec::new(),
            chunk_links: Vec::new(),
            link_kinds,
            staging: None,
            relay: None,
            remote: None,
            gate: None,
            submission_order: Vec::new(),
            space_waits: Vec::new(),
            space_signals: Vec::new(),
            cut_short: false,
            next_frame: 0,
            plan_epoch: 0,
            history_origin: 0,
            in_flight: VecDeque::new(),
            reports: Vec::new(),
            first_frame_done_ns: None,
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
        executor.build(plan.into())?;
        Ok(executor)
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

    /// When the host saw the first frame this executor ran done, in host CLOCK_MONOTONIC ns
    /// ([`crate::host_now_ns`]): as it waited for it, at [`Self::finish`] or when a later frame
    /// needed its slot, so no more than `frames_in_flight − 1` frames after the GPU finished it.
    /// A host clock read, unlike the GPU's timestamps, so it never precedes what the host did
    /// before submitting the frame. None until that frame retired.
    pub fn first_frame_done_ns(&self) -> Option<u64> {
        self.first_frame_done_ns
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
    pub fn plan(&self) -> &KernelPlan {
        &self.plan
    }

    /// A handle on the plan being executed, for a caller that reads it while it drives the
    /// executor (the plan is shared, never copied).
    pub fn shared_plan(&self) -> Arc<KernelPlan> {
        Arc::clone(&self.plan)
    }

    /// The plan's links between devices, one per (producer, consumer) pair it copies over.
    pub fn links(&self) -> Vec<LinkInfo> {
        let info = |l: &Link| LinkInfo {
            from: l.from,
            to: l.to,
            kind: l.kind,
            chunks_per_frame: l.per_frame,
            bytes_per_frame: l.bytes_per_frame,
        };
        self.links.iter().map(info).collect()
    }

    /// Per device: the submissions and cross-device waits of one frame of the plan.
    pub fn submissions(&self) -> Vec<DeviceSubmissions> {
        (0..self.states.len())
            .map(|d| DeviceSubmissions {
                device: d,
                submissions_per_frame: self.states[d].segments.len(),
                cross_device_waits_per_frame: (0..self.states[d].segments.len())
                    .map(|j| self.ready_waits(d, j, 0).len() + self.space_waits[d][j].len())
                    .sum(),
            })
            .collect()
    }

    /// Bytes of host staging memory the plan's copies use (`relay` links), over every
    /// frame-in-flight slot.
    pub fn host_staging_bytes(&self) -> u64 {
        self.staging.as_ref().map_or(0, |s| s.host_bytes)
    }

    /// The most host staging memory the plan's copies may use (`ExecOptions::host_staging_bytes`);
    /// more only where a ring must hold a larger copy or grow out of a wait cycle.
    pub fn host_staging_limit(&self) -> u64 {
        self.options.host_staging_bytes
    }

    /// Bytes of device staging memory the plan's copies use (`gpu` and `shared` links), over
    /// every frame-in-flight slot.
    pub fn device_staging_bytes(&self) -> u64 {
        self.staging.as_ref().map_or(0, |s| s.device_bytes)
    }

    /// Clock calibration of each device (GPU → host CLOCK_MONOTONIC).
    pub fn calibration(&self) -> &[ClockCalibration] {
        &self.calibration
    }

    /// Fails if the validation layer reported anything since the last check.
    pub fn check_validation(&self) -> Result<()> {
        self.instance.check_validation()
    }
}
