//! parallax-passes: the concrete passes of Parallax and the graphs that use them.
//!
//! * [`upload_scene`]: a `parallax_scene::gpu::GpuScene` as global buffers and textures of the
//!   executor.
//! * [`PathTraceKernel`] (`path_trace`): shaders/pt_trace.comp, the GPU twin of the CPU
//!   reference path tracer, over a whole view, a row band or a compacted pixel list, writing
//!   radiance and first-hit data into the view's images.
//! * [`RaycastKernel`] / [`Raycaster`] (`raycast`): rays through the CWBVH, for the GPU-vs-CPU
//!   traversal check and the rays/s benchmark ([`bench`](mod@bench)).
//! * [`GbufferRasterKernel`] (`gbuffer_raster`): shaders/gbuffer_raster.{vert,frag}, the
//!   G-buffer rasterised from the uploaded scene (vertices pulled by address) into the path
//!   tracer's first-hit layers and a `Depth32f` depth resource ([`declare_gbuffer_raster`],
//!   camera from the frame block: [`raster_camera`]).
//! * [`pixel_list`]: the list format of `path_trace`'s list mode and a demo list producer.
//! * [`trace`]: the graph declaring path tracing per view, and [`GpuTracer`], which runs it.
//!
//! ```no_run
//! use parallax_backend::{Context, ContextDesc, DeviceSelection};
//! use parallax_passes::{GpuTracer, trace_plan};
//! use parallax_scene::{default_scene, gpu::GpuScene, SceneBvh, TraceSettings, View};
//!
//! let scene = default_scene();
//! let bvh = SceneBvh::build(&scene);
//! let context = Context::new(&ContextDesc::from_env(DeviceSelection::FakeDevices(2)))?;
//! // One 64x48 view in row bands over two devices, gathered on device 0.
//! let plan = trace_plan(1, 1, (64, 48), 2, parallax_graph::Scheme::FineAll, None)?;
//! let mut tracer = GpuTracer::new(&context, plan, &GpuScene::new(&scene, &bvh))?;
//! let view = View { camera: scene.default_camera(), width: 64, height: 48, index: 0 };
//! let pixels = tracer.render(&scene, &[view], &TraceSettings::default())?;
//! assert_eq!(pixels[0].len(), 64 * 48);
//! # Ok::<(), parallax_passes::PassError>(())
//! ```

pub mod bench;
pub mod error;
pub mod path_trace;
pub mod pixel_list;
pub mod raster_gbuffer;
pub mod raycast;
pub mod scene_upload;
pub mod trace;

pub use error::{PassError, Result};
pub use path_trace::{
    PATH_TRACE, PathTraceKernel, TRACE_OUTPUTS, pixels_from_images, to_pixel_sample, trace_frame_data,
};
pub use pixel_list::{PIXEL_LIST, StridedPixelListKernel, pixel_list_bytes, strided_pixels};
pub use raster_gbuffer::{
    GBUFFER_RASTER, GbufferHandles, GbufferRasterKernel, GbufferRasterPush, RASTER_DEPTH, RASTER_OUTPUTS,
    declare_gbuffer_raster, raster_camera,
};
pub use raycast::{
    HitOut, RAYCAST, RAYCAST_WORK, RayIn, RaySchedule, RaycastKernel, Raycaster, TraversalComparison, compare_with_cpu,
    random_rays,
};
pub use scene_upload::{SCENE_BUFFERS, upload_scene};
pub use trace::{GpuTracer, banded_trace_plan, declare_trace, trace_plan};
