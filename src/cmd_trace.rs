//! `parallax trace`: path trace one view of a scene and write it as EXR (+ optional PNG), on
//! the GPU through the `path_trace` pass (the view in row bands over the selected devices,
//! gathered on device 0) or with `--cpu` on the CPU reference.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use parallax_accuracy::exposure::LogAverage;
use parallax_backend::DeviceSelection;
use parallax_scene::output::{ExrLayers, write_contact_sheet, write_exr};
use parallax_scene::{CpuTracer, Frame, Scene, SceneBvh, TraceSettings, View};

use crate::logging::{bar, spinner};
use crate::options::{Exposure, MAX_DEVICES, Resolution, count_in, parse_exposure, parse_resolution, selection};
use crate::scene_args::{DepthArgs, SceneArgs};
use parallax_render::outputs::budget::TraceWork;
use parallax_render::outputs::{Format, Output, Sink, check, stage};
use parallax_render::trace_run::{GpuTraceSettings, GpuTracer};

#[derive(Debug, clap::Args)]
pub struct TraceArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Image size as WxH.
    #[arg(long, default_value = "512x512", value_name = "WxH", value_parser = parse_resolution)]
    pub resolution: Resolution,
    /// Samples per pixel.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub spp: u32,
    #[command(flatten)]
    pub depth: DepthArgs,
    /// Output EXR (radiance; with --layers also albedo, normal and depth).
    #[arg(long, default_value = "trace.exr")]
    pub out: PathBuf,
    /// Also write albedo, normal and depth layers into the EXR.
    #[arg(long)]
    pub layers: bool,
    /// Also write a tonemapped PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Exposure of the PNG: `auto` (the log-average luminance of the image mapped to 0.18,
    /// computed on the host from the traced radiance) or a multiplier > 0.
    #[arg(long, allow_negative_numbers = true, default_value = "auto", value_parser = parse_exposure)]
    pub exposure: Exposure,
    /// Trace on the CPU reference path tracer instead of the GPU.
    #[arg(long)]
    pub cpu: bool,
    /// GPU tracing on N physical GPUs (1..=64; the view is split into row bands over them).
    #[arg(long, allow_negative_numbers = true, conflicts_with_all = ["fake_devices", "cpu"], value_parser = count_in(1..=MAX_DEVICES as u64))]
    pub gpus: Option<u64>,
    /// GPU tracing on N logical devices of one physical device (1..=64; how lavapipe runs
    /// multi-device code).
    #[arg(long, allow_negative_numbers = true, conflicts_with = "cpu", value_parser = count_in(1..=MAX_DEVICES as u64))]
    pub fake_devices: Option<u64>,
    /// Frame index (part of the random-number key).
    #[arg(long, default_value_t = 0)]
    pub frame: u32,
    /// Turn on Russian roulette from this bounce on (off by default).
    #[arg(long)]
    pub russian_roulette_from: Option<u32>,
}

pub fn run(args: TraceArgs) -> anyhow::Result<()> {
    let (width, height) = args.resolution.pair();
    let out = Sink::File(args.out.clone());
    let png = args.png.clone().map(Sink::File);
    let mut outputs = vec![Output { flag: "--out", sink: &out, format: Format::Exr }];
    if let Some(sink) = &png {
        outputs.push(Output { flag: "--png", sink, format: Format::Png });
    }
    check(&outputs)?;
    let devices = if args.cpu { 0 } else { selection(args.gpus, args.fake_devices).count() as u64 };
    let work = TraceWork::one_view(width, height, args.spp, devices);
    parallax_render::outputs::budget::refuse_every_exceeded([work.check_duration(), work.check_host()])?;

    let t0 = Instant::now();
    let scene = args.scene.load()?;
    let mut written = vec![("--out", args.out.as_path())];
    written.extend(args.png.as_deref().map(|p| ("--png", p)));
    parallax_render::outputs::check_inputs(&written, &args.scene.settings().inputs(&scene))?;
    let load_time = t0.elapsed();
    let bvh = SceneBvh::build(&scene);
    tracing::info!(
        "scene '{}': {} triangles, {} materials, {} textures; loaded in {:.2?}; CWBVH {} nodes built in {:.2?}",
        scene.name,
        scene.triangle_count(),
        scene.materials.len(),
        scene.textures.len(),
        load_time,
        bvh.node_count(),
        bvh.build_time
    );

    let view = View { camera: args.scene.settings().camera_or_default(&scene), width, height, index: 0 };
    let settings = TraceSettings {
        spp: args.spp,
        max_depth: args.depth.max_depth,
        frame: args.frame,
        russian_roulette_from: args.russian_roulette_from,
        ..Default::default()
    };
    settings.validate()?;
    let frame = if args.cpu {
        trace_cpu(&scene, &bvh, &view, &settings)?
    } else {
        trace_gpu(selection(args.gpus, args.fake_devices), work, &scene, &bvh, &view, &settings)?
    };

    let layers = if args.layers { ExrLayers::ALL } else { ExrLayers::default() };
    let exr = stage(&args.out, |tmp| {
        write_exr(tmp, &frame, layers).with_context(|| format!("cannot write --out {}", args.out.display()))
    })?;
    let sheet = match &args.png {
        Some(path) => Some(stage(path, |tmp| {
            let mut average = LogAverage::default();
            let radiance: Vec<[f32; 3]> = frame.pixels.iter().map(|p| p.radiance.to_array()).collect();
            average.add_image(frame.width as usize, &radiance);
            let exposure = args.exposure.resolve(&average);
            tracing::info!("--png at exposure {exposure:.4} ({})", args.exposure.mode());
            write_contact_sheet(tmp, &[&frame], 1, exposure)
                .with_context(|| format!("cannot write --png {}", path.display()))
        })?),
        None => None,
    };
    exr.commit()?;
    tracing::info!("wrote {}", args.out.display());
    if let (Some(sheet), Some(path)) = (sheet, &args.png) {
        sheet.commit()?;
        tracing::info!("wrote {}", path.display());
    }
    Ok(())
}

fn trace_cpu(scene: &Scene, bvh: &SceneBvh, view: &View, settings: &TraceSettings) -> anyhow::Result<Frame> {
    let tracer = CpuTracer::new(scene, bvh);
    let bar = bar(view.pixel_count() as u64);
    let t1 = Instant::now();
    let (frame, stats) = tracer.render(view, settings, &|n| bar.inc(n))?;
    bar.finish_and_clear();
    let secs = t1.elapsed().as_secs_f64();
    tracing::info!(
        "traced {}x{} at {} spp, max depth {} on the CPU in {:.2} s ({:.2} Mpaths/s){}",
        view.width,
        view.height,
        settings.spp,
        settings.max_depth,
        secs,
        view.pixel_count() as f64 * settings.spp as f64 / secs / 1e6,
        if stats.non_finite_samples > 0 {
            format!("; {} non-finite samples discarded", stats.non_finite_samples)
        } else {
            String::new()
        }
    );
    Ok(frame)
}

/// One frame of the `path_trace` pass ([`GpuTracer`]): the view in one row band per selected
/// device, gathered on device 0.
fn trace_gpu(
    selection: DeviceSelection,
    work: TraceWork,
    scene: &Scene,
    bvh: &SceneBvh,
    view: &View,
    settings: &TraceSettings,
) -> anyhow::Result<Frame> {
    let gpu = GpuTraceSettings { devices: selection, views: 1, size: (view.width, view.height), timed: true };
    let mut tracer = GpuTracer::start(gpu, work, scene, bvh)?;
    let spinner = spinner(format!("tracing {}x{} at {} spp on the GPU", view.width, view.height, settings.spp));
    let t1 = Instant::now();
    let (frame, gpu_ms) = tracer.trace_frame(scene, view, settings)?;
    spinner.finish_and_clear();
    let secs = t1.elapsed().as_secs_f64();
    let devices = tracer.devices();
    tracer.finish()?;
    tracing::info!(
        "traced {}x{} at {} spp, max depth {} on {} device(s) in {:.2} s ({:.1} ms of GPU time, {:.2} Mpaths/s)",
        view.width,
        view.height,
        settings.spp,
        settings.max_depth,
        devices,
        secs,
        gpu_ms,
        view.pixel_count() as f64 * settings.spp as f64 / (gpu_ms * 1e-3) / 1e6
    );
    Ok(frame)
}
