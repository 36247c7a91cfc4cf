//! Misuse gives the exact error: views out of order, too many rays, a `path_trace` pass with
//! accesses it cannot serve, textures that do not fit the backend's texture array.

mod common;

use std::sync::Arc;

use parallax_backend::{
    BackendError, ExecOptions, Executor, InstanceId, KernelGraph, KernelPlan, MAX_TEXTURES, ShaderLibrary, TextureData,
};
use parallax_graph::{BandedPlacement, Role, ViewTopology, compile};
use parallax_passes::{
    LightFieldRenderer, PATH_TRACE, PassError, PathTraceKernel, RaySchedule, Raycaster, random_rays, trace_frame_data,
};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{SceneBvh, TraceSettings, default_scene};

#[test]
fn trace_parameters_must_list_views_in_order() {
    let scene = default_scene();
    let mut views = common::views(&scene, 2, 8, 8);
    views.swap(0, 1);
    match trace_frame_data(&scene, &views, &TraceSettings::default()) {
        Err(PassError::ViewOrder { position: 0, index: 1 }) => {}
        other => panic!("expected ViewOrder, got {other:?}"),
    }
    let zero_spp = TraceSettings { spp: 0, ..Default::default() };
    assert!(matches!(trace_frame_data(&scene, &views[..0], &zero_spp), Err(PassError::Scene(_))));
}

#[test]
fn raycaster_refuses_more_rays_than_planned_and_path_trace_refuses_a_buffer_target() {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let gpu_scene = GpuScene::new(&scene, &bvh);
    let ctx = common::context(1);
    let mut raycaster = Raycaster::new(&ctx, &gpu_scene, 10, false, RaySchedule::PerRay).unwrap();
    match raycaster.cast(&random_rays(&scene, 11), false, 1) {
        Err(PassError::TooManyRays { rays: 11, capacity: 10 }) => {}
        other => panic!("expected TooManyRays, got {other:?}"),
    }
    drop(raycaster);

    // Views must have the size of the plan's images.
    let trace = parallax_passes::banded_trace_plan(1, (8, 8), 1, 1).unwrap();
    let mut tracer =
        parallax_passes::LightFieldRenderer::tracing(&ctx, trace, &gpu_scene, ExecOptions::default()).unwrap();
    let view = parallax_scene::View { camera: scene.default_camera(), width: 8, height: 4, index: 0 };
    match tracer.trace(&scene, &[view], &TraceSettings::default()) {
        Err(PassError::ViewSize { view: 0, width: 8, height: 4, plan_width: 8, plan_height: 8, .. }) => {}
        other => panic!("expected ViewSize, got {other:?}"),
    }
    match tracer.trace(&scene, &[], &TraceSettings::default()) {
        Err(PassError::MissingViews { plan_views: 1, given: 0 }) => {}
        other => panic!("expected MissingViews, got {other:?}"),
    }
    drop(tracer);

    // A path_trace pass whose only write is a buffer: the kernel says what it expects.
    let mut g = KernelGraph::with_payload(ViewTopology::all_sources(1, 8, 8));
    let mut list = g.buffer("list", 64);
    let mut pass = g.pass(PATH_TRACE, Role::All);
    let kernel = PathTraceKernel::new(pass.write_slot(&mut list));
    pass.kernel(Arc::new(kernel)).add();
    g.export(&list);
    let schedule = compile(&g, &BandedPlacement { devices: 1, bands: 1 }).unwrap();
    let plan = KernelPlan::from_schedule(&g, &schedule).unwrap();
    let options = ExecOptions { shaders: parallax_passes::shader_library(), ..ExecOptions::default() };
    let mut exec = Executor::new(&ctx, plan, options).unwrap();
    parallax_passes::upload_scene(&mut exec, &gpu_scene).unwrap();
    match exec.run_frame() {
        Err(BackendError::KernelMisuse { kernel, instance: Some(InstanceId(0)), .. }) => {
            assert_eq!(kernel, "path_trace")
        }
        other => panic!("expected KernelMisuse, got {other:?}"),
    }

    // Textures: the byte count must match the size, and the array has a fixed capacity.
    let texel = [255u8; 4];
    match exec.upload_textures(&[TextureData { width: 2, height: 1, rgba8: &texel }]) {
        Err(BackendError::TextureData { width: 2, height: 1, bytes: 4, .. }) => {}
        other => panic!("expected TextureData, got {other:?}"),
    }
    let many = vec![TextureData { width: 1, height: 1, rgba8: &texel }; MAX_TEXTURES as usize + 1];
    match exec.upload_textures(&many) {
        Err(BackendError::TooManyTextures { count, max: MAX_TEXTURES }) => assert_eq!(count, many.len()),
        other => panic!("expected TooManyTextures, got {other:?}"),
    }
    drop(exec);
    ctx.check_validation().unwrap();
}

#[test]
fn a_user_shader_replaces_the_pass_shader_of_its_name() {
    // The benchmark's fill shader under the name `pt_trace`: the tracer looks in the user's
    // library before the passes', so its push-constant block is the one checked, and refused.
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let ctx = common::context(1);
    let fill = parallax_backend::spirv("bench_fill").unwrap();
    let user = ShaderLibrary::new().with_spirv("pt_trace", fill).unwrap();
    let trace = parallax_passes::banded_trace_plan(1, (8, 8), 1, 1).unwrap();
    let options = ExecOptions { shaders: user, ..ExecOptions::default() };
    let mut tracer = LightFieldRenderer::tracing(&ctx, trace, &GpuScene::new(&scene, &bvh), options).unwrap();
    let views = common::views(&scene, 1, 8, 8);
    match tracer.trace(&scene, &views, &TraceSettings::default()) {
        Err(PassError::Backend(BackendError::PushConstantLayout { shader, .. })) => assert_eq!(shader, "pt_trace"),
        other => panic!("expected the user's pt_trace to be refused, got {other:?}"),
    }
    drop(tracer);
    // Without it, the passes' own.
    let trace = parallax_passes::banded_trace_plan(1, (8, 8), 1, 1).unwrap();
    let mut tracer =
        LightFieldRenderer::tracing(&ctx, trace, &GpuScene::new(&scene, &bvh), ExecOptions::default()).unwrap();
    assert_eq!(tracer.trace(&scene, &views, &TraceSettings::default()).unwrap()[0].len(), 64);
}
