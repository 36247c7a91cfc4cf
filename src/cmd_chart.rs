//! `parallax chart KIND INPUT… --out FILE.svg --out FILE.png`: plotters charts over the JSON
//! that `render` (render.json), `reference` (reference.json), `compare --json` and files of the
//! points schema hold (see `parallax_accuracy::points`), or, for `timeline`, a Chrome trace
//! (`render --trace`).

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};
use parallax_accuracy::chart::{self, AccuracyAxis};
use parallax_accuracy::load_points;
use parallax_accuracy::points::of_case;
use parallax_accuracy::timeline::Timeline;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ChartKind {
    /// Frame time against FLIP (or `--metric psnr`), one labelled point per configuration, with
    /// the Pareto front.
    SpeedAccuracy,
    /// Frame time against device count, with the ideal line per series.
    Scaling,
    /// Frame time against the number of views.
    Views,
    /// Missing pixels (%) against hole-filling time, one series per assignment (bench's
    /// points.json).
    Holes,
    /// Missing pixels (%) against the reprojection tolerance, one line per case, each point
    /// labelled with its FLIP (or `--metric psnr`): bench with `--reprojection-tolerances`.
    Tolerance,
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
    /// "views", "case", "assignment", "sources_per_set", "spp", "missing", "hole_fill_ms",
    /// "reprojection_tolerance"}]}`,
    /// a file with a `point` (compare --json, reference.json) or a render.json; for
    /// `timeline`, one Chrome trace.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output file(s), .svg or .png; repeat for both.
    #[arg(long, short, required = true)]
    out: Vec<PathBuf>,
    /// Accuracy axis of speed-accuracy (and the point labels of tolerance).
    #[arg(long, value_enum, default_value = "flip")]
    metric: Metric,
    /// Only the points of this bench case (points.json's `case`), so that one points.json gives
    /// one chart per case; not for `timeline`.
    #[arg(long)]
    case: Option<String>,
}

pub fn run(args: ChartArgs) -> Result<()> {
    let written: Vec<(&str, &Path)> = args.out.iter().map(|p| ("--out", p.as_path())).collect();
    let read: Vec<(&str, &Path)> = args.inputs.iter().map(|p| ("INPUT", p.as_path())).collect();
    parallax_render::outputs::check_inputs(&written, &read)?;
    if args.kind == ChartKind::Timeline {
        if args.case.is_some() {
            bail!("--case selects points of a points file; a timeline reads one Chrome trace: drop --case");
        }
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
    if let Some(case) = &args.case {
        points = of_case(points, case)?;
    }
    let accuracy = match args.metric {
        Metric::Flip => AccuracyAxis::Flip,
        Metric::Psnr => AccuracyAxis::Psnr,
    };
    let mut xy = match args.kind {
        ChartKind::SpeedAccuracy => chart::speed_accuracy(&points, accuracy)?,
        ChartKind::Scaling => chart::scaling(&points)?,
        ChartKind::Views => chart::frame_time_over_views(&points)?,
        ChartKind::Holes => chart::holes(&points)?,
        ChartKind::Tolerance => chart::tolerance(&points, accuracy)?,
        ChartKind::Timeline => unreachable!("handled above"),
    };
    if let Some(case) = &args.case {
        xy.title = format!("{}, case {case}", xy.title);
    }
    for out in &args.out {
        xy.write(out)?;
        tracing::info!("wrote {}", out.display());
    }
    Ok(())
}
