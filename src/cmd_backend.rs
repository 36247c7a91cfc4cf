//! Backend subcommands: `parallax devices` (which Vulkan devices would run) and
//! `parallax bench-copy` (cross-device copy bandwidth and executor overhead).

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};
use parallax_backend::bench::{CopyBenchOptions, OverheadBenchOptions, copy_bandwidth, executor_overhead};
use parallax_backend::{BackendError, Context, ContextDesc, LinkKind, chrome_trace};

use crate::logging::result;
use crate::options::sink_parser;
use crate::options::{DeviceArgs, count_in};
use parallax_render::outputs::budget::check_host_bytes;
use parallax_render::outputs::{Format, Output, Sink, check, write_json};

#[derive(Args, Debug)]
pub struct DevicesArgs {
    #[command(flatten)]
    devices: DeviceArgs,
}

/// `parallax devices`: create the devices and print them.
pub fn devices(args: DevicesArgs) -> Result<()> {
    let selection = args.devices.selection();
    let progress = crate::logging::spinner(format!("creating {} device(s)", selection.count()));
    let context = Context::new(&ContextDesc::from_env(selection))?;
    progress.finish_and_clear();
    crate::logging::result(false, context.to_string().trim_end());
    context.check_validation()?;
    Ok(())
}

/// The JSON outputs of a command, checked before any work.
fn check_json_outputs(json: &Option<Sink>, trace: &Option<Sink>) -> Result<()> {
    let outputs: Vec<Output> = [("--json", json), ("--trace", trace)]
        .into_iter()
        .filter_map(|(flag, sink)| Some(Output { flag, sink: sink.as_ref()?, format: Format::Json }))
        .collect();
    check(&outputs)
}

/// `parallax run`: plan, compile, execute, report.
#[derive(Args, Debug)]
pub struct BenchCopyArgs {
    #[command(flatten)]
    devices: DeviceArgs,
    /// Bytes moved from device 0 to device 1 per frame, in MiB (1..=65536, and within host memory).
    #[arg(long, allow_negative_numbers = true, default_value_t = 64, value_parser = count_in(1..=65_536))]
    size_mib: u64,
    /// Chunk size in MiB (copies are pipelined chunk by chunk); 0 = one chunk.
    #[arg(long, allow_negative_numbers = true, default_value_t = 8, value_parser = count_in(0..=65_536))]
    chunk_mib: u64,
    /// Measured frames (after 3 warm-up frames; 1..=10000).
    #[arg(long, allow_negative_numbers = true, default_value_t = 30, value_parser = count_in(1..=10_000))]
    frames: u64,
    /// Frames submitted before the host waits for the oldest (1..=16; 1 = every copy runs alone).
    #[arg(long, allow_negative_numbers = true, default_value_t = 2, value_parser = count_in(1..=16))]
    frames_in_flight: u64,
    /// The link kinds to measure: `all` (each kind the two devices offer, best first; the
    /// others are named as unavailable), or one of `gpu`, `shared`, `relay` (refused if the
    /// devices cannot use it).
    #[arg(long, value_enum, default_value_t = BenchLink::All)]
    link: BenchLink,
    /// Submit copies to the main queue instead of a transfer-only queue (the copy engines,
    /// used by default where the devices have one).
    #[arg(long)]
    copies_on_main_queue: bool,
    /// Tiny passes per device for the executor-overhead measurement (1..=65536).
    #[arg(long, allow_negative_numbers = true, default_value_t = 256, value_parser = count_in(1..=65_536))]
    passes_per_device: u64,
    /// Write both measurements as JSON (`-` = stdout).
    #[arg(long, value_parser = sink_parser())]
    json: Option<Sink>,
    /// Chrome trace of the copy frames (`-` = stdout).
    #[arg(long, value_parser = sink_parser())]
    trace: Option<Sink>,
}

/// `bench-copy --link`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum BenchLink {
    All,
    Gpu,
    Shared,
    Relay,
}

impl BenchLink {
    /// The kinds asked for.
    fn kinds(self) -> Vec<LinkKind> {
        match self {
            BenchLink::All => LinkKind::ALL.to_vec(),
            BenchLink::Gpu => vec![LinkKind::Gpu],
            BenchLink::Shared => vec![LinkKind::Shared],
            BenchLink::Relay => vec![LinkKind::Relay],
        }
    }
}

/// `parallax bench-copy`: copy bandwidth between devices 0 and 1 over each link kind, and
/// executor CPU cost.
pub fn bench_copy(args: BenchCopyArgs) -> Result<()> {
    let selection = args.devices.selection();
    if selection.count() < 2 {
        bail!("bench-copy needs two devices: --gpus 2 or --fake-devices 2");
    }
    check_json_outputs(&args.json, &args.trace)?;
    // Every frame in flight holds its own copy in host memory shared by both devices.
    check_host_bytes(
        &format!("--size-mib {} with --frames-in-flight {}", args.size_mib, args.frames_in_flight),
        (args.size_mib << 20) * args.frames_in_flight,
        "lower --size-mib or --frames-in-flight",
    )?;
    let desc = ContextDesc::from_env(selection);
    let copy_options = CopyBenchOptions {
        bytes: args.size_mib << 20,
        chunk_bytes: if args.chunk_mib == 0 { u64::MAX } else { args.chunk_mib << 20 },
        frames: args.frames as usize,
        frames_in_flight: args.frames_in_flight as usize,
        separate_copy_queue: !args.copies_on_main_queue,
        ..CopyBenchOptions::default()
    };
    let say = |line: String| result([&args.json, &args.trace].iter().any(|s| matches!(s, Some(Sink::Stdout))), &line);
    let mut copies = Vec::new();
    for kind in args.link.kinds() {
        let progress = crate::logging::spinner(format!(
            "copying {} MiB per frame for {} frames over `{}` links",
            args.size_mib,
            args.frames,
            kind.name()
        ));
        let copy = copy_bandwidth(&desc, &CopyBenchOptions { link: Some(kind), ..copy_options.clone() });
        progress.finish_and_clear();
        let copy = match copy {
            Ok(copy) => copy,
            // Measuring every kind: one the devices lack is named, not an error.
            Err(e @ BackendError::LinkUnavailable { .. }) if args.link == BenchLink::All => {
                say(format!("link {}: not measured ({e})", kind.name()));
                continue;
            }
            Err(e @ BackendError::LinkUnavailable { .. }) => {
                return Err(crate::options::UsageError(format!("--link {}: {e}", kind.name())).into());
            }
            Err(e) => return Err(e.into()),
        };
        if copies.is_empty() {
            for d in &copy.devices {
                say(format!(
                    "device {}: {} ({} {}, Vulkan {})",
                    d.index, d.name, d.driver, d.driver_info, d.api_version
                ));
            }
        }
        let rate = |r: Option<f64>| r.map_or("n/a".to_string(), |r| format!("{r:.2}"));
        say(format!(
            "link {}: copy {} MiB device 0 -> 1, {} chunk(s), {} frame(s) in flight: sustained {} GB/s; per frame median {} GB/s, best {} GB/s (while copying: out {}, in {}); handoff {:.1} µs",
            kind.name(),
            args.size_mib,
            copy.chunks,
            args.frames_in_flight,
            rate(copy.sustained_gb_per_s),
            rate(copy.median_gb_per_s),
            rate(copy.best_gb_per_s),
            rate(copy.median_device_to_host_gb_per_s),
            rate(copy.median_host_to_device_gb_per_s),
            copy.median_handoff_us
        ));
        if copy.sustained_gb_per_s.is_none() {
            tracing::warn!(
                "the copies were too short for the device timer (or too few frames) to give a rate: raise --size-mib or --frames"
            );
        }
        copies.push(copy);
    }
    let overhead_options =
        OverheadBenchOptions { passes_per_device: args.passes_per_device as u32, ..Default::default() };
    let progress = crate::logging::spinner("measuring executor overhead".into());
    let overhead = executor_overhead(&desc, &overhead_options)?;
    progress.finish_and_clear();
    say(format!(
        "executor: {:.3} µs CPU per submitted pass ({} passes/frame, {:.1} µs/frame); recording once {:.2} µs/pass",
        overhead.median_submit_us_per_pass,
        overhead.passes_per_frame,
        overhead.median_submit_us_per_frame,
        overhead.record_us_per_pass
    ));
    if let (Some(sink), Some(first)) = (&args.trace, copies.first()) {
        let reports: Vec<_> = copies.iter().flat_map(|c| c.reports.iter().cloned()).collect();
        write_json(sink, &chrome_trace(&reports, &first.devices))?;
    }
    if let Some(sink) = &args.json {
        write_json(sink, &serde_json::json!({ "copy": &copies, "overhead": &overhead }))?;
    }
    Ok(())
}
