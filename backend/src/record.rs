//! Recording one segment of a device program into a command buffer: barriers, timestamp pairs
//! (around every op, or around each run of one pass's instances: `Timing`), the kernels'
//! commands and the copies.
//!
//! An op is one item, or a group of consecutive instances of one pass that its kernel records
//! together (`PassKernel::records_groups`, [`op_groups`]): one dispatch for all of them, where
//! each alone would be too small to fill the GPU.
//!
//! Images stay in `GENERAL` layout, so the only barriers needed are memory barriers: a global
//! barrier before every op (`Barriers::EveryOp`), or (`Barriers::Tracked`) where the compiled
//! schedule put one (`parallax_graph::DeviceProgram::barriers`, the segment's
//! [`Segment::barriers`]), before the first op of a segment (it follows other submissions), and
//! before and after a kernel that touches undeclared memory. Nothing is looked for again here:
//! so the instances of one pass for many views, between two of the schedule's barriers, run side
//! by side.

use std::collections::HashMap;
use std::ops::Range;

use ash::vk;

use crate::device::QueueKind;
use crate::error::{Result, VkContext};
use crate::exec_options::Timing;
use crate::kernel::KernelPlan;
use crate::memory::Image;
use crate::plan::{AllocId, ExecutionPlan, InstanceId};
use crate::recorder::Recorder;
use crate::segments::{Chunk, Item, Segment, chunk_bytes};
use crate::shader_pipelines::Bindless;
use crate::timing::EventKind;

/// What timestamp pair `i` of a device measures.
#[derive(Clone, Debug)]
pub(crate) struct TimerLabel {
    pub name: String,
    pub kind: EventKind,
    pub view: u32,
    pub index: usize,
    pub chunk: u32,
    /// Copy chunks the span covers (0 for passes).
    pub copies: u32,
    /// Bytes of those copies.
    pub bytes: u64,
    /// A copy of a finished view to device 0 ([`crate::CrossCopy::is_gather`]).
    pub gather: bool,
    /// Queue the item runs on (timestamp width differs between queue families).
    pub queue: QueueKind,
}

/// The ops of `segment`, as ranges of its items in order: every item alone, but for runs of
/// consecutive instances of one pass whose kernel records groups, which end where the schedule
/// puts a barrier (an instance touches what an earlier one since the last barrier touched).
pub(crate) fn op_groups(plan: &KernelPlan, segment: &Segment) -> Vec<Range<usize>> {
    let grouped_pass = |item: &Item| match *item {
        Item::Pass(p) if plan.kernels.of(plan.pass(p).pass).is_some_and(|k| k.records_groups()) => Some(p),
        _ => None,
    };
    let mut groups: Vec<Range<usize>> = Vec::new();
    for (i, item) in segment.items.iter().enumerate() {
        let joins = grouped_pass(item).is_some_and(|p| {
            !segment.barrier_before(i)
                && groups.last().is_some_and(|last| {
                    grouped_pass(&segment.items[last.start])
                        .is_some_and(|first| plan.pass(first).pass == plan.pass(p).pass)
                })
        });
        match groups.last_mut() {
            Some(last) if joins => last.end = i + 1,
            _ => groups.push(i..i + 1),
        }
    }
    groups
}

/// The items each timestamp pair of `segment` covers, in order: every op alone
/// (`Timing::PerOp`; a group of instances is one op, [`op_groups`]), or runs of consecutive
/// instances of one pass and runs of consecutive copies of one direction (`Timing::PerStage`).
/// Spans never split an op. A span of copies is also recorded as one batch (one barrier for
/// their ownership transfers, [`record_items`]): a timestamp drains the queue on NVIDIA, and
/// the fine schemes copy thousands of small chunks a frame, whose cost was these drains.
pub(crate) fn timer_spans(plan: &KernelPlan, segment: &Segment, timing: Timing) -> Vec<Range<usize>> {
    #[derive(PartialEq)]
    enum Stage<'a> {
        Pass(&'a str),
        /// Gathers (Table 1's "transfer") are timed apart from copies between stages.
        CopyOut {
            gather: bool,
        },
        CopyIn {
            gather: bool,
        },
    }
    let gather = |chunk: &Chunk| plan.copy(chunk.copy).is_gather();
    let stage = |item: &Item| match item {
        Item::Pass(p) => Stage::Pass(plan.pass(*p).name.as_str()),
        Item::CopyOut(c) => Stage::CopyOut { gather: gather(c) },
        Item::CopyIn(c) => Stage::CopyIn { gather: gather(c) },
    };
    let mut spans: Vec<Range<usize>> = Vec::new();
    for op in op_groups(plan, segment) {
        let item = &segment.items[op.start];
        let joins = timing == Timing::PerStage
            && spans.last().is_some_and(|last| stage(&segment.items[last.start]) == stage(item));
        match spans.last_mut() {
            Some(last) if joins => last.end = op.end,
            _ => spans.push(op),
        }
    }
    spans
}

/// Timer labels of all timestamp pairs of `segments` (`spans[j]`: segment j's
/// [`timer_spans`]), in recording order; a span is labelled by its first item.
pub(crate) fn timer_labels(plan: &ExecutionPlan, segments: &[Segment], spans: &[Vec<Range<usize>>]) -> Vec<TimerLabel> {
    let copy_label = |items: &[Item], kind, queue| {
        let chunks: Vec<&Chunk> = items
            .iter()
            .filter_map(|item| match item {
                Item::CopyOut(c) | Item::CopyIn(c) => Some(c),
                Item::Pass(_) => None,
            })
            .collect();
        let chunk = chunks[0];
        let copy = plan.copy(chunk.copy);
        let resource = plan.resource(copy.src_alloc);
        TimerLabel {
            name: format!(
                "{} {} view {} → device {}",
                if kind == EventKind::CopyOut { "copy out" } else { "copy in" },
                resource.name,
                resource.view,
                copy.to
            ),
            kind,
            view: resource.view,
            index: chunk.copy.index(),
            chunk: chunk.index,
            copies: chunks.len() as u32,
            bytes: chunks.iter().map(|c| chunk_bytes(plan, c)).sum(),
            gather: copy.is_gather(),
            queue,
        }
    };
    segments
        .iter()
        .zip(spans)
        .flat_map(|(s, spans)| spans.iter().map(move |span| (s.queue, &s.items[span.clone()])))
        .map(|(queue, items)| match &items[0] {
            Item::Pass(p) => {
                let pass = plan.pass(*p);
                TimerLabel {
                    name: pass.name.clone(),
                    kind: EventKind::Pass,
                    view: pass.view.0,
                    index: p.index(),
                    chunk: 0,
                    copies: 0,
                    bytes: 0,
                    gather: false,
                    queue,
                }
            }
            Item::CopyOut(_) => copy_label(items, EventKind::CopyOut, queue),
            Item::CopyIn(_) => copy_label(items, EventKind::CopyIn, queue),
        })
        .collect()
}

/// Everything a segment recording reads from the device state: what a [`Recorder`] borrows.
/// What recording changes is beside it ([`SegmentScratch`]).
pub(crate) struct SegmentContext<'a> {
    pub barriers: crate::exec_options::Barriers,
    pub raw: &'a ash::Device,
    pub device_index: usize,
    pub plan: &'a KernelPlan,
    pub images: &'a HashMap<AllocId, Image>,
    pub image_slots: &'a HashMap<AllocId, u32>,
    pub slot: usize,
    pub query_pool: vk::QueryPool,
    /// Per copy, the staging buffer of this slot as seen by this device and the copy's offset
    /// in it (device_state.rs `Staging::of_device`).
    pub staging: &'a [(vk::Buffer, u64)],
    /// Addresses of the global buffers on this device, and of the slot's per-frame data.
    pub global_buffers: &'a HashMap<String, (u64, u64)>,
    pub frame_data_address: u64,
    pub frame_sections: &'a [(String, u64)],
    pub frame_block: Option<u64>,
    /// Per-view buffer resources of this device and their addresses.
    pub buffers: &'a HashMap<AllocId, crate::memory::Buffer>,
    pub buffer_addresses: &'a HashMap<AllocId, u64>,
    /// The plan's history pairs swapped for an odd frame (empty for an even one).
    pub parity_map: &'a HashMap<AllocId, AllocId>,
    /// Exported resources and the slot's host-visible buffer each is read back into (device 0
    /// with `ExecOptions::read_back_exports`; empty otherwise).
    pub readback: &'a [(AllocId, vk::Buffer)],
    pub device: &'a std::sync::Arc<crate::device::Device>,
}

/// What recording a segment changes: the device's pipelines (created on first use) and the
/// slot's recording buffers (`Recorder::recording_buffer`), emptied before it records.
pub(crate) struct SegmentScratch<'a> {
    pub bindless: &'a mut Bindless,
    pub recording_buffers: &'a mut Vec<crate::memory::Buffer>,
}

impl SegmentContext<'_> {
    /// The resource an access to `resource` touches in this slot's frame parity.
    fn resolve(&self, resource: AllocId) -> AllocId {
        self.parity_map.get(&resource).copied().unwrap_or(resource)
    }
}

/// Where a segment sits in its device's frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SegmentPlace {
    pub first: bool,
    pub last: bool,
}

/// Records `segment`; its first timer is `first_timer`, and `spans` are its [`timer_spans`].
pub(crate) fn record_segment(
    ctx: &SegmentContext<'_>,
    scratch: &mut SegmentScratch<'_>,
    cb: vk::CommandBuffer,
    segment: &Segment,
    first_timer: u32,
    spans: &[Range<usize>],
    place: SegmentPlace,
) -> Result<()> {
    unsafe { ctx.raw.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default()) }.vk("vkBeginCommandBuffer")?;
    if place.first {
        record_resets(ctx, cb);
    }
    let recorded = record_items(ctx, scratch, cb, segment, first_timer, spans).and_then(|()| {
        if place.last {
            record_readback(ctx, cb);
        }
        unsafe { ctx.raw.end_command_buffer(cb) }.vk("vkEndCommandBuffer")
    });
    if recorded.is_err() {
        // Leave the buffer re-recordable (its pool allows resets) rather than half recorded.
        let _ = unsafe { ctx.raw.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty()) };
    }
    recorded
}

fn record_items(
    ctx: &SegmentContext<'_>,
    scratch: &mut SegmentScratch<'_>,
    cb: vk::CommandBuffer,
    segment: &Segment,
    first_timer: u32,
    spans: &[Range<usize>],
) -> Result<()> {
    let raw = ctx.raw;
    unsafe {
        // Queries are reset from the host before each submission of the slot (a transfer-only
        // queue cannot reset them), and only the main queue has a compute bind point.
        if segment.queue == QueueKind::Main {
            raw.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                scratch.bindless.pipeline_layout,
                0,
                &[scratch.bindless.sets[ctx.slot]],
                &[],
            );
        }
    }
    let mut bound = None;
    // The timestamp pair of each item (the spans tile the items in order).
    let timer_of: Vec<usize> = spans.iter().enumerate().flat_map(|(t, span)| span.clone().map(move |_| t)).collect();
    // A span of copies is recorded as one batch, up to the next barrier of the schedule: its
    // ops are one op here.
    let mut ops: Vec<Range<usize>> = Vec::new();
    for op in op_groups(ctx.plan, segment) {
        let span = &spans[timer_of[op.start]];
        let copy = !matches!(segment.items[op.start], Item::Pass(_));
        match ops.last_mut() {
            Some(last) if copy && last.start >= span.start && !segment.barrier_before(op.start) => last.end = op.end,
            _ => ops.push(op),
        }
    }
    // Whether the op recorded last was a kernel that touches undeclared memory.
    let mut after_opaque = false;
    for (g, op) in ops.into_iter().enumerate() {
        let span = &spans[timer_of[op.start]];
        let query = (first_timer + timer_of[op.start] as u32) * 2;
        let opaque = segment.items[op.clone()].iter().any(|item| touches_undeclared_memory(ctx.plan, item));
        // The first op waits for everything submitted before (other segments, the previous
        // frame); a later one where the schedule says, so the instances of one pass for many
        // views run side by side.
        let tracked = ctx.barriers == crate::exec_options::Barriers::Tracked;
        if g == 0 || !tracked || segment.barrier_before(op.start) || opaque || after_opaque {
            full_barrier(raw, cb);
        }
        after_opaque = opaque;
        if op.start == span.start {
            unsafe { raw.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::ALL_COMMANDS, ctx.query_pool, query) };
        }
        let items = &segment.items[op.clone()];
        match items[0] {
            Item::Pass(_) => bound = record_passes(ctx, scratch, cb, items, bound)?,
            Item::CopyOut(_) => {
                record_copies(ctx, cb, items, CopyDirection::Out);
                // The other device reads the bytes, through host memory on a `relay` link.
                copies_to_host_barrier(raw, cb);
            }
            Item::CopyIn(_) => record_copies(ctx, cb, items, CopyDirection::In),
        }
        if op.end == span.end {
            unsafe { raw.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::ALL_COMMANDS, ctx.query_pool, query + 1) };
        }
    }
    Ok(())
}

/// Records the pass instances of one op (one item, or a group of [`op_groups`]) through their
/// kernel; returns the pipeline left bound.
fn record_passes(
    ctx: &SegmentContext<'_>,
    scratch: &mut SegmentScratch<'_>,
    cb: vk::CommandBuffer,
    items: &[Item],
    bound: Option<vk::Pipeline>,
) -> Result<Option<vk::Pipeline>> {
    let instances: Vec<InstanceId> =
        items.iter().filter_map(|item| if let Item::Pass(p) = *item { Some(p) } else { None }).collect();
    let first = instances[0];
    let kernel = ctx.plan.kernel(first);
    let mut rec = Recorder {
        ctx,
        pass: &ctx.plan.pass(first).name,
        cb,
        bound,
        bindless: &mut *scratch.bindless,
        recording_buffers: &mut *scratch.recording_buffers,
    };
    if kernel.records_groups() {
        kernel.record_group(&mut rec, &instances)?;
    } else {
        kernel.record(&mut rec, ctx.plan.pass(first), first)?;
    }
    Ok(rec.bound)
}

/// Rewrites the buffers the plan resets every frame (`ExecResource::reset`): the header words,
/// zeros after them. Runs before the first item's barrier, so every pass of the frame sees the
/// reset values; the barrier in front orders it after last frame's uses of the buffers.
fn record_resets(ctx: &SegmentContext<'_>, cb: vk::CommandBuffer) {
    let mut resets: Vec<(AllocId, &[u32])> =
        ctx.buffers.keys().filter_map(|&r| ctx.plan.resource(r).reset.as_deref().map(|header| (r, header))).collect();
    if resets.is_empty() {
        return;
    }
    resets.sort_unstable_by_key(|&(r, _)| r);
    full_barrier(ctx.raw, cb);
    for (r, header) in resets {
        let buffer = &ctx.buffers[&r];
        let header_bytes = header.len() as u64 * 4;
        // The two ranges are disjoint, so the fill and the update need no barrier between them.
        unsafe {
            if header_bytes < buffer.size {
                ctx.raw.cmd_fill_buffer(cb, buffer.raw, header_bytes, vk::WHOLE_SIZE, 0);
            }
            if !header.is_empty() {
                let bytes: Vec<u8> = header.iter().flat_map(|w| w.to_le_bytes()).collect();
                ctx.raw.cmd_update_buffer(cb, buffer.raw, 0, &bytes);
            }
        }
    }
}

/// Copies every exported resource into its readback buffer and makes the bytes visible to the
/// host, which reads them once the segment's progress value is reached.
fn record_readback(ctx: &SegmentContext<'_>, cb: vk::CommandBuffer) {
    if ctx.readback.is_empty() {
        return;
    }
    full_barrier(ctx.raw, cb);
    for &(exported, target) in ctx.readback {
        // A history allocation's frame writes the half its parity selects.
        let r = ctx.resolve(exported);
        record_copy_to_host_buffer(ctx.raw, cb, (ctx.images, ctx.buffers), r, ctx.plan.resource(r), target);
    }
    copies_to_host_barrier(ctx.raw, cb);
}

/// Records the copy of the whole of `resource` of this device (`desc` describes it) into
/// `target`: an image as tightly packed rows, a buffer byte for byte. Both readbacks copy
/// through it — the frame loop's ([`record_readback`]) and `Executor::read_resource` — so they
/// lay the bytes out alike. The caller orders it after the writes ([`full_barrier`]) and before
/// the host's read ([`copies_to_host_barrier`]); a resource the device does not hold copies
/// nothing.
pub(crate) fn record_copy_to_host_buffer(
    raw: &ash::Device,
    cb: vk::CommandBuffer,
    (images, buffers): (&HashMap<AllocId, Image>, &HashMap<AllocId, crate::memory::Buffer>),
    resource: AllocId,
    desc: &crate::plan::ExecResource,
    target: vk::Buffer,
) {
    unsafe {
        if let Some(image) = images.get(&resource) {
            let region = vk::BufferImageCopy::default().image_subresource(image.layers()).image_extent(vk::Extent3D {
                width: desc.width,
                height: desc.height,
                depth: 1,
            });
            raw.cmd_copy_image_to_buffer(cb, image.raw, vk::ImageLayout::GENERAL, target, &[region]);
        } else if let Some(buffer) = buffers.get(&resource) {
            let region = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: desc.bytes() };
            raw.cmd_copy_buffer(cb, buffer.raw, target, &[region]);
        }
    }
}

/// Makes the bytes of earlier copies available to the host domain (a device reading them
/// through shared host memory, or the host itself).
pub(crate) fn copies_to_host_barrier(raw: &ash::Device, cb: vk::CommandBuffer) {
    let to_host = [vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::COPY)
        .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::HOST)
        .dst_access_mask(vk::AccessFlags2::HOST_READ)];
    unsafe { raw.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&to_host)) };
}

/// Whether `item` is a pass whose kernel touches memory its pass does not declare: the schedule
/// cannot see that, so a barrier goes before and after it.
fn touches_undeclared_memory(plan: &KernelPlan, item: &Item) -> bool {
    matches!(*item, Item::Pass(p) if plan.kernel(p).touches_undeclared_memory())
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum CopyDirection {
    /// Resource → staging (producer).
    Out,
    /// Staging → resource (consumer).
    In,
}

/// Copies a run of chunks of one direction between their resources and their places in the
/// staging buffer, with one barrier for all their ownership transfers (before copy-ins, after
/// copy-outs) rather than one per chunk: each barrier waits for the copies before it.
fn record_copies(ctx: &SegmentContext<'_>, cb: vk::CommandBuffer, items: &[Item], direction: CopyDirection) {
    let copies: Vec<(Chunk, AllocId, (vk::Buffer, u64, u64))> = items
        .iter()
        .map(|item| {
            let chunk = match *item {
                Item::CopyOut(c) | Item::CopyIn(c) => c,
                Item::Pass(_) => unreachable!("a copy span holds copies only"),
            };
            let copy = ctx.plan.copy(chunk.copy);
            let local = ctx.resolve(match direction {
                CopyDirection::Out => copy.src_alloc,
                CopyDirection::In => copy.dst_alloc,
            });
            let row_bytes = ctx.plan.resource(local).row_bytes();
            let (staging, offset) = ctx.staging[chunk.copy.index()];
            let staging_offset = offset + u64::from(chunk.y0 - copy.region.y0) * row_bytes;
            (chunk, local, (staging, staging_offset, chunk_bytes(&ctx.plan.plan, &chunk)))
        })
        .collect();
    // A batch lies in one range of its link's staging (ExecutionPlan::staging_order): one
    // ownership transfer for it, not one per copy.
    let ranges = merged_ranges(copies.iter().map(|&(.., range)| range).collect());
    if direction == CopyDirection::In {
        external_ownership(ctx, cb, &ranges, direction);
    }
    // One copy command per allocation and staging buffer, a region per chunk: the run has no
    // barrier inside, so its copies of one allocation touch distinct rows (Schedule::validate
    // proves it of a batch).
    let mut commands: Vec<(AllocId, vk::Buffer, Vec<StagedChunk>)> = Vec::new();
    for &(chunk, local, (staging, offset, size)) in &copies {
        match commands.iter_mut().find(|(a, b, _)| (*a, *b) == (local, staging)) {
            Some((.., regions)) => regions.push((chunk, offset, size)),
            None => commands.push((local, staging, vec![(chunk, offset, size)])),
        }
    }
    for (local, staging, regions) in &commands {
        record_allocation_copy(ctx, cb, direction, *local, *staging, regions);
    }
    if direction == CopyDirection::Out {
        external_ownership(ctx, cb, &ranges, direction);
    }
}

/// `ranges` (buffer, offset, size) with those of one buffer that touch, or lie less than the
/// staging alignment apart (the padding between two copies belongs to neither), joined; in
/// order of buffer and offset.
pub(crate) fn merged_ranges(mut ranges: Vec<(vk::Buffer, u64, u64)>) -> Vec<(vk::Buffer, u64, u64)> {
    use ash::vk::Handle;
    ranges.sort_unstable_by_key(|&(buffer, offset, _)| (buffer.as_raw(), offset));
    let mut merged: Vec<(vk::Buffer, u64, u64)> = Vec::with_capacity(ranges.len());
    for (buffer, offset, size) in ranges {
        match merged.last_mut() {
            Some((b, start, len))
                if *b == buffer && offset <= *start + *len + (crate::staging_ring::STAGING_ALIGN - 1) =>
            {
                *len = (*len).max(offset + size - *start);
            }
            _ => merged.push((buffer, offset, size)),
        }
    }
    merged
}

/// Passes the ownership of staging ranges to the other `VkDevice` after copy-outs, or takes
/// it back before copy-ins (`VK_QUEUE_FAMILY_EXTERNAL`): the spec asks this of every resource
/// on memory shared with another instance or device, whatever its sharing mode
/// (resources-external-sharing). The semaphore between the two orders release and acquire.
fn external_ownership(
    ctx: &SegmentContext<'_>,
    cb: vk::CommandBuffer,
    ranges: &[(vk::Buffer, u64, u64)],
    direction: CopyDirection,
) {
    // Staging buffers are concurrent over the device's queue families when it has several
    // (link_memory.rs, memory.rs): the local side of the transfer is then IGNORED.
    let local = if ctx.device.families().len() > 1 { vk::QUEUE_FAMILY_IGNORED } else { ctx.device.queue_family };
    let barriers: Vec<vk::BufferMemoryBarrier2> = ranges
        .iter()
        .map(|&(buffer, offset, size)| {
            let barrier = vk::BufferMemoryBarrier2::default().buffer(buffer).offset(offset).size(size);
            match direction {
                CopyDirection::Out => barrier
                    .src_stage_mask(vk::PipelineStageFlags2::COPY)
                    .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                    .src_queue_family_index(local)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_EXTERNAL),
                CopyDirection::In => barrier
                    .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                    .dst_access_mask(vk::AccessFlags2::TRANSFER_READ)
                    .src_queue_family_index(vk::QUEUE_FAMILY_EXTERNAL)
                    .dst_queue_family_index(local),
            }
        })
        .collect();
    unsafe { ctx.raw.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().buffer_memory_barriers(&barriers)) };
}

/// A chunk of a copy, its offset in the staging buffer and its bytes.
type StagedChunk = (Chunk, u64, u64);

/// The copy between the resource `local` and `staging` of each chunk in `regions`: one command
/// with a region per chunk.
fn record_allocation_copy(
    ctx: &SegmentContext<'_>,
    cb: vk::CommandBuffer,
    direction: CopyDirection,
    local: AllocId,
    staging: vk::Buffer,
    regions: &[StagedChunk],
) {
    let raw = ctx.raw;
    let resource = ctx.plan.resource(local);
    if let Some(buffer) = ctx.buffers.get(&local) {
        let copies: Vec<vk::BufferCopy> = regions
            .iter()
            .map(|&(chunk, staging_offset, size)| {
                let resource_offset = u64::from(chunk.y0) * resource.row_bytes();
                match direction {
                    CopyDirection::Out => {
                        vk::BufferCopy { src_offset: resource_offset, dst_offset: staging_offset, size }
                    }
                    CopyDirection::In => {
                        vk::BufferCopy { src_offset: staging_offset, dst_offset: resource_offset, size }
                    }
                }
            })
            .collect();
        let (src, dst) = match direction {
            CopyDirection::Out => (buffer.raw, staging),
            CopyDirection::In => (staging, buffer.raw),
        };
        unsafe { raw.cmd_copy_buffer(cb, src, dst, &copies) };
        return;
    }
    let image = &ctx.images[&local];
    let copies: Vec<vk::BufferImageCopy> = regions
        .iter()
        .map(|&(chunk, staging_offset, _)| {
            vk::BufferImageCopy::default()
                .buffer_offset(staging_offset)
                .image_subresource(image.layers())
                .image_offset(vk::Offset3D { x: 0, y: chunk.y0 as i32, z: 0 })
                .image_extent(vk::Extent3D { width: resource.width, height: chunk.rows(), depth: 1 })
        })
        .collect();
    unsafe {
        match direction {
            CopyDirection::Out => {
                raw.cmd_copy_image_to_buffer(cb, image.raw, vk::ImageLayout::GENERAL, staging, &copies)
            }
            CopyDirection::In => {
                raw.cmd_copy_buffer_to_image(cb, staging, image.raw, vk::ImageLayout::GENERAL, &copies)
            }
        }
    }
}

/// Every earlier write is visible to every later access on this queue. `ALL_COMMANDS` and
/// `MEMORY_READ` include `DRAW_INDIRECT` and `INDIRECT_COMMAND_READ`: the arguments of an
/// indirect dispatch that an earlier pass wrote are ready too.
pub(crate) fn full_barrier(raw: &ash::Device, cb: vk::CommandBuffer) {
    let barrier = [vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)];
    unsafe { raw.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&barrier)) };
}

/// Hand-laid plans of grouped passes, for the tests of grouping here and in segments.rs.
#[cfg(test)]
pub(crate) mod grouping_plans {
    use std::sync::Arc;

    use crate::kernel::{KernelPlan, Kernels, PassKernel};
    use crate::plan::{
        DeviceId, DeviceProgram, ExecutionPlan, InstanceId, Op, PassId, PassInstance, Region, ViewId, own_access,
    };
    use crate::recorder::Recorder;

    /// Records nothing; `groups` says whether it records groups.
    pub(crate) struct Nothing {
        pub(crate) groups: bool,
    }

    impl PassKernel for Nothing {
        fn record(&self, _: &mut Recorder<'_>, _: &PassInstance, _: InstanceId) -> crate::Result<()> {
            Ok(())
        }

        fn records_groups(&self) -> bool {
            self.groups
        }
    }

    /// Passes `(name, reads, writes)` on device 0, in order, the passes named `fill…` with a
    /// kernel that records groups, the others with one that does not; every pass op in order
    /// on device 0; reads and writes are allocation numbers.
    pub(crate) fn plan(passes: &[(&str, &[u32], &[u32])]) -> KernelPlan {
        let mut kernels = Kernels::default();
        let rows = Region::new(0, 1);
        let access = |&r: &u32| own_access(0, crate::plan::AllocId(r), rows);
        let names: Vec<&str> = passes.iter().map(|p| p.0).collect();
        let passes: Vec<PassInstance> = passes
            .iter()
            .enumerate()
            .map(|(view, &(name, reads, writes))| {
                let pass = pass_named(name, &names);
                kernels.insert(pass, Arc::new(Nothing { groups: name.starts_with("fill") }));
                PassInstance {
                    pass,
                    name: name.to_string(),
                    view: ViewId(view as u32),
                    region: rows,
                    device: DeviceId(0),
                    reads: reads.iter().map(access).collect(),
                    writes: writes.iter().map(access).collect(),
                    history_reads: Vec::new(),
                }
            })
            .collect();
        let ops = (0..passes.len() as u32).map(|i| Op::Pass(InstanceId(i))).collect();
        let program = DeviceProgram { device: DeviceId(0), ops, barriers: Vec::new() };
        KernelPlan { plan: ExecutionPlan { passes, devices: vec![program], ..ExecutionPlan::default() }, kernels }
    }

    /// The declared pass of the instances named `name` among instances named `names`: one per
    /// distinct name, numbered by its first instance.
    pub(crate) fn pass_named(name: &str, names: &[&str]) -> PassId {
        PassId(names.iter().position(|&n| n == name).expect("a name of the plan") as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::{AllocId, CopyId, CopyKind, CrossCopy, DeviceId, Op, PassInstance, ResourceId, ViewId};

    #[test]
    fn a_batch_s_staging_ranges_are_one_ownership_transfer() {
        use ash::vk::Handle;
        let (a, b) = (vk::Buffer::from_raw(1), vk::Buffer::from_raw(2));
        // Two copies 256-aligned side by side, one after padding, one far off, one elsewhere.
        let ranges = vec![(a, 512, 100), (b, 0, 64), (a, 0, 300), (a, 4096, 8), (a, 256, 200)];
        assert_eq!(super::merged_ranges(ranges), vec![(a, 0, 612), (a, 4096, 8), (b, 0, 64)]);
    }

    #[test]
    fn grouped_passes_are_one_op_until_a_barrier_of_the_schedule_and_per_op_timing_times_each_op() {
        // A compaction, three fills of which the third writes what the first wrote (two bands
        // of one view), a copy of what the second wrote, two more fills, an instance of another
        // grouped pass, then a pass reading the third fill's result: barriers where compiling a
        // schedule places them for these accesses (the copy's read of the second fill's write
        // is already behind the barrier at the third).
        let mut plan = grouping_plans::plan(&[
            ("compact", &[], &[0]),
            ("fill", &[0], &[1]),
            ("fill", &[2], &[3]),
            ("fill", &[0], &[1]),
            ("fill", &[4], &[5]),
            ("fill", &[6], &[7]),
            ("fill_sky", &[9], &[10]),
            ("svgf", &[1], &[8]),
        ]);
        // The plan describes no resources: nothing here counts the copy's bytes.
        plan.copies = vec![CrossCopy {
            resource: ResourceId(3),
            version: 1,
            region: parallax_graph::Region::new(0, 1),
            from: DeviceId(0),
            to: DeviceId(1),
            src_alloc: AllocId(3),
            dst_alloc: AllocId(3),
            bytes: 0,
            kind: CopyKind::Dependency,
        }];
        let mut ops: Vec<Op> = (0..8).map(|i| Op::Pass(InstanceId(i))).collect();
        ops.insert(4, Op::CopyOut(CopyId(0)));
        let barriers = parallax_graph::place_barriers(&plan.passes, &plan.copies, &ops);
        assert_eq!(barriers, [0, 1, 3, 8]);
        let chunk = Chunk { copy: CopyId(0), index: 0, y0: 0, y1: 1 };
        let mut items: Vec<Item> = (0..8).map(|i| Item::Pass(InstanceId(i))).collect();
        items.insert(4, Item::CopyOut(chunk));
        let s = Segment { barriers: barriers.iter().map(|&b| b as usize).collect(), ..segment(items) };
        // `fill_sky` follows the fills with no barrier between, and is grouped too, but is
        // another pass: a group of its own.
        assert_eq!(op_groups(&plan, &s), vec![0..1, 1..3, 3..4, 4..5, 5..7, 7..8, 8..9]);
        assert_eq!(timer_spans(&plan, &s, Timing::PerOp), op_groups(&plan, &s));
        assert_eq!(timer_spans(&plan, &s, Timing::PerStage), vec![0..1, 1..4, 4..5, 5..7, 7..8, 8..9]);
        // Without grouping kernels every item is its own op.
        let plain = plan_of(&["fill", "fill", "fill"]);
        let s = segment((0..3).map(|i| Item::Pass(InstanceId(i))).collect());
        assert_eq!(op_groups(&plain, &s), vec![0..1, 1..2, 2..3]);
    }

    /// A plan whose passes are named `names` (one instance each, view = index; one declared pass
    /// per distinct name).
    fn plan_of(names: &[&str]) -> KernelPlan {
        let pass = |(view, name): (usize, &&str)| PassInstance {
            pass: grouping_plans::pass_named(name, names),
            name: name.to_string(),
            view: ViewId(view as u32),
            region: parallax_graph::Region::new(0, 1),
            device: DeviceId(0),
            reads: Vec::new(),
            writes: Vec::new(),
            history_reads: Vec::new(),
        };
        let plan = ExecutionPlan { passes: names.iter().enumerate().map(pass).collect(), ..ExecutionPlan::default() };
        KernelPlan { plan, ..KernelPlan::default() }
    }

    fn segment(items: Vec<Item>) -> Segment {
        Segment { items, ..Segment::default() }
    }

    #[test]
    fn per_op_times_every_item_and_per_stage_each_run_of_one_pass_or_copy_direction() {
        let mut plan = plan_of(&["gbuffer", "gbuffer", "gbuffer", "svgf", "svgf", "gbuffer"]);
        plan.resources = vec![crate::plan::ExecResource::image(
            "radiance",
            parallax_graph::FamilyId(0),
            0,
            4,
            2,
            crate::plan::Format::Rgba32f,
        )];
        let copy = |kind| {
            let rows = parallax_graph::Region::new(0, 2);
            plan.laid_copy((AllocId(0), AllocId(0)), rows, (DeviceId(0), DeviceId(1)), kind)
        };
        plan.copies = vec![copy(CopyKind::Dependency), copy(CopyKind::Gather)];
        let chunk = |c: u32, y0| Chunk { copy: CopyId(c), index: y0, y0, y1: y0 + 1 };
        let items = vec![
            Item::Pass(InstanceId(0)),
            Item::Pass(InstanceId(1)),
            Item::Pass(InstanceId(2)),
            Item::CopyOut(chunk(0, 0)),
            Item::CopyOut(chunk(0, 1)),
            Item::CopyIn(chunk(0, 0)),
            Item::CopyOut(chunk(1, 0)),
            Item::Pass(InstanceId(3)),
            Item::Pass(InstanceId(4)),
            Item::Pass(InstanceId(5)),
        ];
        let s = segment(items);
        assert_eq!(timer_spans(&plan, &s, Timing::PerOp), (0..10).map(|i| i..i + 1).collect::<Vec<_>>());
        // Copies of one direction form a run of their own, gathers apart; a pass name coming
        // back starts a new run.
        let spans = timer_spans(&plan, &s, Timing::PerStage);
        assert_eq!(spans, vec![0..3, 3..5, 5..6, 6..7, 7..9, 9..10]);
        let labels = timer_labels(&plan, std::slice::from_ref(&s), std::slice::from_ref(&spans));
        let copies: Vec<(u32, u64, bool)> = labels.iter().map(|l| (l.copies, l.bytes, l.gather)).collect();
        let row = 4 * 16;
        assert_eq!(
            copies,
            [(0, 0, false), (2, 2 * row, false), (1, row, false), (1, row, true), (0, 0, false), (0, 0, false)]
        );
    }

    #[test]
    fn a_label_per_span_named_after_its_first_item() {
        let plan = plan_of(&["gbuffer", "gbuffer", "svgf"]);
        let segments = [
            segment(vec![Item::Pass(InstanceId(0)), Item::Pass(InstanceId(1))]),
            segment(vec![Item::Pass(InstanceId(2))]),
        ];
        let spans: Vec<Vec<Range<usize>>> = segments.iter().map(|s| timer_spans(&plan, s, Timing::PerStage)).collect();
        let labels = timer_labels(&plan, &segments, &spans);
        let named: Vec<(&str, u32)> = labels.iter().map(|l| (l.name.as_str(), l.view)).collect();
        assert_eq!(named, [("gbuffer", 0), ("svgf", 2)]);
    }
}
