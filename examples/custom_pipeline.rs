//! A pipeline of your own, run on the GPU: two passes with their own kernels and GLSL
//! (`examples/custom_pipeline/`, compiled by the root build.rs through parallax-glsl) joined by
//! a δ-edge, placed over N devices by the planner, every pixel checked against the CPU, the
//! views written as a PNG contact sheet. The pipeline itself is in `custom_pipeline/pipeline.rs`.
//!
//! Run: `cargo run --example custom_pipeline -- --fake-devices 2 --out out/custom_pipeline.png`
//! (`--gpus N` on GPUs); `--dot` prints the schedule as DOT instead (no GPU needed):
//! `cargo run --example custom_pipeline -- --fake-devices 2 --dot | dot -Tsvg > custom.svg`.

#[path = "custom_pipeline/pipeline.rs"]
mod pipeline;

use std::path::PathBuf;

use anyhow::Result;
use clap::Parser;
use parallax_backend::{DeviceSelection, validation_from_env};
use parallax_graph::Scheme;

#[derive(Parser, Debug)]
#[command(about = "Runs a two-pass pipeline with its own kernels, checks it against the CPU, writes a PNG")]
struct Args {
    /// Use N physical GPUs.
    #[arg(long, conflicts_with = "fake_devices")]
    gpus: Option<usize>,
    /// Use N logical devices on one physical device (how lavapipe runs multi-device code).
    #[arg(long)]
    fake_devices: Option<usize>,
    /// Partitioning scheme: multi-source, fine-sources or fine-all.
    #[arg(long, default_value = "multi-source")]
    scheme: Scheme,
    /// The PNG contact sheet of every view.
    #[arg(long, default_value = "out/custom_pipeline.png")]
    out: PathBuf,
    /// Print the compiled schedule as DOT and stop.
    #[arg(long)]
    dot: bool,
}

fn main() {
    if let Err(err) = run(Args::parse()) {
        eprintln!("error: {err:#}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<()> {
    let devices = match (args.gpus, args.fake_devices) {
        (Some(n), _) => DeviceSelection::Gpus(n),
        (None, Some(n)) => DeviceSelection::FakeDevices(n),
        (None, None) => DeviceSelection::Gpus(1),
    };
    if args.dot {
        print!("{}", pipeline::schedule_dot(args.scheme, devices.count() as u32)?);
        return Ok(());
    }
    let report = pipeline::run(&pipeline::Options {
        devices,
        validation: validation_from_env(),
        scheme: args.scheme,
        out: args.out.clone(),
    })?;
    println!(
        "{} views, {} pass instances, {} δ-edges, {} copies: every pixel equals the CPU's; wrote {} ({}x{})",
        report.views,
        report.instances,
        report.delta_edges,
        report.copies,
        args.out.display(),
        report.png_size.0,
        report.png_size.1
    );
    Ok(())
}
