//! History pairs in the schedule: a resource read as history has two allocations on its device,
//! and `Schedule::validate()` proves they cannot alias. Each rule is broken on purpose and
//! reported with its exact variant.

mod common;

use common::*;
use parallax_graph::*;

/// A 3×1 light field on 3 devices (FineAll): `shade` writes `color`, `accumulate` reads it and
/// last frame's `accum` and writes this frame's, `accum` exported.
fn temporal() -> Schedule {
    let config =
        PartitionConfig { devices: 3, scheme: Scheme::FineAll, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::new(&grid(3, 1, 8), &config).unwrap();
    let mut g = Graph::new(plan.topology.clone());
    let mut color = g.image("color", Format::Rgba32f);
    let mut accum = g.image("accum", Format::Rgba32f);
    g.pass("shade", Role::All).write(&mut color).add();
    g.pass("accumulate", Role::All).read(&color).read_history(&accum).write(&mut accum).add();
    g.export(&accum);
    let s = compile(&g, &plan).unwrap();
    assert_eq!(s.validate().errors, vec![]);
    assert!(s.history.len() >= 2, "a pair per (view, device) that reads history");
    s.into_schedule()
}

/// The first `accumulate` instance and its history read's pair.
fn first_reader(s: &Schedule) -> (InstanceId, HistoryPair) {
    let i = s.instances.iter().position(|i| !i.history_reads.is_empty()).unwrap();
    let pair = *s.history_pair_of_previous(s.instances[i].history_reads[0].alloc).unwrap();
    (InstanceId(i as u32), pair)
}

fn errors(s: &Schedule) -> Vec<ScheduleError> {
    s.validate().errors
}

#[test]
fn every_pair_is_two_distinct_allocations_of_one_resource_on_one_device() {
    let s = temporal();
    let mut halves: Vec<AllocId> = s.history.iter().flat_map(|p| [p.current, p.previous]).collect();
    let count = halves.len();
    halves.sort_unstable();
    halves.dedup();
    assert_eq!(halves.len(), count, "no allocation is a half of two pairs, nor both halves of one");
    for pair in &s.history {
        let (current, previous) = (s.allocation(pair.current), s.allocation(pair.previous));
        assert_eq!((current.resource, current.device), (previous.resource, previous.device));
        assert!(previous.versions.is_empty());
    }
}

#[test]
fn halves_that_are_one_allocation_are_refused() {
    let mut s = temporal();
    s.history[0].previous = s.history[0].current;
    assert!(errors(&s).contains(&ScheduleError::HistoryHalvesAlias { pair: 0, alloc: s.history[0].current }));
}

#[test]
fn halves_of_another_resource_or_device_are_refused() {
    let mut s = temporal();
    let HistoryPair { current, previous } = s.history[0];
    let other = DeviceId((s.allocation(previous).device.0 + 1) % 3);
    s.allocations[previous.index()].device = other;
    assert!(errors(&s).contains(&ScheduleError::HistoryHalvesDiffer { pair: 0, current, previous }));

    let mut s = temporal();
    let HistoryPair { current, previous } = s.history[0];
    let color = ResourceId(s.resources.iter().position(|r| r.name == "color").unwrap() as u32);
    s.allocations[previous.index()].resource = color;
    assert!(errors(&s).contains(&ScheduleError::HistoryHalvesDiffer { pair: 0, current, previous }));
}

#[test]
fn an_allocation_in_two_pairs_is_refused() {
    let mut s = temporal();
    s.history[1].previous = s.history[0].previous;
    assert!(errors(&s).contains(&ScheduleError::HistoryHalfShared { alloc: s.history[0].previous }));
}

#[test]
fn a_previous_half_holding_a_version_of_the_frame_is_refused() {
    let mut s = temporal();
    let previous = s.history[0].previous;
    s.allocations[previous.index()].versions = vec![1];
    assert!(errors(&s).contains(&ScheduleError::PreviousHalfHoldsVersions { alloc: previous, versions: vec![1] }));
}

#[test]
fn a_write_or_copy_into_the_previous_half_is_refused() {
    let mut s = temporal();
    let (reader, pair) = first_reader(&s);
    s.instances[reader.index()].writes[0].alloc = pair.previous;
    assert!(errors(&s).contains(&ScheduleError::PreviousHalfTouched { alloc: pair.previous, op: Op::Pass(reader) }));

    let mut s = temporal();
    let c = s.copies.iter().position(|c| s.resource(c.resource).name == "accum").expect("accum is gathered");
    let previous = s.history.iter().find(|p| s.allocation(p.previous).device == s.copies[c].from).unwrap().previous;
    s.copies[c].src_alloc = previous;
    assert!(
        errors(&s).contains(&ScheduleError::PreviousHalfTouched { alloc: previous, op: Op::CopyOut(CopyId(c as u32)) })
    );
}

#[test]
fn a_history_read_of_the_current_half_is_refused() {
    let mut s = temporal();
    let (reader, pair) = first_reader(&s);
    let resource = s.instances[reader.index()].history_reads[0].resource;
    s.instances[reader.index()].history_reads[0].alloc = pair.current;
    assert!(errors(&s).contains(&ScheduleError::HistoryReadOutsidePair {
        instance: reader,
        resource,
        alloc: pair.current
    }));
}

#[test]
fn a_history_read_of_a_version_its_pair_does_not_hold_is_refused() {
    let mut s = temporal();
    let (reader, pair) = first_reader(&s);
    let read = &mut s.instances[reader.index()].history_reads[0];
    read.version += 1;
    let (resource, version) = (read.resource, read.version);
    assert!(errors(&s).contains(&ScheduleError::HistoryVersionNotCurrent {
        instance: reader,
        resource,
        version,
        current: pair.current
    }));
}

#[test]
fn a_pair_naming_a_missing_allocation_is_refused_before_anything_else() {
    let mut s = temporal();
    let missing = s.allocations.len() as u32;
    s.history[0].previous = AllocId(missing);
    assert_eq!(
        errors(&s),
        vec![ScheduleError::Dangling { what: "history pair", index: 0, missing: "allocation", target: missing }]
    );
}
