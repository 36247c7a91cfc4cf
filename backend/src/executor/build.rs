//! Building the executor's state for a plan: device states (images kept across plan changes),
//! copy chunks and their links (kinds, semaphores), the fault gate, the submission order, staging and
//! readback memory, relay threads.

use std::sync::Arc;

use ash::vk;

use crate::device_state::{Kept, create_device_state, create_staging, fault_gate, staged_bytes};
use crate::error::{BackendError, Result};
use crate::exec_options::FaultInjection;
use crate::kernel::KernelPlan;
use crate::link_memory::import_timeline;
use crate::links::{ChunkLink, Link, LinkKind, LinkKinds, link_order};
use crate::plan::{CopyId, DeviceId, ExecutionPlan};
use crate::relay::Relay;
use crate::remote::{ReceiveLink, Remote, RemoteTransport, number_receives, wires};
use crate::segments::{Chunk, Item, Segment, chunks_of_copies, cross_device_waits, segment_devices};
use crate::staging_ring::{RingCopy, RingLayout, RingLink, fit_rings};
use crate::texture::Texture;

use super::Executor;

impl Executor {
    /// Replaces the plan. Returns `false` (and re-records nothing) when `plan` equals the
    /// current one; otherwise waits for all frames, keeps the images whose resource description
    /// is unchanged (their contents survive), and records everything anew at the next frame.
    pub fn set_plan(&mut self, plan: impl Into<Arc<KernelPlan>>) -> Result<bool> {
        let plan = plan.into();
        if plan == self.plan {
            return Ok(false);
        }
        self.finish()?;
        self.build(plan)?;
        Ok(true)
    }

    pub(super) fn build(&mut self, plan: Arc<KernelPlan>) -> Result<()> {
        plan.validate(self.devices.len())?;
        // Threads first (they use the old semaphores), then the old states.
        self.relay = None;
        self.remote = None;
        let mut kept = Kept::default();
        for (d, mut state) in std::mem::take(&mut self.states).into_iter().enumerate() {
            for (resource, image) in state.images.drain() {
                kept.images.insert((d, self.plan.resource(resource).clone()), image);
            }
            for (resource, buffer) in state.buffers.drain() {
                kept.buffers.insert((d, self.plan.resource(resource).clone()), buffer);
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
        // Small copies share a submission up to `chunk_bytes` together where a host relay
        // carries them (a bounded batch lets the two PCIe directions overlap). Over device memory
        // a batch moves at the copy engines' speed and every submission costs a signal and a
        // wait: the small copies of a pass's run then share one, whatever their bytes.
        let device_memory = plan
            .copies
            .iter()
            .all(|c| matches!(self.link_kinds.of(c.from.index(), c.to.index()), LinkKind::Gpu | LinkKind::Shared));
        let merge_bytes = if device_memory { u64::MAX } else { self.options.chunk_bytes };
        let wires = wires(&plan);
        let remote = wires.iter().any(Option::is_some);
        if remote && self.options.remote.is_none() {
            return Err(BackendError::Remote(
                "the plan copies to or from another process's device, but the executor has no transport for it \
                 (ExecOptions::remote)"
                    .into(),
            ));
        }
        // The schedule's order (batched or not) was proven free of cycles on the whole global
        // schedule when it was compiled, so a process running its part keeps it as it is.
        let cut = segment_devices(&plan, &chunks, merge_bytes, dropped_wait, self.options.separate_copy_queue);
        let chunk_counts: Vec<usize> = chunks.iter().map(Vec::len).collect();
        let mut order = link_order(&plan, &cut, &chunk_counts);
        number_receives(&plan, &cut, &mut order);
        let kinds: Vec<LinkKind> = order.links.iter().map(|&(from, to, _)| self.link_kinds.of(from, to)).collect();
        let exports_progress =
            |d: usize| order.links.iter().zip(&kinds).any(|(&(from, ..), &kind)| from == d && kind == LinkKind::Gpu);
        for ((d, device), segments) in self.devices.iter().enumerate().zip(cut) {
            let state =
                create_device_state(device, &plan, segments, slots, &self.options, exports_progress(d), &mut kept)?;
            let views: Vec<vk::ImageView> = self.textures[d].iter().map(Texture::view).collect();
            state.bindless.set_textures(&views);
            states.push(state);
        }
        drop(kept);
        let segments: Vec<Vec<Segment>> = states.iter().map(|s| s.segments.clone()).collect();
        let link_of_copy: Vec<usize> =
            order.chunks.iter().map(|c| c.first().expect("a copy has at least one chunk").link).collect();
        let mut bytes_per_frame = vec![0u64; order.links.len()];
        for (c, &link) in link_of_copy.iter().enumerate() {
            bytes_per_frame[link] += plan.copy_bytes(CopyId(c as u32));
        }
        let mut links = Vec::with_capacity(order.links.len());
        for (l, (&(from, to, per_frame), &kind)) in order.links.iter().zip(&kinds).enumerate() {
            // The consumer waits on the producer's own progress timeline (`gpu`), or on a ready
            // timeline of its own that the relay raises.
            let ready = match kind {
                LinkKind::Gpu => import_timeline(&self.devices[from], states[from].progress, &self.devices[to])?,
                LinkKind::Remote if to >= states.len() => vk::Semaphore::null(),
                LinkKind::Shared | LinkKind::Relay | LinkKind::Remote => states[to].device.create_timeline(0)?,
            };
            if to < states.len() {
                states[to].ready.push(ready);
            }
            links.push(Link { from, to, kind, ready, space: None, per_frame, bytes_per_frame: bytes_per_frame[l] });
        }
        self.gate = match self.options.fault {
            Some(FaultInjection::DropCrossDeviceWait { copy }) => Some(fault_gate(&plan, &mut states, copy)?),
            _ => None,
        };
        let mut waits = cross_device_waits(&segments);
        if let Some(gate) = &self.gate {
            // The producer's first segment waits for the consumer's gate segment.
            waits[gate.producer][0].push((gate.consumer, gate.consumer_segment));
        }
        // Host staging is a ring per `relay` link (staging_ring.rs); not under fault injection,
        // whose gate the ring's check cannot see.
        let rings = if self.gate.is_none() { ring_links(&plan, &segments, &links, &order.chunks) } else { Vec::new() };
        let cycle = || BackendError::ExecutionPlan(crate::plan::ExecutionPlanError::WaitCycle);
        let fitted = fit_rings(&rings, self.options.host_staging_bytes, slots, &waits).ok_or_else(cycle)?;
        self.submission_order = fitted.order;
        self.space_waits = segments.iter().map(|s| vec![Vec::new(); s.len()]).collect();
        self.space_signals = segments.iter().map(|s| vec![Vec::new(); s.len()]).collect();
        for wait in &fitted.waits {
            if links[wait.link].space.is_none() {
                let semaphore = states[wait.device].device.create_timeline(0)?;
                states[wait.device].ready.push(semaphore);
                links[wait.link].space = Some(semaphore);
            }
            self.space_waits[wait.device][wait.segment].push((wait.link, wait.value));
        }
        for (to, device) in segments.iter().enumerate() {
            let mut counts = vec![0u64; links.len()];
            for (j, segment) in device.iter().enumerate() {
                for item in &segment.items {
                    if let Item::CopyIn(chunk) = item {
                        let link = order.chunks[chunk.copy.index()][chunk.index as usize].link;
                        counts[link] += 1;
                        if links[link].space.is_some() {
                            self.space_signals[to][j].push((link, counts[link]));
                        }
                    }
                }
            }
        }
        let ring_layouts: Vec<RingLayout> = rings
            .iter()
            .zip(fitted.sizes.iter().zip(fitted.offsets))
            .map(|(ring, (&size, offsets))| RingLayout {
                link: ring.link,
                size,
                offsets: ring.copies.iter().map(|c| c.copy).zip(offsets).collect(),
            })
            .collect();
        let link_ends: Vec<(usize, usize, LinkKind)> = links.iter().map(|l| (l.from, l.to, l.kind)).collect();
        self.staging = create_staging(&self.devices, &plan, &link_ends, &link_of_copy, slots, &ring_layouts)?;
        let remote = match (&self.options.remote, remote) {
            (Some(transport), true) => {
                Some(remote_side(transport.clone(), wires, &links, &order.chunks, &chunks, &states, slots)?)
            }
            _ => None,
        };
        if let Some(readback) = &mut self.readback {
            readback.allocate(&self.devices[0], &plan, slots)?;
        }
        self.plan = plan;
        self.chunks = chunks;
        self.states = states;
        self.links = links;
        self.chunk_links = order.chunks;
        self.needs_record = true;
        // Relay threads only where a signal is forwarded by the host, or chunks handed to another
        // process: none when every link waits on the GPU.
        let sends = remote.as_ref().is_some_and(|r| r.sends_per_frame.iter().any(|&n| n > 0));
        self.remote = remote;
        if self.links.iter().any(|l| l.kind.relayed()) || self.gate.is_some() || sends {
            let progress: Vec<vk::Semaphore> = self.states.iter().map(|s| s.progress).collect();
            self.relay = Some(Relay::new(&self.devices, &progress)?);
        }
        self.plan_epoch = self.next_frame;
        self.history_origin = self.next_frame;
        Ok(())
    }

    /// Recorded frame slots: [`slots_for`] the frames in flight.
    pub(super) fn slot_count(&self) -> usize {
        slots_for(self.options.frames_in_flight)
    }

    /// Device-local bytes [`Executor::new`] would allocate for `plan` on each of its devices,
    /// known before any is made: every allocation a device touches at its description's size
    /// (`ExecResource::bytes`, as `create_device_state` creates them), and on the producer of
    /// each `gpu` or `shared` link its staging, once per frame-in-flight slot (`create_staging`;
    /// such links join devices of one physical GPU). Not counted: `relay` and `remote` staging,
    /// read-back and frame data, which live in host-visible memory; the global buffers and
    /// textures uploaded later (the scene's); and what the driver itself allocates for
    /// descriptors, command buffers, query pools and pipelines, or pads an image by, which it
    /// reports only once they exist.
    pub fn device_local_bytes(plan: &ExecutionPlan, kinds: &LinkKinds, frames_in_flight: usize) -> Vec<u64> {
        let mut bytes: Vec<u64> = (0..plan.devices.len() as u32)
            .map(|d| plan.resources_of_device(DeviceId(d)).iter().map(|&a| plan.resource(a).bytes()).sum())
            .collect();
        let slots = slots_for(frames_in_flight) as u64;
        for (c, copy) in plan.copies.iter().enumerate() {
            let from = copy.from.index();
            if from < bytes.len() && matches!(kinds.of(from, copy.to.index()), LinkKind::Gpu | LinkKind::Shared) {
                bytes[from] += slots * staged_bytes(plan, CopyId(c as u32));
            }
        }
        bytes
    }
}

/// Recorded frame slots for `frames_in_flight` (at least one): rounded up to even, so a slot's
/// frame parity never changes and history pairs can be swapped in the recording (see
/// `ExecutionPlan::history`).
fn slots_for(frames_in_flight: usize) -> usize {
    frames_in_flight.max(1).div_ceil(2) * 2
}

/// The `relay` links of a plan as [`RingLink`]s: each copy with its bytes in staging, the
/// producer's segment that starts sending it, and the place of its last chunk among the
/// link's copy-ins in the consumer's segment order.
fn ring_links(
    plan: &ExecutionPlan,
    segments: &[Vec<Segment>],
    links: &[Link],
    chunks: &[Vec<ChunkLink>],
) -> Vec<RingLink> {
    let mut rings: Vec<Option<RingLink>> = links
        .iter()
        .enumerate()
        .map(|(l, link)| {
            (link.kind == LinkKind::Relay).then(|| RingLink {
                link: l,
                from: link.from,
                to: link.to,
                copies: Vec::new(),
            })
        })
        .collect();
    let mut copies: Vec<usize> = (0..plan.copies.len()).collect();
    copies.sort_by_key(|&c| chunks[c][0].position);
    // Per copy: (freed, consumer segment) of its last chunk in the consumer's order.
    let mut freed = vec![(0u64, 0usize); plan.copies.len()];
    for device in segments {
        let mut counts = vec![0u64; links.len()];
        for (j, segment) in device.iter().enumerate() {
            for item in &segment.items {
                if let Item::CopyIn(chunk) = item {
                    let link = chunks[chunk.copy.index()][chunk.index as usize].link;
                    counts[link] += 1;
                    freed[chunk.copy.index()] = (counts[link], j);
                }
            }
        }
    }
    for c in copies {
        let first = chunks[c][0];
        if let Some(ring) = &mut rings[first.link] {
            let (freed, consumer_segment) = freed[c];
            ring.copies.push(RingCopy {
                copy: CopyId(c as u32),
                bytes: staged_bytes(plan, CopyId(c as u32)),
                producer_segment: first.segment,
                freed,
                consumer_segment,
            });
        }
    }
    rings.into_iter().flatten().collect()
}

/// The remote side of a plan (remote.rs): its receive links, each with its chunks in the
/// consumer's order, and per device of this process the chunks it sends a frame.
fn remote_side(
    transport: std::sync::Arc<dyn RemoteTransport>,
    wires: Vec<Option<crate::remote::Wire>>,
    links: &[Link],
    chunk_links: &[Vec<ChunkLink>],
    chunks: &[Vec<Chunk>],
    states: &[crate::device_state::DeviceState],
    slots: usize,
) -> Result<Remote> {
    let here = states.len();
    let mut receives = Vec::new();
    let mut ends = Vec::new();
    for (l, link) in links.iter().enumerate().filter(|(_, l)| l.kind == LinkKind::Remote && l.to < here) {
        let mut on_link: Vec<(u64, Chunk, crate::remote::Wire)> = chunk_links
            .iter()
            .enumerate()
            .flat_map(|(c, places)| places.iter().zip(&chunks[c]).map(move |(place, &chunk)| (c, place, chunk)))
            .filter(|(_, place, _)| place.link == l)
            .map(|(c, place, chunk)| (place.position, chunk, wires[c].expect("a remote copy has a wire")))
            .collect();
        on_link.sort_by_key(|&(position, ..)| position);
        receives
            .push(ReceiveLink { link: l, chunks: on_link.into_iter().map(|(_, chunk, wire)| (chunk, wire)).collect() });
        ends.push((states[link.to].device.clone(), link.ready));
    }
    let mut sends_per_frame = vec![0u64; here];
    for link in links.iter().filter(|l| l.kind == LinkKind::Remote && l.from < here) {
        sends_per_frame[link.from] += link.per_frame;
    }
    Remote::new(transport, wires, receives, ends, sends_per_frame, slots)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::copy_plan;

    /// The copy benchmark's 16×8 RGBA32F payload (2048 B) lives on both devices; over a `gpu`
    /// or `shared` link its staging adds one copy's bytes per slot to the producer, over a
    /// `relay` link nothing (host memory).
    #[test]
    fn device_local_bytes_are_the_allocations_and_the_producers_device_staging() {
        let plan = copy_plan(16, 8).unwrap();
        let kinds = |kind| LinkKinds(vec![vec![None, Some(kind)], vec![Some(kind), None]]);
        let payload = 16 * 8 * 16;
        for kind in [LinkKind::Gpu, LinkKind::Shared] {
            assert_eq!(Executor::device_local_bytes(&plan, &kinds(kind), 2), vec![3 * payload, payload], "{kind:?}");
            assert_eq!(Executor::device_local_bytes(&plan, &kinds(kind), 3), vec![5 * payload, payload], "4 slots");
        }
        assert_eq!(Executor::device_local_bytes(&plan, &kinds(LinkKind::Relay), 2), vec![payload, payload]);
    }
}
