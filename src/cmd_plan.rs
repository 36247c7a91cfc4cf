//! `parallax plan`: compile the standard light-field pipeline for a layout, a device count and a
//! scheme, check the schedule, print a summary and optionally write DOT and JSON.

use anyhow::{Result, bail};
use clap::Args;
use parallax_graph::*;

use crate::budget::check_plan_size;
use crate::logging::{result, spinner};
use crate::options::{
    AssignArg, DotDetail, MAX_DEVICES, Resolution, SchemeArg, SourceList, assignment, count_in, parse_layout,
    parse_resolution, parse_sources, parse_spacing,
};
use crate::outputs::{Format, Output, Sink, check, parse_sink, write_bytes, write_json};

#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Light-field layout: multiscopic, nelf or WxH (e.g. 8x4; at most 4096 views).
    #[arg(long, value_parser = parse_layout)]
    lf: LayoutSpec,
    /// Number of devices N (1 ≤ N ≤ 64 and N ≤ number of views).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_parser = count_in(1..=MAX_DEVICES as u64))]
    gpus: u64,
    /// Partitioning scheme.
    #[arg(long, value_enum, default_value_t = SchemeArg::MultiSource)]
    scheme: SchemeArg,
    /// How views are grouped into sets (multi-source only) [default: compact]
    #[arg(long, value_enum)]
    assign: Option<AssignArg>,
    /// Explicit source views for the fine-grained schemes, e.g. 0,99.
    #[arg(long, value_parser = parse_sources)]
    sources: Option<SourceList>,
    /// Spacing between neighbouring views in metres (default 0.001).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_spacing)]
    spacing: Option<f64>,
    /// Per-view resolution WxH (default: the preset's, 512x512 for grids).
    #[arg(long, value_name = "WxH", value_parser = parse_resolution)]
    resolution: Option<Resolution>,
    /// Write the schedule as Graphviz DOT (.dot or .gv; `-` = stdout).
    #[arg(long, value_parser = parse_sink)]
    dot: Option<Sink>,
    /// How much of the schedule the DOT shows.
    #[arg(long, value_enum, default_value_t = DotDetail::Auto)]
    dot_detail: DotDetail,
    /// Write a JSON summary (.json; `-` = stdout).
    #[arg(long, value_parser = parse_sink)]
    json: Option<Sink>,
}

pub fn run(args: PlanArgs) -> Result<()> {
    let assign = assignment(args.scheme, args.assign)?;
    let mut outputs = Vec::new();
    if let Some(sink) = &args.dot {
        outputs.push(Output { flag: "--dot", sink, format: Format::Dot });
    }
    if let Some(sink) = &args.json {
        outputs.push(Output { flag: "--json", sink, format: Format::Json });
    }
    check(&outputs)?;
    let lf = LightField::new(args.lf, args.spacing, args.resolution.map(Resolution::pair), Rig::default())?;
    let config = PlanConfig {
        devices: args.gpus as u32,
        scheme: args.scheme.into(),
        assign,
        sources: args.sources.map(|s| s.0),
    };
    let sources = config.sources.as_ref().map_or(args.gpus, |s| s.len() as u64);
    check_plan_size(lf.len() as u64, args.gpus, sources, config.scheme)?;
    let progress = spinner(format!("planning {} views over {} device(s)", lf.len(), args.gpus));
    let plan = Plan::new(&lf, &config)?;
    let mut graph = Graph::new(plan.topology.clone());
    declare_standard_pipeline(&mut graph);
    let schedule = compile_checked(&graph, &plan)?;
    let summary = PlanSummary::new(&lf, &plan, &schedule);
    // Render everything before writing anything, so a failure leaves no partial output.
    let dot = args.dot.as_ref().map(|_| args.dot_detail.render(&schedule));
    progress.finish_and_clear();
    if let (Some(sink), Some(dot)) = (&args.dot, &dot) {
        write_bytes(sink, dot.as_bytes())?;
    }
    if let Some(sink) = &args.json {
        write_json(sink, &summary)?;
    }
    // The summary is the result, on stdout, unless stdout already carries the DOT or JSON.
    let stdout_taken = [&args.dot, &args.json].iter().any(|s| matches!(s, Some(Sink::Stdout)));
    for line in summary_lines(&summary) {
        result(stdout_taken, &line);
    }
    Ok(())
}

fn summary_lines(s: &PlanSummary) -> [String; 6] {
    [
        format!("light field   {} ({} views, {}x{} each)", s.layout, s.views, s.resolution[0], s.resolution[1]),
        format!(
            "scheme        {} on {} device(s), assignment {}",
            s.scheme,
            s.devices,
            s.assign.unwrap_or("none (row bands)")
        ),
        format!("sources       {:?}", s.sources),
        format!("δ-edges       {} (mean baseline {:.2} mm)", s.delta_edges, s.mean_delta_distance_mm),
        format!(
            "passes        {} instances, per device {:?}, {} culled",
            s.pass_instances, s.passes_per_device, s.culled_passes
        ),
        format!(
            "copies        {} cross-device + {} gather, {:.2} MiB per frame",
            s.cross_device_copies,
            s.gather_copies,
            s.bytes_per_frame as f64 / (1 << 20) as f64
        ),
    ]
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
