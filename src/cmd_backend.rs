//! Backend subcommands: `parallax devices` (which Vulkan devices would run) and
//! `parallax bench-copy` (cross-device copy bandwidth and executor overhead).

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use parallax_backend::bench::{CopyBenchOptions, OverheadBenchOptions, copy_bandwidth, executor_overhead};
use parallax_backend::{Context, ContextDesc, DeviceSelection, chrome_trace, write_json};

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
