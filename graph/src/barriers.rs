//! Memory barriers of each device program, placed when the schedule is compiled and proven by
//! `Schedule::validate()`: the backend records a barrier exactly where
//! [`DeviceProgram::barriers`](crate::DeviceProgram::barriers) says (plus what only it knows:
//! the start of each submission, kernels that touch undeclared memory).
//!
//! An op needs a barrier when it reads what an op since the last barrier wrote, or writes what
//! such an op read or wrote; the first op of a program that touches memory always has one, since
//! it follows the previous frame's ops. Everything between two barriers may run side by side, so
//! the instances of one pass for many views, which touch distinct allocations, overlap on the
//! GPU. A pass is taken to touch the whole of each allocation it accesses (a kernel is trusted
//! with no finer bound); a copy touches exactly its rows, so copies of disjoint bands of one
//! allocation, such as the bands a device gathers of one view, share a barrier. A frame parity
//! swap of history halves maps distinct allocations to distinct ones, so it changes no hazard.

use std::collections::HashMap;

use crate::error::ScheduleError;
use crate::ids::{AllocId, DeviceId, Region};
use crate::schedule::{CrossCopy, DeviceProgram, Op, PassInstance, Schedule};

/// Rows of an allocation an op touches.
type Touch = (AllocId, Region);

/// What a program's ops name: the instances and copies its `Op`s index.
#[derive(Clone, Copy)]
struct OpsOf<'a> {
    instances: &'a [PassInstance],
    copies: &'a [CrossCopy],
}

impl<'a> OpsOf<'a> {
    fn schedule(schedule: &'a Schedule) -> Self {
        Self { instances: &schedule.instances, copies: &schedule.copies }
    }

    /// What `op` reads and writes: a pass all of each allocation it accesses (history reads
    /// included), a copy-out its rows of the source allocation, a copy-in its rows of the
    /// destination; signals and waits nothing.
    fn accesses(self, op: Op) -> (Vec<Touch>, Vec<Touch>) {
        let whole = |alloc: AllocId| (alloc, Region::new(0, u32::MAX));
        match op {
            Op::Pass(i) => {
                let instance = &self.instances[i.index()];
                let reads = instance.reads.iter().chain(&instance.history_reads).map(|a| whole(a.alloc)).collect();
                (reads, instance.writes.iter().map(|a| whole(a.alloc)).collect())
            }
            Op::CopyOut(c) => (vec![(self.copies[c.index()].src_alloc, self.copies[c.index()].region)], vec![]),
            Op::CopyIn(c) => (vec![], vec![(self.copies[c.index()].dst_alloc, self.copies[c.index()].region)]),
            Op::Signal(_) | Op::Wait(_) => (vec![], vec![]),
        }
    }
}

/// What the ops since the last barrier read and wrote, each touch with the op that made it.
#[derive(Default)]
struct SinceBarrier {
    read: HashMap<AllocId, Vec<(Region, Op)>>,
    written: HashMap<AllocId, Vec<(Region, Op)>>,
}

impl SinceBarrier {
    /// An earlier op that `reads` and `writes` conflict with: read after write, write after
    /// write, or write after read, on overlapping rows of one allocation.
    fn conflict(&self, reads: &[Touch], writes: &[Touch]) -> Option<Op> {
        let overlapping = |touched: &HashMap<AllocId, Vec<(Region, Op)>>, &(alloc, rows): &Touch| {
            touched.get(&alloc)?.iter().find(|(earlier, _)| earlier.intersect(rows).is_some()).map(|&(_, op)| op)
        };
        let after_write = reads.iter().chain(writes).find_map(|t| overlapping(&self.written, t));
        after_write.or_else(|| writes.iter().find_map(|t| overlapping(&self.read, t)))
    }

    fn add(&mut self, op: Op, reads: Vec<Touch>, writes: Vec<Touch>) {
        for (alloc, rows) in reads {
            self.read.entry(alloc).or_default().push((rows, op));
        }
        for (alloc, rows) in writes {
            self.written.entry(alloc).or_default().push((rows, op));
        }
    }
}

/// Indices of the ops of `ops` (one device's program) that a barrier precedes, in increasing
/// order, by the rule of this module; `instances` and `copies` are what the ops index. What
/// compiling a schedule places; a plan laid out by hand (the backend's tests) places its
/// barriers with it too.
pub fn place_barriers(instances: &[PassInstance], copies: &[CrossCopy], ops: &[Op]) -> Vec<u32> {
    let named = OpsOf { instances, copies };
    let mut barriers = Vec::new();
    let mut since = SinceBarrier::default();
    for (index, &op) in ops.iter().enumerate() {
        let (reads, writes) = named.accesses(op);
        if reads.is_empty() && writes.is_empty() {
            continue;
        }
        if barriers.is_empty() || since.conflict(&reads, &writes).is_some() {
            barriers.push(index as u32);
            since = SinceBarrier::default();
        }
        since.add(op, reads, writes);
    }
    barriers
}

/// Places every program's barriers (after its ops are in their final order).
pub(crate) fn place_all(schedule: &mut Schedule) {
    let placed: Vec<Vec<u32>> =
        schedule.devices.iter().map(|p| place_barriers(&schedule.instances, &schedule.copies, &p.ops)).collect();
    for (program, barriers) in schedule.devices.iter_mut().zip(placed) {
        program.barriers = barriers;
    }
}

impl DeviceProgram {
    /// What is wrong with the form of the barrier list, which recording walks beside the ops: an
    /// index past the last op, or indices not increasing. None when it has neither fault.
    pub fn barrier_list_fault(&self) -> Option<ScheduleError> {
        let device = self.device;
        if let Some(&index) = self.barriers.iter().find(|&&i| i as usize >= self.ops.len()) {
            return Some(ScheduleError::BarrierOutOfRange { device, index, ops: self.ops.len() });
        }
        let increasing = self.barriers.windows(2).all(|w| w[0] < w[1]);
        (!increasing).then_some(ScheduleError::BarriersOutOfOrder { device })
    }
}

impl Schedule {
    /// Every program's barrier list is increasing and names its ops, and every hazard between two
    /// of its ops (and between its first memory op and the previous frame) has a barrier between.
    /// Runs after `validate()` has refused dangling ids, so every op's ids index.
    pub(crate) fn check_barriers(&self, errors: &mut Vec<ScheduleError>) {
        for program in &self.devices {
            let fault = program.barrier_list_fault();
            if let Some(error) =
                fault.or_else(|| self.first_unguarded_hazard(program.device, &program.ops, &program.barriers))
            {
                errors.push(error);
            }
        }
    }

    fn first_unguarded_hazard(&self, device: DeviceId, ops: &[Op], barriers: &[u32]) -> Option<ScheduleError> {
        let mut since: Option<SinceBarrier> = None;
        for (index, &op) in ops.iter().enumerate() {
            let (reads, writes) = OpsOf::schedule(self).accesses(op);
            if barriers.binary_search(&(index as u32)).is_ok() {
                since = Some(SinceBarrier::default());
            } else if !reads.is_empty() || !writes.is_empty() {
                let Some(current) = &since else {
                    return Some(ScheduleError::NoBarrierAfterLastFrame { device, op });
                };
                if let Some(after) = current.conflict(&reads, &writes) {
                    return Some(ScheduleError::MissingBarrier { device, op, after });
                }
            }
            if let Some(current) = &mut since {
                current.add(op, reads, writes);
            }
        }
        None
    }
}
