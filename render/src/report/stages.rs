//! What `parallax render` measures and writes to render.json: per-stage per-device GPU time in
//! the layout of the paper's Table 1, frame times, busy fraction per device (Fig. 8), copies and
//! bytes moved, where the host's time per frame goes, and missing pixels per view and per
//! device (Table 4). Built from running statistics of the frames ([`FrameStats`]), not from
//! every frame's report.

use std::collections::BTreeMap;

use parallax_backend::{EventKind, EventTotals, ExecutionPlan, FrameStats, Summary};
use parallax_graph::FamilyId;

/// Mean GPU time of one stage on one device over the measured frames.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StageRow {
    pub stage: String,
    pub device: usize,
    pub mean_ms: f64,
    /// Timed events per frame: pass instances and copy chunks under `--timing per-op`, runs of
    /// one pass under `per-stage`.
    pub events_per_frame: f64,
}

/// Statistics of a list of times.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Spread {
    pub mean_ms: f64,
    pub median_ms: f64,
    pub p95_ms: f64,
}

impl Spread {
    /// Mean (exact), median and p95 (exact up to `SUMMARY_SAMPLE` frames, from a uniform
    /// sample after that) of a running summary of times in ms.
    pub fn of(summary: &Summary) -> Self {
        Self { mean_ms: summary.mean(), median_ms: summary.quantile(0.5), p95_ms: summary.quantile(0.95) }
    }
}

/// Where the host's time per frame goes, and whether it kept the GPU fed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct HostTimings {
    /// From one frame's submission to the next's: the frame period the host sees (compare with
    /// `frame_gpu`: equal when the GPU is the bottleneck and is never left waiting).
    pub frame_interval: Spread,
    /// Building and setting each frame's data (views' trace parameters, camera block).
    pub prepare: Spread,
    /// Executor CPU time to submit a frame (command buffers are recorded once, not per frame).
    pub submit_cpu: Spread,
    /// Time a submission waited for the frame whose slot it reuses (frames in flight full):
    /// the host is ahead of the GPU.
    pub slot_wait: Spread,
    /// From the last GPU event of a frame to the first of the next: idle GPU, or GPU work no
    /// timestamp covers (the per-frame buffer resets).
    pub gpu_gap: Spread,
    /// Frames submitted only after the previous frame's GPU work had ended (the GPU ran dry).
    pub late_frames: u64,
}

/// Everything timed about the measured frames.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Timings {
    pub frames: usize,
    /// GPU span of each frame (first event start to last event end over all devices), in
    /// frame order; beyond `SUMMARY_SAMPLE` frames a uniform sample of them (memory stays flat).
    pub frame_gpu_ms: Vec<f64>,
    /// Whether `frame_gpu_ms` holds every measured frame.
    pub frame_gpu_ms_complete: bool,
    pub frame_gpu: Spread,
    pub stages: Vec<StageRow>,
    /// Per device: time covered by its events over the frame's GPU span, averaged.
    pub busy_fraction: Vec<f64>,
    pub copies_per_frame: f64,
    pub copy_bytes_per_frame: f64,
    pub host: HostTimings,
}

/// The stage of display images moving to device 0 (Table 1's last stage).
pub const TRANSFER_STAGE: &str = "transfer";
/// The stage of every other transfer between devices.
pub const COPY_STAGE: &str = "copy";

/// Stage of an event: the pass name; [`TRANSFER_STAGE`] for display images moving to device 0,
/// [`COPY_STAGE`] for every other transfer between devices.
fn stage_of(totals: &EventTotals) -> String {
    match totals.kind {
        EventKind::Pass => totals.name.clone(),
        _ if totals.gather => TRANSFER_STAGE.to_string(),
        _ => COPY_STAGE.to_string(),
    }
}

/// The stages in the order the pipeline runs them (the paper's Table 1): its passes in the order
/// `plan` instantiates them, which is the order the pipeline declared them (not the order a
/// device submits them: that interleaves views); then the copies between devices, then the
/// gathers to device 0.
fn stage_order(plan: &ExecutionPlan) -> Vec<&str> {
    let mut order: Vec<&str> = Vec::new();
    for pass in &plan.passes {
        if !order.contains(&pass.name.as_str()) {
            order.push(&pass.name);
        }
    }
    order.extend([COPY_STAGE, TRANSFER_STAGE]);
    order
}

/// Where `stage` ranks in `order`: after all of it when not in it (callers sort those by name).
fn rank_in(order: &[&str], stage: &str) -> usize {
    order.iter().position(|&s| s == stage).unwrap_or(order.len())
}

/// The timings of the frames folded into `stats`; `prepare` is the renderer's frame-data time,
/// `plan` what ran them (it orders the stages).
pub fn timings(stats: &FrameStats, prepare: &Summary, plan: &ExecutionPlan) -> Timings {
    let frames = stats.frames().max(1) as f64;
    let mut stages: BTreeMap<(String, usize), (u64, u64)> = BTreeMap::new();
    let mut copies = 0u64;
    let mut bytes = 0u64;
    for totals in stats.event_totals() {
        let entry = stages.entry((stage_of(totals), totals.device)).or_default();
        entry.0 += totals.total_ns;
        entry.1 += totals.count;
        if totals.kind == EventKind::CopyIn {
            copies += totals.copies;
            bytes += totals.bytes;
        }
    }
    let mut stages: Vec<_> = stages.into_iter().collect();
    // Stable: a stage's devices in order (the map's), and stages the plan lacks by name.
    let order = stage_order(plan);
    stages.sort_by_key(|((stage, _), _)| rank_in(&order, stage));
    Timings {
        frames: stats.frames() as usize,
        frame_gpu_ms: stats.gpu_span_ms().sample().to_vec(),
        frame_gpu_ms_complete: stats.gpu_span_ms().is_complete(),
        frame_gpu: Spread::of(stats.gpu_span_ms()),
        stages: stages
            .into_iter()
            .map(|((stage, device), (ns, count))| StageRow {
                stage,
                device,
                mean_ms: ns as f64 / 1e6 / frames,
                events_per_frame: count as f64 / frames,
            })
            .collect(),
        busy_fraction: stats.busy_fraction(),
        copies_per_frame: copies as f64 / frames,
        copy_bytes_per_frame: bytes as f64 / frames,
        host: HostTimings {
            frame_interval: Spread::of(stats.interval_ms()),
            prepare: Spread::of(prepare),
            submit_cpu: Spread::of(stats.submit_cpu_ms()),
            slot_wait: Spread::of(stats.slot_wait_ms()),
            gpu_gap: Spread::of(stats.gpu_gap_ms()),
            late_frames: stats.host_late_frames(),
        },
    }
}

/// The stage table as markdown: one row per stage, one column per device (ms per frame).
pub fn stage_table(t: &Timings) -> String {
    let devices = t.stages.iter().map(|s| s.device + 1).max().unwrap_or(0);
    let mut order: Vec<String> = Vec::new();
    for s in &t.stages {
        if !order.contains(&s.stage) {
            order.push(s.stage.clone());
        }
    }
    let mut out = String::from("| stage |");
    for d in 0..devices {
        out.push_str(&format!(" GPU {d} (ms) |"));
    }
    out.push('\n');
    out.push_str(&"|---".repeat(devices + 1));
    out.push_str("|\n");
    for stage in order {
        out.push_str(&format!("| {stage} |"));
        for d in 0..devices {
            match t.stages.iter().find(|s| s.stage == stage && s.device == d) {
                Some(s) => out.push_str(&format!(" {:.3} |", s.mean_ms)),
                None => out.push_str(" – |"),
            }
        }
        out.push('\n');
    }
    out.push_str(&format!(
        "| frame (GPU span) | {:.3} mean, {:.3} median, {:.3} p95 |\n",
        t.frame_gpu.mean_ms, t.frame_gpu.median_ms, t.frame_gpu.p95_ms
    ));
    out
}

/// Missing pixels after reprojection (Table 4): per target view and per device that reprojected
/// them, the fraction of pixels that are holes.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct MissingPixels {
    /// (view, fraction), targets only.
    pub per_view: Vec<(u32, f64)>,
    /// Fraction of the pixels each device reprojected.
    pub per_device: Vec<f64>,
    pub overall: f64,
}

/// `holes[v]` is view v's hole mask (None for sources), the declared resource `holes_family`;
/// `plan` says which device wrote which rows of its final version (reprojection).
pub fn missing_pixels(
    plan: &ExecutionPlan,
    holes_family: FamilyId,
    holes: &[Option<Vec<u32>>],
    width: u32,
) -> MissingPixels {
    let devices = plan.devices.len();
    let (mut missed, mut total) = (vec![0u64; devices], vec![0u64; devices]);
    let mut per_view = Vec::new();
    for (v, mask) in holes.iter().enumerate() {
        let Some(mask) = mask else { continue };
        per_view.push((v as u32, mask.iter().filter(|&&h| h != 0).count() as f64 / mask.len().max(1) as f64));
        for (device, write) in plan.final_writes(holes_family, v as u32) {
            let rows = &mask[(write.region.y0 * width) as usize..(write.region.y1 * width) as usize];
            missed[device.index()] += rows.iter().filter(|&&h| h != 0).count() as u64;
            total[device.index()] += rows.len() as u64;
        }
    }
    let all: u64 = total.iter().sum();
    MissingPixels {
        per_view,
        per_device: missed.iter().zip(&total).map(|(&m, &t)| if t == 0 { 0.0 } else { m as f64 / t as f64 }).collect(),
        overall: if all == 0 { 0.0 } else { missed.iter().sum::<u64>() as f64 / all as f64 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plan of one instance per `(pass name, view)`, in that order, all on device 0.
    fn plan_of(instances: &[(&str, u32)]) -> ExecutionPlan {
        let pass_id = |name: &str| instances.iter().position(|&(n, _)| n == name).unwrap() as u32;
        let passes = instances
            .iter()
            .map(|&(name, view)| parallax_backend::PassInstance {
                pass: parallax_backend::PassId(pass_id(name)),
                name: name.into(),
                view: parallax_backend::ViewId(view),
                region: parallax_backend::Region::new(0, 1),
                device: parallax_backend::DeviceId(0),
                reads: vec![],
                writes: vec![],
                history_reads: vec![],
            })
            .collect();
        ExecutionPlan { passes, ..ExecutionPlan::default() }
    }

    #[test]
    fn stages_rank_in_the_order_the_plan_declares_its_passes() {
        // A source view 0 and a target view 1: each pass's first instance sets its rank, and
        // svgf_atrous_10 is declared (and ranks) after svgf_atrous_9, whatever the names' order.
        let plan = plan_of(&[
            ("gbuffer", 0),
            ("gbuffer", 1),
            ("path_trace", 0),
            ("reproject", 1),
            ("svgf_atrous_9", 0),
            ("svgf_atrous_9", 1),
            ("svgf_atrous_10", 0),
            ("tonemap", 0),
        ]);
        let order = stage_order(&plan);
        let mut names = [
            "transfer",
            "tonemap",
            "svgf_atrous_10",
            "zeta",
            "reproject",
            "svgf_atrous_9",
            "copy",
            "gbuffer",
            "path_trace",
            "alpha",
        ];
        names.sort_by_key(|n| (rank_in(&order, n), *n));
        assert_eq!(
            names,
            [
                "gbuffer",
                "path_trace",
                "reproject",
                "svgf_atrous_9",
                "svgf_atrous_10",
                "tonemap",
                "copy",
                "transfer",
                "alpha",
                "zeta"
            ]
        );
    }
}
