//! [`LightFieldRenderer`]: runs a compiled light-field pipeline frame after frame on a scene,
//! with the per-frame data every pass reads (each view's `GpuTraceParams` as the unnamed blob,
//! the frame block of current and previous cameras as section `frame`), and reads layers back.
//!
//! The frame loop keeps the GPU fed: the command buffers are recorded once and resubmitted
//! while the plan is unchanged (only the per-frame data changes), up to the executor's
//! `frames_in_flight` frames are queued so that the host prepares frame n + 1 while the GPU
//! runs frame n, and each retired frame's report is folded into running statistics
//! ([`FrameStats`]) rather than kept, so host memory stays flat however many frames run.

use std::time::Instant;

use parallax_backend::{
    AllocId, Context, DeviceId, ExecOptions, ExecutionPlan, Executor, FRAME_BLOCK_SECTION, FamilyId, FrameClock,
    FrameData, FrameReport, FrameStats, Summary,
};
use parallax_scene::gpu::{GpuScene, TraceLighting};
use parallax_scene::{Scene, TraceSettings, View};

use crate::camera::frame_block;
use crate::error::{PassError, Result};
use crate::path_trace::{TRACE_PARAMS_BYTES, trace_frame_data_lit};
use crate::scene_upload::upload_scene;

/// Bytes of one view's cameras in the frame block (current and previous `GpuCamera`).
const FRAME_BLOCK_VIEW_BYTES: u64 = 2 * std::mem::size_of::<parallax_backend::GpuCamera>() as u64;

/// Runs an execution plan of a light-field pipeline.
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
}

impl LightFieldRenderer {
    /// Creates the executor for `plan` (a pipeline over `views` views) and uploads `scene`.
    pub fn new(context: &Context, plan: ExecutionPlan, views: u32, scene: &GpuScene<'_>) -> Result<Self> {
        Self::with_options(context, plan, views, scene, ExecOptions::default())
    }

    /// [`Self::new`] with other executor options (barrier placement, timing, ...); the per-frame
    /// data capacity is raised to what the views need.
    pub fn with_options(
        context: &Context,
        plan: ExecutionPlan,
        views: u32,
        scene: &GpuScene<'_>,
        options: ExecOptions,
    ) -> Result<Self> {
        // Every view's trace parameters, then the frame block (header + cameras), aligned.
        let needed = u64::from(views) * (TRACE_PARAMS_BYTES + FRAME_BLOCK_VIEW_BYTES) + 2 * 256 + 16;
        let options = ExecOptions { frame_data_bytes: options.frame_data_bytes.max(needed), ..options };
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
        data.section(FRAME_BLOCK_SECTION, &frame_block(&mut self.clock, views).to_bytes())?;
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

    /// The final contents of the declared resource `family` (a handle's `family()`) of `view`
    /// after the last frame (read from device 0 where it was gathered, else from the device
    /// that wrote it), as raw texels.
    pub fn read(&mut self, family: FamilyId, view: u32) -> Result<Vec<u8>> {
        let (device, resource) =
            self.executor.plan().final_output(family, view).ok_or(PassError::MissingOutput { family, view })?;
        Ok(self.executor.read_resource(device, resource)?)
    }

    /// The declared resource `family` of `view` after the last frame, whole, as tightly packed
    /// rows: each row band read on the device whose instance wrote its final version there (a
    /// fine scheme leaves the bands of a layer that is not gathered on different devices).
    pub fn read_stitched(&mut self, family: FamilyId, view: u32) -> Result<Vec<u8>> {
        let missing = || PassError::MissingOutput { family, view };
        let plan = self.executor.plan();
        let writes = || {
            plan.passes.iter().filter(move |p| p.view == view).flat_map(move |p| {
                p.writes.iter().filter(move |w| plan.resource(w.resource).family == family).map(move |w| (p.device, w))
            })
        };
        let version = writes().map(|(_, w)| w.version).max().ok_or_else(missing)?;
        let bands: Vec<(DeviceId, AllocId, u32, u32)> = writes()
            .filter(|(_, w)| w.version == version)
            .map(|(d, w)| (d, w.resource, w.rows.y0, w.rows.y1))
            .collect();
        let desc = plan.resource(bands[0].1).clone();
        let row_bytes = desc.row_bytes() as usize;
        let mut out = vec![0u8; row_bytes * desc.height as usize];
        for (device, resource, y0, y1) in bands {
            let bytes = self.executor.read_resource(device, resource)?;
            let (a, b) = (y0 as usize * row_bytes, y1 as usize * row_bytes);
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

    pub fn executor(&mut self) -> &mut Executor {
        &mut self.executor
    }
}
