//! Resources that are not one per view at view size: a per-view image of its own size, a
//! global buffer written by the one instance of a global pass and read by every view. Planned
//! under every scheme (one instance where the writer runs, copies to every other device that
//! reads it), checked by `Schedule::validate()`, and each misuse refused at declaration or
//! reported by the validator with its exact variant.

mod common;

use common::*;
use parallax_graph::*;

/// An auto-exposure shape over a 4×1 light field: `shade` writes every view's radiance,
/// `measure` reduces each view to a 1×1 image, the global `expose` pass reads all of them and
/// writes the global `exposure` buffer, and `tonemap` of every view reads it.
fn exposure_graph(plan: &Partition) -> Graph {
    let mut g = Graph::new(plan.topology.clone());
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut luminance = g.image_sized("luminance", 1, 1, Format::R32f);
    let mut exposure = g.global_buffer("exposure", 16);
    let mut display = g.image("display", Format::Rgba8);
    g.pass("shade", Role::All).write(&mut radiance).add();
    g.pass("measure", Role::All).read_whole(&radiance).write(&mut luminance).add();
    let mut expose = g.global_pass("expose");
    expose.read_every_view_slot(&luminance);
    expose.write(&mut exposure).add();
    g.pass("tonemap", Role::All).read(&radiance).read(&exposure).write(&mut display).add();
    g.export(&display);
    g
}

fn plan(devices: u32, scheme: Scheme) -> Partition {
    Partition::new(&grid(4, 1, 8), &PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources: None })
        .unwrap()
}

fn exposure_schedule(devices: u32, scheme: Scheme) -> Schedule {
    let plan = plan(devices, scheme);
    compile(&exposure_graph(&plan), &plan).unwrap().into_schedule()
}

fn named<'s>(s: &'s Schedule, name: &str) -> Vec<&'s PassInstance> {
    s.instances.iter().filter(|i| i.name == name).collect()
}

#[test]
fn a_global_buffer_is_one_resource_written_once_and_read_by_every_view() {
    for scheme in Scheme::ALL {
        for devices in [1, 2, 4] {
            let s = exposure_schedule(devices, scheme);
            assert_eq!(s.validate().errors, vec![], "{scheme:?} on {devices} devices");
            let exposure: Vec<&ResourceInfo> = s.resources.iter().filter(|r| r.name == "exposure").collect();
            assert_eq!(exposure.len(), 1, "one resource, not one per view");
            assert!(exposure[0].global);
            let expose = named(&s, "expose");
            assert_eq!(expose.len(), 1, "{scheme:?}: a global pass runs once");
            assert_eq!(expose[0].reads.len(), 4, "it reads every view's luminance");
            assert!(expose[0].reads.iter().all(|r| r.region == Region::rows(1)), "1×1 images are read whole");
            let global = s.resources.iter().position(|r| r.name == "exposure").unwrap();
            for tonemap in named(&s, "tonemap") {
                let read = tonemap.reads.iter().find(|r| r.resource.index() == global).unwrap();
                assert_eq!(read.region, Region::rows(1), "a band of tonemap reads all of the buffer");
            }
        }
    }
}

#[test]
fn the_global_buffer_is_copied_once_to_each_other_device_that_reads_it() {
    for scheme in Scheme::ALL {
        let s = exposure_schedule(2, scheme);
        let global = s.resources.iter().position(|r| r.name == "exposure").unwrap();
        let writer = named(&s, "expose")[0].device;
        let readers: std::collections::BTreeSet<DeviceId> = named(&s, "tonemap").iter().map(|i| i.device).collect();
        let mut copied_to: Vec<DeviceId> =
            s.copies.iter().filter(|c| c.resource.index() == global).map(|c| c.to).collect();
        copied_to.sort_unstable();
        let expected: Vec<DeviceId> = readers.into_iter().filter(|&d| d != writer).collect();
        assert_eq!(copied_to, expected, "{scheme:?}");
        let allocations = s.allocations.iter().filter(|a| a.resource.index() == global).count();
        assert_eq!(allocations, expected.len() + 1, "{scheme:?}: one instance per device that touches it");
    }
}

#[test]
fn a_global_pass_and_global_reads_make_no_delta_edges() {
    let s = exposure_schedule(2, Scheme::FineAll);
    assert_eq!(s.delta_edges, vec![], "nothing here is reprojected");
}

#[test]
fn tonemap_still_splits_into_bands_when_it_reads_a_global_buffer() {
    let s = exposure_schedule(2, Scheme::FineAll);
    assert_eq!(named(&s, "tonemap").len(), 4 * 2, "two bands per view");
    assert_eq!(named(&s, "measure").len(), 4, "it writes a 1×1 image: one instance per view");
}

#[test]
fn a_per_view_pass_may_not_write_a_global_resource() {
    let plan = plan(1, Scheme::MultiSource);
    let mut g = Graph::new(plan.topology.clone());
    let mut exposure = g.global_buffer("exposure", 16);
    g.pass("expose", Role::All).write(&mut exposure).add();
    g.export(&exposure);
    let err = compile(&g, &plan).unwrap_err();
    assert!(matches!(&err, GraphError::WriteScope { pass, global: true, .. } if pass == "expose"), "{err}");
    assert!(err.to_string().contains("global_pass"), "{err}");
}

#[test]
fn a_global_pass_may_not_write_a_per_view_resource_nor_read_one_as_its_own_view() {
    let plan = plan(1, Scheme::MultiSource);
    let mut g = Graph::new(plan.topology.clone());
    let mut radiance = g.image("radiance", Format::Rgba32f);
    g.global_pass("shade").write(&mut radiance).add();
    assert!(matches!(compile(&g, &plan), Err(GraphError::WriteScope { global: false, .. })));

    let mut g = Graph::new(plan.topology.clone());
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut exposure = g.global_buffer("exposure", 16);
    g.pass("shade", Role::All).write(&mut radiance).add();
    g.global_pass("expose").read(&radiance).write(&mut exposure).add();
    g.export(&exposure);
    let err = compile(&g, &plan).unwrap_err();
    assert!(matches!(&err, GraphError::ReadScope { resource, global: false, .. } if resource == "radiance"), "{err}");
}

#[test]
fn a_per_view_pass_may_not_read_a_global_resource_as_sources_or_history() {
    let plan = plan(1, Scheme::FineSources);
    for history in [false, true] {
        let mut g = Graph::new(plan.topology.clone());
        let mut exposure = g.global_buffer("exposure", 16);
        let mut display = g.image("display", Format::Rgba8);
        g.global_pass("expose").write(&mut exposure).add();
        let pass = g.pass("tonemap", Role::Targets);
        let pass = if history { pass.read_history(&exposure) } else { pass.read_sources(&exposure) };
        pass.write(&mut display).add();
        g.export(&display);
        let err = compile(&g, &plan).unwrap_err();
        assert!(matches!(&err, GraphError::ReadScope { global: true, .. }), "{err}");
    }
}

#[test]
fn a_global_pass_reads_last_frames_global_buffer_as_history() {
    let plan = plan(2, Scheme::MultiSource);
    let mut g = Graph::new(plan.topology.clone());
    let mut exposure = g.global_buffer("exposure", 16);
    g.global_pass("adapt").read_history(&exposure).write(&mut exposure).add();
    g.export(&exposure);
    let s = compile(&g, &plan).unwrap();
    assert_eq!(s.validate().errors, vec![]);
    let adapt = &named(&s, "adapt")[0];
    assert!(s.history_pair_of_previous(adapt.history_reads[0].alloc).is_some());
}

#[test]
fn the_validator_refuses_a_global_written_per_view_or_in_part_or_by_two_instances() {
    let s = exposure_schedule(2, Scheme::FineAll);
    let global = ResourceId(s.resources.iter().position(|r| r.name == "exposure").unwrap() as u32);
    let expose = InstanceId(s.instances.iter().position(|i| i.name == "expose").unwrap() as u32);

    let mut per_view = s.clone();
    let pass = per_view.instance(expose).pass;
    per_view.passes[pass.index()].role = Role::All;
    assert!(
        per_view
            .validate()
            .errors
            .contains(&ScheduleError::GlobalWrittenPerView { instance: expose, resource: global })
    );

    let mut part = s.clone();
    part.instances[expose.index()].writes[0].region = Region::new(0, 0);
    assert!(part.validate().errors.contains(&ScheduleError::GlobalAccessedInPart {
        instance: expose,
        resource: global,
        rows: Region::new(0, 0)
    }));

    let mut twice = s.clone();
    let copy = twice.instances[expose.index()].clone();
    twice.instances.push(copy);
    let pass = twice.instance(expose).pass;
    assert!(twice.validate().errors.contains(&ScheduleError::GlobalPassInstances { pass, instances: 2 }));
}
