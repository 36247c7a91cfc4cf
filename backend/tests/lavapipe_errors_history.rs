//! Exact error variants of the backend, the validation messenger, and history resources that
//! survive from frame to frame (lavapipe or any Vulkan device).

use std::collections::BTreeSet;
use std::sync::Arc;

use parallax_backend::{
    BackendError, Context, ContextDesc, DeviceSelection, ExecOptions, ExecutionPlanError, Executor, KernelGraph,
    KernelPlan, KernelPlanError, Validation,
};
use parallax_graph::{
    AllocId, BandedPlacement, CopyId, DeviceId, FamilyId, Format, Op, PassPlacementInfo, Placement, Region, Role,
    ScheduleError, ViewId, ViewTopology, compile,
};
use parallax_testkit::kernels::{
    AccumulateKernel, FillKernel, FillMaskKernel, RasterDemoKernel, WeightedFillKernel, declare_writer,
};

fn context(selection: DeviceSelection) -> Result<Context, BackendError> {
    Context::new(&ContextDesc { selection, validation: Validation::Core })
}

#[test]
fn asking_for_more_gpus_than_exist_names_both_counts() {
    let err = context(DeviceSelection::Gpus(64)).err().unwrap();
    match err {
        BackendError::NotEnoughGpus { requested, available } => {
            assert_eq!(requested, 64);
            assert!((1..64).contains(&available));
        }
        other => panic!("unexpected {other}"),
    }
}

#[test]
fn zero_devices_is_refused() {
    assert!(matches!(context(DeviceSelection::FakeDevices(0)).err().unwrap(), BackendError::ZeroDevices));
}

#[test]
fn validation_messages_fail_the_check() {
    use ash::vk;
    let ctx = context(DeviceSelection::FakeDevices(1)).unwrap();
    ctx.check_validation().unwrap();
    let device = ctx.devices()[0].raw();
    // size 0 violates VUID-VkBufferCreateInfo-size-00912.
    let info = vk::BufferCreateInfo::default().size(0).usage(vk::BufferUsageFlags::TRANSFER_DST);
    if let Ok(buffer) = unsafe { device.create_buffer(&info, None) } {
        unsafe { device.destroy_buffer(buffer, None) };
    }
    match ctx.check_validation() {
        Err(BackendError::Validation { messages }) => {
            assert!(messages.iter().any(|m| m.contains("VUID-VkBufferCreateInfo-size")), "{messages:?}");
        }
        other => panic!("expected a validation failure, got {other:?}"),
    }
    ctx.check_validation().unwrap();
}

/// Every pass instance on one device, whole views.
struct OnDevice {
    device: u32,
    devices: u32,
}

impl Placement for OnDevice {
    fn devices(&self) -> u32 {
        self.devices
    }

    fn place(&self, _: PassPlacementInfo<'_>, _: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        vec![(DeviceId(self.device), Region::rows(height))]
    }
}

fn compile_graph(graph: &KernelGraph, placement: &dyn Placement) -> KernelPlan {
    let schedule = compile(graph, placement).unwrap();
    assert_eq!(schedule.validate().errors, vec![]);
    KernelPlan::from_schedule(graph, &schedule).unwrap()
}

/// `views` views of `size`², each accumulating into `acc` from its own history (`read_history`),
/// exported; and the family of `acc`.
fn history_graph(views: u32, size: u32) -> (KernelGraph, FamilyId) {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(views, size, size));
    let mut acc = graph.image("acc", Format::Rgba32f);
    let mut pass = graph.pass("accumulate", Role::All);
    let history = pass.read_history_slot(&acc);
    let kernel = AccumulateKernel { acc: pass.write_slot(&mut acc), history };
    pass.kernel(Arc::new(kernel)).add();
    graph.export(&acc);
    (graph, acc.family())
}

/// [`history_graph`] under `placement`, and the family of its `acc`.
fn history_plan(views: u32, size: u32, placement: &dyn Placement) -> (KernelPlan, FamilyId) {
    let (graph, acc) = history_graph(views, size);
    (compile_graph(&graph, placement), acc)
}

fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// Runs `frames` frames with 2 in flight; returns every view's final `acc` as read on device 0
/// and the other half of its history allocation on the device that wrote it (last frame's).
fn run_history(devices: usize, placement: &dyn Placement, views: u32, frames: u32) -> Vec<(Vec<f32>, Vec<f32>)> {
    let ctx = context(DeviceSelection::FakeDevices(devices)).unwrap();
    let (plan, acc) = history_plan(views, 8, placement);
    assert_eq!(
        plan.history.len(),
        plan.passes.iter().map(|p| p.device).collect::<BTreeSet<_>>().len() * views as usize
    );
    let options = ExecOptions { frames_in_flight: 2, ..parallax_testkit::options() };
    let mut exec = Executor::new(&ctx, plan.clone(), options).unwrap();
    for _ in 0..frames {
        exec.run_frame().unwrap();
    }
    let mut out = Vec::new();
    for v in 0..views {
        let (device, resource) = plan.final_output(acc, v).unwrap();
        let current = floats(&exec.read_resource(device, resource).unwrap());
        let writer = plan.passes.iter().find(|p| p.view.0 == v).unwrap();
        let own = writer.writes.iter().map(|w| w.alloc).find(|&w| plan.resource(w).family == acc).unwrap();
        // Reads resolve through the last frame's parity: `own` is what it wrote, its twin what
        // the frame before wrote (what its history reads saw).
        let other = plan.history.iter().find(|p| p.current == own).unwrap().previous;
        let previous = floats(&exec.read_resource(writer.device, other).unwrap());
        out.push((current, previous));
    }
    assert_eq!(exec.recordings(), 1, "parity swaps need no re-recording");
    drop(exec);
    ctx.check_validation().unwrap();
    out
}

#[test]
fn history_reads_see_exactly_last_frames_output_on_one_and_three_devices() {
    let frames = 6;
    let sum = |n: u32| (n * (n + 1) / 2) as f32;
    let one = run_history(1, &OnDevice { device: 0, devices: 1 }, 3, frames);
    let three = run_history(3, &BandedPlacement { devices: 3, bands: 3 }, 3, frames);
    assert_eq!(one, three, "1 and 3 devices are bit-identical");
    for (current, previous) in &one {
        assert!(current.chunks_exact(4).all(|t| t[0] == sum(frames) && t[1] == 1.0), "{:?}", &current[..4]);
        let distinct: BTreeSet<u32> = previous.chunks_exact(4).map(|t| t[0] as u32).collect();
        assert_eq!(distinct, BTreeSet::from([sum(frames - 1) as u32]), "last frame's half");
    }
}

#[test]
fn the_first_frame_and_a_reset_tell_the_kernel_history_is_invalid() {
    let ctx = context(DeviceSelection::FakeDevices(1)).unwrap();
    let (plan, acc) = history_plan(1, 8, &OnDevice { device: 0, devices: 1 });
    let (device, resource) = plan.final_output(acc, 0).unwrap();
    let mut exec = Executor::new(&ctx, plan, parallax_testkit::options()).unwrap();
    let texel = |exec: &mut Executor| {
        exec.finish().unwrap();
        let t = floats(&exec.read_resource(device, resource).unwrap());
        (t[0], t[1])
    };
    exec.run_frame().unwrap();
    assert_eq!(texel(&mut exec), (1.0, 0.0), "frame 0: history invalid, nothing blended");
    exec.run_frame().unwrap();
    exec.run_frame().unwrap();
    exec.reset_history();
    exec.run_frame().unwrap();
    // Frame 3 after the reset starts over: 0 + (3 + 1), flag 0.
    assert_eq!(texel(&mut exec), (4.0, 0.0));
    exec.run_frame().unwrap();
    assert_eq!(texel(&mut exec), (9.0, 1.0), "frame 4 builds on frame 3 again");
    drop(exec);
    ctx.check_validation().unwrap();
}

#[test]
fn plan_errors_are_reported_before_any_gpu_work() {
    // A changed schedule is proven again before a kernel plan is built from it (`from_schedule` takes only a
    // proven one); the error is the validator's own.
    let (graph, _) = history_graph(1, 8);
    let mut schedule = compile(&graph, &OnDevice { device: 1, devices: 2 }).unwrap().into_schedule();
    let c = schedule.copies.iter().position(|c| c.to == DeviceId(0)).expect("exports are gathered on device 0");
    schedule.devices[0].ops.retain(|op| *op != Op::Wait(CopyId(c as u32)));
    let first = ScheduleError::CopyOpMissing { copy: CopyId(c as u32), op: "Wait" };
    assert_eq!(schedule.proven().unwrap_err().errors.first(), Some(&first));
    let one = context(DeviceSelection::FakeDevices(1)).unwrap();
    let err = Executor::new(&one, parallax_testkit::plans::copy_plan(8, 8), parallax_testkit::options()).err().unwrap();
    assert!(
        matches!(err, BackendError::ExecutionPlan(ExecutionPlanError::DeviceCount { plan: 2, context: 1 })),
        "{err}"
    );

    // A pass declared without a kernel gets no kernel plan; the error names it.
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(1, 8, 8));
    let mut acc = graph.image("acc", Format::Rgba32f);
    graph.pass("accumulate", Role::All).write(&mut acc).add();
    graph.export(&acc);
    let schedule = compile(&graph, &OnDevice { device: 0, devices: 1 }).unwrap();
    assert_eq!(
        KernelPlan::from_schedule(&graph, &schedule).err().unwrap(),
        KernelPlanError::MissingKernel { pass: "accumulate".into() }
    );
}

#[test]
fn integer_images_go_through_the_uint_binding_and_across_devices() {
    use parallax_testkit::kernels::{reference_fill, reference_mask};
    let size = 16;
    // Device 1 writes a uint mask and a float image side by side (indices interleave the two
    // bindings); both travel to device 0.
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(1, size, size));
    let mut mask = graph.image("mask", Format::R32u);
    let mut radiance = graph.image("radiance", Format::Rgba32f);
    declare_writer(&mut graph, "fill_mask", Role::All, &mut mask, |out| FillMaskKernel { out }).add();
    declare_writer(&mut graph, "fill", Role::All, &mut radiance, |out| FillKernel { out }).add();
    graph.export(&mask);
    graph.export(&radiance);
    let plan = compile_graph(&graph, &OnDevice { device: 1, devices: 2 });
    assert_eq!(plan.copies.len(), 2);
    let (mask_device, mask_resource) = plan.final_output(mask.family(), 0).unwrap();
    let (radiance_device, radiance_resource) = plan.final_output(radiance.family(), 0).unwrap();
    assert_eq!((mask_device, radiance_device), (DeviceId(0), DeviceId(0)));
    let ctx = context(DeviceSelection::FakeDevices(2)).unwrap();
    let mut exec = Executor::new(&ctx, plan, parallax_testkit::options()).unwrap();
    exec.run_frame().unwrap();
    let mask = exec.read_resource(DeviceId(0), mask_resource).unwrap();
    let radiance = exec.read_resource(DeviceId(0), radiance_resource).unwrap();
    let words = |b: &[u8]| b.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect::<Vec<_>>();
    let mask: Vec<u32> = words(&mask).into_iter().map(u32::from_le_bytes).collect();
    let radiance: Vec<f32> = words(&radiance).into_iter().map(f32::from_le_bytes).collect();
    let expected_mask: Vec<u32> = (0..size).flat_map(|y| (0..size).map(move |x| reference_mask(x, y, 0))).collect();
    let expected_radiance: Vec<f32> =
        (0..size).flat_map(|y| (0..size).flat_map(move |x| reference_fill(x, y, 0))).collect();
    assert_eq!(mask, expected_mask);
    assert_eq!(radiance, expected_radiance);
    drop(exec);
    ctx.check_validation().unwrap();
}

/// One raster pass instance per device, each over a row band of the same colour image and
/// depth resource; bands of both gathered on device 0. Returns the plan and the families of the
/// image and the depth resource.
fn raster_plan(devices: usize, size: u32) -> (KernelPlan, [FamilyId; 2]) {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(6, size, size));
    let mut gbuffer = graph.image("gbuffer", Format::Rgba32f);
    let mut depth = graph.image("depth", Format::Depth32f);
    let mut pass = graph.pass("raster_demo", Role::All);
    let kernel = RasterDemoKernel { gbuffer: pass.write_slot(&mut gbuffer), depth: pass.write_slot(&mut depth) };
    pass.kernel(Arc::new(kernel)).add();
    graph.export(&gbuffer);
    graph.export(&depth);
    let plan = compile_graph(&graph, &BandedPlacement { devices: devices as u32, bands: devices as u32 });
    (plan, [gbuffer.family(), depth.family()])
}

#[test]
fn raster_passes_render_row_bands_into_a_depth_resource_on_any_device_count() {
    use parallax_testkit::kernels::{RASTER_FAR_DEPTH, RASTER_NEAR_DEPTH, reference_raster};
    let size = 32;
    let expected: Vec<f32> =
        (0..size).flat_map(|y| (0..size).flat_map(move |x| reference_raster(x, y, 5, size))).collect();
    let expected_depth: Vec<f32> = (0..size)
        .flat_map(|_| (0..size).map(move |x| if x < size / 2 { RASTER_NEAR_DEPTH } else { RASTER_FAR_DEPTH }))
        .collect();
    for devices in [1, 2, 3] {
        let ctx = context(DeviceSelection::FakeDevices(devices)).unwrap();
        let (plan, [gbuffer, depth]) = raster_plan(devices, size);
        let (device, resource) = plan.final_output(gbuffer, 5).unwrap();
        let (depth_device, depth_resource) = plan.final_output(depth, 5).unwrap();
        assert_eq!((device, depth_device), (DeviceId(0), DeviceId(0)));
        let mut exec = Executor::new(&ctx, plan, parallax_testkit::options()).unwrap();
        exec.run_frame().unwrap();
        exec.run_frame().unwrap();
        let values = floats(&exec.read_resource(device, resource).unwrap());
        assert_eq!(values, expected, "{devices} device(s)");
        // The depth attachment is a graph resource: its bands crossed devices as depth copies.
        let depth = floats(&exec.read_resource(depth_device, depth_resource).unwrap());
        assert_eq!(depth, expected_depth, "{devices} device(s)");
        drop(exec);
        ctx.check_validation().unwrap();
    }
}

/// Two views, view v on device v, each `weighted_fill`ed; view 1 gathered on device 0. Returns
/// the plan and the family of `w`.
fn weighted_plan(size: u32) -> (KernelPlan, FamilyId) {
    struct ViewPerDevice;
    impl Placement for ViewPerDevice {
        fn devices(&self) -> u32 {
            2
        }
        fn place(&self, _: PassPlacementInfo<'_>, view: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
            vec![(DeviceId(view.0), Region::rows(height))]
        }
    }
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(2, size, size));
    let mut w = graph.image("w", Format::Rgba32f);
    declare_writer(&mut graph, "weighted_fill", Role::All, &mut w, |out| WeightedFillKernel { out }).add();
    graph.export(&w);
    (compile_graph(&graph, &ViewPerDevice), w.family())
}

#[test]
fn global_buffers_and_frame_data_reach_kernels_by_address() {
    use parallax_testkit::kernels::reference_fill;
    let size = 16;
    let ctx = context(DeviceSelection::FakeDevices(2)).unwrap();
    let (plan, w) = weighted_plan(size);
    let outputs: Vec<AllocId> = (0..2).map(|v| plan.final_output(w, v).unwrap().1).collect();
    let mut exec = Executor::new(&ctx, plan, parallax_testkit::options()).unwrap();
    let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let check = |exec: &mut Executor, weights: [f32; 2], offset: f32| {
        for view in 0..2u32 {
            let bytes = exec.read_resource(DeviceId(0), outputs[view as usize]).unwrap();
            let got: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            let expected: Vec<f32> = (0..size)
                .flat_map(|y| (0..size).flat_map(move |x| reference_fill(x, y, view)))
                .map(|p| p * weights[view as usize] + offset)
                .collect();
            assert_eq!(got, expected, "view {view}, weights {weights:?}, offset {offset}");
        }
    };

    // Running before the kernel's buffer exists is an error naming it.
    match exec.run_frame() {
        Err(BackendError::UnknownBuffer { name, device: 0 }) => assert_eq!(name, "weights"),
        other => panic!("expected UnknownBuffer, got {other:?}"),
    }
    exec.upload_buffer("weights", &floats(&[0.5, 2.0])).unwrap();
    exec.set_frame_data(&floats(&[0.25])).unwrap();
    exec.run_frame().unwrap();
    check(&mut exec, [0.5, 2.0], 0.25);
    let recorded = exec.recordings();

    // Same size: contents change in place, nothing is re-recorded; frame data changes per frame.
    exec.upload_buffer("weights", &floats(&[1.0, 4.0])).unwrap();
    exec.set_frame_data(&floats(&[0.5])).unwrap();
    exec.run_frame().unwrap();
    exec.run_frame().unwrap();
    check(&mut exec, [1.0, 4.0], 0.5);
    assert_eq!(exec.recordings(), recorded);

    // Another size moves the buffer: recorded again before the next frame.
    exec.upload_buffer("weights", &floats(&[0.25, 0.125, 9.0])).unwrap();
    exec.run_frame().unwrap();
    check(&mut exec, [0.25, 0.125], 0.5);
    assert_eq!(exec.recordings(), recorded + 1);

    let too_big = vec![0u8; (parallax_testkit::options().frame_data_bytes + 4) as usize];
    assert!(matches!(exec.set_frame_data(&too_big), Err(BackendError::FrameDataTooLarge { .. })));
    drop(exec);
    ctx.check_validation().unwrap();
}
