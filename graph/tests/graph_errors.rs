//! Declaration and compile errors (exact variants), culling and side effects.

use parallax_graph::*;

/// Two views: view 0 is the source of view 1.
fn topology() -> ViewTopology {
    ViewTopology { width: 4, height: 4, sources_of: vec![vec![], vec![ViewId(0)]], is_source: vec![true, false] }
}

struct Single;
impl Placement for Single {
    fn devices(&self) -> u32 {
        1
    }
    fn place(&self, _: PassPlacementInfo<'_>, _: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        vec![(DeviceId(0), Region::rows(height))]
    }
}

#[test]
fn reading_a_version_nobody_writes() {
    let mut g = Graph::new(topology());
    let a = g.image("a", Format::R32f);
    let mut out = g.image("out", Format::R32f);
    g.pass("consume", Role::All).read(&a).write(&mut out).add();
    g.export(&out);
    let err = compile(&g, &Single).unwrap_err();
    assert!(
        matches!(err, GraphError::ReadOfUnwritten { ref pass, ref resource, version: 0, .. } if pass == "consume" && resource == "a"),
        "{err}"
    );
    assert!(err.to_string().contains("graph_errors.rs"), "error names the declaration site: {err}");
}

#[test]
fn exporting_what_nobody_writes() {
    let mut g = Graph::new(topology());
    let a = g.image("a", Format::R32f);
    g.export(&a);
    let err = compile(&g, &Single).unwrap_err();
    assert!(
        matches!(err, GraphError::ExportOfUnwritten { ref resource, view: ViewId(0), .. } if resource == "a"),
        "{err}"
    );
}

#[test]
fn imported_resources_may_be_read_before_written() {
    let mut g = Graph::new(topology());
    let scene = g.buffer("scene", 64);
    g.import(&scene);
    let mut out = g.image("out", Format::R32f);
    g.pass("consume", Role::All).read(&scene).write(&mut out).add();
    g.export(&out);
    assert!(compile(&g, &Single).unwrap().validate().is_ok());
}

#[test]
fn two_passes_writing_one_version() {
    let mut g = Graph::new(topology());
    let a = g.image("a", Format::R32f);
    g.pass("first", Role::All).write_version(&a, 1).add();
    g.pass("second", Role::All).write_version(&a, 1).add();
    g.export(&a);
    let err = compile(&g, &Single).unwrap_err();
    assert!(
        matches!(err, GraphError::DoubleWrite { ref first, ref second, version: 1, .. } if first == "first" && second == "second"),
        "{err}"
    );
}

#[test]
fn cycles_are_reported_with_their_passes() {
    let mut g = Graph::new(topology());
    let a = g.image("a", Format::R32f);
    let b = g.image("b", Format::R32f);
    g.pass("ping", Role::All).read_version(&b, 1).write_version(&a, 1).add();
    g.pass("pong", Role::All).read_version(&a, 1).write_version(&b, 1).add();
    g.pass("sink", Role::All).read_version(&b, 1).side_effect().add();
    assert_eq!(compile(&g, &Single).unwrap_err(), GraphError::Cycle { passes: vec!["ping".into(), "pong".into()] });
}

#[test]
fn handles_of_another_graph_are_rejected() {
    let mut other = Graph::new(topology());
    let foreign = other.image("foreign", Format::R32f);
    let mut g = Graph::new(topology());
    let mut out = g.image("out", Format::R32f);
    g.pass("mix", Role::All).read(&foreign).write(&mut out).add();
    g.export(&out);
    let refused = |err: &GraphError| matches!(err, GraphError::ForeignHandle { pass, .. } if pass == "mix");
    assert!(g.declaration_error().is_some_and(refused), "refused when declared, before compiling");
    assert!(refused(&compile(&g, &Single).unwrap_err()));
}

#[test]
fn two_resources_with_one_name_are_refused_where_the_second_is_declared() {
    let mut g = Graph::new(topology());
    let mut a = g.image("radiance", Format::Rgba32f);
    let twin = g.buffer("radiance", 64);
    g.import(&twin);
    g.pass("trace", Role::All).read(&twin).write(&mut a).add();
    g.export(&a);
    let err = compile(&g, &Single).unwrap_err();
    assert!(
        matches!(err, GraphError::DuplicateResource { ref name, first, at } if name == "radiance" && first.line() < at.line()),
        "{err}"
    );
    assert_eq!(g.declaration_error(), Some(&err), "refused when declared, before compiling");
    assert!(err.to_string().contains("graph_errors.rs"), "error names both declarations: {err}");
}

#[test]
fn a_pass_declaring_one_access_twice_is_refused() {
    let mut g = Graph::new(topology());
    let a = g.image("a", Format::R32f);
    g.import(&a);
    let mut out = g.image("out", Format::R32f);
    g.pass("blur", Role::All).read(&a).read_whole(&a).write(&mut out).add();
    g.export(&out);
    let err = compile(&g, &Single).unwrap_err();
    assert!(
        matches!(err, GraphError::DuplicateSlot { ref pass, ref slot, access: SlotAccess::Read, .. } if pass == "blur" && slot == "a"),
        "{err}"
    );
}

#[test]
fn a_pass_writing_one_resource_twice_is_refused() {
    let mut g = Graph::new(topology());
    let mut a = g.image("a", Format::R32f);
    g.pass("twice", Role::All).write(&mut a).write(&mut a).add();
    g.export(&a);
    let err = compile(&g, &Single).unwrap_err();
    assert!(
        matches!(err, GraphError::DuplicateSlot { ref pass, ref slot, access: SlotAccess::Write, .. } if pass == "twice" && slot == "a"),
        "{err}"
    );
}

#[test]
fn one_resource_read_as_own_view_history_and_in_place_is_one_slot_each() {
    let mut g = Graph::new(topology());
    let mut acc = g.image("acc", Format::R32f);
    g.import(&acc);
    g.pass("accumulate", Role::All).read_history(&acc).modify(&mut acc).add();
    g.export(&acc);
    assert_eq!(g.declaration_error(), None);
    assert!(compile(&g, &Single).is_ok());
}

#[test]
fn a_graph_without_roots_is_an_error() {
    let mut g = Graph::new(topology());
    let mut a = g.image("a", Format::R32f);
    g.pass("orphan", Role::All).write(&mut a).add();
    assert_eq!(compile(&g, &Single).unwrap_err(), GraphError::NoRoots);
}

#[test]
fn unused_passes_are_culled_and_side_effects_kept() {
    let mut g = Graph::new(topology());
    let mut a = g.image("a", Format::R32f);
    let mut unused = g.image("unused", Format::R32f);
    let mut stats = g.buffer("stats", 16);
    g.pass("produce", Role::All).write(&mut a).add();
    g.pass("dead", Role::All).read(&a).write(&mut unused).add();
    // Reads `a` but writes nothing exported: only side_effect() keeps it, and it keeps `a` alive.
    g.pass("readback", Role::Sources).read(&a).write(&mut stats).side_effect().add();
    let s = compile(&g, &Single).unwrap();
    let names: Vec<(&str, ViewId)> = s.instances.iter().map(|i| (i.name.as_str(), i.view)).collect();
    assert_eq!(names, vec![("produce", ViewId(0)), ("readback", ViewId(0))]);
    let culled: Vec<(&str, ViewId)> = s.culled.iter().map(|c| (c.name.as_str(), c.view)).collect();
    assert_eq!(culled, vec![("produce", ViewId(1)), ("dead", ViewId(0)), ("dead", ViewId(1))]);
    assert!(s.validate().is_ok());
}

#[test]
fn reprojection_reads_derive_delta_edges_and_versions_order_passes() {
    let mut g = Graph::new(topology());
    let mut colour = g.image("colour", Format::Rgba32f);
    g.pass("trace", Role::Sources).write(&mut colour).add();
    g.pass("reproject", Role::Targets).read_sources(&colour).write(&mut colour).add();
    g.pass("post", Role::All).read(&colour).write(&mut colour).add();
    g.export(&colour);
    assert_eq!(colour.version(ViewId(0)), 2, "source: trace, post");
    assert_eq!(colour.version(ViewId(1)), 2, "target: reproject, post");
    let s = compile(&g, &Single).unwrap();
    assert_eq!(s.delta_edges.len(), 1);
    let e = s.delta_edges[0];
    assert_eq!((e.source, e.target, s.instance(e.consumer).name.as_str()), (ViewId(0), ViewId(1), "reproject"));
    // post of the target reads version 1 of its own colour, written by reproject
    let post1 = s.instances.iter().position(|i| i.name == "post" && i.view == ViewId(1)).unwrap();
    let producers: Vec<&str> =
        s.edges.iter().filter(|e| e.consumer.index() == post1).map(|e| s.instance(e.producer).name.as_str()).collect();
    assert_eq!(producers, vec!["reproject"]);
}

#[test]
fn history_must_stay_on_its_device() {
    struct Swapped;
    impl Placement for Swapped {
        fn devices(&self) -> u32 {
            2
        }
        fn place(&self, pass: PassPlacementInfo<'_>, _: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
            let d = if pass.name == "accumulate" { 1 } else { 0 };
            vec![(DeviceId(d), Region::rows(height))]
        }
    }
    let mut g = Graph::new(topology());
    let mut acc = g.image("acc", Format::Rgba32f);
    let mut out = g.image("out", Format::Rgba32f);
    g.pass("accumulate", Role::All).write(&mut acc).add();
    g.pass("temporal", Role::All).read(&acc).read_history(&out).write(&mut out).add();
    g.export(&out);
    assert!(compile(&g, &Single).unwrap().validate().is_ok());
    let mut g2 = Graph::new(topology());
    let mut acc = g2.image("acc", Format::Rgba32f);
    g2.pass("accumulate", Role::All).read_history(&acc).write(&mut acc).add();
    g2.pass("blend", Role::All).read_history(&acc).read(&acc).side_effect().add();
    assert!(
        matches!(compile(&g2, &Swapped).unwrap_err(), GraphError::HistoryAcrossDevices { ref pass, reader: 0, writer: 1, .. } if pass == "blend")
    );
}
