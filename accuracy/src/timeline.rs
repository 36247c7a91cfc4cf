//! A per-device timeline of a Chrome trace (what `render --trace` writes): one lane per device
//! (`tid`), one bar per complete event (`"ph": "X"`), coloured by event name, with a legend;
//! frames (the events' `args.frame`) alternate on a shaded and a white background, each
//! named at its start where there is room.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::chart::{FONT, LEGEND_WIDTH, SIZE, Swatch, X_TICKS, chart_err, color, draw_legend, tick_label, write_chart};
use crate::error::{AccuracyError, Result};
use parallax_scene::input::{TEXT_FILE_LIMIT, read_bounded};

/// Height (in lanes) of the row above the lanes that names the frames.
const FRAME_ROW: f64 = 0.3;

/// One bar.
#[derive(Clone, Debug, PartialEq)]
pub struct Span {
    pub lane: u64,
    /// The pass name, or for copies their category ("copy_in", "copy_out"): one colour each.
    pub name: String,
    pub start_ms: f64,
    pub end_ms: f64,
    /// The frame it belongs to (`args.frame`), when the trace says.
    pub frame: Option<u64>,
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
                    let frame = e.pointer("/args/frame").and_then(|f| f.as_u64());
                    spans.push(Span { lane: tid, name, start_ms: ts / 1e3, end_ms: (ts + dur) / 1e3, frame });
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

    /// Each frame's first start and last end (ms), in frame order.
    pub fn frames(&self) -> Vec<(u64, f64, f64)> {
        let mut frames: Vec<(u64, f64, f64)> = Vec::new();
        for s in &self.spans {
            let Some(f) = s.frame else { continue };
            match frames.iter_mut().find(|(g, _, _)| *g == f) {
                Some((_, a, b)) => (*a, *b) = (a.min(s.start_ms), b.max(s.end_ms)),
                None => frames.push((f, s.start_ms, s.end_ms)),
            }
        }
        frames.sort_by_key(|f| f.0);
        frames
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
            .build_cartesian_2d(start..end * 1.02 + 1e-6, 0.0..n as f64 + FRAME_ROW)
            .map_err(chart_err)?;
        let lanes = self.lanes.clone();
        let span = end * 1.02 + 1e-6 - start;
        // Frames first, beneath the bars: every other one shaded, each named at its start when
        // the name does not run into the previous one's.
        let frames = self.frames();
        let shade = RGBColor(232, 232, 232);
        chart
            .draw_series(
                frames
                    .iter()
                    .skip(1)
                    .step_by(2)
                    .map(|&(_, a, b)| Rectangle::new([(a, 0.0), (b, n as f64 + FRAME_ROW)], shade.filled())),
            )
            .map_err(chart_err)?;
        let mut last_label_px: Option<i32> = None;
        let mut names = Vec::new();
        for &(f, a, _) in &frames {
            let top = n as f64 + FRAME_ROW;
            let (px, _) = chart.backend_coord(&(a, top));
            let text = format!("frame {f}");
            if last_label_px.is_none_or(|last| px - last > 8 * text.len() as i32 + 8) {
                names.push(EmptyElement::at((a, top)) + Text::new(text, (3, 3), (FONT, 13)));
                last_label_px = Some(px);
            }
        }
        chart.draw_series(names).map_err(chart_err)?;
        chart
            .configure_mesh()
            .x_desc("time since the first event (ms)")
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 17))
            .x_labels(X_TICKS)
            .x_label_formatter(&|x: &f64| tick_label(*x, span))
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
