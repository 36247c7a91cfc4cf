//! `parallax render`: path trace every view of a light field of a scene, spread over devices by
//! the planner, finished views gathered on device 0; one EXR per view and a PNG contact sheet.
//!
//! Every view is path traced in full: this is the reference rendering of the light field (no
//! reprojection), the ground truth that reprojecting pipelines are compared against.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use clap::Args;
use parallax_backend::{
    Context as VkContext, ContextDesc, EventKind, ExecutionPlan as ExecPlan, FrameReport, KernelGraph, chrome_trace,
};
use parallax_graph::{LayoutSpec, LightField, Plan, PlanConfig, PlanSummary, Rig};
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_passes::{GpuTracer, PATH_TRACE, declare_trace, to_pixel_sample};
use parallax_scene::gpu::GpuScene;
use parallax_scene::output::{ExrLayers, write_contact_sheet, write_exr};
use parallax_scene::{Frame, SceneBvh, TraceSettings, View, load_scene};

use crate::budget::TraceWork;
use crate::cmd_plan::compile_checked;
use crate::cmd_trace::warn_if_unlit;
use crate::logging::{result, spinner};
use crate::options::{
    AssignArg, DeviceArgs, Resolution, SchemeArg, assignment, parse_exposure, parse_focus, parse_layout,
    parse_resolution, parse_spacing,
};
use crate::outputs::{Format, Output, Sink, Staged, check, parse_sink, stage};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// glTF file (.gltf/.glb) or `default` for the embedded default scene.
    #[arg(long, default_value = "default")]
    scene: String,
    /// Light-field layout: multiscopic, nelf or WxH (at most 4096 views).
    #[arg(long, default_value = "8x4", value_parser = parse_layout)]
    lf: LayoutSpec,
    /// Spacing between neighbouring views in metres (default 0.001, the paper's).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_spacing)]
    spacing: Option<f64>,
    /// Per-view resolution WxH (default: the preset's, 512x512 for grids).
    #[arg(long, value_name = "WxH", value_parser = parse_resolution)]
    resolution: Option<Resolution>,
    /// Distance of the zero-disparity plane from the rig camera (default: to the scene centre).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_focus)]
    focus: Option<f64>,
    #[command(flatten)]
    devices: DeviceArgs,
    /// Partitioning scheme.
    #[arg(long, value_enum, default_value_t = SchemeArg::MultiSource)]
    scheme: SchemeArg,
    /// How views are grouped into sets (multi-source only) [default: compact]
    #[arg(long, value_enum)]
    assign: Option<AssignArg>,
    /// Samples per pixel.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    spp: u32,
    /// Maximum number of scattering events per path (0..=1024).
    #[arg(long, allow_negative_numbers = true, default_value_t = 6, value_parser = clap::value_parser!(u32).range(0..=1024))]
    max_depth: u32,
    /// Folder for view_NNN.exr, lightfield.png and render.json (created if missing). Every
    /// view_NNN.exr already there that this run does not write is removed, so the folder
    /// holds exactly the views render.json lists; nothing changes there if the run fails.
    #[arg(long, default_value = "out/lightfield")]
    out_dir: PathBuf,
    /// Exposure multiplier for the contact sheet (> 0).
    #[arg(long, allow_negative_numbers = true, default_value = "1", value_parser = parse_exposure)]
    exposure: f32,
    /// Write a Chrome trace-event JSON of the frame (open in Perfetto or chrome://tracing;
    /// `-` = stdout).
    #[arg(long, value_parser = parse_sink)]
    trace: Option<Sink>,
}

pub fn run(args: RenderArgs) -> Result<()> {
    let assign = assignment(args.scheme, args.assign)?;
    let sheet = args.out_dir.join("lightfield.png");
    let render_json = args.out_dir.join("render.json");
    check_outputs(&args.out_dir, &sheet, &render_json, args.trace.as_ref())?;
    let settings = TraceSettings { spp: args.spp, max_depth: args.max_depth, ..Default::default() };
    settings.validate()?;
    // The layout's size is known without the scene: check what it costs before loading one.
    let sized = LightField::new(args.lf, args.spacing, args.resolution.map(Resolution::pair), Rig::default())?;
    let work = TraceWork { views: sized.len() as u64, width: sized.width, height: sized.height, spp: args.spp };
    work.check_duration()?;
    work.check_host()?;
    let scene = load_scene(&args.scene).with_context(|| format!("loading --scene {}", args.scene))?;
    warn_if_unlit(&scene);
    let rig = rig_of(&scene.default_camera(), scene.bounds().center(), args.focus);
    let lf = LightField::new(args.lf, args.spacing, args.resolution.map(Resolution::pair), rig)?;
    let selection = args.devices.selection();
    let config = PlanConfig { devices: selection.count() as u32, scheme: args.scheme.into(), assign, sources: None };
    let plan = Plan::new(&lf, &config)?;
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    declare_trace(&mut graph, None);
    let schedule = compile_checked(&graph, &plan)?;
    let summary = PlanSummary::new(&lf, &plan, &schedule);

    let bvh = SceneBvh::build(&scene);
    let context = VkContext::new(&ContextDesc::from_env(selection))?;
    tracing::info!("{}", context.to_string().trim_end());
    work.check_devices(&context)?;
    let exec_plan = ExecPlan::from_schedule(&graph, &schedule)?;
    let mut tracer = GpuTracer::new(&context, exec_plan, &GpuScene::new(&scene, &bvh))?;
    let views: Vec<View> = lightfield_views(&lf);
    let progress = spinner(format!("tracing {} views of {}x{} at {} spp", views.len(), lf.width, lf.height, args.spp));
    let started = Instant::now();
    let pixels = tracer.render(&scene, &views, &settings)?;
    let wall = started.elapsed();
    progress.finish_and_clear();
    let reports = tracer.executor().take_reports();
    drop(tracer);
    context.check_validation()?;

    let frames: Vec<Frame> = pixels
        .iter()
        .zip(&views)
        .map(|(p, v)| Frame { width: v.width, height: v.height, pixels: p.iter().map(to_pixel_sample).collect() })
        .collect();
    // Everything is staged before anything is put in place, and render.json goes last: a
    // failure (or Ctrl-C) at any point leaves the folder as it was or complete.
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create --out-dir {}", args.out_dir.display()))?;
    let mut staged: Vec<Staged> = Vec::new();
    for (frame, view) in frames.iter().zip(&views) {
        let path = args.out_dir.join(view_file_name(view.index));
        staged.push(stage(&path, |tmp| {
            write_exr(tmp, frame, ExrLayers::default()).with_context(|| format!("cannot write {}", path.display()))
        })?);
    }
    staged.push(stage(&sheet, |tmp| {
        write_contact_sheet(tmp, &frames.iter().collect::<Vec<_>>(), lf.cols, args.exposure)
            .with_context(|| format!("cannot write {}", sheet.display()))
    })?);
    let timing = timing_summary(&reports);
    let json = serde_json::json!({ "plan": &summary, "spp": args.spp, "max_depth": args.max_depth,
                                   "wall_ms": wall.as_secs_f64() * 1e3, "timing": &timing, "frames": &reports });
    let json_file = crate::outputs::stage_json(&render_json, &json)?;
    let trace = args.trace.as_ref().map(|_| chrome_trace(&reports, &context.device_infos()));
    for s in staged {
        s.commit()?;
    }
    remove_stale_views(&args.out_dir, lf.len())?;
    if let (Some(sink), Some(trace)) = (&args.trace, &trace) {
        crate::outputs::write_json(sink, trace)?;
    }
    json_file.commit()?;
    let say = |line: String| result(matches!(args.trace, Some(Sink::Stdout)), &line);
    say(format!(
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
    ));
    say(format!("wrote {} view EXRs, {} and {}", lf.len(), sheet.display(), render_json.display()));
    Ok(())
}

fn view_file_name(index: u32) -> String {
    format!("view_{index:03}.exr")
}

/// Checks the outputs before any work. The folder may not exist yet (it is created when the
/// views are written), but the nearest folder above it must be writable.
fn check_outputs(out_dir: &Path, sheet: &Path, render_json: &Path, trace: Option<&Sink>) -> Result<()> {
    if out_dir.exists() && !out_dir.is_dir() {
        bail!("--out-dir {} is a file: give a folder", out_dir.display());
    }
    let existing = out_dir.ancestors().find(|a| a.as_os_str().is_empty() || a.exists()).unwrap_or(Path::new("."));
    let existing = if existing.as_os_str().is_empty() { Path::new(".") } else { existing };
    if !existing.is_dir() {
        bail!("--out-dir {}: {} is not a folder", out_dir.display(), existing.display());
    }
    tempfile::NamedTempFile::new_in(existing)
        .with_context(|| format!("--out-dir {}: folder {} is not writable", out_dir.display(), existing.display()))?;
    let sheet_sink = Sink::File(sheet.to_path_buf());
    let json_sink = Sink::File(render_json.to_path_buf());
    let mut outputs = Vec::new();
    if out_dir.is_dir() {
        outputs.push(Output { flag: "--out-dir", sink: &sheet_sink, format: Format::Png });
        outputs.push(Output { flag: "--out-dir", sink: &json_sink, format: Format::Json });
    }
    if let Some(sink) = trace {
        if let Sink::File(path) = sink
            && path.parent().is_some_and(|p| p == out_dir)
            && path.file_name().and_then(|n| n.to_str()).is_some_and(|n| n == "render.json" || n.starts_with("view_"))
        {
            bail!("--trace {} would overwrite an output of --out-dir: give it another name", path.display());
        }
        outputs.push(Output { flag: "--trace", sink, format: Format::Json });
    }
    check(&outputs)
}

/// Removes `view_NNN.exr` files of an earlier run that this run of `views` views did not write.
fn remove_stale_views(out_dir: &Path, views: usize) -> Result<()> {
    let entries = std::fs::read_dir(out_dir).with_context(|| format!("cannot list --out-dir {}", out_dir.display()))?;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(index) = name.to_str().and_then(parse_view_file_name) else { continue };
        if index as usize >= views && entry.file_type().is_ok_and(|t| t.is_file()) {
            std::fs::remove_file(entry.path())
                .with_context(|| format!("cannot remove stale {}", entry.path().display()))?;
            tracing::info!("removed {} of an earlier run", entry.path().display());
        }
    }
    Ok(())
}

/// The view index of a file name this command writes (`view_007.exr` → 7).
fn parse_view_file_name(name: &str) -> Option<u32> {
    let digits = name.strip_prefix("view_")?.strip_suffix(".exr")?;
    if digits.len() < 3 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let index: u32 = digits.parse().ok()?;
    (view_file_name(index) == name).then_some(index)
}

/// The rig is the scene's camera; the zero-disparity plane goes through the scene's centre
/// unless `--focus` says otherwise.
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
