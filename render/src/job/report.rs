//! `render`'s report room: what a finished run leaves behind. The last frame's views (EXR, and
//! PNG at one exposure), the contact sheet, quilt, wiggle and viewer, render.json with the
//! plan, the stage table and the missing pixels, the trace and the DOT; every file is staged
//! first and put in place at the end, render.json last, so a failure (or Ctrl-C) leaves the
//! folder as it was or complete. Also the checks of those outputs that run before any work.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result};
use parallax_backend::{Context as VkContext, KernelPlan, chrome_trace};
use parallax_graph::LightField;
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::lightfield_views;
use parallax_passes::pipeline::PipelineKind;

use super::posing::GeometryReport;
use super::prepare::RenderJob;
use super::view_files::{ViewLayers, bytemuck_words, remove_stale_views, stage_views};
use crate::compile::{
    denoiser_name, fireflies_name, gbuffer_name, hole_fill_name, pipeline_name, plan_json, sources_per_set_json,
};
use crate::console::result;
use crate::outputs::resident::ResidentSummary;
use crate::outputs::{FolderLock, Sink, Staged};
use crate::ranks::view_source::{Gathered, ViewSource};
use crate::report::pictures::{display_images, stage_pictures};
use crate::report::setup::{CameraSetup, Setup};
use crate::report::stages::{MissingPixels, missing_pixels, stage_table, timings};
use crate::settings::{RenderSettings, barriers_name, timing_name};

/// What the frame loop leaves for the report: the renderer after the last frame (its
/// statistics and final images), the context it ran on, the views already staged by
/// `--save-every`, and the wall time of the measured frames.
pub(super) struct Rendered {
    pub context: VkContext,
    pub renderer: LightFieldRenderer,
    pub staged: Vec<Staged>,
    pub wall: Duration,
    /// The process's resident set over the measured frames.
    pub host_memory: ResidentSummary,
    /// The light field of frame 0 (its layout is every frame's).
    pub lf: LightField,
    /// Held until the outputs are in place: no other run writes into --out-dir meanwhile (None:
    /// a rank other than 0, which writes nothing).
    pub lock: Option<FolderLock>,
    /// The extra EXR layers every view gets.
    pub layers: ViewLayers,
    /// Whether the meshes moved, and what posing them cost.
    pub geometry: GeometryReport,
    /// Rank 0 of a render over several ranks: the views the others sent.
    pub ranks: Option<RankViews>,
}

/// What rank 0 gathered from the other ranks for the outputs.
pub(super) struct RankViews {
    /// Resources of their views, by (family, view).
    pub remote: HashMap<(u32, u32), Vec<u8>>,
    pub remote_views: BTreeSet<u32>,
    /// Under a fine scheme, the bands of layers left on other ranks' devices, by (family, view,
    /// global device) (view_source.rs).
    pub bands: HashMap<(u32, u32, u32), Vec<u8>>,
    /// The whole run's plan (which device wrote which rows).
    pub plan: Arc<KernelPlan>,
    /// Every device of the run, in global order.
    pub device_names: Vec<String>,
    /// Wall time per measured frame of the slowest rank.
    pub wall_ms: f64,
    /// render.json's `ranks`.
    pub json: serde_json::Value,
}

/// Reads the last frame back, writes every output and says what was rendered.
pub(super) fn write_outputs(settings: &RenderSettings, job: &RenderJob, rendered: Rendered) -> Result<()> {
    let Rendered { context, mut renderer, mut staged, wall, host_memory, lf, lock, layers, geometry, ranks } = rendered;
    let reports = renderer.take_reports();
    // Stats borrow the renderer mutably (they fold the retired frames first).
    let stats = renderer.stats().clone();
    let timing = timings(&stats, renderer.prepare_ms(), renderer.plan());
    let (kind, handles) = (job.compiled.kind, &job.compiled.handles);
    let last_views = lightfield_views(&job.lf_of(settings, job.total_frames - 1)?);
    let no_remote = (HashMap::new(), BTreeSet::new(), HashMap::new());
    let (remote, remote_views, bands) =
        ranks.as_ref().map_or((&no_remote.0, &no_remote.1, &no_remote.2), |r| (&r.remote, &r.remote_views, &r.bands));
    let mut views = Gathered { local: &mut renderer, remote, remote_views, bands };
    staged.extend(stage_views(&mut views, handles, &settings.out_dir, &last_views, layers)?);
    let (exposure, displays) = display_images(&mut views, handles, (lf.len() as u32, lf.width), settings.exposure)?;
    let pictures = stage_pictures(&settings.out_dir, &lf, &displays, settings.quilt, settings.wiggle.as_deref())?;
    drop(displays);
    let holes = match kind {
        PipelineKind::Reproject => Some(holes_of_targets(job, &mut views, lf.len() as u32)?),
        PipelineKind::PathTrace => None,
    };
    let missing = match holes {
        // Which device wrote which rows: the whole run's plan, not this rank's part.
        Some((family, holes)) => {
            let plan = ranks.as_ref().map_or_else(|| renderer.plan(), |r| &r.plan);
            missing_pixels(plan, family, &holes, lf.width)
        }
        None => MissingPixels::default(),
    };
    let links = links_json(renderer.executor());
    drop(renderer);
    context.check_validation()?;

    let device_names: Vec<String> = match &ranks {
        Some(r) => r.device_names.clone(),
        None => context.device_infos().iter().map(|d| d.name.clone()).collect(),
    };
    let wall_ms = ranks.as_ref().map_or_else(|| wall_ms(settings, wall), |r| r.wall_ms);
    let json = render_json(
        settings,
        job,
        &Measured {
            exposure,
            wall_ms,
            timing: &timing,
            missing: &missing,
            device_names,
            host_memory,
            geometry,
            links,
            ranks: ranks.as_ref().map(|r| r.json.clone()),
        },
    )?;
    let viewer = pictures.stage_viewer(&settings.out_dir, &lf, &json)?;
    let json_file = crate::outputs::stage_json(&job.render_json, &json)?;
    let trace = settings.trace.as_ref().map(|_| chrome_trace(&reports, &context.device_infos()));
    for s in staged.into_iter().chain(pictures.staged) {
        s.commit()?;
    }
    viewer.commit()?;
    remove_stale_views(&settings.out_dir, lf.len())?;
    if let (Some(sink), Some(trace)) = (&settings.trace, &trace) {
        crate::outputs::write_json(sink, trace)?;
    }
    if let (Some(sink), Some(dot)) = (&settings.dot, &job.dot) {
        crate::outputs::write_bytes(sink, dot.as_bytes())?;
    }
    json_file.commit()?;
    crate::outputs::keep_folders();
    drop(lock);
    let stdout_taken = [&settings.trace, &settings.dot].iter().any(|s| matches!(s, Some(Sink::Stdout)));
    let say = |line: String| result(stdout_taken, &line);
    // The table is detail for a person at a terminal: -q (bench's cells, scripts) keeps the
    // one-line results only.
    if !crate::console::quiet() {
        say(stage_table(&timing));
    }
    say(format!(
        "rendered {} views of {}x{} ({}, {}, {} device(s), {} spp, {} measured frame(s)): {:.2} ms per frame wall, GPU span {:.2} ms mean; missing pixels {:.2} %",
        lf.len(),
        lf.width,
        lf.height,
        crate::compile::pipeline_name(settings.pipeline.config.kind),
        job.compiled.summary.scheme,
        job.compiled.summary.devices,
        settings.spp,
        settings.frames,
        wall_ms,
        timing.frame_gpu.mean_ms,
        100.0 * missing.overall
    ));
    say(format!(
        "wrote {} views (EXR and PNG at exposure {exposure:.4}, {}), {}, {} and {}",
        lf.len(),
        settings.exposure.mode(),
        job.sheet.display(),
        settings.out_dir.join("viewer.html").display(),
        job.render_json.display()
    ));
    Ok(())
}

/// Wall time per measured frame, in milliseconds.
fn wall_ms(settings: &RenderSettings, wall: std::time::Duration) -> f64 {
    wall.as_secs_f64() * 1e3 / f64::from(settings.frames)
}

/// What the run measured, for render.json.
struct Measured<'a> {
    exposure: f32,
    wall_ms: f64,
    timing: &'a crate::report::stages::Timings,
    missing: &'a MissingPixels,
    device_names: Vec<String>,
    host_memory: ResidentSummary,
    geometry: GeometryReport,
    links: serde_json::Value,
    /// A render over several ranks: what each rank ran, sent and measured.
    ranks: Option<serde_json::Value>,
}

/// render.json's `links`: each (producer, consumer) device pair the plan copies over, how it
/// moves data and how many chunks and bytes a frame (by the run's device numbers: rank 0 of a
/// render over several ranks lists its `remote` links too); and the host and device staging
/// memory they use.
fn links_json(executor: &parallax_backend::Executor) -> serde_json::Value {
    let end = |d: usize| crate::ranks::run_device(executor.plan(), 0, d);
    let links: Vec<serde_json::Value> = executor
        .links()
        .iter()
        .map(|l| {
            serde_json::json!({
                "from": end(l.from), "to": end(l.to), "kind": l.kind.name(),
                "chunks_per_frame": l.chunks_per_frame, "bytes_per_frame": l.bytes_per_frame,
            })
        })
        .collect();
    let devices: Vec<serde_json::Value> = executor
        .submissions()
        .iter()
        .map(|s| {
            serde_json::json!({
                "device": s.device, "submissions_per_frame": s.submissions_per_frame,
                "cross_device_waits_per_frame": s.cross_device_waits_per_frame,
            })
        })
        .collect();
    serde_json::json!({
        "pairs": links,
        "devices": devices,
        "host_staging_bytes": executor.host_staging_bytes(),
        "host_staging_limit_bytes": executor.host_staging_limit(),
        "device_staging_bytes": executor.device_staging_bytes(),
    })
}

/// The hole masks of the targets (None for sources): the pixels no source covered, which hole
/// filling path traced; and their family.
fn holes_of_targets(
    job: &RenderJob,
    renderer: &mut dyn ViewSource,
    views: u32,
) -> Result<(parallax_graph::FamilyId, Vec<Option<Vec<u32>>>)> {
    let holes_family =
        job.compiled.handles.holes.as_ref().map(|h| h.family()).context("the pipeline has no hole masks")?;
    let holes: Vec<Option<Vec<u32>>> = (0..views)
        .map(|v| {
            if job.compiled.partition.topology.is_source[v as usize] {
                return Ok(None);
            }
            let bytes = renderer.read_view(holes_family, v)?;
            Ok(Some(bytemuck_words(&bytes)))
        })
        .collect::<Result<_, parallax_passes::PassError>>()?;
    Ok((holes_family, holes))
}

/// render.json: the setup that comparisons check, the plan and what was measured.
fn render_json(settings: &RenderSettings, job: &RenderJob, measured: &Measured<'_>) -> Result<serde_json::Value> {
    let last = job.total_frames - 1;
    let lf = job.lf_of(settings, 0)?;
    let still = matches!(job.motion, super::prepare::Motion::Still);
    let last_lf = job.lf_of(settings, last)?;
    let spacing = job.spacing;
    let camera_last = job.camera_at(settings, last);
    let setup =
        Setup::new(&settings.scene.path, &job.scene, &camera_last, still, (&last_lf, spacing), settings.max_depth)?;
    let (summary, kind) = (&job.compiled.summary, job.compiled.kind);
    Ok(serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "scene": settings.scene.path.to_string_lossy(),
        "camera": CameraSetup::of(&job.camera), "sun": &setup.sun, "sky": &setup.sky,
        "layout": { "lf": &lf.name, "views": lf.len(), "cols": lf.cols, "rows": lf.rows,
                    "width": lf.width, "height": lf.height, "spacing_m": setup.spacing_m, "focus_m": lf.rig.focus_distance },
        // The assignment groups views only under multi-source (`--assign` is refused otherwise).
        "pipeline": pipeline_name(settings.pipeline.config.kind), "scheme": summary.scheme, "assign": summary.assign,
        "sources_per_set": sources_per_set_json(settings.pipeline.sources_per_set), "denoise": denoiser_name(settings.pipeline.config.denoise),
        "fireflies": fireflies_name(settings.pipeline.config.fireflies),
        "hole_fill": hole_fill_name(settings.pipeline.config.hole_fill),
        "exposure": measured.exposure, "exposure_mode": settings.exposure.mode(), "still": still,
        "motion": job.motion.name(), "geometry": &measured.geometry, "setup": &setup,
        "barriers": barriers_name(settings.barriers), "timestamps": timing_name(settings.timing), "gbuffer": gbuffer_name(job.gbuffer.runs),
        "gbuffer_requested": gbuffer_name(settings.pipeline.config.gbuffer), "gbuffer_fallback": &job.gbuffer.fallback,
        "reprojection_tolerance": settings.pipeline.reprojection_tolerance,
        "spp": settings.spp, "max_depth": settings.max_depth, "frames": settings.frames, "warmup": settings.warmup,
        "frames_in_flight": settings.frames_in_flight,
        "devices": measured.device_names,
        "run": settings.run.clone(),
        "plan": plan_json(summary, job.gbuffer.runs),
        "startup": job.startup.to_json(),
        "wall_ms_per_frame": measured.wall_ms,
        "timing": measured.timing,
        "host_memory": measured.host_memory,
        "links": measured.links,
        // Path tracing every view leaves no holes to count.
        "missing_pixels": (kind == PipelineKind::Reproject).then_some(measured.missing),
        "ranks": measured.ranks,
    }))
}
