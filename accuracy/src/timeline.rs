//! A per-device timeline of a Chrome trace (what `render --trace` writes): one lane per device
//! (`tid`), one bar per complete event (`"ph": "X"`), coloured by event name, with a legend.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::chart::{FONT, LEGEND_WIDTH, SIZE, Swatch, chart_err, color, draw_legend, write_chart};
use crate::error::{AccuracyError, Result};
use parallax_scene::input::{TEXT_FILE_LIMIT, read_bounded};

/// One bar.
#[derive(Clone, Debug, PartialEq)]
pub struct Span {
    pub lane: u64,
    /// The pass name, or for copies their category ("copy_in", "copy_out"): one colour each.
    pub name: String,
    pub start_ms: f64,
    pub end_ms: f64,
}

/// The events of a Chrome trace, and lane names from its `thread_name` metadata.
#[derive(Clone, Debug, PartialEq)]
pub struct Timeline {
    pub lanes: Vec<(u64, String)>,
    pub spans: Vec<Span>,
}

impl Timeline {
    pub fn read(path: &Path) -> Result<Self> {
        let bad = |detail: String| AccuracyError::BadInput { path: path.into(), detail };
        let bytes = read_bounded(path, TEXT_FILE_LIMIT, "Chrome trace")?;
        let json: serde_json::Value = serde_json::from_slice(&bytes).map_err(|e| bad(format!("not JSON: {e}")))?;
        // Both forms of the format: {"traceEvents": [...]} and a bare array.
        let events = json
            .get("traceEvents")
            .unwrap_or(&json)
            .as_array()
            .ok_or_else(|| bad("not a Chrome trace (no traceEvents array)".into()))?;
        let mut lanes: Vec<(u64, String)> = Vec::new();
        let mut spans = Vec::new();
        for e in events {
            let tid = e.get("tid").and_then(|t| t.as_u64()).unwrap_or(0);
            match e.get("ph").and_then(|p| p.as_str()) {
                Some("M") if e.get("name").and_then(|n| n.as_str()) == Some("thread_name") => {
                    let name = e.pointer("/args/name").and_then(|n| n.as_str()).unwrap_or("").to_string();
                    lanes.push((tid, name));
                }
                Some("X") => {
                    let ts =
                        e.get("ts").and_then(|t| t.as_f64()).ok_or_else(|| bad(format!("event without ts: {e}")))?;
                    let dur = e.get("dur").and_then(|t| t.as_f64()).unwrap_or(0.0);
                    let name = match e.get("cat").and_then(|c| c.as_str()) {
                        Some(cat) if cat != "pass" => cat,
                        _ => e.get("name").and_then(|n| n.as_str()).unwrap_or("?"),
                    }
                    .to_string();
                    spans.push(Span { lane: tid, name, start_ms: ts / 1e3, end_ms: (ts + dur) / 1e3 });
                }
                _ => {}
            }
        }
        if spans.is_empty() {
            return Err(bad("the trace has no complete (\"ph\": \"X\") events".into()));
        }
        let mut named: HashSet<u64> = lanes.iter().map(|l| l.0).collect();
        for s in &spans {
            if named.insert(s.lane) {
                lanes.push((s.lane, format!("device {}", s.lane)));
            }
        }
        lanes.sort_by_key(|l| l.0);
        Ok(Self { lanes, spans })
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        root.fill(&WHITE).map_err(chart_err)?;
        // The legend beside the lanes, never over them.
        let (plot, legend) = root.split_horizontally(SIZE.0 - LEGEND_WIDTH);
        let end = self.spans.iter().map(|s| s.end_ms).fold(0.0, f64::max);
        let start = self.spans.iter().map(|s| s.start_ms).fold(f64::INFINITY, f64::min).min(0.0);
        let n = self.lanes.len();
        let mut chart = ChartBuilder::on(&plot)
            .caption("Per-device timeline", (FONT, 22))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(260)
            .build_cartesian_2d(start..end * 1.02 + 1e-6, 0.0..n as f64)
            .map_err(chart_err)?;
        let lanes = self.lanes.clone();
        chart
            .configure_mesh()
            .x_desc("time since the first event (ms)")
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 17))
            // Lane i spans [i, i + 1]: its name goes on the tick at i + 0.5.
            .y_labels(2 * n + 1)
            .y_label_formatter(&move |y: &f64| {
                let lane = y - 0.5;
                if (lane - lane.round()).abs() < 1e-6 && lane >= 0.0 {
                    lanes.get(lane.round() as usize).map_or(String::new(), |l| l.1.clone())
                } else {
                    String::new()
                }
            })
            .disable_y_mesh()
            .draw()
            .map_err(chart_err)?;
        // The spans of each name (in order of first appearance) and each lane's row, through
        // maps: a trace of 10⁵ events with as many names would take minutes with lookups in lists.
        let row: HashMap<u64, usize> = self.lanes.iter().enumerate().map(|(i, l)| (l.0, i)).collect();
        let mut names: Vec<(&str, Vec<&Span>)> = Vec::new();
        let mut index: HashMap<&str, usize> = HashMap::new();
        for s in &self.spans {
            let at = *index.entry(&s.name).or_insert_with(|| {
                names.push((&s.name, Vec::new()));
                names.len() - 1
            });
            names[at].1.push(s);
        }
        let mut entries = Vec::new();
        for (k, (name, spans)) in names.iter().enumerate() {
            let c = color(k);
            let bars = spans.iter().map(|s| {
                let lane = row[&s.lane];
                Rectangle::new([(s.start_ms, lane as f64 + 0.05), (s.end_ms, lane as f64 + 0.95)], c.mix(0.8).filled())
            });
            chart.draw_series(bars).map_err(chart_err)?;
            entries.push((name.to_string(), c, Swatch::Bar));
        }
        draw_legend(&legend, &entries, &[])?;
        root.present().map_err(chart_err)
    }

    /// Writes the timeline to `path`: SVG or PNG by its extension.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_chart(path, |root| self.draw(root), |root| self.draw(root))
    }
}
