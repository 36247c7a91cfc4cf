//! Path tracing views on the GPU alone, below `parallax trace` and `parallax reference`: a
//! Vulkan context over the selected devices, every view in one row band per device gathered on
//! device 0 ([`banded_trace_plan`]), and the runner of that plan ([`LightFieldRenderer::tracing`]).
//! The command line parses its flags into [`GpuTraceSettings`], calls these and prints.

use anyhow::Result;
use parallax_backend::{Context, ContextDesc, DeviceSelection, EventKind, ExecOptions};
use parallax_passes::{LightFieldRenderer, PATH_TRACE, banded_trace_plan, to_pixel_sample};
use parallax_scene::gpu::{GpuPixel, GpuScene};
use parallax_scene::{Frame, Scene, SceneBvh, TraceSettings, View};

use crate::outputs::budget::TraceWork;

/// What a [`GpuTracer`] traces and where: plain values.
#[derive(Clone, Copy, Debug)]
pub struct GpuTraceSettings {
    /// The devices; each view is split into one row band per device.
    pub devices: DeviceSelection,
    /// Views per frame (`views[i]` of [`GpuTracer::trace`] is plan view `i`).
    pub views: u32,
    /// Every view's width and height.
    pub size: (u32, u32),
    /// Keep every frame's timed events, for the GPU time [`GpuTracer::trace_frame`] returns
    /// (memory grows with the frames traced).
    pub timed: bool,
}

/// A GPU path tracer: the context and the runner of the banded compiled trace on it.
pub struct GpuTracer {
    // Dropped before the context it runs on.
    renderer: Box<LightFieldRenderer>,
    context: Context,
    devices: u32,
}

impl GpuTracer {
    /// Creates the context over `settings.devices` (one log line per device), checks `work`
    /// against every device's limits, and compiles and loads the compiled trace with `scene`.
    pub fn start(settings: GpuTraceSettings, work: TraceWork, scene: &Scene, bvh: &SceneBvh) -> Result<Self> {
        let context = Context::new(&ContextDesc::from_env(settings.devices))?;
        // One message per device: a message is one line (the CLI's logging).
        context.to_string().lines().for_each(|line| tracing::info!("{line}"));
        work.check_devices(&context)?;
        let devices = settings.devices.count() as u32;
        let trace = banded_trace_plan(settings.views, settings.size, devices, devices)?;
        let mut renderer =
            LightFieldRenderer::tracing(&context, trace, &GpuScene::new(scene, bvh), ExecOptions::default())?;
        if settings.timed {
            renderer.keep_reports(true);
        }
        Ok(GpuTracer { renderer: Box::new(renderer), context, devices })
    }

    /// How many devices it traces on.
    pub fn devices(&self) -> u32 {
        self.devices
    }

    /// One frame of every view ([`LightFieldRenderer::trace`]): each view's pixels, row-major.
    pub fn trace(&mut self, scene: &Scene, views: &[View], settings: &TraceSettings) -> Result<Vec<Vec<GpuPixel>>> {
        Ok(self.renderer.trace(scene, views, settings)?)
    }

    /// One frame of the single view `view` as a [`Frame`] (the GPU drops non-finite samples as
    /// the CPU does), and its GPU time in ms: from the first `path_trace` band's start to the
    /// last one's end, any device (NaN without [`GpuTraceSettings::timed`]).
    pub fn trace_frame(&mut self, scene: &Scene, view: &View, settings: &TraceSettings) -> Result<(Frame, f64)> {
        let pixels = self.trace(scene, std::slice::from_ref(view), settings)?.remove(0);
        let events: Vec<_> = self
            .renderer
            .take_reports()
            .into_iter()
            .flat_map(|r| r.events)
            .filter(|e| e.kind == EventKind::Pass && e.name == PATH_TRACE)
            .collect();
        let gpu_ms = match (events.iter().map(|e| e.start_ns).min(), events.iter().map(|e| e.end_ns).max()) {
            (Some(start), Some(end)) => end.saturating_sub(start) as f64 / 1e6,
            _ => f64::NAN,
        };
        let frame =
            Frame { width: view.width, height: view.height, pixels: pixels.iter().map(to_pixel_sample).collect() };
        Ok((frame, gpu_ms))
    }

    /// Ends the run: the runner released, then any validation message the run caused is an error.
    pub fn finish(self) -> Result<()> {
        let GpuTracer { renderer, context, .. } = self;
        drop(renderer);
        context.check_validation()?;
        Ok(())
    }
}
