//! Schedules compiled by the graph crate, executed on 1, 2 and 3 logical devices: bit-identical
//! to each other and to the CPU reference, every copy of the schedule executed once per frame.

use std::sync::Arc;

use parallax_backend::KernelGraph;
use parallax_backend::{
    Context, ContextDesc, DeviceSelection, EventKind, ExecOptions, ExecutionPlan, Executor, KernelPlan, Validation,
};
use parallax_graph::Format;
use parallax_graph::{
    AllocId, AssignStrategy, DeviceId, FamilyId, LightField, PartitionConfig, ProvenSchedule, Rig, Role, Scheme,
    ViewId, compile,
};
use parallax_testkit::kernels::{
    FillBufferKernel, FillKernel, ShiftBlendKernel, declare_writer, reference_shift_blend,
};

const SIZE: u32 = 32;

/// The family of [`fill_and_blend`]'s `output` (its second declared resource).
const OUTPUT: FamilyId = FamilyId(1);

/// fill (sources and targets as separate passes) → shift_blend reading the view's first
/// source → output exported (gathered on device 0).
fn demo_schedule(scheme: Scheme, devices: u32) -> ((KernelGraph, ProvenSchedule), Vec<Vec<ViewId>>) {
    let lf = LightField::new("4x1".parse().unwrap(), None, Some((SIZE, SIZE)), Rig::default()).unwrap();
    let config = PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources: Some(vec![0, 3]) };
    let plan = parallax_graph::Partition::new(&lf, &config).unwrap();
    (fill_and_blend(&plan), plan.topology.sources_of.clone())
}

/// The fill → shift_blend graph of [`demo_schedule`] compiled for `plan`, validated.
fn fill_and_blend(plan: &parallax_graph::Partition) -> (KernelGraph, ProvenSchedule) {
    let mut g = KernelGraph::with_payload(plan.topology.clone());
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut output = g.image("output", Format::Rgba32f);
    assert_eq!(output.family(), OUTPUT);
    declare_writer(&mut g, "fill", Role::Sources, &mut radiance, |out| FillKernel { out }).add();
    declare_writer(&mut g, "fill", Role::Targets, &mut radiance, |out| FillKernel { out }).add();
    let mut blend = g.pass("shift_blend", Role::All);
    let kernel = ShiftBlendKernel {
        own: blend.read_slot(&radiance),
        sources: blend.read_sources_slot(&radiance),
        out: blend.write_slot(&mut output),
    };
    blend.kernel(Arc::new(kernel)).add();
    g.export(&output);
    let schedule = compile(&g, plan).unwrap();
    (g, schedule)
}

/// Per view, the resource of its gathered `output` on device 0.
fn output_resources(plan: &ExecutionPlan, views: u32) -> Vec<(u32, AllocId)> {
    (0..views)
        .map(|v| (v, plan.final_output(OUTPUT, v).unwrap()))
        .map(|(v, (d, r))| {
            assert_eq!(d, DeviceId(0));
            (v, r)
        })
        .collect()
}

fn run(scheme: Scheme, devices: u32) -> Vec<Vec<f32>> {
    let ((graph, schedule), sources_of) = demo_schedule(scheme, devices);
    let plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
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
    for report in exec.take_reports() {
        let outs = report.events.iter().filter(|e| e.kind == EventKind::CopyOut).count();
        let ins = report.events.iter().filter(|e| e.kind == EventKind::CopyIn).count();
        assert_eq!((outs, ins), (schedule.copies.len(), schedule.copies.len()));
        let passes = report.events.iter().filter(|e| e.kind == EventKind::Pass).count();
        assert_eq!(passes, schedule.instances.len());
    }
    let outputs: Vec<Vec<f32>> = output_resources(&plan, schedule.views)
        .into_iter()
        .map(|(view, r)| {
            let bytes = exec.read_resource(DeviceId(0), r).unwrap();
            let values: Vec<f32> =
                bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            let other = sources_of[view as usize].first().map_or(view, |s| s.0);
            let expected: Vec<f32> = (0..SIZE)
                .flat_map(|y| (0..SIZE).flat_map(move |x| reference_shift_blend(x, y, view, other, SIZE)))
                .collect();
            assert_eq!(values, expected, "{scheme:?} on {devices} devices, view {view}");
            values
        })
        .collect();
    drop(exec);
    ctx.check_validation().unwrap();
    outputs
}

#[test]
fn fine_all_on_one_two_three_devices_is_bit_identical() {
    let one = run(Scheme::FineAll, 1);
    for devices in [2, 3] {
        let ((_, schedule), _) = demo_schedule(Scheme::FineAll, devices);
        assert!(!schedule.copies.is_empty());
        assert_eq!(run(Scheme::FineAll, devices), one);
    }
}

#[test]
fn fine_sources_on_one_two_three_devices_is_bit_identical() {
    let one = run(Scheme::FineSources, 1);
    for devices in [2, 3] {
        assert_eq!(run(Scheme::FineSources, devices), one);
    }
}

#[test]
fn both_schemes_really_copy_between_devices() {
    for scheme in [Scheme::FineAll, Scheme::FineSources] {
        for devices in [2, 3] {
            let ((graph, schedule), _) = demo_schedule(scheme, devices);
            let plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
            plan.validate(devices as usize).unwrap();
            assert!(plan.copies.iter().any(|c| c.region.len() < SIZE), "{scheme:?}/{devices}: expected band copies");
            // Fine-sources finishes every view on device 0; fine-all gathers the bands there.
            let gathers = schedule.gather_copies().count();
            assert_eq!(gathers > 0, scheme == Scheme::FineAll, "{scheme:?}/{devices}");
        }
    }
}

#[test]
fn per_view_buffers_from_the_graph_are_filled_and_gathered() {
    use parallax_backend::ResourceKind;
    use parallax_testkit::kernels::reference_buffer_word;
    let lf = LightField::new("3x1".parse().unwrap(), None, Some((8, 8)), Rig::default()).unwrap();
    let config =
        PartitionConfig { devices: 3, scheme: Scheme::MultiSource, assign: AssignStrategy::Compact, sources: None };
    let plan = parallax_graph::Partition::new(&lf, &config).unwrap();
    let mut g = KernelGraph::with_payload(plan.topology.clone());
    let bytes = 1000; // not a multiple of 4 on purpose: rounded up to 250 words
    let mut list = g.buffer("list", bytes);
    declare_writer(&mut g, "fill_buffer", Role::All, &mut list, |out| FillBufferKernel { out }).add();
    g.export(&list);
    let schedule = compile(&g, &plan).unwrap();
    let exec_plan = KernelPlan::from_schedule(&g, &schedule).unwrap();
    assert!(exec_plan.resources.iter().all(|r| r.kind == ResourceKind::Buffer && r.width == 250));
    assert_eq!(exec_plan.copies.len(), 2, "views on devices 1 and 2 gathered to device 0");
    let gathered: Vec<AllocId> = (0..3).map(|v| exec_plan.final_output(list.family(), v).unwrap().1).collect();
    let ctx = Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(3), validation: Validation::Core })
        .unwrap();
    let mut exec = Executor::new(&ctx, exec_plan.clone(), parallax_testkit::options()).unwrap();
    exec.run_frame().unwrap();
    for r in gathered {
        let resource = exec_plan.resource(r);
        let bytes = exec.read_resource(DeviceId(0), r).unwrap();
        let words: Vec<u32> = bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let expected: Vec<u32> = (0..250).map(|i| reference_buffer_word(i, resource.view)).collect();
        assert_eq!(words, expected, "view {}", resource.view);
    }
    drop(exec);
    ctx.check_validation().unwrap();
}

/// Every scheme, several layouts and device counts: each view's gathered output equals the CPU
/// reference of its own sources (which differ between schemes and device counts).
#[test]
fn every_scheme_layout_and_device_count_matches_the_cpu_reference() {
    let size = 16;
    for layout in ["3x1", "2x2", "5x1"] {
        for scheme in [Scheme::MultiSource, Scheme::FineSources, Scheme::FineAll] {
            for devices in [1u32, 2, 3] {
                let lf = LightField::new(layout.parse().unwrap(), None, Some((size, size)), Rig::default()).unwrap();
                if devices as usize > lf.len() {
                    continue;
                }
                let config = PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources: None };
                let plan = parallax_graph::Partition::new(&lf, &config).unwrap();
                let (graph, schedule) = fill_and_blend(&plan);
                let exec_plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
                let outputs = output_resources(&exec_plan, lf.len() as u32);
                let ctx = Context::new(&ContextDesc {
                    selection: DeviceSelection::FakeDevices(devices as usize),
                    validation: Validation::Core,
                })
                .unwrap();
                let options = ExecOptions { separate_copy_queue: devices == 2, ..parallax_testkit::options() };
                let mut exec = Executor::new(&ctx, exec_plan, options).unwrap();
                exec.run_frame().unwrap();
                exec.run_frame().unwrap();
                for &(view, r) in &outputs {
                    let values: Vec<f32> = exec
                        .read_resource(DeviceId(0), r)
                        .unwrap()
                        .chunks_exact(4)
                        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                        .collect();
                    let other = plan.topology.sources_of[view as usize].first().map_or(view, |s| s.0);
                    let expected: Vec<f32> = (0..size)
                        .flat_map(|y| (0..size).flat_map(move |x| reference_shift_blend(x, y, view, other, size)))
                        .collect();
                    assert_eq!(values, expected, "{layout} {scheme:?} on {devices} devices, view {view}");
                }
                drop(exec);
                ctx.check_validation().unwrap();
            }
        }
    }
}

#[test]
fn graph_exports_are_read_back_by_the_frame_loop() {
    let devices = 2;
    let ((graph, schedule), _) = demo_schedule(Scheme::FineAll, devices);
    let plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let mut outputs: Vec<AllocId> = output_resources(&plan, schedule.views).into_iter().map(|(_, r)| r).collect();
    outputs.sort();
    let exported: Vec<AllocId> = plan.resource_ids().filter(|(_, r)| r.exported).map(|(a, _)| a).collect();
    assert_eq!(exported, outputs, "the kernel plan keeps the graph's exports");
    let ctx = Context::new(&ContextDesc {
        selection: DeviceSelection::FakeDevices(devices as usize),
        validation: Validation::Core,
    })
    .unwrap();
    let options = ExecOptions { read_back_exports: true, ..parallax_testkit::options() };
    let mut exec = Executor::new(&ctx, plan, options).unwrap();
    let tickets = [exec.submit_frame().unwrap(), exec.submit_frame().unwrap()];
    let mut frames = Vec::new();
    for ticket in tickets {
        frames.push(exec.wait_readback(ticket).unwrap());
    }
    assert_eq!(frames[0].len(), outputs.len());
    assert_eq!(frames[0], frames[1], "the demo renders the same every frame");
    for (r, bytes) in &frames[0] {
        assert_eq!(*bytes, exec.read_resource(DeviceId(0), *r).unwrap(), "resource {r}");
    }
    drop(exec);
    ctx.check_validation().unwrap();
}
