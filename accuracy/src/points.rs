//! The chart input: measurement points, read from the JSON that `render`, `reference` and
//! `compare` write, or from a file of this schema (the one `bench` will write):
//!
//! ```json
//! { "points": [ { "label": "multi-source, 2 GPUs", "series": "multi-source",
//!                 "frame_ms": 12.5, "flip": 0.041, "psnr": 31.2, "devices": 2, "views": 32,
//!                 "case": "nelf", "assignment": "compact", "sources_per_set": 2, "spp": 4,
//!                 "missing": 0.012, "hole_fill_ms": 0.8, "reprojection_tolerance": 0.2 } ] }
//! ```
//!
//! Every field but `label` is optional; a chart uses the points that have what it plots.
//! `case`: the bench case the point belongs to (`chart --case`); `assignment`: how views were
//! assigned to devices; `missing`: fraction of reprojected pixels that were holes;
//! `hole_fill_ms`: hole-filling GPU time per frame, summed over devices;
//! `reprojection_tolerance`: `render --reprojection-tolerance` of a reprojecting run.
//! `frame_ms`: milliseconds per frame (render.json: the GPU span of the frame); `flip`: mean
//! LDR-FLIP; `psnr`: dB on linear radiance clamped to [0, 1]; `series` groups points into one
//! line or colour. Accepted files: `{"points": [...]}`, `{"point": {...}}` (what `compare --json`
//! and `reference.json` carry) and `render.json` itself.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{AccuracyError, Result};
use parallax_scene::input::{TEXT_FILE_LIMIT, read_bounded};

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    pub label: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub series: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_ms: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flip: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub psnr: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub devices: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub views: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub case: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub assignment: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sources_per_set: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spp: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub missing: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hole_fill_ms: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reprojection_tolerance: Option<f64>,
}

impl Point {
    pub fn series_name(&self) -> &str {
        self.series.as_deref().unwrap_or("")
    }

    /// Every value a chart can draw: a negative time, a FLIP outside 0..=1 or a 1e308 would give
    /// an axis of garbled ticks, so such a point is refused with the field and its range.
    pub fn check(&self) -> std::result::Result<(), String> {
        let fields = [
            ("frame_ms", self.frame_ms, 0.0..=MAX_MS),
            ("hole_fill_ms", self.hole_fill_ms, 0.0..=MAX_MS),
            ("flip", self.flip, 0.0..=1.0),
            ("psnr", self.psnr, -1e3..=1e3),
            ("missing", self.missing, 0.0..=100.0),
        ];
        for (name, value, range) in fields {
            if let Some(v) = value.filter(|v| !range.contains(v)) {
                let shown = if v.abs() >= 1e6 { format!("{v:e}") } else { v.to_string() };
                return Err(format!("{name} {shown} is outside {}..={}", range.start(), range.end()));
            }
        }
        Ok(())
    }
}

/// The longest time a point may give: 1e9 ms (11 days).
const MAX_MS: f64 = 1e9;

/// The points of case `name`; an error naming the cases there are when none is of it.
pub fn of_case(points: Vec<Point>, name: &str) -> Result<Vec<Point>> {
    let mut known: Vec<&str> = points.iter().filter_map(|p| p.case.as_deref()).collect();
    known.sort_unstable();
    known.dedup();
    let list =
        if known.is_empty() { "none has a case".to_string() } else { format!("the cases are {}", known.join(", ")) };
    let kept: Vec<Point> = points.into_iter().filter(|p| p.case.as_deref() == Some(name)).collect();
    if kept.is_empty() {
        return Err(AccuracyError::Chart(format!("no input point is of case `{name}` ({list})")));
    }
    Ok(kept)
}

/// The point of one render.json (see `parallax render`): label "<pipeline>, <scheme>, N
/// device(s)", series the pipeline (reproject or path-trace), frame time the mean GPU span of
/// the measured frames.
pub fn point_of_render_json(json: &serde_json::Value) -> Option<Point> {
    let plan = json.get("plan")?;
    let scheme = plan.get("scheme")?.as_str()?.to_string();
    let devices = plan.get("devices")?.as_u64()? as u32;
    let pipeline = json.get("pipeline").and_then(|p| p.as_str()).unwrap_or("path-trace").to_string();
    Some(Point {
        label: format!("{pipeline}, {scheme}, {devices} device(s)"),
        series: Some(pipeline),
        frame_ms: json.get("timing")?.get("frame_gpu")?.get("mean_ms")?.as_f64(),
        devices: Some(devices),
        views: plan.get("views")?.as_u64().map(|v| v as u32),
        ..Default::default()
    })
}

/// Every point in a JSON file of one of the accepted shapes (module docs).
pub fn load_points(path: &Path) -> Result<Vec<Point>> {
    let bad = |detail: String| AccuracyError::BadInput { path: path.into(), detail };
    let text = read_bounded(path, TEXT_FILE_LIMIT, "points file")?;
    let json: serde_json::Value = serde_json::from_slice(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let parse = |v: &serde_json::Value| {
        let point = serde_json::from_value::<Point>(v.clone()).map_err(|e| bad(format!("bad point {v}: {e}")))?;
        point.check().map_err(|e| bad(format!("point '{}': {e}", point.label)))?;
        Ok(point)
    };
    if let Some(list) = json.get("points") {
        let list = list.as_array().ok_or_else(|| bad("`points` must be an array".into()))?;
        return list.iter().map(parse).collect();
    }
    if let Some(p) = json.get("point") {
        return Ok(vec![parse(p)?]);
    }
    point_of_render_json(&json).map(|p| vec![p]).ok_or_else(|| {
        bad("no `points`, no `point` and not a render.json: see `parallax chart --help` for the schema".into())
    })
}
