//! Op order as a compile option: the batched programs are what `Schedule::validate()` proves,
//! and an order corrupted after compiling is reported naming the op that breaks it.

mod common;

use common::*;
use parallax_graph::*;

/// The test pipeline of a 3×2 grid, fine-all over two devices: the graph and its plan.
fn fine_all_graph() -> (Graph, Partition) {
    let lf = grid(3, 2, 6);
    let plan = Partition::new(
        &lf,
        &PartitionConfig { devices: 2, scheme: Scheme::FineAll, assign: AssignStrategy::RoundRobin, sources: None },
    )
    .unwrap();
    let mut graph = Graph::new(plan.topology.clone());
    declare_test_pipeline(&mut graph);
    (graph, plan)
}

fn fine_all(batching: Batching) -> Schedule {
    let (graph, plan) = fine_all_graph();
    compile_with(&graph, &plan, &CompileOptions { batching }).unwrap().into_schedule()
}

fn position(s: &Schedule, op: Op) -> (usize, usize) {
    for (d, p) in s.devices.iter().enumerate() {
        if let Some(i) = p.ops.iter().position(|o| *o == op) {
            return (d, i);
        }
    }
    panic!("{op:?} not scheduled")
}

#[test]
fn batching_is_on_by_default_and_reorders_ops_that_validate_proves() {
    let batched = fine_all(Batching::default());
    let lowered = fine_all(Batching::Off);
    assert_eq!(batched.op_order, OpOrder { requested: Batching::default(), applied: Batching::default() });
    assert_eq!(lowered.op_order, OpOrder { requested: Batching::Off, applied: Batching::Off });
    let (graph, plan) = fine_all_graph();
    assert_eq!(compile(&graph, &plan).unwrap().into_schedule(), batched, "compile() batches by default");
    assert!(batched.validate().is_ok(), "{:?}", batched.validate().errors);
    assert!(lowered.validate().is_ok(), "{:?}", lowered.validate().errors);
    // Same ops on each device, in another order: batching moves ops, it adds or drops none.
    assert_ne!(batched.devices, lowered.devices, "batching changes the order of this schedule");
    for (b, l) in batched.devices.iter().zip(&lowered.devices) {
        let (mut b, mut l) = (b.ops.clone(), l.ops.clone());
        b.sort_by_key(|o| format!("{o:?}"));
        l.sort_by_key(|o| format!("{o:?}"));
        assert_eq!(b, l);
    }
    // The JSON summary and the DOT say which order the programs have.
    assert!(batched.to_dot().contains("label=\"op order: batched (copies of at most 8388608 B)\""));
    assert!(lowered.to_dot().contains("label=\"op order: in place\""));
}

#[test]
fn the_dot_lists_every_op_and_barrier_of_each_device_in_program_order() {
    let s = fine_all(Batching::default());
    let dot = s.to_dot();
    for program in &s.devices {
        let prefix = format!("    // {} submits: ", program.device);
        let line = dot.lines().find_map(|l| l.strip_prefix(prefix.as_str())).expect("a submits line per device");
        let expected: Vec<String> = program
            .ops
            .iter()
            .enumerate()
            .flat_map(|(index, op)| {
                let barrier = program.barriers.contains(&(index as u32)).then(|| "barrier".to_string());
                let op = match *op {
                    Op::Pass(p) => p.to_string(),
                    Op::CopyOut(c) => format!("out {c}"),
                    Op::Signal(c) => format!("signal {c}"),
                    Op::Wait(c) => format!("wait {c}"),
                    Op::CopyIn(c) => format!("in {c}"),
                };
                barrier.into_iter().chain([op])
            })
            .collect();
        assert_eq!(line, expected.join(", "));
    }
}

/// A consumer moved up before the wait and copy-in that bring what it reads: the copy arrives
/// late for that consumer.
#[test]
fn a_consumer_moved_before_its_copy_in_is_named() {
    let mut s = fine_all(Batching::default());
    // The first copy-in on device 1 and the first pass after it that reads the copied rows.
    let (copy, consumer) = s.devices[1]
        .ops
        .iter()
        .enumerate()
        .find_map(|(i, op)| {
            let Op::CopyIn(c) = *op else { return None };
            let k = s.copy(c);
            let consumer = s.devices[1].ops[i..].iter().find_map(|op| match *op {
                Op::Pass(p)
                    if s.instance(p).reads.iter().any(|r| {
                        r.resource == k.resource && r.version == k.version && r.region.intersect(k.region).is_some()
                    }) =>
                {
                    Some(p)
                }
                _ => None,
            })?;
            Some((c, consumer))
        })
        .expect("device 1 reads a copy");
    let (_, at) = position(&s, Op::Pass(consumer));
    let (_, wait) = position(&s, Op::Wait(copy));
    remove_op(&mut s.devices[1], at);
    insert_op(&mut s.devices[1], wait, Op::Pass(consumer));
    let errors = s.validate().errors;
    assert!(errors.contains(&ScheduleError::CopyArrivesLate { copy, consumer }), "{errors:?}");
}

/// A wait of device 0 moved to the front of its program, for a copy that device 1 signals only
/// after waiting for device 0: the devices wait on each other, and the report names the wait.
#[test]
fn a_wait_moved_before_what_its_signal_needs_is_named() {
    let mut s = fine_all(Batching::default());
    let ops1 = &s.devices[1].ops;
    let copy = ops1
        .iter()
        .enumerate()
        .find_map(|(i, op)| match *op {
            Op::Signal(c)
                if s.copy(c).to == DeviceId(0)
                    && ops1[..i].iter().any(|o| matches!(o, Op::Wait(k) if s.copy(*k).from == DeviceId(0))) =>
            {
                Some(c)
            }
            _ => None,
        })
        .expect("device 1 signals device 0 after waiting for it");
    let (_, wait) = position(&s, Op::Wait(copy));
    remove_op(&mut s.devices[0], wait);
    insert_op(&mut s.devices[0], 0, Op::Wait(copy));
    assert_eq!(s.validate().errors, vec![ScheduleError::Deadlock { device: DeviceId(0), op: Op::Wait(copy) }]);
}
