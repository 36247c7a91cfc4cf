//! A cell's bench.json entry (its fields: `parallax bench`'s documentation): what the cell is,
//! then what its `render` reported in render.json, or its error.

use parallax_passes::HOLE_FILL;
use serde_json::Value;

use crate::report::stages::TRANSFER_STAGE;

/// What a cell is, its flags' values by the names they are spelled with.
#[derive(Clone, Copy, Debug)]
pub struct CellHead<'a> {
    pub id: &'a str,
    /// The case's name; None for `--common`.
    pub case: Option<&'a str>,
    /// The render arguments beyond the case's.
    pub args: &'a [String],
    pub pipeline: &'a str,
    pub scheme: &'a str,
    /// The assignment asked for (None: render's default, [`ran`] fills it in).
    pub assignment: Option<&'a str>,
    pub sources_per_set: u32,
    pub spp: u32,
    /// Whether it denoises at all, and how (`on`, `off`, `samples`).
    pub denoise: bool,
    pub denoiser: &'a str,
    /// The `--reprojection-tolerance` asked for (None: render's default, [`ran`] fills it in).
    pub tolerance: Option<f64>,
    pub devices: u32,
}

impl CellHead<'_> {
    /// The entry's fields before the cell runs.
    pub fn entry(&self) -> Value {
        serde_json::json!({
            "id": self.id, "case": self.case, "args": self.args, "pipeline": self.pipeline,
            "scheme": self.scheme, "assignment": self.assignment,
            "sources_per_set": self.sources_per_set, "spp": self.spp, "denoise": self.denoise, "denoiser": self.denoiser,
            "reprojection_tolerance": self.tolerance, "devices": self.devices,
        })
    }
}

/// Marks `entry` as a cell that failed with `error`.
pub fn failed(entry: &mut Value, error: String) {
    entry["ok"] = false.into();
    entry["error"] = error.into();
}

/// How to read a cell's render.json.
#[derive(Clone, Copy, Debug)]
pub struct RanCell {
    /// The reprojecting pipeline: render.json's reprojection tolerance and hole filling's time
    /// belong to the entry.
    pub reprojected: bool,
    /// The cell asked for no assignment where its pipeline and scheme use one: render.json's
    /// assignment (render's default) is the entry's.
    pub default_assignment: bool,
}

/// Fills in `entry` from the render.json `report` of a cell that ran.
pub fn ran(entry: &mut Value, report: &Value, cell: RanCell) {
    let timing = &report["timing"];
    let mean = timing["frame_gpu"]["mean_ms"].as_f64().unwrap_or(f64::NAN);
    let views = report["layout"]["views"].as_f64().unwrap_or(0.0);
    if cell.default_assignment {
        // Render's default, as it reports it.
        entry["assignment"] = report["assign"].clone();
    }
    if cell.reprojected {
        // Render's default when the cell gave none, as it reports it.
        entry["reprojection_tolerance"] = report["reprojection_tolerance"].clone();
    }
    entry["ok"] = true.into();
    entry["views"] = report["layout"]["views"].clone();
    entry["frame_ms"] = timing["frame_gpu"].clone();
    entry["views_per_s"] = (views * 1e3 / mean).into();
    entry["stages"] = timing["stages"].clone();
    entry["hole_fill_ms"] = if cell.reprojected { stage_total_ms(timing, HOLE_FILL).into() } else { Value::Null };
    entry["gather_ms"] = stage_total_ms(timing, TRANSFER_STAGE).into();
    entry["busy_fraction"] = timing["busy_fraction"].clone();
    entry["copy_bytes_per_frame"] = timing["copy_bytes_per_frame"].clone();
    entry["missing_pixels"] = report["missing_pixels"].clone();
}

/// The chart point of a cell that ran, for points.json (`parallax bench`'s documentation).
pub fn chart_point(c: &Value) -> Value {
    let reprojected = c["pipeline"] == "reproject";
    serde_json::json!({
        "label": c["id"], "series": c["pipeline"], "case": c["case"], "frame_ms": c["frame_ms"]["mean_ms"],
        "flip": c["flip"], "psnr": c["psnr_db"], "views": c["views"], "devices": c["devices"],
        "assignment": c["assignment"], "sources_per_set": c["sources_per_set"], "spp": c["spp"],
        "reprojection_tolerance": c["reprojection_tolerance"],
        "missing": if reprojected { c["missing_pixels"]["overall"].clone() } else { Value::Null },
        "hole_fill_ms": c["hole_fill_ms"],
    })
}

/// A stage's ms per frame in render.json's `timing`, summed over devices; 0 when no device ran
/// it. A fold from +0, because `sum` over no rows gives -0.
fn stage_total_ms(timing: &Value, stage: &str) -> Option<f64> {
    let rows = timing["stages"].as_array()?;
    Some(rows.iter().filter(|r| r["stage"] == stage).filter_map(|r| r["mean_ms"].as_f64()).fold(0.0, |a, b| a + b))
}
