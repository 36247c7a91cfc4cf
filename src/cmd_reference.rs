//! `parallax reference`: a converged rendering of every view of a light field (or `--views`),
//! path traced progressively in chunks of spp on the GPU (`--gpus N` / `--fake-devices N`, each
//! view in row bands over the devices) or on the CPU reference tracer (`--cpu`).
//!
//! Each chunk is an f32 mean on the device; chunks are summed in f64 by
//! [`parallax_accuracy::Accumulator`], whose sidecar `reference.partial` makes the run
//! resumable: run the same command again (with the same or a higher `--spp`) and it continues
//! from the spp reached, bit-identical to an uninterrupted run. The sidecar, the EXRs and
//! `reference.json` are written atomically at every checkpoint, so an interrupted run leaves
//! the last checkpoint complete.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use clap::Args;
use indicatif::ProgressStyle;
use parallax_accuracy::exposure::LogAverage;
use parallax_accuracy::{Accumulator, PARTIAL_FILE, Point, RgbImage, remove_stale_temporaries, write_atomically};
use parallax_graph::lightfield::DEFAULT_SPACING;
use parallax_graph::{LightField, ViewId};
use parallax_scene::output::write_contact_sheet;
use parallax_scene::{CpuTracer, Frame, PixelSample, Scene, SceneBvh, TraceSettings, View};

use crate::options::{DeviceArgs, Exposure, UsageError, parse_exposure};
use crate::scene_args::{DepthArgs, LightFieldArgs, SceneArgs};
use parallax_passes::camera::lightfield_view;
use parallax_render::outputs::budget::{TraceWork, check_host_bytes, refuse_every_exceeded};
use parallax_render::report::setup::Setup;
use parallax_render::trace_run::{GpuTraceSettings, GpuTracer};

#[derive(Args, Debug)]
pub struct ReferenceArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    light_field: LightFieldArgs,
    /// Only these views, e.g. `0,5,8-11` (default: every view).
    #[arg(long)]
    views: Option<String>,
    #[command(flatten)]
    devices: DeviceArgs,
    /// Trace on the CPU reference path tracer instead of the GPU.
    #[arg(long, conflicts_with_all = ["gpus", "fake_devices"])]
    cpu: bool,
    /// Samples per pixel to reach (a multiple of --chunk-spp).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    spp: u32,
    /// Samples per pixel of one chunk: averaged in f32 on the device, chunks summed in f64.
    #[arg(long, allow_negative_numbers = true, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    chunk_spp: u32,
    #[command(flatten)]
    depth: DepthArgs,
    /// Write the EXRs and the resumable state at least this often (seconds) and at the end.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true, value_parser = parse_checkpoint_secs)]
    checkpoint_secs: f64,
    /// Folder for view_NNN.exr, reference.png, reference.json and reference.partial.
    #[arg(long, default_value = "out/reference")]
    out_dir: PathBuf,
    /// Exposure of the contact sheet: `auto` (the log-average luminance of every view mapped to
    /// 0.18, one exposure for all, computed on the host from the mean radiance) or a multiplier
    /// > 0. The value used is written to reference.json.
    #[arg(long, allow_negative_numbers = true, default_value = "auto", value_parser = parse_exposure)]
    exposure: Exposure,
}

/// The longest checkpoint interval: a day (longer is no checkpoint at all but the last).
const CHECKPOINT_SECS_MAX: f64 = 86_400.0;

/// `--checkpoint-secs`: seconds within 0..=86400 (NaN used to pass clap and fail the run).
fn parse_checkpoint_secs(s: &str) -> std::result::Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=CHECKPOINT_SECS_MAX).contains(&v) => Ok(v),
        Ok(v) => Err(format!("{v} is outside 0..={CHECKPOINT_SECS_MAX} seconds")),
        Err(_) => Err(format!("'{s}' is not a number of seconds in 0..={CHECKPOINT_SECS_MAX}")),
    }
}

/// `0,5,8-11` into sorted, distinct view indices below `count`.
fn parse_views(s: &str, count: usize) -> Result<Vec<u32>> {
    let mut views = Vec::new();
    for part in s.split(',').map(str::trim) {
        let parse = |t: &str| -> Result<u32> {
            t.trim()
                .parse()
                .map_err(|_| UsageError(format!("--views '{s}': '{t}' is not a view number (e.g. 0,5,8-11)")).into())
        };
        let (a, b) = match part.split_once('-') {
            Some((a, b)) => (parse(a)?, parse(b)?),
            None => (parse(part)?, parse(part)?),
        };
        if a > b || b as usize >= count {
            return Err(UsageError(format!(
                "--views '{s}': '{part}' is not a range of views 0..={} of this light field; list views within it",
                count - 1
            ))
            .into());
        }
        views.extend(a..=b);
    }
    views.sort_unstable();
    views.dedup();
    Ok(views)
}

/// Every file the scene was read from, by name with its FNV-1a hash and size: the scene under
/// `--scene`, each buffer and image under `--scene file NAME`, so a resumed run names the one that
/// changed (an edited .bin used to go unnoticed). A different path to the same files is the same
/// scene; `default` is built in.
fn scene_files_key(scene: &Scene) -> BTreeMap<String, String> {
    match scene.sources.split_first() {
        None => BTreeMap::from([("--scene".to_string(), "default".to_string())]),
        Some((main, others)) => std::iter::once(("--scene".to_string(), main.to_string()))
            .chain(others.iter().map(|f| (format!("--scene file {}", f.name), f.to_string())))
            .collect(),
    }
}

enum Tracer<'a> {
    Cpu(CpuTracer<'a>),
    Gpu(GpuTracer),
}

impl<'a> Tracer<'a> {
    /// The CPU reference tracer under `--cpu`, else a GPU tracer over the selected devices, each
    /// view in row bands over them.
    fn start(
        args: &ReferenceArgs,
        scene: &'a Scene,
        bvh: &'a SceneBvh,
        work: TraceWork,
        lf: &LightField,
        views: usize,
    ) -> Result<Self> {
        if args.cpu {
            return Ok(Tracer::Cpu(CpuTracer::new(scene, bvh)));
        }
        let settings = GpuTraceSettings {
            devices: args.devices.selection(),
            views: views as u32,
            size: (lf.width, lf.height),
            timed: false,
        };
        Ok(Tracer::Gpu(GpuTracer::start(settings, work, scene, bvh)?))
    }
}

impl Tracer<'_> {
    /// One chunk: every view's f32 mean radiance over `settings.spp` samples.
    fn chunk(&mut self, scene: &Scene, views: &[View], settings: &TraceSettings) -> Result<Vec<Vec<[f32; 3]>>> {
        match self {
            Tracer::Cpu(cpu) => views
                .iter()
                .map(|v| {
                    let (frame, _) = cpu.render(v, settings, &|_| {})?;
                    Ok(frame.pixels.iter().map(|p| p.radiance.to_array()).collect())
                })
                .collect(),
            Tracer::Gpu(tracer) => Ok(tracer
                .trace(scene, views, settings)?
                .into_iter()
                .map(|pixels| pixels.iter().map(|p| [p.radiance[0], p.radiance[1], p.radiance[2]]).collect())
                .collect()),
        }
    }
}

pub fn run(args: ReferenceArgs) -> Result<()> {
    check_sampling_args(&args)?;
    let scene = args.scene.load()?;
    let written: Vec<PathBuf> =
        ["reference.json", "reference.png", PARTIAL_FILE].iter().map(|name| args.out_dir.join(name)).collect();
    let written: Vec<(&str, &Path)> = written.iter().map(|p| ("--out-dir", p.as_path())).collect();
    parallax_render::outputs::check_inputs(&written, &args.scene.settings().inputs(&scene))?;
    let lf = args
        .light_field
        .settings()
        .around(&args.scene.settings().camera_or_default(&scene), scene.bounds().center())?;
    let selected = match &args.views {
        Some(list) => parse_views(list, lf.len())?,
        None => (0..lf.len() as u32).collect(),
    };
    // The tracers key random numbers by a view's position in the list they are given, so a
    // subset's views get the noise of views 0..k: a different, equally valid estimate.
    let views: Vec<View> = selected
        .iter()
        .enumerate()
        .map(|(i, &v)| View { index: i as u32, ..lightfield_view(&lf, ViewId(v)) })
        .collect();
    let devices = if args.cpu { 0 } else { args.devices.selection().count() as u64 };
    let work = check_cost(&lf, views.len(), args.spp, devices)?;
    let settings_key = settings_key(&args, &scene, &lf, &selected);
    // What compare checks: a reference is always of a still camera.
    let setup = Setup::new(
        &args.scene.scene,
        &scene,
        &args.scene.settings().camera_or_default(&scene),
        true,
        (&lf, args.light_field.layout.settings().spacing_on(&lf.rig)),
        args.depth.max_depth,
    )?;
    let _lock = prepare_out_dir(&args.out_dir, &selected)?;
    let partial = args.out_dir.join(PARTIAL_FILE);
    let size = (lf.width as usize, lf.height as usize);
    let mut acc = resume_or_start(&partial, settings_key, views.len(), size, args.chunk_spp)?;
    let target = u64::from(args.spp);
    if acc.header.spp >= target {
        tracing::info!(
            "{} already holds {} spp (target {target}): nothing to trace",
            partial.display(),
            acc.header.spp
        );
        return write_outputs(&args, &acc, &selected, (&lf, &setup), 0.0, None);
    }

    let bvh = SceneBvh::build(&scene);
    let mut tracer = Tracer::start(&args, &scene, &bvh, work, &lf, views.len())?;
    let devices = if args.cpu { 0 } else { args.devices.selection().count() };
    let started = Instant::now();
    trace_to_target(&args, &mut tracer, &scene, &views, &mut acc, &selected)?;
    if let Tracer::Gpu(tracer) = tracer {
        tracer.finish()?;
    }
    write_outputs(&args, &acc, &selected, (&lf, &setup), started.elapsed().as_secs_f64(), Some(devices))
}

/// Refuses chunks that do not tile `--spp`.
fn check_sampling_args(args: &ReferenceArgs) -> Result<()> {
    if args.chunk_spp == 0 || args.spp % args.chunk_spp != 0 {
        return Err(UsageError(format!(
            "--spp {} is not a multiple of --chunk-spp {}: chunks must tile the samples for a resumed run to equal an \
             uninterrupted one; pick --spp {}",
            args.spp,
            args.chunk_spp,
            args.spp.div_ceil(args.chunk_spp.max(1)) * args.chunk_spp.max(1)
        ))
        .into());
    }
    Ok(())
}

/// What it costs, checked before anything is allocated: the paths, the read-back views and the
/// f64 sums (3 channels × 8 bytes per pixel of every view).
fn check_cost(lf: &LightField, views: usize, spp: u32, devices: u64) -> Result<TraceWork> {
    let work = TraceWork {
        views: views as u64,
        frames: 1,
        width: lf.width,
        height: lf.height,
        spp,
        devices,
        views_flag: "--lf, --views",
        frames_flag: "",
    };
    let sums = check_host_bytes(
        &format!("the f64 sums of {} view(s) of {}x{}", views, lf.width, lf.height),
        work.views * u64::from(lf.width) * u64::from(lf.height) * 24,
        "lower --resolution or trace fewer --views",
    );
    refuse_every_exceeded([work.check_duration(), work.check_host(), sums])?;
    Ok(work)
}

/// Everything the pixels depend on, by the flag that sets it; devices are not among them
/// (results do not depend on the device count), so a reference can resume on other GPUs.
fn settings_key(args: &ReferenceArgs, scene: &Scene, lf: &LightField, selected: &[u32]) -> BTreeMap<String, String> {
    let focus = lf.rig.focus_distance;
    let mut settings_key = scene_files_key(scene);
    settings_key.extend([
        ("--lf".to_string(), format!("{:?} ({}x{} views)", args.light_field.layout.lf, lf.cols, lf.rows)),
        // The spacing in effect, so an explicit --spacing equal to the preset's is the same run.
        (
            "--spacing".to_string(),
            args.light_field.layout.settings().spacing_on(&lf.rig).unwrap_or(DEFAULT_SPACING).to_string(),
        ),
        ("--resolution".to_string(), format!("{}x{}", lf.width, lf.height)),
        ("--focus".to_string(), format!("{focus}")),
        ("--camera".to_string(), format!("{:?}", args.scene.camera.map(|c| c.camera))),
        ("--views".to_string(), format!("{selected:?}")),
        ("--cpu".to_string(), args.cpu.to_string()),
        ("--chunk-spp".to_string(), args.chunk_spp.to_string()),
        ("--max-depth".to_string(), args.depth.max_depth.to_string()),
        ("--sun".to_string(), format!("{:?}", scene.sun)),
        ("--sky".to_string(), format!("{:?}", scene.sky)),
    ]);
    settings_key
}

/// Creates and locks `--out-dir` and checks, before any tracing, that it can take every file
/// the run writes; removes temporaries an interrupted run left. The lock lives as long as the
/// returned guard.
fn prepare_out_dir(out_dir: &Path, selected: &[u32]) -> Result<parallax_render::outputs::FolderLock> {
    parallax_render::outputs::create_folder(out_dir)
        .with_context(|| format!("cannot create --out-dir {}", out_dir.display()))?;
    let lock = parallax_render::outputs::lock_folder(out_dir, "--out-dir")?;
    // Found now rather than at the first checkpoint, after the tracing: a folder that cannot
    // take files (read-only, immutable) or a folder where a view's file goes.
    if let Err(e) = tempfile::NamedTempFile::new_in(out_dir) {
        let why = parallax_accuracy::write_failure(out_dir, &e);
        bail!("--out-dir {}: the folder is not writable: {why}", out_dir.display());
    }
    let names = selected.iter().map(|v| format!("view_{v:03}.exr"));
    parallax_render::outputs::check_targets_in(
        out_dir,
        names.chain(["reference.json", "reference.png", PARTIAL_FILE].map(String::from)),
        "--out-dir",
    )?;
    remove_stale_temporaries(out_dir);
    Ok(lock)
}

/// The sums of an earlier run of the same settings from `partial`, or empty ones.
fn resume_or_start(
    partial: &Path,
    settings_key: BTreeMap<String, String>,
    views: usize,
    size: (usize, usize),
    chunk_spp: u32,
) -> Result<Accumulator> {
    if !partial.exists() {
        return Ok(Accumulator::new(settings_key, views, size, chunk_spp));
    }
    let acc = Accumulator::load(partial)?;
    acc.check_settings(&settings_key, partial)?;
    let h = &acc.header;
    if (h.views, h.width, h.height, h.chunk_spp) != (views, size.0, size.1, chunk_spp) {
        bail!(
            "{}: its header holds {} view(s) of {}x{} in chunks of {} spp, but its settings say {} of {}x{} in \
             chunks of {}: the file was edited; delete it to start over",
            partial.display(),
            h.views,
            h.width,
            h.height,
            h.chunk_spp,
            views,
            size.0,
            size.1,
            chunk_spp
        );
    }
    tracing::info!("resuming {} at {} spp", partial.display(), acc.header.spp);
    Ok(acc)
}

/// Traces chunks until `acc` reaches `--spp`, writing a checkpoint every `--checkpoint-secs`
/// (the last one is written by the caller, with the outputs).
fn trace_to_target(
    args: &ReferenceArgs,
    tracer: &mut Tracer<'_>,
    scene: &Scene,
    views: &[View],
    acc: &mut Accumulator,
    selected: &[u32],
) -> Result<()> {
    let target = u64::from(args.spp);
    // Hidden under -q, like every progress bar of the CLI.
    let bar = crate::logging::bar(target);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} spp ({per_sec}, {eta} left)")
            .context("progress bar template")?,
    );
    bar.set_position(acc.header.spp);
    // The rate, and so the ETA, counts only this run's chunks.
    bar.reset_eta();
    let mut last_checkpoint = Instant::now();
    while acc.header.spp < target {
        let settings = TraceSettings {
            spp: args.chunk_spp,
            max_depth: args.depth.max_depth,
            frame: acc.next_frame(),
            ..Default::default()
        };
        let t = Instant::now();
        let chunk = tracer.chunk(scene, views, &settings)?;
        acc.add_chunk(&chunk, t.elapsed().as_secs_f64());
        bar.set_position(acc.header.spp);
        if acc.header.spp < target && last_checkpoint.elapsed().as_secs_f64() >= args.checkpoint_secs {
            bar.suspend(|| write_checkpoint(&args.out_dir, acc, selected)).context("writing a checkpoint")?;
            last_checkpoint = Instant::now();
        }
    }
    bar.finish_and_clear();
    Ok(())
}

/// The EXRs of the current mean (spp in their attributes), then the sidecar: a crash between
/// the two leaves a sidecar that is older than the EXRs, never newer, and resuming rewrites them.
fn write_checkpoint(dir: &Path, acc: &Accumulator, selected: &[u32]) -> Result<()> {
    let (w, h) = (acc.header.width, acc.header.height);
    for (i, v) in selected.iter().enumerate() {
        let image = RgbImage::new(w, h, acc.mean(i));
        // One attribute: the EXR writer keeps attributes in a hash map, so several would be
        // written in a different order each run.
        let attributes = [("parallaxSpp", acc.header.spp.to_string())];
        image.write_exr(&dir.join(format!("view_{v:03}.exr")), &attributes)?;
    }
    acc.save(&dir.join(PARTIAL_FILE))?;
    Ok(())
}

fn write_outputs(
    args: &ReferenceArgs,
    acc: &Accumulator,
    selected: &[u32],
    (lf, setup): (&LightField, &Setup),
    seconds_this_run: f64,
    devices: Option<usize>,
) -> Result<()> {
    write_checkpoint(&args.out_dir, acc, selected)?;
    let h = &acc.header;
    let frames: Vec<Frame> = (0..selected.len())
        .map(|i| Frame {
            width: h.width as u32,
            height: h.height as u32,
            pixels: acc
                .mean(i)
                .into_iter()
                .map(|p| PixelSample { radiance: glam::Vec3::from_array(p), ..Default::default() })
                .collect(),
        })
        .collect();
    let sheet = args.out_dir.join("reference.png");
    let columns = if selected.len() == lf.len() { lf.cols } else { selected.len().min(8) as u32 };
    let mut average = LogAverage::default();
    for frame in &frames {
        let radiance: Vec<[f32; 3]> = frame.pixels.iter().map(|p| p.radiance.to_array()).collect();
        average.add_image(frame.width as usize, &radiance);
    }
    let exposure = args.exposure.resolve(&average);
    write_contact_sheet(&sheet, &frames.iter().collect::<Vec<_>>(), columns, exposure)?;
    let (mean, standard_error) = acc.mean_and_standard_error();
    // One "frame" of the reference is one sample per pixel of every selected view.
    let ms_per_spp = h.seconds * 1e3 / h.spp.max(1) as f64;
    let point = Point {
        label: format!("reference, {} spp", h.spp),
        series: Some("reference".into()),
        frame_ms: Some(ms_per_spp),
        devices: devices.map(|d| d as u32),
        views: Some(selected.len() as u32),
        ..Default::default()
    };
    let json = serde_json::json!({
            "spp": h.spp, "chunks": h.chunks, "chunk_spp": h.chunk_spp,
            "seconds": h.seconds, "seconds_this_run": seconds_this_run, "ms_per_spp": ms_per_spp,
            "tracer": if args.cpu { "cpu" } else { "gpu" }, "devices": devices,
            "views": selected, "width": h.width, "height": h.height,
            "exposure": exposure, "exposure_mode": args.exposure.mode(), "setup": setup,
            "mean_radiance": mean, "standard_error": standard_error, "point": point,
    });
    let bytes = serde_json::to_vec_pretty(&json)?;
    write_atomically(&args.out_dir.join("reference.json"), |f| std::io::Write::write_all(f, &bytes))?;
    crate::logging::result(
        false,
        &format!(
            "reference: {} views of {}x{} at {} spp in {:.2} s of tracing ({:.2} ms per spp); mean radiance {} ± {} (standard error)",
            selected.len(),
            h.width,
            h.height,
            h.spp,
            h.seconds,
            ms_per_spp,
            rgb(mean.map(|m| format!("{m:.5}"))),
            rgb(standard_error.map(|e| format!("{e:.2e}")))
        ),
    );
    crate::logging::result(
        false,
        &format!(
            "wrote {} view EXRs, {}, reference.json and {PARTIAL_FILE} to {}",
            selected.len(),
            sheet.display(),
            args.out_dir.display()
        ),
    );
    Ok(())
}

/// `(r, g, b)` of three formatted numbers.
fn rgb(c: [String; 3]) -> String {
    format!("({}, {}, {})", c[0], c[1], c[2])
}

#[cfg(test)]
mod tests {
    use super::parse_views;

    #[test]
    fn view_lists() {
        assert_eq!(parse_views("3,0-2,2", 8).unwrap(), vec![0, 1, 2, 3]);
        assert!(parse_views("7-9", 8).unwrap_err().to_string().contains("0..=7"));
        assert!(parse_views("x", 8).is_err());
        assert!(parse_views("3-1", 8).is_err());
    }
}
