//! parallax-backend: everything Vulkan (ash 0.38).
//!
//! * [`Context`]: instance (+ validation), N physical devices (`--gpus N`) or N logical
//!   devices on one physical device (`--fake-devices N`).
//! * [`Plan`]: what the executor runs, lowered from the graph crate's `Schedule`.
//! * [`Executor`]: records per-device command buffers once, submits frames with timeline
//!   semaphores, moves cross-device copies through host memory imported into both devices, and
//!   times every pass instance and copy ([`FrameReport`], [`chrome_trace`]).
//! * [`PassKernel`] / [`KernelRegistry`] / [`Recorder`]: how passes plug their GPU work in:
//!   compute dispatches over a bindless image array, raster draws ([`Draw`], dynamic rendering
//!   into plan images), per-view buffers, global buffers ([`Executor::upload_buffer`]) and
//!   per-frame data ([`Executor::set_frame_data`]) by buffer address, sampled RGBA8 textures
//!   ([`Executor::upload_textures`]) by index into the `textures[]` array of set 0.
//! * Shaders: GLSL 460 in `shaders/`, compiled by `glslc` in build.rs and embedded ([`spirv`]);
//!   kernels of other crates bring their own SPIR-V in a [`ShaderLibrary`]
//!   ([`ExecOptions::shaders`]), compiled by their build.rs with parallax-glsl
//!   ([`include_shaders!`]) or loaded at run time.
//!
//! ```
//! use parallax_backend::*;
//! use parallax_backend::demo::reprojection_demo;
//! use parallax_backend::kernels::builtin_kernels;
//!
//! // Two logical devices on one physical device (lavapipe in CI), validation on.
//! let context = Context::new(&ContextDesc {
//!     selection: DeviceSelection::FakeDevices(2),
//!     validation: Validation::Core,
//! })?;
//! let (plan, ids) = reprojection_demo(3, 2, 32, 32); // or Plan::from_schedule(&schedule)?
//! let mut executor = Executor::new(&context, plan, ExecOptions::default())?;
//! for _ in 0..3 {
//!     executor.run_frame()?; // no re-recording, up to 2 frames in flight
//! }
//! let view0 = executor.read_image(0, ids.output[0])?; // gathered on device 0
//! assert_eq!(view0.len(), 32 * 32 * 16);
//! let reports = executor.take_reports(); // GPU timestamps of every pass and copy
//! let trace = chrome_trace(&reports, &context.device_infos());
//! assert!(trace["traceEvents"].as_array().unwrap().len() > 3);
//! drop(executor);
//! context.check_validation()?;
//! # Ok::<(), BackendError>(())
//! ```

mod context;
mod device;
mod device_state;
mod error;
mod executor;
mod instance;
mod lower;
mod memory;
mod pipeline;
mod record;
mod recorder;
mod relay;
mod segments;
mod shaders;
mod texture;
mod timing;

pub mod bench;
pub mod demo;
pub mod kernels;
pub mod plan;
pub mod reflect;

pub use context::{Context, ContextDesc, DeviceSelection};
pub use device::{CalibrationMethod, ClockCalibration, Device, DeviceInfo, QueueKind, host_now_ns};
pub use error::{BackendError, Result};
pub use executor::{ExecOptions, Executor, FaultInjection};
pub use instance::{Instance, Validation, validation_from_env};
pub use lower::{KernelGraph, LowerError};
pub use memory::{Buffer, Image, SharedHostBuffer};
pub use plan::{
    Plan, PlanAccess, PlanCopy, PlanError, PlanOp, PlanPass, PlanResource, ResourceKind, Rows, TexelFormat,
};
pub use recorder::{Draw, PassKernel, PassParams, Recorder};
pub use segments::{Chunk, chunks_of_copies};
pub use shaders::{ShaderLibrary, SpirvDefect, shader_names, spirv};
pub use texture::{MAX_TEXTURES, TextureData};
pub use timing::{DeviceFrameStats, EventKind, FrameReport, StageStats, TimedEvent, chrome_trace, write_json};
