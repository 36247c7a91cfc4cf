//! Copy batches: the dependency copies one device sends another in one stage, moved as one
//! transfer. Formed once the programs are ordered (order.rs), from where their ops stand:
//! copies whose copy-outs sit in one unbroken stretch of copy-outs on the producer (no pass,
//! wait or copy-in between them) and whose copy-ins sit in one unbroken stretch of copy-ins on
//! the consumer form one batch per device pair. The backend lays a batch's copies side by side
//! in the link's staging, moves them with one copy command per allocation (a region per copy),
//! one ownership transfer and one wait (record.rs, segments.rs): what a fine scheme paid per view
//! and band (a command, a barrier, a wait; docs/RESULTS.md, issue 38) it pays per batch.
//!
//! Gathers are not batched: each finished view travels to device 0 on its own, as it always has
//! (multi-source's schedules, and their drawings, stay as they were).

use std::collections::{BTreeMap, HashMap};

use crate::error::ScheduleError;
use crate::ids::{AllocId, BatchId, CopyId, DeviceId, Region, ResourceId};
use crate::schedule::{CopyBatch, CopyKind, Op, Schedule};

/// The stretch of copy ops each op of a program is in: ops of the `kinds` (one direction's
/// two ops) with nothing else between them share a number; anything else starts a new one.
fn stretches(ops: &[Op], producer_side: bool) -> HashMap<CopyId, usize> {
    let mut stretch = HashMap::new();
    let mut number = 0;
    let mut open = false;
    for op in ops {
        match (*op, producer_side) {
            (Op::CopyOut(c), true) | (Op::CopyIn(c), false) => {
                stretch.insert(c, number);
                open = true;
            }
            (Op::Signal(_), true) | (Op::Wait(_), false) => {}
            _ => {
                number += usize::from(open);
                open = false;
            }
        }
    }
    stretch
}

/// The batches of `schedule`'s dependency copies as its programs stand, numbered by their first
/// copy.
pub(crate) fn batch_copies(schedule: &Schedule) -> Vec<CopyBatch> {
    let outs: Vec<HashMap<CopyId, usize>> = schedule.devices.iter().map(|p| stretches(&p.ops, true)).collect();
    let ins: Vec<HashMap<CopyId, usize>> = schedule.devices.iter().map(|p| stretches(&p.ops, false)).collect();
    let mut batches: BTreeMap<(DeviceId, DeviceId, usize, usize), CopyBatch> = BTreeMap::new();
    for program in &schedule.devices {
        for op in &program.ops {
            let Op::CopyOut(c) = *op else { continue };
            let copy = schedule.copy(c);
            if copy.kind != CopyKind::Dependency {
                continue;
            }
            let (Some(&out), Some(&inn)) = (outs[copy.from.index()].get(&c), ins[copy.to.index()].get(&c)) else {
                continue; // validate() reports the missing op
            };
            let batch = batches.entry((copy.from, copy.to, out, inn)).or_insert_with(|| CopyBatch {
                from: copy.from,
                to: copy.to,
                copies: Vec::new(),
                bytes: 0,
            });
            batch.copies.push(c);
            batch.bytes += copy.bytes;
        }
    }
    let mut batches: Vec<CopyBatch> = batches.into_values().collect();
    batches.sort_by_key(|b| b.copies[0]);
    batches
}

impl Schedule {
    /// The batch each copy is in (`None` for gathers and unbatched copies).
    pub fn batch_of_copies(&self) -> Vec<Option<BatchId>> {
        let mut of = vec![None; self.copies.len()];
        for (b, batch) in self.batches.iter().enumerate() {
            for &c in &batch.copies {
                if let Some(slot) = of.get_mut(c.index()) {
                    *slot = Some(BatchId(b as u32));
                }
            }
        }
        of
    }

    /// Every dependency copy is in exactly one batch, and only they are; a batch joins one
    /// device pair, counts its copies' bytes, keeps its copy-outs in one stretch of the
    /// producer's program and its copy-ins in one of the consumer's, and writes no rows of an
    /// allocation twice (one copy command per allocation takes its regions at once). Each
    /// dependency copy carries exactly the rows its consumers read.
    pub(crate) fn check_batches(&self, errors: &mut Vec<ScheduleError>) {
        let mut seen: Vec<u32> = vec![0; self.copies.len()];
        for (b, batch) in self.batches.iter().enumerate() {
            let id = BatchId(b as u32);
            let mut bytes = 0;
            for &c in &batch.copies {
                let Some(copy) = self.copies.get(c.index()) else {
                    errors.push(ScheduleError::Dangling { what: "batch", index: id.0, missing: "copy", target: c.0 });
                    continue;
                };
                seen[c.index()] += 1;
                // From the rows, as `CopyBytesMismatch` checks each copy's own count.
                bytes += self.resource(copy.resource).desc.bytes(copy.region);
                if copy.kind != CopyKind::Dependency || (copy.from, copy.to) != (batch.from, batch.to) {
                    errors.push(ScheduleError::BatchForeignCopy { batch: id, copy: c });
                }
            }
            if bytes != batch.bytes {
                errors.push(ScheduleError::BatchBytesMismatch { batch: id, expected: bytes, actual: batch.bytes });
            }
            for (device, producer_side) in [(batch.from, true), (batch.to, false)] {
                let Some(program) = self.devices.get(device.index()) else { continue };
                let stretch = stretches(&program.ops, producer_side);
                let mut numbers = batch.copies.iter().filter_map(|c| stretch.get(c));
                if let Some(first) = numbers.next()
                    && numbers.any(|n| n != first)
                {
                    errors.push(ScheduleError::BatchSplit { batch: id, device });
                }
            }
            let mut written: HashMap<AllocId, Vec<(Region, CopyId)>> = HashMap::new();
            for &c in batch.copies.iter().filter(|c| c.index() < self.copies.len()) {
                let copy = self.copy(c);
                let earlier = written.entry(copy.dst_alloc).or_default();
                if let Some(&(_, other)) = earlier.iter().find(|(r, _)| r.intersect(copy.region).is_some()) {
                    errors.push(ScheduleError::BatchRegionsOverlap { batch: id, first: other, second: c });
                }
                earlier.push((copy.region, c));
            }
        }
        let read_through = self.rows_read_through();
        for (c, copy) in self.copies.iter().enumerate() {
            let copy_id = CopyId(c as u32);
            let expected = u32::from(copy.kind == CopyKind::Dependency);
            if seen[c] != expected {
                errors.push(ScheduleError::CopyBatchCount { copy: copy_id, batches: seen[c] });
            }
            if let Some(&read) = read_through.get(&copy_id)
                && read != copy.region
            {
                errors.push(ScheduleError::CopyRowsUnread { copy: copy_id, read, copied: copy.region });
            }
        }
    }

    /// For each dependency copy, the rows of its producer's write that instances on its
    /// destination read (their hull), grown to all the written rows where device 0 also
    /// gathers that finished version (the copy doubles as the gather). Copies without a
    /// producer are left out (`CopyWithoutProducer` reports them).
    fn rows_read_through(&self) -> HashMap<CopyId, Region> {
        type Key = (ResourceId, u32, DeviceId);
        let mut writes: HashMap<Key, Vec<Region>> = HashMap::new();
        let mut reads: HashMap<Key, Vec<Region>> = HashMap::new();
        for inst in &self.instances {
            for w in &inst.writes {
                writes.entry((w.resource, w.version, inst.device)).or_default().push(w.region);
            }
            for r in &inst.reads {
                reads.entry((r.resource, r.version, inst.device)).or_default().push(r.region);
            }
        }
        let hull =
            |a: Option<Region>, b: Region| Some(a.map_or(b, |a| Region { y0: a.y0.min(b.y0), y1: a.y1.max(b.y1) }));
        let mut rows = HashMap::new();
        for (c, copy) in self.copies.iter().enumerate().filter(|(_, k)| k.kind == CopyKind::Dependency) {
            let written = writes
                .get(&(copy.resource, copy.version, copy.from))
                .and_then(|w| w.iter().find(|w| w.contains(copy.region)).copied());
            let Some(written) = written else { continue };
            let mut read = None;
            for r in reads.get(&(copy.resource, copy.version, copy.to)).into_iter().flatten() {
                if let Some(overlap) = r.intersect(written) {
                    read = hull(read, overlap);
                }
            }
            if copy.to == DeviceId(0) && self.resource(copy.resource).exported == Some(copy.version) {
                read = hull(read, written);
            }
            if let Some(read) = read {
                rows.insert(CopyId(c as u32), read);
            }
        }
        rows
    }
}
