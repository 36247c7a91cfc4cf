//! `parallax bench-rays`: rays/s of the GPU traversal (the `raycast` pass) for primary and
//! diffuse-bounce rays, and the CWBVH build time; see parallax_passes::bench.

use std::time::Instant;

use parallax_backend::{Context, ContextDesc, DeviceSelection};
use parallax_passes::RaySchedule;
use parallax_passes::bench::{RayRate, bench_rays};
use parallax_scene::Camera;

use crate::logging::{result, spinner};
use crate::options::sink_parser;
use crate::options::{BvhQualityArg, MAX_DEVICES, Resolution, count_in, parse_camera, parse_resolution};
use parallax_render::outputs::budget::TraceWork;
use parallax_render::outputs::{Format, Output, Sink, check, write_json};

#[derive(Debug, clap::Args)]
pub struct BenchRaysArgs {
    /// glTF file (.gltf/.glb) or `default` for the embedded default scene.
    #[arg(long, default_value = "default")]
    pub scene: std::path::PathBuf,
    /// Let the scene's URIs name files outside its folder (`../`, absolute, `file:`).
    #[arg(long)]
    pub allow_outside_files: bool,
    /// Primary rays: one per pixel centre of a WxH image.
    #[arg(long, default_value = "1024x1024", value_name = "WxH", value_parser = parse_resolution)]
    pub resolution: Resolution,
    /// Camera as `eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z,yfov_degrees`;
    /// without it the scene's first camera (or one framing the whole scene).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_camera)]
    pub camera: Option<Camera>,
    /// obvhs BVH build preset.
    #[arg(long, value_enum, default_value_t = BvhQualityArg::Medium)]
    pub bvh_quality: BvhQualityArg,
    /// Timed casts per batch, after one untimed warm-up cast; the median GPU time is reported.
    #[arg(long, allow_negative_numbers = true, default_value_t = 9, value_parser = count_in(1..=1000))]
    pub repeats: u64,
    /// Create N logical devices on one physical device and measure on the first (how it runs
    /// on lavapipe); by default the first GPU.
    #[arg(long, allow_negative_numbers = true, value_parser = count_in(1..=MAX_DEVICES as u64))]
    pub fake_devices: Option<u64>,
    /// Ray schedules of the `raycast` kernel to measure side by side on the same rays
    /// (comma-separated): `per-ray`, or `persistent:THRESHOLD:WORKGROUPS`.
    /// The default compares one ray per invocation with persistent subgroups refilling at 4
    /// idle lanes, 2112 workgroups (16 per SM of an H100; more are harmless).
    #[arg(long, value_delimiter = ',', default_value = "per-ray,persistent:4:2112")]
    pub schedule: Vec<RaySchedule>,
    /// Write the measurements as JSON (.json; `-` = stdout).
    #[arg(long, value_parser = sink_parser())]
    pub json: Option<Sink>,
}

pub fn run(args: BenchRaysArgs) -> anyhow::Result<()> {
    let (width, height) = args.resolution.pair();
    if let Some(sink) = &args.json {
        check(&[Output { flag: "--json", sink, format: Format::Json }])?;
    }
    let work = TraceWork::one_view(width, height, 1, args.fake_devices.unwrap_or(1));
    work.check_host()?;
    let t0 = Instant::now();
    let scene = parallax_render::scene::load_scene(&args.scene, args.allow_outside_files)?;
    if let Some(Sink::File(json)) = &args.json {
        let inputs: Vec<(&str, &std::path::Path)> =
            scene.sources.iter().map(|s| ("--scene", s.path.as_path())).collect();
        parallax_render::outputs::check_inputs(&[("--json", json)], &inputs)?;
    }
    tracing::info!("scene '{}': {} triangles, loaded in {:.2?}", scene.name, scene.triangle_count(), t0.elapsed());
    let selection = args.fake_devices.map_or(DeviceSelection::Gpus(1), |n| DeviceSelection::FakeDevices(n as usize));
    let context = Context::new(&ContextDesc::from_env(selection))?;
    work.check_devices(&context)?;
    let camera = args.camera.unwrap_or_else(|| scene.default_camera());
    let progress = spinner(format!("casting {width}x{height} rays under {} schedule(s)", args.schedule.len()));
    let report = bench_rays(
        &context,
        scene,
        camera,
        (width, height),
        args.repeats as usize,
        args.bvh_quality.into(),
        &args.schedule,
    )?;
    progress.finish_and_clear();
    context.check_validation()?;
    let say = |line: String| result(matches!(args.json, Some(Sink::Stdout)), &line);
    say(format!("device: {}", report.device));
    say(format!(
        "CWBVH: {} triangles, {} nodes, build {:.1} ms (obvhs core {:.1} ms)",
        report.triangles, report.bvh_nodes, report.bvh_build_ms, report.bvh_core_build_ms
    ));
    let line = |what: &str, r: &RayRate| {
        say(format!(
            "{what}: {} rays, {:.3} ms median ({:.3} best) -> {:.3e} rays/s",
            r.rays, r.median_ms, r.best_ms, r.rays_per_s
        ))
    };
    for s in &report.schedules {
        say(format!("schedule {}:", s.schedule));
        line("  primary, closest hit", &s.primary);
        line("  diffuse bounce, closest hit", &s.diffuse_bounce);
        line("  diffuse bounce, any hit", &s.diffuse_bounce_any_hit);
    }
    if let Some(sink) = &args.json {
        write_json(sink, &report)?;
    }
    Ok(())
}
