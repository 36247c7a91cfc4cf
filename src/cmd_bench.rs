//! `parallax bench`: a matrix of `render` runs (pipelines × schemes × sources per set × spp ×
//! denoise × device counts over one scene and light field), each cell a `parallax render` child
//! process of this binary, so a cell that fails (say, more devices than views) is reported with
//! its error and the others still run. Writes `bench.json` (documented below), `bench.md`, and
//! `points.json` (one chart point per cell, for `parallax chart speed-accuracy`).
//!
//! bench.json: `{"cells": [cell]}`; a cell has `id`, `args` (the render arguments), `ok`,
//! `error` (when not ok), and when ok: `frame_ms` (mean, median, p95 of the GPU span of the
//! measured frames), `views_per_s` (elemental images per second at the mean), `stages` (per
//! stage and device, ms per frame: the paper's Table 1), `busy_fraction` (per device: Fig. 8),
//! `missing_pixels` (Table 4), `copy_bytes_per_frame`, and with `--reference`: `flip`, `psnr_db`
//! (linear radiance clamped to [0, 1]) against that folder's views.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context as _, Result, bail};
use clap::{Args, ValueEnum};

use crate::cmd_render::PipelineArg;
use crate::logging::{bar, result};
use crate::options::SchemeArg;

/// `--denoise`: SVGF on or off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Denoise {
    On,
    Off,
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Scene options passed to every cell (`--scene`, `--camera`, `--sun`, `--sky`, `--lf`,
    /// `--resolution`, `--spacing`, `--max-depth`, `--still`, ...) as one string, e.g.
    /// "--scene default --lf 4x2 --resolution 32x32".
    #[arg(long, default_value = "--scene default", allow_hyphen_values = true)]
    common: String,
    /// Pipelines, comma-separated.
    #[arg(long, value_enum, default_value = "reproject,path-trace", value_delimiter = ',')]
    pipelines: Vec<PipelineArg>,
    /// Schemes, comma-separated.
    #[arg(long, value_enum, default_value = "multi-source", value_delimiter = ',')]
    schemes: Vec<SchemeArg>,
    /// Sources per multi-source set, comma-separated (reprojecting multi-source cells only).
    #[arg(long, default_value = "1", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..=64))]
    sources_per_set: Vec<u32>,
    /// Samples per pixel, comma-separated.
    #[arg(long, default_value = "1", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: Vec<u32>,
    /// Denoising, comma-separated.
    #[arg(long, value_enum, default_value = "on", value_delimiter = ',')]
    denoise: Vec<Denoise>,
    /// Device counts, comma-separated.
    #[arg(long, default_value = "1", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..=64))]
    devices: Vec<u32>,
    /// The device counts are logical devices on one GPU (lavapipe, or overhead runs), not GPUs.
    #[arg(long)]
    fake_devices: bool,
    /// Measured frames per cell, after --warmup frames.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Frames rendered before measuring, per cell.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    warmup: u32,
    /// A folder of reference views (`parallax reference`) to measure every cell's accuracy against.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Folder for bench.json, bench.md, points.json and one sub-folder per cell (created if missing).
    #[arg(long, default_value = "out/bench")]
    out_dir: PathBuf,
}

/// Each cell's id and render arguments (beyond the common ones).
fn cells(args: &BenchArgs) -> Vec<(String, Vec<String>)> {
    let value = |v: &dyn ValueEnumName| v.name();
    let mut out = Vec::new();
    for pipeline in &args.pipelines {
        for scheme in &args.schemes {
            // Sources per set only shape the reprojecting pipeline under multi-source.
            let shaped = *pipeline == PipelineArg::Reproject && *scheme == SchemeArg::MultiSource;
            let per_set = if shaped { &args.sources_per_set[..] } else { &args.sources_per_set[..1] };
            for &k in per_set {
                for &spp in &args.spp {
                    for denoise in &args.denoise {
                        for &devices in &args.devices {
                            let flag = if args.fake_devices { "--fake-devices" } else { "--gpus" };
                            let (pipeline, scheme, dn) = (value(pipeline), value(scheme), value(denoise));
                            let mut a: Vec<String> =
                                ["--pipeline", &pipeline, "--scheme", &scheme, "--spp", &spp.to_string()]
                                    .iter()
                                    .map(|s| s.to_string())
                                    .chain([flag.to_string(), devices.to_string()])
                                    .collect();
                            if shaped {
                                a.extend(["--sources-per-set".into(), k.to_string()]);
                            }
                            if *denoise == Denoise::Off {
                                a.push("--no-denoise".into());
                            }
                            out.push((format!("{pipeline}_{scheme}_k{k}_spp{spp}_dn{dn}_d{devices}"), a));
                        }
                    }
                }
            }
        }
    }
    out
}

/// The command-line spelling of a value of a clap enum.
trait ValueEnumName {
    fn name(&self) -> String;
}

impl<T: ValueEnum> ValueEnumName for T {
    fn name(&self) -> String {
        self.to_possible_value().map_or_else(String::new, |v| v.get_name().to_string())
    }
}

/// Runs one cell; returns its bench.json entry.
fn run_cell(args: &BenchArgs, id: &str, cell_args: &[String], folder: &Path) -> Result<serde_json::Value> {
    let exe = std::env::current_exe().context("cannot find this program to run the cells")?;
    let common: Vec<&str> = args.common.split_whitespace().collect();
    let output = Command::new(exe)
        .arg("-q")
        .arg("render")
        .args(&common)
        .args(cell_args)
        .args(["--frames", &args.frames.to_string(), "--warmup", &args.warmup.to_string(), "--out-dir"])
        .arg(folder)
        .output()
        .context("cannot start a cell")?;
    let mut entry = serde_json::json!({ "id": id, "args": cell_args });
    if !output.status.success() {
        let error = String::from_utf8_lossy(&output.stderr).trim().to_string();
        entry["ok"] = false.into();
        entry["error"] = error.into();
        return Ok(entry);
    }
    let report: serde_json::Value = serde_json::from_slice(
        &std::fs::read(folder.join("render.json")).with_context(|| format!("cell {id}: no render.json"))?,
    )?;
    let timing = &report["timing"];
    let mean = timing["frame_gpu"]["mean_ms"].as_f64().unwrap_or(f64::NAN);
    let views = report["layout"]["views"].as_f64().unwrap_or(0.0);
    entry["ok"] = true.into();
    entry["frame_ms"] = timing["frame_gpu"].clone();
    entry["views_per_s"] = (views * 1e3 / mean).into();
    entry["stages"] = timing["stages"].clone();
    entry["busy_fraction"] = timing["busy_fraction"].clone();
    entry["copy_bytes_per_frame"] = timing["copy_bytes_per_frame"].clone();
    entry["missing_pixels"] = report["missing_pixels"].clone();
    if let Some(reference) = &args.reference {
        let c = parallax_accuracy::compare_paths(folder, reference)
            .with_context(|| format!("cell {id}: comparing with --reference {}", reference.display()))?;
        entry["flip"] = c.overall.flip.into();
        entry["psnr_db"] = c.overall.psnr_linear_db.into();
    }
    Ok(entry)
}

/// The cells as a markdown table.
fn table(cells: &[serde_json::Value]) -> String {
    let mut out =
        String::from("| cell | frame ms (mean / median / p95) | views/s | missing pixels | FLIP | PSNR dB |\n");
    out.push_str("|---|---|---:|---:|---:|---:|\n");
    for c in cells {
        if c["ok"] != true {
            // The cell's one-line diagnosis (stderr may hold notes before it).
            let error = c["error"].as_str().unwrap_or("");
            let line = error.lines().find(|l| l.starts_with("error:")).unwrap_or(error);
            out.push_str(&format!("| {} | failed: {line} | | | | |\n", c["id"].as_str().unwrap_or("")));
            continue;
        }
        let f = &c["frame_ms"];
        let num =
            |v: &serde_json::Value, digits: usize| v.as_f64().map_or("–".to_string(), |x| format!("{x:.digits$}"));
        out.push_str(&format!(
            "| {} | {} / {} / {} | {} | {} % | {} | {} |\n",
            c["id"].as_str().unwrap_or(""),
            num(&f["mean_ms"], 2),
            num(&f["median_ms"], 2),
            num(&f["p95_ms"], 2),
            num(&c["views_per_s"], 1),
            c["missing_pixels"]["overall"].as_f64().map_or("–".into(), |m| format!("{:.2}", 100.0 * m)),
            num(&c["flip"], 4),
            num(&c["psnr_db"], 2),
        ));
    }
    out
}

pub fn run(args: BenchArgs) -> Result<()> {
    let cells = cells(&args);
    if let Some(reference) = &args.reference
        && !reference.is_dir()
    {
        bail!("--reference {} is not a folder of reference views (see `parallax reference`)", reference.display());
    }
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create --out-dir {}", args.out_dir.display()))?;
    let progress = bar(cells.len() as u64);
    let mut entries = Vec::with_capacity(cells.len());
    for (id, cell_args) in &cells {
        let folder = args.out_dir.join(id);
        entries.push(run_cell(&args, id, cell_args, &folder)?);
        progress.inc(1);
    }
    progress.finish_and_clear();
    let json =
        serde_json::json!({ "common": args.common, "frames": args.frames, "warmup": args.warmup, "cells": entries });
    let staged_json = crate::outputs::stage_json(&args.out_dir.join("bench.json"), &json)?;
    // The chart input (`parallax chart speed-accuracy points.json`): one point per cell that ran,
    // one series per pipeline.
    let points: Vec<serde_json::Value> = entries
        .iter()
        .filter(|c| c["ok"] == true)
        .map(|c| {
            serde_json::json!({ "label": c["id"], "series": c["args"][1], "frame_ms": c["frame_ms"]["mean_ms"],
                                "flip": c["flip"], "psnr": c["psnr_db"] })
        })
        .collect();
    let staged_points =
        crate::outputs::stage_json(&args.out_dir.join("points.json"), &serde_json::json!({ "points": points }))?;
    let md = table(&entries);
    let md_path = args.out_dir.join("bench.md");
    let staged_md = crate::outputs::stage(&md_path, |tmp| {
        std::fs::write(tmp, &md).with_context(|| format!("cannot write {}", md_path.display()))
    })?;
    staged_md.commit()?;
    staged_points.commit()?;
    staged_json.commit()?;
    result(false, &md);
    let failed = entries.iter().filter(|c| c["ok"] != true).count();
    result(
        false,
        &format!("{} cell(s), {failed} failed; wrote {}", entries.len(), args.out_dir.join("bench.json").display()),
    );
    Ok(())
}
