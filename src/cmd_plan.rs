//! `parallax plan`: compile the standard light-field pipeline for a layout, a device count and a
//! scheme, check the schedule, print a summary and optionally write DOT and JSON.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use parallax_graph::*;

use crate::output::write_atomically;

#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Light-field layout: multiscopic, nelf or WxH (e.g. 8x4).
    #[arg(long)]
    lf: String,
    /// Number of devices N (1 ≤ N ≤ number of views).
    #[arg(long, default_value_t = 1)]
    gpus: u32,
    /// Partitioning scheme: multi-source, fine-sources or fine-all.
    #[arg(long, default_value = "multi-source")]
    scheme: String,
    /// How views are grouped into sets: round-robin, contiguous or compact.
    #[arg(long, default_value = "round-robin")]
    assign: String,
    /// Explicit source views for the fine-grained schemes, e.g. 0,99.
    #[arg(long)]
    sources: Option<String>,
    /// Spacing between neighbouring views in metres (default 0.001).
    #[arg(long, allow_negative_numbers = true)]
    spacing: Option<f64>,
    /// Per-view resolution WxH (default: the preset's, 512x512 for grids).
    #[arg(long)]
    resolution: Option<String>,
    /// Write the schedule as Graphviz DOT.
    #[arg(long)]
    dot: Option<PathBuf>,
    /// Write a JSON summary.
    #[arg(long)]
    json: Option<PathBuf>,
}

pub fn run(args: PlanArgs) -> Result<()> {
    let spec: LayoutSpec = args.lf.parse()?;
    let resolution = match &args.resolution {
        Some(r) => match lightfield::parse_pair(r) {
            Some(pair) => Some(pair),
            None => bail!("--resolution '{r}' is not WxH (e.g. 768x432)"),
        },
        None => None,
    };
    let lf = LightField::new(spec, args.spacing, resolution, Rig::default())?;
    let config = PlanConfig {
        devices: args.gpus,
        scheme: args.scheme.parse()?,
        assign: args.assign.parse()?,
        sources: args.sources.as_deref().map(parse_source_list).transpose()?,
    };
    if config.devices == 0 {
        return Err(PlanError::NoDevices.into());
    }
    let plan = Plan::new(&lf, &config)?;
    let mut graph = Graph::new(plan.topology.clone());
    declare_standard_pipeline(&mut graph);
    let schedule = compile_checked(&graph, &plan)?;
    let summary = PlanSummary::new(&lf, &plan, &schedule);
    // Render everything before writing anything, so a failure leaves no partial output.
    let dot = args.dot.as_ref().map(|_| schedule.to_dot());
    let json = args.json.as_ref().map(|_| serde_json::to_string_pretty(&summary)).transpose()?;
    if let (Some(path), Some(dot)) = (&args.dot, &dot) {
        write_atomically(path, dot.as_bytes())?;
    }
    if let (Some(path), Some(json)) = (&args.json, &json) {
        write_atomically(path, json.as_bytes())?;
    }
    print_summary(&summary);
    Ok(())
}

fn print_summary(s: &PlanSummary) {
    println!("light field   {} ({} views, {}x{} each)", s.layout, s.views, s.resolution[0], s.resolution[1]);
    println!("scheme        {} on {} device(s), assignment {}", s.scheme, s.devices, s.assign);
    println!("sources       {:?}", s.sources);
    println!("δ-edges       {} (mean baseline {:.2} mm)", s.delta_edges, s.mean_delta_distance_mm);
    println!(
        "passes        {} instances, per device {:?}, {} culled",
        s.pass_instances, s.passes_per_device, s.culled_passes
    );
    println!(
        "copies        {} cross-device + {} gather, {:.2} MiB per frame",
        s.cross_device_copies,
        s.gather_copies,
        s.bytes_per_frame as f64 / (1 << 20) as f64
    );
}

/// Compiles `graph` under `plan` and checks every schedule invariant: a broken one is a bug of
/// the compiler, reported as such rather than executed.
pub(crate) fn compile_checked<P>(graph: &Graph<P>, plan: &Plan) -> Result<Schedule> {
    let schedule = compile(graph, plan)?;
    let report = schedule.validate();
    if !report.is_ok() {
        bail!(
            "internal error: the compiled schedule breaks {} invariant(s), first: {:?}",
            report.errors.len(),
            report.errors[0]
        );
    }
    Ok(schedule)
}
