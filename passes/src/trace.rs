//! Path tracing views through the framework: the graphs that declare it, and the runner's
//! methods for a plan of `path_trace` (and `pixel_list`) passes ([`LightFieldRenderer::trace`]),
//! which trace the views and decode their pixels. `parallax trace`, `parallax reference` and
//! the GPU tests use them; the light-field pipelines declare the same pass among their others.

use std::sync::Arc;

use parallax_backend::{Compiled, Context, ExecOptions, KernelGraph, KernelPlan, ResourceKind};
use parallax_graph::{
    AssignStrategy, BandedPlacement, Format, Handle, Image, LayoutSpec, LightField, PartitionConfig, Placement, Rig,
    Role, Scheme, ViewTopology,
};
use parallax_scene::gpu::{GpuPixel, GpuScene};
use parallax_scene::{Scene, TraceSettings, View};

use crate::error::{PassError, Result};
use crate::path_trace::{PATH_TRACE, PathTraceKernel, TRACE_OUTPUTS, TraceOutputs, pixels_from_images};
use crate::pixel_list::{PIXEL_LIST, StridedPixelListKernel, StridedPixels, pixel_list_bytes};
use crate::renderer::LightFieldRenderer;

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
        pass.whole_view().kernel(Arc::new(kernel)).add();
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
    pass.kernel(Arc::new(kernel)).add();
    for image in &images {
        graph.export(image);
    }
    images
}

/// Path tracing compiled: the kernel plan of its `path_trace` (and `pixel_list`) passes and its
/// [`TraceOutputs`], what [`LightFieldRenderer::tracing`] runs.
#[derive(Clone, Debug)]
pub struct CompiledTrace {
    pub plan: KernelPlan,
    pub outputs: TraceOutputs,
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
) -> Result<CompiledTrace> {
    let lf = LightField::new(LayoutSpec::Grid { cols, rows }, None, Some((width, height)), Rig::default())?;
    // Multi-source picks its own sources (one medoid per set); the fine schemes get view 0.
    let sources = (scheme != Scheme::MultiSource).then(|| vec![0]);
    let config = PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources };
    let placement = parallax_graph::Partition::new(&lf, &config)?;
    compile_trace(placement.topology.clone(), &placement, pixel_list)
}

/// The plan for tracing `views` views of `width`×`height`, each in `bands` row bands, band `b`
/// on device `b % devices`, every band traced away from device 0 gathered there: the shape of
/// a fine-all schedule without the light-field rule of at least one view per device.
/// `parallax trace` splits its single view over any number of devices this way.
pub fn banded_trace_plan(views: u32, (width, height): (u32, u32), bands: u32, devices: u32) -> Result<CompiledTrace> {
    let topology = ViewTopology::all_sources(views, width, height);
    compile_trace(topology, &BandedPlacement { devices, bands }, None)
}

fn compile_trace(
    topology: ViewTopology,
    placement: &dyn Placement,
    pixel_list: Option<(u64, StridedPixels)>,
) -> Result<CompiledTrace> {
    let mut graph = KernelGraph::with_payload(topology);
    let outputs = declare_trace(&mut graph, pixel_list).map(|image| Some(image.family()));
    let plan = Compiled::compile(&graph, placement)?.plan;
    Ok(CompiledTrace { plan, outputs })
}

impl LightFieldRenderer {
    /// The runner of a plan of path tracing alone ([`trace_plan`], [`banded_trace_plan`], or a
    /// plan of one's own with its [`TraceOutputs`]): [`Self::with_options`], knowing which
    /// images [`Self::trace`] decodes into pixels.
    pub fn tracing(
        context: &Context,
        CompiledTrace { plan, outputs }: CompiledTrace,
        scene: &GpuScene<'_>,
        options: ExecOptions,
    ) -> Result<Self> {
        let mut renderer = Self::with_options(context, plan, scene, options)?;
        renderer.trace_outputs = Some(outputs);
        Ok(renderer)
    }

    /// Traces one frame of every view (`views[i]` describes plan view `i`; its size must match
    /// the plan's images), waits for it, and returns each view's pixels, row-major. Pixels a
    /// pass did not trace (outside a pixel list) keep their previous contents (zero at first).
    pub fn trace(&mut self, scene: &Scene, views: &[View], settings: &TraceSettings) -> Result<Vec<Vec<GpuPixel>>> {
        for view in views {
            self.check_trace_view(view)?;
        }
        self.submit(scene, views, settings)?;
        self.finish()?;
        views.iter().map(|view| self.read_pixels(view)).collect()
    }

    /// The traced pixels of `view` after the last frame: its [`TRACE_OUTPUTS`] decoded, the
    /// first-hit layers the plan lacks left empty.
    pub fn read_pixels(&mut self, view: &View) -> Result<Vec<GpuPixel>> {
        let outputs = self.check_trace_view(view)?;
        let mut layers: [Option<Vec<u8>>; 4] = Default::default();
        for (layer, family) in layers.iter_mut().zip(outputs) {
            if let Some(family) = family.filter(|&f| self.plan().final_bands(f, view.index).is_some()) {
                *layer = Some(self.read(family, view.index)?);
            }
        }
        if layers[0].is_none() {
            return Err(PassError::MissingRadiance { view: view.index });
        }
        Ok(pixels_from_images(view.width, view.height, [0, 1, 2, 3].map(|k| layers[k].as_deref())))
    }

    /// The trace outputs, once every one the plan has for `view` is `view`-sized RGBA32F.
    fn check_trace_view(&self, view: &View) -> Result<TraceOutputs> {
        let outputs = self.trace_outputs.ok_or(PassError::NoTraceOutputs)?;
        let plan = self.plan();
        for (&name, &family) in TRACE_OUTPUTS.iter().zip(&outputs) {
            let Some(bands) = family.and_then(|f| plan.final_bands(f, view.index)) else {
                continue;
            };
            let desc = plan.resource(bands[0].1);
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
        Ok(outputs)
    }
}
