//! `parallax trace`: path trace one view of a scene and write it as EXR (+ optional PNG), on
//! the GPU through the `path_trace` pass (the view in row bands over the selected devices,
//! gathered on device 0) or with `--cpu` on the CPU reference.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use parallax_backend::{Context as VkContext, ContextDesc, DeviceSelection, EventKind};
use parallax_passes::{GpuTracer, PATH_TRACE, banded_trace_plan, to_pixel_sample, trace_kernels};
use parallax_scene::gpu::GpuScene;
use parallax_scene::output::{ExrLayers, write_contact_sheet, write_exr};
use parallax_scene::{Camera, CpuTracer, Frame, Scene, SceneBvh, Sky, Sun, TraceSettings, View, load_scene};

#[derive(Debug, clap::Args)]
pub struct TraceArgs {
    /// glTF file (.gltf/.glb) or `default` for the embedded default scene.
    #[arg(long, default_value = "default")]
    pub scene: String,
    /// Camera as `eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z,yfov_degrees`;
    /// without it the scene's first camera (or one framing the whole scene) is used.
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Image size as WxH.
    #[arg(long, default_value = "512x512")]
    pub resolution: String,
    /// Samples per pixel.
    #[arg(long, default_value_t = 1)]
    pub spp: u32,
    /// Maximum number of scattering events per path.
    #[arg(long, default_value_t = 6)]
    pub max_depth: u32,
    /// Output EXR (radiance; with --layers also albedo, normal and depth).
    #[arg(long, default_value = "trace.exr")]
    pub out: PathBuf,
    /// Also write albedo, normal and depth layers into the EXR.
    #[arg(long)]
    pub layers: bool,
    /// Also write a tonemapped PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Exposure multiplier for the PNG.
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
    /// Trace on the CPU reference path tracer instead of the GPU.
    #[arg(long)]
    pub cpu: bool,
    /// GPU tracing on N physical GPUs (the view is split into row bands over them).
    #[arg(long, conflicts_with_all = ["fake_devices", "cpu"])]
    pub gpus: Option<usize>,
    /// GPU tracing on N logical devices of one physical device (how lavapipe runs multi-device
    /// code).
    #[arg(long, conflicts_with = "cpu")]
    pub fake_devices: Option<usize>,
    /// Frame index (part of the random-number key).
    #[arg(long, default_value_t = 0)]
    pub frame: u32,
    /// Sun as `to_sun_x,to_sun_y,to_sun_z,irradiance[,angular_radius_degrees]`; replaces the
    /// scene's sun.
    #[arg(long, allow_hyphen_values = true)]
    pub sun: Option<String>,
    /// Remove the scene's sun.
    #[arg(long, conflicts_with = "sun")]
    pub no_sun: bool,
    /// Constant sky radiance `r,g,b`, or a gradient `zenith_rgb,horizon_rgb,ground_rgb` (9 values).
    #[arg(long)]
    pub sky: Option<String>,
    /// Turn on Russian roulette from this bounce on (off by default).
    #[arg(long)]
    pub russian_roulette_from: Option<u32>,
}

fn parse_floats(what: &str, s: &str) -> anyhow::Result<Vec<f32>> {
    s.split(',')
        .map(|p| {
            let v: f32 = p.trim().parse().with_context(|| format!("--{what}: '{p}' is not a number"))?;
            if !v.is_finite() {
                bail!("--{what}: '{p}' is not finite");
            }
            Ok(v)
        })
        .collect()
}

pub(crate) fn parse_resolution(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s.split_once(['x', 'X']).with_context(|| format!("--resolution '{s}': expected WxH, e.g. 512x512"))?;
    let w: u32 = w.trim().parse().with_context(|| format!("--resolution '{s}': bad width"))?;
    let h: u32 = h.trim().parse().with_context(|| format!("--resolution '{s}': bad height"))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        bail!("--resolution '{s}': width and height must be 1..=16384");
    }
    Ok((w, h))
}

pub(crate) fn parse_camera(s: &str) -> anyhow::Result<Camera> {
    let v = parse_floats("camera", s)?;
    if v.len() != 10 {
        bail!("--camera: expected 10 numbers eye(3),target(3),up(3),yfov_degrees; got {}", v.len());
    }
    let eye = Vec3::new(v[0], v[1], v[2]);
    let target = Vec3::new(v[3], v[4], v[5]);
    let up = Vec3::new(v[6], v[7], v[8]);
    if (target - eye).length() == 0.0 || up.length() == 0.0 {
        bail!("--camera: eye and target must differ and up must be non-zero");
    }
    if !(0.1..179.0).contains(&v[9]) {
        bail!("--camera: yfov {} degrees is outside 0.1..179", v[9]);
    }
    Ok(Camera::look_at(eye, target, up, v[9].to_radians()))
}

pub(crate) fn parse_sun(s: &str) -> anyhow::Result<Sun> {
    let v = parse_floats("sun", s)?;
    if v.len() != 4 && v.len() != 5 {
        bail!("--sun: expected to_sun_x,to_sun_y,to_sun_z,irradiance[,angular_radius_degrees]");
    }
    let dir = Vec3::new(v[0], v[1], v[2]);
    if dir.length() == 0.0 || v[3] < 0.0 {
        bail!("--sun: direction must be non-zero and irradiance non-negative");
    }
    let radius = v.get(4).copied().unwrap_or(0.27);
    if !(0.0..=45.0).contains(&radius) {
        bail!("--sun: angular radius {radius} degrees is outside 0..45");
    }
    Ok(Sun { to_sun: dir.normalize(), irradiance: Vec3::splat(v[3]), angular_radius: radius.to_radians() })
}

pub(crate) fn parse_sky(s: &str) -> anyhow::Result<Sky> {
    let v = parse_floats("sky", s)?;
    if v.iter().any(|&x| x < 0.0) {
        bail!("--sky: radiance must be non-negative");
    }
    match v.len() {
        3 => Ok(Sky::Constant(Vec3::new(v[0], v[1], v[2]))),
        9 => Ok(Sky::Gradient {
            zenith: Vec3::new(v[0], v[1], v[2]),
            horizon: Vec3::new(v[3], v[4], v[5]),
            ground: Vec3::new(v[6], v[7], v[8]),
        }),
        n => bail!("--sky: expected 3 (constant) or 9 (gradient) numbers, got {n}"),
    }
}

pub fn run(args: TraceArgs) -> anyhow::Result<()> {
    let (width, height) = parse_resolution(&args.resolution)?;
    let camera = args.camera.as_deref().map(parse_camera).transpose()?;
    let sun = args.sun.as_deref().map(parse_sun).transpose()?;
    let sky = args.sky.as_deref().map(parse_sky).transpose()?;

    let t0 = Instant::now();
    let mut scene = load_scene(&args.scene).with_context(|| format!("loading scene '{}'", args.scene))?;
    if let Some(sun) = sun {
        scene.sun = Some(sun);
    }
    if args.no_sun {
        scene.sun = None;
    }
    if let Some(sky) = sky {
        scene.sky = Some(sky);
    }
    let load_time = t0.elapsed();
    let bvh = SceneBvh::build(&scene);
    eprintln!(
        "scene '{}': {} triangles, {} materials, {} textures; loaded in {:.2?}; CWBVH {} nodes built in {:.2?}",
        scene.name,
        scene.triangle_count(),
        scene.materials.len(),
        scene.textures.len(),
        load_time,
        bvh.node_count(),
        bvh.build_time
    );

    let view = View { camera: camera.unwrap_or_else(|| scene.default_camera()), width, height, index: 0 };
    let settings = TraceSettings {
        spp: args.spp,
        max_depth: args.max_depth,
        frame: args.frame,
        russian_roulette_from: args.russian_roulette_from,
        ..Default::default()
    };
    settings.validate()?;
    let frame = if args.cpu {
        trace_cpu(&scene, &bvh, &view, &settings)?
    } else {
        let selection = match (args.gpus, args.fake_devices) {
            (Some(n), _) => DeviceSelection::Gpus(n),
            (None, Some(n)) => DeviceSelection::FakeDevices(n),
            (None, None) => DeviceSelection::Gpus(1),
        };
        trace_gpu(selection, &scene, &bvh, &view, &settings)?
    };

    let layers = if args.layers { ExrLayers::ALL } else { ExrLayers::default() };
    write_exr(&args.out, &frame, layers)?;
    eprintln!("wrote {}", args.out.display());
    if let Some(png) = &args.png {
        write_contact_sheet(png, &[&frame], 1, args.exposure)?;
        eprintln!("wrote {}", png.display());
    }
    Ok(())
}

fn trace_cpu(scene: &Scene, bvh: &SceneBvh, view: &View, settings: &TraceSettings) -> anyhow::Result<Frame> {
    let tracer = CpuTracer::new(scene, bvh);
    let bar = ProgressBar::new(view.pixel_count() as u64);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {percent}% ({eta} left)")
            .context("progress bar template")?,
    );
    let t1 = Instant::now();
    let (frame, stats) = tracer.render(view, settings, &|n| bar.inc(n))?;
    bar.finish_and_clear();
    let secs = t1.elapsed().as_secs_f64();
    eprintln!(
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

/// One frame of the `path_trace` pass: the view in one row band per selected device, gathered
/// on device 0. The GPU drops non-finite samples as the CPU does.
fn trace_gpu(
    selection: DeviceSelection,
    scene: &Scene,
    bvh: &SceneBvh,
    view: &View,
    settings: &TraceSettings,
) -> anyhow::Result<Frame> {
    let context = VkContext::new(&ContextDesc::from_env(selection))?;
    eprint!("{context}");
    let devices = selection.count() as u32;
    let plan = banded_trace_plan(1, (view.width, view.height), devices, devices as usize);
    let mut tracer = GpuTracer::new(&context, plan, trace_kernels(None), &GpuScene::new(scene, bvh))?;
    let spinner = ProgressBar::new_spinner();
    spinner.set_message(format!("tracing {}x{} at {} spp on the GPU", view.width, view.height, settings.spp));
    spinner.enable_steady_tick(std::time::Duration::from_millis(200));
    let t1 = Instant::now();
    let pixels = tracer.render(scene, std::slice::from_ref(view), settings)?.remove(0);
    spinner.finish_and_clear();
    let secs = t1.elapsed().as_secs_f64();
    // GPU time: from the first path_trace band's start to the last one's end, any device.
    let events: Vec<_> = tracer
        .executor()
        .take_reports()
        .into_iter()
        .flat_map(|r| r.events)
        .filter(|e| e.kind == EventKind::Pass && e.name == PATH_TRACE)
        .collect();
    let gpu_ms = match (events.iter().map(|e| e.start_ns).min(), events.iter().map(|e| e.end_ns).max()) {
        (Some(start), Some(end)) => end.saturating_sub(start) as f64 / 1e6,
        _ => f64::NAN,
    };
    drop(tracer);
    context.check_validation()?;
    eprintln!(
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
    Ok(Frame { width: view.width, height: view.height, pixels: pixels.iter().map(to_pixel_sample).collect() })
}
