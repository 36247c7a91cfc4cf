//! Global resources on the GPU: a global image written once by a global pass (the testkit's
//! fill, as view 0's pattern) and a global buffer, allocated by the backend on the writer's
//! device, copied to the other device where per-view passes read the image, every view's
//! output bit-identical to the CPU reference under every scheme on one and two devices.

use std::sync::Arc;

use parallax_backend::{
    Context, ContextDesc, DeviceSelection, ExecutionPlan, Executor, KernelGraph, ResourceKind, Validation,
};
use parallax_graph::{AssignStrategy, Format, LightField, Plan, PlanConfig, Rig, Role, Schedule, Scheme, compile};
use parallax_testkit::kernels::{FillBufferKernel, FillKernel, ShiftBlendKernel, reference_shift_blend};

const SIZE: u32 = 16;

/// fill per view → `pattern`; the global pass `fill_global` → the global image `shared` (view
/// 0's pattern) and `shared_words` → shift_blend of every view: its own pattern with `shared`.
fn global_graph(scheme: Scheme, devices: u32) -> (KernelGraph, Schedule) {
    let lf = LightField::new("2x1".parse().unwrap(), None, Some((SIZE, SIZE)), Rig::default()).unwrap();
    let config = PlanConfig { devices, scheme, assign: AssignStrategy::Compact, sources: None };
    let plan = Plan::new(&lf, &config).unwrap();
    let mut g = KernelGraph::with_payload(plan.topology.clone());
    let mut pattern = g.image("pattern", Format::Rgba32f);
    let mut shared = g.global_image("shared", SIZE, SIZE, Format::Rgba32f);
    let mut words = g.global_buffer("shared_words", 64);
    let mut output = g.image("output", Format::Rgba32f);
    g.pass("fill", Role::All).write(&mut pattern).kernel(Arc::new(FillKernel)).record();
    g.global_pass("fill_global").write(&mut shared).kernel(Arc::new(FillKernel)).record();
    g.global_pass("fill_words").write(&mut words).kernel(Arc::new(FillBufferKernel)).side_effect().record();
    g.pass("blend", Role::All)
        .read(&pattern)
        .read(&shared)
        .write(&mut output)
        .kernel(Arc::new(ShiftBlendKernel))
        .record();
    g.export(&output);
    let schedule = compile(&g, &plan).unwrap();
    assert_eq!(schedule.validate().errors, vec![], "{scheme:?} on {devices}");
    (g, schedule)
}

fn run(scheme: Scheme, devices: u32) -> Vec<Vec<u8>> {
    let (graph, schedule) = global_graph(scheme, devices);
    let plan = ExecutionPlan::from_schedule(&graph, &schedule).unwrap();
    let shared: Vec<_> = plan.resources.iter().filter(|r| r.name == "shared").collect();
    let blend_devices: std::collections::BTreeSet<usize> =
        plan.passes.iter().filter(|p| p.name == "blend").map(|p| p.device).collect();
    assert_eq!(shared.len(), blend_devices.len(), "{scheme:?}: one allocation on each device that reads it");
    let words: Vec<_> = plan.resources.iter().filter(|r| r.name == "shared_words").collect();
    assert_eq!(words.len(), 1, "nothing reads the buffer elsewhere: one allocation");
    assert_eq!((words[0].kind, words[0].width), (ResourceKind::Buffer, 16));
    let ctx = Context::new(&ContextDesc {
        selection: DeviceSelection::FakeDevices(devices as usize),
        validation: Validation::Core,
    })
    .unwrap();
    let mut exec = Executor::new(&ctx, plan.clone(), parallax_testkit::options()).unwrap();
    for _ in 0..2 {
        exec.run_frame().unwrap();
    }
    exec.finish().unwrap();
    let outputs = (0..2)
        .map(|view| {
            let (device, resource) = plan.final_output("output", view).unwrap();
            let bytes = exec.read_image(device, resource).unwrap();
            let expected: Vec<u8> = (0..SIZE)
                .flat_map(|y| (0..SIZE).flat_map(move |x| reference_shift_blend(x, y, view, 0, SIZE)))
                .flat_map(f32::to_le_bytes)
                .collect();
            assert!(bytes == expected, "{scheme:?} on {devices} devices, view {view}");
            bytes
        })
        .collect();
    drop(exec);
    ctx.check_validation().unwrap();
    outputs
}

#[test]
fn a_global_image_is_written_once_copied_where_it_is_read_and_bit_identical_on_one_and_two_devices() {
    for scheme in Scheme::ALL {
        let one = run(scheme, 1);
        assert_eq!(run(scheme, 2), one, "{scheme:?}");
    }
    let (_, schedule) = global_graph(Scheme::MultiSource, 2);
    let shared = schedule.resources.iter().position(|r| r.name == "shared").unwrap();
    assert_eq!(schedule.copies.iter().filter(|c| c.resource.index() == shared).count(), 1, "to device 1 only");
}
