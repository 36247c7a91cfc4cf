//! `parallax plan`: compile the pipeline `render` runs (same pipeline, G-buffer, denoise,
//! scheme, assignment and sources flags) for a layout and a device count, check the schedule,
//! print a summary and optionally write DOT and JSON. No GPU is needed.

use anyhow::Result;
use clap::{Args, ValueEnum};
use parallax_graph::{Rig, ScheduleSummary};

use crate::logging::{result, spinner};
use crate::options::sink_parser;
use crate::options::{DeviceArgs, UsageError};
use crate::pipeline_args::{DenoiseArg, DotArgs, PipelineArgs};
use crate::scene_args::LayoutArgs;
use parallax_render::compile::plan_json;
use parallax_render::outputs::{Format, Output, Sink, check, write_bytes, write_json};
use parallax_render::ranks::{RankLayout, RankShare, shares};

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
    /// Plan a render over R processes (MPI ranks, `render` under `mpirun -n R`), each driving
    /// the same share of the devices: which rank runs which views, and the bytes each sends per
    /// frame (its finished views to rank 0 under multi-source, its bands to other ranks under a
    /// fine scheme).
    #[arg(long, value_name = "R", value_parser = clap::value_parser!(u32).range(1..=4096))]
    ranks: Option<u32>,
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
    let layout = args.ranks.map(|r| RankLayout::even(devices, r)).transpose().map_err(|e| UsageError(e.to_string()))?;
    let progress = spinner(format!("planning {} views over {devices} device(s)", lf.len()));
    // The exposure is a push constant of tonemap: it changes no pass, resource or copy.
    let compiled = args.pipeline.compile(&lf, devices, 1.0)?;
    let summary = compiled.summary;
    let shares = layout.as_ref().map(|layout| shares(&compiled.schedule, &compiled.exec, layout, lf.width));
    // Render everything before writing anything, so a failure leaves no partial output.
    let dot = args.dot.render(&compiled.schedule);
    let dot = match (&layout, dot) {
        (Some(layout), Some(dot)) => Some(label_ranks(&dot, layout)),
        (_, dot) => dot,
    };
    progress.finish_and_clear();
    if let (Some(sink), Some(dot)) = (&args.dot.dot, &dot) {
        write_bytes(sink, dot.as_bytes())?;
    }
    if let Some(sink) = &args.json {
        match &shares {
            Some(shares) => {
                let mut json = plan_json(&summary, args.pipeline.gbuffer.into());
                json["ranks"] = serde_json::to_value(shares)?;
                write_json(sink, &json)?;
            }
            None => write_json(sink, &plan_json(&summary, args.pipeline.gbuffer.into()))?,
        }
    }
    // The summary is the result, on stdout, unless stdout already carries the DOT or JSON.
    let stdout_taken = [&args.dot.dot, &args.json].iter().any(|s| matches!(s, Some(Sink::Stdout)));
    for line in summary_lines(&args.pipeline, &summary) {
        result(stdout_taken, &line);
    }
    for line in shares.iter().flatten().map(rank_line) {
        result(stdout_taken, &line);
    }
    Ok(())
}

/// The DOT with every device's cluster labelled with its rank (`gpu2` → `gpu2 (rank 1)`): the
/// graph crate draws devices only, and a cluster's label is where the drawing names one.
fn label_ranks(dot: &str, layout: &RankLayout) -> String {
    let mut dot = dot.to_string();
    for rank in 0..layout.devices.len() {
        let first = layout.first(rank);
        for d in first..first + layout.devices[rank] {
            dot = dot.replace(&format!("label=\"gpu{d}\";"), &format!("label=\"gpu{d} (rank {rank})\";"));
        }
    }
    dot
}

/// One rank of `--ranks`: its devices, views and what it sends per frame.
fn rank_line(s: &RankShare) -> String {
    let kib = |b: u64| b as f64 / 1024.0;
    let (first, last) = (s.devices[0], s.devices[s.devices.len() - 1]);
    if s.link_bytes_per_frame > 0 {
        return format!(
            "rank {:<8} devices {first}..={last}, {} views {:?}, sends other ranks {:.1} KiB of bands per frame",
            s.rank,
            s.views.len(),
            s.views,
            kib(s.link_bytes_per_frame)
        );
    }
    format!(
        "rank {:<8} devices {first}..={last}, {} views {:?}, sends rank 0 {:.1} KiB of display views per frame ({:.1} \
         KiB more with the linear EXRs)",
        s.rank,
        s.views.len(),
        s.views,
        kib(s.display_bytes_per_frame),
        kib(s.linear_bytes_per_frame)
    )
}

fn summary_lines(p: &PipelineArgs, s: &ScheduleSummary) -> [String; 9] {
    [
        format!(
            "pipeline      {}, G-buffer {}, fireflies {}, {}",
            flag_value(p.pipeline),
            flag_value(p.gbuffer),
            flag_value(p.fireflies_applied()),
            match p.denoise_applied() {
                DenoiseArg::Views => "SVGF over every view",
                DenoiseArg::Samples => "SVGF over the samples (sources, then hole pixels)",
                DenoiseArg::None => "no denoising",
            }
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
        format!(
            "batches       {} transfers of the cross-device copies (one per device pair and stage)",
            s.copy_batches
        ),
    ]
}

/// How each set's sources were chosen and what they are predicted to cost (multi-source).
fn sources_prediction_line(s: &ScheduleSummary) -> String {
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
