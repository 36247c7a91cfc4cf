//! `parallax chart KIND INPUT… --out FILE.svg --out FILE.png`: plotters charts over the JSON
//! that `render` (render.json), `reference` (reference.json), `compare --json` and files of the
//! points schema hold (see `parallax_accuracy::points`), or, for `timeline`, a Chrome trace
//! (`render --trace`).

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};
use parallax_accuracy::chart::{self, AccuracyAxis};
use parallax_accuracy::load_points;
use parallax_accuracy::timeline::Timeline;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ChartKind {
    /// Frame time against FLIP (or `--metric psnr`), one labelled point per configuration.
    SpeedAccuracy,
    /// Frame time against device count, with the ideal line per series.
    Scaling,
    /// Frame time against the number of views.
    Views,
    /// Per-device timeline of one Chrome trace.
    Timeline,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Metric {
    Flip,
    Psnr,
}

#[derive(Args, Debug)]
pub struct ChartArgs {
    /// Which chart.
    #[arg(value_enum)]
    kind: ChartKind,
    /// JSON inputs: `{"points": [{"label", "series", "frame_ms", "flip", "psnr", "devices",
    /// "views"}]}`, a file with a `point` (compare --json, reference.json) or a render.json;
    /// for `timeline`, one Chrome trace.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output file(s), .svg or .png; repeat for both.
    #[arg(long, short, required = true)]
    out: Vec<PathBuf>,
    /// Accuracy axis of speed-accuracy.
    #[arg(long, value_enum, default_value = "flip")]
    metric: Metric,
}

pub fn run(args: ChartArgs) -> Result<()> {
    if args.kind == ChartKind::Timeline {
        let [trace] = args.inputs.as_slice() else {
            bail!("timeline takes one Chrome trace, got {} inputs", args.inputs.len());
        };
        let timeline = Timeline::read(trace)?;
        for out in &args.out {
            timeline.write(out)?;
            tracing::info!("wrote {}", out.display());
        }
        return Ok(());
    }
    let mut points = Vec::new();
    for input in &args.inputs {
        points.extend(load_points(input)?);
    }
    let xy = match args.kind {
        ChartKind::SpeedAccuracy => chart::speed_accuracy(
            &points,
            match args.metric {
                Metric::Flip => AccuracyAxis::Flip,
                Metric::Psnr => AccuracyAxis::Psnr,
            },
        )?,
        ChartKind::Scaling => chart::scaling(&points)?,
        ChartKind::Views => chart::frame_time_over_views(&points)?,
        ChartKind::Timeline => unreachable!("handled above"),
    };
    for out in &args.out {
        xy.write(out)?;
        tracing::info!("wrote {}", out.display());
    }
    Ok(())
}
