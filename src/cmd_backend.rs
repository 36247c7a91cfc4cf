//! Backend subcommands: `parallax devices` (which Vulkan devices would run), `parallax run`
//! (compile a demo pipeline and execute it on the devices, with timing report and trace), and
//! `parallax bench-copy` (cross-device copy bandwidth and executor overhead).
//!
//! `parallax run` executes the backend's own demo kernels (`fill` → `shift_blend` reading the
//! view's first source → exported output), not the path tracer: the passes crate plugs in the
//! real kernels attached where the graph declares its passes.

use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Args;
use parallax_backend::bench::{CopyBenchOptions, OverheadBenchOptions, copy_bandwidth, executor_overhead};
use std::sync::Arc;

use parallax_backend::kernels::{FillKernel, ShiftBlendKernel};
use parallax_backend::{
    Context, ContextDesc, DeviceSelection, ExecOptions, Executor, FrameReport, chrome_trace, write_json,
};
use parallax_backend::{KernelGraph, PassKernel};
use parallax_graph::{Format, LayoutSpec, LightField, PlanConfig, Rig, Role, compile, lightfield};

/// Which Vulkan devices to use.
#[derive(Args, Debug, Clone)]
pub struct DeviceArgs {
    /// Use N physical GPUs.
    #[arg(long, conflicts_with = "fake_devices")]
    gpus: Option<usize>,
    /// Use N logical devices on one physical device (how lavapipe runs multi-device code).
    #[arg(long)]
    fake_devices: Option<usize>,
}

impl DeviceArgs {
    pub(crate) fn selection(&self) -> DeviceSelection {
        match (self.gpus, self.fake_devices) {
            (Some(n), _) => DeviceSelection::Gpus(n),
            (None, Some(n)) => DeviceSelection::FakeDevices(n),
            (None, None) => DeviceSelection::Gpus(1),
        }
    }
}

#[derive(Args, Debug)]
pub struct DevicesArgs {
    #[command(flatten)]
    devices: DeviceArgs,
}

/// `parallax devices`: create the devices and print them.
pub fn devices(args: DevicesArgs) -> Result<()> {
    let context = Context::new(&ContextDesc::from_env(args.devices.selection()))?;
    print!("{context}");
    context.check_validation()?;
    Ok(())
}

#[derive(Args, Debug)]
pub struct RunArgs {
    #[command(flatten)]
    devices: DeviceArgs,
    /// Light-field layout: multiscopic, nelf or WxH.
    #[arg(long, default_value = "4x1")]
    lf: String,
    /// Partitioning scheme: multi-source, fine-sources or fine-all.
    #[arg(long, default_value = "fine-all")]
    scheme: String,
    /// How views are grouped into sets (multi-source).
    #[arg(long, default_value = "compact")]
    assign: String,
    /// Explicit source views for the fine-grained schemes, e.g. 0,3.
    #[arg(long)]
    sources: Option<String>,
    /// Per-view resolution WxH.
    #[arg(long, default_value = "64x64")]
    resolution: String,
    /// Frames to execute.
    #[arg(long, default_value_t = 3)]
    frames: usize,
    /// Frames submitted before the host waits for the oldest.
    #[arg(long, default_value_t = 2)]
    frames_in_flight: usize,
    /// Submit copies to the main queue instead of a transfer-only queue (the copy engines,
    /// used by default where the devices have one).
    #[arg(long)]
    copies_on_main_queue: bool,
    /// Write the per-frame timing reports as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write a Chrome trace-event JSON (open in Perfetto or chrome://tracing).
    #[arg(long)]
    trace: Option<PathBuf>,
}

/// `parallax run`: plan, compile, execute, report.
pub fn run(args: RunArgs) -> Result<()> {
    let selection = args.devices.selection();
    let spec: LayoutSpec = args.lf.parse()?;
    let Some(resolution) = lightfield::parse_pair(&args.resolution) else {
        bail!("--resolution '{}' is not WxH (e.g. 64x64)", args.resolution);
    };
    let lf = LightField::new(spec, None, Some(resolution), Rig::default())?;
    let config = PlanConfig {
        devices: selection.count() as u32,
        scheme: args.scheme.parse()?,
        assign: args.assign.parse()?,
        sources: args.sources.as_deref().map(parallax_graph::parse_source_list).transpose()?,
    };
    let plan = parallax_graph::Plan::new(&lf, &config)?;
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    let mut radiance = graph.image("radiance", Format::Rgba32f);
    let mut output = graph.image("output", Format::Rgba32f);
    let fill: Arc<dyn PassKernel> = Arc::new(FillKernel);
    graph.pass("fill", Role::Sources).write(&mut radiance).kernel(fill.clone()).record();
    graph.pass("fill", Role::Targets).write(&mut radiance).kernel(fill).record();
    graph
        .pass("shift_blend", Role::All)
        .read(&radiance)
        .read_sources(&radiance)
        .write(&mut output)
        .kernel(Arc::new(ShiftBlendKernel))
        .record();
    graph.export(&output);
    let schedule = compile(&graph, &plan)?;
    let report = schedule.validate();
    if !report.is_ok() {
        bail!("internal error: the compiled schedule breaks {} invariant(s)", report.errors.len());
    }

    let context = Context::new(&ContextDesc::from_env(selection))?;
    print!("{context}");
    let exec_plan = parallax_backend::ExecutionPlan::from_schedule(&graph, &schedule)?;
    let options = ExecOptions {
        frames_in_flight: args.frames_in_flight,
        separate_copy_queue: !args.copies_on_main_queue,
        ..ExecOptions::default()
    };
    let mut executor = Executor::new(&context, exec_plan, options)?;
    for _ in 0..args.frames {
        executor.run_frame()?;
    }
    executor.finish()?;
    let reports = executor.take_reports();
    drop(executor);
    context.check_validation()?;
    for r in &reports {
        print_frame(r);
    }
    if let Some(path) = &args.json {
        write_json(path, &reports).with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.trace {
        write_json(path, &chrome_trace(&reports, &context.device_infos()))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn print_frame(r: &FrameReport) {
    let busy: Vec<String> = r.devices.iter().map(|d| format!("{:.0}%", d.busy_fraction * 100.0)).collect();
    println!(
        "frame {}: wall {:.3} ms, GPU span {:.3} ms, {} passes in {} submissions ({:.1} µs CPU), busy {}",
        r.frame,
        r.frame_wall_ns as f64 / 1e6,
        r.gpu_span_ns as f64 / 1e6,
        r.submitted_passes,
        r.submitted_segments,
        r.submit_cpu_ns as f64 / 1e3,
        busy.join(" / ")
    );
}

#[derive(Args, Debug)]
pub struct BenchCopyArgs {
    #[command(flatten)]
    devices: DeviceArgs,
    /// Bytes moved from device 0 to device 1 per frame, in MiB.
    #[arg(long, default_value_t = 64)]
    size_mib: u64,
    /// Chunk size in MiB (copies are pipelined chunk by chunk); 0 = one chunk.
    #[arg(long, default_value_t = 8)]
    chunk_mib: u64,
    /// Measured frames (after 3 warm-up frames).
    #[arg(long, default_value_t = 30)]
    frames: usize,
    /// Frames submitted before the host waits for the oldest (1 = every copy runs alone).
    #[arg(long, default_value_t = 2)]
    frames_in_flight: usize,
    /// Submit copies to the main queue instead of a transfer-only queue (the copy engines,
    /// used by default where the devices have one).
    #[arg(long)]
    copies_on_main_queue: bool,
    /// Tiny passes per device for the executor-overhead measurement.
    #[arg(long, default_value_t = 256)]
    passes_per_device: u32,
    #[arg(long)]
    json: Option<PathBuf>,
    /// Chrome trace of the copy frames.
    #[arg(long)]
    trace: Option<PathBuf>,
}

/// `parallax bench-copy`: copy bandwidth between devices 0 and 1, and executor CPU cost.
pub fn bench_copy(args: BenchCopyArgs) -> Result<()> {
    let selection = args.devices.selection();
    if selection.count() < 2 {
        bail!("bench-copy needs two devices: --gpus 2 or --fake-devices 2");
    }
    let desc = ContextDesc::from_env(selection);
    let copy_options = CopyBenchOptions {
        bytes: args.size_mib << 20,
        chunk_bytes: if args.chunk_mib == 0 { u64::MAX } else { args.chunk_mib << 20 },
        frames: args.frames,
        frames_in_flight: args.frames_in_flight,
        separate_copy_queue: !args.copies_on_main_queue,
        ..CopyBenchOptions::default()
    };
    let copy = copy_bandwidth(&desc, &copy_options)?;
    for d in &copy.devices {
        println!("device {}: {} ({} {}, Vulkan {})", d.index, d.name, d.driver, d.driver_info, d.api_version);
    }
    println!(
        "copy {} MiB device 0 -> 1, {} chunk(s), {} frame(s) in flight: sustained {:.2} GB/s; per frame median {:.2} GB/s, best {:.2} GB/s (while copying: D->H {:.2}, H->D {:.2})",
        args.size_mib,
        copy.chunks,
        args.frames_in_flight,
        copy.sustained_gb_per_s,
        copy.median_gb_per_s,
        copy.best_gb_per_s,
        copy.median_device_to_host_gb_per_s,
        copy.median_host_to_device_gb_per_s
    );
    let overhead_options = OverheadBenchOptions { passes_per_device: args.passes_per_device, ..Default::default() };
    let overhead = executor_overhead(&desc, &overhead_options)?;
    println!(
        "executor: {:.3} µs CPU per submitted pass ({} passes/frame, {:.1} µs/frame); recording once {:.2} µs/pass",
        overhead.median_submit_us_per_pass,
        overhead.passes_per_frame,
        overhead.median_submit_us_per_frame,
        overhead.record_us_per_pass
    );
    if let Some(path) = &args.json {
        write_json(path, &serde_json::json!({ "copy": &copy, "overhead": &overhead }))?;
    }
    if let Some(path) = &args.trace {
        write_json(path, &chrome_trace(&copy.reports, &copy.devices))?;
    }
    Ok(())
}
