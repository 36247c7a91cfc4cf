//! Data-dependent work on lavapipe, validation (with synchronisation validation) on: a pass
//! computes a count on the GPU and writes indirect-dispatch arguments, the next dispatch runs on
//! them, and the buffers the plan resets start every frame from their header. Frames are read
//! back through the frame loop with two in flight, so a reset that did not happen, or happened
//! in the wrong frame, shows up as a wrong count.

use parallax_backend::kernels::reference_mask;
use parallax_backend::{
    BackendError, Context, ContextDesc, DeviceSelection, ExecOptions, Executor, KernelRegistry, PassKernel, Plan,
    PlanAccess, PlanError, PlanOp, PlanPass, PlanResource, Recorder, ResourceKind, Rows, TexelFormat, Validation,
};

const SALT: u32 = 0x5eed;
/// groups_x, groups_y, groups_z, count: what test_indirect_args.comp starts from each frame.
const ARGS_HEADER: [u32; 4] = [0, 1, 1, 0];
const ARGS: usize = 0;
const COUNTER: usize = 1;

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

fn push(address: u64, word: &[u8]) -> Vec<u8> {
    [address.to_le_bytes().as_slice(), word].concat()
}

/// Records the arguments pass (one workgroup) into `writes[0]`.
fn record_args(rec: &mut Recorder<'_>, pass: &PlanPass) -> parallax_backend::Result<()> {
    let args = rec.buffer_of(pass.writes[0].resource)?;
    rec.dispatch_bytes("test_indirect_args", &push(args, &SALT.to_le_bytes()), [1, 1, 1])
}

/// Records the indirect dispatch on the arguments `args` into the counter `counter`.
fn record_count(rec: &mut Recorder<'_>, args: usize, counter: usize) -> parallax_backend::Result<()> {
    let push = push(rec.buffer_of(args)?, &rec.buffer_of(counter)?.to_le_bytes());
    rec.dispatch_indirect("test_indirect_count", &push, args, 0)
}

/// Pass `indirect_args`: writes the arguments.
struct ArgsKernel;

impl PassKernel for ArgsKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PlanPass, _: usize) -> parallax_backend::Result<()> {
        record_args(rec, pass)
    }
}

/// Pass `indirect_count`: reads the arguments, writes the counter.
struct CountKernel;

impl PassKernel for CountKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PlanPass, _: usize) -> parallax_backend::Result<()> {
        record_count(rec, pass.reads[0].resource, pass.writes[0].resource)
    }
}

/// Pass `indirect_fused`: both in one pass, so only the barrier of `dispatch_indirect` itself
/// orders the arguments before their use. (Lavapipe runs dispatches in order, and
/// synchronisation validation cannot see accesses through buffer addresses, so this shows the
/// one-pass form works; it cannot show the barrier is needed.)
struct FusedKernel;

impl PassKernel for FusedKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PlanPass, _: usize) -> parallax_backend::Result<()> {
        record_args(rec, pass)?;
        record_count(rec, pass.writes[0].resource, pass.writes[1].resource)
    }
}

/// A pass that dispatches indirectly from `resource` at `offset`, whatever they are.
struct MisusedKernel {
    resource: usize,
    offset: u64,
}

impl PassKernel for MisusedKernel {
    fn record(&self, rec: &mut Recorder<'_>, _: &PlanPass, _: usize) -> parallax_backend::Result<()> {
        rec.dispatch_indirect("test_indirect_count", &[0; 16], self.resource, self.offset)
    }
}

fn kernels() -> KernelRegistry {
    KernelRegistry::new()
        .with("indirect_args", ArgsKernel)
        .with("indirect_count", CountKernel)
        .with("indirect_fused", FusedKernel)
}

/// Arguments and counter (both reset every frame and exported), written by `fused` as one pass
/// or by two.
fn indirect_plan(fused: bool) -> Plan {
    let mut args = PlanResource::buffer("indirect args", 0, 16);
    args.reset = Some(ARGS_HEADER.to_vec());
    let mut counter = PlanResource::buffer("counter", 0, 4);
    counter.reset = Some(vec![]);
    let access = |resource| PlanAccess { resource, version: 1, rows: Rows::new(0, 1) };
    let pass = |name: &str, reads, writes| PlanPass {
        name: name.into(),
        view: 0,
        rows: Rows::new(0, 1),
        device: 0,
        reads,
        writes,
        history_reads: vec![],
    };
    let passes = if fused {
        vec![pass("indirect_fused", vec![], vec![access(ARGS), access(COUNTER)])]
    } else {
        vec![
            pass("indirect_args", vec![], vec![access(ARGS)]),
            pass("indirect_count", vec![access(ARGS)], vec![access(COUNTER)]),
        ]
    };
    Plan {
        resources: [args, counter].map(|r| PlanResource { exported: true, ..r }).to_vec(),
        devices: vec![(0..passes.len()).map(PlanOp::Pass).collect()],
        passes,
        copies: vec![],
    }
}

#[test]
fn gpu_counts_drive_the_next_dispatch_and_resets_start_every_frame_afresh() {
    const FRAMES: u32 = 6;
    let counts: Vec<u32> = (0..FRAMES).map(expected_count).collect();
    assert!(counts.windows(2).all(|w| w[0] != w[1]), "the count changes from frame to frame: {counts:?}");
    for fused in [false, true] {
        let ctx = context();
        let options = ExecOptions { read_back_exports: true, frames_in_flight: 2, ..ExecOptions::default() };
        let mut exec = Executor::new(&ctx, indirect_plan(fused), kernels(), options).unwrap();
        let mut tickets = std::collections::VecDeque::new();
        let mut checked = 0;
        for frame in 0..FRAMES + 2 {
            // Two frames in flight: wait for the older one only once a third is due.
            if tickets.len() == 2 || frame >= FRAMES {
                let Some(ticket) = tickets.pop_front() else { break };
                let f = checked as usize;
                let readback = exec.wait_readback(ticket).unwrap();
                let n = counts[f];
                assert_eq!(readback[0].0, ARGS);
                assert_eq!(
                    words(&readback[0].1),
                    vec![n.div_ceil(64), 1, 1, n],
                    "arguments of frame {f}, fused {fused}"
                );
                assert_eq!(readback[1].0, COUNTER);
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
    let image = PlanResource {
        name: "image".into(),
        view: 0,
        width: 4,
        height: 4,
        format: TexelFormat::R32Uint,
        kind: ResourceKind::Image,
        exported: false,
        reset: None,
    };
    let mut plan = Plan::single_pass("misused", PlanResource::buffer("args", 0, 16), 1);
    plan.resources.push(image);
    plan.passes[0].writes.push(PlanAccess { resource: 1, version: 1, rows: Rows::new(0, 4) });
    let ctx = context();
    for (resource, offset, problem) in [
        (0, 2, "multiple of 4"),
        (0, 8, "do not fit the 16-byte buffer"),
        (1, 0, "is an image"),
        (7, 0, "not allocated"),
    ] {
        let kernels = KernelRegistry::new().with("misused", MisusedKernel { resource, offset });
        let mut exec = Executor::new(&ctx, plan.clone(), kernels, ExecOptions::default()).unwrap();
        match exec.run_frame() {
            Err(BackendError::IndirectArgs { shader, resource: r, offset: o, problem: p }) => {
                assert_eq!((shader.as_str(), r, o), ("test_indirect_count", resource, offset));
                assert!(p.contains(problem), "{p:?} should say {problem:?}");
            }
            other => panic!("resource {resource} offset {offset}: expected IndirectArgs, got {other:?}"),
        }
    }
    // The last 12 bytes of the buffer are a valid place.
    let kernels = KernelRegistry::new().with("misused", MisusedKernel { resource: 0, offset: 4 });
    let mut exec = Executor::new(&ctx, plan.clone(), kernels, ExecOptions::default()).unwrap();
    exec.run_frame().unwrap();
    exec.finish().unwrap();
    drop(exec);
    // Only buffers are reset.
    plan.resources[1].reset = Some(vec![]);
    let err = Executor::new(&ctx, plan, KernelRegistry::new(), ExecOptions::default()).err().unwrap();
    assert!(matches!(err, BackendError::Plan(PlanError::ResetOfImage { resource: 1 })), "{err}");
    ctx.check_validation().unwrap();
}
