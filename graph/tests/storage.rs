//! Explicit storage: which allocation each version lives in, and the storage rules of
//! `Schedule::validate()` (in-place access, hazards, history, bands, dangling ids), each broken
//! on purpose and reported with its exact variant.

mod common;

use common::*;
use parallax_graph::*;

/// A 3×1 light field on `devices` devices under `scheme`, with a temporal pass: `accumulate`
/// reads last frame's `accum` and writes this frame's, `shade` writes `color` and then modifies
/// it in place, `blur` reads it and writes a new version.
fn temporal(devices: u32, scheme: Scheme) -> Schedule {
    let plan = Partition::new(
        &grid(3, 1, 8),
        &PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources: None },
    )
    .unwrap();
    let mut g = Graph::new(plan.topology.clone());
    let mut color = g.image("color", Format::Rgba32f);
    let mut accum = g.image("accum", Format::Rgba32f);
    g.pass("shade", Role::All).write(&mut color).add();
    g.pass("tint", Role::All).modify(&mut color).add();
    g.pass("blur", Role::All).read(&color).write(&mut color).add();
    g.pass("accumulate", Role::All).read(&color).read_history(&accum).write(&mut accum).add();
    g.export(&accum);
    compile(&g, &plan).unwrap().into_schedule()
}

fn instance_of<'s>(s: &'s Schedule, name: &str, view: u32) -> (InstanceId, &'s PassInstance) {
    let (i, inst) = s.instances.iter().enumerate().find(|(_, i)| i.name == name && i.view == ViewId(view)).unwrap();
    (InstanceId(i as u32), inst)
}

#[test]
fn compiled_temporal_schedules_are_sound_under_every_scheme() {
    for scheme in [Scheme::MultiSource, Scheme::FineSources, Scheme::FineAll] {
        for devices in [1, 3] {
            let s = temporal(devices, scheme);
            assert_eq!(s.validate().errors, vec![], "{scheme:?} on {devices} devices");
        }
    }
}

#[test]
fn a_new_version_gets_its_own_allocation_and_an_in_place_one_shares() {
    let s = temporal(1, Scheme::MultiSource);
    let (_, shade) = instance_of(&s, "shade", 0);
    let (_, tint) = instance_of(&s, "tint", 0);
    let (_, blur) = instance_of(&s, "blur", 0);
    assert_eq!(tint.reads[0].alloc, shade.writes[0].alloc, "tint reads what shade wrote");
    assert_eq!(tint.writes[0].alloc, tint.reads[0].alloc, "modify stays in place");
    assert!(tint.writes[0].in_place);
    assert_eq!(blur.reads[0].alloc, tint.writes[0].alloc);
    assert_ne!(blur.writes[0].alloc, blur.reads[0].alloc, "blur's output must not alias its input");
    assert_eq!(s.allocation(tint.writes[0].alloc).versions, vec![1, 2]);
}

#[test]
fn a_band_modified_in_place_stays_in_place_when_a_whole_view_read_copies_the_other_bands_in() {
    // `tint` modifies each band of `color` in place on its device, `gather` then reads the whole
    // view: the other bands' final rows are copied into the allocation the in-place band lives
    // in, whichever device's `tint` comes first in the frame's order.
    let plan = Partition::new(
        &grid(3, 1, 8),
        &PartitionConfig { devices: 3, scheme: Scheme::FineAll, assign: AssignStrategy::Compact, sources: None },
    )
    .unwrap();
    let mut g = Graph::new(plan.topology.clone());
    let mut color = g.image("color", Format::Rgba32f);
    let mut out = g.image("out", Format::Rgba32f);
    g.pass("shade", Role::All).write(&mut color).add();
    g.pass("tint", Role::All).modify(&mut color).add();
    g.pass("gather", Role::All).read_whole(&color).write(&mut out).add();
    g.export(&out);
    let s = compile(&g, &plan).unwrap();
    assert_eq!(s.validate().errors, vec![]);
    assert!(!s.copies.is_empty(), "bands of other devices are copied in");
    for tint in s.instances.iter().filter(|i| i.name == "tint") {
        assert_eq!(tint.writes[0].alloc, tint.reads[0].alloc, "{} on {}", tint.name, tint.device.0);
    }
    for gather in s.instances.iter().filter(|i| i.name == "gather") {
        let tint = s.instances.iter().find(|i| i.name == "tint" && i.view == gather.view && i.device == gather.device);
        assert_eq!(
            Some(gather.reads[0].alloc),
            tint.map(|t| t.writes[0].alloc),
            "gather reads the in-place allocation"
        );
    }
}

#[test]
fn history_reads_the_previous_half_of_the_pair_whose_current_half_the_final_write_fills() {
    let s = temporal(3, Scheme::FineAll);
    for inst in s.instances.iter().filter(|i| i.name == "accumulate") {
        let history = &inst.history_reads[0];
        let write = &inst.writes[0];
        assert_eq!(history.origin, Origin::History);
        let pair = s.history_pair_of_previous(history.alloc).expect("history reads see a previous half");
        assert_eq!(pair.current, write.alloc, "the final write fills the current half");
        assert_ne!(pair.current, pair.previous);
        assert_eq!(s.allocation(history.alloc).device, inst.device);
        assert!(s.allocation(pair.previous).versions.is_empty(), "the previous half holds no version of the frame");
    }
    // Only the history resource is double buffered.
    assert!(s.history.iter().all(|p| s.resource(s.allocation(p.current).resource).name == "accum"));
}

#[test]
fn reads_carry_their_slot_and_origin() {
    let lf = grid(3, 1, 8);
    let plan = Partition::new(
        &lf,
        &PartitionConfig {
            devices: 1,
            scheme: Scheme::FineAll,
            assign: AssignStrategy::Compact,
            sources: Some(vec![0, 2]),
        },
    )
    .unwrap();
    let mut g = Graph::new(plan.topology.clone());
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut depth = g.image("depth", Format::R32f);
    g.pass("raster", Role::All).write(&mut depth).add();
    g.pass("trace", Role::Sources).write(&mut radiance).add();
    g.pass("reproject", Role::Targets)
        .read(&depth)
        .read_sources(&depth)
        .read_sources(&radiance)
        .write(&mut radiance)
        .add();
    g.export(&radiance);
    let s = compile(&g, &plan).unwrap();
    let (_, target) = instance_of(&s, "reproject", 1);
    let info = &s.passes[target.pass.index()];
    let names: Vec<(&str, Origin)> =
        target.reads.iter().map(|r| (info.reads[r.decl as usize].name.as_str(), r.origin)).collect();
    assert_eq!(
        names,
        vec![
            ("depth", Origin::Own),
            ("depth", Origin::Source(0)),
            ("depth", Origin::Source(1)),
            ("radiance", Origin::Source(0)),
            ("radiance", Origin::Source(1)),
        ]
    );
    assert_eq!(s.resource(target.reads[2].resource).view, ViewId(2));
}

#[test]
fn a_write_into_the_allocation_it_reads_without_declaring_it_is_refused() {
    let mut s = temporal(1, Scheme::MultiSource);
    let (id, blur) = instance_of(&s, "blur", 0);
    let (read, write) = (blur.reads[0].alloc, blur.writes[0].alloc);
    let version = s.instances[id.index()].writes[0].version;
    s.allocations[read.index()].versions.push(version);
    s.instances[id.index()].writes[0].alloc = read;
    assert_ne!(read, write);
    assert!(s.validate().errors.contains(&ScheduleError::UndeclaredInPlace { instance: id, alloc: read }));
}

#[test]
fn an_older_version_touched_after_a_newer_write_is_a_hazard() {
    let mut s = temporal(1, Scheme::MultiSource);
    // Run tint (writes version 2 in place) before shade (writes version 1 into the same
    // allocation): shade's write lands on top of the newer version.
    let (shade, _) = instance_of(&s, "shade", 0);
    let (tint, _) = instance_of(&s, "tint", 0);
    let ops = &mut s.devices[0].ops;
    let a = ops.iter().position(|o| *o == Op::Pass(shade)).unwrap();
    let b = ops.iter().position(|o| *o == Op::Pass(tint)).unwrap();
    ops.swap(a, b);
    let alloc = s.instance(tint).writes[0].alloc;
    let errors = s.validate().errors;
    assert!(
        errors.contains(&ScheduleError::AllocationHazard {
            alloc,
            device: DeviceId(0),
            earlier: Op::Pass(tint),
            earlier_version: 2,
            later: Op::Pass(shade),
            later_version: 1,
        }),
        "{errors:?}"
    );
}

#[test]
fn history_from_another_devices_allocation_is_refused() {
    let mut s = temporal(3, Scheme::FineAll);
    let (id, inst) =
        s.instances.iter().enumerate().find(|(_, i)| i.name == "accumulate" && i.device == DeviceId(1)).unwrap();
    let (id, resource) = (InstanceId(id as u32), inst.history_reads[0].resource);
    let elsewhere = s
        .history
        .iter()
        .map(|p| p.previous)
        .find(|&a| s.allocation(a).resource == resource && s.allocation(a).device != DeviceId(1))
        .unwrap();
    s.instances[id.index()].history_reads[0].alloc = elsewhere;
    assert!(s.validate().errors.contains(&ScheduleError::HistoryOnOtherDevice {
        instance: id,
        resource,
        alloc: elsewhere
    }));
}

#[test]
fn bands_that_leave_a_gap_are_refused() {
    let mut s = temporal(3, Scheme::FineAll);
    let (id, inst) = instance_of(&s, "shade", 0);
    let (pass, view) = (inst.pass, inst.view);
    s.instances[id.index()].region.y1 -= 1;
    assert!(s.validate().errors.contains(&ScheduleError::BandsDoNotTile { pass, view, height: 8 }));
}

#[test]
fn an_op_naming_a_missing_instance_is_refused_before_anything_indexes_by_it() {
    let mut s = temporal(1, Scheme::MultiSource);
    s.devices[0].ops.push(Op::Pass(InstanceId(9999)));
    assert_eq!(
        s.validate().errors,
        vec![ScheduleError::Dangling { what: "op", index: 0, missing: "instance", target: 9999 }]
    );
    let message = s.validate().errors[0].to_string();
    assert!(message.contains("missing instance 9999"), "{message}");
}

#[test]
fn an_exported_version_read_on_device_0_travels_there_once() {
    let plan = Partition::new(
        &grid(3, 1, 8),
        &PartitionConfig {
            devices: 2,
            scheme: Scheme::FineAll,
            assign: AssignStrategy::Compact,
            sources: Some(vec![1]),
        },
    )
    .unwrap();
    let mut g = Graph::new(plan.topology.clone());
    let mut x = g.image("x", Format::Rgba32f);
    let mut y = g.image("y", Format::Rgba32f);
    g.pass("trace", Role::All).write(&mut x).add();
    g.pass("reproject", Role::Targets).read_sources(&x).write(&mut y).side_effect().add();
    g.export(&x);
    let s = compile(&g, &plan).unwrap();
    assert_eq!(s.validate().errors, vec![]);
    let mut seen = std::collections::HashSet::new();
    for c in &s.copies {
        assert!(seen.insert((c.resource, c.version, c.from, c.to, c.region)), "copied twice: {c:?}");
    }
}
