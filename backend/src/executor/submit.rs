//! Submitting a frame: frame constants and per-frame data into the slot, then every segment in
//! the submission order, each with its waits and progress signal, and the relay jobs of its
//! copy-outs.

use std::time::Instant;

use ash::vk;

use crate::device::host_now_ns;
use crate::error::{BackendError, Result};
use crate::exec_options::FaultInjection;
use crate::frame_block::FrameConstants;
use crate::links::{ChunkLink, LinkKind};
use crate::readback::FrameTicket;
use crate::relay::{RelayAction, RelayJob};
use crate::remote::HostSpan;
use crate::segments::Chunk;
use crate::segments::{Run, progress_value, ready_value};

use super::{Executor, InFlight};

/// What one segment's `VkSubmitInfo2` points at.
struct SegmentSubmit {
    waits: Vec<vk::SemaphoreSubmitInfo<'static>>,
    signal: [vk::SemaphoreSubmitInfo<'static>; 1],
    command_buffer: [vk::CommandBufferSubmitInfo<'static>; 1],
}

impl Executor {
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

    /// Marks history invalid for the next frame (a camera cut, a teleport): its kernels see
    /// `history_valid = 0` (in the frame constants) and must not
    /// blend in what their history reads or previous cameras hold.
    pub fn reset_history(&mut self) {
        self.history_origin = self.next_frame;
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
        if let Some(relay) = &self.relay {
            relay.check()?;
        }
        if self.needs_record {
            self.record_all()?;
        }
        let submit_start_ns = host_now_ns();
        let cpu_start = Instant::now();
        let frame = self.next_frame;
        let local = frame - self.plan_epoch;
        let slot = (frame % self.slot_count() as u64) as usize;
        // The one frame index and history flag, in the one place kernels read them.
        let constants = FrameConstants::new(frame, frame > self.history_origin);
        for state in &mut self.states {
            state.bindless.set_frame_constants(slot, constants);
        }
        let frame_bytes = self.frame_data.bytes();
        if !frame_bytes.is_empty() {
            for buffer in &mut self.frame_data_buffers[slot] {
                let mapped = &mut buffer.mapped_mut().expect("CpuToGpu buffers are mapped")[..frame_bytes.len()];
                mapped.copy_from_slice(frame_bytes);
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
        // Chunks from other processes go into this slot's staging, whose last frame retired.
        if let Some(remote) = &self.remote {
            let spans = remote
                .receives
                .iter()
                .map(|r| r.chunks.iter().map(|&(chunk, _)| self.host_span(r.link, slot, chunk)).collect())
                .collect();
            remote.queue_frame(local, spans)?;
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
        self.queue_relays(run, local, slot)
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
        let mut waits: Vec<vk::SemaphoreSubmitInfo<'static>> =
            self.ready_waits(d, j, local).into_iter().map(|(semaphore, value)| on(semaphore, value)).collect();
        // A copy-out into bytes of a staging ring that an earlier copy of the frame still
        // holds waits until the consumer has copied that one in (staging_ring.rs).
        for &(l, value) in &self.space_waits[d][j] {
            let link = &self.links[l];
            waits.push(on(
                link.space.expect("a link with space waits has a space timeline"),
                local * link.per_frame + value,
            ));
        }
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

    /// The cross-device waits of segment `j` of device `d` in frame `local`: one per link it
    /// waits on, at the largest value its chunks on that link need. Timeline values on a link
    /// rise in the producer's segment order (its progress timeline, or the ready values the
    /// relay signals in that order), so the largest covers the others: one wait instead of one
    /// per chunk.
    pub(super) fn ready_waits(&self, d: usize, j: usize, local: u64) -> Vec<(vk::Semaphore, u64)> {
        let mut waits: Vec<(vk::Semaphore, u64)> = Vec::new();
        for wait in &self.states[d].segments[j].waits {
            let chunk = self.chunk_links[wait.copy.index()][wait.chunk as usize];
            let link = &self.links[chunk.link];
            let value = match link.kind {
                // The producer's progress value of the segment that completes the chunk.
                LinkKind::Gpu => progress_value(local, self.states[link.from].segments.len(), chunk.segment),
                LinkKind::Shared | LinkKind::Relay | LinkKind::Remote => {
                    ready_value(local, link.per_frame, chunk.position)
                }
            };
            match waits.iter_mut().find(|(semaphore, _)| *semaphore == link.ready) {
                Some((_, max)) => *max = (*max).max(value),
                None => waits.push((link.ready, value)),
            }
        }
        waits
    }

    /// Relay jobs of the copy-outs in `run` and the space signals of its copy-ins from staging
    /// rings, in segment order (see relay.rs).
    fn queue_relays(&self, run: &Run, local: u64, slot: usize) -> Result<()> {
        let Some(relay) = &self.relay else {
            return Ok(());
        };
        let d = run.device;
        let segment_count = self.states[d].segments.len();
        for j in run.segments.clone() {
            let watch_value = progress_value(local, segment_count, j);
            for chunk in &self.states[d].segments[j].relays {
                let ChunkLink { link, position, .. } = self.chunk_links[chunk.copy.index()][chunk.index as usize];
                if let Some(remote) = self.remote.as_ref().filter(|_| self.links[link].kind == LinkKind::Remote) {
                    let wire = remote.wires[chunk.copy.index()].expect("a remote copy has a wire");
                    let send = remote.send_job(d, wire, self.host_span(link, slot, *chunk));
                    relay.push(d, RelayJob { watch_value, action: RelayAction::Send(send) })?;
                    continue;
                }
                let link = &self.links[link];
                if !link.kind.relayed() {
                    continue;
                }
                relay.push(
                    d,
                    RelayJob::signal(
                        watch_value,
                        self.devices[link.to].clone(),
                        link.ready,
                        ready_value(local, link.per_frame, position),
                    ),
                )?;
            }
            for &(l, value) in &self.space_signals[d][j] {
                let link = &self.links[l];
                relay.push(
                    d,
                    RelayJob::signal(
                        watch_value,
                        self.devices[link.from].clone(),
                        link.space.expect("a link with space signals has a space timeline"),
                        local * link.per_frame + value,
                    ),
                )?;
            }
            if let Some(gate) = &self.gate
                && gate.consumer == d
                && gate.consumer_segment == j
            {
                relay.push(
                    d,
                    RelayJob::signal(watch_value, self.devices[gate.producer].clone(), gate.semaphore, local + 1),
                )?;
            }
        }
        Ok(())
    }
}

impl Executor {
    /// Where `chunk` lies in the host staging of `link` in `slot` (a `remote` link's).
    fn host_span(&self, link: usize, slot: usize, chunk: Chunk) -> HostSpan {
        let staging = self.staging.as_ref().expect("a plan with copies has staging");
        let base = staging.buffers[link][slot].host_ptr().expect("a remote link's staging is host memory");
        let copy = self.plan.copy(chunk.copy);
        let row_bytes = self.plan.resource(copy.src_alloc).row_bytes();
        let offset = staging.places[chunk.copy.index()].1 + u64::from(chunk.y0 - copy.region.y0) * row_bytes;
        HostSpan::new(base, offset, crate::segments::chunk_bytes(&self.plan, &chunk))
    }
}
