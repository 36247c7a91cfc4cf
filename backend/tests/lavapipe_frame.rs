//! The frame model on lavapipe, validation on: the typed frame block (its Rust layout held
//! against the GLSL one through the SPIR-V), per-pass sections of the per-frame data, camera
//! history as kernels see it, and the frame loop that reads back each frame's exported images
//! with two frames in flight and no `finish()`.

use glam::{Mat4, Vec2, Vec3};
use parallax_backend::reflect::{MemberLayout, struct_layout};
use parallax_backend::{
    BackendError, Context, ExecOptions, ExecResource, Executor, FrameBlock, FrameClock, FrameData, FrameHeader,
    GpuCamera, InstanceId, KernelGraph, KernelPlan, PassInstance, PassKernel, Recorder, ViewCameras, WriteSlot,
};
use parallax_graph::{
    AllocId, DeviceId, FamilyId, Format, PassPlacementInfo, Placement, Region, Role, ViewId, ViewTopology, compile,
};
use parallax_testkit::ids::{self, FrameBlockProbe, FrameFillParams};
use parallax_testkit::kernels::reference_mask;
use std::mem::{offset_of, size_of};
use std::sync::Arc;

const SIZE: u32 = 16;
const FILL_SECTION: &str = "fill";

fn context(devices: usize) -> Context {
    parallax_testkit::lavapipe_context(devices)
}

fn words(bytes: &[u8]) -> Vec<u32> {
    bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// (member, offset) pairs of a reflected struct.
fn offsets(layout: &[MemberLayout]) -> Vec<(&str, u32)> {
    layout.iter().map(|m| (m.name.as_str(), m.offset)).collect()
}

#[test]
fn the_frame_block_matches_its_glsl_layout() {
    let probe = parallax_testkit::shaders().spirv("test_frame_block").unwrap();
    let camera = struct_layout(&probe, "GpuCamera").unwrap();
    assert_eq!(
        offsets(&camera),
        vec![
            ("view_proj", offset_of!(GpuCamera, view_proj) as u32),
            ("inv_view_proj", offset_of!(GpuCamera, inv_view_proj) as u32),
            ("position", offset_of!(GpuCamera, position) as u32),
            ("jitter", offset_of!(GpuCamera, jitter) as u32),
            ("pad", offset_of!(GpuCamera, pad) as u32),
        ]
    );
    let views = struct_layout(&probe, "ViewCameras").unwrap();
    assert_eq!(
        offsets(&views),
        vec![
            ("current", offset_of!(ViewCameras, current) as u32),
            ("previous", offset_of!(ViewCameras, previous) as u32)
        ]
    );
    let block = struct_layout(&probe, "FrameBlock").unwrap();
    assert_eq!(
        offsets(&block),
        vec![
            ("view_count", offset_of!(FrameHeader, view_count) as u32),
            ("pad", offset_of!(FrameHeader, pad) as u32),
            ("views", size_of::<FrameHeader>() as u32),
        ]
    );
    assert_eq!(block[2].array_stride, Some(size_of::<ViewCameras>() as u32));
}

/// Camera of view `view` in frame `frame`: every frame and view different.
fn camera(frame: u32, view: u32) -> GpuCamera {
    let x = frame as f32 + 0.125 * view as f32;
    let view_proj = Mat4::from_scale(Vec3::new(1.0 + x, 1.5, 0.25)) * Mat4::from_translation(Vec3::new(-x, -1.0, -2.0));
    GpuCamera::new(view_proj, Vec3::new(x, 1.0, 2.0), Vec2::new(0.5 - 0.25 * frame as f32, 0.125 * view as f32))
}

/// Pass `frame_fill`: test_frame_fill.comp into its `out` write, with the frame block and the
/// pass's own section.
struct FrameFillKernel {
    out: WriteSlot,
}

impl PassKernel for FrameFillKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let params = FrameFillParams {
            dst: rec.image(pass.write(self.out)?.alloc)?,
            view: pass.view.0,
            width: SIZE,
            height: SIZE,
            block: rec.frame_block_address()?,
            section: rec.frame_section_address(FILL_SECTION)?,
        };
        rec.dispatch(ids::TEST_FRAME_FILL, &params, [SIZE.div_ceil(8), SIZE.div_ceil(8), 1])
    }
}

/// View `v` on device `v`.
struct ViewPerDevice;

impl Placement for ViewPerDevice {
    fn devices(&self) -> u32 {
        2
    }

    fn place(&self, _: PassPlacementInfo<'_>, view: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        vec![(DeviceId(view.0), Region::rows(height))]
    }
}

/// View 0 filled on device 0, view 1 on device 1 and gathered on device 0; both exported.
fn gather_plan() -> KernelPlan {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(2, SIZE, SIZE));
    let mut fill = graph.image("fill", Format::R32u);
    let mut pass = graph.pass("frame_fill", Role::All);
    let kernel = FrameFillKernel { out: pass.write_slot(&mut fill) };
    pass.kernel(Arc::new(kernel)).add();
    graph.export(&fill);
    let schedule = compile(&graph, &ViewPerDevice).unwrap();
    KernelPlan::from_schedule(&graph, &schedule).unwrap()
}

/// This frame's data: the frame block, then the fill pass's salt.
fn frame_data(block: &FrameBlock, salt: u32) -> FrameData {
    let mut data = FrameData::new();
    data.frame_block(block).unwrap();
    data.section(FILL_SECTION, &salt.to_le_bytes()).unwrap();
    data
}

fn salt_of(frame: u32) -> u32 {
    0x9e37_79b9u32.wrapping_mul(frame + 1)
}

#[test]
fn the_frame_loop_reads_back_every_frames_exports_with_two_frames_in_flight() {
    const FRAMES: u32 = 5;
    let ctx = context(2);
    let options = ExecOptions { read_back_exports: true, frames_in_flight: 2, ..parallax_testkit::options() };
    let plan = gather_plan();
    let view_of = |r: AllocId| plan.resource(r).view;
    let mut exec = Executor::new(&ctx, plan.clone(), options).unwrap();
    let mut clock = FrameClock::new();
    let expected = |frame: u32, view: u32| -> Vec<u32> {
        (0..SIZE)
            .flat_map(|y| (0..SIZE).map(move |x| reference_mask(x, y, 8 * frame + view) ^ salt_of(frame)))
            .collect()
    };
    let mut pending = std::collections::VecDeque::new();
    for frame in 0..FRAMES {
        if pending.len() == 2 {
            let (f, ticket) = pending.pop_front().unwrap();
            let readback = exec.wait_readback(ticket).unwrap();
            assert_eq!(readback.iter().map(|(r, _)| view_of(*r)).collect::<Vec<_>>(), vec![0, 1]);
            for (r, bytes) in &readback {
                let view = view_of(*r);
                assert_eq!(words(bytes), expected(f, view), "frame {f}, view {view}");
            }
            // Only the frame asked for (and none after it) has retired.
            assert_eq!(exec.reports().last().map(|r| r.frame), Some(u64::from(f)));
        }
        let block = clock.advance(&[camera(frame, 0), camera(frame, 1)]);
        exec.set_frame(&frame_data(&block, salt_of(frame))).unwrap();
        let ticket = exec.submit_frame().unwrap();
        assert_eq!(ticket.frame(), u64::from(frame));
        pending.push_back((frame, ticket));
        if frame == 1 {
            assert!(exec.reports().is_empty(), "frames 0 and 1 are both in flight");
        }
    }
    for (f, ticket) in pending {
        for (r, bytes) in exec.wait_readback(ticket).unwrap() {
            let view = view_of(r);
            assert_eq!(words(&bytes), expected(f, view), "frame {f}, view {view}");
        }
    }
    assert_eq!(exec.recordings(), 1, "the same sections every frame: recorded once");
    // Another layout is recorded again; a missing section is an error naming it.
    let mut only_block = FrameData::new();
    only_block.frame_block(&clock.advance(&[camera(9, 0), camera(9, 1)])).unwrap();
    exec.set_frame(&only_block).unwrap();
    match exec.submit_frame() {
        Err(BackendError::UnknownFrameSection { name, known }) => {
            assert_eq!((name.as_str(), known), (FILL_SECTION, Vec::<String>::new()));
        }
        other => panic!("expected UnknownFrameSection, got {other:?}"),
    }
    drop(exec);
    // The frame loop is asked for, not implied.
    let mut plain = Executor::new(&ctx, gather_plan(), parallax_testkit::options()).unwrap();
    assert!(matches!(plain.submit_frame(), Err(BackendError::ReadbackDisabled)));
    drop(plain);
    ctx.check_validation().unwrap();
}

/// Pass `frame_probe`: test_frame_block.comp writes the frame block into its `out` write.
struct FrameProbeKernel {
    views: u32,
    out: WriteSlot,
}

impl PassKernel for FrameProbeKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let push = FrameBlockProbe {
            block: rec.frame_block_address()?,
            target: rec.buffer_of(pass.write(self.out)?.alloc)?,
            max_views: self.views,
            pad: 0,
        };
        rec.dispatch(ids::TEST_FRAME_BLOCK, &push, [1, 1, 1])
    }
}

/// The words test_frame_block.comp writes for one camera.
fn camera_words(c: &GpuCamera) -> Vec<u32> {
    let floats = c.view_proj.iter().chain(&c.inv_view_proj).flatten().chain(&c.position).chain(&c.jitter);
    floats.map(|f| f.to_bits()).collect()
}

#[test]
fn kernels_see_last_frames_camera_as_previous_and_no_history_after_a_cut() {
    const VIEWS: u32 = 2;
    const FRAMES: u32 = 6;
    const CUT: u32 = 3;
    let camera_words_per_view = 2 * 38;
    let bytes = 4 * (3 + camera_words_per_view * VIEWS as u64);
    let mut probe = ExecResource::buffer("frame block copy", FamilyId(0), 0, bytes);
    probe.exported = true;
    let plan = KernelPlan::single_pass("frame_probe", |out| FrameProbeKernel { views: VIEWS, out }, probe, 1);
    let ctx = context(1);
    let options = ExecOptions { read_back_exports: true, frames_in_flight: 2, ..parallax_testkit::options() };
    let mut exec = Executor::new(&ctx, plan.clone(), options.clone()).unwrap();
    let mut clock = FrameClock::new();
    let mut tickets = Vec::new();
    for frame in 0..FRAMES {
        if frame == CUT {
            exec.reset_history();
        }
        let cameras: Vec<GpuCamera> = (0..VIEWS).map(|v| camera(frame, v)).collect();
        let mut data = FrameData::new();
        data.frame_block(&clock.advance(&cameras)).unwrap();
        exec.set_frame(&data).unwrap();
        tickets.push(exec.submit_frame().unwrap());
    }
    for (frame, ticket) in (0..FRAMES).zip(tickets) {
        let readback = exec.wait_readback(ticket).unwrap();
        let got = words(&readback[0].1);
        let history = frame != 0 && frame != CUT;
        assert_eq!(got[..3], [frame, u32::from(history), VIEWS], "frame constants and view count of frame {frame}");
        for view in 0..VIEWS {
            let at = 3 + (view * 76) as usize;
            // The clock keeps last frame's camera over a cut; the executor's flag says not to use it.
            let previous_frame = frame.saturating_sub(1);
            assert_eq!(got[at..at + 38], camera_words(&camera(frame, view)), "current, frame {frame} view {view}");
            assert_eq!(
                got[at + 38..at + 76],
                camera_words(&camera(previous_frame, view)),
                "previous, frame {frame} view {view}"
            );
        }
    }
    assert!(exec.recordings() == 1);
    drop(exec);
    // A frame whose data has no block is refused when recorded, naming the pass that reads it.
    let mut without_block = Executor::new(&ctx, plan, options).unwrap();
    without_block.set_frame(&FrameData::whole(&[0; 16])).unwrap();
    match without_block.run_frame() {
        Err(BackendError::NoFrameBlock { pass }) => assert_eq!(pass, "frame_probe"),
        other => panic!("expected NoFrameBlock, got {other:?}"),
    }
    drop(without_block);
    ctx.check_validation().unwrap();
}
