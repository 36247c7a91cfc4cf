//! Memory barriers placed when a schedule is compiled (`DeviceProgram::barriers`): where they
//! fall, that the instances of one pass for many views share one, and that `validate()` names
//! a missing, misplaced or disordered barrier.

mod common;

use std::collections::HashSet;

use common::*;
use parallax_graph::*;

/// Three views on one device: `write` writes `a` of each view, `blur` reads it and writes `b`,
/// `blur_again` reads `b` and writes `b` again in place.
fn chain() -> Schedule {
    let mut graph = Graph::new(ViewTopology::all_sources(3, 8, 8));
    let mut a = graph.image("a", Format::Rgba32f);
    let mut b = graph.image("b", Format::Rgba32f);
    graph.pass("write", Role::All).write(&mut a).add();
    graph.pass("blur", Role::All).read(&a).write(&mut b).add();
    graph.pass("blur_again", Role::All).modify(&mut b).add();
    graph.export(&b);
    compile(&graph, &BandedPlacement { devices: 1, bands: 1 }).unwrap().into_schedule()
}

fn names(s: &Schedule, program: &DeviceProgram) -> Vec<String> {
    program
        .ops
        .iter()
        .map(|op| match *op {
            Op::Pass(i) => format!("{}@{}", s.instance(i).name, s.instance(i).view.0),
            other => format!("{other:?}"),
        })
        .collect()
}

#[test]
fn a_barrier_stands_where_an_op_reads_or_rewrites_what_an_op_since_the_last_one_wrote() {
    let s = chain();
    let program = &s.devices[0];
    assert_eq!(
        names(&s, program),
        ["write@0", "write@1", "write@2", "blur@0", "blur@1", "blur@2", "blur_again@0", "blur_again@1", "blur_again@2"]
    );
    // The first op follows last frame; each pass's instances touch their own view's allocations,
    // so all three views of a pass run side by side, and each pass waits for the one before.
    assert_eq!(program.barriers, vec![0, 3, 6]);
    assert!(s.validate().is_ok(), "{:?}", s.validate().errors);
}

#[test]
fn validate_names_the_op_that_lost_its_barrier_and_what_it_conflicts_with() {
    let mut s = chain();
    s.devices[0].barriers = vec![0, 6];
    let blur0 = s.devices[0].ops[3];
    let write0 = s.devices[0].ops[0];
    assert_eq!(
        s.validate().errors,
        vec![ScheduleError::MissingBarrier { device: DeviceId(0), op: blur0, after: write0 }]
    );

    s.devices[0].barriers = vec![3, 6];
    assert_eq!(s.validate().errors, vec![ScheduleError::NoBarrierAfterLastFrame { device: DeviceId(0), op: write0 }]);
    s.devices[0].barriers = vec![0, 6, 3];
    assert_eq!(s.validate().errors, vec![ScheduleError::BarriersOutOfOrder { device: DeviceId(0) }]);
    s.devices[0].barriers = vec![0, 3, 6, 9];
    assert_eq!(s.validate().errors, vec![ScheduleError::BarrierOutOfRange { device: DeviceId(0), index: 9, ops: 9 }]);
    // More barriers than needed are slower, never wrong.
    s.devices[0].barriers = (0..9).collect();
    assert!(s.validate().is_ok());
}

/// The allocations an op reads and writes, as the test sees the schedule.
fn touched(s: &Schedule, op: Op) -> (HashSet<AllocId>, HashSet<AllocId>) {
    match op {
        Op::Pass(i) => {
            let inst = s.instance(i);
            (
                inst.reads.iter().chain(&inst.history_reads).map(|a| a.alloc).collect(),
                inst.writes.iter().map(|a| a.alloc).collect(),
            )
        }
        Op::CopyOut(c) => ([s.copy(c).src_alloc].into(), HashSet::new()),
        Op::CopyIn(c) => (HashSet::new(), [s.copy(c).dst_alloc].into()),
        Op::Signal(_) | Op::Wait(_) => (HashSet::new(), HashSet::new()),
    }
}

/// Every barrier of every scheme's programs is needed: the op after it touches what an op since
/// the barrier before wrote, or writes what one read (or it is the program's first memory op).
/// So the compiled barriers are the fewest that `validate()` accepts for that order.
#[test]
fn every_compiled_barrier_guards_a_hazard() {
    for scheme in [Scheme::MultiSource, Scheme::FineSources, Scheme::FineAll] {
        for devices in [1, 3] {
            let (_, s) = test_schedule(&grid(4, 2, 12), devices, scheme, AssignStrategy::Compact, None);
            assert!(s.validate().is_ok(), "{scheme:?} on {devices}: {:?}", s.validate().errors);
            for program in &s.devices {
                for (k, &b) in program.barriers.iter().enumerate() {
                    if k == 0 {
                        continue;
                    }
                    let since = &program.ops[program.barriers[k - 1] as usize..b as usize];
                    let (reads, writes) = touched(&s, program.ops[b as usize]);
                    let conflict = since.iter().any(|&earlier| {
                        let (r, w) = touched(&s, earlier);
                        !w.is_disjoint(&reads) || !w.is_disjoint(&writes) || !r.is_disjoint(&writes)
                    });
                    assert!(conflict, "{scheme:?} on {devices}, {}: barrier {b} guards nothing", program.device);
                }
                // And fewer barriers than ops: instances of one pass share them.
                assert!(
                    program.ops.is_empty() || program.barriers.len() < program.ops.len(),
                    "{scheme:?} on {devices}"
                );
            }
        }
    }
}

/// Copies touch only their rows: the bands of one view that device 0 gathers from the other
/// devices into one allocation need no barrier between them.
#[test]
fn copies_of_disjoint_bands_into_one_allocation_share_a_barrier() {
    let (_, s) = test_schedule(&grid(4, 2, 12), 3, Scheme::FineAll, AssignStrategy::Compact, None);
    let program = &s.devices[0];
    let copy_ins: Vec<(usize, CopyId)> = program
        .ops
        .iter()
        .enumerate()
        .filter_map(|(i, op)| if let Op::CopyIn(c) = *op { Some((i, c)) } else { None })
        .collect();
    let shared = copy_ins.windows(2).any(|pair| {
        let ((i, a), (j, b)) = (pair[0], pair[1]);
        s.copy(a).dst_alloc == s.copy(b).dst_alloc
            && s.copy(a).region.intersect(s.copy(b).region).is_none()
            && !program.barriers.iter().any(|&k| (i + 1..=j).contains(&(k as usize)))
    });
    assert!(shared, "no two copy-ins of bands of one allocation without a barrier between");
}
