//! `parallax compare TEST REFERENCE`: PSNR, SSIM, FLIP and relMSE of two EXRs or two light-field
//! folders (views matched by name), per view and pooled, as a markdown table on stdout and,
//! with `--json`, a file that also carries a chart point (frame time from the test folder's
//! render.json when it has one).
//!
//! Before any figure, the settings recorded beside both sides (`setup` in render.json or
//! reference.json, [`parallax_render::report::setup`]) must agree: a comparison of a moving camera with a
//! still reference, or of another scene, light or depth, measures the difference in settings,
//! not the error, so it is refused (exit 1) naming each differing setting, unless
//! `--allow-mismatch`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use parallax_accuracy::flip::error_map_rgb8;
use parallax_accuracy::points::point_of_render_json;
use parallax_accuracy::{CompareOptions, Comparison, Point, compare_paths, write_atomically};
use parallax_scene::input::{TEXT_FILE_LIMIT, read_bounded};

use crate::options::{Exposure, parse_exposure};
use parallax_render::outputs::{Format, Output, Sink, check, check_inputs, stage, write_json};
use parallax_render::report::setup::{differences, setup_beside};

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// The image or light-field folder to judge (e.g. a `render` output).
    test: PathBuf,
    /// The reference: an EXR, or a folder of view_NNN.exr (e.g. a `reference` output).
    reference: PathBuf,
    /// Write the figures (and a chart point) as JSON here (`-` = stdout; the table then goes to
    /// stderr).
    #[arg(long, value_parser = crate::options::sink_parser())]
    json: Option<Sink>,
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
    /// Exposure at which both sides are tonemapped for PSNR tm, SSIM and FLIP: `auto` (the
    /// reference's log-average luminance over all its views mapped to 0.18) or a multiplier > 0.
    #[arg(long, allow_negative_numbers = true, default_value = "auto", value_parser = parse_exposure)]
    exposure: Exposure,
    /// Write the per-pixel FLIP error as a PNG in NVIDIA's magma colour map (black: no error,
    /// pale yellow: the most); of a light field, every view's map in view order, as the contact
    /// sheet lays them out.
    #[arg(long, value_name = "FILE.png")]
    flip_map: Option<PathBuf>,
    /// Write the per-view error across the grid as a PNG: one cell per view, laid out as the
    /// contact sheet, filled with its mean FLIP in magma, scaled so that the worst view is pale
    /// yellow (the scale is printed): where in the light field the error lies.
    #[arg(long, value_name = "FILE.png")]
    error_grid: Option<PathBuf>,
    /// Compare even when the settings recorded beside the two sides differ (scene, camera,
    /// still or not, layout, spacing, focus, resolution, lights, max depth).
    #[arg(long)]
    allow_mismatch: bool,
}

/// Checks that `test` and `reference` were rendered with the same settings; returns the
/// differences allowed with `--allow-mismatch` (empty when they agree or were not checked).
pub fn check_settings(test: &Path, reference: &Path, allow_mismatch: bool) -> Result<Vec<String>> {
    let (t, r) = (setup_beside(test)?, setup_beside(reference)?);
    let (t, r) = match (t, r) {
        (Ok(t), Ok(r)) => (t, r),
        (Err(why), _) | (_, Err(why)) => {
            tracing::warn!("the settings of the two sides are not checked: {why}");
            return Ok(Vec::new());
        }
    };
    let diffs = differences(&t, &r);
    if diffs.is_empty() {
        return Ok(diffs);
    }
    let list = diffs.join("; ");
    if !allow_mismatch {
        bail!(
            "{} and the reference {} were rendered with different settings (test vs reference): {list}; the figures \
             would measure these differences, not the error: render again with the reference's settings (for a \
             reference, `render --still`), or pass --allow-mismatch to compare anyway",
            test.display(),
            reference.display()
        );
    }
    tracing::warn!("comparing although the settings differ (--allow-mismatch): {list}");
    Ok(diffs)
}

/// `--json`'s file (none when it goes to stdout).
fn json_file(args: &CompareArgs) -> Option<PathBuf> {
    match &args.json {
        Some(Sink::File(path)) => Some(path.clone()),
        _ => None,
    }
}

/// `--json` and `--markdown`: the extension of their format, writable folders, two distinct
/// paths, and neither one of the images compared (`compare a.exr b.exr --json a.exr` used to
/// replace the test image with JSON).
fn check_outputs(args: &CompareArgs) -> Result<()> {
    let json = args.json.clone();
    let markdown = args.markdown.clone().map(Sink::File);
    let flip_map = args.flip_map.clone().map(Sink::File);
    let mut outputs = Vec::new();
    if let Some(sink) = &json {
        outputs.push(Output { flag: "--json", sink, format: Format::Json });
    }
    if let Some(sink) = &markdown {
        outputs.push(Output { flag: "--markdown", sink, format: Format::Markdown });
    }
    if let Some(sink) = &flip_map {
        outputs.push(Output { flag: "--flip-map", sink, format: Format::Png });
    }
    let error_grid = args.error_grid.clone().map(Sink::File);
    if let Some(sink) = &error_grid {
        outputs.push(Output { flag: "--error-grid", sink, format: Format::Png });
    }
    check(&outputs)?;
    let json_file = json_file(args);
    let written: Vec<(&str, &Path)> = [
        ("--json", &json_file),
        ("--markdown", &args.markdown),
        ("--flip-map", &args.flip_map),
        ("--error-grid", &args.error_grid),
    ]
    .into_iter()
    .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
    .collect();
    check_inputs(&written, &[("TEST", args.test.as_path()), ("REFERENCE", args.reference.as_path())])
}

pub fn run(args: CompareArgs) -> Result<()> {
    for path in [&args.test, &args.reference] {
        if !path.exists() {
            bail!("{} does not exist: give an EXR file or a light-field folder", path.display());
        }
    }
    check_outputs(&args)?;
    let mismatches = check_settings(&args.test, &args.reference, args.allow_mismatch)?;
    let options = CompareOptions { exposure: args.exposure, flip_maps: args.flip_map.is_some() };
    let comparison = compare_paths(&args.test, &args.reference, &options)?;
    warn_if_tonemapping_hides_the_error(&comparison);
    let table = comparison.markdown();
    crate::logging::result(args.json == Some(Sink::Stdout), table.trim_end());
    if let Some(path) = &args.flip_map {
        let columns = sheet_columns(&args.test, comparison.views.len());
        stage(path, |tmp| write_flip_sheet(tmp, &comparison, columns))?.commit()?;
        tracing::info!("wrote {}", path.display());
    }
    if let Some(path) = &args.error_grid {
        let columns = sheet_columns(&args.test, comparison.views.len());
        let mut worst = 0.0;
        stage(path, |tmp| write_error_grid(tmp, &comparison, columns).map(|w| worst = w))?.commit()?;
        tracing::info!("wrote {} (pale yellow: mean FLIP {worst:.4}, black: 0)", path.display());
    }
    if let Some(path) = &args.markdown {
        write_atomically(path, |f| std::io::Write::write_all(f, table.as_bytes()))?;
    }
    if let Some(sink) = &args.json {
        let render_json = args.test.join("render.json");
        let timing = match read_bounded(&render_json, TEXT_FILE_LIMIT, "render.json") {
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
        let json = serde_json::json!({ "comparison": &comparison, "setting_mismatches": mismatches, "point": point });
        write_json(sink, &json)?;
        if let Sink::File(path) = sink {
            tracing::info!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// Perceptual figures of a perfect match for images whose radiance differs mean the exposure
/// hides the difference (everything black or white at it): say so rather than let them pass
/// for a result.
fn warn_if_tonemapping_hides_the_error(comparison: &Comparison) {
    let o = &comparison.overall;
    if o.psnr_tonemapped_db == f64::INFINITY && o.rel_mse > 0.0 {
        tracing::warn!(
            "at exposure {} ({}) both sides tonemap to the same 8-bit pixels although their radiance differs (relMSE \
             {:.3e}): PSNR tm, SSIM and FLIP cannot see the difference; give an --exposure at which the images show",
            comparison.exposure,
            comparison.exposure_mode,
            o.rel_mse
        );
    }
}

/// Columns of the error-map sheet: the light field's own, as render's contact sheet (at most
/// 10), when render.json says; else as square as the views allow. render.json was read (and
/// checked) for the settings before the comparison.
fn sheet_columns(test: &Path, views: usize) -> u32 {
    let cols = read_bounded(&test.join("render.json"), TEXT_FILE_LIMIT, "render.json")
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .and_then(|j| j["layout"]["cols"].as_u64());
    match cols {
        Some(c) => (c as u32).clamp(1, 10),
        None => ((views as f64).sqrt().ceil() as u32).max(1),
    }
}

/// `--error-grid`: one cell per view (48 pixels high, the views' aspect), `columns` per row,
/// 2-pixel white gaps, filled with the view's mean FLIP in magma scaled by the worst view's,
/// which it returns.
fn write_error_grid(path: &Path, comparison: &Comparison, columns: u32) -> Result<f64> {
    let views = &comparison.views;
    let Some(first) = views.first() else { bail!("no views were compared") };
    let h = 48u32;
    let w = ((h as f64 * first.width as f64 / first.height as f64).round() as u32).clamp(8, 192);
    let worst = views.iter().map(|v| v.metrics.flip).fold(0.0, f64::max);
    let (gap, n) = (2, views.len() as u32);
    let columns = columns.clamp(1, n);
    let rows = n.div_ceil(columns);
    let mut grid = image::RgbImage::from_pixel(columns * (w + gap) - gap, rows * (h + gap) - gap, image::Rgb([255; 3]));
    for (k, view) in views.iter().enumerate() {
        let value = if worst > 0.0 { (view.metrics.flip / worst) as f32 } else { 0.0 };
        let rgb = error_map_rgb8(&[value], 1, 1);
        let (x0, y0) = ((k as u32 % columns) * (w + gap), (k as u32 / columns) * (h + gap));
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                grid.put_pixel(x, y, image::Rgb([rgb[0], rgb[1], rgb[2]]));
            }
        }
    }
    grid.save_with_format(path, image::ImageFormat::Png).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(worst)
}

/// Every view's FLIP error map in magma, `columns` per row, 2-pixel gaps (black).
fn write_flip_sheet(path: &Path, comparison: &Comparison, columns: u32) -> Result<()> {
    let views = &comparison.views;
    let Some(first) = views.first() else { bail!("no views were compared") };
    let (w, h) = (first.width as u32, first.height as u32);
    if views.iter().any(|v| (v.width as u32, v.height as u32) != (w, h)) {
        bail!("--flip-map: the views differ in size, so they do not tile into one picture");
    }
    let gap = 2;
    let columns = columns.clamp(1, views.len() as u32);
    let rows = (views.len() as u32).div_ceil(columns);
    let mut sheet = image::RgbImage::new(columns * w + (columns - 1) * gap, rows * h + (rows - 1) * gap);
    for (k, map) in comparison.flip_maps.iter().enumerate() {
        let rgb = error_map_rgb8(map, w as usize, h as usize);
        let (x0, y0) = ((k as u32 % columns) * (w + gap), (k as u32 / columns) * (h + gap));
        for (i, p) in rgb.chunks_exact(3).enumerate() {
            sheet.put_pixel(x0 + i as u32 % w, y0 + i as u32 / w, image::Rgb([p[0], p[1], p[2]]));
        }
    }
    sheet.save_with_format(path, image::ImageFormat::Png).with_context(|| format!("cannot write {}", path.display()))
}
