//! Executor on lavapipe (or any Vulkan device): the reprojection demo on 1, 2 and 3 logical
//! devices, with validation always on.

use parallax_backend::{
    BackendError, Context, DeviceId, EventKind, ExecOptions, Executor, FaultInjection, LinkKind, Op, chrome_trace,
};
use parallax_testkit::kernels::reference_shift_blend;
use parallax_testkit::plans::{demo_device_of_view, reprojection_demo};

const VIEWS: u32 = 3;
const SIZE: u32 = 32;

/// Validation always on; synchronisation validation where the layer copes (one device, see
/// `Validation::CoreAndSync`).
fn context(devices: usize) -> Context {
    parallax_testkit::lavapipe_context(devices)
}

fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// Runs `frames` frames of the demo on `devices` devices; returns the gathered outputs (bytes
/// per view, read on device 0) and the executor.
fn run_demo(devices: usize, frames: usize, options: ExecOptions) -> (Vec<Vec<u8>>, Executor, Context) {
    let ctx = context(devices);
    let (plan, ids) = reprojection_demo(VIEWS, devices, SIZE, SIZE);
    let mut exec = Executor::new(&ctx, plan, options).unwrap();
    for _ in 0..frames {
        exec.run_frame().unwrap();
    }
    exec.finish().unwrap();
    let outputs = ids.output.iter().map(|&r| exec.read_resource(DeviceId(0), r).unwrap()).collect();
    (outputs, exec, ctx)
}

fn reference_output(view: u32) -> Vec<f32> {
    let other = (view + 1) % VIEWS;
    (0..SIZE).flat_map(|y| (0..SIZE).flat_map(move |x| reference_shift_blend(x, y, view, other, SIZE))).collect()
}

#[test]
fn one_two_three_devices_give_bit_identical_images() {
    let (single, exec1, ctx1) = run_demo(1, 3, parallax_testkit::options());
    assert_eq!(exec1.plan().copies.len(), 0);
    ctx1.check_validation().unwrap();
    for (v, bytes) in single.iter().enumerate() {
        assert_eq!(floats(bytes), reference_output(v as u32), "view {v} vs CPU reference");
    }
    drop(exec1);
    for devices in [2, 3] {
        let (outputs, mut exec, ctx) = run_demo(devices, 3, parallax_testkit::options());
        assert_eq!(outputs, single, "{devices} devices differ from 1 device");
        // Every copy of the plan ran once per frame: one copy-out and one copy-in event each.
        let copies = exec.plan().copies.len();
        assert!(copies > 0);
        for report in exec.take_reports() {
            let outs = report.events.iter().filter(|e| e.kind == EventKind::CopyOut).count();
            let ins = report.events.iter().filter(|e| e.kind == EventKind::CopyIn).count();
            assert_eq!((outs, ins), (copies, copies), "frame {}", report.frame);
        }
        drop(exec);
        ctx.check_validation().unwrap();
    }
}

#[test]
fn dropping_a_cross_device_wait_gives_a_wrong_image() {
    let devices = 2;
    let (plan, ids) = reprojection_demo(VIEWS, devices, SIZE, SIZE);
    // The first copy-in of device 1 that nothing else on device 1 waits before.
    let copy = plan.devices[1]
        .ops
        .iter()
        .find_map(|op| match op {
            Op::CopyIn(c) => Some(*c),
            _ => None,
        })
        .unwrap();
    // Views whose blend reads the copied resource on the consumer are the ones that go wrong.
    let dropped = *plan.copy(copy);
    let expected: Vec<usize> = plan
        .passes
        .iter()
        .filter(|p| p.device == dropped.to && p.reads.iter().any(|a| a.alloc == dropped.src_alloc))
        .map(|p| p.view.index())
        .collect();
    assert!(!expected.is_empty());
    for separate_copy_queue in [false, true] {
        let ctx = context(devices);
        let options = ExecOptions {
            fault: Some(FaultInjection::DropCrossDeviceWait { copy }),
            separate_copy_queue,
            ..parallax_testkit::options()
        };
        let mut exec = Executor::new(&ctx, plan.clone(), options).unwrap();
        exec.run_frame().unwrap();
        exec.finish().unwrap();
        let wrong: Vec<usize> = (0..VIEWS)
            .filter(|&v| {
                let bytes = exec.read_resource(DeviceId(0), ids.output[v as usize]).unwrap();
                floats(&bytes) != reference_output(v)
            })
            .map(|v| v as usize)
            .collect();
        assert_eq!(wrong, expected, "exactly the views fed by the un-awaited copy are wrong");
        drop(exec);
        ctx.check_validation().unwrap();
    }
}

#[test]
fn fault_injection_refuses_a_copy_that_would_deadlock() {
    let devices = 2;
    let (plan, _) = reprojection_demo(VIEWS, devices, SIZE, SIZE);
    // Device 0 receives two copies from device 1; the second one comes after a wait.
    let later = plan.devices[0]
        .ops
        .iter()
        .filter_map(|op| match op {
            Op::CopyIn(c) => Some(*c),
            _ => None,
        })
        .nth(1)
        .unwrap();
    let ctx = context(devices);
    let options =
        ExecOptions { fault: Some(FaultInjection::DropCrossDeviceWait { copy: later }), ..parallax_testkit::options() };
    let err = Executor::new(&ctx, plan, options).err().unwrap();
    assert!(matches!(err, BackendError::FaultInjection(_)), "{err}");
}

#[test]
fn timestamps_are_ordered_and_trace_lists_every_pass() {
    let devices = 3;
    let (_, mut exec, ctx) = run_demo(devices, 2, parallax_testkit::options());
    let plan = exec.plan().clone();
    let reports = exec.take_reports();
    assert_eq!(reports.len(), 2);
    for report in &reports {
        for d in 0..devices {
            let mut events: Vec<_> = report.events.iter().filter(|e| e.device == d).collect();
            assert!(!events.is_empty(), "device {d} has no events");
            events.sort_by_key(|e| e.start_ns);
            for e in &events {
                assert!(e.start_ns > 0 && e.end_ns >= e.start_ns, "{e:?}");
            }
            // One queue per device: intervals follow each other.
            for pair in events.windows(2) {
                assert!(pair[0].end_ns <= pair[1].start_ns, "{:?} overlaps {:?}", pair[0], pair[1]);
            }
        }
        for stats in &report.devices {
            assert!(stats.busy_fraction > 0.0 && stats.busy_fraction <= 1.0 + 1e-9);
        }
        let passes = report.events.iter().filter(|e| e.kind == EventKind::Pass).count();
        assert_eq!(passes, plan.passes.len());
    }
    let trace = chrome_trace(&reports, &ctx.device_infos());
    let text = serde_json::to_string(&trace).unwrap();
    let parsed: serde_json::Value = serde_json::from_str(&text).unwrap();
    let events = parsed["traceEvents"].as_array().unwrap();
    for (i, pass) in plan.passes.iter().enumerate() {
        let listed =
            events.iter().filter(|e| e["ph"] == "X" && e["name"] == pass.name.as_str() && e["args"]["index"] == i);
        assert_eq!(listed.count(), reports.len(), "pass instance {i} ({})", pass.name);
    }
    for e in events.iter().filter(|e| e["ph"] == "X") {
        assert_eq!(e["tid"].as_u64().unwrap() as usize, demo_tid_check(&plan, e));
    }
    drop(exec);
    ctx.check_validation().unwrap();
}

/// Device an event of the demo must be on: the pass's device, or the copy's producer/consumer.
fn demo_tid_check(plan: &parallax_backend::ExecutionPlan, e: &serde_json::Value) -> usize {
    let index = e["args"]["index"].as_u64().unwrap() as usize;
    match e["cat"].as_str().unwrap() {
        "pass" => plan.passes[index].device.index(),
        "copy_out" => plan.copies[index].from.index(),
        _ => plan.copies[index].to.index(),
    }
}

#[test]
fn frames_reuse_recorded_command_buffers() {
    let devices = 2;
    let ctx = context(devices);
    let (plan, _) = reprojection_demo(VIEWS, devices, SIZE, SIZE);
    let mut exec = Executor::new(&ctx, plan.clone(), parallax_testkit::options()).unwrap();
    for _ in 0..5 {
        exec.run_frame().unwrap();
    }
    assert_eq!(exec.recordings(), 1);
    assert!(!exec.set_plan(plan).unwrap(), "same plan must not re-record");
    assert_eq!(exec.recordings(), 1);
    let (other, _) = reprojection_demo(VIEWS + 1, devices, SIZE, SIZE);
    assert!(exec.set_plan(other).unwrap());
    exec.run_frame().unwrap();
    assert_eq!(exec.recordings(), 2);
    exec.finish().unwrap();
    assert_eq!(exec.reports().len(), 6);
    drop(exec);
    ctx.check_validation().unwrap();
}

#[test]
fn demo_device_assignment_is_round_robin() {
    assert_eq!(demo_device_of_view(4, 3), DeviceId(1));
}

#[test]
fn copies_in_submissions_of_their_own_give_the_same_images() {
    // lavapipe has no transfer-only queue, so this runs the separate-copy-queue code path
    // (queue-pure segments ordered through the progress timeline) on the main queue.
    let (reference, exec, ctx) = run_demo(1, 1, parallax_testkit::options());
    drop(exec);
    ctx.check_validation().unwrap();
    for devices in [1, 2, 3] {
        let options = ExecOptions { separate_copy_queue: true, chunk_bytes: 4096, ..parallax_testkit::options() };
        let (outputs, mut exec, ctx) = run_demo(devices, 3, options);
        assert_eq!(outputs, reference, "{devices} devices");
        let reports = exec.take_reports();
        assert_eq!(reports.len(), 3);
        for r in &reports {
            let mut events: Vec<_> = r.events.iter().collect();
            events.sort_by_key(|e| (e.device, e.start_ns));
            for pair in events.windows(2).filter(|p| p[0].device == p[1].device) {
                assert!(pair[0].end_ns <= pair[1].start_ns, "{:?} overlaps {:?}", pair[0], pair[1]);
            }
        }
        drop(exec);
        ctx.check_validation().unwrap();
    }
}

/// Small copies share a submission up to `chunk_bytes` together over a `relay` link, and
/// without a cap over device memory (`shared`): fewer submissions, the same images.
#[test]
fn small_copies_over_device_memory_share_submissions_beyond_the_chunk_size() {
    let (plan, _) = reprojection_demo(VIEWS, 3, SIZE, SIZE);
    let largest = (0..plan.copies.len()).map(|c| plan.copy_bytes(parallax_backend::CopyId(c as u32))).max().unwrap();
    let run = |link| {
        let options = ExecOptions { chunk_bytes: largest, link: Some(link), ..parallax_testkit::options() };
        let (outputs, exec, ctx) = run_demo(3, 2, options);
        let submissions: usize = exec.submissions().iter().map(|s| s.submissions_per_frame).sum();
        let waits: usize = exec.submissions().iter().map(|s| s.cross_device_waits_per_frame).sum();
        drop(exec);
        ctx.check_validation().unwrap();
        (outputs, submissions, waits)
    };
    let (relayed, relay_submissions, relay_waits) = run(LinkKind::Relay);
    let (shared, shared_submissions, shared_waits) = run(LinkKind::Shared);
    assert_eq!(shared, relayed);
    assert!(
        shared_submissions < relay_submissions && shared_waits <= relay_waits,
        "shared: {shared_submissions} submissions, {shared_waits} waits; relay: {relay_submissions}, {relay_waits}"
    );
}

/// Host staging rings of one copy each (`host_staging_bytes: 1`) wrap around within every
/// frame: copy-outs wait for the space the consumer frees, and the images stay the same. Six
/// views on two devices: three copies over each link a frame.
#[test]
fn a_tiny_host_staging_ring_wraps_around_and_gives_the_same_images() {
    let views = 6;
    let run = |devices: usize, options: ExecOptions| {
        let ctx = context(devices);
        let (plan, ids) = reprojection_demo(views, devices, SIZE, SIZE);
        let mut exec = Executor::new(&ctx, plan, options).unwrap();
        for _ in 0..3 {
            exec.run_frame().unwrap();
        }
        exec.finish().unwrap();
        let outputs: Vec<Vec<u8>> = ids.output.iter().map(|&r| exec.read_resource(DeviceId(0), r).unwrap()).collect();
        let waits: usize = exec.submissions().iter().map(|s| s.cross_device_waits_per_frame).sum();
        let staging = exec.host_staging_bytes();
        drop(exec);
        ctx.check_validation().unwrap();
        (outputs, waits, staging)
    };
    let (reference, ..) = run(1, parallax_testkit::options());
    let relay = |host_staging_bytes| ExecOptions {
        link: Some(LinkKind::Relay),
        host_staging_bytes,
        ..parallax_testkit::options()
    };
    let (whole, whole_waits, whole_staging) = run(2, relay(512 << 20));
    let (tiny, tiny_waits, tiny_staging) = run(2, relay(1));
    assert!(whole == reference, "whole links: 2 devices and 1 device differ");
    assert!(tiny == reference, "tiny rings: 2 devices and 1 device differ");
    assert!(tiny_staging < whole_staging, "ring {tiny_staging} B, whole links {whole_staging} B");
    assert!(tiny_waits > whole_waits, "the wrapped ring adds space waits: {tiny_waits} against {whole_waits}");
}

/// A device lost in the middle of a frame's submission ends the run with that error, and what
/// follows is clean: no further frame is submitted, and dropping the executor does not hang on
/// the segments already queued, which wait for copies that will never be sent.
#[test]
fn a_device_lost_mid_frame_is_one_error_and_teardown_does_not_hang() {
    let started = std::time::Instant::now();
    let devices = 2;
    let ctx = context(devices);
    let (plan, _) = reprojection_demo(VIEWS, devices, SIZE, SIZE);
    let options = ExecOptions { fault: Some(FaultInjection::LoseDevice { frame: 1 }), ..parallax_testkit::options() };
    let mut exec = Executor::new(&ctx, plan, options).unwrap();
    exec.run_frame().unwrap();
    let err = exec.run_frame().unwrap_err();
    assert!(matches!(err, BackendError::DeviceLost { .. }), "{err}");
    assert!(err.to_string().contains("the GPU was lost"), "{err}");
    let again = exec.run_frame().unwrap_err();
    assert!(matches!(again, BackendError::SubmissionCutShort { frame: 1 }), "{again}");
    drop(exec);
    assert!(started.elapsed() < std::time::Duration::from_secs(30), "teardown took {:?}", started.elapsed());
}
