//! The order of each device's ops: lowering's, or with the runs of one pass batched (a compile
//! option, [`CompileOptions::batching`]). What this leaves in `Schedule::devices` is what the
//! backend submits, op for op: it cuts the programs into submissions and large copies into
//! chunks, and changes no order. `Schedule::validate()` proves the result (hazards on every
//! allocation, copies before their consumers, no wait cycle across devices).
//!
//! Why batch: the fine schemes give every (view, stage) its own copies; in lowering's order, one
//! stage of a 100-view light field on 4 devices is hundreds of submissions per device, each a
//! cross-device hop whose latency (not its bytes) sets the frame time. Batched, a stage is a few
//! submissions: its copy-ins, its passes, its copy-outs.

use serde::Serialize;

use crate::ids::{AllocId, CopyId, InstanceId};
pub use crate::op_order::{Batching, DEFAULT_CHUNK_BYTES, OpOrder};
use crate::schedule::{Op, Schedule};

/// How `compile_with` builds a schedule.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CompileOptions {
    pub batching: Batching,
}

/// Re-orders `schedule`'s programs (as lowered, storage assigned) by `batching`, falling back
/// to [`Batching::Off`] where batching would deadlock. Deterministic: a function of the
/// schedule and the option.
pub(crate) fn order_programs(schedule: &mut Schedule, batching: Batching) {
    let lowered = std::mem::take(&mut schedule.devices);
    let ordered = |schedule: &Schedule, batching: Batching| {
        let batch = |c: CopyId| match batching {
            Batching::Off => false,
            Batching::SmallCopies { chunk_bytes } => moves_in_one_piece(schedule, c, chunk_bytes),
        };
        let mut devices = lowered.clone();
        for program in &mut devices {
            program.ops = device_order(schedule, &program.ops, &batch);
        }
        devices
    };
    schedule.devices = ordered(schedule, batching);
    let mut applied = batching;
    if batching != Batching::Off && schedule.wait_cycle().is_some() {
        applied = Batching::Off;
        schedule.devices = ordered(schedule, applied);
    }
    schedule.op_order = OpOrder { requested: batching, applied };
}

/// Whether the backend moves copy `c` in one chunk of at most `chunk_bytes` (at least a row).
fn moves_in_one_piece(schedule: &Schedule, c: CopyId, chunk_bytes: u64) -> bool {
    let copy = schedule.copy(c);
    let row_bytes = schedule.resource(copy.resource).desc.row_bytes().max(1);
    u64::from(copy.region.len()) <= (chunk_bytes / row_bytes).max(1)
}

/// One device's ops in order: `ops` (lowering's), except within a run of instances of one pass,
/// which is batched:
/// * the copy-outs and signals that separate two instances move down to the end of the run,
///   when the later instances write nothing they copy;
/// * with `batch(c)` for a copy `c`, its wait and copy-in move up to the start of the run, when
///   no instance they pass reads or writes what it copies into.
///
/// Copies that are not batched keep their place: a wait for one ends the run. Always deferred
/// are the copy-outs of [grouped](crate::PassBuilder::grouped) passes: lowering puts the gather
/// of each band right after the pass that finishes it, which would cut a device's hole filling
/// into one op per target band.
fn device_order(schedule: &Schedule, ops: &[Op], batch: &dyn Fn(CopyId) -> bool) -> Vec<Op> {
    let grouped = |p: InstanceId| schedule.passes[schedule.instance(p).pass.index()].grouped;
    let same_pass = |a: InstanceId, b: InstanceId| schedule.instance(a).pass == schedule.instance(b).pass;
    let touches = |p: InstanceId, alloc: AllocId| {
        let i = schedule.instance(p);
        i.reads.iter().chain(&i.writes).chain(&i.history_reads).any(|a| a.alloc == alloc)
    };
    let mut order: Vec<Op> = Vec::with_capacity(ops.len());
    let mut run = Run::default();
    let mut i = 0;
    while i < ops.len() {
        let op = ops[i];
        match op {
            Op::Pass(p)
                if run.first.is_some_and(|first| same_pass(first, p))
                    && !schedule.instance(p).writes.iter().any(|w| run.copied.contains(&w.alloc)) =>
            {
                order.push(op);
            }
            Op::CopyOut(c) if run.defers(&grouped, batch, c) => {
                run.copied.push(schedule.copy(c).src_alloc);
                run.deferred.push(op);
            }
            Op::Signal(c) if run.defers(&grouped, batch, c) => run.deferred.push(op),
            Op::Wait(c)
                if run.first.is_some_and(|first| batch(c) && next_pass_continues(ops, i + 2, first, &same_pass))
                    && ops.get(i + 1) == Some(&Op::CopyIn(c))
                    && !order[run.start..]
                        .iter()
                        .any(|&o| matches!(o, Op::Pass(p) if touches(p, schedule.copy(c).dst_alloc)))
                    && !run.copied.contains(&schedule.copy(c).dst_alloc) =>
            {
                run.hoisted.extend([op, Op::CopyIn(c)]);
                i += 1;
            }
            _ => {
                run.close(&mut order);
                if let Op::Pass(p) = op {
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

/// The run of one pass that [`device_order`] is batching.
#[derive(Default)]
struct Run {
    /// Its first instance; `None` between runs.
    first: Option<InstanceId>,
    /// Where that instance is in the new order.
    start: usize,
    /// Copy-outs and signals held back to the end of the run, and the allocations they read.
    deferred: Vec<Op>,
    copied: Vec<AllocId>,
    /// Waits and copy-ins moved up to the start of the run.
    hoisted: Vec<Op>,
}

impl Run {
    fn defers(&self, grouped: &dyn Fn(InstanceId) -> bool, batch: &dyn Fn(CopyId) -> bool, copy: CopyId) -> bool {
        self.first.is_some_and(|first| grouped(first) || batch(copy))
    }

    fn close(&mut self, order: &mut Vec<Op>) {
        order.splice(self.start..self.start, self.hoisted.drain(..));
        order.append(&mut self.deferred);
        self.copied.clear();
        self.first = None;
    }
}

/// Whether the op after a wait and its copy-in (at `next`) is another instance of the run's
/// pass (or more copy-ins that lead to one): only then is the copy-in part of the run.
fn next_pass_continues(
    ops: &[Op],
    mut next: usize,
    first: InstanceId,
    same_pass: &dyn Fn(InstanceId, InstanceId) -> bool,
) -> bool {
    while let Some(op) = ops.get(next) {
        match *op {
            Op::Wait(_) | Op::CopyIn(_) => next += 1,
            Op::Pass(p) => return same_pass(first, p),
            Op::CopyOut(_) | Op::Signal(_) => return false,
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::{DeviceId, PassId, Region, ResourceId, ViewId};
    use crate::schedule::{
        Access, CopyKind, CrossCopy, DeviceProgram, Format, Origin, PassInfo, PassInstance, ResourceDesc,
    };
    use crate::scope::Role;

    /// Instances `(name, reads, writes)` on device 0, in that order on its program (reads and
    /// writes are allocation numbers); the instances of one name are one pass, and a pass named
    /// `fill` is declared grouped.
    fn schedule(instances: &[(&str, &[u32], &[u32])]) -> Schedule {
        let mut names: Vec<&str> = Vec::new();
        let region = Region { y0: 0, y1: 1 };
        let access = |&alloc: &u32| Access {
            resource: ResourceId(0),
            version: 1,
            region,
            alloc: AllocId(alloc),
            origin: Origin::Own,
            decl: 0,
            in_place: false,
        };
        let instances: Vec<PassInstance> = instances
            .iter()
            .enumerate()
            .map(|(view, &(name, reads, writes))| {
                let pass = names.iter().position(|n| *n == name).unwrap_or_else(|| {
                    names.push(name);
                    names.len() - 1
                });
                PassInstance {
                    pass: PassId(pass as u32),
                    name: name.to_string(),
                    view: ViewId(view as u32),
                    region,
                    device: DeviceId(0),
                    reads: reads.iter().map(access).collect(),
                    writes: writes.iter().map(access).collect(),
                    history_reads: Vec::new(),
                }
            })
            .collect();
        let passes = names
            .iter()
            .map(|&name| PassInfo {
                name: name.to_string(),
                role: Role::All,
                grouped: name == "fill",
                reads: Vec::new(),
                writes: Vec::new(),
            })
            .collect();
        let ops = (0..instances.len() as u32).map(|i| Op::Pass(InstanceId(i))).collect();
        Schedule {
            views: instances.len() as u32,
            height: 1,
            devices: vec![DeviceProgram { device: DeviceId(0), ops, barriers: Vec::new() }],
            passes,
            resources: Vec::new(),
            allocations: Vec::new(),
            history: Vec::new(),
            instances,
            edges: Vec::new(),
            delta_edges: Vec::new(),
            copies: Vec::new(),
            batches: Vec::new(),
            culled: Vec::new(),
            op_order: OpOrder::default(),
        }
    }

    /// A one-row copy from device 0 to 1 out of allocation `src` into `dst`.
    fn copy(src: u32, dst: u32) -> CrossCopy {
        CrossCopy {
            resource: ResourceId(0),
            version: 1,
            region: Region { y0: 0, y1: 1 },
            from: DeviceId(0),
            to: DeviceId(1),
            src_alloc: AllocId(src),
            dst_alloc: AllocId(dst),
            bytes: 16,
            kind: CopyKind::Dependency,
        }
    }

    const P: fn(u32) -> Op = |i| Op::Pass(InstanceId(i));
    const OUT: fn(u32) -> Op = |c| Op::CopyOut(CopyId(c));
    const SIG: fn(u32) -> Op = |c| Op::Signal(CopyId(c));
    const WAIT: fn(u32) -> Op = |c| Op::Wait(CopyId(c));
    const IN: fn(u32) -> Op = |c| Op::CopyIn(CopyId(c));

    #[test]
    fn grouped_passes_move_up_past_copy_outs_of_what_they_do_not_write() {
        // Four fills writing 1, 3, 5 and 1 again, a fill of 7, then a pass that is not grouped.
        let mut s = schedule(&[
            ("fill", &[0], &[1]),
            ("fill", &[2], &[3]),
            ("fill", &[0], &[5]),
            ("fill", &[0], &[1]),
            ("fill", &[6], &[7]),
            ("tonemap", &[1], &[9]),
        ]);
        s.copies = vec![copy(1, 1), copy(3, 3), copy(9, 9)];
        let lowered = vec![
            P(0),
            OUT(0),
            SIG(0),
            P(1),
            OUT(1),
            SIG(1),
            P(2),
            // Writes what copy 0 reads: stays behind it, and starts the next run.
            P(3),
            WAIT(2),
            // Not past a wait.
            P(4),
            P(5),
        ];
        let expected = vec![P(0), P(1), P(2), OUT(0), SIG(0), OUT(1), SIG(1), P(3), WAIT(2), P(4), P(5)];
        assert_eq!(device_order(&s, &lowered, &|_| false), expected);
        // Copies between passes that are not grouped stay where they are.
        s.passes.iter_mut().for_each(|p| p.grouped = false);
        assert_eq!(device_order(&s, &lowered, &|_| false), lowered);
    }

    #[test]
    fn batched_small_copies_gather_at_the_ends_of_a_run_unless_an_instance_touches_them() {
        // A pass that is not grouped, over four views: each reads a band copied in (allocations
        // 10..13) and writes what is copied out (1, 3, 5, 7); view 2 also reads 13, which view
        // 3's copy-in writes; then another pass.
        let mut s = schedule(&[
            ("atrous", &[10], &[1]),
            ("atrous", &[11], &[3]),
            ("atrous", &[12, 13], &[5]),
            ("atrous", &[13], &[7]),
            ("tonemap", &[7], &[9]),
        ]);
        s.copies = vec![copy(1, 1), copy(3, 3), copy(5, 5), copy(7, 7), copy(20, 11), copy(21, 12), copy(22, 13)];
        let lowered = vec![
            P(0),
            OUT(0),
            SIG(0),
            WAIT(4),
            IN(4),
            P(1),
            OUT(1),
            SIG(1),
            WAIT(5),
            IN(5),
            P(2),
            OUT(2),
            SIG(2),
            WAIT(6),
            IN(6),
            P(3),
            OUT(3),
            SIG(3),
            P(4),
        ];
        let batched = vec![
            WAIT(4),
            IN(4),
            WAIT(5),
            IN(5),
            P(0),
            P(1),
            P(2),
            OUT(0),
            SIG(0),
            OUT(1),
            SIG(1),
            OUT(2),
            SIG(2),
            // Pass 2 reads 13, which copy 6 writes: it stays after pass 2 and ends the run.
            WAIT(6),
            IN(6),
            P(3),
            OUT(3),
            SIG(3),
            P(4),
        ];
        assert_eq!(device_order(&s, &lowered, &|_| true), batched);
        // A copy that is not batched (a large one) keeps its place, and its wait ends the run.
        let one_kept = vec![
            WAIT(4),
            IN(4),
            P(0),
            P(1),
            OUT(0),
            SIG(0),
            OUT(1),
            SIG(1),
            WAIT(5),
            IN(5),
            P(2),
            OUT(2),
            SIG(2),
            WAIT(6),
            IN(6),
            P(3),
            OUT(3),
            SIG(3),
            P(4),
        ];
        assert_eq!(device_order(&s, &lowered, &|c| c != CopyId(5)), one_kept);
        // Nothing batched: lowering's order.
        assert_eq!(device_order(&s, &lowered, &|_| false), lowered);
    }

    /// Device 0's run of `a` would wait (hoisted) for what device 1 makes only after the run's
    /// first instance's output (deferred) reaches it: the devices would wait on each other, so
    /// the programs keep lowering's order and say so.
    #[test]
    fn batching_that_would_deadlock_falls_back_to_lowering_s_order() {
        let mut s = schedule(&[("a", &[], &[1]), ("a", &[12], &[3]), ("b", &[11], &[2])]);
        s.instances[2].device = DeviceId(1);
        s.resources = vec![crate::schedule::ResourceInfo {
            name: "x".into(),
            family: crate::ids::FamilyId(0),
            view: ViewId(0),
            desc: ResourceDesc::Image { width: 1, height: 1, format: Format::R32f },
            exported: None,
            history: false,
            versions: 1,
            reset: None,
            global: false,
        }];
        s.copies = vec![copy(1, 11), CrossCopy { from: DeviceId(1), to: DeviceId(0), ..copy(2, 12) }];
        let lowered = vec![
            DeviceProgram {
                device: DeviceId(0),
                ops: vec![P(0), OUT(0), SIG(0), WAIT(1), IN(1), P(1)],
                barriers: vec![],
            },
            DeviceProgram { device: DeviceId(1), ops: vec![WAIT(0), IN(0), P(2), OUT(1), SIG(1)], barriers: vec![] },
        ];
        s.devices = lowered.clone();
        // Batched, device 0 would start with the wait and end with the copy-out.
        let device_0 = device_order(&s, &lowered[0].ops, &|_| true);
        assert_eq!(device_0, vec![WAIT(1), IN(1), P(0), P(1), OUT(0), SIG(0)]);
        let batching = Batching::SmallCopies { chunk_bytes: u64::MAX };
        order_programs(&mut s, batching);
        assert_eq!(s.devices, lowered);
        assert_eq!(s.op_order, OpOrder { requested: batching, applied: Batching::Off });
        assert_eq!(s.op_order.to_string(), "in place (batched (every copy) would make devices wait in a cycle)");
    }

    #[test]
    fn a_copy_moves_in_one_piece_up_to_the_chunk_size_or_one_row() {
        let mut s = schedule(&[]);
        s.resources = vec![crate::schedule::ResourceInfo {
            name: "radiance".into(),
            family: crate::ids::FamilyId(0),
            view: ViewId(0),
            desc: ResourceDesc::Image { width: 4, height: 8, format: Format::Rgba32f }, // 64 B a row
            exported: None,
            history: false,
            versions: 1,
            reset: None,
            global: false,
        }];
        s.copies = vec![CrossCopy { region: Region { y0: 0, y1: 4 }, bytes: 256, ..copy(0, 0) }];
        assert!(moves_in_one_piece(&s, CopyId(0), 256));
        assert!(!moves_in_one_piece(&s, CopyId(0), 255), "4 rows of 64 B are two chunks of 255 B");
        assert!(moves_in_one_piece(&s, CopyId(0), u64::MAX));
        s.copies[0].region = Region { y0: 3, y1: 4 };
        assert!(moves_in_one_piece(&s, CopyId(0), 1), "a chunk holds at least a row");
    }
}
