//! `render`'s report room: what a finished run leaves behind. The last frame's views (EXR, and
//! PNG at one exposure), the contact sheet, quilt, wiggle and viewer, render.json with the
//! plan, the stage table and the missing pixels, the trace and the DOT; every file is staged
//! first and put in place at the end, render.json last, so a failure (or Ctrl-C) leaves the
//! folder as it was or complete. Also the checks of those outputs that run before any work.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::time::Duration;

use anyhow::{Context as _, Result};
use glam::Vec3;
use parallax_backend::{Context as VkContext, ExecutionPlan, chrome_trace};
use parallax_graph::LightField;
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::lightfield_views;
use parallax_passes::pipeline::{PipelineHandles, PipelineKind};
use parallax_scene::output::{ExrLayers, write_exr_with};
use parallax_scene::{Frame, PixelSample, View};

use super::posing::GeometryReport;
use super::prepare::{RenderJob, view_file_name};
use crate::compile::{denoiser_name, fireflies_name, gbuffer_name, pipeline_name, plan_json, sources_per_set_json};
use crate::console::result;
use crate::outputs::resident::ResidentSummary;
use crate::outputs::{FolderLock, Sink, Staged, stage};
use crate::ranks::view_source::{Gathered, ViewSource};
use crate::report::pictures::{display_images, stage_pictures, view_png_name};
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
    pub plan: ExecutionPlan,
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
            if job.compiled.plan.topology.is_source[v as usize] {
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

/// The extra EXR layers of the views.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ViewLayers {
    /// Albedo, normal and depth, each where the pipeline produces it.
    exr: ExrLayers,
    /// The hole mask of targets (reprojection only).
    holes: bool,
}

/// What `--layers` gives with the plan `renderer` runs: albedo, normal and depth where the
/// pipeline computes them, and the hole mask with reprojection. Path tracing without denoising
/// computes no G-buffer: its views carry radiance alone, which is said once, before the frames
/// (reading a layer no pass writes used to fail the run after all of them).
pub(super) fn view_layers(
    settings: &RenderSettings,
    kind: PipelineKind,
    handles: &PipelineHandles,
    renderer: &LightFieldRenderer,
) -> ViewLayers {
    if !settings.layers {
        return ViewLayers::default();
    }
    // A view this process renders (a rank of several renders only some).
    let view = renderer.plan().passes.first().map_or(0, |p| p.view.0);
    let produced = |family| renderer.plan().final_bands(family, view).is_some();
    let g = &handles.gbuffer;
    let exr = ExrLayers {
        albedo: produced(g.albedo_roughness.family()),
        normal: produced(g.normal_metallic.family()),
        depth: produced(g.position_depth.family()),
    };
    let absent: Vec<&str> = [("albedo", exr.albedo), ("normal", exr.normal), ("depth", exr.depth)]
        .into_iter()
        .filter_map(|(name, there)| (!there).then_some(name))
        .collect();
    if !absent.is_empty() {
        tracing::warn!(
            "--layers: this pipeline computes no {} (no stage needs a G-buffer), so the views' EXRs leave that out; \
             drop --no-denoise or use --pipeline reproject to get every layer",
            absent.join(", ")
        );
    }
    ViewLayers { exr, holes: kind == PipelineKind::Reproject }
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
/// after hole filling with --no-denoise), with `layers`: albedo, normal and depth, and the hole
/// mask of targets as channel `holes.Y` (1 = the pixel was path traced by hole filling).
pub(super) fn stage_views(
    renderer: &mut dyn ViewSource,
    handles: &PipelineHandles,
    folder: &Path,
    views: &[View],
    layers: ViewLayers,
) -> Result<Vec<Staged>> {
    let mut staged = Vec::with_capacity(views.len());
    let gbuffer = &handles.gbuffer;
    for view in views {
        let radiance = texels(&renderer.read_view(handles.linear, view.index)?);
        let mut layer = |wanted: bool, family| -> Result<Vec<[f32; 4]>> {
            Ok(if wanted { texels(&renderer.read_view(family, view.index)?) } else { Vec::new() })
        };
        let albedo = layer(layers.exr.albedo, gbuffer.albedo_roughness.family())?;
        let normal = layer(layers.exr.normal, gbuffer.normal_metallic.family())?;
        let position = layer(layers.exr.depth, gbuffer.position_depth.family())?;
        // Sources have no hole mask: only targets get the channel.
        let mask = match &handles.holes {
            Some(mask) if layers.holes => match renderer.read_view(mask.family(), view.index) {
                Ok(bytes) => Some(bytemuck_words(&bytes)),
                Err(parallax_passes::PassError::MissingOutput { .. }) => None,
                Err(e) => return Err(e.into()),
            },
            _ => None,
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
        if layers.exr.depth {
            staged.extend(stage_layer_pictures(folder, view.index, &frame, mask.as_deref())?);
        }
        let path = folder.join(view_file_name(view.index));
        let exr_layers = layers.exr;
        let mask: Option<Vec<f32>> = mask.map(|m| m.iter().map(|&h| h as f32).collect());
        let extra: Vec<(&str, &[f32])> = mask.iter().map(|m| ("holes.Y", m.as_slice())).collect();
        staged.push(stage(&path, |tmp| {
            write_exr_with(tmp, &frame, exr_layers, &extra).with_context(|| format!("cannot write {}", path.display()))
        })?);
    }
    Ok(staged)
}

/// With `--layers`, pictures of the layers a person looks at: `view_NNN_depth.png` (grey, the
/// view's nearest hit white, its farthest dark grey, sky black) and, of targets,
/// `view_NNN_holes.png` (white where hole filling path traced the pixel).
fn stage_layer_pictures(folder: &Path, index: u32, frame: &Frame, mask: Option<&[u32]>) -> Result<Vec<Staged>> {
    let hits = || frame.pixels.iter().filter(|p| p.hit).map(|p| p.depth);
    let (near, far) = hits().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), d| (a.min(d), b.max(d)));
    let grey = |p: &PixelSample| -> u8 {
        if !p.hit {
            return 0;
        }
        let t = if far > near { (p.depth - near) / (far - near) } else { 0.0 };
        (255.0 - 191.0 * t.clamp(0.0, 1.0)).round() as u8
    };
    let depth: Vec<u8> = frame.pixels.iter().map(grey).collect();
    let mut pictures = vec![(format!("view_{index:03}_depth.png"), depth)];
    if let Some(mask) = mask {
        pictures
            .push((format!("view_{index:03}_holes.png"), mask.iter().map(|&h| if h != 0 { 255 } else { 0 }).collect()));
    }
    pictures
        .into_iter()
        .map(|(name, luma)| {
            let path = folder.join(name);
            let image =
                image::GrayImage::from_raw(frame.width, frame.height, luma).context("a layer of the view's size")?;
            stage(&path, |tmp| {
                image
                    .save_with_format(tmp, image::ImageFormat::Png)
                    .with_context(|| format!("cannot write {}", path.display()))
            })
        })
        .collect()
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

/// What rank 0 reads of a view to write the outputs, so what another rank sends of its views:
/// the linear radiance, the tonemapped display (at a fixed exposure), the hole mask
/// (reprojection) and the `--layers`.
#[cfg(feature = "mpi")]
pub(super) fn output_families(
    settings: &RenderSettings,
    job: &RenderJob,
    layers: ViewLayers,
) -> Vec<parallax_graph::FamilyId> {
    let handles = &job.compiled.handles;
    let gbuffer = &handles.gbuffer;
    let mut families = vec![handles.linear];
    if matches!(settings.exposure, parallax_accuracy::exposure::Exposure::Fixed(_)) {
        families.push(handles.display.family());
    }
    if job.compiled.kind == PipelineKind::Reproject {
        families.extend(handles.holes.as_ref().map(|h| h.family()));
    }
    let exr = layers.exr;
    families.extend(exr.albedo.then(|| gbuffer.albedo_roughness.family()));
    families.extend(exr.normal.then(|| gbuffer.normal_metallic.family()));
    families.extend(exr.depth.then(|| gbuffer.position_depth.family()));
    families
}
