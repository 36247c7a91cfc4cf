//! Firefly suppression on lavapipe (validation on). A synthetic input from a test kernel
//! (`tests/firefly_kernels/`, compiled at run time): a firefly keeps its neighbourhood's bound
//! and its excess lands on its neighbours with a hit, so the view's per-channel sum is
//! unchanged, sky pixels are untouched and pixels away from a firefly keep their bits; three
//! row bands on three devices give the one-device result bit for bit (the halo reads). And the
//! path-traced default scene with a still camera: each frame's per-channel sum is the
//! unsuppressed frame's, its luminance's second moment is lower (excess spread out), sky pixels
//! are unchanged, and suppression moves less radiance as the running mean grows (bound × √n).

mod common;

use std::path::Path;
use std::sync::{Arc, OnceLock};

use parallax_backend::{
    ExecOptions, Executor, InstanceId, KernelGraph, KernelPlan, PassInstance, PassKernel, PassParams, Recorder,
    ShaderLibrary,
};
use parallax_graph::{BandedPlacement, Format, Role, ViewTopology, WriteSlot, compile};
use parallax_passes::LightFieldRenderer;
use parallax_passes::firefly::{FireflyMode, declare_firefly_suppression};
use parallax_passes::pipeline::{Denoiser, PipelineConfig, PipelineKind, declare_pipeline};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{SceneBvh, TraceSettings, default_scene};

const WIDTH: u32 = 24;
const HEIGHT: u32 = 20;
/// The synthetic input's grey, and its fireflies (test_fireflies.comp).
const GREY: f32 = 0.1;
const CENTRE: (usize, usize, [f32; 3]) = (10, 9, [60.0, 30.0, 10.0]);
const CORNER: (usize, usize, [f32; 3]) = (0, 0, [8.0, 8.0, 8.0]);
const BY_THE_SKY: (usize, usize, [f32; 3]) = (18, 12, [20.0, 20.0, 20.0]);
/// Columns from here on have no hit (sky).
const SKY_FROM: usize = 20;

/// The test kernels of `tests/firefly_kernels/`, over the passes' shaders.
fn test_shaders() -> ShaderLibrary {
    // Compiled once per test binary: tests run in parallel, and one test reading a SPIR-V file
    // while another's glslc rewrites it can read it empty.
    static SPIRV: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    let spirv = SPIRV.get_or_init(|| {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("firefly_kernels");
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firefly_kernels");
        std::fs::create_dir_all(&out).unwrap();
        let includes = [parallax_glsl::parallax_include_dir()];
        let compiled = parallax_glsl::Compiler::new().compile_dir(&src, &includes, &out).unwrap();
        compiled.into_iter().map(|shader| (shader.name, std::fs::read(&shader.spirv).unwrap())).collect()
    });
    let test = spirv
        .iter()
        .fold(ShaderLibrary::new(), |library, (name, bytes)| library.with_spirv_bytes(name, bytes).unwrap());
    test.layered_over(parallax_passes::shader_library())
}

/// `test_fireflies.comp`: the synthetic radiance (dst) and position_depth (src0).
struct SyntheticInput {
    radiance: WriteSlot,
    position: WriteSlot,
}

impl PassKernel for SyntheticInput {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let radiance = pass.write(self.radiance)?;
        let params = PassParams {
            dst: rec.image(radiance.alloc)?,
            src0: rec.image(pass.write(self.position)?.alloc)?,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width: rec.resource(radiance.alloc).width,
            ..Default::default()
        };
        rec.dispatch_rows("test_fireflies", params)
    }
}

/// The synthetic input, suppressed or not, in `devices` row bands on as many devices; the
/// final radiance (RGBA f32).
fn synthetic(devices: u32, suppress: bool) -> Vec<f32> {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(1, WIDTH, HEIGHT));
    let mut radiance = graph.image("radiance", Format::Rgba32f);
    let mut position = graph.image("position_depth", Format::Rgba32f);
    let mut pass = graph.pass("test_fireflies", Role::All);
    let kernel = SyntheticInput { radiance: pass.write_slot(&mut radiance), position: pass.write_slot(&mut position) };
    pass.kernel(Arc::new(kernel)).add();
    if suppress {
        declare_firefly_suppression(&mut graph, Role::All, &position, &mut radiance);
    }
    graph.export(&radiance);
    let schedule = compile(&graph, &BandedPlacement { devices, bands: devices }).unwrap();
    assert_eq!(schedule.validate().errors, vec![]);
    let plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let ctx = common::context(devices as usize);
    let options = ExecOptions { shaders: test_shaders(), ..ExecOptions::default() };
    let mut exec = Executor::new(&ctx, plan, options).unwrap();
    exec.run_frame().unwrap();
    exec.finish().unwrap();
    let (device, resource) = exec.plan().final_output(radiance.family(), 0).unwrap();
    let out = common::floats(&exec.read_resource(device, resource).unwrap());
    drop(exec);
    ctx.check_validation().unwrap();
    out
}

fn rgb(image: &[f32], x: usize, y: usize) -> [f32; 3] {
    let i = 4 * (y * WIDTH as usize + x);
    [image[i], image[i + 1], image[i + 2]]
}

/// Per-channel sums over every pixel.
fn sums(image: &[f32]) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    for pixel in image.chunks_exact(4) {
        for c in 0..3 {
            sum[c] += f64::from(pixel[c]);
        }
    }
    sum
}

fn assert_close(what: &str, got: [f32; 3], expected: [f32; 3]) {
    for c in 0..3 {
        assert!(
            (got[c] - expected[c]).abs() <= 1e-5 * expected[c].abs().max(1.0),
            "{what}: {got:?}, expected {expected:?}"
        );
    }
}

#[test]
fn a_synthetic_firefly_keeps_its_neighbourhoods_bound_and_gives_its_excess_to_its_neighbours() {
    let before = synthetic(1, false);
    let after = synthetic(1, true);
    let (b, a) = (sums(&before), sums(&after));
    for c in 0..3 {
        assert!((a[c] / b[c] - 1.0).abs() < 1e-6, "channel {c}: sum {} before, {} after", b[c], a[c]);
    }
    // Its 24 neighbours are all grey: the bound is their luminance, the hue stays, and each
    // neighbour gets 1/24 of the excess on top of its grey.
    let (x, y, firefly) = CENTRE;
    let luminance = 0.2126 * firefly[0] + 0.7152 * firefly[1] + 0.0722 * firefly[2];
    let kept = firefly.map(|v| v * GREY / luminance);
    assert_close("the centre firefly", rgb(&after, x, y), kept);
    let share = [0, 1, 2].map(|c| GREY + (firefly[c] - kept[c]) / 24.0);
    assert_close("the centre's neighbour (12, 11)", rgb(&after, x + 2, y + 2), share);
    assert_close("the centre's neighbour (9, 8)", rgb(&after, x - 1, y - 1), share);
    // In the corner 8 neighbours are in the view: each gets an eighth.
    let (x, y, firefly) = CORNER;
    assert_close("the corner firefly", rgb(&after, x, y), [GREY; 3]);
    assert_close("the corner's neighbour (2, 2)", rgb(&after, 2, 2), [GREY + (firefly[0] - GREY) / 8.0; 3]);
    // By the sky: 4 columns of 5 rows with a hit, itself excluded, receive.
    let (x, y, firefly) = BY_THE_SKY;
    assert_close("the firefly by the sky", rgb(&after, x, y), [GREY; 3]);
    assert_close("its neighbour (19, 14)", rgb(&after, 19, 14), [GREY + (firefly[0] - GREY) / 19.0; 3]);
    for y in 0..HEIGHT as usize {
        for x in 0..WIDTH as usize {
            let near = |(fx, fy, _): (usize, usize, [f32; 3])| x.abs_diff(fx) <= 2 && y.abs_diff(fy) <= 2;
            if x >= SKY_FROM {
                assert_eq!(rgb(&after, x, y), rgb(&before, x, y), "sky pixel ({x}, {y}) changed");
            } else if ![CENTRE, CORNER, BY_THE_SKY].into_iter().any(near) {
                assert_close(&format!("grey pixel ({x}, {y})"), rgb(&after, x, y), [GREY; 3]);
            }
        }
    }
}

#[test]
fn suppression_in_three_row_bands_on_three_devices_equals_one_device_bit_for_bit() {
    let one = synthetic(1, true);
    let three = synthetic(3, true);
    assert!(one == three, "3 devices and 1 device differ");
    assert!(one != synthetic(1, false), "nothing was suppressed");
}

/// The path-trace pipeline without denoising over two views of the default scene at 1 spp,
/// fireflies `mode`; per frame, each view's radiance and position_depth.
fn traced(mode: FireflyMode, frames: u32) -> Vec<Vec<(Vec<f32>, Vec<f32>)>> {
    let scene = default_scene();
    let views = common::views(&scene, 2, 48, 36);
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(2, 48, 36));
    let config = PipelineConfig {
        kind: PipelineKind::PathTrace,
        fireflies: mode,
        denoise: Denoiser::None,
        ..PipelineConfig::default()
    };
    let handles = declare_pipeline(&mut graph, &config).unwrap();
    graph.export(&handles.radiance);
    graph.export(&handles.gbuffer.position_depth);
    let schedule = compile(&graph, &BandedPlacement { devices: 1, bands: 1 }).unwrap();
    let plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let ctx = common::context(1);
    let bvh = SceneBvh::build(&scene);
    let mut renderer = LightFieldRenderer::new(&ctx, plan, &GpuScene::new(&scene, &bvh)).unwrap();
    let out = (0..frames)
        .map(|frame| {
            let settings = TraceSettings { spp: 1, max_depth: 4, frame, jitter: true, ..Default::default() };
            renderer.submit(&scene, &views, &settings).unwrap();
            renderer.finish().unwrap();
            (0..2)
                .map(|view| {
                    let radiance = common::floats(&renderer.read(handles.radiance.family(), view).unwrap());
                    let position =
                        common::floats(&renderer.read(handles.gbuffer.position_depth.family(), view).unwrap());
                    (radiance, position)
                })
                .collect()
        })
        .collect();
    drop(renderer);
    ctx.check_validation().unwrap();
    out
}

#[test]
fn suppressing_a_path_traced_frame_keeps_its_per_channel_sums_and_fades_as_a_still_camera_accumulates() {
    let kept = traced(FireflyMode::Keep, 4);
    let suppressed = traced(FireflyMode::Suppress, 4);
    // Per frame, the pixels suppression changed, over both views.
    let mut changed = Vec::new();
    let luminance = |p: &[f32]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    for (frame, (kept, suppressed)) in kept.iter().zip(&suppressed).enumerate() {
        for (view, ((before, position), (after, _))) in kept.iter().zip(suppressed).enumerate() {
            let second_moment =
                |image: &[f32]| image.chunks_exact(4).map(|p| f64::from(luminance(p)).powi(2)).sum::<f64>();
            let (b, a) = (sums(before), sums(after));
            for c in 0..3 {
                assert!(
                    (a[c] / b[c] - 1.0).abs() < 1e-5,
                    "frame {frame}, view {view}, channel {c}: {} → {}",
                    b[c],
                    a[c]
                );
            }
            let (mb, ma) = (second_moment(before), second_moment(after));
            if view == 0 {
                changed.push(0);
            }
            *changed.last_mut().unwrap() +=
                before.chunks_exact(4).zip(after.chunks_exact(4)).filter(|(b, a)| b != a).count();
            assert!(ma < mb, "frame {frame}, view {view}: Σ luminance² {mb} before, {ma} after");
            for (i, (pb, pa)) in before.chunks_exact(4).zip(after.chunks_exact(4)).enumerate() {
                if position[4 * i + 3] == 0.0 {
                    assert_eq!(pb, pa, "frame {frame}, view {view}: sky pixel {i} changed");
                }
            }
        }
    }
    // The fourth still frame is bounded at 2 × the first's deviations (√4): fewer donors, so
    // fewer pixels changed (measured: 705, 268, 300, 176 of 3,456).
    assert!(2 * changed[3] < changed[0], "suppression did not fade: pixels changed per frame {changed:?}");
}
