//! Benchmarks (commands, not tests): cross-device copy bandwidth and the executor's CPU cost per
//! submitted pass. Used by `parallax bench-copy`; results go to docs/RESULTS.md.
//!
//! Both are declared as graphs, compiled under a placement of whole views in order over the devices
//! and turned into a kernel plan like any pipeline, so what they measure is what a real plan runs. Their producer is
//! `bench_fill` (`backend/shaders/bench_fill.comp`), whose values nobody reads.

use std::sync::Arc;

use parallax_graph::{
    DeviceId, Format, Handle, Image, PassBuilder, PassPlacementInfo, Placement, Region, Role, ViewId, ViewTopology,
    WriteSlot,
};
use serde::Serialize;

use crate::context::{Context, ContextDesc};
use crate::device::DeviceInfo;
use crate::error::Result;
use crate::exec_options::ExecOptions;
use crate::executor::Executor;
use crate::kernel::{KernelPlan, PassKernel};
use crate::kernel_graph::{Compiled, KernelGraph};
use crate::plan::{CopyId, InstanceId, PassInstance};
use crate::recorder::Recorder;
use crate::timing::{EventKind, FrameReport};

/// Width of the benchmark payload image (RGBA32F, 16 KiB per row).
const PAYLOAD_WIDTH: u32 = 1024;

/// Settings of [`copy_bandwidth`].
#[derive(Clone, Debug)]
pub struct CopyBenchOptions {
    pub bytes: u64,
    pub chunk_bytes: u64,
    pub frames: usize,
    /// Frames run before measuring (first-touch of host pages, pipeline creation).
    pub warmup: usize,
    pub frames_in_flight: usize,
    /// Copies on a transfer-only queue where the devices have one.
    pub separate_copy_queue: bool,
    /// The link kind to copy over (`None`: the best the devices offer).
    pub link: Option<crate::links::LinkKind>,
}

impl Default for CopyBenchOptions {
    fn default() -> Self {
        Self {
            bytes: 64 << 20,
            chunk_bytes: 8 << 20,
            frames: 30,
            warmup: 3,
            frames_in_flight: 2,
            separate_copy_queue: true,
            link: None,
        }
    }
}

/// One frame of the copy benchmark, from GPU timestamps on the host clock.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CopyFrame {
    pub frame: u64,
    /// First copy-out start to last copy-in end: what a consumer waits for.
    pub end_to_end_ns: u64,
    /// Producer side: first copy-out start to last copy-out end.
    pub device_to_host_span_ns: u64,
    /// Consumer side: first copy-in start to last copy-in end (includes waits for chunks).
    pub host_to_device_span_ns: u64,
    /// Sum of the copy-out chunk durations (the device→host transfer rate without gaps).
    pub device_to_host_busy_ns: u64,
    /// Sum of the copy-in chunk durations.
    pub host_to_device_busy_ns: u64,
    /// Time both directions were running at once (0 = not pipelined).
    pub overlap_ns: u64,
    /// Per chunk: copy-in start minus copy-out end (the cross-device signal latency, host relay
    /// included, plus any wait for the consumer's queue); the median over the chunks.
    pub median_handoff_ns: i64,
    /// Host-clock time the frame's last copy-in ended (for the sustained rate).
    pub copy_in_end_ns: u64,
}

/// Result of [`copy_bandwidth`].
#[derive(Clone, Debug, Serialize)]
pub struct CopyBenchResult {
    pub devices: Vec<DeviceInfo>,
    /// The kind of link the copy went over (links.rs).
    pub link: crate::links::LinkKind,
    pub bytes: u64,
    pub chunk_bytes: u64,
    pub chunks: usize,
    /// Whether copies were asked to go to a queue of their own, and whether each device really
    /// has a transfer-only queue (if not, its copies went to the main queue): in JSON
    /// `copy_queue_requested`, so that `true` beside `[false, false]` does not read as a queue
    /// the devices do not have.
    #[serde(rename = "copy_queue_requested")]
    pub separate_copy_queue: bool,
    pub devices_with_copy_queue: Vec<bool>,
    pub frames: Vec<CopyFrame>,
    /// Median over frames of bytes / end_to_end (GB/s, 1 GB = 1e9 bytes). With several frames
    /// in flight a frame's copy can queue behind the previous frame's upload, so this is the
    /// latency-bound rate; with one frame in flight it is the rate of an isolated copy.
    ///
    /// Each rate is `None` (JSON `null`) when it could not be measured: copies too short for the
    /// device timer (0 ns), or fewer than two frames for the sustained rate. Never a made-up 0.
    pub median_gb_per_s: Option<f64>,
    /// Bytes delivered per second over all measured frames: bytes × (frames − 1) / (time between
    /// the first and the last frame's last copy-in end). The throughput a stream of frames gets.
    pub sustained_gb_per_s: Option<f64>,
    pub best_gb_per_s: Option<f64>,
    /// Median rate of the device→host copies while they run (bytes / busy time).
    pub median_device_to_host_gb_per_s: Option<f64>,
    /// Median rate of the host→device copies while they run.
    pub median_host_to_device_gb_per_s: Option<f64>,
    /// Median over frames of the per-chunk handoff latency (µs).
    pub median_handoff_us: f64,
    /// The measured frames' full reports (for `--trace`).
    #[serde(skip)]
    pub reports: Vec<FrameReport>,
}

/// Writes its `payload` write over the instance's rows (`bench_fill.comp`).
pub struct BenchFillKernel {
    payload: WriteSlot,
}

/// Name of the producer pass, its slot and its shader.
pub const BENCH_FILL: &str = "bench_fill";
const PAYLOAD: &str = "payload";

impl PassKernel for BenchFillKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
        let dst = pass.write(self.payload)?.alloc;
        let params = rec.row_params(pass, dst)?;
        rec.dispatch_rows(crate::bindings::BENCH_FILL, params)
    }
}

/// Declares `bench_fill` writing `payload` for the views of `role`, its kernel attached; the
/// caller records it.
fn declare_fill<'g>(
    graph: &'g mut KernelGraph,
    role: Role,
    payload: &mut Handle<Image>,
) -> PassBuilder<'g, Arc<dyn PassKernel>> {
    let mut pass = graph.pass(BENCH_FILL, role);
    let kernel = BenchFillKernel { payload: pass.write_slot(payload) };
    pass.kernel(Arc::new(kernel))
}

/// The consumer of the copy benchmark: it records nothing, its read of the payload is what
/// makes the copy.
struct ReceiveKernel;

impl PassKernel for ReceiveKernel {
    fn record(&self, _: &mut Recorder<'_>, _: &PassInstance, _: InstanceId) -> Result<()> {
        Ok(())
    }
}

/// View `v` whole on device `v / views_per_device`.
struct ViewsInOrder {
    devices: u32,
    views_per_device: u32,
}

impl Placement for ViewsInOrder {
    fn devices(&self) -> u32 {
        self.devices
    }

    fn place(&self, _: PassPlacementInfo<'_>, view: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        vec![(DeviceId(view.0 / self.views_per_device.max(1)), Region::rows(height))]
    }
}

/// The copy benchmark: `bench_fill` writes a `width`×`height` RGBA32F payload for view 0 on
/// device 0; view 1 on device 1 reads it as its source, so the payload crosses from device 0
/// to device 1 every frame.
pub fn copy_plan(width: u32, height: u32) -> Result<KernelPlan> {
    let topology =
        ViewTopology { width, height, sources_of: vec![vec![], vec![ViewId(0)]], is_source: vec![true, false] };
    let mut graph = KernelGraph::with_payload(topology);
    let mut payload = graph.image(PAYLOAD, Format::Rgba32f);
    declare_fill(&mut graph, Role::Sources, &mut payload).add();
    graph.pass("receive", Role::Targets).read_sources(&payload).side_effect().kernel(Arc::new(ReceiveKernel)).add();
    Ok(Compiled::compile(&graph, &ViewsInOrder { devices: 2, views_per_device: 1 })?.plan)
}

/// `sources` payloads on device 0 that one target on device 1 reads: `sources` copies in a row
/// into device 1 (segmentation tests).
#[cfg(test)]
pub(crate) fn gather_plan(sources: u32, width: u32, height: u32) -> Result<KernelPlan> {
    let all: Vec<ViewId> = (0..sources).map(ViewId).collect();
    let mut sources_of = vec![vec![]; sources as usize];
    sources_of.push(all);
    let mut is_source = vec![true; sources as usize];
    is_source.push(false);
    let mut graph = KernelGraph::with_payload(ViewTopology { width, height, sources_of, is_source });
    let mut payload = graph.image(PAYLOAD, Format::Rgba32f);
    declare_fill(&mut graph, Role::Sources, &mut payload).add();
    graph.pass("receive", Role::Targets).read_sources(&payload).side_effect().kernel(Arc::new(ReceiveKernel)).add();
    Ok(Compiled::compile(&graph, &ViewsInOrder { devices: 2, views_per_device: sources })?.plan)
}

/// The overhead benchmark: `passes_per_device` views of `size`×`size` RGBA8 per device, each
/// filled by one `bench_fill` and kept by `side_effect()`; no copies.
pub fn overhead_plan(devices: u32, passes_per_device: u32, size: u32) -> Result<KernelPlan> {
    let topology = ViewTopology::all_sources(devices * passes_per_device, size, size);
    let mut graph = KernelGraph::with_payload(topology);
    let mut target = graph.image(PAYLOAD, Format::Rgba8);
    declare_fill(&mut graph, Role::All, &mut target).side_effect().add();
    Ok(Compiled::compile(&graph, &ViewsInOrder { devices, views_per_device: passes_per_device })?.plan)
}

fn sustained_rate(bytes: u64, frames: &[CopyFrame]) -> Option<f64> {
    match (frames.first(), frames.last()) {
        (Some(first), Some(last)) if frames.len() > 1 => {
            gb_per_s(bytes * (frames.len() as u64 - 1), last.copy_in_end_ns.saturating_sub(first.copy_in_end_ns))
        }
        _ => None,
    }
}

/// None for a span the timer did not resolve.
fn gb_per_s(bytes: u64, ns: u64) -> Option<f64> {
    (ns > 0).then(|| bytes as f64 / ns as f64)
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median over chunks of (copy-in start − copy-out end) of the same chunk.
fn median_handoff(report: &FrameReport) -> i64 {
    let end_of =
        |chunk: u32| report.events.iter().find(|e| e.kind == EventKind::CopyOut && e.chunk == chunk).map(|e| e.end_ns);
    let mut gaps: Vec<i64> = report
        .events
        .iter()
        .filter(|e| e.kind == EventKind::CopyIn)
        .filter_map(|e| end_of(e.chunk).map(|end| e.start_ns as i64 - end as i64))
        .collect();
    gaps.sort_unstable();
    gaps.get(gaps.len() / 2).copied().unwrap_or(0)
}

/// Span (first start, last end) of the events of `kind`.
fn span(report: &FrameReport, kind: EventKind) -> (u64, u64) {
    let events = report.events.iter().filter(|e| e.kind == kind);
    let start = events.clone().map(|e| e.start_ns).min().unwrap_or(0);
    let end = events.map(|e| e.end_ns).max().unwrap_or(0);
    (start, end)
}

/// Moves `options.bytes` from device 0 to device 1 every frame (fill on device 0, copy-out,
/// copy-in on device 1) and measures the copy with GPU timestamps. `desc` must yield two devices.
pub fn copy_bandwidth(desc: &ContextDesc, options: &CopyBenchOptions) -> Result<CopyBenchResult> {
    let context = Context::new(desc)?;
    let row_bytes = u64::from(PAYLOAD_WIDTH) * 16;
    let height = options.bytes.div_ceil(row_bytes).max(1) as u32;
    let plan = copy_plan(PAYLOAD_WIDTH, height)?;
    let bytes = plan.copy_bytes(CopyId(0));
    let mut executor = Executor::new(
        &context,
        plan,
        ExecOptions {
            frames_in_flight: options.frames_in_flight,
            chunk_bytes: options.chunk_bytes,
            separate_copy_queue: options.separate_copy_queue,
            link: options.link,
            ..ExecOptions::default()
        },
    )?;
    let link = executor.links().first().expect("the copy plan has one link").kind;
    for _ in 0..options.warmup + options.frames {
        executor.run_frame()?;
    }
    executor.finish()?;
    context.check_validation()?;
    let reports: Vec<FrameReport> = executor.take_reports().into_iter().skip(options.warmup).collect();
    let chunks = reports.first().map_or(0, |r| r.events.iter().filter(|e| e.kind == EventKind::CopyOut).count());
    let frames: Vec<CopyFrame> = reports
        .iter()
        .map(|r| {
            let (out_start, out_end) = span(r, EventKind::CopyOut);
            let (in_start, in_end) = span(r, EventKind::CopyIn);
            let busy = |kind| r.events.iter().filter(|e| e.kind == kind).map(|e| e.duration_ns()).sum();
            CopyFrame {
                frame: r.frame,
                end_to_end_ns: in_end.saturating_sub(out_start),
                device_to_host_span_ns: out_end.saturating_sub(out_start),
                host_to_device_span_ns: in_end.saturating_sub(in_start),
                device_to_host_busy_ns: busy(EventKind::CopyOut),
                host_to_device_busy_ns: busy(EventKind::CopyIn),
                overlap_ns: out_end.min(in_end).saturating_sub(out_start.max(in_start)),
                median_handoff_ns: median_handoff(r),
                copy_in_end_ns: in_end,
            }
        })
        .collect();
    let rate = |f: fn(&CopyFrame) -> u64| {
        let rates: Vec<f64> = frames.iter().filter_map(|fr| gb_per_s(bytes, f(fr))).collect();
        (!rates.is_empty()).then(|| median(rates))
    };
    Ok(CopyBenchResult {
        devices: context.device_infos(),
        link,
        bytes,
        chunk_bytes: options.chunk_bytes,
        chunks,
        separate_copy_queue: options.separate_copy_queue,
        devices_with_copy_queue: context.devices().iter().map(|d| d.has_copy_queue()).collect(),
        median_gb_per_s: rate(|f| f.end_to_end_ns),
        sustained_gb_per_s: sustained_rate(bytes, &frames),
        best_gb_per_s: frames.iter().filter_map(|f| gb_per_s(bytes, f.end_to_end_ns)).reduce(f64::max),
        median_device_to_host_gb_per_s: rate(|f| f.device_to_host_busy_ns),
        median_host_to_device_gb_per_s: rate(|f| f.host_to_device_busy_ns),
        median_handoff_us: median(frames.iter().map(|f| f.median_handoff_ns as f64 / 1000.0).collect()),
        frames,
        reports,
    })
}

/// Settings of [`executor_overhead`].
#[derive(Clone, Debug)]
pub struct OverheadBenchOptions {
    pub passes_per_device: u32,
    pub frames: usize,
    pub warmup: usize,
}

impl Default for OverheadBenchOptions {
    fn default() -> Self {
        Self { passes_per_device: 256, frames: 200, warmup: 10 }
    }
}

/// Result of [`executor_overhead`].
#[derive(Clone, Debug, Serialize)]
pub struct OverheadBenchResult {
    pub devices: Vec<DeviceInfo>,
    pub passes_per_frame: usize,
    pub frames: usize,
    /// Median CPU time of `run_frame` (submission + relay bookkeeping, excluding the
    /// frames-in-flight wait) per frame, and per submitted pass.
    pub median_submit_us_per_frame: f64,
    pub median_submit_us_per_pass: f64,
    /// Median host wall time per frame (`run_frame` calls back to back, throttled by the GPU).
    pub median_frame_wall_us: f64,
    /// One-time cost of recording all command buffers (every slot), per pass instance.
    pub record_us_per_pass: f64,
}

/// Submits frames of many tiny passes and reports the executor's CPU cost per pass.
pub fn executor_overhead(desc: &ContextDesc, options: &OverheadBenchOptions) -> Result<OverheadBenchResult> {
    let context = Context::new(desc)?;
    let devices = context.devices().len();
    let plan = overhead_plan(devices as u32, options.passes_per_device, 8)?;
    let passes = plan.passes.len();
    let mut executor = Executor::new(&context, plan, ExecOptions::default())?;
    for _ in 0..options.warmup + options.frames {
        executor.run_frame()?;
    }
    executor.finish()?;
    context.check_validation()?;
    let reports: Vec<FrameReport> = executor.take_reports().into_iter().skip(options.warmup).collect();
    let per_frame = median(reports.iter().map(|r| r.submit_cpu_ns as f64 / 1000.0).collect());
    let walls: Vec<f64> =
        reports.windows(2).map(|w| w[1].submit_start_ns.saturating_sub(w[0].submit_start_ns) as f64 / 1000.0).collect();
    Ok(OverheadBenchResult {
        devices: context.device_infos(),
        passes_per_frame: passes,
        frames: reports.len(),
        median_submit_us_per_frame: per_frame,
        median_submit_us_per_pass: per_frame / passes.max(1) as f64,
        median_frame_wall_us: median(walls),
        record_us_per_pass: executor.last_record_ns() as f64 / 1000.0 / passes.max(1) as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Copies too short for the timer used to report 0.0 GB/s; they report no rate.
    #[test]
    fn an_unresolved_span_gives_no_rate_rather_than_zero() {
        assert_eq!(gb_per_s(1 << 20, 0), None);
        assert_eq!(gb_per_s(2_000, 1_000), Some(2.0));
        let frame = |copy_in_end_ns| CopyFrame { copy_in_end_ns, ..Default::default() };
        assert_eq!(sustained_rate(1000, &[frame(5)]), None, "one frame");
        assert_eq!(sustained_rate(1000, &[frame(5), frame(5)]), None, "no time between frames");
        assert_eq!(sustained_rate(1000, &[frame(5), frame(505)]), Some(2.0));
    }
}
