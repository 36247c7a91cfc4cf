//! `parallax render`: path trace every view of a light field of a scene, spread over devices by
//! the planner, finished views gathered on device 0; one EXR per view and a PNG contact sheet.
//!
//! Every view is path traced in full: this is the reference rendering of the light field (no
//! reprojection), the ground truth that reprojecting pipelines are compared against.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context as _, Result};
use clap::Args;
use glam::Vec2;
use parallax_backend::{
    Context as VkContext, ContextDesc, EventKind, FrameReport, Plan as ExecPlan, chrome_trace, write_json,
};
use parallax_graph::{
    Graph, LayoutSpec, LightField, Plan, PlanConfig, PlanSummary, Rig, ViewId, lightfield::parse_pair,
};
use parallax_passes::{GpuTracer, PATH_TRACE, declare_trace, to_pixel_sample, trace_kernels};
use parallax_scene::gpu::GpuScene;
use parallax_scene::output::{ExrLayers, write_contact_sheet, write_exr};
use parallax_scene::{Camera, Frame, Scene, SceneBvh, TraceSettings, View, load_scene};

use crate::cmd_backend::DeviceArgs;
use crate::cmd_plan::compile_checked;

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// glTF file (.gltf/.glb) or `default` for the embedded default scene.
    #[arg(long, default_value = "default")]
    scene: String,
    /// Light-field layout: multiscopic, nelf or WxH.
    #[arg(long, default_value = "8x4")]
    lf: String,
    /// Spacing between neighbouring views in metres (default 0.001, the paper's).
    #[arg(long, allow_negative_numbers = true)]
    spacing: Option<f64>,
    /// Per-view resolution WxH (default: the preset's, 512x512 for grids).
    #[arg(long)]
    resolution: Option<String>,
    /// Distance of the zero-disparity plane from the rig camera (default: to the scene centre).
    #[arg(long, allow_negative_numbers = true)]
    focus: Option<f64>,
    #[command(flatten)]
    devices: DeviceArgs,
    /// Partitioning scheme: multi-source, fine-sources or fine-all.
    #[arg(long, default_value = "multi-source")]
    scheme: String,
    /// How views are grouped into sets: round-robin, contiguous or compact.
    #[arg(long, default_value = "compact")]
    assign: String,
    /// Samples per pixel.
    #[arg(long, default_value_t = 1)]
    spp: u32,
    /// Maximum number of scattering events per path.
    #[arg(long, default_value_t = 6)]
    max_depth: u32,
    /// Folder for view_NNN.exr, lightfield.png and render.json (created if missing).
    #[arg(long, default_value = "out/lightfield")]
    out_dir: PathBuf,
    /// Exposure multiplier for the contact sheet.
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// Write a Chrome trace-event JSON of the frame (open in Perfetto or chrome://tracing).
    #[arg(long)]
    trace: Option<PathBuf>,
}

pub fn run(args: RenderArgs) -> Result<()> {
    let spec: LayoutSpec = args.lf.parse()?;
    let resolution = match &args.resolution {
        Some(r) => Some(parse_pair(r).with_context(|| format!("--resolution '{r}' is not WxH (e.g. 256x192)"))?),
        None => None,
    };
    let settings = TraceSettings { spp: args.spp, max_depth: args.max_depth, ..Default::default() };
    settings.validate()?;
    let scene = load_scene(&args.scene).with_context(|| format!("loading scene '{}'", args.scene))?;
    let rig = rig_of(&scene, args.focus)?;
    let lf = LightField::new(spec, args.spacing, resolution, rig)?;
    let selection = args.devices.selection();
    let config = PlanConfig {
        devices: selection.count() as u32,
        scheme: args.scheme.parse()?,
        assign: args.assign.parse()?,
        sources: None,
    };
    let plan = Plan::new(&lf, &config)?;
    let mut graph = Graph::new(plan.topology.clone());
    declare_trace(&mut graph, None);
    let schedule = compile_checked(&graph, &plan)?;
    let summary = PlanSummary::new(&lf, &plan, &schedule);

    let bvh = SceneBvh::build(&scene);
    let context = VkContext::new(&ContextDesc::from_env(selection))?;
    eprint!("{context}");
    let exec_plan = ExecPlan::from_schedule(&schedule)?;
    let mut tracer = GpuTracer::new(&context, exec_plan, trace_kernels(None), &GpuScene::new(&scene, &bvh))?;
    let views: Vec<View> = lf
        .views()
        .map(|v| View { camera: camera_of(&lf, v), width: lf.width, height: lf.height, index: v.0 })
        .collect();
    let started = Instant::now();
    let pixels = tracer.render(&scene, &views, &settings)?;
    let wall = started.elapsed();
    let reports = tracer.executor().take_reports();
    drop(tracer);
    context.check_validation()?;

    let frames: Vec<Frame> = pixels
        .iter()
        .zip(&views)
        .map(|(p, v)| Frame { width: v.width, height: v.height, pixels: p.iter().map(to_pixel_sample).collect() })
        .collect();
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create --out-dir {}", args.out_dir.display()))?;
    for (frame, view) in frames.iter().zip(&views) {
        write_exr(&args.out_dir.join(format!("view_{:03}.exr", view.index)), frame, ExrLayers::default())?;
    }
    let sheet = args.out_dir.join("lightfield.png");
    write_contact_sheet(&sheet, &frames.iter().collect::<Vec<_>>(), lf.cols, args.exposure)?;
    let timing = timing_summary(&reports);
    write_json(
        &args.out_dir.join("render.json"),
        &serde_json::json!({ "plan": &summary, "spp": args.spp, "max_depth": args.max_depth,
                             "wall_ms": wall.as_secs_f64() * 1e3, "timing": &timing, "frames": &reports }),
    )?;
    if let Some(path) = &args.trace {
        write_json(path, &chrome_trace(&reports, &context.device_infos()))?;
    }
    println!(
        "rendered {} views of {}x{} at {} spp ({}, {} device(s)) in {:.1} ms wall; GPU span {:.2} ms, path_trace per device {:?} ms, {} gather copies",
        lf.len(),
        lf.width,
        lf.height,
        args.spp,
        summary.scheme,
        summary.devices,
        wall.as_secs_f64() * 1e3,
        timing.gpu_span_ms,
        timing.path_trace_ms_per_device,
        summary.gather_copies
    );
    println!("wrote {} view EXRs, {} and render.json to {}", lf.len(), sheet.display(), args.out_dir.display());
    Ok(())
}

/// The rig is the scene's camera; the zero-disparity plane goes through the scene's centre
/// unless `--focus` says otherwise.
pub(crate) fn rig_of(scene: &Scene, focus: Option<f64>) -> Result<Rig> {
    let camera = scene.default_camera();
    let to_centre = (scene.bounds().center() - camera.eye).dot(camera.forward.normalize()) as f64;
    let focus_distance = focus.unwrap_or(if to_centre > 0.0 { to_centre } else { 1.0 });
    Ok(Rig {
        eye: camera.eye.as_dvec3(),
        forward: camera.forward.as_dvec3(),
        up: camera.up.as_dvec3(),
        yfov: camera.yfov as f64,
        focus_distance,
    })
}

/// View `v`'s camera for the renderer. The scene's camera adds its shift to the NDC point (the
/// planner's subtracts it), hence the sign.
pub(crate) fn camera_of(lf: &LightField, v: ViewId) -> Camera {
    let c = lf.camera(v);
    Camera {
        eye: c.eye.as_vec3(),
        forward: c.forward.as_vec3(),
        up: c.up.as_vec3(),
        yfov: c.yfov as f32,
        shift: -Vec2::new(c.ndc_shift.x as f32, c.ndc_shift.y as f32),
    }
}

#[derive(serde::Serialize)]
struct TimingSummary {
    gpu_span_ms: f64,
    path_trace_ms_per_device: Vec<f64>,
    gather_ms: f64,
}

fn timing_summary(reports: &[FrameReport]) -> TimingSummary {
    let events: Vec<_> = reports.iter().flat_map(|r| &r.events).collect();
    let devices = events.iter().map(|e| e.device + 1).max().unwrap_or(0);
    let ms = |filter: &dyn Fn(&&&parallax_backend::TimedEvent) -> bool| {
        events.iter().filter(filter).map(|e| e.end_ns.saturating_sub(e.start_ns)).sum::<u64>() as f64 / 1e6
    };
    TimingSummary {
        gpu_span_ms: reports.iter().map(|r| r.gpu_span_ns).sum::<u64>() as f64 / 1e6,
        path_trace_ms_per_device: (0..devices)
            .map(|d| ms(&|e| e.device == d && e.kind == EventKind::Pass && e.name == PATH_TRACE))
            .collect(),
        gather_ms: ms(&|e| e.kind != EventKind::Pass),
    }
}
