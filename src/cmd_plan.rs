//! `parallax plan`: compile the pipeline `render` runs (same pipeline, G-buffer, denoise,
//! scheme, assignment and sources flags) for a layout and a device count, check the schedule,
//! print a summary and optionally write DOT and JSON. No GPU is needed.

use anyhow::Result;
use clap::{Args, ValueEnum};
use parallax_graph::{PlanSummary, Rig};

use crate::logging::{result, spinner};
use crate::options::DeviceArgs;
use crate::outputs::{Format, Output, Sink, check, sink_parser, write_bytes, write_json};
use crate::pipeline_args::{DotArgs, PipelineArgs};
use crate::scene_args::LayoutArgs;

/// The options of `render` that decide its schedule, taken the same way, so `plan` with
/// render's flags shows the schedule render runs.
#[derive(Args, Debug)]
pub struct PlanArgs {
    #[command(flatten)]
    layout: LayoutArgs,
    #[command(flatten)]
    devices: DeviceArgs,
    #[command(flatten)]
    pipeline: PipelineArgs,
    #[command(flatten)]
    dot: DotArgs,
    /// Write a JSON summary (.json; `-` = stdout).
    #[arg(long, value_parser = sink_parser())]
    json: Option<Sink>,
}

pub fn run(args: PlanArgs) -> Result<()> {
    args.pipeline.check()?;
    let mut outputs = Vec::new();
    if let Some(sink) = &args.dot.dot {
        outputs.push(Output { flag: "--dot", sink, format: Format::Dot });
    }
    if let Some(sink) = &args.json {
        outputs.push(Output { flag: "--json", sink, format: Format::Json });
    }
    check(&outputs)?;
    let lf = args.layout.with_rig(Rig::default())?;
    let devices = args.devices.selection().count() as u32;
    let progress = spinner(format!("planning {} views over {devices} device(s)", lf.len()));
    // The exposure is a push constant of tonemap: it changes no pass, resource or copy.
    let compiled = args.pipeline.compile(&lf, devices, 1.0)?;
    let summary = compiled.summary;
    // Render everything before writing anything, so a failure leaves no partial output.
    let dot = args.dot.render(&compiled.schedule);
    progress.finish_and_clear();
    if let (Some(sink), Some(dot)) = (&args.dot.dot, &dot) {
        write_bytes(sink, dot.as_bytes())?;
    }
    if let Some(sink) = &args.json {
        write_json(sink, &summary)?;
    }
    // The summary is the result, on stdout, unless stdout already carries the DOT or JSON.
    let stdout_taken = [&args.dot.dot, &args.json].iter().any(|s| matches!(s, Some(Sink::Stdout)));
    for line in summary_lines(&args.pipeline, &summary) {
        result(stdout_taken, &line);
    }
    Ok(())
}

fn summary_lines(p: &PipelineArgs, s: &PlanSummary) -> [String; 8] {
    [
        format!(
            "pipeline      {}, G-buffer {}, fireflies {}, {}",
            flag_value(p.pipeline),
            flag_value(p.gbuffer),
            flag_value(p.fireflies),
            if p.no_denoise { "no denoising" } else { "SVGF" }
        ),
        format!("light field   {} ({} views, {}x{} each)", s.layout, s.views, s.resolution[0], s.resolution[1]),
        format!(
            "scheme        {} on {} device(s), assignment {}",
            s.scheme,
            s.devices,
            s.assign.unwrap_or("none (row bands)")
        ),
        format!("sources       {:?}", s.sources),
        sources_prediction_line(s),
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

/// How each set's sources were chosen and what they are predicted to cost (multi-source).
fn sources_prediction_line(s: &PlanSummary) -> String {
    if s.sources_prediction.is_empty() {
        return "per set       (row bands: no sets)".to_string();
    }
    let how = if s.sources_auto { "auto" } else { "fixed" };
    let sets: Vec<String> = s
        .sources_prediction
        .iter()
        .map(|p| {
            format!(
                "set {}: {} source(s), {} block(s), predicted {:.2} % missing, {:.2} views",
                p.set,
                p.sources,
                p.blocks,
                100.0 * p.predicted_missing,
                p.predicted_cost_views
            )
        })
        .collect();
    format!("per set       {how}; {}", sets.join("; "))
}

/// How a value of an option is spelt on the command line.
fn flag_value(v: impl ValueEnum) -> String {
    v.to_possible_value().map_or_else(String::new, |p| p.get_name().to_string())
}
