//! Cross-device copy bandwidth and executor overhead.
//!
//! ```text
//! cargo run --release -p parallax-backend --example copy_bench -- --gpus 2
//! cargo run --release -p parallax-backend --example copy_bench -- --fake-devices 2 --size-mib 16
//! ```
//! Options: `--gpus N` | `--fake-devices N` (default: 2 fake devices), `--size-mib M` (64),
//! `--chunk-mib C` (8; 0 = one chunk), `--frames F` (30), `--copy-queue main|separate|both`
//! (both: measure copies on the main queue, then on a transfer-only queue), `--json FILE`,
//! `--trace FILE` (Chrome trace of the last copy run). `PARALLAX_VALIDATION=1` turns validation
//! on.

use std::path::PathBuf;
use std::process::ExitCode;

use parallax_backend::bench::{CopyBenchOptions, OverheadBenchOptions, copy_bandwidth, executor_overhead};
use parallax_backend::{ContextDesc, DeviceSelection, chrome_trace, write_json};

struct Args {
    selection: DeviceSelection,
    /// Copy-queue modes to measure (false = main queue, true = separate copy queue).
    queue_modes: Vec<bool>,
    copy: CopyBenchOptions,
    overhead: OverheadBenchOptions,
    json: Option<PathBuf>,
    trace: Option<PathBuf>,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        selection: DeviceSelection::FakeDevices(2),
        queue_modes: vec![false, true],
        copy: CopyBenchOptions::default(),
        overhead: OverheadBenchOptions::default(),
        json: None,
        trace: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let number = |v: String| v.parse::<u64>().map_err(|e| format!("{flag} {v}: {e}"));
        match flag.as_str() {
            "--gpus" => args.selection = DeviceSelection::Gpus(number(value()?)? as usize),
            "--fake-devices" => args.selection = DeviceSelection::FakeDevices(number(value()?)? as usize),
            "--size-mib" => args.copy.bytes = number(value()?)? << 20,
            "--chunk-mib" => {
                let mib = number(value()?)?;
                args.copy.chunk_bytes = if mib == 0 { u64::MAX } else { mib << 20 };
            }
            "--frames" => args.copy.frames = number(value()?)? as usize,
            "--passes-per-device" => args.overhead.passes_per_device = number(value()?)? as u32,
            "--copy-queue" => {
                args.queue_modes = match value()?.as_str() {
                    "main" => vec![false],
                    "separate" => vec![true],
                    "both" => vec![false, true],
                    other => return Err(format!("--copy-queue {other}: expected main, separate or both")),
                }
            }
            "--json" => args.json = Some(value()?.into()),
            "--trace" => args.trace = Some(value()?.into()),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if args.selection.count() < 2 {
        return Err("the copy benchmark needs 2 devices".into());
    }
    Ok(args)
}

fn run() -> Result<(), String> {
    let args = parse()?;
    let desc = ContextDesc::from_env(args.selection);
    let mut copies = Vec::new();
    for &separate in &args.queue_modes {
        let options = CopyBenchOptions { separate_copy_queue: separate, ..args.copy.clone() };
        let copy = copy_bandwidth(&desc, &options).map_err(|e| e.to_string())?;
        if copies.is_empty() {
            for d in &copy.devices {
                println!("device {}: {} ({}, {}, Vulkan {})", d.index, d.name, d.driver, d.driver_info, d.api_version);
            }
        }
        let queue = match (separate, copy.devices_with_copy_queue.iter().all(|&q| q)) {
            (false, _) => "main queue",
            (true, true) => "transfer-only queue",
            (true, false) => "main queue in copy-only submissions (no transfer-only queue)",
        };
        println!(
            "copy {:.1} MiB device 0 -> device 1 in {} chunk(s) of <= {:.1} MiB on the {queue}, {} frames:",
            copy.bytes as f64 / (1 << 20) as f64,
            copy.chunks,
            (copy.chunk_bytes.min(copy.bytes)) as f64 / (1 << 20) as f64,
            copy.frames.len()
        );
        println!("  end-to-end  median {:.2} GB/s, best {:.2} GB/s", copy.median_gb_per_s, copy.best_gb_per_s);
        println!(
            "  while copying: device->host {:.2} GB/s, host->device {:.2} GB/s (medians of bytes / busy time)",
            copy.median_device_to_host_gb_per_s, copy.median_host_to_device_gb_per_s
        );
        println!("  chunk handoff (copy-in start - copy-out end): median {:.1} µs", copy.median_handoff_us);
        copies.push(copy);
    }
    let overhead = executor_overhead(&desc, &args.overhead).map_err(|e| e.to_string())?;
    println!(
        "executor: {} passes/frame on {} device(s): {:.2} µs CPU per submitted pass ({:.1} µs per frame), recording {:.2} µs per pass (once), frame wall {:.1} µs",
        overhead.passes_per_frame,
        overhead.devices.len(),
        overhead.median_submit_us_per_pass,
        overhead.median_submit_us_per_frame,
        overhead.record_us_per_pass,
        overhead.median_frame_wall_us
    );
    if let Some(path) = &args.json {
        let value = serde_json::json!({ "copy": &copies, "overhead": &overhead });
        write_json(path, &value).map_err(|e| e.to_string())?;
    }
    if let Some(path) = &args.trace {
        let last = copies.last().expect("at least one copy run");
        write_json(path, &chrome_trace(&last.reports, &last.devices)).map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("copy_bench: {e}");
            ExitCode::FAILURE
        }
    }
}
