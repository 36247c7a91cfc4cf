//! The SVGF and tonemap passes on lavapipe (validation on): the tonemap against its CPU twin,
//! SVGF on a noiseless input (gives it back), on a spoilt one (NaN, Inf, black albedo, bad
//! normals and depths: only finite output), on path-traced noise (error against a 64-spp reference),
//! after a history reset (a fresh first frame, bit for bit) and over row bands on three devices
//! (the one-device result, bit for bit). Inputs come from the `path_trace` pass of the default
//! scene; `motion` and the changes to the input from test kernels in `tests/svgf_kernels/`,
//! compiled at run time.

mod common;

use std::path::Path;
use std::sync::Arc;

use parallax_backend::{
    Context, ExecOptions, ExecutionPlan, Executor, InstanceId, KernelGraph, KernelPlan, PassInstance, PassKernel,
    PassParams, Recorder, ShaderLibrary,
};
use parallax_graph::{
    BandedPlacement, FamilyId, Format, Handle, Image, Placement, ReadSlot, Role, ViewTopology, WriteSlot, compile,
};
use parallax_passes::path_trace::TRACE_PARAMS_BYTES;
use parallax_passes::{
    DENOISED, LightFieldRenderer, PATH_TRACE, PathTraceKernel, SvgfInputs, TRACE_OUTPUTS, banded_trace_plan,
    declare_svgf, declare_tonemap, tonemap_pixel, trace_frame_data, upload_scene,
};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{Scene, SceneBvh, TraceSettings, View, default_scene};

const SIZE: u32 = 32;

/// The test kernels of `tests/svgf_kernels/`, compiled into a folder of `test`'s own, over the
/// passes' shaders.
fn test_shaders(test: &str) -> ShaderLibrary {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("svgf_kernels");
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("svgf_kernels").join(test);
    std::fs::create_dir_all(&out).unwrap();
    let shaders =
        parallax_glsl::Compiler::new().compile_dir(&src, &[parallax_glsl::parallax_include_dir()], &out).unwrap();
    let test = shaders.iter().fold(ShaderLibrary::new(), |library, shader| {
        library.with_spirv_bytes(&shader.name, &std::fs::read(&shader.spirv).unwrap()).unwrap()
    });
    test.layered_over(parallax_passes::shader_library())
}

/// `test_motion.comp`: motion = own pixel centre + `offset` where there is a hit.
struct MotionKernel {
    position: ReadSlot,
    motion: WriteSlot,
    offset: [f32; 2],
}

impl PassKernel for MotionKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let (dst, position) = (pass.write(self.motion)?, pass.read(self.position)?);
        let width = rec.resource(dst.alloc).width;
        let push = MotionPush {
            dst: rec.image(dst.alloc)?,
            position: rec.image(position.alloc)?,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            offset_x: self.offset[0],
            offset_y: self.offset[1],
        };
        rec.dispatch("test_motion", &push, [width.div_ceil(8), pass.region.len().div_ceil(8), 1])
    }
}

/// Push constants of `test_motion.comp`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct MotionPush {
    dst: u32,
    position: u32,
    y0: u32,
    y1: u32,
    width: u32,
    offset_x: f32,
    offset_y: f32,
}

parallax_backend::push_constants!(MotionPush { dst, position, y0, y1, width, offset_x, offset_y });

/// `test_constant.comp` or `test_poison.comp` (the shader named): radiance (dst), albedo
/// (src0) and, where declared, normal (src1) and position (param) changed in place.
struct ChangeKernel {
    shader: &'static str,
    radiance: WriteSlot,
    albedo: WriteSlot,
    normal: Option<WriteSlot>,
    position: Option<WriteSlot>,
}

impl PassKernel for ChangeKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let (radiance, albedo) = (pass.write(self.radiance)?, pass.write(self.albedo)?);
        let optional = |slot: Option<WriteSlot>| slot.map_or(Ok(0), |slot| rec.image(pass.write(slot)?.alloc));
        let (normal, position) = (optional(self.normal)?, optional(self.position)?);
        let params = PassParams {
            dst: rec.image(radiance.alloc)?,
            src0: rec.image(albedo.alloc)?,
            src1: normal,
            param: position,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width: rec.resource(radiance.alloc).width,
            ..Default::default()
        };
        rec.dispatch_rows(self.shader, params)
    }
}

/// What a test kernel does to the traced input before SVGF.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Change {
    None,
    /// Radiance and albedo replaced by constants (`test_constant`).
    Constant,
    /// NaN, Inf, black albedo, zero or NaN normals, NaN depth on some pixels (`test_poison`).
    Poison,
}

/// What the SVGF test graphs feed in.
#[derive(Clone, Copy)]
struct Input {
    change: Change,
    /// The motion test kernel's offset.
    motion: [f32; 2],
}

/// `path_trace` (G-buffer and radiance) → [`Input`] → `declare_svgf`, for `views` views;
/// `denoised` and the traced radiance exported.
fn svgf_plan(views: u32, input: Input, placement: &dyn Placement) -> KernelPlan {
    let mut g = KernelGraph::with_payload(ViewTopology::all_sources(views, SIZE, SIZE));
    let [mut radiance, mut albedo, mut normal, mut position]: [Handle<Image>; 4] =
        TRACE_OUTPUTS.map(|name| g.image(name, Format::Rgba32f));
    let mut pass = g.pass(PATH_TRACE, Role::All);
    let traced = PathTraceKernel::new(pass.write_slot(&mut radiance)).with_gbuffer([
        pass.write_slot(&mut albedo),
        pass.write_slot(&mut normal),
        pass.write_slot(&mut position),
    ]);
    pass.kernel(Arc::new(traced)).add();
    match input.change {
        Change::None => {}
        Change::Constant => {
            let mut pass = g.pass("test_constant", Role::All);
            let (_, radiance) = pass.modify_slot(&mut radiance);
            let (_, albedo) = pass.modify_slot(&mut albedo);
            let kernel = ChangeKernel { shader: "test_constant", radiance, albedo, normal: None, position: None };
            pass.kernel(Arc::new(kernel)).add();
        }
        Change::Poison => {
            let mut pass = g.pass("test_poison", Role::All);
            let kernel = ChangeKernel {
                shader: "test_poison",
                radiance: pass.modify_slot(&mut radiance).1,
                albedo: pass.modify_slot(&mut albedo).1,
                normal: Some(pass.modify_slot(&mut normal).1),
                position: Some(pass.modify_slot(&mut position).1),
            };
            pass.kernel(Arc::new(kernel)).add();
        }
    }
    let mut motion = g.image("motion", Format::Rg32f);
    let mut pass = g.pass("test_motion", Role::All);
    let (position_slot, motion_slot) = (pass.read_slot(&position), pass.write_slot(&mut motion));
    let kernel = MotionKernel { position: position_slot, motion: motion_slot, offset: input.motion };
    pass.kernel(Arc::new(kernel)).add();
    let inputs = SvgfInputs {
        radiance: &radiance,
        albedo_roughness: &albedo,
        normal_metallic: &normal,
        position_depth: &position,
        motion: &motion,
    };
    let denoised = declare_svgf(&mut g, Role::All, &inputs);
    g.export(&denoised);
    g.export(&radiance);
    compile_graph(&g, placement)
}

fn compile_graph(graph: &KernelGraph, placement: &dyn Placement) -> KernelPlan {
    let schedule = compile(graph, placement).unwrap();
    assert_eq!(schedule.validate().errors, vec![]);
    KernelPlan::from_schedule(graph, &schedule).unwrap()
}

fn one_device() -> BandedPlacement {
    BandedPlacement { devices: 1, bands: 1 }
}

/// An executor of `plan` with the test kernels and the default scene uploaded.
struct Run {
    exec: Executor,
    scene: Scene,
    views: Vec<View>,
}

impl Run {
    fn new(ctx: &Context, plan: KernelPlan, views: u32, test: &str) -> Self {
        let scene = default_scene();
        let bvh = SceneBvh::build(&scene);
        let options = ExecOptions { shaders: test_shaders(test), ..ExecOptions::default() };
        assert!(options.frame_data_bytes >= u64::from(views) * TRACE_PARAMS_BYTES);
        let mut exec = Executor::new(ctx, plan, options).unwrap();
        upload_scene(&mut exec, &GpuScene::new(&scene, &bvh)).unwrap();
        let views = common::views(&scene, views, SIZE, SIZE);
        Self { exec, scene, views }
    }

    /// Runs one frame traced at 1 spp with the noise of frame `noise`, pixel centres only (a
    /// G-buffer that does not move between frames, like a raster one).
    fn frame(&mut self, noise: u32) {
        let settings = TraceSettings { spp: 1, frame: noise, jitter: false, ..TraceSettings::default() };
        self.exec.set_frame_data(&trace_frame_data(&self.scene, &self.views, &settings).unwrap()).unwrap();
        self.exec.run_frame().unwrap();
    }

    /// The final version of the declared resource named `name` (internal ones of the SVGF
    /// stage too, which no handle reaches) of `view`, as f32s (RGBA per pixel).
    fn read(&mut self, name: &str, view: u32) -> Vec<f32> {
        self.exec.finish().unwrap();
        let (device, resource) = self.exec.plan().final_output(family_named(self.exec.plan(), name), view).unwrap();
        common::floats(&self.exec.read_resource(device, resource).unwrap())
    }
}

/// The family of the resources `plan` allocates under `name`.
fn family_named(plan: &ExecutionPlan, name: &str) -> FamilyId {
    plan.resources.iter().find(|r| r.name == name).map(|r| r.family).unwrap_or_else(|| panic!("no `{name}`"))
}

#[test]
fn tonemap_matches_its_cpu_twin_within_one_step_of_255() {
    let exposure = 1.5;
    let ctx = common::context(2);
    let mut g = KernelGraph::with_payload(ViewTopology::all_sources(2, SIZE, SIZE));
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut pass = g.pass(PATH_TRACE, Role::All);
    let kernel = PathTraceKernel::new(pass.write_slot(&mut radiance));
    pass.kernel(Arc::new(kernel)).add();
    let display = declare_tonemap(&mut g, &radiance, exposure).unwrap();
    g.export(&display);
    g.export(&radiance);
    let plan = compile_graph(&g, &BandedPlacement { devices: 2, bands: 2 });
    let mut run = Run::new(&ctx, plan, 2, "tonemap");
    run.frame(0);
    run.exec.finish().unwrap();
    for view in 0..2 {
        let radiance = run.read("radiance", view);
        let (device, resource) = run.exec.plan().final_output(display.family(), view).unwrap();
        let bytes = run.exec.read_resource(device, resource).unwrap();
        assert_eq!(bytes.len(), (SIZE * SIZE * 4) as usize);
        let mut worst = 0i32;
        for (rgb, got) in radiance.chunks_exact(4).zip(bytes.chunks_exact(4)) {
            let expected = tonemap_pixel([rgb[0], rgb[1], rgb[2]], exposure);
            for c in 0..4 {
                let want = (expected[c] * 255.0).round() as i32;
                worst = worst.max((i32::from(got[c]) - want).abs());
            }
        }
        assert!(worst <= 1, "view {view}: a byte differs by {worst} from the CPU curve");
    }
    drop(run);
    ctx.check_validation().unwrap();
}

#[test]
fn svgf_gives_a_constant_input_back_on_every_frame() {
    let ctx = common::context(1);
    let plan = svgf_plan(1, Input { change: Change::Constant, motion: [0.0, 0.0] }, &one_device());
    let mut run = Run::new(&ctx, plan, 1, "constant");
    let expected = [0.3f32, 0.2, 0.1];
    for frame in 0..6 {
        run.frame(frame);
        let denoised = run.read(DENOISED, 0);
        let mut worst = 0.0f32;
        for pixel in denoised.chunks_exact(4) {
            assert!(pixel.iter().all(|v| v.is_finite()), "frame {frame}: {pixel:?}");
            for c in 0..3 {
                worst = worst.max((pixel[c] - expected[c]).abs() / expected[c]);
            }
        }
        assert!(worst <= 1e-4, "frame {frame}: relative error {worst}");
    }
    drop(run);
    ctx.check_validation().unwrap();
}

#[test]
fn svgf_writes_only_finite_values_from_nan_inf_black_albedo_bad_normals_and_depths() {
    let ctx = common::context(1);
    // Motion half a pixel off: bilinear taps reach the spoilt neighbours through history too.
    let plan = svgf_plan(1, Input { change: Change::Poison, motion: [0.5, 0.5] }, &one_device());
    let mut run = Run::new(&ctx, plan, 1, "poison");
    for frame in 0..6 {
        run.frame(frame);
        let denoised = run.read(DENOISED, 0);
        let bad = denoised.iter().filter(|v| !v.is_finite()).count();
        assert_eq!(bad, 0, "frame {frame}: {bad} values are NaN or Inf");
    }
    drop(run);
    ctx.check_validation().unwrap();
}

#[test]
fn svgf_lowers_the_error_of_one_spp_against_a_64_spp_reference_by_3x() {
    let ctx = common::context(1);
    let frames = 8;
    let plan = svgf_plan(1, Input { change: Change::None, motion: [0.0, 0.0] }, &one_device());
    let mut run = Run::new(&ctx, plan, 1, "noisy");
    let mut timings = Vec::new();
    for frame in 0..frames {
        run.frame(frame);
        run.exec.finish().unwrap();
        timings.extend(run.exec.take_reports());
    }
    let noisy = run.read("radiance", 0);
    let denoised = run.read(DENOISED, 0);
    assert!(denoised.iter().all(|v| v.is_finite()));
    print_svgf_timings(&timings);

    let bvh = SceneBvh::build(&run.scene);
    let trace = banded_trace_plan(1, (SIZE, SIZE), 1, 1).unwrap();
    let mut tracer =
        LightFieldRenderer::tracing(&ctx, trace, &GpuScene::new(&run.scene, &bvh), ExecOptions::default()).unwrap();
    let settings = TraceSettings { spp: 64, frame: 1000, jitter: false, ..TraceSettings::default() };
    let reference: Vec<f32> =
        tracer.trace(&run.scene, &run.views, &settings).unwrap()[0].iter().flat_map(|p| p.radiance).collect();
    let (noisy_mse, denoised_mse) =
        (common::clamped_mse(&noisy, &reference), common::clamped_mse(&denoised, &reference));
    eprintln!("MSE against 64 spp: 1 spp {noisy_mse:.5}, SVGF after {frames} frames {denoised_mse:.5}");
    assert!(denoised_mse * 3.0 <= noisy_mse, "1 spp {noisy_mse}, denoised {denoised_mse}");
    drop(tracer);
    drop(run);
    ctx.check_validation().unwrap();
}

/// GPU time of the SVGF passes, averaged over frames (a sanity check on lavapipe, not a figure).
fn print_svgf_timings(reports: &[parallax_backend::FrameReport]) {
    let mut total = std::collections::BTreeMap::<String, (f64, usize)>::new();
    for report in reports {
        for event in report.events.iter().filter(|e| e.name.starts_with("svgf")) {
            let entry = total.entry(event.name.clone()).or_default();
            entry.0 += (event.end_ns - event.start_ns) as f64 * 1e-6;
            entry.1 += 1;
        }
    }
    for (name, (ms, n)) in total {
        eprintln!("{name}: {:.3} ms per frame ({SIZE}x{SIZE}, lavapipe)", ms / n as f64);
    }
}

#[test]
fn a_frame_after_a_history_reset_equals_a_fresh_first_frame_bit_for_bit() {
    let ctx = common::context(1);
    let input = Input { change: Change::None, motion: [0.0, 0.0] };
    let mut fresh = Run::new(&ctx, svgf_plan(1, input, &one_device()), 1, "reset_fresh");
    fresh.frame(0);
    let first = fresh.read(DENOISED, 0);
    drop(fresh);

    let mut run = Run::new(&ctx, svgf_plan(1, input, &one_device()), 1, "reset");
    for frame in 1..5 {
        run.frame(frame);
    }
    // The same input with history: what a reset must not show.
    run.frame(0);
    let with_history = run.read(DENOISED, 0);
    assert_ne!(with_history, first, "history changes the image");
    run.exec.reset_history();
    run.frame(0);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&run.read(DENOISED, 0)), bits(&first));
    drop(run);
    ctx.check_validation().unwrap();
}

#[test]
fn svgf_in_three_row_bands_on_three_devices_equals_one_device_bit_for_bit() {
    // Motion 5.75 rows down: reprojection reads rows of other bands (and bilinear weights).
    let input = Input { change: Change::None, motion: [0.25, 5.75] };
    let frames = 4;
    let views = 2;
    let run = |devices: usize| -> Vec<Vec<u32>> {
        let ctx = common::context(devices);
        let placement = BandedPlacement { devices: devices as u32, bands: devices as u32 };
        let plan = svgf_plan(views, input, &placement);
        if devices > 1 {
            assert!(!plan.copies.is_empty(), "bands of other devices are copied in");
        }
        let mut run = Run::new(&ctx, plan, views, &format!("bands_{devices}"));
        let mut out = Vec::new();
        for frame in 0..frames {
            run.frame(frame);
            for view in 0..views {
                out.push(run.read(DENOISED, view).iter().map(|v| v.to_bits()).collect());
            }
        }
        if devices == 1 {
            // Not vacuous: pixels of rows 5..10 (band 0 is rows 0..10) reuse history (length
            // >= 2, the colour history's alpha) through rows 10..16, which band 1 wrote.
            let color = run.read("svgf_color", 0);
            let reused = (5..10usize)
                .flat_map(|y| (0..SIZE as usize).map(move |x| y * SIZE as usize + x))
                .filter(|&i| color[4 * i + 3] >= 2.0)
                .count();
            assert!(reused > 10, "only {reused} pixels reprojected across the band border");
        }
        drop(run);
        ctx.check_validation().unwrap();
        out
    };
    let one = run(1);
    let three = run(3);
    for (k, (a, b)) in one.iter().zip(&three).enumerate() {
        let differing = a.iter().zip(b).filter(|(x, y)| x != y).count();
        assert_eq!(
            differing,
            0,
            "frame {}, view {}: {differing} values differ",
            k / views as usize,
            k % views as usize
        );
    }
}

#[test]
fn history_farther_than_the_reach_restarts_the_pixel() {
    let reach = parallax_passes::svgf::HISTORY_REACH;
    assert!(reach + 2 <= SIZE, "the test needs rows beyond the reach");
    let ctx = common::context(1);
    // Motion of exactly `rows` rows down, no fraction: one tap, `rows` from its pixel.
    let reused_rows = |rows: u32| -> Vec<usize> {
        let input = Input { change: Change::None, motion: [0.0, rows as f32] };
        let mut run = Run::new(&ctx, svgf_plan(1, input, &one_device()), 1, &format!("reach_{rows}"));
        for frame in 0..3 {
            run.frame(frame);
        }
        // A pixel that reused history has length >= 2 (the colour history's alpha).
        let color = run.read("svgf_color", 0);
        let size = SIZE as usize;
        (0..size).filter(|&y| (0..size).any(|x| color[4 * (y * size + x) + 3] >= 2.0)).collect()
    };
    let within = reused_rows(reach);
    assert!(!within.is_empty(), "motion of {reach} rows reuses history");
    assert!(within.iter().all(|&y| y + (reach as usize) < SIZE as usize), "{within:?}");
    let beyond = reused_rows(reach + 1);
    assert_eq!(beyond, Vec::<usize>::new(), "motion of {} rows must restart every pixel", reach + 1);
    ctx.check_validation().unwrap();
}
