//! `parallax compare TEST REFERENCE`: PSNR, SSIM, FLIP and relMSE of two EXRs or two light-field
//! folders (views matched by name), per view and pooled, as a markdown table on stdout and,
//! with `--json`, a file that also carries a chart point (frame time from the test folder's
//! render.json when it has one).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use parallax_accuracy::points::point_of_render_json;
use parallax_accuracy::{Point, compare_paths, write_atomically};

use crate::outputs::{Format, Output, Sink, check, check_inputs};

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// The image or light-field folder to judge (e.g. a `render` output).
    test: PathBuf,
    /// The reference: an EXR, or a folder of view_NNN.exr (e.g. a `reference` output).
    reference: PathBuf,
    /// Write the figures (and a chart point) as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Also write the markdown table here.
    #[arg(long)]
    markdown: Option<PathBuf>,
    /// Label of the chart point (default: from the test folder's render.json, else its path).
    #[arg(long)]
    label: Option<String>,
    /// Series of the chart point (default: the scheme in render.json): points of one series
    /// share a colour, and a line in the scaling and views charts.
    #[arg(long)]
    series: Option<String>,
}

/// `--json` and `--markdown`: the extension of their format, writable folders, two distinct
/// paths, and neither one of the images compared (`compare a.exr b.exr --json a.exr` used to
/// replace the test image with JSON).
fn check_outputs(args: &CompareArgs) -> Result<()> {
    let json = args.json.clone().map(Sink::File);
    let markdown = args.markdown.clone().map(Sink::File);
    let mut outputs = Vec::new();
    if let Some(sink) = &json {
        outputs.push(Output { flag: "--json", sink, format: Format::Json });
    }
    if let Some(sink) = &markdown {
        outputs.push(Output { flag: "--markdown", sink, format: Format::Markdown });
    }
    check(&outputs)?;
    let written: Vec<(&str, &Path)> = [("--json", &args.json), ("--markdown", &args.markdown)]
        .into_iter()
        .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
        .collect();
    check_inputs(&written, &[("TEST", args.test.as_path()), ("REFERENCE", args.reference.as_path())])
}

pub fn run(args: CompareArgs) -> Result<()> {
    for path in [&args.test, &args.reference] {
        if !path.exists() {
            anyhow::bail!("{} does not exist: give an EXR file or a light-field folder", path.display());
        }
    }
    check_outputs(&args)?;
    let comparison = compare_paths(&args.test, &args.reference)?;
    let table = comparison.markdown();
    print!("{table}");
    if let Some(path) = &args.markdown {
        write_atomically(path, |f| std::io::Write::write_all(f, table.as_bytes()))?;
    }
    if let Some(path) = &args.json {
        let render_json = args.test.join("render.json");
        let timing = match parallax_scene::input::read_bounded(
            &render_json,
            parallax_scene::input::TEXT_FILE_LIMIT,
            "render.json",
        ) {
            Ok(bytes) => serde_json::from_slice(&bytes)
                .ok()
                .and_then(|json| point_of_render_json(&json))
                .with_context(|| format!("{} is not a render.json of `parallax render`", render_json.display()))?,
            Err(_) => Point { label: args.test.display().to_string(), ..Default::default() },
        };
        let o = &comparison.overall;
        let point = Point {
            label: args.label.clone().unwrap_or(timing.label.clone()),
            series: args.series.clone().or(timing.series.clone()),
            flip: Some(o.flip),
            psnr: o.psnr_linear_db.is_finite().then_some(o.psnr_linear_db),
            ..timing
        };
        let json = serde_json::json!({ "comparison": &comparison, "point": point });
        let bytes = serde_json::to_vec_pretty(&json)?;
        write_atomically(path, |f| std::io::Write::write_all(f, &bytes))?;
        tracing::info!("wrote {}", path.display());
    }
    Ok(())
}
