//! The hole-filling benchmark: GPU time of hole filling per hole pixel against full-view path
//! tracing per pixel, for the target "hole-filling time per hole pixel ≤ 1.25× full-view path
//! tracing time per pixel". Before reprojection produces real holes, the mask is synthetic
//! ([`HashedHoleMaskKernel`]: scattered pixels, a hashed fraction of the view), which is the
//! incoherent end for hole filling: real holes cluster along disocclusions. With first hits the
//! plan has the pipeline's G-buffer, and hole filling bounds its camera rays by the centre rays'
//! hits as in the pipeline (`first_hit`, [`crate::HoleFillKernel`]); without, it traces them whole
//! (the raster G-buffer's case), so the two runs compare the same holes.

use std::sync::Arc;

use parallax_backend::{
    BackendError, Compiled, Context, ExecOptions, Executor, Format, FrameClock, FrameData, FrameReport, InstanceId,
    KernelGraph, KernelPlan, PassInstance, PassKernel, PassParams, Recorder,
};
use parallax_graph::{BandedPlacement, FamilyId, Role, ViewId, ViewTopology, WriteSlot};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{Camera, Scene, SceneBvh, TraceSettings, View};

use crate::camera::frame_block;
use crate::error::{PassError, Result};
use crate::gbuffer::declare_gbuffer;
use crate::holes::{COMPACT_HOLES, HOLE_FILL, HOLES, declare_hole_fill};
use crate::path_trace::{PATH_TRACE, PathTraceKernel, trace_frame_data};
use crate::scene_upload::upload_scene;
use crate::shaders;

/// Pass name of [`HashedHoleMaskKernel`].
pub const HOLE_MASK: &str = "hole_mask";

/// Hashes below this (of 16 bits) make a hole when the whole view is one.
const ALL_HOLES: u32 = 1 << 16;

/// The threshold of [`HashedHoleMaskKernel`] for a fraction of holes in `[0, 1]`.
pub fn hole_threshold(fraction: f64) -> Result<u32> {
    if !(0.0..=1.0).contains(&fraction) {
        return Err(PassError::HoleFraction { fraction });
    }
    Ok((fraction * f64::from(ALL_HOLES)).round() as u32)
}

/// Whether [`HashedHoleMaskKernel`] with `threshold` marks pixel (x, y) of `view` as a hole
/// (its CPU twin).
pub fn is_hashed_hole(x: u32, y: u32, view: u32, threshold: u32) -> bool {
    (hash3(x, y, view) & 0xffff) < threshold
}

/// Writes a synthetic hole mask (shaders/hole_mask_hashed.comp) into its `mask` write (an
/// R32u image) over the instance's rows: 1 where [`is_hashed_hole`], else 0. `threshold` 0
/// gives no hole, 65536 (fraction 1) every pixel.
pub struct HashedHoleMaskKernel {
    pub mask: WriteSlot,
    pub threshold: u32,
}

impl PassKernel for HashedHoleMaskKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let mask = pass.write(self.mask)?;
        if rec.resource(mask.alloc).format != Format::R32u {
            return Err(BackendError::KernelMisuse {
                kernel: HOLE_MASK.into(),
                instance: Some(index),
                detail: "writes its mask into an R32u image".into(),
            });
        }
        let params = PassParams { param: self.threshold, ..rec.row_params(pass, mask.alloc)? };
        rec.dispatch_rows(shaders::HOLE_MASK_HASHED, params)
    }
}

/// What [`bench_holes`] measured (GPU timestamps, median over the frames).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HoleBench {
    pub device: String,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub hole_fraction: f64,
    /// Hole filling bounded its camera rays by the G-buffer's `first_hit`.
    pub first_hits: bool,
    /// Hole pixels of the target view (as compacted on the GPU).
    pub holes: u64,
    /// `path_trace` of the whole source view, ms.
    pub path_trace_ms: f64,
    /// `compact_holes` of the target view, ms.
    pub compact_ms: f64,
    /// `hole_fill` of the target view, ms.
    pub hole_fill_ms: f64,
    /// Full-view path tracing per pixel, ns.
    pub trace_ns_per_pixel: f64,
    /// Compaction and hole filling together per hole pixel, ns (NaN without holes).
    pub hole_ns_per_hole: f64,
    /// `hole_ns_per_hole / trace_ns_per_pixel`: the target is ≤ 1.25.
    pub ratio: f64,
}

/// Times hole filling on device 0 of `context`: two views of `scene` through `camera` at
/// `width`×`height` with `settings`, view 0 a source path traced whole (radiance only, as in
/// the pipeline), view 1 a target whose synthetic mask holds `hole_fraction` of its pixels,
/// compacted and filled (radiance only). Both views look through the same camera, so per-pixel
/// costs compare the same rays; `frames` frames (frame index `settings.frame + f`), medians.
/// With `first_hits` both views get the first-hit G-buffer (not timed here) and hole filling
/// reads its `first_hit` layer. The GPU's hole count is checked against the mask's CPU twin.
#[allow(clippy::too_many_arguments)]
pub fn bench_holes(
    context: &Context,
    scene: &Scene,
    camera: Camera,
    (width, height): (u32, u32),
    hole_fraction: f64,
    settings: &TraceSettings,
    frames: usize,
    first_hits: bool,
) -> Result<HoleBench> {
    let threshold = hole_threshold(hole_fraction)?;
    let frames = frames.max(1);
    let (plan, list_family) = bench_plan(width, height, threshold, first_hits)?;
    let bvh = SceneBvh::build(scene);
    let mut executor =
        Executor::new(context, plan, ExecOptions { shaders: crate::shader_library(), ..ExecOptions::default() })?;
    upload_scene(&mut executor, &GpuScene::new(scene, &bvh))?;
    let views: Vec<View> = (0..2).map(|index| View { camera, width, height, index }).collect();
    let mut clock = FrameClock::new();
    for f in 0..frames {
        let frame = TraceSettings { frame: settings.frame.wrapping_add(f as u32), ..*settings };
        let mut data = FrameData::whole(&trace_frame_data(scene, &views, &frame)?);
        data.frame_block(&frame_block(&mut clock, &views))?;
        executor.set_frame(&data)?;
        executor.run_frame()?;
    }
    executor.finish()?;
    let reports = executor.take_reports();

    let expected: u64 = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .filter(|&(x, y)| is_hashed_hole(x, y, 1, threshold))
        .count() as u64;
    let (device, list) = executor
        .plan()
        .final_output(list_family, 1)
        .ok_or(PassError::MissingOutput { family: list_family, view: 1 })?;
    let header = executor.read_resource(device, list)?;
    let holes = u64::from(u32::from_le_bytes([header[12], header[13], header[14], header[15]]));
    if holes != expected {
        return Err(PassError::HoleCount { compacted: holes, expected });
    }
    executor.check_validation()?;

    let path_trace_ms = median_stage_ms(&reports, PATH_TRACE);
    let compact_ms = median_stage_ms(&reports, COMPACT_HOLES);
    let hole_fill_ms = median_stage_ms(&reports, HOLE_FILL);
    let trace_ns_per_pixel = path_trace_ms * 1e6 / (f64::from(width) * f64::from(height));
    let hole_ns_per_hole = (compact_ms + hole_fill_ms) * 1e6 / holes as f64;
    Ok(HoleBench {
        device: context.device_infos()[0].name.clone(),
        width,
        height,
        frames,
        hole_fraction,
        first_hits,
        holes,
        path_trace_ms,
        compact_ms,
        hole_fill_ms,
        trace_ns_per_pixel,
        hole_ns_per_hole,
        ratio: hole_ns_per_hole / trace_ns_per_pixel,
    })
}

/// Source view 0 path traced, target view 1 masked, compacted and filled (after the first-hit
/// G-buffer of both with `first_hits`), on one device. The plan, and the family of its hole
/// list.
fn bench_plan(width: u32, height: u32, threshold: u32, first_hits: bool) -> Result<(KernelPlan, FamilyId)> {
    let topology =
        ViewTopology { width, height, sources_of: vec![Vec::new(), vec![ViewId(0)]], is_source: vec![true, false] };
    let mut graph = KernelGraph::with_payload(topology);
    let first_hit = first_hits.then(|| declare_gbuffer(&mut graph, true).first_hit).flatten();
    let mut radiance = graph.image("radiance", Format::Rgba32f);
    let mut holes = graph.image(HOLES, Format::R32u);
    // The targets' radiance before filling is whatever the image holds (reprojection's place).
    graph.import(&radiance);
    let mut pass = graph.pass(PATH_TRACE, Role::Sources);
    let kernel = PathTraceKernel::new(pass.write_slot(&mut radiance));
    pass.kernel(Arc::new(kernel)).add();
    let mut pass = graph.pass(HOLE_MASK, Role::Targets);
    let mask = pass.write_slot(&mut holes);
    pass.kernel(Arc::new(HashedHoleMaskKernel { mask, threshold })).add();
    let list = declare_hole_fill(&mut graph, &holes, first_hit.as_ref(), &mut radiance);
    graph.export(&radiance);
    let plan = Compiled::compile(&graph, &BandedPlacement { devices: 1, bands: 1 })?.plan;
    Ok((plan, list.family()))
}

/// Median over `reports` of the GPU time of the passes named `stage` in one frame, ms.
fn median_stage_ms(reports: &[FrameReport], stage: &str) -> f64 {
    let mut per_frame: Vec<u64> =
        reports.iter().map(|r| r.stages.iter().filter(|s| s.stage == stage).map(|s| s.total_ns).sum()).collect();
    per_frame.sort_unstable();
    per_frame.get(per_frame.len() / 2).map_or(0.0, |&ns| ns as f64 / 1e6)
}

/// `hash3` of shaders/include/hash.glsl (PCG), what the synthetic hole mask is made of.
fn hash3(a: u32, b: u32, c: u32) -> u32 {
    fn pcg(v: u32) -> u32 {
        let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
        let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
        (word >> 22) ^ word
    }
    pcg(a ^ pcg(b ^ pcg(c)))
}
