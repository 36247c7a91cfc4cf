//! The `parallax` command line.

mod cmd_backend;
mod cmd_bench_rays;
mod cmd_plan;
mod cmd_render;
mod cmd_trace;
mod output;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "parallax", version, about = "Multi-GPU light-field path tracing as a render graph")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Plan a light field over N devices: sources, δ-edges, per-device schedule, copies.
    Plan(cmd_plan::PlanArgs),
    /// Path trace every view of a light field over N devices (reference, no reprojection).
    Render(cmd_render::RenderArgs),
    /// Path trace one view of a scene on the GPU (`--cpu`: the CPU reference) to EXR (+ PNG).
    Trace(cmd_trace::TraceArgs),
    /// List the Vulkan devices a selection would use (name, driver, API version).
    Devices(cmd_backend::DevicesArgs),
    /// Measure cross-device copy bandwidth and executor overhead.
    BenchCopy(cmd_backend::BenchCopyArgs),
    /// Measure GPU traversal: primary and diffuse-bounce rays/s, and the CWBVH build time.
    BenchRays(cmd_bench_rays::BenchRaysArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Plan(args) => cmd_plan::run(args),
        Command::Render(args) => cmd_render::run(args),
        Command::Trace(args) => cmd_trace::run(args),
        Command::Devices(args) => cmd_backend::devices(args),
        Command::BenchCopy(args) => cmd_backend::bench_copy(args),
        Command::BenchRays(args) => cmd_bench_rays::run(args),
    };
    if let Err(err) = result {
        eprintln!("error: {err:#}");
        std::process::exit(1);
    }
}
