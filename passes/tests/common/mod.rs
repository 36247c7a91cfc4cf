//! Shared set-up of the lavapipe tests: validation always on (any message fails the test).

#![allow(dead_code)]

use glam::Vec3;
use parallax_backend::{Context, ExecOptions, KernelGraph, KernelPlan};
use parallax_graph::{AssignStrategy, LightField, Partition, PartitionConfig, Scheme, compile};
use parallax_passes::LightFieldRenderer;
use parallax_passes::firefly::FireflyMode;
use parallax_passes::hole_subsample::HoleFillMode;
use parallax_passes::pipeline::{
    Denoiser, GbufferSource, PipelineConfig, PipelineHandles, PipelineKind, declare_pipeline,
};
use parallax_passes::reproject::ReprojectionTolerances;
use parallax_scene::gpu::GpuScene;
use parallax_scene::{Camera, Scene, SceneBvh, View};

/// `devices` logical devices on the first Vulkan device (lavapipe in CI), with core
/// validation; synchronisation validation too on one device (see the backend's Known limits).
pub fn context(devices: usize) -> Context {
    parallax_testkit::lavapipe_context(devices)
}

/// `count` views of `scene`'s default camera, each moved sideways by 5 % of the scene's size.
pub fn views(scene: &Scene, count: u32, width: u32, height: u32) -> Vec<View> {
    let base = scene.default_camera();
    let (right, _, _) = base.basis();
    let step = 0.05 * scene.bounds().diagonal();
    (0..count)
        .map(|index| {
            let offset: Vec3 = right * step * index as f32;
            let camera = Camera { eye: base.eye + offset, ..base };
            View { camera, width, height, index }
        })
        .collect()
}

/// The reprojection pipeline with SVGF over `lf`'s views on `context`'s first device, its
/// display images exported, run by a [`LightFieldRenderer`] with `options`; and its handles.
pub fn reprojection_renderer(
    context: &Context,
    scene: &Scene,
    bvh: &SceneBvh,
    lf: &LightField,
    options: ExecOptions,
) -> (LightFieldRenderer, PipelineHandles) {
    let config =
        PartitionConfig { devices: 1, scheme: Scheme::MultiSource, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::new(lf, &config).unwrap();
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    let pipeline = denoising_pipeline(PipelineKind::Reproject);
    let handles = declare_pipeline(&mut graph, &pipeline).unwrap();
    graph.export(&handles.display);
    let schedule = compile(&graph, &plan).unwrap();
    let exec = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let renderer = LightFieldRenderer::with_options(context, exec, &GpuScene::new(scene, bvh), options).unwrap();
    (renderer, handles)
}

/// The standard pipeline of `kind`: first-hit G-buffer, default tolerances, firefly
/// suppression, SVGF, exposure 1.
pub fn denoising_pipeline(kind: PipelineKind) -> PipelineConfig {
    PipelineConfig {
        kind,
        gbuffer: GbufferSource::FirstHits,
        tolerances: ReprojectionTolerances::default(),
        fireflies: FireflyMode::Suppress,
        denoise: Denoiser::Views,
        hole_fill: HoleFillMode::Full,
        exposure: 1.0,
    }
}

/// Little-endian f32s of a read-back image.
pub fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

/// Mean squared error of two RGBA images over rgb, each value clamped to [0, 1] first (what a
/// display can show at exposure 1; keeps a few fireflies from deciding the comparison).
pub fn clamped_mse(a: &[f32], b: &[f32]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for c in 0..3 {
            let d = f64::from(pa[c].clamp(0.0, 1.0)) - f64::from(pb[c].clamp(0.0, 1.0));
            sum += d * d;
            n += 1;
        }
    }
    sum / n as f64
}
