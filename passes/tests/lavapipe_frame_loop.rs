//! The frame loop of [`LightFieldRenderer`] on lavapipe: the command buffers are recorded once
//! and resubmitted while the plan is unchanged, frames kept in flight give the same bits as
//! frames run one at a time, and the running statistics count every frame without keeping its
//! report.

mod common;

use glam::Vec3;
use parallax_backend::ExecOptions;
use parallax_graph::{LayoutSpec, LightField};
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_scene::{Camera, Scene, SceneBvh, TraceSettings, default_scene};

const SIZE: u32 = 24;

/// The light field of frame `f`: the default camera dollied sideways a little every frame, so
/// every frame's data differs and history (SVGF) carries each frame into the next.
fn light_field(scene: &Scene, f: u32) -> LightField {
    let base = scene.default_camera();
    let (right, _, _) = base.basis();
    let camera = Camera { eye: base.eye + right * (0.01 * f as f32 * scene.bounds().diagonal()), ..base };
    let rig = rig_of(&camera, scene.bounds().center(), None);
    LightField::new(LayoutSpec::Grid { cols: 3, rows: 1 }, Some(0.02), Some((SIZE, SIZE)), rig).unwrap()
}

/// Submits `frames` frames without waiting in between (the executor waits only for slots),
/// then reads every view's denoised radiance and display image; checks there was one recording.
fn render(frames_in_flight: usize, frames: u32) -> Vec<(Vec<u8>, Vec<u8>)> {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let lf = light_field(&scene, 0);
    let options = ExecOptions { frames_in_flight, ..ExecOptions::default() };
    let (mut renderer, handles) = common::reprojection_renderer(&common::context(1), &scene, &bvh, &lf, options);
    let (denoised, display) = (handles.denoised.expect("the pipeline denoises").family(), handles.display.family());
    let settings = TraceSettings { spp: 1, max_depth: 3, ..Default::default() };
    for f in 0..frames {
        let views = lightfield_views(&light_field(&scene, f));
        renderer.submit(&scene, &views, &TraceSettings { frame: f, ..settings }).unwrap();
    }
    renderer.finish().unwrap();
    assert_eq!(renderer.stats().frames(), u64::from(frames), "every retired frame is folded");
    let out = (0..lf.len() as u32)
        .map(|v| (renderer.read(denoised, v).unwrap(), renderer.read(display, v).unwrap()))
        .collect();
    assert_eq!(renderer.executor().recordings(), 1, "{frames_in_flight} in flight: recorded once");
    renderer.executor().check_validation().unwrap();
    out
}

#[test]
fn frames_in_flight_give_the_same_bits_as_one_frame_at_a_time() {
    let one = render(1, 6);
    let three = render(3, 6);
    assert!(one == three, "1 and 3 frames in flight differ after 6 frames of a moving camera");
    // The frames differ from each other, so a frame reading another slot's data would show.
    let five_frames = render(3, 5);
    assert!(five_frames != three, "the last frame depends on the frame count");
}

#[test]
fn command_buffers_are_recorded_once_while_the_plan_is_unchanged() {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let lf = light_field(&scene, 0);
    let (mut renderer, _) = common::reprojection_renderer(
        &common::context(1),
        &scene,
        &bvh,
        &lf,
        ExecOptions { frames_in_flight: 2, ..ExecOptions::default() },
    );
    let settings = TraceSettings { spp: 1, max_depth: 2, ..Default::default() };
    let mut moved = scene.clone();
    moved.sun = Some(parallax_scene::Sun {
        to_sun: Vec3::new(0.2, 1.0, 0.1),
        irradiance: Vec3::splat(2.0),
        angular_radius: 0.0,
    });
    for f in 0..8u32 {
        if f == 4 {
            renderer.cut();
        }
        // Camera, frame index, cut and sun change; the plan does not.
        let lit = if f >= 6 { &moved } else { &scene };
        let views = lightfield_views(&light_field(&scene, f));
        renderer.submit(lit, &views, &TraceSettings { frame: f, ..settings }).unwrap();
        assert_eq!(renderer.executor().recordings(), 1, "frame {f} re-recorded");
    }
    renderer.finish().unwrap();
    assert_eq!(renderer.executor().recordings(), 1);
    let stats = renderer.stats();
    assert_eq!(stats.frames(), 8);
    assert_eq!(stats.gpu_span_ms().count(), 8);
    // Every pass of the pipeline was timed on every frame.
    let gbuffer = stats.event_totals().into_iter().find(|t| t.name == "gbuffer").expect("gbuffer timed");
    assert_eq!(gbuffer.count, 8 * lf.len() as u64);
    // Reports are folded, not kept, unless asked for.
    assert!(renderer.take_reports().is_empty());
    renderer.keep_reports(true);
    let views = lightfield_views(&light_field(&scene, 8));
    renderer.submit(&scene, &views, &TraceSettings { frame: 8, ..settings }).unwrap();
    renderer.finish().unwrap();
    assert_eq!(renderer.take_reports().len(), 1);
    renderer.reset_stats();
    assert_eq!(renderer.stats().frames(), 0);
    renderer.executor().check_validation().unwrap();
}
