//! Subset independence of `path_trace`: the same views traced whole, in row bands (one device;
//! alternating over two devices; fine-all over two devices, bands gathered on device 0) and as
//! compacted pixel lists (one device, and one view per device) give bit-identical pixels. This holds because
//! every random number is keyed by (pixel, view, frame, sample, bounce) and nothing else.

mod common;

use parallax_backend::ExecOptions;
use parallax_graph::Scheme;
use parallax_passes::{
    CompiledTrace, LightFieldRenderer, PATH_TRACE, StridedPixels, banded_trace_plan, strided_pixels, trace_plan,
};
use parallax_scene::gpu::{GpuPixel, GpuScene};
use parallax_scene::{SceneBvh, TraceSettings, default_scene};

const W: u32 = 24;
const H: u32 = 16;
const VIEWS: u32 = 2;
const STRIDE: u32 = 3;
const PHASE: u32 = 1;

fn render(devices: usize, trace: CompiledTrace) -> Vec<Vec<GpuPixel>> {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let ctx = common::context(devices);
    let views = common::views(&scene, VIEWS, W, H);
    let settings = TraceSettings { spp: 2, max_depth: 3, frame: 7, ..Default::default() };
    let mut tracer =
        LightFieldRenderer::tracing(&ctx, trace, &GpuScene::new(&scene, &bvh), ExecOptions::default()).unwrap();
    let pixels = tracer.trace(&scene, &views, &settings).unwrap();
    drop(tracer);
    ctx.check_validation().unwrap();
    pixels
}

fn list(capacity: u64) -> Option<(u64, StridedPixels)> {
    Some((capacity, StridedPixels { width: W, height: H, stride: STRIDE, phase: PHASE }))
}

#[test]
fn whole_views_bands_and_pixel_lists_give_identical_pixels_on_one_and_two_devices() {
    let capacity = u64::from(W * H);
    let whole = render(1, trace_plan(VIEWS, 1, (W, H), 1, Scheme::MultiSource, None).unwrap());
    for view in &whole {
        assert!(view.iter().any(|p| p.radiance[3] == 1.0), "the default camera sees the scene");
        assert!(view.iter().flat_map(|p| p.radiance).all(f32::is_finite));
    }
    assert_ne!(whole[0], whole[1], "views differ (camera and random key)");

    let bands_one_device = render(1, banded_trace_plan(VIEWS, (W, H), 3, 1).unwrap());
    assert_eq!(bands_one_device, whole, "3 row bands on one device");
    let bands_copied = banded_trace_plan(VIEWS, (W, H), 3, 2).unwrap();
    assert_eq!(bands_copied.plan.copies.len(), 2 * 4, "per view, the band on device 1 comes back as 4 images");
    assert_eq!(render(2, bands_copied), whole, "3 row bands alternating over 2 devices");

    let bands_two_devices = trace_plan(VIEWS, 1, (W, H), 2, Scheme::FineAll, None).unwrap();
    let split: Vec<usize> = bands_two_devices.plan.passes.iter().map(|p| p.device.index()).collect();
    assert!(split.contains(&0) && split.contains(&1), "fine-all puts bands on both devices: {split:?}");
    assert_eq!(render(2, bands_two_devices), whole, "row bands over 2 devices, gathered");

    let listed = strided_pixels(W, H, STRIDE, PHASE);
    let check_list = |got: &[Vec<GpuPixel>], what: &str| {
        for (view, (g, w)) in got.iter().zip(&whole).enumerate() {
            for y in 0..H {
                for x in 0..W {
                    let i = (y * W + x) as usize;
                    let expected = if listed.contains(&(x, y)) { w[i] } else { GpuPixel::default() };
                    assert_eq!(g[i], expected, "{what}: view {view}, pixel ({x}, {y})");
                }
            }
        }
    };
    let list_one = render(1, trace_plan(VIEWS, 1, (W, H), 1, Scheme::MultiSource, list(capacity)).unwrap());
    check_list(&list_one, "pixel list, one device");
    let list_plan = trace_plan(VIEWS, 1, (W, H), 2, Scheme::MultiSource, list(capacity)).unwrap();
    let devices: Vec<usize> =
        list_plan.plan.passes.iter().filter(|p| p.name == PATH_TRACE).map(|p| p.device.index()).collect();
    assert_eq!(devices, [0, 1], "multi-source: one view per device");
    check_list(&render(2, list_plan), "pixel lists, one view per device");
}
