//! parallax-passes: the concrete passes of Parallax and the graphs that use them.
//!
//! * [`upload_scene`]: a `parallax_scene::gpu::GpuScene` as global buffers and textures of the
//!   executor.
//! * [`shader_library`]: the SPIR-V of the passes' shaders (the top-level `shaders/`, compiled by
//!   this crate's build.rs with parallax-glsl), which every executor of passes' kernels is given
//!   ([`LightFieldRenderer`] layers it beneath its options' library).
//! * [`PathTraceKernel`] (`path_trace`): shaders/pt_trace.comp, the GPU twin of the CPU
//!   reference path tracer, over a whole view, a row band or a compacted pixel list, writing
//!   radiance and first-hit data into the view's images.
//! * [`RaycastKernel`] / [`Raycaster`] (`raycast`): rays through the CWBVH, for the GPU-vs-CPU
//!   traversal check and the rays/s benchmark ([`bench`](mod@bench)).
//! * [`GbufferRasterKernel`] (`gbuffer_raster`): shaders/gbuffer_raster.{vert,frag}, the
//!   G-buffer rasterised from the uploaded scene (vertices pulled by address) into the path
//!   tracer's first-hit layers and a `Depth32f` depth resource ([`declare_gbuffer_raster`],
//!   camera from the frame block: [`raster_camera`]).
//! * [`visibility`]: the G-buffer without tracing, a compute visibility buffer (64-bit
//!   atomics of distance and triangle) and a resolve into the traced G-buffer's images.
//! * [`pixel_list`]: the list format of `path_trace`'s list mode (a header that is the indirect
//!   arguments, then the pixels) and a test list producer.
//! * [`holes`]: hole filling per row band, `compact_holes` (hole mask → per-band pixel lists)
//!   and `hole_fill` (the lists of all target bands of a device path traced by one indirect
//!   dispatch); [`hole_bench`] times it.
//! * [`trace`]: the graph declaring path tracing per view; [`LightFieldRenderer`] (the one
//!   runner of plans, [`renderer`]) traces it ([`LightFieldRenderer::tracing`], `trace`).
//! * [`reproject`] and [`view_bound`]: the gather of targets from their sources, and the bound
//!   on view-dependence that decides which pixels it may reuse.
//!
//! ```no_run
//! use parallax_backend::{Context, ContextDesc, DeviceSelection, ExecOptions};
//! use parallax_passes::{LightFieldRenderer, trace_plan};
//! use parallax_scene::{default_scene, gpu::GpuScene, SceneBvh, TraceSettings, View};
//!
//! let scene = default_scene();
//! let bvh = SceneBvh::build(&scene);
//! let context = Context::new(&ContextDesc::from_env(DeviceSelection::FakeDevices(2)))?;
//! // One 64x48 view in row bands over two devices, gathered on device 0.
//! let plan = trace_plan(1, 1, (64, 48), 2, parallax_graph::Scheme::FineAll, None)?;
//! let scene_on_gpu = GpuScene::new(&scene, &bvh);
//! let mut renderer = LightFieldRenderer::tracing(&context, plan, &scene_on_gpu, ExecOptions::default())?;
//! let view = View { camera: scene.default_camera(), width: 64, height: 48, index: 0 };
//! let pixels = renderer.trace(&scene, &[view], &TraceSettings::default())?;
//! assert_eq!(pixels[0].len(), 64 * 48);
//! # Ok::<(), parallax_passes::PassError>(())
//! ```

pub mod bench;
pub mod camera;
pub mod error;
pub mod firefly;
pub mod gbuffer;
pub mod hole_bench;
pub mod hole_denoise;
pub mod hole_subsample;
pub mod holes;
pub mod path_trace;
pub mod pipeline;
pub mod pixel_list;
pub mod raster_gbuffer;
pub mod raycast;
pub mod renderer;
pub mod reproject;
pub mod scene_upload;
pub mod shaders;
pub mod svgf;
pub mod tonemap;
pub mod trace;
pub mod view_bound;
pub mod visibility;

pub use error::{PassError, Result};
pub use hole_bench::{HOLE_MASK, HashedHoleMaskKernel, HoleBench, bench_holes, hole_threshold, is_hashed_hole};
pub use holes::{
    COMPACT_HOLES, CompactHolesKernel, HOLE_FILL, HOLE_LIST, HOLES, HoleFillKernel, declare_hole_fill,
    hole_list_row_bytes,
};
pub use path_trace::{
    PATH_TRACE, PathTraceKernel, TRACE_OUTPUTS, TraceOutputs, pixels_from_images, to_pixel_sample, trace_frame_data,
    trace_frame_data_lit,
};
pub use pixel_list::{
    LIST_HEADER_WORDS, PIXEL_LIST, StridedPixelListKernel, StridedPixels, list_groups, pixel_list_bytes, strided_pixels,
};
pub use raster_gbuffer::{
    GBUFFER_RASTER, GbufferHandles, GbufferRasterKernel, RASTER_DEPTH, RASTER_OUTPUTS, declare_gbuffer_raster,
    raster_camera,
};
pub use raycast::{
    HitOut, RAYCAST, RAYCAST_WORK, RayIn, RaySchedule, RaycastKernel, Raycaster, TraversalComparison, compare_with_cpu,
    random_rays,
};
pub use renderer::LightFieldRenderer;
pub use scene_upload::{SCENE_BUFFERS, upload_scene};
pub use shaders::shader_library;
pub use svgf::{DENOISED, SvgfInputs, declare_svgf};
pub use tonemap::{DISPLAY, TONEMAP, TonemapError, declare_tonemap, declare_tonemap_scaled, tonemap_pixel};
pub use trace::{CompiledTrace, banded_trace_plan, declare_trace, trace_plan};
