//! Path tracing views through the framework: the graphs that declare it, and [`GpuTracer`],
//! which runs a plan of `path_trace` (and `pixel_list`) passes on a scene and reads the views
//! back. `parallax trace` and the GPU tests use it; the light-field pipelines will declare the
//! same pass among their others.

use std::sync::Arc;

use parallax_backend::{
    BackendError, Context, ExecOptions, ExecutionPlan, Executor, KernelGraph, ResourceKind, ShaderLibrary,
};
use parallax_graph::{
    AssignStrategy, BandedPlacement, FamilyId, Format, Handle, Image, LayoutSpec, LightField, Placement, PlanConfig,
    Rig, Role, Scheme, ViewTopology, compile,
};
use parallax_scene::gpu::{GpuPixel, GpuScene};
use parallax_scene::{Scene, TraceSettings, View};

use crate::error::{PassError, Result};
use crate::path_trace::{
    PATH_TRACE, PathTraceKernel, TRACE_OUTPUTS, TRACE_PARAMS_BYTES, pixels_from_images, trace_frame_data,
};
use crate::pixel_list::{PIXEL_LIST, StridedPixelListKernel, StridedPixels, pixel_list_bytes};
use crate::scene_upload::upload_scene;

/// Declares, for every view, one `path_trace` pass writing the four [`TRACE_OUTPUTS`] images
/// (all exported, so finished views end on device 0). With a pixel list (its capacity in
/// entries and the pixels it holds) the pass first gets a `pixel_list` pass writing a
/// per-view plain buffer with one whole-view list (header and entries, see
/// [`crate::pixel_list`]) and traces only the listed pixels (both passes whole-view; per-band
/// lists are hole filling's, [`crate::holes`]).
pub fn declare_trace(graph: &mut KernelGraph, pixel_list: Option<(u64, StridedPixels)>) -> [Handle<Image>; 4] {
    let mut images = TRACE_OUTPUTS.map(|name| graph.image(name, Format::Rgba32f));
    let list = pixel_list.map(|(entries, pixels)| {
        let mut list = graph.buffer(PIXEL_LIST, pixel_list_bytes(entries));
        let mut pass = graph.pass(PIXEL_LIST, Role::All);
        let kernel = StridedPixelListKernel { pixels, list: pass.write_slot(&mut list) };
        pass.whole_view().kernel(Arc::new(kernel)).record();
        list
    });
    let mut pass = graph.pass(PATH_TRACE, Role::All);
    let list_slot = list.as_ref().map(|list| pass.read_whole_slot(list));
    let [radiance, gbuffer @ ..] = images.each_mut().map(|image| pass.write_slot(image));
    let mut kernel = PathTraceKernel::new(radiance).with_gbuffer(gbuffer);
    if let Some(list) = list_slot {
        kernel = kernel.with_list(list);
        pass = pass.whole_view();
    }
    pass.kernel(Arc::new(kernel)).record();
    for image in &images {
        graph.export(image);
    }
    images
}

/// A plan of `path_trace` passes and the declared resources of its [`TRACE_OUTPUTS`] images, in
/// that order (radiance always; a G-buffer layer where the graph declares it): what
/// [`GpuTracer`] reads the traced views from.
#[derive(Clone, Debug)]
pub struct TracePlan {
    pub plan: ExecutionPlan,
    pub outputs: [Option<FamilyId>; 4],
}

/// The executor plan for tracing a `cols`×`rows` grid of `width`×`height` views on `devices`
/// devices under `scheme` (fine-all: every view in row bands over all devices; multi-source:
/// whole views spread over the devices), as [`declare_trace`] declares it. View 0 is the
/// fine schemes' only source: tracing has no δ-edges, so sources only matter for placement.
pub fn trace_plan(
    cols: u32,
    rows: u32,
    (width, height): (u32, u32),
    devices: u32,
    scheme: Scheme,
    pixel_list: Option<(u64, StridedPixels)>,
) -> Result<TracePlan> {
    let lf = LightField::new(LayoutSpec::Grid { cols, rows }, None, Some((width, height)), Rig::default())?;
    // Multi-source picks its own sources (one medoid per set); the fine schemes get view 0.
    let sources = (scheme != Scheme::MultiSource).then(|| vec![0]);
    let config = PlanConfig { devices, scheme, assign: AssignStrategy::Compact, sources };
    let placement = parallax_graph::Plan::new(&lf, &config)?;
    lower_trace(placement.topology.clone(), &placement, pixel_list)
}

/// The plan for tracing `views` views of `width`×`height`, each in `bands` row bands, band `b`
/// on device `b % devices`, every band traced away from device 0 gathered there: the shape of
/// a fine-all schedule without the light-field rule of at least one view per device.
/// `parallax trace` splits its single view over any number of devices this way.
pub fn banded_trace_plan(views: u32, (width, height): (u32, u32), bands: u32, devices: u32) -> Result<TracePlan> {
    let topology = ViewTopology::all_sources(views, width, height);
    lower_trace(topology, &BandedPlacement { devices, bands }, None)
}

fn lower_trace(
    topology: ViewTopology,
    placement: &dyn Placement,
    pixel_list: Option<(u64, StridedPixels)>,
) -> Result<TracePlan> {
    let mut graph = KernelGraph::with_payload(topology);
    let outputs = declare_trace(&mut graph, pixel_list).map(|image| Some(image.family()));
    let schedule = compile(&graph, placement)?;
    let plan = ExecutionPlan::from_schedule(&graph, &schedule).map_err(BackendError::from)?;
    Ok(TracePlan { plan, outputs })
}

/// Runs plans of `path_trace` passes on a scene and reads the traced views back.
pub struct GpuTracer {
    executor: Executor,
    frame_data_bytes: u64,
    outputs: [Option<FamilyId>; 4],
}

impl GpuTracer {
    /// Creates the executor for `plan` on `context` and uploads `scene`.
    pub fn new(context: &Context, plan: TracePlan, scene: &GpuScene<'_>) -> Result<Self> {
        Self::with_shaders(context, plan, scene, ShaderLibrary::new())
    }

    /// [`Self::new`] for plans whose kernels dispatch shaders of `shaders` (a user library).
    pub fn with_shaders(
        context: &Context,
        TracePlan { plan, outputs }: TracePlan,
        scene: &GpuScene<'_>,
        shaders: ShaderLibrary,
    ) -> Result<Self> {
        // Room for every view's parameters, so a large light field is not refused for a buffer
        // size the caller never chose.
        let views = plan.resources.iter().map(|r| u64::from(r.view) + 1).max().unwrap_or(1);
        let defaults = ExecOptions { shaders, ..ExecOptions::default() };
        let options =
            ExecOptions { frame_data_bytes: defaults.frame_data_bytes.max(views * TRACE_PARAMS_BYTES), ..defaults };
        let frame_data_bytes = options.frame_data_bytes;
        let mut executor = Executor::new(context, plan, options)?;
        upload_scene(&mut executor, scene)?;
        Ok(Self { executor, frame_data_bytes, outputs })
    }

    /// Traces one frame of every view of the plan (`views[i]` describes plan view `i`; its
    /// size must match the plan's images) and returns each view's pixels, row-major. Pixels a
    /// pass did not trace (outside a pixel list) keep their previous contents (zero at first).
    pub fn render(&mut self, scene: &Scene, views: &[View], settings: &TraceSettings) -> Result<Vec<Vec<GpuPixel>>> {
        let plan_views = self.executor.plan().passes.iter().map(|p| p.view + 1).max().unwrap_or(0);
        if (views.len() as u64) < u64::from(plan_views) {
            return Err(PassError::MissingViews { plan_views, given: views.len() });
        }
        for view in views {
            self.check_view(view)?;
        }
        let data = trace_frame_data(scene, views, settings)?;
        if data.len() as u64 > self.frame_data_bytes {
            return Err(PassError::TooManyViews {
                views: views.len(),
                bytes: views.len() * TRACE_PARAMS_BYTES as usize,
                capacity: self.frame_data_bytes,
            });
        }
        self.executor.set_frame_data(&data)?;
        self.executor.run_frame()?;
        self.executor.finish()?;
        views.iter().map(|view| self.read_view(view)).collect()
    }

    /// The traced pixels of `view` (from device 0 where the view was gathered, else from the
    /// device that traced it).
    pub fn read_view(&mut self, view: &View) -> Result<Vec<GpuPixel>> {
        self.check_view(view)?;
        let mut layers: [Option<Vec<u8>>; 4] = Default::default();
        for (layer, family) in layers.iter_mut().zip(self.outputs) {
            let Some((device, resource)) = family.and_then(|f| self.executor.plan().final_output(f, view.index)) else {
                continue;
            };
            *layer = Some(self.executor.read_resource(device, resource)?);
        }
        if layers[0].is_none() {
            return Err(PassError::MissingResource { name: TRACE_OUTPUTS[0].into(), view: view.index });
        }
        Ok(pixels_from_images(view.width, view.height, [0, 1, 2, 3].map(|k| layers[k].as_deref())))
    }

    /// Every output image the plan has for `view` must be `view`-sized RGBA32F.
    fn check_view(&self, view: &View) -> Result<()> {
        for (name, family) in TRACE_OUTPUTS.into_iter().zip(self.outputs) {
            let Some((_, resource)) = family.and_then(|f| self.executor.plan().final_output(f, view.index)) else {
                continue;
            };
            let desc = self.executor.plan().resource(resource);
            if (desc.width, desc.height) != (view.width, view.height)
                || desc.kind != ResourceKind::Image
                || desc.format != Format::Rgba32f
            {
                return Err(PassError::ViewSize {
                    view: view.index,
                    name: name.into(),
                    width: view.width,
                    height: view.height,
                    plan_width: desc.width,
                    plan_height: desc.height,
                    format: format!("{:?}", desc.format),
                });
            }
        }
        Ok(())
    }

    /// The executor (timing reports, validation).
    pub fn executor(&mut self) -> &mut Executor {
        &mut self.executor
    }
}
