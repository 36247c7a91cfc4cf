//! `Schedule::validate()`: compiled schedules pass; each kind of corruption is reported with
//! its exact error variant.

mod common;

use common::*;
use parallax_graph::*;
use proptest::prelude::*;

fn fine_all() -> Schedule {
    test_schedule(&grid(3, 2, 6), 2, Scheme::FineAll, AssignStrategy::RoundRobin, None).1
}

fn position(s: &Schedule, op: Op) -> (usize, usize) {
    for (d, p) in s.devices.iter().enumerate() {
        if let Some(i) = p.ops.iter().position(|o| *o == op) {
            return (d, i);
        }
    }
    panic!("{op:?} not scheduled")
}

fn first_dependency_copy(s: &Schedule) -> CopyId {
    CopyId(s.copies.iter().position(|c| c.kind == CopyKind::Dependency).unwrap() as u32)
}

#[test]
fn dropping_a_pass_is_reported() {
    let mut s = fine_all();
    let (d, i) = position(&s, Op::Pass(InstanceId(0)));
    remove_op(&mut s.devices[d], i);
    assert!(s.validate().errors.contains(&ScheduleError::InstanceNotScheduled { instance: InstanceId(0) }));
}

#[test]
fn a_pass_on_two_devices_is_reported() {
    let mut s = fine_all();
    s.devices[1].ops.push(Op::Pass(InstanceId(0)));
    assert!(s.validate().errors.contains(&ScheduleError::InstanceScheduledTwice { instance: InstanceId(0) }));
}

#[test]
fn a_pass_moved_to_another_device_is_reported() {
    let mut s = fine_all();
    let id = InstanceId(0);
    let (d, i) = position(&s, Op::Pass(id));
    remove_op(&mut s.devices[d], i);
    insert_op(&mut s.devices[1 - d], 0, Op::Pass(id));
    let placed = s.instance(id).device;
    assert!(s.validate().errors.contains(&ScheduleError::InstanceOnWrongDevice {
        instance: id,
        placed,
        listed: DeviceId(1 - d as u32)
    }));
}

#[test]
fn dropping_a_cross_device_wait_is_reported() {
    let mut s = fine_all();
    let c = first_dependency_copy(&s);
    let (d, i) = position(&s, Op::Wait(c));
    remove_op(&mut s.devices[d], i);
    assert_eq!(s.validate().errors, vec![ScheduleError::CopyOpMissing { copy: c, op: "Wait" }]);
}

#[test]
fn a_copy_within_one_device_is_reported() {
    let mut s = fine_all();
    let c = first_dependency_copy(&s);
    let copy = s.copies[c.index()];
    s.copies[c.index()].to = copy.from;
    let errors = s.validate().errors;
    assert!(errors.contains(&ScheduleError::CopyWithinDevice { copy: c }), "{errors:?}");
}

#[test]
fn a_duplicated_copy_is_ambiguous() {
    let mut s = fine_all();
    let c = first_dependency_copy(&s);
    let copy = s.copies[c.index()];
    let dup = CopyId(s.copies.len() as u32);
    s.copies.push(copy);
    let (from, out) = position(&s, Op::CopyOut(c));
    s.devices[from].ops.splice(out + 2..out + 2, [Op::CopyOut(dup), Op::Signal(dup)]);
    let (to, wait) = position(&s, Op::Wait(c));
    s.devices[to].ops.splice(wait..wait, [Op::Wait(dup), Op::CopyIn(dup)]);
    let errors = s.validate().errors;
    assert!(
        errors.iter().any(|e| matches!(e, ScheduleError::AmbiguousRead { copies, .. } if copies == &vec![c, dup])),
        "{errors:?}"
    );
}

#[test]
fn a_copy_sent_before_its_producer_is_reported() {
    let mut s = fine_all();
    let c = first_dependency_copy(&s);
    let (d, out) = position(&s, Op::CopyOut(c));
    let ops: Vec<Op> = s.devices[d].ops.drain(out..out + 2).collect();
    s.devices[d].ops.splice(0..0, ops);
    let errors = s.validate().errors;
    assert!(
        errors.iter().any(|e| matches!(e, ScheduleError::CopyBeforeProducer { copy, .. } if *copy == c)),
        "{errors:?}"
    );
}

#[test]
fn a_copy_arriving_after_its_reader_is_reported() {
    let mut s = fine_all();
    let c = first_dependency_copy(&s);
    let (d, wait) = position(&s, Op::Wait(c));
    let ops: Vec<Op> = s.devices[d].ops.drain(wait..wait + 2).collect();
    s.devices[d].ops.extend(ops);
    let errors = s.validate().errors;
    assert!(
        errors.iter().any(|e| matches!(e, ScheduleError::CopyArrivesLate { copy, .. } if *copy == c)),
        "{errors:?}"
    );
}

#[test]
fn swapped_producer_and_consumer_are_reported() {
    let mut s = test_schedule(&grid(2, 1, 4), 1, Scheme::MultiSource, AssignStrategy::RoundRobin, None).1;
    let e = s.edges[0];
    let ops = &mut s.devices[0].ops;
    let (a, b) = (
        ops.iter().position(|o| *o == Op::Pass(e.producer)).unwrap(),
        ops.iter().position(|o| *o == Op::Pass(e.consumer)).unwrap(),
    );
    ops.swap(a, b);
    assert!(
        s.validate().errors.contains(&ScheduleError::OrderViolation { producer: e.producer, consumer: e.consumer })
    );
}

#[test]
fn wrong_byte_counts_are_reported() {
    let mut s = fine_all();
    let expected = s.copies[0].bytes;
    s.copies[0].bytes += 1;
    assert_eq!(
        s.validate().errors,
        vec![ScheduleError::CopyBytesMismatch { copy: CopyId(0), expected, actual: expected + 1 }]
    );
}

#[test]
fn a_missing_gather_is_reported() {
    let mut s = fine_all();
    let c = s.copies.iter().position(|c| c.kind == CopyKind::Gather).map(|c| CopyId(c as u32)).unwrap();
    let copy = s.copies[c.index()];
    for p in &mut s.devices {
        p.ops.retain(|o| !matches!(o, Op::CopyOut(k) | Op::Signal(k) | Op::Wait(k) | Op::CopyIn(k) if *k == c));
    }
    s.copies[c.index()].kind = CopyKind::Dependency; // no longer counts as a gather
    let errors = s.validate().errors;
    let view = s.resource(copy.resource).view;
    assert!(errors.contains(&ScheduleError::ViewNotGathered { view, resource: copy.resource }), "{errors:?}");
}

#[test]
fn crossed_waits_deadlock() {
    let mut s = fine_all();
    // Each device first waits for a copy that the other only sends after its own waits.
    let to0 = s
        .copies
        .iter()
        .position(|c| c.kind == CopyKind::Dependency && c.to == DeviceId(0))
        .map(|c| CopyId(c as u32))
        .unwrap();
    let to1 = s
        .copies
        .iter()
        .position(|c| c.kind == CopyKind::Dependency && c.to == DeviceId(1))
        .map(|c| CopyId(c as u32))
        .unwrap();
    for (copy, device) in [(to0, 0usize), (to1, 1usize)] {
        let (_, wait) = position(&s, Op::Wait(copy));
        remove_op(&mut s.devices[device], wait);
        insert_op(&mut s.devices[device], 0, Op::Wait(copy));
    }
    // Device 0 is stuck first, at the wait it now starts with.
    let errors = s.validate().errors;
    assert!(errors.contains(&ScheduleError::Deadlock { device: DeviceId(0), op: Op::Wait(to0) }), "{errors:?}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 40, rng_seed: proptest::test_runner::RngSeed::Fixed(PROPTEST_SEED), ..ProptestConfig::default() })]
    #[test]
    fn compiled_schedules_validate(cols in 1u32..7, rows in 1u32..4, n in 1u32..5, scheme in 0usize..3, assign in 0usize..3, res in 4u32..12) {
        let lf = grid(cols, rows, res);
        prop_assume!(n as usize <= lf.len());
        let assign = [AssignStrategy::RoundRobin, AssignStrategy::Contiguous, AssignStrategy::Compact][assign];
        let (_, s) = test_schedule(&lf, n, Scheme::ALL[scheme], assign, None);
        let report = s.validate();
        prop_assert!(report.is_ok(), "{:?}", report.errors);
    }
}

#[test]
fn an_empty_resource_is_reported() {
    let mut s = fine_all();
    let ResourceDesc::Image { height, format, .. } = s.resources[0].desc else { panic!("images only") };
    s.resources[0].desc = ResourceDesc::Image { width: 0, height, format };
    assert!(s.validate().errors.contains(&ScheduleError::EmptyResource { resource: ResourceId(0) }));
}

#[test]
fn rows_outside_their_resource_are_reported() {
    let mut s = fine_all();
    let height = s.height;
    let c = first_dependency_copy(&s);
    let copy = &mut s.copies[c.index()];
    let resource = copy.resource;
    copy.region = Region::new(copy.region.y0, height + 1);
    let rows = copy.region;
    assert!(s.validate().errors.contains(&ScheduleError::RowsOutsideResource {
        what: "copy",
        index: c.0,
        resource,
        rows,
        height
    }));

    let mut s = fine_all();
    let write = &mut s.instances[0].writes[0];
    write.region = Region::new(2, 2);
    let (resource, rows) = (write.resource, write.region);
    assert!(s.validate().errors.contains(&ScheduleError::RowsOutsideResource {
        what: "instance",
        index: 0,
        resource,
        rows,
        height
    }));
}
