//! `parallax bench`: a matrix of `render` runs (cases × pipelines × schemes × assignments ×
//! sources per set × spp × denoise × reprojection tolerances × device counts; see [`crate::bench_matrix`] for the
//! `--matrix FILE.toml` form), each cell a `parallax render` child process of this binary, so a
//! cell that fails (say, more devices than views) is reported with its error and the others
//! still run. Every cell's render arguments are parsed before the first cell runs, so a typo
//! in a case fails at once. Writes `bench.json` (documented below), `bench.md` (tables in the
//! paper's layouts, [`parallax_render::bench::tables`]), and `points.json` (one chart point per cell, for
//! `parallax chart speed-accuracy`, `views` and `holes`), all three after every cell.
//!
//! bench.json: `{"common", "matrix", "frames", "warmup", "cases": [{"name", "args",
//! "reference"}], "cells": [cell]}` (`common` with `--common`, `matrix` the file with
//! `--matrix`); a cell has `id` (`[case/]pipeline_scheme[_assignment]_kK_sppS_dnD_dN[_tolT]`), `case`
//! (the case's name; null for `--common`), `args` (the render arguments beyond the case's),
//! `pipeline`, `scheme`, `assignment` (reprojecting multi-source cells: the one asked for, or
//! the one render used by default), `sources_per_set`, `spp`, `denoise` (bool), `denoiser` (`on`, `off`, `samples`),
//! `reprojection_tolerance` (reprojecting cells: the one asked for, or render's default; else
//! null), `devices`,
//! `ok`, `error` (when not ok), and when ok: `views`, `frame_ms` (mean, median, p95 of the GPU
//! span of the measured frames), `views_per_s` (elemental images per second at the mean),
//! `stages` (per stage and device, ms per frame: the paper's Table 1), `hole_fill_ms` (the
//! `hole_fill` stage's ms per frame summed over devices; null for path-trace), `gather_ms` (the
//! `transfer` stage, display images moving to device 0, summed over devices), `busy_fraction`
//! (per device: Fig. 8), `missing_pixels` (Table 4), `copy_bytes_per_frame`, and with a
//! reference: `flip`, `psnr_db` (linear radiance clamped to [0, 1]) against its views, or
//! `accuracy_error` when the views cannot be compared with it.
//!
//! Each cell is reported on stderr as it ends, and the progress bar names the cell running;
//! `--resume` keeps the cells of an earlier run's bench.json that ran well
//! ([`parallax_render::bench::resume`]).
//!
//! points.json: `{"points": [point]}`, one per ok cell: `label` (the id), `series` (the
//! pipeline), `case`, `frame_ms`, `flip`, `psnr`, `views`, `devices`, `assignment`,
//! `sources_per_set`, `spp`, `reprojection_tolerance`, and for reprojecting cells `missing`
//! (overall missing-pixel ratio) and `hole_fill_ms`.

use std::ffi::OsString;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context as _, Result, bail};
use clap::Args;

use crate::bench_matrix::{self, Axes, Case, Cell, Denoise, Matrix, name_of};
use crate::cmd_render::RenderArgs;
use crate::logging::{bar, result};
use crate::options::{AssignArg, SchemeArg};
use crate::pipeline_args::PipelineArg;
use parallax_render::bench::cell::{self as bench_cell, CellHead, RanCell};
use parallax_render::bench::resume as bench_resume;
use parallax_render::bench::tables;

/// Bytes of a failed cell's diagnostics kept for bench.json.
const MAX_CELL_ERROR_BYTES: u64 = 1 << 20;

/// Measured frames and warm-up frames per cell when neither the flags nor the matrix file say.
const DEFAULT_FRAMES: u32 = 10;
const DEFAULT_WARMUP: u32 = 2;

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Scene options passed to every cell (`--scene`, `--camera`, `--sun`, `--sky`, `--lf`,
    /// `--resolution`, `--spacing`, `--max-depth`, `--still`, ...) as one string, e.g.
    /// "--scene default --lf 4x2 --resolution 32x32".
    #[arg(long, default_value = "--scene default", allow_hyphen_values = true)]
    common: String,
    /// A TOML file of cases (render arguments, optional reference) and matrix slices, instead
    /// of --common, --reference and the axis flags: `[[case]]` tables with `name`, `args`,
    /// `reference`; `[[matrix]]` tables with `cases`, `pipelines`, `schemes`, `assignments`,
    /// `sources_per_set`, `spp`, `denoise`, `reprojection_tolerances`, `devices`, `fake_devices` (lists; every key
    /// optional); top-level `frames` and `warmup`. See README.md.
    #[arg(long, value_name = "FILE.toml", conflicts_with_all = [
        "common", "reference", "pipelines", "schemes", "assignments", "sources_per_set", "spp", "denoise",
        "reprojection_tolerances", "devices", "fake_devices",
    ])]
    matrix: Option<PathBuf>,
    /// Pipelines, comma-separated.
    #[arg(long, value_enum, default_value = "reproject,path-trace", value_delimiter = ',')]
    pipelines: Vec<PipelineArg>,
    /// Schemes, comma-separated.
    #[arg(long, value_enum, default_value = "multi-source", value_delimiter = ',')]
    schemes: Vec<SchemeArg>,
    /// View-to-device assignments, comma-separated (reprojecting multi-source cells only;
    /// default: render's).
    #[arg(long, value_enum, value_delimiter = ',')]
    assignments: Vec<AssignArg>,
    /// Sources per multi-source set, comma-separated (reprojecting multi-source cells only).
    #[arg(long, default_value = "1", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..=64))]
    sources_per_set: Vec<u32>,
    /// Samples per pixel, comma-separated.
    #[arg(long, default_value = "1", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: Vec<u32>,
    /// Denoising, comma-separated: `on` (SVGF on every view), `off`, `samples` (render's
    /// `--denoise samples`).
    #[arg(long, value_enum, default_value = "on", value_delimiter = ',')]
    denoise: Vec<Denoise>,
    /// `render --reprojection-tolerance` values, comma-separated (reprojecting cells only;
    /// default: render's): hole ratio, frame time and accuracy per tolerance.
    #[arg(long, allow_negative_numbers = true, value_delimiter = ',',
          value_parser = crate::pipeline_args::parse_reprojection_tolerance)]
    reprojection_tolerances: Vec<f64>,
    /// GPU counts, comma-separated (render's `--gpus`).
    #[arg(long, default_value = "1", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..=64))]
    devices: Vec<u32>,
    /// Counts of logical devices on one GPU (lavapipe, or overhead runs), comma-separated, as
    /// render's `--fake-devices N`: in place of --devices.
    #[arg(long, value_delimiter = ',', conflicts_with = "devices", value_parser = clap::value_parser!(u32).range(1..=64))]
    fake_devices: Vec<u32>,
    /// Measured frames per cell, after --warmup frames [default: the matrix file's `frames`, or 10].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: Option<u32>,
    /// Frames rendered before measuring, per cell [default: the matrix file's `warmup`, or 2].
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    warmup: Option<u32>,
    /// A folder of reference views (`parallax reference`) to measure every cell's accuracy against
    /// (FLIP and PSNR as `parallax compare` computes them, at the reference's automatic exposure).
    /// The settings in the first cell's render.json must match reference.json's (scene, camera,
    /// still, layout, spacing, focus, resolution, lights, max depth), else bench stops (exit 1)
    /// naming each difference.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Measure accuracy against the references even where the settings differ.
    #[arg(long)]
    allow_mismatch: bool,
    /// Folder for bench.json, bench.md, points.json and one sub-folder per cell (created if missing).
    #[arg(long, default_value = "out/bench")]
    out_dir: PathBuf,
    /// Keep the cells that ran well in --out-dir's bench.json (of the same matrix: frames,
    /// warm-up and case arguments are checked) and run only the others.
    #[arg(long)]
    resume: bool,
}

/// The one case and slice of the command-line flags.
fn matrix_of_flags(args: &BenchArgs) -> Result<Matrix> {
    if let Some(reference) = &args.reference
        && !reference.is_dir()
    {
        bail!("--reference {} is not a folder of reference views (see `parallax reference`)", reference.display());
    }
    let axes = Axes {
        pipelines: args.pipelines.clone(),
        schemes: args.schemes.clone(),
        assignments: args.assignments.clone(),
        sources_per_set: args.sources_per_set.clone(),
        spp: args.spp.clone(),
        denoise: args.denoise.clone(),
        tolerances: args.reprojection_tolerances.clone(),
        devices: if args.fake_devices.is_empty() { args.devices.clone() } else { args.fake_devices.clone() },
        fake_devices: !args.fake_devices.is_empty(),
    };
    let case = Case { name: None, args: args.common.clone(), reference: args.reference.clone() };
    Ok(Matrix { frames: None, warmup: None, cases: vec![case], slices: vec![(vec![0], axes)] })
}

/// The whole `parallax render` command line of a cell (after `render`). A cell's camera stays
/// where the case put it unless the case asks for a motion (`--motion`; `--still` is one too):
/// a benchmark measures views of one place, comparable with a still reference.
fn render_argv(case: &Case, cell: &Cell, frames: u32, warmup: u32, folder: &Path) -> Result<Vec<OsString>> {
    let words = case.words()?;
    let motion_given = words.iter().any(|w| w == "--motion" || w.starts_with("--motion=") || w == "--still");
    let mut argv: Vec<OsString> = words.into_iter().map(OsString::from).collect();
    if !motion_given {
        argv.extend(["--motion", "none"].map(OsString::from));
    }
    argv.extend(cell.args.iter().map(OsString::from));
    for a in ["--frames".into(), frames.to_string(), "--warmup".into(), warmup.to_string(), "--out-dir".into()] {
        argv.push(a.into());
    }
    argv.push(folder.into());
    Ok(argv)
}

/// Where a case comes from, for messages: its table in the matrix file, or `--common`.
fn case_origin(matrix: Option<&Path>, case: &Case) -> String {
    match (matrix, &case.name) {
        (Some(file), Some(name)) => format!("--matrix {}: [[case]] `{name}`: args", file.display()),
        _ => "--common".to_string(),
    }
}

/// The render flags bench sets per cell (clap id, spelling): a case may not give them.
const BENCH_FLAGS: [(&str, &str); 13] = [
    ("pipeline", "--pipeline"),
    ("scheme", "--scheme"),
    ("assign", "--assign"),
    ("sources_per_set", "--sources-per-set"),
    ("spp", "--spp"),
    ("no_denoise", "--no-denoise"),
    ("denoise", "--denoise"),
    ("reprojection_tolerance", "--reprojection-tolerance"),
    ("gpus", "--gpus"),
    ("fake_devices", "--fake-devices"),
    ("frames", "--frames"),
    ("warmup", "--warmup"),
    ("out_dir", "--out-dir"),
];

/// Parses a cell's render arguments as `render` will, so a bad case (a typo, or a flag the
/// matrix sets itself such as `--spp` or `--no-denoise`, which would make the cell render other
/// than its id says) fails before any cell runs rather than in every cell. `matrix` is the file
/// the case comes from, for the message.
fn check_render_args(matrix: Option<&Path>, case: &Case, argv: &[OsString]) -> Result<()> {
    let command = || <RenderArgs as clap::Args>::augment_args(clap::Command::new("render").no_binary_name(true));
    let origin = case_origin(matrix, case);
    let bench_flags = BENCH_FLAGS.map(|(_, flag)| flag).join(", ");
    let words = case.words().map_err(|e| anyhow::anyhow!("{origin}: {e}"))?;
    if let Ok(alone) = command().try_get_matches_from(&words)
        && let Some((_, flag)) =
            BENCH_FLAGS.iter().find(|(id, _)| alone.value_source(id) == Some(clap::parser::ValueSource::CommandLine))
    {
        bail!("{origin}: gives {flag}, which bench sets per cell; leave out {bench_flags}");
    }
    let matches = match command().try_get_matches_from(argv) {
        Ok(matches) => matches,
        Err(e) => {
            let text = e.to_string();
            let line = text.lines().next().unwrap_or("").trim_start_matches("error: ");
            bail!(
                "{origin}: not a render command line together with each cell's flags ({line}); fix it, and leave out \
                 what bench sets per cell: {bench_flags}"
            );
        }
    };
    // A missing scene would otherwise be found only when its first cell runs.
    if let Some(scene) = matches.get_one::<std::path::PathBuf>("scene").filter(|s| s.as_os_str() != "default") {
        parallax_scene::input::open_regular(scene)
            .map_err(|e| crate::options::input_error("--scene", scene, e))
            .with_context(|| origin.clone())?;
    }
    Ok(())
}

/// Makes a cell's `render` end with bench (Linux): a bench ended by a signal, or killed, would
/// otherwise leave its running cell rendering on, reparented to init, writing a complete cell
/// later into a matrix that no longer runs. The child asks for SIGTERM when its parent thread
/// ends (bench runs its cells from the main thread), which its own handler answers by removing
/// its unfinished outputs.
fn die_with_bench(render: &mut Command) {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt;
        let bench = nix::unistd::getpid();
        // SAFETY: between fork and exec the closure makes only async-signal-safe calls (prctl,
        // getppid) and allocates nothing.
        unsafe {
            render.pre_exec(move || {
                nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGTERM)?;
                // Bench may have ended before the request: then no signal would come.
                if nix::unistd::getppid() != bench {
                    return Err(std::io::Error::from_raw_os_error(libc::ESRCH));
                }
                Ok(())
            });
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = render;
}

/// Runs one cell; returns its bench.json entry. An error (the cell's settings differ from its
/// reference's) stops the matrix.
fn run_cell(
    case: &Case,
    cell: &Cell,
    argv: &[OsString],
    folder: &Path,
    allow_mismatch: bool,
) -> Result<serde_json::Value> {
    let exe = std::env::current_exe().context("cannot find this program to run the cells")?;
    // The cell's diagnostics go to an unnamed temporary file rather than a pipe: a render told
    // to stop because bench ended must still be able to write its last line, and a pipe
    // without its reader would fail that write.
    let mut diagnostics = tempfile::tempfile().context("cannot create a temporary file for a cell's diagnostics")?;
    let mut render = Command::new(exe);
    render.arg("-q").arg("render").args(argv).stdin(Stdio::null()).stdout(Stdio::null());
    render.stderr(diagnostics.try_clone().context("cannot pass a cell its diagnostics file")?);
    die_with_bench(&mut render);
    let status = render.status().context("cannot start a cell")?;
    let id = &cell.id;
    let shaped = Cell::shaped(cell.pipeline, cell.scheme);
    let (pipeline, scheme, denoiser) = (name_of(&cell.pipeline), name_of(&cell.scheme), name_of(&cell.denoise));
    let assignment = cell.assignment.map(|a| name_of(&a));
    let mut entry = CellHead {
        id,
        case: case.name.as_deref(),
        args: &cell.args,
        pipeline: &pipeline,
        scheme: &scheme,
        assignment: assignment.as_deref(),
        sources_per_set: cell.sources_per_set,
        spp: cell.spp,
        denoise: cell.denoise != Denoise::Off,
        denoiser: &denoiser,
        tolerance: cell.tolerance,
        devices: cell.devices,
    }
    .entry();
    if !status.success() {
        let mut stderr = Vec::new();
        diagnostics.seek(SeekFrom::Start(0))?;
        diagnostics.take(MAX_CELL_ERROR_BYTES).read_to_end(&mut stderr)?;
        bench_cell::failed(&mut entry, String::from_utf8_lossy(&stderr).trim().to_string());
        return Ok(entry);
    }
    let report: serde_json::Value = match parallax_scene::input::read_bounded(
        &folder.join("render.json"),
        parallax_scene::input::TEXT_FILE_LIMIT,
        "render.json",
    )
    .map_err(anyhow::Error::from)
    .and_then(|bytes| serde_json::from_slice(&bytes).map_err(anyhow::Error::from))
    {
        Ok(report) => report,
        Err(e) => {
            bench_cell::failed(&mut entry, format!("error: the cell ran but its render.json is unreadable: {e}"));
            return Ok(entry);
        }
    };
    let reprojected = cell.pipeline == PipelineArg::Reproject;
    let ran = RanCell { reprojected, default_assignment: shaped && cell.assignment.is_none() };
    bench_cell::ran(&mut entry, &report, ran);
    if let Some(reference) = &case.reference {
        // Settings that differ would make every cell of the case measure them, not its error.
        crate::cmd_compare::check_settings(folder, reference, allow_mismatch)
            .with_context(|| format!("cell {id}: --reference {}", reference.display()))?;
        // A reference that does not fit (other views or sizes) costs this cell its accuracy,
        // not the matrix its remaining cells.
        let options = parallax_accuracy::CompareOptions::default();
        match parallax_accuracy::compare_paths(folder, reference, &options) {
            Ok(c) => {
                entry["flip"] = c.overall.flip.into();
                entry["psnr_db"] = c.overall.psnr_linear_db.into();
            }
            Err(e) => entry["accuracy_error"] = format!("comparing with {}: {e}", reference.display()).into(),
        }
    }
    Ok(entry)
}

/// Writes bench.json, points.json and bench.md for the cells run so far; returns bench.md.
fn write_outputs(
    args: &BenchArgs,
    matrix: &bench_matrix::Matrix,
    frames: u32,
    warmup: u32,
    entries: &[serde_json::Value],
) -> Result<String> {
    let cases: Vec<serde_json::Value> = matrix
        .cases
        .iter()
        .map(|c| serde_json::json!({ "name": c.name, "args": c.args, "reference": c.reference }))
        .collect();
    let json = serde_json::json!({
        "common": args.matrix.is_none().then_some(&args.common), "matrix": args.matrix, "frames": frames,
        "warmup": warmup, "cases": cases, "cells": entries,
    });
    let staged_json = parallax_render::outputs::stage_json(&args.out_dir.join("bench.json"), &json)?;
    let points: Vec<serde_json::Value> =
        entries.iter().filter(|c| c["ok"] == true).map(bench_cell::chart_point).collect();
    let staged_points = parallax_render::outputs::stage_json(
        &args.out_dir.join("points.json"),
        &serde_json::json!({ "points": points }),
    )?;
    let md = tables::markdown(entries);
    let md_path = args.out_dir.join("bench.md");
    let staged_md = parallax_render::outputs::stage(&md_path, |tmp| {
        std::fs::write(tmp, &md).with_context(|| format!("cannot write {}", md_path.display()))
    })?;
    staged_md.commit()?;
    staged_points.commit()?;
    staged_json.commit()?;
    Ok(md)
}

pub fn run(args: BenchArgs) -> Result<()> {
    let matrix = match &args.matrix {
        Some(path) => bench_matrix::load(path)?,
        None => matrix_of_flags(&args)?,
    };
    let frames = args.frames.or(matrix.frames).unwrap_or(DEFAULT_FRAMES);
    let warmup = args.warmup.or(matrix.warmup).unwrap_or(DEFAULT_WARMUP);
    let cells = matrix.cells()?;
    let argvs: Vec<Vec<OsString>> = cells
        .iter()
        .map(|cell| {
            let case = &matrix.cases[cell.case];
            let argv = render_argv(case, cell, frames, warmup, &args.out_dir.join(&cell.id))
                .with_context(|| case_origin(args.matrix.as_deref(), case))?;
            check_render_args(args.matrix.as_deref(), case, &argv).map(|()| argv)
        })
        .collect::<Result<_>>()?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create --out-dir {}", args.out_dir.display()))?;
    let mut previous = if args.resume {
        bench_resume::previous_cells(&args.out_dir, &matrix.cases, frames, warmup)?
    } else {
        Default::default()
    };
    let progress = bar(cells.len() as u64);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} ({eta} left) {msg}")
    {
        progress.set_style(style);
    }
    let mut entries = Vec::with_capacity(cells.len());
    let mut md = String::new();
    for (k, (cell, argv)) in cells.iter().zip(&argvs).enumerate() {
        progress.set_message(cell.id.clone());
        let folder = args.out_dir.join(&cell.id);
        let (entry, kept) = match previous.remove(&cell.id) {
            Some(entry) => (entry, true),
            None => (run_cell(&matrix.cases[cell.case], cell, argv, &folder, args.allow_mismatch)?, false),
        };
        // A line per cell, so a log (stderr not a terminal, where the bar is not drawn) follows it.
        progress.suspend(|| tracing::info!("{}", bench_resume::cell_line(k + 1, cells.len(), &entry, kept)));
        entries.push(entry);
        // Written after every cell, so a run that is stopped keeps the cells it finished.
        md = write_outputs(&args, &matrix, frames, warmup, &entries)?;
        progress.inc(1);
    }
    progress.finish_and_clear();
    result(false, &md);
    let failed = entries.iter().filter(|c| c["ok"] != true).count();
    result(
        false,
        &format!("{} cell(s), {failed} failed; wrote {}", entries.len(), args.out_dir.join("bench.json").display()),
    );
    // A matrix with some failed cells still measured the others (exit 0, the failures listed);
    // one whose every cell failed measured nothing, which must not look like success.
    if failed > 0 && failed == entries.len() {
        bail!(
            "every one of the {failed} cell(s) failed (their errors are in {}): nothing was measured",
            args.out_dir.join("bench.json").display()
        );
    }
    if failed > 0 {
        tracing::warn!("{failed} of {} cell(s) failed: see their errors in bench.json", entries.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        bench: BenchArgs,
    }

    #[test]
    fn the_flags_defaults_are_the_matrix_files() {
        let args = Cli::try_parse_from(["bench"]).unwrap().bench;
        let m = matrix_of_flags(&args).unwrap();
        assert_eq!(m.slices, vec![(vec![0], Axes::default())]);
    }

    #[test]
    fn a_matrix_file_excludes_the_axis_flags() {
        assert!(Cli::try_parse_from(["bench", "--matrix", "m.toml", "--spp", "2"]).is_err());
        assert!(Cli::try_parse_from(["bench", "--matrix", "m.toml", "--frames", "2"]).is_ok());
    }

    #[test]
    fn case_args_that_clash_with_the_matrix_fail_before_running() {
        let case = Case { name: Some("a".into()), args: "--lf 2x1 --spp 4".into(), reference: None };
        let cell =
            &Matrix { frames: None, warmup: None, cases: vec![case.clone()], slices: vec![(vec![0], Axes::default())] }
                .cells()
                .unwrap()[0];
        let argv = render_argv(&case, cell, 1, 0, Path::new("out")).unwrap();
        let e = check_render_args(Some(Path::new("m.toml")), &case, &argv).unwrap_err().to_string();
        assert!(
            e.contains("--matrix m.toml: [[case]] `a`: args") && e.contains("gives --spp, which bench sets"),
            "{e}"
        );
        // A typo is still reported as render's parser sees it.
        let typo = Case { args: "--lf 2x1 --spp-typo 4".into(), ..case.clone() };
        let e = check_render_args(None, &typo, &render_argv(&typo, cell, 1, 0, Path::new("out")).unwrap()).unwrap_err();
        assert!(e.to_string().contains("--common: not a render command line") && e.to_string().contains("--spp-typo"));
        let fine = Case { args: "--lf 2x1".into(), ..case };
        check_render_args(None, &fine, &render_argv(&fine, cell, 1, 0, Path::new("out")).unwrap()).unwrap();
        // Quotes keep a path with spaces in one word; an unclosed one is refused.
        let quoted = Case { args: "--scene 'my scenes/a.gltf' --lf 2x1".into(), ..fine.clone() };
        assert_eq!(quoted.words().unwrap(), ["--scene", "my scenes/a.gltf", "--lf", "2x1"]);
        let open = Case { args: "--scene 'my scenes/a.gltf --lf 2x1".into(), ..fine };
        assert!(check_render_args(None, &open, &[]).unwrap_err().to_string().contains("a quote is not closed"));
    }
}
