//! Cross-device copy bandwidth and executor overhead.
//!
//! ```text
//! cargo run --release -p parallax-backend --example copy_bench -- --gpus 2
//! cargo run --release -p parallax-backend --example copy_bench -- --fake-devices 2 --size-mib 16
//! ```
//! Options: `--gpus N` | `--fake-devices N` (default: 2 fake devices), `--size-mib M` (64),
//! `--chunk-mib C` (8; 0 = one chunk), `--frames F` (30), `--json FILE`, `--trace FILE`
//! (Chrome trace of the copy frames). `PARALLAX_VALIDATION=1` turns validation on.

use std::path::PathBuf;
use std::process::ExitCode;

use parallax_backend::bench::{CopyBenchOptions, OverheadBenchOptions, copy_bandwidth, executor_overhead};
use parallax_backend::{ContextDesc, DeviceSelection, chrome_trace, write_json};

struct Args {
    selection: DeviceSelection,
    copy: CopyBenchOptions,
    overhead: OverheadBenchOptions,
    json: Option<PathBuf>,
    trace: Option<PathBuf>,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        selection: DeviceSelection::FakeDevices(2),
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
    let copy = copy_bandwidth(&desc, &args.copy).map_err(|e| e.to_string())?;
    for d in &copy.devices {
        println!("device {}: {} ({}, {}, Vulkan {})", d.index, d.name, d.driver, d.driver_info, d.api_version);
    }
    println!(
        "copy {:.1} MiB device 0 -> device 1 in {} chunk(s) of <= {:.1} MiB, {} frames:",
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
        let value = serde_json::json!({ "copy": &copy, "overhead": &overhead });
        write_json(path, &value).map_err(|e| e.to_string())?;
    }
    if let Some(path) = &args.trace {
        write_json(path, &chrome_trace(&copy.reports, &copy.devices)).map_err(|e| e.to_string())?;
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
