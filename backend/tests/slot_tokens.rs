//! Kernels bind through the slot tokens their pass's declaration returned (no GPU needed): each
//! token finds its own access in every instance, and a token of another pass is refused
//! naming the pass that lacks it, even where that pass has an access at the same index.

use std::sync::Arc;

use parallax_backend::{BackendError, InstanceId, KernelGraph, KernelPlan, PassInstance, PassKernel, Recorder};
use parallax_graph::{BandedPlacement, Format, Origin, Role, UnboundSlot, ViewId, ViewTopology, compile};

/// A kernel that records nothing: these tests only look at the kernel plan built.
struct Nothing;

impl PassKernel for Nothing {
    fn record(&self, _: &mut Recorder<'_>, _: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        Ok(())
    }
}

fn pass_named<'p>(plan: &'p KernelPlan, name: &str, view: u32) -> &'p PassInstance {
    plan.passes.iter().find(|p| p.name == name && p.view == ViewId(view)).unwrap()
}

#[test]
fn each_token_binds_its_own_access_and_a_foreign_one_is_refused() {
    // View 0 is the source of view 1.
    let topology =
        ViewTopology { width: 4, height: 4, sources_of: vec![vec![], vec![ViewId(0)]], is_source: vec![true, false] };
    let mut g = KernelGraph::with_payload(topology);
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut acc = g.image("acc", Format::Rgba32f);
    let mut out = g.image("out", Format::Rgba32f);
    g.import(&acc);

    let mut trace = g.pass("trace", Role::All);
    let traced = trace.write_slot(&mut radiance);
    trace.kernel(Arc::new(Nothing)).add();
    let mut blend = g.pass("blend", Role::Targets);
    let history = blend.read_history_slot(&acc);
    let own = blend.read_slot(&radiance);
    let sources = blend.read_sources_slot(&radiance);
    let (_, accumulated) = blend.modify_slot(&mut acc);
    let blended = blend.write_slot(&mut out);
    blend.side_effect().kernel(Arc::new(Nothing)).add();

    let placement = BandedPlacement { devices: 1, bands: 1 };
    let plan = KernelPlan::from_schedule(&g, &compile(&g, &placement).unwrap()).unwrap();
    let blend = pass_named(&plan, "blend", 1);
    let name = |access: &parallax_backend::Access| plan.resource(access.alloc).name.clone();
    assert_eq!(name(blend.read(own).unwrap()), "radiance");
    assert_eq!(blend.read(own).unwrap().origin, Origin::Own);
    let source_views: Vec<u32> = blend.sources(sources).unwrap().map(|a| plan.resource(a.alloc).view).collect();
    assert_eq!(source_views, [0]);
    assert_eq!(name(blend.history_read(history).unwrap()), "acc");
    assert_eq!(name(blend.write(accumulated).unwrap()), "acc");
    assert_eq!(name(blend.write(blended).unwrap()), "out");
    assert_eq!(name(pass_named(&plan, "trace", 0).write(traced).unwrap()), "radiance");

    // `trace` declared no reads: `blend`'s read token names nothing there.
    match pass_named(&plan, "trace", 1).read(own) {
        Err(UnboundSlot { pass, .. }) => assert_eq!(pass, "trace"),
        other => panic!("expected UnboundSlot, got {other:?}"),
    }
    // `blend` has a write at `trace`'s write's index, but the token is `trace`'s.
    let refused = blend.write(traced).unwrap_err();
    assert_eq!(refused.pass, "blend");
    // A kernel's `?` turns it into the backend's error, message kept.
    let message = refused.to_string();
    assert!(message.starts_with("pass `blend`'s kernel binds WriteSlot("), "{message}");
    assert_eq!(BackendError::from(refused).to_string(), message);
}
