//! Global resources on the GPU: a global image written once by a global pass (the testkit's
//! fill, as view 0's pattern) and a global buffer, allocated by the backend on the writer's
//! device, copied to the other device where per-view passes read the image, every view's
//! output bit-identical to the CPU reference under every scheme on one and two devices.

use std::sync::Arc;

use parallax_backend::{
    Executor, InstanceId, KernelGraph, KernelPlan, PassInstance, PassKernel, PassParams, Recorder, ResourceKind,
};
use parallax_graph::{
    AssignStrategy, DeviceId, FamilyId, Format, LightField, Partition, PartitionConfig, ProvenSchedule, ReadSlot, Rig,
    Role, Scheme, WriteSlot, compile,
};
use parallax_testkit::kernels::{FillBufferKernel, FillKernel, reference_shift_blend, shift_of_view};

const SIZE: u32 = 16;

/// The family of [`global_graph`]'s `output` (its fourth declared resource).
const OUTPUT: FamilyId = FamilyId(3);

/// fill per view → `pattern`; the global pass `fill_global` → the global image `shared` (view
/// 0's pattern) and `shared_words` → shift_blend of every view: its own pattern with `shared`.
fn global_graph(scheme: Scheme, devices: u32) -> (KernelGraph, ProvenSchedule) {
    let lf = LightField::new("2x1".parse().unwrap(), None, Some((SIZE, SIZE)), Rig::default()).unwrap();
    let config = PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::new(&lf, &config).unwrap();
    let mut g = KernelGraph::with_payload(plan.topology.clone());
    let mut pattern = g.image("pattern", Format::Rgba32f);
    let mut shared = g.global_image("shared", SIZE, SIZE, Format::Rgba32f);
    let mut words = g.global_buffer("shared_words", 64);
    let mut output = g.image("output", Format::Rgba32f);
    assert_eq!(output.family(), OUTPUT);
    let mut fill = g.pass("fill", Role::All);
    let out = fill.write_slot(&mut pattern);
    fill.kernel(Arc::new(FillKernel { out })).add();
    let mut fill_global = g.global_pass("fill_global");
    let out = fill_global.write_slot(&mut shared);
    fill_global.kernel(Arc::new(FillKernel { out })).add();
    let mut fill_words = g.global_pass("fill_words");
    let out = fill_words.write_slot(&mut words);
    fill_words.kernel(Arc::new(FillBufferKernel { out })).side_effect().add();
    let mut blend = g.pass("blend", Role::All);
    let (own, other, out) = (blend.read_slot(&pattern), blend.read_slot(&shared), blend.write_slot(&mut output));
    blend.kernel(Arc::new(BlendWithGlobal { own, other, out })).add();
    g.export(&output);
    let schedule = compile(&g, &plan).unwrap();
    assert_eq!(schedule.validate().errors, vec![], "{scheme:?} on {devices}");
    (g, schedule)
}

/// `shift_blend.comp` of the view's own pattern with the global image (the testkit's
/// `ShiftBlendKernel` blends with a source view instead).
struct BlendWithGlobal {
    own: ReadSlot,
    other: ReadSlot,
    out: WriteSlot,
}

impl PassKernel for BlendWithGlobal {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let dst = pass.write(self.out)?.alloc;
        let base = rec.row_params(pass, dst)?;
        let params = PassParams {
            src0: rec.image(pass.read(self.own)?.alloc)?,
            src1: rec.image(pass.read(self.other)?.alloc)?,
            param: shift_of_view(pass.view.0, base.width),
            ..base
        };
        rec.dispatch_rows("shift_blend", params)
    }
}

fn run(scheme: Scheme, devices: u32) -> Vec<Vec<u8>> {
    let (graph, schedule) = global_graph(scheme, devices);
    let plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let shared: Vec<_> = plan.resources.iter().filter(|r| r.name == "shared").collect();
    let blend_devices: std::collections::BTreeSet<DeviceId> =
        plan.passes.iter().filter(|p| p.name == "blend").map(|p| p.device).collect();
    assert_eq!(shared.len(), blend_devices.len(), "{scheme:?}: one allocation on each device that reads it");
    let words: Vec<_> = plan.resources.iter().filter(|r| r.name == "shared_words").collect();
    assert_eq!(words.len(), 1, "nothing reads the buffer elsewhere: one allocation");
    assert_eq!((words[0].kind, words[0].width), (ResourceKind::Buffer, 16));
    let ctx = parallax_testkit::lavapipe_context(devices as usize);
    let mut exec = Executor::new(&ctx, plan.clone(), parallax_testkit::options()).unwrap();
    for _ in 0..2 {
        exec.run_frame().unwrap();
    }
    exec.finish().unwrap();
    let outputs = (0..2)
        .map(|view| {
            let (device, resource) = plan.final_output(OUTPUT, view).unwrap();
            let bytes = exec.read_resource(device, resource).unwrap();
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
