//! Per-frame timing reports built from GPU timestamp pairs mapped to the host clock, and their
//! Chrome trace-event form (opens in Perfetto or chrome://tracing).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::device::DeviceInfo;
use crate::error::{BackendError, Result};

/// What a timed interval covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    Pass,
    CopyOut,
    CopyIn,
}

/// One timestamp pair, in host CLOCK_MONOTONIC nanoseconds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimedEvent {
    /// Pass name, or `copy <resource name>` for copies.
    pub name: String,
    pub kind: EventKind,
    pub device: usize,
    pub view: u32,
    /// Pass instance index or copy index in the plan.
    pub index: usize,
    /// Chunk index for copies (0 for passes).
    pub chunk: u32,
    /// Copy chunks the interval covers: 1 for a copy under `Timing::PerOp`, the run of
    /// consecutive copies of one direction under `Timing::PerStage`; 0 for passes.
    pub copies: u32,
    /// Bytes of those copies.
    pub bytes: u64,
    /// A copy of a finished view to device 0 ([`crate::CrossCopy::is_gather`]): Table 1's
    /// "transfer" rather than a copy between stages.
    pub gather: bool,
    pub start_ns: u64,
    pub end_ns: u64,
}

impl TimedEvent {
    pub fn duration_ns(&self) -> u64 {
        self.end_ns.saturating_sub(self.start_ns)
    }
}

/// Per device totals of one frame.
#[derive(Clone, Debug, Serialize)]
pub struct DeviceFrameStats {
    pub device: usize,
    /// Time covered by at least one event (overlaps counted once).
    pub busy_ns: u64,
    /// `busy_ns` over the frame's GPU span (first start to last end over all devices).
    pub busy_fraction: f64,
    pub events: usize,
}

/// Total time per stage (pass name or copy kind) and device.
#[derive(Clone, Debug, Serialize)]
pub struct StageStats {
    pub stage: String,
    pub device: usize,
    pub count: usize,
    pub total_ns: u64,
}

/// Everything measured about one frame.
#[derive(Clone, Debug, Serialize)]
pub struct FrameReport {
    pub frame: u64,
    /// Host time when the executor started submitting the frame.
    pub submit_start_ns: u64,
    /// CPU time the executor spent recording-free submission of this frame (excludes the
    /// frames-in-flight throttle wait).
    pub submit_cpu_ns: u64,
    /// Host time the submission waited for a frame in flight to retire before it could reuse
    /// its slot (the frames-in-flight throttle; 0 while fewer frames are in flight).
    pub slot_wait_ns: u64,
    pub submitted_passes: usize,
    pub submitted_segments: usize,
    /// From `submit_start_ns` to the end of the last GPU event.
    pub frame_wall_ns: u64,
    /// From the first GPU event start to the last end, over all devices.
    pub gpu_span_ns: u64,
    pub devices: Vec<DeviceFrameStats>,
    pub stages: Vec<StageStats>,
    pub events: Vec<TimedEvent>,
}

impl FrameReport {
    /// Builds the aggregates from the events of one frame.
    pub fn new(
        frame: u64,
        submit_start_ns: u64,
        submit_cpu_ns: u64,
        submitted_passes: usize,
        submitted_segments: usize,
        device_count: usize,
        mut events: Vec<TimedEvent>,
    ) -> Self {
        events.sort_by_key(|e| (e.device, e.start_ns, e.end_ns));
        let first = events.iter().map(|e| e.start_ns).min().unwrap_or(0);
        let last = events.iter().map(|e| e.end_ns).max().unwrap_or(0);
        let gpu_span_ns = last.saturating_sub(first);
        let devices = (0..device_count)
            .map(|d| {
                let mine: Vec<&TimedEvent> = events.iter().filter(|e| e.device == d).collect();
                let busy_ns = union_length(mine.iter().map(|e| (e.start_ns, e.end_ns)));
                DeviceFrameStats {
                    device: d,
                    busy_ns,
                    busy_fraction: if gpu_span_ns == 0 { 0.0 } else { busy_ns as f64 / gpu_span_ns as f64 },
                    events: mine.len(),
                }
            })
            .collect();
        let mut stages: BTreeMap<(String, usize), (usize, u64)> = BTreeMap::new();
        for e in &events {
            let stage = match e.kind {
                EventKind::Pass => e.name.clone(),
                EventKind::CopyOut => "copy out".to_string(),
                EventKind::CopyIn => "copy in".to_string(),
            };
            let entry = stages.entry((stage, e.device)).or_default();
            entry.0 += 1;
            entry.1 += e.duration_ns();
        }
        Self {
            frame,
            submit_start_ns,
            submit_cpu_ns,
            slot_wait_ns: 0,
            submitted_passes,
            submitted_segments,
            frame_wall_ns: last.saturating_sub(submit_start_ns),
            gpu_span_ns,
            devices,
            stages: stages
                .into_iter()
                .map(|((stage, device), (count, total_ns))| StageStats { stage, device, count, total_ns })
                .collect(),
            events,
        }
    }
}

/// Length of the union of intervals.
fn union_length(intervals: impl Iterator<Item = (u64, u64)>) -> u64 {
    let mut sorted: Vec<(u64, u64)> = intervals.collect();
    sorted.sort_unstable();
    let mut total = 0;
    let mut current: Option<(u64, u64)> = None;
    for (s, e) in sorted {
        current = match current {
            Some((cs, ce)) if s <= ce => Some((cs, ce.max(e))),
            Some((cs, ce)) => {
                total += ce - cs;
                Some((s, e))
            }
            None => Some((s, e)),
        };
    }
    total + current.map_or(0, |(s, e)| e - s)
}

/// Chrome trace-event JSON of `reports`: one process, one thread per device (named after it),
/// one complete ("X") event per timed span (a pass instance or copy chunk under `Timing::PerOp`,
/// a run of one pass's instances under `PerStage`), timestamps in µs relative to the first
/// event.
pub fn chrome_trace(reports: &[FrameReport], devices: &[DeviceInfo]) -> serde_json::Value {
    let origin =
        reports.iter().flat_map(|r| r.events.iter().map(|e| e.start_ns).chain([r.submit_start_ns])).min().unwrap_or(0);
    let us = |ns: u64| ns.saturating_sub(origin) as f64 / 1000.0;
    let mut events = Vec::new();
    for d in devices {
        events.push(serde_json::json!({
            "name": "thread_name", "ph": "M", "pid": 0, "tid": d.index,
            "args": { "name": format!("device {}: {}", d.index, d.name) },
        }));
    }
    for report in reports {
        for e in &report.events {
            events.push(serde_json::json!({
                "name": e.name,
                "cat": match e.kind { EventKind::Pass => "pass", EventKind::CopyOut => "copy_out", EventKind::CopyIn => "copy_in" },
                "ph": "X",
                "pid": 0,
                "tid": e.device,
                "ts": us(e.start_ns),
                "dur": e.duration_ns() as f64 / 1000.0,
                "args": { "frame": report.frame, "view": e.view, "index": e.index, "chunk": e.chunk, "bytes": e.bytes },
            }));
        }
    }
    serde_json::json!({ "traceEvents": events, "displayTimeUnit": "ms" })
}

/// Writes `value` as pretty JSON to `path`.
pub fn write_json(path: &std::path::Path, value: &impl Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value).expect("reports serialise");
    std::fs::write(path, text).map_err(|source| BackendError::Io { path: path.display().to_string(), source })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn union_counts_overlap_once() {
        assert_eq!(union_length([(0, 10), (5, 15), (20, 25)].into_iter()), 20);
        assert_eq!(union_length(std::iter::empty()), 0);
    }
}
