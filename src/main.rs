//! The `parallax` command line.

mod cmd_plan;
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
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Plan(args) => cmd_plan::run(args),
    };
    if let Err(err) = result {
        eprintln!("error: {err:#}");
        std::process::exit(1);
    }
}
