//! Cutting a device's op list into submissions ("segments"). Pure data, no Vulkan.
//!
//! A segment is one command buffer submitted with its waits; it signals the device's progress
//! timeline with a value fixed by its position: segment `j` of frame `f` on a device with `S`
//! segments per frame signals `f * S + j + 1`. Values are a function of (frame, segment), so
//! nothing needs to be counted at run time and recorded command buffers stay valid.
//!
//! Cuts happen:
//! * after every chunk of a copy-out: the chunk's bytes are complete in host memory when the
//!   segment's signal fires, and the host relay forwards that to the consumer;
//! * before every chunk of a copy-in: a wait applies to a whole submission, so the chunk must
//!   start one.
//!
//! except between copies of one chunk each in the same direction, which share a submission up
//! to `merge_bytes` together (a copy-out's relay then fires when its neighbours are done too).
//!
//! Splitting a large copy into chunks lets the consumer's host→device copy of chunk i run while
//! the producer's device→host copy of chunk i+1 is still going (the two PCIe directions of two
//! GPUs overlap instead of adding up).

use std::collections::HashMap;
use std::ops::Range;

use crate::device::QueueKind;
use crate::plan::{AllocId, CopyId, ExecOp, ExecutionPlan, InstanceId};

/// A row band of a copy moved by one submission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chunk {
    pub copy: CopyId,
    pub index: u32,
    /// Region relative to the image (absolute `y`).
    pub y0: u32,
    pub y1: u32,
}

/// What a segment records, in order (the executor puts barriers and timestamp pairs between
/// the items: `Barriers`, `Timing`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Item {
    Pass(InstanceId),
    CopyOut(Chunk),
    CopyIn(Chunk),
}

/// A wait on the consumer-side "ready" timeline of a copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadyWait {
    pub copy: CopyId,
    pub chunk: u32,
}

/// One submission of a device program.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Segment {
    /// Queue the segment is submitted to.
    pub queue: QueueKind,
    pub items: Vec<Item>,
    pub waits: Vec<ReadyWait>,
    /// Copy-out chunks completed by this segment: the relay signals their consumer once this
    /// segment's progress value is reached.
    pub relays: Vec<Chunk>,
}

impl Default for Segment {
    fn default() -> Self {
        Self { queue: QueueKind::Main, items: Vec::new(), waits: Vec::new(), relays: Vec::new() }
    }
}

impl Item {
    /// Queue of the item when copies have a queue of their own. A copy into a depth image stays
    /// on the main queue: a queue without graphics may not write the depth aspect
    /// (VUID-vkCmdCopyBufferToImage-commandBuffer-07737).
    fn queue(self, plan: &ExecutionPlan, separate_copy_queue: bool) -> QueueKind {
        match self {
            Item::Pass(_) => QueueKind::Main,
            Item::CopyIn(chunk) if plan.resource(plan.copy(chunk.copy).dst).format.is_depth() => QueueKind::Main,
            Item::CopyOut(_) | Item::CopyIn(_) if separate_copy_queue => QueueKind::Copy,
            Item::CopyOut(_) | Item::CopyIn(_) => QueueKind::Main,
        }
    }
}

/// Row bands of each copy (`[c]` for copy `CopyId(c)`): at most `chunk_bytes` per band (at
/// least one row), see [`band_rows`].
pub fn chunks_of_copies(plan: &ExecutionPlan, chunk_bytes: u64) -> Vec<Vec<Chunk>> {
    plan.copies
        .iter()
        .enumerate()
        .map(|(c, copy)| {
            let c = CopyId(c as u32);
            let row_bytes = plan.resource(copy.resource).row_bytes().max(1);
            let rows_per_chunk = (chunk_bytes / row_bytes).clamp(1, u64::from(u32::MAX)) as u32;
            let mut y0 = copy.rows.y0;
            band_rows(copy.rows.y1 - copy.rows.y0, rows_per_chunk)
                .into_iter()
                .enumerate()
                .map(|(index, rows)| {
                    let chunk = Chunk { copy: c, index: index as u32, y0, y1: y0 + rows };
                    y0 += rows;
                    chunk
                })
                .collect()
        })
        .collect()
}

/// Heights of the bands a copy of `total` rows is cut into: full bands of `rows_per_chunk`,
/// tapering to a half, a quarter and an eighth of that at the end. The consumer uploads a band
/// only after the producer has downloaded it, so the last band's upload is pure latency on the
/// copy's critical path; small last bands shorten it while full bands keep per-band overhead
/// low (64 MiB between two H200s: 42 GB/s with uniform 8 MiB bands, docs/RESULTS.md).
pub fn band_rows(total: u32, rows_per_chunk: u32) -> Vec<u32> {
    let rows_per_chunk = rows_per_chunk.max(1);
    let mut tail = Vec::new();
    let mut rest = total;
    for shift in [3, 2, 1] {
        let rows = (rows_per_chunk >> shift).max(1);
        // Saturating: one chunk for the whole copy (`bench-copy --chunk-mib 0`) is u32::MAX rows.
        if rest > rows_per_chunk.saturating_add(rows) && (tail.is_empty() || tail.last() != Some(&rows)) {
            tail.push(rows);
            rest -= rows;
        }
    }
    let mut bands = Vec::new();
    if rest % rows_per_chunk != 0 {
        bands.push(rest % rows_per_chunk);
    }
    bands.extend(std::iter::repeat_n(rows_per_chunk, (rest / rows_per_chunk) as usize));
    bands.extend(tail.into_iter().rev());
    bands
}

/// Value the ready timeline of a link (links.rs) reaches when the chunk at `position` among
/// the link's `per_frame` chunks of frame `frame` is in host memory.
pub fn ready_value(frame: u64, per_frame: u64, position: u64) -> u64 {
    frame * per_frame + position + 1
}

/// Value the progress timeline of a device reaches when segment `segment` of `frame` is done.
pub fn progress_value(frame: u64, segments: usize, segment: usize) -> u64 {
    frame * segments as u64 + segment as u64 + 1
}

/// Cuts every device's op list ([`segment_device`]), with the small copies of each pass's runs
/// batched ([`recording_order`]) unless that makes the devices wait on each other in a cycle
/// (a run's hoisted wait for a copy whose producer needs the run's own deferred output); then
/// every copy stays in place, as the schedule lowered it (and under fault injection).
pub fn segment_devices(
    plan: &ExecutionPlan,
    chunks: &[Vec<Chunk>],
    merge_bytes: u64,
    dropped_wait: Option<CopyId>,
    separate_copy_queue: bool,
) -> Vec<Vec<Segment>> {
    let cut = |batched: bool| -> Vec<Vec<Segment>> {
        (0..plan.devices.len())
            .map(|d| segment_device(plan, d, chunks, merge_bytes, dropped_wait, separate_copy_queue, batched))
            .collect()
    };
    // A dropped wait (fault injection) comes with a gate whose extra wait the trial below cannot
    // see: the injected fault keeps the schedule's own order.
    if dropped_wait.is_some() {
        return cut(false);
    }
    let batched = cut(true);
    if submission_order(&cross_device_waits(&batched)).is_some() { batched } else { cut(false) }
}

/// Cuts `device`'s op list; consecutive single-chunk copies of one direction share a segment
/// up to `merge_bytes`, and with `batched` they gather at the ends of each pass's runs.
/// `dropped_wait` (fault injection) leaves out the ready waits of one copy. With
/// `separate_copy_queue`, copies go to [`QueueKind::Copy`] and a segment never mixes the two
/// queues (the executor orders segments of different queues by the progress timeline).
pub fn segment_device(
    plan: &ExecutionPlan,
    device: usize,
    chunks: &[Vec<Chunk>],
    merge_bytes: u64,
    dropped_wait: Option<CopyId>,
    separate_copy_queue: bool,
    batched: bool,
) -> Vec<Segment> {
    let segments = segment_single_queue(plan, device, chunks, merge_bytes, dropped_wait, batched);
    if !separate_copy_queue {
        return segments;
    }
    let mut split = Vec::new();
    for segment in segments {
        let mut pieces: Vec<Segment> = Vec::new();
        for item in segment.items {
            let queue = item.queue(plan, true);
            match pieces.last_mut() {
                Some(piece) if piece.queue == queue => piece.items.push(item),
                _ => pieces.push(Segment { queue, items: vec![item], ..Segment::default() }),
            }
        }
        // Waits guard the segment's first item (a copy-in); relays belong to its last item (a
        // copy-out chunk).
        if let Some(first) = pieces.first_mut() {
            first.waits = segment.waits;
        }
        if let Some(last) = pieces.last_mut() {
            last.relays = segment.relays;
        }
        split.extend(pieces);
    }
    split
}

/// What the segment being cut can still take: more small copy-ins (while it holds only those)
/// or more small copy-outs (at its end), and how many bytes of them it holds.
#[derive(Clone, Copy)]
enum Tail {
    Closed,
    CopyIns(u64),
    CopyOuts(u64),
}

/// Device `device`'s ops in recording order: the plan's, except within a run of instances of
/// one pass (one kernel and name), which is recorded as a batch:
/// * the copy-outs and signals that separate two instances move down to the end of the run,
///   when the later instances write nothing they copy;
/// * with `batch(c)` for a copy `c` (small copies when the schedule is batched, see
///   [`segment_devices`]), its wait and copy-in move up to the start of the run, when no
///   instance they pass reads or writes what it copies into.
///
/// Copies that are not batched keep their place: a wait for one ends the run. Always batched
/// are the copy-outs of kernels that record groups ([`PassKernel::records_groups`]): lowering
/// puts the gather of each band right after the pass that finishes it, which would cut a
/// device's hole filling into one op per target band.
///
/// Why batch at all: the fine schemes give every (view, stage) its own copies; recorded in
/// place, one stage of a 100-view light field on 4 devices is hundreds of submissions per
/// device, each a cross-device hop whose latency (not its bytes) sets the frame time. Batched,
/// a stage is a few submissions: its copy-ins, its passes, its copy-outs.
///
/// [`PassKernel::records_groups`]: crate::PassKernel::records_groups
pub(crate) fn recording_order(plan: &ExecutionPlan, device: usize, batch: &dyn Fn(CopyId) -> bool) -> Vec<ExecOp> {
    let groups = |p: InstanceId| plan.kernels.0.get(plan.pass(p).kernel).is_some_and(|k| k.records_groups());
    let same_pass = |a: InstanceId, b: InstanceId| {
        let (a, b) = (plan.pass(a), plan.pass(b));
        a.kernel == b.kernel && a.name == b.name
    };
    let touches = |p: InstanceId, resource: AllocId| {
        let pass = plan.pass(p);
        pass.reads.iter().chain(&pass.writes).chain(&pass.history_reads).any(|a| a.resource == resource)
    };
    let ops = &plan.devices[device];
    let mut order: Vec<ExecOp> = Vec::with_capacity(ops.len());
    let mut run = Batch::default();
    let mut i = 0;
    while i < ops.len() {
        let op = ops[i];
        match op {
            ExecOp::Pass(p)
                if run.first.is_some_and(|first| same_pass(first, p))
                    && !plan.pass(p).writes.iter().any(|w| run.copied.contains(&w.resource)) =>
            {
                order.push(op);
            }
            ExecOp::CopyOut(c) if run.defers(groups, batch, c) => {
                run.copied.push(plan.copy(c).resource);
                run.deferred.push(op);
            }
            ExecOp::Signal(c) if run.defers(groups, batch, c) => run.deferred.push(op),
            ExecOp::Wait(c)
                if run.first.is_some_and(|first| batch(c) && next_pass_continues(ops, i + 2, first, &same_pass))
                    && ops.get(i + 1) == Some(&ExecOp::CopyIn(c))
                    && !order[run.start..]
                        .iter()
                        .any(|&o| matches!(o, ExecOp::Pass(p) if touches(p, plan.copy(c).dst)))
                    && !run.copied.contains(&plan.copy(c).dst) =>
            {
                run.hoisted.extend([op, ExecOp::CopyIn(c)]);
                i += 1;
            }
            _ => {
                run.close(&mut order);
                if let ExecOp::Pass(p) = op {
                    run.first = Some(p);
                    run.start = order.len();
                }
                order.push(op);
            }
        }
        i += 1;
    }
    run.close(&mut order);
    order
}

/// The run of one pass that [`recording_order`] is batching.
#[derive(Default)]
struct Batch {
    /// Its first instance; `None` between runs.
    first: Option<InstanceId>,
    /// Where that instance is in the recording order.
    start: usize,
    /// Copy-outs and signals held back to the end of the run, and the resources they read.
    deferred: Vec<ExecOp>,
    copied: Vec<AllocId>,
    /// Waits and copy-ins moved up to the start of the run.
    hoisted: Vec<ExecOp>,
}

impl Batch {
    fn defers(&self, groups: impl Fn(InstanceId) -> bool, batch: &dyn Fn(CopyId) -> bool, copy: CopyId) -> bool {
        self.first.is_some_and(|first| groups(first) || batch(copy))
    }

    fn close(&mut self, order: &mut Vec<ExecOp>) {
        order.splice(self.start..self.start, self.hoisted.drain(..));
        order.append(&mut self.deferred);
        self.copied.clear();
        self.first = None;
    }
}

/// Whether the op after a wait and its copy-in (at `next`) is another instance of the run's
/// pass (or more copy-ins that lead to one): only then is the copy-in part of the run.
fn next_pass_continues(
    ops: &[ExecOp],
    mut next: usize,
    first: InstanceId,
    same_pass: &dyn Fn(InstanceId, InstanceId) -> bool,
) -> bool {
    while let Some(op) = ops.get(next) {
        match *op {
            ExecOp::Wait(_) | ExecOp::CopyIn(_) => next += 1,
            ExecOp::Pass(p) => return same_pass(first, p),
            ExecOp::CopyOut(_) | ExecOp::Signal(_) => return false,
        }
    }
    false
}

fn segment_single_queue(
    plan: &ExecutionPlan,
    device: usize,
    chunks: &[Vec<Chunk>],
    merge_bytes: u64,
    dropped_wait: Option<CopyId>,
    batched: bool,
) -> Vec<Segment> {
    // A copy of one chunk shares its submission with its neighbours of the same direction, up
    // to `merge_bytes` together: the fine schemes send thousands of small copies per frame,
    // and a submission each is most of their cost. A chunked copy keeps a submission per chunk
    // (its chunks overlap across the two devices); the fault's copy keeps its own.
    let small = |c: CopyId| chunks[c.index()].len() == 1 && dropped_wait != Some(c);
    let bytes =
        |chunk: &Chunk| plan.resource(plan.copy(chunk.copy).resource).row_bytes() * u64::from(chunk.y1 - chunk.y0);
    let mut segments = Vec::new();
    let mut current = Segment::default();
    let mut tail = Tail::Closed;
    let batch = |c: CopyId| batched && small(c);
    for op in &recording_order(plan, device, &batch) {
        match *op {
            ExecOp::Pass(p) => {
                // A copy-out ends its segment: the relay forwards it once the segment is done.
                if !current.relays.is_empty() {
                    segments.push(std::mem::take(&mut current));
                }
                current.items.push(Item::Pass(p));
                tail = Tail::Closed;
            }
            ExecOp::CopyOut(c) => {
                for &chunk in &chunks[c.index()] {
                    let held = match tail {
                        Tail::CopyOuts(held) if small(c) && held.saturating_add(bytes(&chunk)) <= merge_bytes => {
                            Some(held)
                        }
                        _ => None,
                    };
                    if !current.relays.is_empty() && held.is_none() {
                        segments.push(std::mem::take(&mut current));
                    }
                    current.items.push(Item::CopyOut(chunk));
                    current.relays.push(chunk);
                    tail = if small(c) { Tail::CopyOuts(held.unwrap_or(0) + bytes(&chunk)) } else { Tail::Closed };
                }
            }
            // The producer's signal is sent per chunk, right after the chunk's copy; the wait is
            // placed on the copy-in itself, the only command that reads the host buffer.
            ExecOp::Signal(_) | ExecOp::Wait(_) => {}
            ExecOp::CopyIn(c) => {
                for &chunk in &chunks[c.index()] {
                    // A wait applies to a whole submission: a copy-in starts one, unless it joins
                    // the small copy-ins that the current one starts with.
                    let held = match tail {
                        Tail::CopyIns(held) if small(c) && held.saturating_add(bytes(&chunk)) <= merge_bytes => {
                            Some(held)
                        }
                        _ => None,
                    };
                    if !current.items.is_empty() && held.is_none() {
                        segments.push(std::mem::take(&mut current));
                    }
                    if dropped_wait != Some(c) {
                        current.waits.push(ReadyWait { copy: c, chunk: chunk.index });
                    }
                    current.items.push(Item::CopyIn(chunk));
                    tail = if small(c) { Tail::CopyIns(held.unwrap_or(0) + bytes(&chunk)) } else { Tail::Closed };
                }
            }
        }
    }
    if !current.items.is_empty() {
        segments.push(current);
    }
    segments
}

/// Consecutive segments of one device that the host submits before turning to another device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Run {
    pub device: usize,
    pub segments: Range<usize>,
}

/// For each device and segment, the segments of other devices whose copy-outs it waits for:
/// `(device, segment)` of the producer of every chunk its ready waits name.
pub fn cross_device_waits(segments: &[Vec<Segment>]) -> Vec<Vec<Vec<(usize, usize)>>> {
    let mut producer: HashMap<(CopyId, u32), (usize, usize)> = HashMap::new();
    for (d, device) in segments.iter().enumerate() {
        for (j, segment) in device.iter().enumerate() {
            for chunk in &segment.relays {
                producer.insert((chunk.copy, chunk.index), (d, j));
            }
        }
    }
    segments
        .iter()
        .map(|device| {
            device
                .iter()
                .map(|s| s.waits.iter().filter_map(|w| producer.get(&(w.copy, w.chunk)).copied()).collect())
                .collect()
        })
        .collect()
}

/// The order the host submits one frame's segments in: every device's segments in program
/// order, and each segment only after every segment it waits for (`waits`, from
/// [`cross_device_waits`]) has been submitted. So no submitted wait ever depends on a
/// submission the host has not made yet, and everything submitted can complete. Submitting a
/// whole device's frame before the next device's instead leaves the first device's queue
/// blocked on waits whose signals are not even submitted; a driver whose queue holds a bounded
/// number of submissions then blocks vkQueueSubmit for good (NVIDIA: until the watchdog calls
/// the device lost). Each device runs as far as it can before the next takes over, so runs are
/// long where the waits allow. `None` when the waits form a cycle (a schedule that
/// `Schedule::validate` refuses).
pub fn submission_order(waits: &[Vec<Vec<(usize, usize)>>]) -> Option<Vec<Run>> {
    let mut next = vec![0usize; waits.len()];
    let mut runs = Vec::new();
    loop {
        let mut advanced = false;
        for device in 0..waits.len() {
            let start = next[device];
            while next[device] < waits[device].len()
                && waits[device][next[device]].iter().all(|&(producer, segment)| segment < next[producer])
            {
                next[device] += 1;
            }
            if next[device] > start {
                runs.push(Run { device, segments: start..next[device] });
                advanced = true;
            }
        }
        if next.iter().zip(waits).all(|(n, w)| *n == w.len()) {
            return Some(runs);
        }
        if !advanced {
            return None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::copy_plan;

    #[test]
    fn large_copy_is_chunked_and_every_chunk_is_its_own_submission() {
        let plan = copy_plan(256, 256).unwrap(); // 1 MiB
        let chunks = chunks_of_copies(&plan, 256 * 1024); // 64 rows per chunk
        let heights: Vec<u32> = chunks[0].iter().map(|c| c.y1 - c.y0).collect();
        assert_eq!(heights, band_rows(256, 64));
        assert_eq!(chunks[0].last().map(|c| c.y1), Some(256));
        let n = chunks[0].len();
        let producer = segment_device(&plan, 0, &chunks, 256 * 1024, None, false, false);
        assert_eq!(producer.len(), n);
        assert_eq!(producer[0].items.len(), 2, "fill + first chunk");
        assert!(producer.iter().all(|s| s.relays.len() == 1 && s.waits.is_empty()));
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, false, false);
        assert_eq!(consumer.len(), n);
        for (i, s) in consumer.iter().enumerate() {
            assert_eq!(s.waits, vec![ReadyWait { copy: CopyId(0), chunk: i as u32 }]);
        }
        let dropped = segment_device(&plan, 1, &chunks, 256 * 1024, Some(CopyId(0)), false, false);
        assert!(dropped.iter().all(|s| s.waits.is_empty()));
    }

    #[test]
    fn grouped_passes_move_up_past_copy_outs_of_what_they_do_not_write() {
        use crate::plan::{DeviceId, ExecCopy, Region};
        // Four fills writing 1, 3, 1 (a second band of the first view) and 5, then a pass that
        // does not record groups.
        let mut plan = crate::record::grouping_plans::plan(&[
            ("fill", &[0], &[1]),
            ("fill", &[2], &[3]),
            ("fill", &[0], &[5]),
            ("fill", &[0], &[1]),
            ("fill", &[6], &[7]),
            ("tonemap", &[1], &[9]),
        ]);
        let copy = |resource| ExecCopy {
            resource: AllocId(resource),
            dst: AllocId(resource),
            version: 1,
            rows: Region::new(0, 1),
            from: DeviceId(0),
            to: DeviceId(1),
            gather: false,
        };
        plan.copies = vec![copy(1), copy(3), copy(9)];
        use ExecOp::{CopyOut, Pass, Signal, Wait};
        plan.devices[0] = vec![
            Pass(InstanceId(0)),
            CopyOut(CopyId(0)),
            Signal(CopyId(0)),
            Pass(InstanceId(1)),
            CopyOut(CopyId(1)),
            Signal(CopyId(1)),
            Pass(InstanceId(2)),
            // Writes what copy 0 reads: stays behind it, and starts the next group.
            Pass(InstanceId(3)),
            Wait(CopyId(2)),
            // Not past a wait.
            Pass(InstanceId(4)),
            Pass(InstanceId(5)),
        ];
        let expected = vec![
            Pass(InstanceId(0)),
            Pass(InstanceId(1)),
            Pass(InstanceId(2)),
            CopyOut(CopyId(0)),
            Signal(CopyId(0)),
            CopyOut(CopyId(1)),
            Signal(CopyId(1)),
            Pass(InstanceId(3)),
            Wait(CopyId(2)),
            Pass(InstanceId(4)),
            Pass(InstanceId(5)),
        ];
        assert_eq!(recording_order(&plan, 0, &|_| false), expected);
        // Copies between passes that do not record groups stay where they are.
        plan.passes.iter_mut().for_each(|p| p.kernel = 0);
        assert_eq!(recording_order(&plan, 0, &|_| false), plan.devices[0]);
    }

    #[test]
    fn batched_small_copies_gather_at_the_ends_of_a_run_unless_an_instance_touches_them() {
        use crate::plan::{DeviceId, ExecCopy, Region};
        use ExecOp::{CopyIn, CopyOut, Pass, Signal, Wait};
        // A pass that does not record groups, over four views: each reads a band copied in
        // (resources 10..13) and writes what is copied out (1, 3, 5, 7); view 2 also reads 13,
        // which view 3's copy-in writes; then another pass.
        let mut plan = crate::record::grouping_plans::plan(&[
            ("atrous", &[10], &[1]),
            ("atrous", &[11], &[3]),
            ("atrous", &[12, 13], &[5]),
            ("atrous", &[13], &[7]),
            ("tonemap", &[7], &[9]),
        ]);
        let copy = |resource, dst| ExecCopy {
            resource: AllocId(resource),
            dst: AllocId(dst),
            version: 1,
            rows: Region::new(0, 1),
            from: DeviceId(0),
            to: DeviceId(1),
            gather: false,
        };
        plan.copies = vec![copy(1, 1), copy(3, 3), copy(5, 5), copy(7, 7), copy(20, 11), copy(21, 12), copy(22, 13)];
        plan.devices[0] = vec![
            Pass(InstanceId(0)),
            CopyOut(CopyId(0)),
            Signal(CopyId(0)),
            Wait(CopyId(4)),
            CopyIn(CopyId(4)),
            Pass(InstanceId(1)),
            CopyOut(CopyId(1)),
            Signal(CopyId(1)),
            Wait(CopyId(5)),
            CopyIn(CopyId(5)),
            Pass(InstanceId(2)),
            CopyOut(CopyId(2)),
            Signal(CopyId(2)),
            Wait(CopyId(6)),
            CopyIn(CopyId(6)),
            Pass(InstanceId(3)),
            CopyOut(CopyId(3)),
            Signal(CopyId(3)),
            Pass(InstanceId(4)),
        ];
        let batched = vec![
            Wait(CopyId(4)),
            CopyIn(CopyId(4)),
            Wait(CopyId(5)),
            CopyIn(CopyId(5)),
            Pass(InstanceId(0)),
            Pass(InstanceId(1)),
            Pass(InstanceId(2)),
            CopyOut(CopyId(0)),
            Signal(CopyId(0)),
            CopyOut(CopyId(1)),
            Signal(CopyId(1)),
            CopyOut(CopyId(2)),
            Signal(CopyId(2)),
            // Pass 2 reads 13, which copy 6 writes: it stays after pass 2 and ends the run.
            Wait(CopyId(6)),
            CopyIn(CopyId(6)),
            Pass(InstanceId(3)),
            CopyOut(CopyId(3)),
            Signal(CopyId(3)),
            Pass(InstanceId(4)),
        ];
        assert_eq!(recording_order(&plan, 0, &|_| true), batched);
        // A copy that is not batched (a large one) keeps its place, and its wait ends the run.
        let one_kept = vec![
            Wait(CopyId(4)),
            CopyIn(CopyId(4)),
            Pass(InstanceId(0)),
            Pass(InstanceId(1)),
            CopyOut(CopyId(0)),
            Signal(CopyId(0)),
            CopyOut(CopyId(1)),
            Signal(CopyId(1)),
            Wait(CopyId(5)),
            CopyIn(CopyId(5)),
            Pass(InstanceId(2)),
            CopyOut(CopyId(2)),
            Signal(CopyId(2)),
            Wait(CopyId(6)),
            CopyIn(CopyId(6)),
            Pass(InstanceId(3)),
            CopyOut(CopyId(3)),
            Signal(CopyId(3)),
            Pass(InstanceId(4)),
        ];
        assert_eq!(recording_order(&plan, 0, &|c| c != CopyId(5)), one_kept);
        // Nothing batched: the plan's order.
        assert_eq!(recording_order(&plan, 0, &|_| false), plan.devices[0]);
    }

    #[test]
    fn bands_cover_the_copy_and_taper_at_the_end() {
        for (total, per) in [(4096, 512), (100, 7), (5, 8), (513, 512), (1, 1), (4096, 1), (0, 16)] {
            let bands = band_rows(total, per);
            assert_eq!(bands.iter().sum::<u32>(), total, "{total} rows in bands of {per}: {bands:?}");
            assert!(bands.iter().all(|&b| b >= 1 && b <= per.max(1)), "{bands:?}");
        }
        assert_eq!(band_rows(4096, 512), [vec![64], vec![512; 7], vec![256, 128, 64]].concat());
        assert_eq!(band_rows(512, 512), vec![512], "a copy that fits one band is not cut");
        assert_eq!(band_rows(100, u32::MAX), vec![100], "unbounded chunks: one band");
    }

    #[test]
    fn a_separate_copy_queue_never_mixes_queues_in_a_segment() {
        let plan = copy_plan(256, 256).unwrap();
        let chunks = chunks_of_copies(&plan, 256 * 1024);
        let producer = segment_device(&plan, 0, &chunks, 256 * 1024, None, true, false);
        let queues: Vec<QueueKind> = producer.iter().map(|s| s.queue).collect();
        let n = chunks[0].len();
        assert_eq!(queues, [vec![QueueKind::Main], vec![QueueKind::Copy; n]].concat());
        assert!(producer[0].relays.is_empty(), "the fill completes no chunk");
        assert!(producer[1..].iter().all(|s| s.relays.len() == 1 && s.items.len() == 1));
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, true, false);
        assert_eq!(consumer.len(), n + 1, "the copy-ins, then the receiving pass");
        assert!(consumer[..n].iter().all(|s| s.queue == QueueKind::Copy && s.waits.len() == 1));
        assert_eq!(consumer[n].queue, QueueKind::Main);
    }

    #[test]
    fn copies_into_depth_images_stay_on_the_main_queue() {
        let mut plan = copy_plan(64, 64).unwrap();
        for resource in &mut plan.resources {
            resource.format = crate::plan::Format::Depth32f;
        }
        let chunks = chunks_of_copies(&plan, 64 * 64);
        let producer = segment_device(&plan, 0, &chunks, 256 * 1024, None, true, false);
        assert!(producer[1..].iter().all(|s| s.queue == QueueKind::Copy), "copies out of depth may use the copy queue");
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, true, false);
        let copy_ins: Vec<&Segment> = consumer.iter().filter(|s| !s.waits.is_empty()).collect();
        assert!(!copy_ins.is_empty());
        assert!(copy_ins.iter().all(|s| s.queue == QueueKind::Main), "a transfer-only queue may not write depth");
    }

    #[test]
    fn timeline_values_are_distinct_and_increasing() {
        let mut last = 0;
        for frame in 0..3 {
            for segment in 0..4 {
                let v = progress_value(frame, 4, segment);
                assert!(v > last);
                last = v;
            }
        }
        assert_eq!(ready_value(2, 3, 1), 8, "the second of 3 chunks a frame, frame 2");
    }

    /// Device 0 waits for device 1's copy, which device 1 sends only after waiting for device
    /// 0's: the host must alternate, and a device never runs ahead of a segment it waits for.
    #[test]
    fn segments_are_submitted_after_the_segments_they_wait_for() {
        let waits = vec![vec![vec![], vec![(1, 1)], vec![]], vec![vec![], vec![(0, 0)], vec![(0, 2)]]];
        let order = submission_order(&waits).unwrap();
        assert_eq!(
            order,
            vec![
                Run { device: 0, segments: 0..1 },
                Run { device: 1, segments: 0..2 },
                Run { device: 0, segments: 1..3 },
                Run { device: 1, segments: 2..3 },
            ]
        );
        let cycle = vec![vec![vec![(1, 0)]], vec![vec![(0, 0)]]];
        assert_eq!(submission_order(&cycle), None);
    }

    #[test]
    fn the_consumer_of_a_copy_waits_for_the_segment_of_its_copy_out() {
        let plan = copy_plan(256, 256).unwrap();
        let chunks = chunks_of_copies(&plan, 256 * 1024);
        let segments: Vec<Vec<Segment>> =
            (0..2).map(|d| segment_device(&plan, d, &chunks, 256 * 1024, None, false, false)).collect();
        let waits = cross_device_waits(&segments);
        assert!(waits[0].iter().all(Vec::is_empty), "the producer waits for nobody");
        let expected: Vec<Vec<(usize, usize)>> = (0..chunks[0].len()).map(|i| vec![(0, i)]).collect();
        assert_eq!(waits[1], expected, "chunk i is copied out by the producer's segment i");
        let n = chunks[0].len();
        let order = submission_order(&waits).unwrap();
        assert_eq!(order, vec![Run { device: 0, segments: 0..n }, Run { device: 1, segments: 0..n }]);
    }

    /// Small copies in a row share a submission up to the byte cap; chunks of a chunked copy
    /// and the fault's copy do not.
    #[test]
    fn small_copies_in_a_row_share_a_segment_up_to_the_cap() {
        let plan = crate::bench::gather_plan(3, 64, 64).unwrap(); // 64 KiB per copy
        let chunks = chunks_of_copies(&plan, 256 * 1024);
        assert!(chunks.iter().all(|c| c.len() == 1));
        let copy_ins = |s: &Segment| s.items.iter().filter(|i| matches!(i, Item::CopyIn(_))).count();
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, false, false);
        assert_eq!(consumer.len(), 1, "three copy-ins and the receiving pass: {consumer:?}");
        assert_eq!((copy_ins(&consumer[0]), consumer[0].waits.len()), (3, 3));
        let capped = segment_device(&plan, 1, &chunks, 128 * 1024, None, false, false);
        assert_eq!(capped.iter().map(copy_ins).collect::<Vec<_>>(), vec![2, 1]);
        assert!(capped.iter().all(|s| s.waits.len() == copy_ins(s)));
        let copy = match capped[0].items[0] {
            Item::CopyIn(chunk) => chunk.copy,
            _ => unreachable!("a copy-in starts the segment"),
        };
        let faulty = segment_device(&plan, 1, &chunks, 256 * 1024, Some(copy), false, false);
        assert_eq!(faulty.iter().map(copy_ins).collect::<Vec<_>>(), vec![1, 2], "the fault's copy alone");
        // Producer: a pass between the copy-outs; each copy-out ends its segment.
        let producer = segment_device(&plan, 0, &chunks, 256 * 1024, None, false, false);
        assert!(producer.iter().all(|s| s.relays.len() == 1));
        // A chunked copy: one segment per chunk, whatever the cap.
        let big = copy_plan(256, 256).unwrap();
        let big_chunks = chunks_of_copies(&big, 256 * 1024);
        let consumer = segment_device(&big, 1, &big_chunks, u64::MAX, None, false, false);
        assert_eq!(consumer.len(), big_chunks[0].len());
    }
}
