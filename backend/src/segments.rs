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
//! to `merge_bytes` together (a copy-out's relay then fires when its neighbours are done too),
//! and between the copies of one batch (`ExecutionPlan::batches`), which share one whatever
//! their bytes.
//!
//! Splitting a large copy into chunks lets the consumer's host→device copy of chunk i run while
//! the producer's device→host copy of chunk i+1 is still going (the two PCIe directions of two
//! GPUs overlap instead of adding up).

use std::collections::HashMap;
use std::ops::Range;

use crate::device::QueueKind;
use crate::plan::{BatchId, CopyId, ExecutionPlan, InstanceId, Op};

/// A row band of a copy moved by one submission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chunk {
    pub copy: CopyId,
    pub index: u32,
    /// Region relative to the image (absolute `y`).
    pub y0: u32,
    pub y1: u32,
}

impl Chunk {
    /// Rows the chunk moves.
    pub fn rows(&self) -> u32 {
        self.y1 - self.y0
    }
}

/// Bytes `chunk` moves: its rows of its copy's source ([`crate::ExecResource::rows_bytes`]).
pub(crate) fn chunk_bytes(plan: &ExecutionPlan, chunk: &Chunk) -> u64 {
    plan.resource(plan.copy(chunk.copy).src_alloc).rows_bytes(chunk.rows())
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
    /// Indices of the items the schedule puts a memory barrier before (`DeviceProgram::barriers`),
    /// increasing. The executor also puts one before the first item (it follows other
    /// submissions) and around kernels that touch undeclared memory.
    pub barriers: Vec<usize>,
    pub waits: Vec<ReadyWait>,
    /// Copy-out chunks completed by this segment: the relay signals their consumer once this
    /// segment's progress value is reached.
    pub relays: Vec<Chunk>,
}

impl Default for Segment {
    fn default() -> Self {
        Self { queue: QueueKind::Main, items: Vec::new(), barriers: Vec::new(), waits: Vec::new(), relays: Vec::new() }
    }
}

impl Segment {
    /// Appends `item`, after a barrier when `barrier` is set (which it then clears).
    fn push(&mut self, item: Item, barrier: &mut bool) {
        if std::mem::take(barrier) {
            self.barriers.push(self.items.len());
        }
        self.items.push(item);
    }

    /// Whether the schedule puts a barrier before item `index`.
    pub fn barrier_before(&self, index: usize) -> bool {
        self.barriers.binary_search(&index).is_ok()
    }
}

impl Item {
    /// Queue of the item when copies have a queue of their own. A copy into a depth image stays
    /// on the main queue: a queue without graphics may not write the depth aspect
    /// (VUID-vkCmdCopyBufferToImage-commandBuffer-07737).
    fn queue(self, plan: &ExecutionPlan, separate_copy_queue: bool) -> QueueKind {
        match self {
            Item::Pass(_) => QueueKind::Main,
            Item::CopyIn(chunk) if plan.resource(plan.copy(chunk.copy).dst_alloc).format.is_depth() => QueueKind::Main,
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
            let row_bytes = plan.resource(copy.src_alloc).row_bytes().max(1);
            let rows_per_chunk = (chunk_bytes / row_bytes).clamp(1, u64::from(u32::MAX)) as u32;
            let mut y0 = copy.region.y0;
            band_rows(copy.region.len(), rows_per_chunk)
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

/// Cuts every device's op list ([`segment_device`]), in the plan's order: the schedule's, which
/// batching already ordered when it was compiled (`parallax_graph::CompileOptions`).
pub fn segment_devices(
    plan: &ExecutionPlan,
    chunks: &[Vec<Chunk>],
    merge_bytes: u64,
    dropped_wait: Option<CopyId>,
    separate_copy_queue: bool,
) -> Vec<Vec<Segment>> {
    (0..plan.devices.len())
        .map(|d| segment_device(plan, d, chunks, merge_bytes, dropped_wait, separate_copy_queue))
        .collect()
}

/// Cuts `device`'s op list, in its order; consecutive single-chunk copies of one direction share
/// a segment up to `merge_bytes`.
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
) -> Vec<Segment> {
    let segments = segment_single_queue(plan, device, chunks, merge_bytes, dropped_wait);
    if !separate_copy_queue {
        return segments;
    }
    let mut split = Vec::new();
    for segment in segments {
        let mut pieces: Vec<Segment> = Vec::new();
        for (index, &item) in segment.items.iter().enumerate() {
            let queue = item.queue(plan, true);
            if pieces.last().is_none_or(|piece| piece.queue != queue) {
                pieces.push(Segment { queue, ..Segment::default() });
            }
            let mut barrier = segment.barrier_before(index);
            pieces.last_mut().expect("a piece for the item").push(item, &mut barrier);
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

fn segment_single_queue(
    plan: &ExecutionPlan,
    device: usize,
    chunks: &[Vec<Chunk>],
    merge_bytes: u64,
    dropped_wait: Option<CopyId>,
) -> Vec<Segment> {
    // A copy of one chunk shares its submission with its neighbours of the same direction, up
    // to `merge_bytes` together: the fine schemes send thousands of small copies per frame,
    // and a submission each is most of their cost. A chunked copy keeps a submission per chunk
    // (its chunks overlap across the two devices); the fault's copy keeps its own.
    // A batch's copies (ExecutionPlan::batches) share one submission whatever their bytes:
    // the batch is one transfer.
    let small = |c: CopyId| chunks[c.index()].len() == 1 && dropped_wait != Some(c);
    let batch_of = plan.batch_of_copies();
    let mut last_batch: Option<BatchId> = None;
    let joins_batch = |last: Option<BatchId>, c: CopyId| last.is_some() && batch_of[c.index()] == last;
    let mut segments = Vec::new();
    let mut current = Segment::default();
    let mut tail = Tail::Closed;
    let program = &plan.devices[device];
    let mut barriers = program.barriers.iter().peekable();
    // A barrier stands before the next item pushed.
    let mut barrier = false;
    for (index, op) in program.ops.iter().enumerate() {
        barrier |= barriers.next_if(|&&b| b as usize == index).is_some();
        match *op {
            Op::Pass(p) => {
                // A copy-out ends its segment: the relay forwards it once the segment is done.
                if !current.relays.is_empty() {
                    segments.push(std::mem::take(&mut current));
                }
                current.push(Item::Pass(p), &mut barrier);
                tail = Tail::Closed;
                last_batch = None;
            }
            Op::CopyOut(c) => {
                for &chunk in &chunks[c.index()] {
                    let held = match tail {
                        Tail::CopyOuts(held)
                            if small(c)
                                && (joins_batch(last_batch, c)
                                    || held.saturating_add(chunk_bytes(plan, &chunk)) <= merge_bytes) =>
                        {
                            Some(held)
                        }
                        _ => None,
                    };
                    if !current.relays.is_empty() && held.is_none() {
                        segments.push(std::mem::take(&mut current));
                    }
                    current.push(Item::CopyOut(chunk), &mut barrier);
                    current.relays.push(chunk);
                    tail = if small(c) {
                        Tail::CopyOuts(held.unwrap_or(0) + chunk_bytes(plan, &chunk))
                    } else {
                        Tail::Closed
                    };
                    last_batch = batch_of[c.index()];
                }
            }
            // The producer's signal is sent per chunk, right after the chunk's copy; the wait is
            // placed on the copy-in itself, the only command that reads the host buffer.
            Op::Signal(_) | Op::Wait(_) => {}
            Op::CopyIn(c) => {
                for &chunk in &chunks[c.index()] {
                    // A wait applies to a whole submission: a copy-in starts one, unless it joins
                    // the small copy-ins that the current one starts with.
                    let held = match tail {
                        Tail::CopyIns(held)
                            if small(c)
                                && (joins_batch(last_batch, c)
                                    || held.saturating_add(chunk_bytes(plan, &chunk)) <= merge_bytes) =>
                        {
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
                    current.push(Item::CopyIn(chunk), &mut barrier);
                    tail = if small(c) {
                        Tail::CopyIns(held.unwrap_or(0) + chunk_bytes(plan, &chunk))
                    } else {
                        Tail::Closed
                    };
                    last_batch = batch_of[c.index()];
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
        let producer = segment_device(&plan, 0, &chunks, 256 * 1024, None, false);
        assert_eq!(producer.len(), n);
        assert_eq!(producer[0].items.len(), 2, "fill + first chunk");
        assert!(producer.iter().all(|s| s.relays.len() == 1 && s.waits.is_empty()));
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, false);
        assert_eq!(consumer.len(), n);
        for (i, s) in consumer.iter().enumerate() {
            assert_eq!(s.waits, vec![ReadyWait { copy: CopyId(0), chunk: i as u32 }]);
        }
        let dropped = segment_device(&plan, 1, &chunks, 256 * 1024, Some(CopyId(0)), false);
        assert!(dropped.iter().all(|s| s.waits.is_empty()));
    }

    /// The backend submits each device's ops in the plan's order, which is the schedule's
    /// (batching included), with the schedule's barriers before the same ops: cutting segments
    /// and chunks changes no order and moves no barrier.
    #[test]
    fn segments_submit_each_device_s_ops_and_barriers_in_the_plan_s_order() {
        use Op::{CopyIn, CopyOut, Pass, Signal, Wait};
        let plan = crate::bench::gather_plan(3, 64, 256).unwrap(); // 256 KiB per copy
        // The schedule batched device 0's run of fills: its copy-outs follow the whole run, after
        // one barrier (they read what the fills wrote); the fills share the frame's first one.
        let batched = [Pass(InstanceId(0)), Pass(InstanceId(1)), Pass(InstanceId(2)), CopyOut(CopyId(0))];
        assert_eq!(plan.devices[0].ops[..4], batched);
        assert_eq!(plan.devices[0].barriers[..2], [0, 3]);
        // Each op submitted, with whether a barrier precedes it: a barrier before a signal or a
        // wait (recorded on no command buffer) guards the next op submitted.
        let planned = |d: usize| {
            let program = &plan.devices[d];
            let mut guarded = false;
            let mut steps: Vec<(bool, Op)> = Vec::new();
            for (index, &op) in program.ops.iter().enumerate() {
                guarded |= program.barriers.contains(&(index as u32));
                if !matches!(op, Signal(_) | Wait(_)) {
                    steps.push((std::mem::take(&mut guarded), op));
                }
            }
            steps
        };
        for chunk_bytes in [64 << 10, 1 << 20] {
            let chunks = chunks_of_copies(&plan, chunk_bytes);
            for separate_copy_queue in [false, true] {
                let cut = segment_devices(&plan, &chunks, chunk_bytes, None, separate_copy_queue);
                for (d, segments) in cut.iter().enumerate() {
                    let mut submitted: Vec<(bool, Op)> = Vec::new();
                    for segment in segments {
                        for (index, item) in segment.items.iter().enumerate() {
                            let op = match *item {
                                Item::Pass(p) => Pass(p),
                                Item::CopyOut(chunk) => CopyOut(chunk.copy),
                                Item::CopyIn(chunk) => CopyIn(chunk.copy),
                            };
                            // A copy's chunks are consecutive items; the first carries its barrier.
                            if submitted.last().is_none_or(|&(_, last)| last != op) {
                                submitted.push((segment.barrier_before(index), op));
                            }
                        }
                    }
                    assert_eq!(submitted, planned(d), "device {d}, chunks of {chunk_bytes} B");
                }
            }
        }
    }

    /// A batch is one transfer: its copies share a submission on each side even past
    /// `merge_bytes`, where the same copies unbatched take one each.
    #[test]
    fn a_batch_is_one_submission_whatever_its_bytes() {
        let mut plan = crate::bench::gather_plan(3, 64, 256).unwrap(); // 256 KiB per copy
        assert_eq!(plan.batches.len(), 1, "the schedule batches the three copies 0 → 1");
        assert_eq!(plan.batches[0].copies, [CopyId(0), CopyId(1), CopyId(2)]);
        let chunks = chunks_of_copies(&plan, 1 << 20);
        let with_copies = |segments: &[Segment], out: bool| {
            segments
                .iter()
                .filter(|s| {
                    s.items.iter().any(|i| matches!((i, out), (Item::CopyOut(_), true) | (Item::CopyIn(_), false)))
                })
                .count()
        };
        let merge_bytes = 256 << 10;
        assert_eq!(with_copies(&segment_device(&plan, 0, &chunks, merge_bytes, None, false), true), 1);
        let consumer = segment_device(&plan, 1, &chunks, merge_bytes, None, false);
        assert_eq!(with_copies(&consumer, false), 1);
        plan.batches.clear();
        assert_eq!(with_copies(&segment_device(&plan, 0, &chunks, merge_bytes, None, false), true), 3);
        assert_eq!(with_copies(&segment_device(&plan, 1, &chunks, merge_bytes, None, false), false), 3);
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
        let producer = segment_device(&plan, 0, &chunks, 256 * 1024, None, true);
        let queues: Vec<QueueKind> = producer.iter().map(|s| s.queue).collect();
        let n = chunks[0].len();
        assert_eq!(queues, [vec![QueueKind::Main], vec![QueueKind::Copy; n]].concat());
        assert!(producer[0].relays.is_empty(), "the fill completes no chunk");
        assert!(producer[1..].iter().all(|s| s.relays.len() == 1 && s.items.len() == 1));
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, true);
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
        let producer = segment_device(&plan, 0, &chunks, 256 * 1024, None, true);
        assert!(producer[1..].iter().all(|s| s.queue == QueueKind::Copy), "copies out of depth may use the copy queue");
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, true);
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
            (0..2).map(|d| segment_device(&plan, d, &chunks, 256 * 1024, None, false)).collect();
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
        let mut plan = crate::bench::gather_plan(3, 64, 64).unwrap(); // 64 KiB per copy
        // Copies in no batch (a batch ignores the cap: a_batch_is_one_submission_whatever_its_bytes).
        plan.batches.clear();
        let chunks = chunks_of_copies(&plan, 256 * 1024);
        assert!(chunks.iter().all(|c| c.len() == 1));
        let copy_ins = |s: &Segment| s.items.iter().filter(|i| matches!(i, Item::CopyIn(_))).count();
        let consumer = segment_device(&plan, 1, &chunks, 256 * 1024, None, false);
        assert_eq!(consumer.len(), 1, "three copy-ins and the receiving pass: {consumer:?}");
        assert_eq!((copy_ins(&consumer[0]), consumer[0].waits.len()), (3, 3));
        let capped = segment_device(&plan, 1, &chunks, 128 * 1024, None, false);
        assert_eq!(capped.iter().map(copy_ins).collect::<Vec<_>>(), vec![2, 1]);
        assert!(capped.iter().all(|s| s.waits.len() == copy_ins(s)));
        let copy = match capped[0].items[0] {
            Item::CopyIn(chunk) => chunk.copy,
            _ => unreachable!("a copy-in starts the segment"),
        };
        let faulty = segment_device(&plan, 1, &chunks, 256 * 1024, Some(copy), false);
        assert_eq!(faulty.iter().map(copy_ins).collect::<Vec<_>>(), vec![1, 2], "the fault's copy alone");
        // Producer: the schedule batched the copy-outs after the run of fills; they join the
        // fills' segment up to the cap.
        let relays = |cap| -> Vec<usize> {
            segment_device(&plan, 0, &chunks, cap, None, false).iter().map(|s| s.relays.len()).collect()
        };
        assert_eq!(relays(256 * 1024), vec![3]);
        assert_eq!(relays(128 * 1024), vec![2, 1]);
        // A chunked copy: one segment per chunk, whatever the cap.
        let big = copy_plan(256, 256).unwrap();
        let big_chunks = chunks_of_copies(&big, 256 * 1024);
        let consumer = segment_device(&big, 1, &big_chunks, u64::MAX, None, false);
        assert_eq!(consumer.len(), big_chunks[0].len());
    }
}
