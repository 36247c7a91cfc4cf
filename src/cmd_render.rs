//! `parallax render`: a light field of a scene through the paper's reconstruction pipeline
//! (`--pipeline reproject`: G-buffer, path tracing of the sources, reprojection of the targets,
//! hole filling, SVGF, tonemapping) or with every view path traced (`--pipeline path-trace`, the
//! baseline), over N devices under any of the three schemes, for F frames of a camera dolly.
//! Writes the last frame's views (EXR, linear radiance after denoising; PNG at one exposure for
//! the whole light field), the contact sheet, `viewer.html` (the views in a browser, with
//! parallax), an optional Looking Glass quilt and wiggle, and render.json with the paper's
//! Table 1 / Table 4 measures and the `setup` that comparisons check.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use clap::{Args, ValueEnum};
use glam::Vec3;
use parallax_backend::{
    Barriers, Context as VkContext, ContextDesc, ExecOptions, ExecutionPlan, FaultInjection, Timing, chrome_trace,
};
use parallax_graph::{LightField, Rig};
use parallax_passes::camera::lightfield_views;
use parallax_passes::pipeline::PipelineKind;
use parallax_passes::renderer::LightFieldRenderer;
use parallax_scene::gpu::GpuScene;
use parallax_scene::output::{ExrLayers, write_exr_with};
use parallax_scene::{Camera, Frame, PixelSample, Scene, SceneBvh, TraceSettings, View};

use crate::budget::TraceWork;
use crate::logging::{bar, result};
use crate::options::{DeviceArgs, Exposure, parse_exposure};
use crate::outputs::{Format, Output, Sink, Staged, check, parse_sink, stage};
use crate::pipeline_args::{DotArgs, PipelineArgs};
use crate::render_pictures::{display_images, gpu_exposure, stage_pictures, view_png_name};
use crate::render_report::{MissingPixels, missing_pixels, stage_table, timings};
use crate::run_setup::{CameraSetup, Setup};
use crate::scene_args::{DepthArgs, LightFieldArgs, SceneArgs};

/// `--barriers`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BarrierArg {
    EveryOp,
    Tracked,
}

/// `--timing`: what the GPU timestamp pairs cover.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TimingArg {
    PerOp,
    PerStage,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Repeat a run: a render.json (its `run`) or a TOML run file with the same keys (`spp = 4`,
    /// `lf = "8x4"`, `still = true`, ...). Flags given here as well win over the file's.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    light_field: LightFieldArgs,
    #[command(flatten)]
    devices: DeviceArgs,
    #[command(flatten)]
    pipeline: PipelineArgs,
    /// Samples per pixel of path tracing (sources, holes, or every view).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: u32,
    #[command(flatten)]
    depth: DepthArgs,
    /// Measured frames (the camera dollies across the scene over the measured frames; one frame
    /// is a still camera).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Frames submitted before the host waits for the oldest: the host prepares and submits the
    /// next frames while the GPU runs this one.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=8))]
    frames_in_flight: u32,
    /// Frames rendered before measuring, at the first measured frame's camera (timings and
    /// outputs ignore them). The first frame pays for pipeline creation and first-use costs
    /// (seconds on some drivers), so measuring from frame 0 with `--warmup 0` times those too.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    warmup: u32,
    /// Keep the camera still over the frames (no dolly, no glTF animation): what accuracy
    /// against a reference of the same camera needs.
    #[arg(long)]
    still: bool,
    /// Also write the views of every N-th measured frame to frame_FFFFF/ under --out-dir.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    save_every: Option<u32>,
    /// Folder for view_NNN.exr and view_NNN.png, lightfield.png, viewer.html and render.json
    /// (created if missing). Every view_NNN.exr or .png already there that this run does not
    /// write is removed, so the folder holds exactly the views render.json lists; nothing
    /// changes there if the run fails.
    #[arg(long, default_value = "out/lightfield")]
    out_dir: PathBuf,
    /// Exposure of the PNGs, sheet, quilt, wiggle and viewer: `auto` (the last frame's
    /// log-average luminance over every view mapped to 0.18, computed on the host from the
    /// read-back linear views; the value is written to render.json) or a multiplier > 0 (the
    /// GPU tonemap pass's own output).
    #[arg(long, allow_negative_numbers = true, default_value = "auto", value_parser = parse_exposure)]
    exposure: Exposure,
    /// Also write an animated PNG sweeping through the views of the middle row, there and back
    /// (for slides and READMEs).
    #[arg(long, value_name = "FILE.png")]
    wiggle: Option<PathBuf>,
    /// Add the hole mask, albedo, normal and depth to every view's EXR.
    #[arg(long)]
    layers: bool,
    /// Also write a Looking Glass quilt (lightfield_qs{cols}x{rows}a{aspect}.png).
    #[arg(long)]
    quilt: bool,
    /// Barriers between GPU ops: `tracked` (only where declared accesses conflict, so the
    /// instances of one pass for many views overlap; synchronisation validation reports false
    /// hazards with it), or `every-op`.
    #[arg(long, value_enum, default_value_t = BarrierArg::Tracked)]
    barriers: BarrierArg,
    /// What each GPU timestamp pair times: `per-stage` (each run of one pass's instances; with
    /// `--barriers tracked` the instances overlap, and stage and frame times are those of the
    /// overlapped run) or `per-op` (every pass instance and copy, for per-view timelines; a
    /// timestamp drains the queue on NVIDIA, so ops cannot overlap).
    #[arg(long, value_enum, default_value_t = TimingArg::PerStage)]
    timing: TimingArg,
    /// Write a Chrome trace-event JSON of the measured frames (open in Perfetto or
    /// chrome://tracing; `-` = stdout). With the default `--timing per-stage` an event is a
    /// run of one pass over many views; add `--timing per-op` for one event per view.
    #[arg(long, value_parser = parse_sink)]
    trace: Option<Sink>,
    #[command(flatten)]
    dot: DotArgs,
}

/// The rig of frame `f` of `total`: a smooth sideways dolly across 10 % of the scene's size,
/// eased in and out, centred on the starting camera.
fn dolly(camera: &Camera, scene: &Scene, f: u32, total: u32) -> Camera {
    if total <= 1 {
        return *camera;
    }
    let (right, _, _) = camera.basis();
    let t = f as f32 / (total - 1) as f32;
    let eased = 0.5 - 0.5 * (std::f32::consts::PI * t).cos();
    let offset: Vec3 = right * (0.1 * scene.bounds().diagonal() * (eased - 0.5));
    Camera { eye: camera.eye + offset, ..*camera }
}

impl RenderArgs {
    /// The run's settings as a run file for `--config`: every flag that shapes the pixels and
    /// the timing, by its long name, typed (outputs such as `--out-dir` are left to the command
    /// line).
    fn run_file(&self) -> serde_json::Value {
        use crate::bench_matrix::name_of as name;
        let (gpus, fake_devices) = self.devices.given();
        let camera = self.scene.camera.map(|c| c.numbers);
        let sun =
            self.scene.sun.map(|s| [s.to_sun.x, s.to_sun.y, s.to_sun.z, s.irradiance.x, s.angular_radius.to_degrees()]);
        let sky = self.scene.sky.map(|sky| match sky {
            parallax_scene::Sky::Constant(c) => c.to_array().to_vec(),
            parallax_scene::Sky::Gradient { zenith, horizon, ground } => {
                [zenith.to_array(), horizon.to_array(), ground.to_array()].concat()
            }
        });
        let (lf, p) = (&self.light_field, &self.pipeline);
        serde_json::json!({
            "scene": self.scene.scene, "camera": camera, "sun": sun, "no_sun": self.scene.no_sun, "sky": sky,
            "lf": crate::run_file::layout_spelling(&lf.layout.lf), "spacing": lf.layout.spacing,
            "resolution": lf.layout.resolution.map(|r| format!("{}x{}", r.width, r.height)), "focus": lf.focus,
            "gpus": gpus, "fake_devices": fake_devices,
            "pipeline": name(&p.pipeline), "scheme": name(&p.scheme), "assign": p.assign.map(|a| name(&a)),
            "sources_per_set": p.sources_per_set, "sources": p.sources.as_ref().map(|s| s.0.clone()),
            "no_denoise": p.no_denoise, "reprojection_tolerance": p.reprojection_tolerance, "spp": self.spp, "max_depth": self.depth.max_depth,
            "frames": self.frames, "warmup": self.warmup, "still": self.still, "save_every": self.save_every,
            "exposure": match self.exposure { Exposure::Auto => serde_json::json!("auto"), Exposure::Fixed(v) => serde_json::json!(v) },
            "layers": self.layers, "quilt": self.quilt, "gbuffer": name(&p.gbuffer), "barriers": name(&self.barriers),
            "timing": name(&self.timing),
        })
    }
}

pub fn run(args: RenderArgs) -> Result<()> {
    if let Some(file) = &args.config {
        return run(crate::run_file::render_args_of(file)?);
    }
    args.pipeline.check()?;
    let sheet = args.out_dir.join("lightfield.png");
    let render_json = args.out_dir.join("render.json");
    check_outputs(
        &args.out_dir,
        &sheet,
        &render_json,
        args.trace.as_ref(),
        args.dot.dot.as_ref(),
        args.wiggle.as_deref(),
    )?;
    let settings = TraceSettings { spp: args.spp, max_depth: args.depth.max_depth, ..Default::default() };
    settings.validate()?;
    let total_frames = args.warmup + args.frames;
    let sized = args.light_field.with_rig(Rig::default())?;
    crate::outputs::check_targets_in(&args.out_dir, (0..sized.len() as u32).map(view_file_name), "--out-dir")?;
    let work = TraceWork {
        views: sized.len() as u64 * u64::from(total_frames),
        width: sized.width,
        height: sized.height,
        spp: args.spp,
    };
    work.check_duration()?;
    // Memory is per frame: the frames reuse the same images.
    let one_frame = TraceWork { views: sized.len() as u64, ..work };
    one_frame.check_host()?;
    // Planned from the layout alone, as `plan` plans it: the schedule depends on the views'
    // positions in the rig plane, not on where the rig stands.
    let selection = args.devices.selection();
    let compiled = args.pipeline.compile(&sized, selection.count() as u32, gpu_exposure(args.exposure))?;
    let dot = args.dot.render(&compiled.schedule);
    let (plan, summary, kind) = (&compiled.plan, &compiled.summary, compiled.kind);

    let scene = args.scene.load()?;
    let mut written = vec![("--out-dir", render_json.as_path()), ("--out-dir", sheet.as_path())];
    if let Some(Sink::File(trace)) = &args.trace {
        written.push(("--trace", trace.as_path()));
    }
    crate::outputs::check_inputs(&written, &args.scene.inputs(&scene))?;
    let camera = args.scene.camera_or_default(&scene);
    let centre = scene.bounds().center();
    // The scene's own camera animation, spread over the measured frames; else a dolly (an
    // explicit --camera is a rig the user placed: it dollies too). Warm-up frames see the first
    // measured frame's camera, so one measured frame is a still camera whatever the warm-up.
    let animation = if args.scene.camera.is_none() { scene.camera_animation.clone() } else { None };
    let camera_at = |f: u32| {
        let m = f.saturating_sub(args.warmup);
        match &animation {
            _ if args.still => camera,
            Some(a) => a.camera_at(a.duration * m as f32 / args.frames.saturating_sub(1).max(1) as f32),
            None => dolly(&camera, &scene, m, args.frames),
        }
    };
    let lf_of = |f: u32| -> Result<LightField> { args.light_field.around(&camera_at(f), centre) };
    let lf = lf_of(0)?;

    let bvh = SceneBvh::build(&scene);
    let context = VkContext::new(&ContextDesc::from_env(selection))?;
    tracing::info!("{}", context.to_string().trim_end());
    one_frame.check_devices(&context)?;
    let exec_plan = ExecutionPlan::from_schedule(&compiled.graph, &compiled.schedule)?;
    let barriers = match args.barriers {
        BarrierArg::EveryOp => Barriers::EveryOp,
        BarrierArg::Tracked => Barriers::Tracked,
    };
    let timing = match args.timing {
        TimingArg::PerOp => Timing::PerOp,
        TimingArg::PerStage => Timing::PerStage,
    };
    let mut renderer = LightFieldRenderer::with_options(
        &context,
        exec_plan,
        lf.len() as u32,
        &GpuScene::new(&scene, &bvh),
        ExecOptions {
            barriers,
            timing,
            frames_in_flight: args.frames_in_flight as usize,
            fault: fault_from_env()?,
            ..ExecOptions::default()
        },
    )?;

    crate::outputs::create_folder(&args.out_dir)
        .with_context(|| format!("cannot create --out-dir {}", args.out_dir.display()))?;
    let _lock = crate::outputs::lock_folder(&args.out_dir, "--out-dir")?;
    let progress = bar(u64::from(total_frames));
    let started = Instant::now();
    let mut measured_from = None;
    let mut staged: Vec<Staged> = Vec::new();
    for f in 0..total_frames {
        if f == args.warmup {
            renderer.finish()?;
            renderer.reset_stats();
            // Only a trace needs every event of every frame; otherwise the statistics are all.
            renderer.keep_reports(args.trace.is_some());
            measured_from = Some(Instant::now());
        }
        let views = lightfield_views(&lf_of(f)?);
        renderer.submit(&scene, &views, &TraceSettings { frame: f, ..settings })?;
        let measured = f.checked_sub(args.warmup);
        if let (Some(every), Some(m)) = (args.save_every, measured)
            && m % every == 0
            && f + 1 < total_frames
        {
            renderer.finish()?;
            let folder = args.out_dir.join(format!("frame_{m:05}"));
            crate::outputs::create_folder(&folder).with_context(|| format!("cannot create {}", folder.display()))?;
            staged.extend(stage_views(
                &mut renderer,
                compiled.handles.linear_slot,
                &folder,
                &views,
                &extra_layers(&args, kind),
            )?);
        }
        progress.inc(1);
    }
    renderer.finish()?;
    let wall = measured_from.unwrap_or(started).elapsed();
    progress.finish_and_clear();
    let reports = renderer.take_reports();
    let prepare = renderer.prepare_ms().clone();
    let timing = timings(renderer.stats(), &prepare);
    let last_views = lightfield_views(&lf_of(total_frames - 1)?);

    // Everything is staged before anything is put in place, and render.json goes last: a
    // failure (or Ctrl-C) at any point leaves the folder as it was or complete.
    staged.extend(stage_views(
        &mut renderer,
        compiled.handles.linear_slot,
        &args.out_dir,
        &last_views,
        &extra_layers(&args, kind),
    )?);
    let (exposure, displays) =
        display_images(&mut renderer, compiled.handles.linear_slot, (lf.len() as u32, lf.width), args.exposure)?;
    let pictures = stage_pictures(&args.out_dir, &lf, &displays, args.quilt, args.wiggle.as_deref())?;
    drop(displays);
    let missing = match kind {
        PipelineKind::Reproject => {
            let holes: Vec<Option<Vec<u32>>> = (0..lf.len() as u32)
                .map(|v| {
                    if plan.topology.is_source[v as usize] {
                        return Ok(None);
                    }
                    let bytes = renderer.read_stitched("holes", v)?;
                    Ok(Some(bytemuck_words(&bytes)))
                })
                .collect::<Result<_, parallax_passes::PassError>>()?;
            missing_pixels(renderer.executor().plan(), &holes, lf.width)
        }
        PipelineKind::PathTrace => MissingPixels::default(),
    };
    drop(renderer);
    context.check_validation()?;

    let device_names: Vec<String> = context.device_infos().iter().map(|d| d.name.clone()).collect();
    let still = args.still || args.frames == 1;
    let last_lf = lf_of(total_frames - 1)?;
    let spacing = args.light_field.layout.spacing;
    let setup = Setup::new(
        &args.scene.scene,
        &scene,
        &camera_at(total_frames - 1),
        still,
        (&last_lf, spacing),
        args.depth.max_depth,
    )?;
    let json = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "scene": args.scene.scene,
        "camera": CameraSetup::of(&camera), "sun": &setup.sun, "sky": &setup.sky,
        "layout": { "lf": &lf.name, "views": lf.len(), "cols": lf.cols, "rows": lf.rows,
                    "width": lf.width, "height": lf.height, "spacing_m": setup.spacing_m, "focus_m": lf.rig.focus_distance },
        // The assignment groups views only under multi-source (`--assign` is refused otherwise).
        "pipeline": args.pipeline.pipeline, "scheme": summary.scheme, "assign": summary.assign,
        "sources_per_set": args.pipeline.sources_per_set, "denoise": !args.pipeline.no_denoise,
        "exposure": exposure, "exposure_mode": args.exposure.mode(), "still": still, "setup": &setup,
        "barriers": args.barriers, "timestamps": args.timing, "gbuffer": args.pipeline.gbuffer,
        "reprojection_tolerance": args.pipeline.reprojection_tolerance,
        "spp": args.spp, "max_depth": args.depth.max_depth, "frames": args.frames, "warmup": args.warmup,
        "frames_in_flight": args.frames_in_flight,
        "devices": device_names,
        "run": args.run_file(),
        "plan": summary,
        "wall_ms_per_frame": wall.as_secs_f64() * 1e3 / f64::from(args.frames),
        "timing": &timing,
        // Path tracing every view leaves no holes to count.
        "missing_pixels": (kind == PipelineKind::Reproject).then_some(&missing),
    });
    let viewer = pictures.stage_viewer(&args.out_dir, &lf, &json)?;
    let json_file = crate::outputs::stage_json(&render_json, &json)?;
    let trace = args.trace.as_ref().map(|_| chrome_trace(&reports, &context.device_infos()));
    for s in staged.into_iter().chain(pictures.staged) {
        s.commit()?;
    }
    viewer.commit()?;
    remove_stale_views(&args.out_dir, lf.len())?;
    if let (Some(sink), Some(trace)) = (&args.trace, &trace) {
        crate::outputs::write_json(sink, trace)?;
    }
    if let (Some(sink), Some(dot)) = (&args.dot.dot, &dot) {
        crate::outputs::write_bytes(sink, dot.as_bytes())?;
    }
    json_file.commit()?;
    crate::outputs::keep_folders();
    let stdout_taken = [&args.trace, &args.dot.dot].iter().any(|s| matches!(s, Some(Sink::Stdout)));
    let say = |line: String| result(stdout_taken, &line);
    say(stage_table(&timing));
    say(format!(
        "rendered {} views of {}x{} ({}, {}, {} device(s), {} spp, {} measured frame(s)): {:.2} ms per frame wall, GPU span {:.2} ms mean; missing pixels {:.2} %",
        lf.len(),
        lf.width,
        lf.height,
        crate::bench_matrix::name_of(&args.pipeline.pipeline),
        summary.scheme,
        summary.devices,
        args.spp,
        args.frames,
        wall.as_secs_f64() * 1e3 / f64::from(args.frames),
        timing.frame_gpu.mean_ms,
        100.0 * missing.overall
    ));
    say(format!(
        "wrote {} views (EXR and PNG at exposure {exposure:.4}, {}), {}, {} and {}",
        lf.len(),
        args.exposure.mode(),
        sheet.display(),
        args.out_dir.join("viewer.html").display(),
        render_json.display()
    ));
    Ok(())
}

/// `PARALLAX_FAULT=device-lost:F`: frame F's submission fails as on a lost GPU
/// (`FaultInjection::LoseDevice`), so tests can check what a failed run leaves behind.
fn fault_from_env() -> Result<Option<FaultInjection>> {
    let Ok(value) = std::env::var("PARALLAX_FAULT") else {
        return Ok(None);
    };
    match value.strip_prefix("device-lost:").and_then(|f| f.parse().ok()) {
        Some(frame) => Ok(Some(FaultInjection::LoseDevice { frame })),
        None => bail!("PARALLAX_FAULT={value}: the only fault is device-lost:FRAME (e.g. device-lost:1); unset it"),
    }
}

/// Which extra EXR layers the views get.
fn extra_layers(args: &RenderArgs, kind: PipelineKind) -> (bool, bool) {
    (args.layers, args.layers && kind == PipelineKind::Reproject)
}

fn bytemuck_words(bytes: &[u8]) -> Vec<u32> {
    bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

fn texels(bytes: &[u8]) -> Vec<[f32; 4]> {
    bytes
        .chunks_exact(16)
        .map(|b| std::array::from_fn(|i| f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])))
        .collect()
}

/// Stages `view_NNN.exr` of every view into `folder`: the linear radiance after denoising (or
/// after hole filling with --no-denoise), with `(layers, holes)`: albedo, normal and depth, and
/// the hole mask of targets as channel `holes.Y` (1 = the pixel was path traced by hole filling).
fn stage_views(
    renderer: &mut LightFieldRenderer,
    linear_slot: &str,
    folder: &Path,
    views: &[View],
    (layers, holes): &(bool, bool),
) -> Result<Vec<Staged>> {
    let mut staged = Vec::with_capacity(views.len());
    for view in views {
        let radiance = texels(&renderer.read_stitched(linear_slot, view.index)?);
        let (albedo, normal, position) = if *layers {
            (
                texels(&renderer.read_stitched("albedo_roughness", view.index)?),
                texels(&renderer.read_stitched("normal_metallic", view.index)?),
                texels(&renderer.read_stitched("position_depth", view.index)?),
            )
        } else {
            (Vec::new(), Vec::new(), Vec::new())
        };
        // Sources have no hole mask: only targets get the channel.
        let mask = if *holes {
            match renderer.read_stitched("holes", view.index) {
                Ok(bytes) => Some(bytemuck_words(&bytes)),
                Err(parallax_passes::PassError::MissingResource { .. }) => None,
                Err(e) => return Err(e.into()),
            }
        } else {
            None
        };
        let pixels = (0..radiance.len())
            .map(|i| {
                let g = |layer: &[[f32; 4]]| layer.get(i).copied().unwrap_or([0.0; 4]);
                let (a, n, p) = (g(&albedo), g(&normal), g(&position));
                PixelSample {
                    radiance: Vec3::from_slice(&radiance[i][..3]),
                    albedo: Vec3::from_slice(&a[..3]),
                    normal: Vec3::from_slice(&n[..3]),
                    depth: p[3],
                    position: Vec3::from_slice(&p[..3]),
                    roughness: a[3],
                    metallic: n[3],
                    hit: radiance[i][3] > 0.5,
                }
            })
            .collect();
        let frame = Frame { width: view.width, height: view.height, pixels };
        let path = folder.join(view_file_name(view.index));
        let exr_layers = if *layers { ExrLayers::ALL } else { ExrLayers::default() };
        let mask: Option<Vec<f32>> = mask.map(|m| m.iter().map(|&h| h as f32).collect());
        let extra: Vec<(&str, &[f32])> = mask.iter().map(|m| ("holes.Y", m.as_slice())).collect();
        staged.push(stage(&path, |tmp| {
            write_exr_with(tmp, &frame, exr_layers, &extra).with_context(|| format!("cannot write {}", path.display()))
        })?);
    }
    Ok(staged)
}

fn view_file_name(index: u32) -> String {
    format!("view_{index:03}.exr")
}

/// Checks the outputs before any work. The folder may not exist yet (it is created when the
/// views are written), but the nearest folder above it must be writable.
fn check_outputs(
    out_dir: &Path,
    sheet: &Path,
    render_json: &Path,
    trace: Option<&Sink>,
    dot: Option<&Sink>,
    wiggle: Option<&Path>,
) -> Result<()> {
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
    let viewer_sink = Sink::File(out_dir.join("viewer.html"));
    let mut outputs = Vec::new();
    if out_dir.is_dir() {
        outputs.push(Output { flag: "--out-dir", sink: &sheet_sink, format: Format::Png });
        outputs.push(Output { flag: "--out-dir", sink: &json_sink, format: Format::Json });
        outputs.push(Output { flag: "--out-dir", sink: &viewer_sink, format: Format::Html });
    }
    let in_out_dir = |flag: &str, path: &Path| {
        if path.parent().is_some_and(|p| p == out_dir)
            && path.file_name().and_then(|n| n.to_str()).is_some_and(|n| n == "render.json" || n.starts_with("view_"))
        {
            bail!("{flag} {} would overwrite an output of --out-dir: give it another name", path.display());
        }
        Ok(())
    };
    if let Some(sink) = trace {
        if let Sink::File(path) = sink {
            in_out_dir("--trace", path)?;
        }
        outputs.push(Output { flag: "--trace", sink, format: Format::Json });
    }
    if let Some(sink) = dot {
        outputs.push(Output { flag: "--dot", sink, format: Format::Dot });
    }
    let wiggle_sink = wiggle.map(|p| Sink::File(p.to_path_buf()));
    if let Some(sink @ Sink::File(path)) = &wiggle_sink {
        in_out_dir("--wiggle", path)?;
        outputs.push(Output { flag: "--wiggle", sink, format: Format::Png });
    }
    check(&outputs)
}

/// Removes `view_NNN.exr` and `view_NNN.png` files of an earlier run that this run of `views`
/// views did not write.
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

/// The view index of a file name this command writes (`view_007.exr` or `.png` → 7).
fn parse_view_file_name(name: &str) -> Option<u32> {
    let stem = name.strip_prefix("view_")?;
    let digits = stem.strip_suffix(".exr").or_else(|| stem.strip_suffix(".png"))?;
    if digits.len() < 3 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let index: u32 = digits.parse().ok()?;
    (view_file_name(index) == name || view_png_name(index) == name).then_some(index)
}
