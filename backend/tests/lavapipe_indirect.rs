//! Data-dependent work on lavapipe, validation (with synchronisation validation) on: a pass
//! computes a count on the GPU and writes indirect-dispatch arguments, the next dispatch runs on
//! them, and the buffers the plan resets start every frame from their header. Frames are read
//! back through the frame loop with two in flight, so a reset that did not happen, or happened
//! in the wrong frame, shows up as a wrong count.

use std::sync::Arc;

use parallax_backend::{
    BackendError, Context, ContextDesc, DeviceSelection, ExecOptions, ExecResource, ExecutionPlanError, Executor,
    Format, InstanceId, KernelGraph, KernelPlan, PassInstance, PassKernel, Recorder, Region, Validation, own_access,
};
use parallax_graph::{AllocId, BandedPlacement, FamilyId, ReadSlot, Role, ViewTopology, WriteSlot, compile};
use parallax_testkit::ids::{self, IndirectArgsParams, IndirectCountParams};
use parallax_testkit::kernels::reference_mask;

const SALT: u32 = 0x5eed;
/// groups_x, groups_y, groups_z, count: what test_indirect_args.comp starts from each frame.
const ARGS_HEADER: [u32; 4] = [0, 1, 1, 0];
const ARGS: &str = "indirect args";
const COUNTER: &str = "counter";

fn context() -> Context {
    Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(1), validation: Validation::CoreAndSync })
        .expect("a Vulkan device (apt-get install mesa-vulkan-drivers) and validation layers")
}

/// N of executor frame `frame`, as test_indirect_args.comp sums it.
fn expected_count(frame: u32) -> u32 {
    (0..64).map(|i| reference_mask(i, frame, SALT) % 32).sum()
}

fn words(bytes: &[u8]) -> Vec<u32> {
    bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// Records the arguments pass (one workgroup) into the buffer `args`.
fn record_args(rec: &mut Recorder<'_>, args: AllocId) -> parallax_backend::Result<()> {
    let args = rec.buffer_of(args)?;
    rec.dispatch(ids::TEST_INDIRECT_ARGS, &IndirectArgsParams { args, salt: SALT, pad: 0 }, [1, 1, 1])
}

/// Records the indirect dispatch on the arguments `args` into the counter `counter`.
fn record_count(rec: &mut Recorder<'_>, args: AllocId, counter: AllocId) -> parallax_backend::Result<()> {
    let push = IndirectCountParams { args: rec.buffer_of(args)?, counter: rec.buffer_of(counter)? };
    rec.dispatch_indirect(ids::TEST_INDIRECT_COUNT, &push, args, 0)
}

/// Pass `indirect_args`: writes the arguments.
struct ArgsKernel {
    args: WriteSlot,
}

impl PassKernel for ArgsKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        record_args(rec, pass.write(self.args)?.alloc)
    }
}

/// Pass `indirect_count`: reads the arguments, writes the counter.
struct CountKernel {
    args: ReadSlot,
    counter: WriteSlot,
}

impl PassKernel for CountKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        record_count(rec, pass.read(self.args)?.alloc, pass.write(self.counter)?.alloc)
    }
}

/// Pass `indirect_fused`: both in one pass, so only the barrier of `dispatch_indirect` itself
/// orders the arguments before their use. (Lavapipe runs dispatches in order, and
/// synchronisation validation cannot see accesses through buffer addresses, so this shows the
/// one-pass form works; it cannot show the barrier is needed.)
struct FusedKernel {
    args: WriteSlot,
    counter: WriteSlot,
}

impl PassKernel for FusedKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let args = pass.write(self.args)?.alloc;
        record_args(rec, args)?;
        record_count(rec, args, pass.write(self.counter)?.alloc)
    }
}

/// A pass that dispatches indirectly from `resource` at `offset`, whatever they are.
struct MisusedKernel {
    resource: AllocId,
    offset: u64,
}

impl PassKernel for MisusedKernel {
    fn record(&self, rec: &mut Recorder<'_>, _: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let push = IndirectCountParams { args: 0, counter: 0 };
        rec.dispatch_indirect(ids::TEST_INDIRECT_COUNT, &push, self.resource, self.offset)
    }
}

/// Arguments and counter (both reset every frame and exported), written by `fused` as one pass
/// or by two; both accumulate into their reset contents in place.
fn indirect_plan(fused: bool) -> KernelPlan {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(1, 1, 1));
    let mut args = graph.buffer(ARGS, 16);
    let mut counter = graph.buffer(COUNTER, 4);
    graph.reset_each_frame(&args, ARGS_HEADER.to_vec());
    graph.reset_each_frame(&counter, vec![]);
    if fused {
        let mut pass = graph.pass("indirect_fused", Role::All);
        let kernel = FusedKernel { args: pass.modify_slot(&mut args).1, counter: pass.modify_slot(&mut counter).1 };
        pass.kernel(Arc::new(kernel)).add();
    } else {
        let mut pass = graph.pass("indirect_args", Role::All);
        let kernel = ArgsKernel { args: pass.modify_slot(&mut args).1 };
        pass.kernel(Arc::new(kernel)).add();
        let mut pass = graph.pass("indirect_count", Role::All);
        let kernel = CountKernel { args: pass.read_slot(&args), counter: pass.modify_slot(&mut counter).1 };
        pass.kernel(Arc::new(kernel)).add();
    }
    graph.export(&args);
    graph.export(&counter);
    let schedule = compile(&graph, &BandedPlacement { devices: 1, bands: 1 }).unwrap();
    assert_eq!(schedule.validate().errors, vec![]);
    KernelPlan::from_schedule(&graph, &schedule).unwrap()
}

#[test]
fn gpu_counts_drive_the_next_dispatch_and_resets_start_every_frame_afresh() {
    const FRAMES: u32 = 6;
    let counts: Vec<u32> = (0..FRAMES).map(expected_count).collect();
    assert!(counts.windows(2).all(|w| w[0] != w[1]), "the count changes from frame to frame: {counts:?}");
    for fused in [false, true] {
        let ctx = context();
        let options = ExecOptions { read_back_exports: true, frames_in_flight: 2, ..parallax_testkit::options() };
        let plan = indirect_plan(fused);
        let name_of = |r: AllocId| plan.resource(r).name.clone();
        let mut exec = Executor::new(&ctx, plan.clone(), options).unwrap();
        let mut tickets = std::collections::VecDeque::new();
        let mut checked = 0;
        for frame in 0..FRAMES + 2 {
            // Two frames in flight: wait for the older one only once a third is due.
            if tickets.len() == 2 || frame >= FRAMES {
                let Some(ticket) = tickets.pop_front() else { break };
                let f = checked as usize;
                let readback = exec.wait_readback(ticket).unwrap();
                let n = counts[f];
                assert_eq!(name_of(readback[0].0), ARGS);
                assert_eq!(
                    words(&readback[0].1),
                    vec![n.div_ceil(64), 1, 1, n],
                    "arguments of frame {f}, fused {fused}"
                );
                assert_eq!(name_of(readback[1].0), COUNTER);
                assert_eq!(words(&readback[1].1), vec![n], "invocations below N in frame {f}, fused {fused}");
                checked += 1;
            }
            if frame < FRAMES {
                tickets.push_back(exec.submit_frame().unwrap());
            }
        }
        assert_eq!(checked, FRAMES);
        drop(exec);
        ctx.check_validation().unwrap();
    }
}

#[test]
fn indirect_arguments_that_cannot_be_read_are_refused_naming_the_resource() {
    // Resource 0: a 16-byte buffer; resource 1: an image.
    let image = ExecResource { storage: 1, ..ExecResource::image("image", FamilyId(1), 0, 4, 4, Format::R32u) };
    let plan = |kernel: MisusedKernel| {
        let args = ExecResource::buffer("args", FamilyId(0), 0, 16);
        let mut plan = KernelPlan::single_pass("misused", |_| kernel, args, 1);
        plan.resources.push(image.clone());
        plan.passes[0].writes.push(own_access(1, AllocId(1), Region::new(0, 4)));
        plan
    };
    let ctx = context();
    for (resource, offset, problem) in [
        (AllocId(0), 2, "multiple of 4"),
        (AllocId(0), 8, "do not fit the 16-byte buffer"),
        (AllocId(1), 0, "is an image"),
        (AllocId(7), 0, "not allocated"),
    ] {
        let mut exec =
            Executor::new(&ctx, plan(MisusedKernel { resource, offset }), parallax_testkit::options()).unwrap();
        match exec.run_frame() {
            Err(BackendError::IndirectArgs { shader, resource: r, offset: o, problem: p }) => {
                assert_eq!((shader.as_str(), r, o), ("test_indirect_count", resource, offset));
                assert!(p.contains(problem), "{p:?} should say {problem:?}");
            }
            other => panic!("resource {resource} offset {offset}: expected IndirectArgs, got {other:?}"),
        }
    }
    // The last 12 bytes of the buffer are a valid place.
    let mut exec =
        Executor::new(&ctx, plan(MisusedKernel { resource: AllocId(0), offset: 4 }), parallax_testkit::options())
            .unwrap();
    exec.run_frame().unwrap();
    exec.finish().unwrap();
    drop(exec);
    // Only buffers are reset.
    let mut reset_image = plan(MisusedKernel { resource: AllocId(0), offset: 4 });
    reset_image.resources[1].reset = Some(vec![]);
    let err = Executor::new(&ctx, reset_image, parallax_testkit::options()).err().unwrap();
    assert!(
        matches!(err, BackendError::ExecutionPlan(ExecutionPlanError::ResetOfImage { resource: AllocId(1) })),
        "{err}"
    );
    ctx.check_validation().unwrap();
}
