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
//! Splitting a large copy into chunks lets the consumer's host→device copy of chunk i run while
//! the producer's device→host copy of chunk i+1 is still going (the two PCIe directions of two
//! GPUs overlap instead of adding up).

use crate::device::QueueKind;
use crate::plan::{Plan, PlanOp};

/// A row band of a copy moved by one submission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chunk {
    pub copy: usize,
    pub index: u32,
    /// Rows relative to the image (absolute `y`).
    pub y0: u32,
    pub y1: u32,
}

/// What a segment records, in order (the executor puts a barrier before each item and a
/// timestamp pair around it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Item {
    Pass(usize),
    CopyOut(Chunk),
    CopyIn(Chunk),
}

/// A wait on the consumer-side "ready" timeline of a copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadyWait {
    pub copy: usize,
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
    /// Queue of the item when copies have a queue of their own.
    fn queue(self, separate_copy_queue: bool) -> QueueKind {
        match self {
            Item::Pass(_) => QueueKind::Main,
            Item::CopyOut(_) | Item::CopyIn(_) if separate_copy_queue => QueueKind::Copy,
            Item::CopyOut(_) | Item::CopyIn(_) => QueueKind::Main,
        }
    }
}

/// Row bands of each copy: at most `chunk_bytes` per band (at least one row).
pub fn chunks_of_copies(plan: &Plan, chunk_bytes: u64) -> Vec<Vec<Chunk>> {
    plan.copies
        .iter()
        .enumerate()
        .map(|(c, copy)| {
            let row_bytes = plan.resources[copy.resource].row_bytes().max(1);
            let rows_per_chunk = (chunk_bytes / row_bytes).clamp(1, u64::from(u32::MAX)) as u32;
            let mut chunks = Vec::new();
            let mut y0 = copy.rows.y0;
            while y0 < copy.rows.y1 {
                let y1 = copy.rows.y1.min(y0.saturating_add(rows_per_chunk));
                chunks.push(Chunk { copy: c, index: chunks.len() as u32, y0, y1 });
                y0 = y1;
            }
            chunks
        })
        .collect()
}

/// Value the ready timeline of a copy reaches when chunk `chunk` of frame `frame` is in host
/// memory.
pub fn ready_value(frame: u64, chunks: usize, chunk: u32) -> u64 {
    frame * chunks as u64 + u64::from(chunk) + 1
}

/// Value the progress timeline of a device reaches when segment `segment` of `frame` is done.
pub fn progress_value(frame: u64, segments: usize, segment: usize) -> u64 {
    frame * segments as u64 + segment as u64 + 1
}

/// Cuts `device`'s op list. `dropped_wait` (fault injection) leaves out the ready waits of one
/// copy. With `separate_copy_queue`, copies go to [`QueueKind::Copy`] and a segment never mixes
/// the two queues (the executor orders segments of different queues by the progress timeline).
pub fn segment_device(
    plan: &Plan,
    device: usize,
    chunks: &[Vec<Chunk>],
    dropped_wait: Option<usize>,
    separate_copy_queue: bool,
) -> Vec<Segment> {
    let segments = segment_single_queue(plan, device, chunks, dropped_wait);
    if !separate_copy_queue {
        return segments;
    }
    let mut split = Vec::new();
    for segment in segments {
        let mut pieces: Vec<Segment> = Vec::new();
        for item in segment.items {
            let queue = item.queue(true);
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

fn segment_single_queue(
    plan: &Plan,
    device: usize,
    chunks: &[Vec<Chunk>],
    dropped_wait: Option<usize>,
) -> Vec<Segment> {
    let mut segments = Vec::new();
    let mut current = Segment::default();
    for op in &plan.devices[device] {
        match *op {
            PlanOp::Pass(p) => current.items.push(Item::Pass(p)),
            PlanOp::CopyOut(c) => {
                for &chunk in &chunks[c] {
                    current.items.push(Item::CopyOut(chunk));
                    current.relays.push(chunk);
                    segments.push(std::mem::take(&mut current));
                }
            }
            // The producer's signal is sent per chunk, right after the chunk's copy; the wait is
            // placed on the copy-in itself, the only command that reads the host buffer.
            PlanOp::Signal(_) | PlanOp::Wait(_) => {}
            PlanOp::CopyIn(c) => {
                for &chunk in &chunks[c] {
                    if !current.items.is_empty() {
                        segments.push(std::mem::take(&mut current));
                    }
                    if dropped_wait != Some(c) {
                        current.waits.push(ReadyWait { copy: c, chunk: chunk.index });
                    }
                    current.items.push(Item::CopyIn(chunk));
                }
            }
        }
    }
    if !current.items.is_empty() {
        segments.push(current);
    }
    segments
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demo::copy_benchmark;

    #[test]
    fn large_copy_is_chunked_and_every_chunk_is_its_own_submission() {
        let plan = copy_benchmark(256, 256); // 1 MiB
        let chunks = chunks_of_copies(&plan, 256 * 1024);
        assert_eq!(chunks[0].len(), 4);
        assert_eq!((chunks[0][3].y0, chunks[0][3].y1), (192, 256));
        let producer = segment_device(&plan, 0, &chunks, None, false);
        assert_eq!(producer.len(), 4);
        assert_eq!(producer[0].items.len(), 2, "fill + first chunk");
        assert!(producer.iter().all(|s| s.relays.len() == 1 && s.waits.is_empty()));
        let consumer = segment_device(&plan, 1, &chunks, None, false);
        assert_eq!(consumer.len(), 4);
        for (i, s) in consumer.iter().enumerate() {
            assert_eq!(s.waits, vec![ReadyWait { copy: 0, chunk: i as u32 }]);
        }
        let dropped = segment_device(&plan, 1, &chunks, Some(0), false);
        assert!(dropped.iter().all(|s| s.waits.is_empty()));
    }

    #[test]
    fn a_separate_copy_queue_never_mixes_queues_in_a_segment() {
        let plan = copy_benchmark(256, 256);
        let chunks = chunks_of_copies(&plan, 256 * 1024);
        let producer = segment_device(&plan, 0, &chunks, None, true);
        let queues: Vec<QueueKind> = producer.iter().map(|s| s.queue).collect();
        assert_eq!(queues, [QueueKind::Main, QueueKind::Copy, QueueKind::Copy, QueueKind::Copy, QueueKind::Copy]);
        assert!(producer[0].relays.is_empty(), "the fill completes no chunk");
        assert!(producer[1..].iter().all(|s| s.relays.len() == 1 && s.items.len() == 1));
        let consumer = segment_device(&plan, 1, &chunks, None, true);
        assert_eq!(consumer.len(), 4);
        assert!(consumer.iter().all(|s| s.queue == QueueKind::Copy && s.waits.len() == 1));
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
        assert_eq!(ready_value(2, 3, 1), 8);
    }
}
