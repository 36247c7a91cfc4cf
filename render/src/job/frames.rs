//! `render`'s run room: the devices, the executor and the frame loop. Warm-up frames run
//! first at the first measured frame's camera, then the statistics restart and the measured
//! frames run (the camera dollies or follows the scene's animation, moving meshes are posed at
//! each frame's time: [`super::posing`]); `--save-every` stages the views of some measured
//! frames on the way. A user crate's [`RenderExtension`] brings the shaders of its stages and
//! looks at the renderer once the last frame is done.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use parallax_backend::{Context as VkContext, ContextDesc, DeviceInfo, ExecOptions, Executor, KernelPlan, LinkKinds};
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::lightfield_views;
use parallax_passes::pipeline::PipelineBuilder;
use parallax_passes::scene_upload::scene_device_bytes;
use parallax_scene::gpu::GpuScene;
use parallax_scene::{SceneBvh, TraceSettings};

use super::faults::fault_from_env;
use super::posing::Posing;
use super::prepare::RenderJob;
use super::report::Rendered;
use super::view_files::{ViewLayers, stage_views, view_layers};
use crate::console::bar;
use crate::outputs::Staged;
use crate::outputs::budget::{DeviceMemory, SchemeOnDevices};
use crate::outputs::resident::{ResidentSampler, ResidentSummary};
use crate::report::startup::Step;
use crate::settings::{RenderExtension, RenderSettings};

/// Called after each frame is submitted with its index and host wall time: how ranks report
/// and listen while they render.
pub(super) type OnFrame<'a> = &'a mut dyn FnMut(u32, Duration) -> Result<()>;

/// Creates the devices and the executor for `job` and runs every frame; the scene is left in
/// the last frame's pose.
pub(super) fn render_frames(
    settings: &RenderSettings,
    job: &mut RenderJob,
    extension: &mut RenderExtension,
    on_frame: Option<OnFrame<'_>>,
) -> Result<Rendered> {
    let lf = job.lf_of(settings, 0)?;
    let bvh = SceneBvh::build(&job.scene);
    let context = VkContext::new(&ContextDesc::from_env(settings.devices))?;
    job.startup.ended(Step::Devices);
    // One message per device: a message is one line (crate::logging).
    context.to_string().lines().for_each(|line| tracing::info!("{line}"));
    job.one_frame.check_devices(&context)?;
    let identity = |builder: PipelineBuilder| builder;
    let extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder = extension.stages.as_deref().unwrap_or(&identity);
    let infos: Vec<DeviceInfo> = context.devices().iter().map(|d| d.info.clone()).collect();
    job.choose_gbuffer(settings, extend, &infos)?;
    // A link kind some pair cannot use is a usage error, found before any frame.
    let link_kinds = parallax_backend::link_kinds(context.devices(), settings.link).map_err(|e| {
        crate::error::UsageError(format!(
            "--link {}: {e}; `--link auto` takes the best each pair offers",
            settings.link.map_or("auto", |k| k.name())
        ))
    })?;
    let exec_plan = match &job.rank {
        Some(part) => Arc::new(crate::ranks::restrict_plan(&job.compiled.exec, &part.layout, part.rank)),
        None => Arc::clone(&job.compiled.exec),
    };
    let options = ExecOptions {
        barriers: settings.barriers,
        timing: settings.timing,
        frames_in_flight: settings.frames_in_flight as usize,
        fault: fault_from_env()?,
        link: settings.link,
        shaders: extension.shaders.clone(),
        remote: job.rank.as_ref().and_then(|part| part.transport.clone()),
        ..ExecOptions::default()
    };
    let scene = GpuScene::new(&job.scene, &bvh);
    let spread = SchemeOnDevices { scheme: settings.pipeline.scheme, selection: settings.devices };
    let memory = device_memory(&infos, &exec_plan, &link_kinds, options.frames_in_flight, &scene);
    job.one_frame.check_gpu_memory(spread, &memory)?;
    let mut renderer = LightFieldRenderer::with_options(&context, exec_plan, &scene, options)?;
    job.startup.ended(Step::Executor);
    drop(bvh);
    let layers = view_layers(settings, job.compiled.kind, &job.compiled.handles, &renderer);
    let executor = renderer.executor();
    // Devices by the run's numbers (a rank's own, and other ranks' at the far end of a link).
    let first = job.rank.as_ref().map_or(0, |part| part.layout.first(part.rank));
    for link in executor.links() {
        let end = |d: usize| crate::ranks::run_device(executor.plan(), first, d);
        tracing::info!(
            "link device {} → device {}: {}, {} chunk(s) and {:.1} MiB a frame",
            end(link.from),
            end(link.to),
            link.kind.name(),
            link.chunks_per_frame,
            link.bytes_per_frame as f64 / (1 << 20) as f64
        );
    }
    for s in executor.submissions() {
        tracing::info!(
            "device {}: {} submission(s) and {} cross-device wait(s) a frame",
            s.device,
            s.submissions_per_frame,
            s.cross_device_waits_per_frame
        );
    }
    if !executor.links().is_empty() {
        let mib = |bytes: u64| bytes as f64 / (1 << 20) as f64;
        tracing::info!(
            "staging: {:.1} MiB host (rings within {:.1} MiB), {:.1} MiB device",
            mib(executor.host_staging_bytes()),
            mib(executor.host_staging_limit()),
            mib(executor.device_staging_bytes())
        );
    }

    let lock = if job.writes_outputs {
        crate::outputs::create_folder(&settings.out_dir)
            .with_context(|| format!("cannot create --out-dir {}", settings.out_dir.display()))?;
        Some(crate::outputs::lock_folder(&settings.out_dir, "--out-dir")?)
    } else {
        None
    };
    let mut posing = Posing::of(job);
    let (staged, wall, host_memory) = frame_loop(settings, job, &mut renderer, layers, posing.as_mut(), on_frame)?;
    if let Some(done) = renderer.executor().first_frame_done_ns() {
        job.startup.ended_at(Step::FirstFrame, done);
    }
    if let Some(after) = extension.after_frames.as_mut() {
        after(&mut renderer, &job.compiled.handles)?;
    }
    let geometry = posing.map(|p| p.report()).unwrap_or_default();
    Ok(Rendered { context, renderer, staged, wall, host_memory, lf, lock, layers, geometry, ranks: None })
}

/// What each device of `infos` will allocate in device-local memory for `plan` (with
/// `frames_in_flight` over links of `link_kinds`) and `scene`, before the executor makes any of it.
fn device_memory(
    infos: &[DeviceInfo],
    plan: &KernelPlan,
    link_kinds: &LinkKinds,
    frames_in_flight: usize,
    scene: &GpuScene<'_>,
) -> Vec<DeviceMemory> {
    let scene_bytes = scene_device_bytes(scene);
    let plan_bytes = Executor::device_local_bytes(plan, link_kinds, frames_in_flight);
    infos
        .iter()
        .zip(plan_bytes)
        .map(|(info, bytes)| DeviceMemory {
            device: info.index,
            physical_index: info.physical_index,
            gpu_name: info.name.clone(),
            heap_bytes: info.device_local_heap_bytes,
            bytes: bytes + scene_bytes,
        })
        .collect()
}

/// Submits the warm-up and measured frames, each after `posing` (when the meshes move) has
/// posed the scene at its time; returns the views `--save-every` staged, the wall time of the
/// measured frames and the resident set over them.
fn frame_loop(
    settings: &RenderSettings,
    job: &mut RenderJob,
    renderer: &mut LightFieldRenderer,
    layers: ViewLayers,
    mut posing: Option<&mut Posing>,
    mut on_frame: Option<OnFrame<'_>>,
) -> Result<(Vec<Staged>, Duration, ResidentSummary)> {
    let progress = bar(u64::from(job.total_frames));
    let started = Instant::now();
    let mut measured_from = None;
    let mut sampler = None;
    let mut staged: Vec<Staged> = Vec::new();
    for f in 0..job.total_frames {
        if f == settings.warmup {
            renderer.finish()?;
            renderer.reset_stats();
            // Only a trace needs every event of every frame; otherwise the statistics are all.
            renderer.keep_reports(settings.trace.is_some());
            measured_from = Some(Instant::now());
            sampler = Some(ResidentSampler::start());
        }
        if let Some(posing) = posing.as_deref_mut() {
            posing.before_frame(settings, job, renderer, f)?;
        }
        let frame_started = Instant::now();
        let views = lightfield_views(&job.lf_of(settings, f)?);
        renderer.submit(&job.scene, &views, &TraceSettings { frame: f, ..job.trace_settings })?;
        if let Some(on_frame) = on_frame.as_deref_mut() {
            on_frame(f, frame_started.elapsed())?;
        }
        let measured = f.checked_sub(settings.warmup);
        if let (Some(every), Some(m)) = (settings.save_every, measured)
            && m % every == 0
            && f + 1 < job.total_frames
        {
            renderer.finish()?;
            let folder = settings.out_dir.join(format!("frame_{m:05}"));
            // Only inside --out-dir as it is: making it again would put the frames beside the
            // folder the user moved.
            match crate::outputs::create_subfolder(&folder) {
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    bail!("--out-dir: {}", parallax_accuracy::folder_gone(&settings.out_dir))
                }
                created => created.with_context(|| format!("cannot create {}", folder.display()))?,
            }
            staged.extend(stage_views(renderer, &job.compiled.handles, &folder, &views, layers)?);
        }
        progress.inc(1);
    }
    renderer.finish()?;
    let wall = measured_from.unwrap_or(started).elapsed();
    let host_memory = sampler.unwrap_or_else(ResidentSampler::start).stop();
    progress.finish_and_clear();
    Ok((staged, wall, host_memory))
}
