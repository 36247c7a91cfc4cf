//! The whole reconstruction pipeline (G-buffer, path tracing of sources, reprojection, hole
//! filling, SVGF, tonemap) on lavapipe with validation on, over several frames: every scheme
//! gives the same bits on one and on three devices; a camera cut leaves no trace of the frames
//! before it; thin geometry and a camera inside geometry run; nothing non-finite comes out.

mod common;

use glam::Vec3;
use parallax_backend::{Barriers, EventKind, ExecOptions, FrameReport, KernelGraph, KernelPlan, LinkKind, Timing};
use parallax_graph::{
    AssignStrategy, DeviceId, FamilyId, LayoutSpec, LightField, Partition, PartitionConfig, PassPlacementInfo,
    Placement, Region, Scheme, ViewId, compile,
};
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_passes::firefly::FireflyMode;
use parallax_passes::hole_subsample::HoleFillMode;
use parallax_passes::pipeline::{
    Denoiser, GbufferSource, PipelineConfig, PipelineHandles, PipelineKind, declare_pipeline,
};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{Camera, Scene, SceneBvh, TraceSettings, default_scene};

const SIZE: u32 = 32;
const FRAMES: u32 = 3;

/// A plan's placement with every instance moved to device 0: the same sources, sets and bands,
/// one device.
struct OnOneDevice<'p>(&'p Partition);

impl Placement for OnOneDevice<'_> {
    fn devices(&self) -> u32 {
        1
    }

    fn place(&self, pass: PassPlacementInfo<'_>, view: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        self.0.place(pass, view, height).into_iter().map(|(_, rows)| (DeviceId(0), rows)).collect()
    }
}

fn light_field(scene: &Scene, camera: Camera, spacing: f64) -> LightField {
    let rig = rig_of(&camera, scene.bounds().center(), None);
    LightField::new(LayoutSpec::Grid { cols: 4, rows: 2 }, Some(spacing), Some((SIZE, SIZE)), rig).unwrap()
}

/// Per frame, per view: (denoised linear radiance, display bytes).
type Frames = Vec<Vec<(Vec<u8>, Vec<u8>)>>;

/// Renders `frames` frames of `lf` planned by `plan` and placed by `placement`; `cut_at` cuts
/// the camera before that frame, whose views come from `after_cut`.
fn run(
    scene: &Scene,
    lf: &LightField,
    plan: &Partition,
    placement: &dyn Placement,
    frames: std::ops::Range<u32>,
    cut: Option<(u32, &LightField)>,
) -> Frames {
    run_with(scene, lf, plan, placement, frames, cut, ExecOptions::default()).0
}

fn run_with(
    scene: &Scene,
    lf: &LightField,
    plan: &Partition,
    placement: &dyn Placement,
    frames: std::ops::Range<u32>,
    cut: Option<(u32, &LightField)>,
    options: ExecOptions,
) -> (Frames, Vec<FrameReport>) {
    let config = common::denoising_pipeline(PipelineKind::Reproject);
    run_config(scene, lf, plan, placement, frames, cut, options, &config)
}

/// [`run_with`] of the pipeline `config` declares.
#[allow(clippy::too_many_arguments)]
fn run_config(
    scene: &Scene,
    lf: &LightField,
    plan: &Partition,
    placement: &dyn Placement,
    frames: std::ops::Range<u32>,
    cut: Option<(u32, &LightField)>,
    options: ExecOptions,
    config: &PipelineConfig,
) -> (Frames, Vec<FrameReport>) {
    let read = |h: &PipelineHandles, _source: bool| {
        vec![h.denoised.as_ref().expect("the pipeline denoises").family(), h.display.family()]
    };
    let (layers, reports) = run_layers(scene, lf, plan, placement, frames, cut, options, config, &read);
    let frames = layers.into_iter().map(|views| views.into_iter().map(|mut l| (l.remove(0), l.remove(0))).collect());
    (frames.collect(), reports)
}

/// Per frame, per view, the layers `read` names for it, in its order.
type Layers = Vec<Vec<Vec<Vec<u8>>>>;

/// Renders the pipeline `config` declares and reads back, every view of every frame, the layers
/// `read` picks from its handles for a source (`true`) or a target view.
#[allow(clippy::too_many_arguments)]
fn run_layers(
    scene: &Scene,
    lf: &LightField,
    plan: &Partition,
    placement: &dyn Placement,
    frames: std::ops::Range<u32>,
    cut: Option<(u32, &LightField)>,
    options: ExecOptions,
    config: &PipelineConfig,
    read: &dyn Fn(&PipelineHandles, bool) -> Vec<FamilyId>,
) -> (Layers, Vec<FrameReport>) {
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    let handles = declare_pipeline(&mut graph, config).unwrap();
    graph.export(&handles.display);
    let families = [read(&handles, false), read(&handles, true)];
    let schedule = compile(&graph, placement).unwrap();
    let exec = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let ctx = common::context(placement.devices() as usize);
    let bvh = SceneBvh::build(scene);
    let mut renderer = LightFieldRenderer::with_options(&ctx, exec, &GpuScene::new(scene, &bvh), options).unwrap();
    renderer.keep_reports(true);
    let settings = TraceSettings { spp: 1, max_depth: 3, ..Default::default() };
    let mut out = Vec::new();
    for f in frames {
        let mut views = lightfield_views(lf);
        if let Some((at, after)) = cut
            && f >= at
        {
            if f == at {
                renderer.cut();
            }
            views = lightfield_views(after);
        }
        renderer.submit(scene, &views, &TraceSettings { frame: f, ..settings }).unwrap();
        renderer.finish().unwrap();
        out.push(
            (0..lf.len() as u32)
                .map(|v| {
                    let of_view = &families[usize::from(plan.topology.is_source[v as usize])];
                    of_view.iter().map(|&family| renderer.read(family, v).unwrap()).collect()
                })
                .collect(),
        );
    }
    let reports = renderer.take_reports();
    drop(renderer);
    ctx.check_validation().unwrap();
    (out, reports)
}

fn finite(frames: &Frames) -> bool {
    frames.iter().flatten().all(|(linear, _)| {
        linear.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).all(f32::is_finite)
    })
}

/// `devices` devices under `scheme`, compact assignment: explicit sources 1 and 6 for the fine
/// schemes (so a run and its one-device twin reproject from the same views), the planner's for
/// multi-source.
fn compact_plan(lf: &LightField, devices: u32, scheme: Scheme) -> Partition {
    let sources = (scheme != Scheme::MultiSource).then(|| vec![1, 6]);
    Partition::new(lf, &PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources }).unwrap()
}

/// Every scheme on three devices gives the bits of the same plan on one device, for the
/// pipeline `config` declares (`what` names it in the failure).
fn assert_every_scheme_gives_the_same_bits_on_one_and_three_devices(config: &PipelineConfig, what: &str) {
    let scene = default_scene();
    let lf = light_field(&scene, scene.default_camera(), 0.02);
    for scheme in Scheme::ALL {
        let plan = compact_plan(&lf, 3, scheme);
        let options = ExecOptions::default;
        let (three, _) = run_config(&scene, &lf, &plan, &plan, 0..FRAMES, None, options(), config);
        let (one, _) = run_config(&scene, &lf, &plan, &OnOneDevice(&plan), 0..FRAMES, None, options(), config);
        assert!(finite(&three), "{scheme:?}, {what}: finite");
        assert!(three == one, "{scheme:?}, {what}: 3 devices and 1 device differ");
    }
}

#[test]
fn every_scheme_gives_the_same_bits_on_one_and_three_devices() {
    let config = common::denoising_pipeline(PipelineKind::Reproject);
    assert_every_scheme_gives_the_same_bits_on_one_and_three_devices(&config, "SVGF over every view");
}

#[test]
fn every_scheme_gives_the_same_bits_on_one_and_three_devices_with_the_visibility_gbuffer() {
    let config =
        PipelineConfig { gbuffer: GbufferSource::Visibility, ..common::denoising_pipeline(PipelineKind::Reproject) };
    assert_every_scheme_gives_the_same_bits_on_one_and_three_devices(&config, "the visibility G-buffer");
}

#[test]
fn every_scheme_gives_the_same_bits_on_one_and_three_devices_denoising_the_samples() {
    let config = PipelineConfig { denoise: Denoiser::Samples, ..common::denoising_pipeline(PipelineKind::Reproject) };
    assert_every_scheme_gives_the_same_bits_on_one_and_three_devices(&config, "SVGF over the samples");
}

#[test]
fn every_scheme_gives_the_same_bits_on_one_and_three_devices_subsampling_the_holes() {
    for denoise in [Denoiser::Views, Denoiser::Samples] {
        let config = PipelineConfig {
            denoise,
            hole_fill: HoleFillMode::Subsampled,
            ..common::denoising_pipeline(PipelineKind::Reproject)
        };
        assert_every_scheme_gives_the_same_bits_on_one_and_three_devices(&config, &format!("subsampled, {denoise:?}"));
    }
}

#[test]
fn fine_schemes_give_the_same_bits_on_one_and_three_devices_over_each_lavapipe_link_kind() {
    // Lavapipe offers `shared` (opaque-fd memory, relayed signals) and `relay` (host staging);
    // `gpu` needs VK_KHR_external_semaphore_fd, which it lacks (refused: backend links.rs).
    let scene = default_scene();
    let lf = light_field(&scene, scene.default_camera(), 0.02);
    for scheme in [Scheme::FineAll, Scheme::FineSources] {
        let plan = compact_plan(&lf, 3, scheme);
        let one = run(&scene, &lf, &plan, &OnOneDevice(&plan), 0..FRAMES, None);
        // The last: host staging rings of one copy each, which wrap around within every frame.
        for (kind, host_staging_bytes) in
            [(LinkKind::Shared, 512 << 20), (LinkKind::Relay, 512 << 20), (LinkKind::Relay, 1)]
        {
            let options = ExecOptions { link: Some(kind), host_staging_bytes, ..ExecOptions::default() };
            let (three, _) = run_with(&scene, &lf, &plan, &plan, 0..FRAMES, None, options);
            assert!(
                three == one,
                "{scheme:?} over {kind:?} links ({host_staging_bytes} B host staging): 3 devices and 1 device differ"
            );
        }
    }
}

#[test]
fn the_frame_after_a_camera_cut_equals_a_fresh_start() {
    let scene = default_scene();
    let before = light_field(&scene, scene.default_camera(), 0.02);
    let mut moved = scene.default_camera();
    moved.eye += Vec3::new(0.4, 0.1, -0.3);
    let after = light_field(&scene, moved, 0.02);
    let plan = compact_plan(&before, 1, Scheme::MultiSource);
    for denoise in [Denoiser::Views, Denoiser::Samples] {
        let pipeline = PipelineConfig { denoise, ..common::denoising_pipeline(PipelineKind::Reproject) };
        let run = |lf: &LightField, frames: std::ops::Range<u32>, cut: Option<(u32, &LightField)>| {
            run_config(&scene, lf, &plan, &plan, frames, cut, ExecOptions::default(), &pipeline).0
        };
        let cut = run(&before, 0..4, Some((3, &after)));
        let fresh = run(&after, 3..4, None);
        assert!(cut[3] == fresh[0], "{denoise:?}: no ghost of the frames before the cut");
        // Without the cut, history would have been blended in (so the test can fail).
        let uncut = run(&before, 0..4, None);
        assert!(uncut[3] != cut[3], "{denoise:?}");
    }
}

#[test]
fn denoising_the_samples_makes_each_hole_pixel_the_mean_of_its_samples_on_a_still_camera() {
    // Under `Samples` a target's hole pixels are traced into its `denoised` image and
    // accumulated there (hole_temporal); without a denoiser the same pixels get the same traced
    // samples (one RNG stream per pixel and frame) and keep them as they are. So on a still
    // camera a hole pixel of frame n must be the mean of the undenoised run's frames 0..=n.
    let scene = default_scene();
    let lf = light_field(&scene, scene.default_camera(), 0.02);
    let plan = compact_plan(&lf, 1, Scheme::MultiSource);
    let base = common::denoising_pipeline(PipelineKind::Reproject);
    let samples = PipelineConfig { denoise: Denoiser::Samples, ..base };
    let none = PipelineConfig { denoise: Denoiser::None, fireflies: FireflyMode::Keep, ..base };
    let frames = 0..4;
    // Hole masks exist for targets only.
    let with_holes = |image: FamilyId, h: &PipelineHandles, source: bool| {
        if source { vec![image] } else { vec![image, h.holes.as_ref().unwrap().family()] }
    };
    let read_samples = |h: &PipelineHandles, source: bool| with_holes(h.denoised.as_ref().unwrap().family(), h, source);
    let read_none = |h: &PipelineHandles, source: bool| with_holes(h.radiance.family(), h, source);
    let (accumulated, _) =
        run_layers(&scene, &lf, &plan, &plan, frames.clone(), None, ExecOptions::default(), &samples, &read_samples);
    let (traced, _) = run_layers(&scene, &lf, &plan, &plan, frames, None, ExecOptions::default(), &none, &read_none);
    let (mut holes, mut worst) = (0usize, 0.0f64);
    for view in 0..lf.len() {
        if plan.topology.is_source[view] {
            continue;
        }
        let mask = &accumulated[0][view][1];
        assert_eq!(mask, &traced[0][view][1], "view {view}: both runs find the same holes");
        let is_hole: Vec<bool> =
            mask.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) != 0).collect();
        for (n, frame) in accumulated.iter().enumerate() {
            let got = common::floats(&frame[view][0]);
            let samples: Vec<Vec<f32>> = traced[..=n].iter().map(|f| common::floats(&f[view][0])).collect();
            for (pixel, _) in is_hole.iter().enumerate().filter(|(_, hole)| **hole) {
                holes += usize::from(n == 0);
                for c in 0..3 {
                    let i = pixel * 4 + c;
                    let mean = samples.iter().map(|s| f64::from(s[i].clamp(0.0, 1e8))).sum::<f64>() / (n + 1) as f64;
                    worst = worst.max((f64::from(got[i]) - mean).abs() / mean.abs().max(1e-3));
                }
            }
        }
    }
    eprintln!("{holes} hole pixels; worst relative distance from the mean of their samples {worst:.2e}");
    assert!(holes > 0, "the light field has holes, so the test can fail");
    assert!(worst <= 1e-5, "a hole pixel is {worst:.2e} (relative) off the mean of its samples");
}

/// A scene of very thin geometry: a comb of 1 mm slabs in front of a wall, under a sun and sky.
fn thin_scene() -> Scene {
    let mut b = parallax_scene::SceneBuilder::new("thin");
    let white = b.material(parallax_scene::Material::diffuse("white", Vec3::splat(0.8)));
    b.quad(Vec3::new(-2.0, -1.0, -1.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 3.0, 0.0), white);
    for i in 0..20 {
        let x = -1.0 + 0.1 * i as f32;
        b.quad(Vec3::new(x, -1.0, 0.0), Vec3::new(0.001, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), white);
    }
    // A closed box far to the side, for the camera-inside-geometry case.
    b.cuboid(Vec3::new(10.0, 0.0, 0.0), Vec3::splat(0.5), 0.0, white);
    let mut scene = b.build();
    scene.sun = Some(parallax_scene::Sun {
        to_sun: Vec3::new(0.3, 1.0, 0.5),
        irradiance: Vec3::splat(3.0),
        angular_radius: 0.0,
    });
    scene.sky = Some(parallax_scene::Sky::Constant(Vec3::splat(0.3)));
    scene
}

#[test]
fn thin_geometry_and_a_camera_inside_geometry_render_finite_images() {
    let thin = thin_scene();
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 0.9);
    let lf = light_field(&thin, camera, 0.01);
    let config =
        PartitionConfig { devices: 2, scheme: Scheme::FineAll, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::new(&lf, &config).unwrap();
    assert!(finite(&run(&thin, &lf, &plan, &plan, 0..2, None)));

    // Inside the closed box: every ray hits its inside faces, lit by nothing but what leaks
    // through no gap (so black, but finite).
    let inside = Camera::look_at(Vec3::new(10.0, 0.0, 0.0), Vec3::new(11.0, 0.0, 0.0), Vec3::Y, 1.0);
    let lf = light_field(&thin, inside, 0.001);
    let plan = Partition::new(&lf, &PartitionConfig { scheme: Scheme::MultiSource, ..config }).unwrap();
    assert!(finite(&run(&thin, &lf, &plan, &plan, 0..2, None)));
}

#[test]
fn barriers_only_where_accesses_conflict_and_per_stage_timing_give_the_same_bits() {
    // Three devices: core validation only (synchronisation validation takes every dispatch to
    // touch the whole bindless array, so it reports false hazards with tracked barriers).
    let scene = default_scene();
    let lf = light_field(&scene, scene.default_camera(), 0.02);
    let tracked_per_stage = ExecOptions { barriers: Barriers::Tracked, timing: Timing::PerStage, ..Default::default() };
    for scheme in [Scheme::MultiSource, Scheme::FineAll] {
        let plan = compact_plan(&lf, 3, scheme);
        let (every, per_op) = run_with(&scene, &lf, &plan, &plan, 0..2, None, ExecOptions::default());
        let (tracked, per_stage) = run_with(&scene, &lf, &plan, &plan, 0..2, None, tracked_per_stage.clone());
        assert!(every == tracked, "{scheme:?}");
        // Per-stage timing times every stage of every device, with fewer events than per op.
        let stages = |r: &FrameReport| -> Vec<(String, usize)> {
            r.stages.iter().map(|s| (s.stage.clone(), s.device)).collect()
        };
        assert_eq!((per_op.len(), per_stage.len()), (2, 2), "{scheme:?}: a report per frame");
        for (op, stage) in per_op.iter().zip(&per_stage) {
            assert_eq!(stages(op), stages(stage), "{scheme:?}");
            let passes = |r: &FrameReport| r.events.iter().filter(|e| e.kind == EventKind::Pass).count();
            assert!(passes(stage) < passes(op), "{scheme:?}: {} per stage, {} per op", passes(stage), passes(op));
            assert!(stage.events.iter().all(|e| e.end_ns >= e.start_ns));
        }
    }
}

/// Fine-all on four logical devices cuts a frame into submissions per device whose copy-ins
/// wait for other devices' copy-outs. With one queued submission per device (a
/// driver whose queue is full blocks the next vkQueueSubmit until the GPU has made progress),
/// the host may only submit a segment once everything it waits for is submitted: a whole
/// device's frame before the next device's would wait forever on device 0 (NVIDIA: until the
/// watchdog calls the device lost; here the executor's stall timeout, an error that fails
/// the run). Several frames with the bits of one device; no time bound of its own, which would
/// measure the machine's load, not a wait.
#[test]
fn fine_all_on_four_devices_runs_with_one_queued_submission_per_device() {
    let scene = default_scene();
    let lf = light_field(&scene, scene.default_camera(), 0.02);
    let config =
        PartitionConfig { devices: 4, scheme: Scheme::FineAll, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::new(&lf, &config).unwrap();
    let narrow = ExecOptions { max_queued_segments: 1, ..Default::default() };
    let (four, reports) = run_with(&scene, &lf, &plan, &plan, 0..FRAMES, None, narrow);
    assert_eq!(reports.len(), FRAMES as usize);
    // The small copies of each stage are batched at the ends of its runs: a few submissions
    // per stage (27 per device at this size, 13 stages), most of them waiting for other
    // devices, instead of one per view and stage (212 before batching).
    let per_device = reports[0].submitted_segments / 4;
    assert!((13..=40).contains(&per_device), "{per_device} segments per device");
    let one = run(&scene, &lf, &plan, &OnOneDevice(&plan), 0..FRAMES, None);
    assert!(finite(&four));
    assert!(four == one, "4 devices and 1 device differ");
}
