//! The reconstruction pipeline's reprojection on lavapipe (validation on), on the default scene:
//! with every view a source it is plain path tracing bit for bit; a view reprojected from a
//! source at its own position misses no diffuse pixel; misses grow with the baseline; and what
//! is reprojected is an unbiased estimate of what path tracing the same pixels gives.

mod common;

use parallax_backend::{ExecutionPlan, KernelGraph};
use parallax_graph::{AssignStrategy, LayoutSpec, LightField, Plan, PlanConfig, Scheme, compile};
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_passes::pipeline::{GbufferSource, PipelineConfig, PipelineKind, declare_pipeline};
use parallax_passes::renderer::LightFieldRenderer;
use parallax_passes::reproject::ReprojectionTolerances;
use parallax_scene::gpu::GpuScene;
use parallax_scene::{SceneBvh, TraceSettings, default_scene};

const SIZE: u32 = 32;

/// One rendered light field: per view, radiance texels, and for targets the hole mask and
/// whether each pixel is a diffuse surface.
struct Rendered {
    plan: Plan,
    radiance: Vec<Vec<[f32; 4]>>,
    holes: Vec<Option<Vec<u32>>>,
    diffuse: Vec<Vec<bool>>,
}

fn texels(bytes: &[u8]) -> Vec<[f32; 4]> {
    bytes.chunks_exact(16).map(bytemuck::pod_read_unaligned).collect()
}

fn render(cols: u32, spacing: f64, devices: u32, kind: PipelineKind, spp: u32) -> Rendered {
    render_with(cols, spacing, devices, kind, spp, GbufferSource::FirstHits)
}

fn render_with(
    cols: u32,
    spacing: f64,
    devices: u32,
    kind: PipelineKind,
    spp: u32,
    gbuffer: GbufferSource,
) -> Rendered {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let rig = rig_of(&scene.default_camera(), scene.bounds().center(), None);
    let lf = LightField::new(LayoutSpec::Grid { cols, rows: 1 }, Some(spacing), Some((SIZE, SIZE)), rig).unwrap();
    let config = PlanConfig { devices, scheme: Scheme::MultiSource, assign: AssignStrategy::Compact, sources: None };
    let plan = Plan::new(&lf, &config).unwrap();
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    let config =
        PipelineConfig { kind, gbuffer, tolerances: ReprojectionTolerances::default(), denoise: false, exposure: 1.0 };
    let handles = declare_pipeline(&mut graph, &config).unwrap();
    graph.export(&handles.radiance);
    let schedule = compile(&graph, &plan).unwrap();
    let exec = ExecutionPlan::from_schedule(&graph, &schedule).unwrap();
    let ctx = common::context(devices as usize);
    let views = lightfield_views(&lf);
    let mut renderer = LightFieldRenderer::new(&ctx, exec, views.len() as u32, &GpuScene::new(&scene, &bvh)).unwrap();
    let settings = TraceSettings { spp, max_depth: 4, ..Default::default() };
    renderer.submit(&scene, &views, &settings).unwrap();
    renderer.finish().unwrap();
    let mut out = Rendered { plan, radiance: Vec::new(), holes: Vec::new(), diffuse: Vec::new() };
    for v in 0..views.len() as u32 {
        out.radiance.push(texels(&renderer.read("radiance", v).unwrap()));
        let is_target = !out.plan.topology.is_source[v as usize] && kind == PipelineKind::Reproject;
        out.holes
            .push(is_target.then(|| bytemuck::cast_slice::<u8, u32>(&renderer.read("holes", v).unwrap()).to_vec()));
        if !is_target {
            out.diffuse.push(Vec::new()); // only reprojection reads the G-buffer (else culled)
            continue;
        }
        let t = ReprojectionTolerances::default();
        let albedo = texels(&renderer.read("albedo_roughness", v).unwrap());
        let normal = texels(&renderer.read("normal_metallic", v).unwrap());
        let position = texels(&renderer.read("position_depth", v).unwrap());
        out.diffuse.push(
            (0..albedo.len())
                .map(|i| position[i][3] > 0.0 && albedo[i][3] >= t.min_roughness && normal[i][3] <= t.max_metallic)
                .collect(),
        );
    }
    drop(renderer);
    ctx.check_validation().unwrap();
    out
}

/// Fraction of a target's diffuse surface pixels that could not be reprojected (disocclusions).
fn disoccluded(r: &Rendered, v: usize) -> f64 {
    let holes = r.holes[v].as_ref().unwrap();
    let diffuse = r.diffuse[v].iter().filter(|&&d| d).count();
    let missed = holes.iter().zip(&r.diffuse[v]).filter(|&(&h, &d)| d && h == 1).count();
    missed as f64 / diffuse.max(1) as f64
}

fn targets(r: &Rendered) -> Vec<usize> {
    (0..r.radiance.len()).filter(|&v| !r.plan.topology.is_source[v]).collect()
}

#[test]
fn with_every_view_a_source_the_pipeline_is_path_tracing_bit_for_bit() {
    let reprojecting = render(2, 0.02, 2, PipelineKind::Reproject, 2);
    assert!(reprojecting.plan.topology.is_source.iter().all(|&s| s), "2 views on 2 devices: both are sources");
    let traced = render(2, 0.02, 1, PipelineKind::PathTrace, 2);
    assert_eq!(reprojecting.radiance, traced.radiance);
    assert!(traced.radiance[0].iter().any(|t| t[3] == 1.0), "the camera sees the scene");
}

#[test]
fn a_view_reprojected_from_its_own_position_misses_no_diffuse_pixel() {
    let r = render(2, 0.0, 1, PipelineKind::Reproject, 1);
    let t = targets(&r);
    assert_eq!(t.len(), 1);
    assert!(r.diffuse[t[0]].iter().filter(|&&d| d).count() > 100, "the default scene is mostly diffuse");
    assert_eq!(disoccluded(&r, t[0]), 0.0);
    // Glossy and metal surfaces are never reprojected: every one of their pixels is a hole.
    let holes = r.holes[t[0]].as_ref().unwrap();
    assert!(holes.iter().zip(&r.diffuse[t[0]]).all(|(&h, &d)| d || h == 1));
    assert!(r.radiance[t[0]].iter().flatten().all(|c| c.is_finite()));
}

#[test]
fn missing_pixels_grow_with_the_baseline() {
    // Three views, the middle one the source: the outer targets sit one spacing away.
    let ratios: Vec<f64> = [0.001, 0.005, 0.02, 0.1]
        .iter()
        .map(|&spacing| {
            let r = render(3, spacing, 1, PipelineKind::Reproject, 1);
            let t = targets(&r);
            t.iter().map(|&v| disoccluded(&r, v)).sum::<f64>() / t.len() as f64
        })
        .collect();
    assert!(ratios.windows(2).all(|w| w[0] <= w[1]), "non-decreasing with spacing: {ratios:?}");
    assert!(ratios[0] < 0.02, "1 mm misses under 2 % of the diffuse pixels: {ratios:?}");
    assert!(ratios[3] > ratios[0], "100 mm misses more than 1 mm: {ratios:?}");
}

#[test]
fn reprojected_pixels_match_path_tracing_the_same_pixels_on_average() {
    let spp = 64;
    let reprojected = render(3, 0.02, 1, PipelineKind::Reproject, spp);
    let traced = render(3, 0.02, 1, PipelineKind::PathTrace, spp);
    for v in targets(&reprojected) {
        let holes = reprojected.holes[v].as_ref().unwrap();
        let (mut a, mut b, mut n) = (0.0f64, 0.0f64, 0usize);
        for (i, &h) in holes.iter().enumerate() {
            if h == 0 {
                a += reprojected.radiance[v][i][..3].iter().map(|&c| c as f64).sum::<f64>();
                b += traced.radiance[v][i][..3].iter().map(|&c| c as f64).sum::<f64>();
                n += 1;
            }
        }
        assert!(n > 300, "view {v}: {n} reprojected pixels");
        let relative = (a - b).abs() / b;
        assert!(relative < 0.02, "view {v}: reprojected mean {a} vs traced {b} over {n} pixels ({relative:.4})");
    }
}

#[test]
fn a_wide_baseline_leaves_no_unfilled_pixel_after_hole_filling() {
    // 10 cm between neighbours: the outer targets see plenty the source does not.
    let reprojected = render(3, 0.1, 1, PipelineKind::Reproject, 1);
    let traced = render(3, 0.1, 1, PipelineKind::PathTrace, 1);
    for v in targets(&reprojected) {
        let holes = reprojected.holes[v].as_ref().unwrap();
        let filled: Vec<usize> = (0..holes.len()).filter(|&i| holes[i] == 1).collect();
        assert!(filled.len() > 50, "view {v}: a wide baseline makes holes ({})", filled.len());
        for i in filled {
            // Hole filling path traces exactly the pixel path tracing would: same bits.
            assert_eq!(reprojected.radiance[v][i], traced.radiance[v][i], "view {v}, pixel {i}");
        }
        assert!(reprojected.radiance[v].iter().flatten().all(|c| c.is_finite()));
    }
}

#[test]
fn the_raster_gbuffer_reprojects_like_first_hits() {
    // A view at its source's position: with either G-buffer no diffuse pixel is missed, and
    // the raster one's hole pixels are path traced to the same bits as path tracing them.
    let raster = render_with(2, 0.0, 1, PipelineKind::Reproject, 1, GbufferSource::Raster);
    let t = targets(&raster);
    assert!(raster.diffuse[t[0]].iter().filter(|&&d| d).count() > 100);
    assert!(disoccluded(&raster, t[0]) < 0.01, "{}", disoccluded(&raster, t[0]));
    let wide = render_with(3, 0.1, 1, PipelineKind::Reproject, 1, GbufferSource::Raster);
    let traced = render(3, 0.1, 1, PipelineKind::PathTrace, 1);
    for v in targets(&wide) {
        let holes = wide.holes[v].as_ref().unwrap();
        for i in (0..holes.len()).filter(|&i| holes[i] == 1) {
            assert_eq!(wide.radiance[v][i], traced.radiance[v][i], "view {v}, pixel {i}");
        }
        assert!(wide.radiance[v].iter().flatten().all(|c| c.is_finite()));
    }
}
