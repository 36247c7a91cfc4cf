//! parallax-backend: everything Vulkan (ash 0.38).
//!
//! * [`Context`]: instance (+ validation), N physical devices (`--gpus N`) or N logical
//!   devices on one physical device (`--fake-devices N`).
//! * [`ExecutionPlan`]: the data the executor runs: a proven schedule's own pass instances,
//!   copies, device programs and history pairs, with each allocation's GPU description.
//!   [`KernelPlan`] is an `ExecutionPlan` with each pass's kernel ([`Kernels`]): what
//!   [`Executor::new`] takes.
//! * [`Executor`]: records per-device command buffers once, submits frames with timeline
//!   semaphores, moves cross-device copies over one link per device pair of the kind
//!   [`link_kinds`] chooses (device memory shared by logical devices of one GPU, with GPU-side
//!   or host-forwarded waits, or host memory imported into both devices), and
//!   times every pass instance and copy, or every run of one pass's instances ([`Timing`];
//!   [`FrameReport`], [`chrome_trace`]).
//! * [`KernelGraph`]: a render graph whose passes carry their [`PassKernel`];
//!   [`Compiled::compile`] compiles it and builds the kernel plan of its proven schedule in one call
//!   ([`KernelPlan::from_schedule`] builds one of a schedule compiled or changed apart: allocations get their GPU
//!   description, history allocations two halves swapped by frame parity; kernels bind the
//!   instances' accesses by the slot tokens their declarations returned).
//! * [`PassKernel`] / [`Recorder`]: how passes plug their GPU work in: compute dispatches over a
//!   bindless image array, raster draws ([`Draw`], dynamic rendering into plan images, the
//!   depth attachment a `Format::Depth32f` resource that compute kernels sample),
//!   per-view buffers, global buffers ([`Executor::upload_buffer`]) and per-frame data
//!   ([`Executor::set_frame_data`], or [`FrameData`] cut into one section per pass) by buffer
//!   address, sampled RGBA8 textures ([`Executor::upload_textures`]) by index into the
//!   `textures[]` array of set 0; indirect dispatches on counts a pass wrote
//!   ([`Recorder::dispatch_indirect`], buffers reset every frame by `ExecResource::reset`);
//!   consecutive instances of one pass recorded as one op ([`PassKernel::record_group`]) with
//!   data fixed at record time in a [`RecordingBuffer`].
//! * [`Shader`] ids and [`PushConstants`] structs: a crate's build writes them from its shaders'
//!   SPIR-V ([`shader_bindings!`]), so a dispatch names its shader at compile time with the
//!   struct of that shader's block. A shader added at run time is named by a string with a
//!   struct that lists its fields ([`push_constants!`]); each pipeline's block is reflected
//!   from the SPIR-V when it is created, and a struct that differs is refused with
//!   [`BackendError::PushConstantLayout`].
//! * [`FrameClock`] / [`FrameBlock`]: per view the current and previous camera, as
//!   `shaders/include/frame_block.glsl` declares them ([`FrameData::frame_block`],
//!   [`Recorder::frame_block_address`]); the executor writes its frame index and history flag
//!   ([`FrameConstants`]) into the frame constants alone.
//! * The frame loop: [`Executor::submit_frame`] keeps frames in flight and
//!   [`Executor::wait_readback`] returns one frame's exported resources.
//! * Shaders: the kernels of each crate bring their own SPIR-V in a [`ShaderLibrary`]
//!   ([`ExecOptions::shaders`]), compiled from GLSL 460 by the crate's build.rs with
//!   parallax-glsl ([`include_shaders!`]; the pipeline's, in the top-level `shaders/`, are
//!   parallax-passes') or loaded at run time; a user's library is layered over another
//!   ([`ShaderLibrary::layered_over`]). Only the backend's own shaders (`backend/shaders/`, its
//!   benchmark's) are compiled in build.rs and embedded, as every library's fallback ([`spirv`]).
//!
//! ```
//! use std::sync::Arc;
//! use parallax_backend::*;
//! use parallax_graph::{AssignStrategy, Format, LightField, PartitionConfig, Rig, Role, Scheme};
//!
//! // A kernel of its own: the benchmark's producer shader over the instance's rows, into the
//! // write its pass declared.
//! struct Fill {
//!     payload: WriteSlot,
//! }
//! impl PassKernel for Fill {
//!     fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
//!         let dst = pass.write(self.payload)?.alloc;
//!         let params = PassParams { dst: rec.image(dst)?, view: pass.view.0, y0: pass.region.y0,
//!                                   y1: pass.region.y1, width: rec.resource(dst).width, ..Default::default() };
//!         rec.dispatch_rows("bench_fill", params)
//!     }
//! }
//!
//! // Declare: fill every view in row bands over both devices (FineAll), kernel attached,
//! // finished views gathered on device 0.
//! let lf = LightField::new("3x1".parse()?, None, Some((32, 32)), Rig::default())?;
//! let config = PartitionConfig { devices: 2, scheme: Scheme::FineAll, assign: AssignStrategy::Compact, sources: None };
//! let placement = parallax_graph::Partition::new(&lf, &config)?;
//! let mut graph = KernelGraph::with_payload(placement.topology.clone());
//! let mut payload = graph.image("payload", Format::Rgba32f);
//! let mut pass = graph.pass("fill", Role::All);
//! let fill = Fill { payload: pass.write_slot(&mut payload) };
//! pass.kernel(Arc::new(fill)).add();
//! graph.export(&payload);
//! let plan = Compiled::compile(&graph, &placement)?.plan;
//!
//! // Two logical devices on one physical device (lavapipe in CI), validation on.
//! let context = Context::new(&ContextDesc {
//!     selection: DeviceSelection::FakeDevices(2),
//!     validation: Validation::Core,
//! })?;
//! let (device, view0) = plan.final_output(payload.family(), 0).unwrap(); // gathered on device 0
//! let mut executor = Executor::new(&context, plan, ExecOptions::default())?;
//! for _ in 0..3 {
//!     executor.run_frame()?; // no re-recording, up to 2 frames in flight
//! }
//! assert_eq!(executor.read_resource(device, view0)?.len(), 32 * 32 * 16);
//! let reports = executor.take_reports(); // GPU timestamps of every pass and copy
//! let trace = chrome_trace(&reports, &context.device_infos());
//! assert!(trace["traceEvents"].as_array().unwrap().len() > 3);
//! drop(executor);
//! context.check_validation()?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

// The shader bindings the build writes name the backend by its crate name, inside it too.
extern crate self as parallax_backend;

/// The backend's own shaders (`backend/shaders/`): [`PassParams`], the push block every
/// row-band kernel shares, and their ids.
mod bindings {
    crate::shader_bindings!();
}
mod context;
mod device;
mod device_state;
mod device_support;
mod error;
mod exec_options;
mod executor;
mod frame_block;
mod frame_data;
mod frame_stats;
mod instance;
mod kernel;
mod lifetime_lock;
mod link_memory;
mod links;
pub use links::{DeviceSubmissions, LinkInfo, LinkKind, LinkKinds, link_kinds};
mod kernel_graph;
mod memory;
mod push;
mod readback;
mod record;
mod recorder;
mod relay;
mod remote;
pub use remote::{RemoteTransport, Wire, remote_device, remote_device_id};
mod segments;
mod shader_id;
mod shader_pipelines;
mod shaders;
mod staging_ring;
mod texture;
mod timing;

pub mod bench;
pub mod plan;
pub use bytemuck;
pub use parallax_glsl::{reflect, rust_layout};

pub use bindings::PassParams;
pub use context::{Context, ContextDesc, DeviceSelection};
pub use device::{CalibrationMethod, ClockCalibration, Device, DeviceInfo, QueueKind, host_now_ns};
pub use error::{
    BackendError, CompileError, ExecutionPlanError, KernelPlanError, Result, SearchedShaders, SpirvDefect,
};
pub use exec_options::{Barriers, ExecOptions, FaultInjection, Timing};
pub use executor::Executor;
pub use frame_block::{FrameBlock, FrameClock, FrameConstants, FrameHeader, GpuCamera, ViewCameras};
pub use frame_data::{FRAME_SECTION_ALIGN, FrameData};
pub use frame_stats::{EventTotals, FrameStats, SUMMARY_SAMPLE, Summary};
pub use instance::{Instance, Validation, validation_from_env};
pub use kernel::{KernelPlan, Kernels, PassKernel};
pub use kernel_graph::{Compiled, KernelGraph};
pub use memory::{Buffer, Image, SharedHostBuffer};
pub use plan::{
    Access, AllocId, CopyId, CopyKind, CrossCopy, DeviceId, DeviceProgram, ExecResource, ExecutionPlan, FamilyId,
    Format, HistoryPair, HistorySlot, InstanceId, MAX_RESET_WORDS, Op, Origin, PassId, PassInstance, ReadSlot, Region,
    ResourceId, ResourceKind, SourcesSlot, ViewId, WriteSlot, own_access,
};
pub use push::{LayoutMismatch, PushConstants, check_push_constants};
pub use readback::{FrameReadback, FrameTicket};
pub use recorder::{Draw, Recorder, RecordingBuffer};
pub use segments::{Chunk, chunks_of_copies};
pub use shader_id::{DrawStage, NoPushBlock, Shader, ShaderName};
pub use shaders::{BACKEND_SHADERS, ShaderLibrary, USER_SHADERS, shader_names, spirv};
pub use texture::{MAX_TEXTURES, TextureData};
pub use timing::{DeviceFrameStats, EventKind, FrameReport, StageStats, TimedEvent, chrome_trace, write_json};
