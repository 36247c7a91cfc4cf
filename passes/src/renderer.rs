//! [`LightFieldRenderer`], the one runner of execution plans over views: it runs a compiled
//! plan (a light-field pipeline, or path tracing alone: [`crate::trace`]) frame after frame on a
//! scene, with the per-frame data every pass reads (each view's `GpuTraceParams` as the unnamed
//! blob, the frame block of current and previous cameras after it), and reads a
//! layer's final version back ([`LightFieldRenderer::read`]), whichever devices wrote its bands.
//!
//! The frame loop keeps the GPU fed: the command buffers are recorded once and resubmitted
//! while the plan is unchanged (only the per-frame data changes), up to the executor's
//! `frames_in_flight` frames are queued so that the host prepares frame n + 1 while the GPU
//! runs frame n, and each retired frame's report is folded into running statistics
//! ([`FrameStats`]) rather than kept, so host memory stays flat however many frames run.

use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::sync::Arc;
use std::time::Instant;

use parallax_backend::{
    AllocId, Context, DeviceId, ExecOptions, ExecutionPlan, Executor, FamilyId, FrameClock, FrameData, FrameReport,
    FrameStats, KernelPlan, Summary,
};
use parallax_scene::gpu::{GpuScene, TraceLighting};
use parallax_scene::{Scene, TraceSettings, View};

use crate::camera::frame_block;
use crate::error::{PassError, Result};
use crate::path_trace::{TRACE_PARAMS_BYTES, TraceOutputs, trace_frame_data_lit};
use crate::scene_upload::upload_scene;

/// Bytes of one view's cameras in the frame block (current and previous `GpuCamera`).
const FRAME_BLOCK_VIEW_BYTES: u64 = 2 * std::mem::size_of::<parallax_backend::GpuCamera>() as u64;

/// Runs an execution plan over views: a light-field pipeline, or path tracing alone.
pub struct LightFieldRenderer {
    executor: Executor,
    clock: FrameClock,
    views: u32,
    frames: u64,
    /// Length of the uploaded emissive-triangle table: the per-frame lighting needs it, and
    /// counting it again would walk every triangle of the scene each frame.
    emissive_triangles: usize,
    stats: FrameStats,
    /// Host time of building and setting each frame's data.
    prepare_ms: Summary,
    /// Whole reports of retired frames, while [`Self::keep_reports`] is on.
    kept: Option<Vec<FrameReport>>,
    /// The traced images of a plan of path tracing alone ([`Self::tracing`]): what
    /// [`Self::trace`] decodes into pixels.
    pub(crate) trace_outputs: Option<TraceOutputs>,
}

impl LightFieldRenderer {
    /// Creates the executor for `plan` and uploads `scene`. The plan's views are those its
    /// passes and resources name (views `0..n`): every frame gives that many.
    pub fn new(context: &Context, plan: impl Into<Arc<KernelPlan>>, scene: &GpuScene<'_>) -> Result<Self> {
        Self::with_options(context, plan, scene, ExecOptions::default())
    }

    /// [`Self::new`] with other executor options (user shaders, barrier placement, timing, ...):
    /// the per-frame data capacity is raised to what the views need, and the options' shaders
    /// are layered over the passes' ([`crate::shader_library`]).
    pub fn with_options(
        context: &Context,
        plan: impl Into<Arc<KernelPlan>>,
        scene: &GpuScene<'_>,
        options: ExecOptions,
    ) -> Result<Self> {
        let plan = plan.into();
        let views = plan_views(&plan);
        // Every view's trace parameters, then the frame block (header + cameras), aligned.
        let needed = u64::from(views) * (TRACE_PARAMS_BYTES + FRAME_BLOCK_VIEW_BYTES) + 2 * 256 + 16;
        let options = ExecOptions {
            frame_data_bytes: options.frame_data_bytes.max(needed),
            shaders: options.shaders.layered_over(crate::shader_library()),
            ..options
        };
        let mut executor = Executor::new(context, plan, options)?;
        upload_scene(&mut executor, scene)?;
        Ok(Self {
            executor,
            clock: FrameClock::new(),
            views,
            frames: 0,
            emissive_triangles: scene.emissive.len(),
            stats: FrameStats::new(),
            prepare_ms: Summary::default(),
            kept: None,
            trace_outputs: None,
        })
    }

    /// Submits one frame of every view (`views[i]` is view `i`; `settings.frame` keys the random
    /// numbers) of `scene`, the scene given at construction (its sky and sun may change between
    /// frames). Up to the executor's frames in flight are queued: this waits only when that many
    /// are, for the oldest, whose slot the new frame reuses.
    pub fn submit(&mut self, scene: &Scene, views: &[View], settings: &TraceSettings) -> Result<u64> {
        if views.len() != self.views as usize {
            return Err(PassError::MissingViews { plan_views: self.views, given: views.len() });
        }
        let started = Instant::now();
        let lighting = TraceLighting::with_emissive_triangles(scene, self.emissive_triangles);
        let mut data = FrameData::whole(&trace_frame_data_lit(&lighting, views, settings)?);
        data.frame_block(&frame_block(&mut self.clock, views))?;
        self.executor.set_frame(&data)?;
        self.prepare_ms.add(started.elapsed().as_secs_f64() * 1e3);
        self.frames += 1;
        let frame = self.executor.run_frame()?;
        self.fold_retired();
        Ok(frame)
    }

    /// Folds the reports of frames retired since the last call into the statistics.
    fn fold_retired(&mut self) {
        let reports = self.executor.take_reports();
        for report in &reports {
            self.stats.fold(report);
        }
        if let Some(kept) = &mut self.kept {
            kept.extend(reports);
        }
    }

    /// Replaces the scene's geometry by `scene`'s, a new pose of the scene given at
    /// construction (same triangles, materials, lights and textures; moved vertices and a BVH
    /// built over them). Waits for the frames in flight before overwriting their buffers.
    pub fn upload_geometry(&mut self, scene: &GpuScene<'_>) -> Result<()> {
        crate::scene_upload::upload_geometry(&mut self.executor, scene)?;
        // A triangle posed to zero area leaves the emissive table.
        self.emissive_triangles = scene.emissive.len();
        Ok(())
    }

    /// A camera cut: the next frame's history reads (SVGF) start over, and its motion is unknown.
    pub fn cut(&mut self) {
        self.executor.reset_history();
    }

    /// Waits for every submitted frame.
    pub fn finish(&mut self) -> Result<()> {
        self.executor.finish()?;
        self.fold_retired();
        Ok(())
    }

    /// Running statistics of the frames retired since construction or [`Self::reset_stats`]
    /// (call [`Self::finish`] first to include every submitted frame).
    pub fn stats(&mut self) -> &FrameStats {
        self.fold_retired();
        &self.stats
    }

    /// Host time (ms) of building and setting each frame's data, frames since construction or
    /// [`Self::reset_stats`].
    pub fn prepare_ms(&self) -> &Summary {
        &self.prepare_ms
    }

    /// Starts the statistics (and the kept reports) over, e.g. after warm-up frames; frames
    /// that retired before are left out.
    pub fn reset_stats(&mut self) {
        self.executor.take_reports();
        self.stats = FrameStats::new();
        self.prepare_ms = Summary::default();
        if let Some(kept) = &mut self.kept {
            kept.clear();
        }
    }

    /// Whether whole reports of retired frames are kept for [`Self::take_reports`] besides being
    /// folded into [`Self::stats`] (off by default: they hold every timed event of every frame,
    /// which is what a trace of the frames needs, and memory grows with the frames).
    pub fn keep_reports(&mut self, keep: bool) {
        self.fold_retired();
        self.kept = keep.then(Vec::new);
    }

    /// The final version of the declared resource `family` (a handle's `family()`) of `view`
    /// after the last frame, whole, as tightly packed rows (images) or bytes (buffers). Each row
    /// band comes from device 0 where it was written or gathered there, else from the device
    /// whose instance wrote it (a fine scheme leaves the bands of a layer that is not gathered
    /// on different devices): [`ExecutionPlan::final_bands`]. A layer whole in one allocation
    /// is read once, without stitching.
    pub fn read(&mut self, family: FamilyId, view: u32) -> Result<Vec<u8>> {
        let plan = self.executor.plan();
        if let Some((device, resource)) = plan.final_output(family, view) {
            return Ok(self.executor.read_resource(device, resource)?);
        }
        let bands = plan.final_bands(family, view).ok_or(PassError::MissingOutput { family, view })?;
        let desc = plan.resource(bands[0].1);
        let row_bytes = desc.row_bytes() as usize;
        let mut out = vec![0u8; row_bytes * desc.height as usize];
        // Bands of one allocation may interleave with others' (band b on device b % n): each
        // allocation is read once.
        let mut read: HashMap<(DeviceId, AllocId), Vec<u8>> = HashMap::new();
        for (device, resource, rows) in bands {
            let bytes = match read.entry((device, resource)) {
                Entry::Occupied(bytes) => bytes.into_mut(),
                Entry::Vacant(slot) => slot.insert(self.executor.read_resource(device, resource)?),
            };
            let (a, b) = (rows.y0 as usize * row_bytes, rows.y1 as usize * row_bytes);
            out[a..b].copy_from_slice(&bytes[a..b]);
        }
        Ok(out)
    }

    /// Whole reports of the frames that retired since the last call while
    /// [`Self::keep_reports`] was on (none otherwise).
    pub fn take_reports(&mut self) -> Vec<FrameReport> {
        self.fold_retired();
        self.kept.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// The plan it runs.
    pub fn plan(&self) -> &ExecutionPlan {
        self.executor.plan()
    }

    /// A handle on the plan it runs, for reading it while the renderer is driven.
    pub fn shared_plan(&self) -> Arc<KernelPlan> {
        self.executor.shared_plan()
    }

    /// The executor (timing reports, validation, resources the renderer does not read).
    pub fn executor(&mut self) -> &mut Executor {
        &mut self.executor
    }
}

/// Views of `plan`: one more than the highest view its passes and resources name.
fn plan_views(plan: &ExecutionPlan) -> u32 {
    let passes = plan.passes.iter().map(|p| p.view.0 + 1);
    passes.chain(plan.resources.iter().map(|r| r.view + 1)).max().unwrap_or(0)
}
